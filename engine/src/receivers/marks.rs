//! Which edges of a receiver to split: where interpolating the visibility between an edge's
//! ends misses the truth at its midpoint (see the module documentation of [`super`]).

use super::probe::{Near, Probe};
use crate::scene::refine::Adaptive;
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// What earlier rounds probed on one mesh: per vertex its lights' visibility, per edge its
/// interpolation error.
#[derive(Default)]
pub(super) struct Memo {
    vertex: Vec<Vec<f32>>,
    /// The largest error over the lights' views, and over the environment's.
    edge: HashMap<[u32; 2], [f32; 2]>,
}

/// The edges of `mesh` (placed by `world`, shadowed by `near`) longer than `shortest` whose
/// visibility interpolates worse than `tolerance`, with their error × world length; probes
/// only the vertices and edges `memo` lacks, and keeps them there (a shorter edge is never
/// split, so its midpoint is not probed).
pub(super) fn marked(
    mesh: &Adaptive,
    (world, near): (&glam::Affine3A, &Near),
    probe: &Probe,
    (tolerance, shortest): (f32, f32),
    memo: &mut Memo,
) -> Vec<Mark> {
    let (p, n) = (mesh.positions(), mesh.normals());
    let at = |a: Vec3, na: Vec3| {
        probe.visibility(world.transform_point3(a), world.transform_vector3(na).normalize_or_zero(), near)
    };
    let new: Vec<Vec<f32>> = (memo.vertex.len()..p.len()).into_par_iter().map(|i| at(p[i], n[i])).collect();
    memo.vertex.extend(new);
    let vertex = &memo.vertex;
    let length = |a: u32, b: u32| world.transform_point3(p[a as usize]).distance(world.transform_point3(p[b as usize]));
    let edges: Vec<[u32; 2]> = mesh.edges().into_iter().filter(|&[a, b]| length(a, b) > shortest).collect();
    let fresh: Vec<([u32; 2], [f32; 2])> = edges
        .par_iter()
        .filter(|e| !memo.edge.contains_key(*e))
        .map(|&e| {
            // Across a hard crease the named ends carry one side's normal each (a box's corner
            // would see the light on one face and not on the next): each side is judged on its
            // own vertices.
            let sides = mesh.sides(e).into_iter().map(|side| side_error(side, p, n, vertex, &at, probe.scope.lights));
            (e, sides.fold([0.0f32; 2], |most, s| [most[0].max(s[0]), most[1].max(s[1])]))
        })
        .collect();
    memo.edge.extend(fresh);
    edges
        .into_iter()
        .filter_map(|[a, b]| {
            let [lights, environment] = memo.edge[&[a, b]];
            let (tier, error) =
                if lights > tolerance { (Tier::Lights, lights) } else { (Tier::Environment, environment) };
            (error > tolerance).then(|| (tier, error * length(a, b), [a, b]))
        })
        .collect()
}

/// One side of an edge (`[a, b]`, the vertices one triangle uses): how far what the pixels
/// between its ends are shaded with misses the truth at its midpoint, over the lights' views
/// (the first `lights`) and over the environment's. A light's visible fraction is interpolated
/// as pixels interpolate it ([`crate::bspvt::pixel`]: the shadowed over the unshadowed share),
/// and its error weighed by the unshadowed share there and by how dark the truth is (a few
/// percent of the light show against an umbra, not in full light); a linear ramp across a
/// penumbra, or the light sinking below a curved receiver's horizon (which LTC takes per
/// pixel), is no error.
/// The environment's share is interpolated linearly, so its ends' difference counts too.
fn side_error(
    [a, b]: [u32; 2],
    p: &[Vec3],
    n: &[Vec3],
    vertex: &[Vec<f32>],
    at: &impl Fn(Vec3, Vec3) -> Vec<f32>,
    lights: usize,
) -> [f32; 2] {
    let (a, b) = (a as usize, b as usize);
    // An end inside geometry takes no part in its pixels' lights: they take the other end's.
    let ends: Vec<&Vec<f32>> = [&vertex[a], &vertex[b]].into_iter().filter(|v| !v.is_empty()).collect();
    if ends.is_empty() {
        return [0.0; 2];
    }
    let mid = at(0.5 * (p[a] + p[b]), (n[a] + n[b]).normalize_or_zero());
    let Some(m) = (!mid.is_empty()).then_some(&mid) else { return [0.0; 2] };
    let light = |l: usize| {
        let (s, o) = ends.iter().fold((0.0, 0.0), |(s, o), v| (s + v[2 * l], o + v[2 * l + 1]));
        let (sm, om) = (m[2 * l], m[2 * l + 1]);
        if om <= 0.0 {
            return 0.0;
        }
        // Where no end sees the light above its horizon, pixels take it as unshadowed.
        let shaded = if o > 0.0 { s / o } else { 1.0 };
        let f = sm / om;
        om * (shaded - f).abs() / (f + DARK)
    };
    // The environment's shading still interpolates an inside end's darkness
    // (`docs/receivers.md`): it is judged between two outside ends only.
    let environment = |k: usize| match ends[..] {
        [va, vb] => (va[k] - vb[k]).abs().max((m[k] - 0.5 * (va[k] + vb[k])).abs()),
        _ => 0.0,
    };
    let most = |e: &mut dyn Iterator<Item = f32>| e.fold(0.0, f32::max);
    [most(&mut (0..lights).map(light)), most(&mut (2 * lights..m.len()).map(environment))]
}

/// How much more a light's error counts where the truth is dark: it is divided by f + `DARK`,
/// f the visible fraction at the midpoint — ×4 in an umbra, ×0.8 in full light. Chosen on the
/// floor scene's ball, whose umbra otherwise showed long triangles' gradients of a few percent
/// of the light as light wedges (`docs/receivers.md`).
const DARK: f32 = 0.25;

/// Which views marked an edge. The environment's marks are split only once no light marks
/// any edge: measured, they lower the environment term's error by 1–2 % of itself, where the
/// lights' marks take shadows from 34 % to 3.5 % (`docs/receivers.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Tier {
    Lights,
    Environment,
}

/// An edge to split: its tier, its error × world length, and its ends.
pub(super) type Mark = (Tier, f32, [u32; 2]);

#[cfg(test)]
mod tests {
    use super::*;

    /// An edge from a vertex inside geometry (no visibility) to one outside is held to the
    /// outside end's share, which its pixels show: a shadow between them is an error. With
    /// both ends, or the midpoint, inside there is nothing to judge.
    #[test]
    fn an_edge_with_one_end_inside_is_held_to_the_other_end() {
        let (p, n) = ([Vec3::ZERO, Vec3::X], [Vec3::Y, Vec3::Y]);
        let lit = vec![1.0, 1.0];
        let shadowed = |_: Vec3, _: Vec3| vec![0.2, 1.0];
        let error =
            |vertex: &[Vec<f32>], at: &dyn Fn(Vec3, Vec3) -> Vec<f32>| side_error([0, 1], &p, &n, vertex, &at, 1)[0];
        let expected = (1.0 - 0.2) / (0.2 + DARK);
        assert!((error(&[Vec::new(), lit.clone()], &shadowed) - expected).abs() < 1e-6);
        assert_eq!(error(&[Vec::new(), Vec::new()], &shadowed), 0.0);
        assert_eq!(error(&[Vec::new(), lit], &|_, _| Vec::new()), 0.0);
    }
}
