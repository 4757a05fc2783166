//! `extras.kage.light_reach` on a light's node: where the light promises to stay however it
//! is moved, so that bakers need only cover the directions it can come from (see
//! [`crate::bspvt::reach`]). Blender exports custom properties as such extras.

use glam::Vec3;

/// The reach a node declares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Declared {
    /// `"fixed"`: each light polygon stays where the file puts it.
    Fixed,
    /// `{"min": [x, y, z], "max": [x, y, z]}`: a world-space box the lights never leave.
    Within([Vec3; 2]),
}

const EXPECTED: &str = r#"extras.kage.light_reach: expected "fixed" or {"min": [x, y, z], "max": [x, y, z]}"#;

/// The reach declared in a node's raw extras (`None` when there is none: lights go anywhere).
pub fn declared(extras: Option<&str>) -> Result<Option<Declared>, String> {
    let Some(raw) = extras else { return Ok(None) };
    let v: serde_json::Value = serde_json::from_str(raw).map_err(|e| format!("extras are not JSON: {e}"))?;
    let Some(r) = v.get("kage").and_then(|k| k.get("light_reach")) else { return Ok(None) };
    if r == "fixed" {
        return Ok(Some(Declared::Fixed));
    }
    let corner = |k: &str| -> Option<Vec3> {
        let c = r.get(k)?.as_array().filter(|a| a.len() == 3)?;
        let c: Vec<f32> = c.iter().map(|x| x.as_f64().map(|x| x as f32)).collect::<Option<_>>()?;
        Some(Vec3::from_slice(&c))
    };
    let (Some(lo), Some(hi)) = (corner("min"), corner("max")) else { return Err(EXPECTED.into()) };
    if !(lo.is_finite() && hi.is_finite()) || lo.cmpgt(hi).any() {
        return Err(format!("extras.kage.light_reach: min {lo} and max {hi} must be finite, min ≤ max"));
    }
    Ok(Some(Declared::Within([lo, hi])))
}

/// The box of a light polygon at world `points` under `declared`: the polygon's own bounds
/// when fixed, else the declared box — an error when the polygon lies outside it.
pub fn resolve(declared: Declared, points: &[Vec3]) -> Result<[Vec3; 2], String> {
    let (lo, hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    match declared {
        Declared::Fixed => Ok([lo, hi]),
        Declared::Within([a, b]) if contains([a, b], [lo, hi]) => Ok([a, b]),
        Declared::Within([a, b]) => {
            Err(format!("the light (bounds {lo} … {hi}) lies outside its extras.kage.light_reach box {a} … {b}"))
        }
    }
}

/// Whether box `outer` holds box `inner`, up to single-precision rounding of the transforms.
pub fn contains(outer: [Vec3; 2], inner: [Vec3; 2]) -> bool {
    let slack = 1e-5 * (outer[1] - outer[0]).length().max(inner[1].abs().max(inner[0].abs()).max_element()).max(1.0);
    inner[0].cmpge(outer[0] - slack).all() && inner[1].cmple(outer[1] + slack).all()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_fixed_boxes_and_nothing() {
        assert_eq!(declared(None), Ok(None));
        assert_eq!(declared(Some(r#"{"other": 1}"#)), Ok(None));
        assert_eq!(declared(Some(r#"{"kage": {"light_reach": "fixed"}}"#)), Ok(Some(Declared::Fixed)));
        let b = declared(Some(r#"{"kage": {"light_reach": {"min": [-1, 0, -2], "max": [1, 3.5, 2]}}}"#));
        assert_eq!(b, Ok(Some(Declared::Within([Vec3::new(-1.0, 0.0, -2.0), Vec3::new(1.0, 3.5, 2.0)]))));
    }

    #[test]
    fn refuses_malformed_reaches() {
        for bad in [
            r#"{"kage": {"light_reach": "moving"}}"#,
            r#"{"kage": {"light_reach": {"min": [0, 0], "max": [1, 1, 1]}}}"#,
            r#"{"kage": {"light_reach": {"min": [0, 0, "a"], "max": [1, 1, 1]}}}"#,
            r#"{"kage": {"light_reach": {"min": [2, 0, 0], "max": [1, 1, 1]}}}"#,
            r#"{"kage": {"light_reach": {"min": [0, 0, 0], "max": [1e39, 1, 1]}}}"#,
            "{not json",
        ] {
            assert!(declared(Some(bad)).is_err(), "{bad}");
        }
    }

    #[test]
    fn fixed_is_the_polygon_and_a_box_must_hold_it() {
        let quad = [Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 1.0)];
        assert_eq!(resolve(Declared::Fixed, &quad), Ok([Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 1.0)]));
        let room = [Vec3::splat(-3.0), Vec3::splat(3.0)];
        assert_eq!(resolve(Declared::Within(room), &quad), Ok(room));
        let err = resolve(Declared::Within([Vec3::ZERO, Vec3::ONE]), &quad).unwrap_err();
        assert!(err.contains("outside its extras.kage.light_reach box"), "{err}");
    }
}
