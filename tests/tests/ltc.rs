//! Our fitted LTC table against brute-force integration of GGX and against the published fit
//! (`assets/reference/ltc/ltc.js`, Heitz et al. 2016), over the same random quads.

use glam::{DVec3, Vec3};
use kage_engine::math::ltc::{self, Entry, TABLE_SIZE, Table};
use kage_engine::math::{ggx, rng};
use kage_tests::asset;
use rand::Rng;

/// `g_ltc_1` (normalised inverse matrices) and `g_ltc_2` (magnitude, Fresnel) of ltc.js.
fn published() -> Vec<Entry> {
    let text = std::fs::read_to_string(asset("reference/ltc/ltc.js")).expect("published LTC data");
    let array = |name: &str| -> Vec<f32> {
        let start = text.find(&format!("var {name} = [")).expect("array present") + name.len() + 8;
        let end = start + text[start..].find("];").unwrap();
        text[start..end].split(',').filter_map(|v| v.trim().parse::<f32>().ok()).collect()
    };
    let (m, n) = (array("g_ltc_1"), array("g_ltc_2"));
    assert_eq!((m.len(), n.len()), (4 * TABLE_SIZE * TABLE_SIZE, 4 * TABLE_SIZE * TABLE_SIZE));
    (0..TABLE_SIZE * TABLE_SIZE)
        .map(|i| [m[4 * i], m[4 * i + 1], m[4 * i + 2], m[4 * i + 3], n[4 * i], n[4 * i + 1]])
        .collect()
}

/// ∫_quad f_GGX(v, l) cos θl dl (F = 1) by a 160×160 midpoint rule over the quad's area.
fn brute_force(quad: &[DVec3; 4], v: DVec3, alpha: f32) -> f64 {
    let n = 160;
    let (o, eu, ev) = (quad[0], quad[1] - quad[0], quad[3] - quad[0]);
    let normal = eu.cross(ev);
    let da = normal.length() / (n * n) as f64;
    let nhat = normal.normalize();
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let q = o + eu * ((i as f64 + 0.5) / n as f64) + ev * ((j as f64 + 0.5) / n as f64);
            let d2 = q.length_squared();
            let l = q / d2.sqrt();
            let cos_light = (-l.dot(nhat)).abs();
            let f = ggx::eval(v.as_vec3(), l.as_vec3(), alpha, Vec3::ONE, Vec3::ONE).x as f64;
            sum += f * l.z.max(0.0) * cos_light / d2 * da;
        }
    }
    sum
}

/// Random quads in front of the shading point (origin, normal +Z), facing it.
fn quads(count: usize, seed: u64) -> Vec<[DVec3; 4]> {
    let mut r = rng::seeded(seed);
    (0..count)
        .map(|_| {
            let phi = r.random::<f64>() * std::f64::consts::TAU;
            // Uniform over the hemisphere's solid angle above 3° elevation.
            let z = 0.05 + 0.95 * r.random::<f64>();
            let dir = DVec3::new((1.0 - z * z).sqrt() * phi.cos(), (1.0 - z * z).sqrt() * phi.sin(), z);
            let c = dir * (2.0 + 2.0 * r.random::<f64>());
            let u = dir.any_orthonormal_vector();
            let w = dir.cross(u);
            let (a, b) = (0.3 + r.random::<f64>(), 0.3 + r.random::<f64>());
            // Wound so that the CCW normal (w × u = −dir) faces the origin.
            [c - u * a - w * b, c - u * a + w * b, c + u * a + w * b, c + u * a - w * b]
        })
        .collect()
}

#[test]
fn our_fit_is_no_worse_than_the_published_one() {
    let ours = ltc::table();
    let theirs_entries = published();
    let theirs = Table::new(&theirs_entries);
    let quads = quads(16, 77);
    let (mut num_ours, mut num_theirs, mut den) = (0.0, 0.0, 0.0);
    let (mut max_diff, mut sum_diff, mut count) = (0.0f64, 0.0, 0);
    eprintln!("relative RMS error of LTC vs brute force (ours / published), 16 random quads per cell");
    eprintln!("roughness | cos θv = 0.15        0.4          0.7          0.95");
    for roughness in [0.2, 0.35, 0.5, 0.75, 1.0] {
        let mut line = format!("{roughness:9.2} |");
        for cos_v in [0.15, 0.4, 0.7, 0.95] {
            let v = DVec3::new((1.0f64 - cos_v * cos_v).sqrt(), 0.0, cos_v);
            let alpha = ggx::alpha_from_roughness(roughness as f32);
            let surface = ltc::Surface { p: DVec3::ZERO, n: DVec3::Z, v, roughness, f0: Vec3::ONE, f90: Vec3::ONE };
            let (mut e_o, mut e_t, mut d) = (0.0, 0.0, 0.0);
            for q in &quads {
                let bf = brute_force(q, v, alpha);
                let shade = |t: &Table| ltc::shade_polygon(t, q, &surface).specular.x as f64;
                let (o, t) = (shade(&ours), shade(&theirs));
                e_o += (o - bf).powi(2);
                e_t += (t - bf).powi(2);
                d += bf * bf;
                max_diff = max_diff.max((o - t).abs());
                sum_diff += (o - t).abs();
                count += 1;
            }
            line += &format!(" {:.3}/{:.3}", (e_o / d).sqrt(), (e_t / d).sqrt());
            num_ours += e_o;
            num_theirs += e_t;
            den += d;
        }
        eprintln!("{line}");
    }
    let (ours_err, theirs_err) = ((num_ours / den).sqrt(), (num_theirs / den).sqrt());
    eprintln!(
        "overall: ours {ours_err:.4}, published {theirs_err:.4}; |ours − published| max {max_diff:.2e}, mean {:.2e}",
        sum_diff / count as f64
    );
    assert!(ours_err <= theirs_err * 1.02 + 1e-4, "ours {ours_err} vs published {theirs_err}");
    // LTC's own approximation error, dominated by moderate roughness at grazing views.
    assert!(ours_err < 0.2, "LTC error against brute force: {ours_err}");
}

/// ∫ f cos over the hemisphere by a fine midpoint rule in (cos θ, φ).
fn albedo_quadrature(cos_v: f64, alpha: f32) -> f64 {
    let v = DVec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v).as_vec3();
    let (nt, np) = (2000, 800);
    let mut sum = 0.0;
    for i in 0..nt {
        let c = (i as f64 + 0.5) / nt as f64;
        for j in 0..np {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
            let s = (1.0 - c * c).sqrt();
            let l = DVec3::new(s * phi.cos(), s * phi.sin(), c).as_vec3();
            sum += ggx::eval(v, l, alpha, Vec3::ONE, Vec3::ONE).x as f64 * c;
        }
    }
    sum * std::f64::consts::TAU / (nt * np) as f64
}

#[test]
fn magnitude_terms_match_quadrature_and_the_published_table() {
    let ours = ltc::table();
    let theirs_entries = published();
    let theirs = Table::new(&theirs_entries);
    // Table nodes, including the most grazing column (t = 63, cos θv ≈ 8e-4).
    for (a, t) in [(63, 0), (32, 20), (20, 45), (40, 60), (22, 63), (50, 63)] {
        let (v, alpha) = ltc::entry_params(a, t);
        let r = a as f64 / 63.0;
        let exact = albedo_quadrature(v.z, alpha as f32);
        let (o, p) = (ours.lookup(r, v.z).magnitude, theirs.lookup(r, v.z).magnitude);
        eprintln!("a {a:2} t {t:2}: quadrature {exact:.5}  ours {o:.5}  published {p:.5}");
        // At t = 63 (cos θv ≈ 8e-4) the lobe is extremely peaked and the quadrature itself is
        // least accurate; the published table is 6e-2 off there.
        let tolerance = if t == 63 { 1e-2 } else { 1e-3 };
        assert!((o - exact).abs() < tolerance, "ours {o} vs {exact}");
    }
    // Elsewhere the two tables agree closely.
    let mut diffs = Vec::new();
    for a in 0..TABLE_SIZE {
        for t in 0..TABLE_SIZE - 1 {
            let (v, _) = ltc::entry_params(a, t);
            let (o, p) = (ours.lookup(a as f64 / 63.0, v.z), theirs.lookup(a as f64 / 63.0, v.z));
            diffs.push((o.magnitude - p.magnitude).abs().max((o.fresnel - p.fresnel).abs()));
        }
    }
    let (max, mean) = (diffs.iter().copied().fold(0.0, f64::max), diffs.iter().sum::<f64>() / diffs.len() as f64);
    eprintln!("magnitude/Fresnel, ours vs published (t < 63): max {max:.2e}, mean {mean:.2e}");
    // The largest differences sit at grazing columns, where the published magnitudes are the
    // less accurate ones (see above).
    assert!(mean < 5e-3, "{max} {mean}");
}
