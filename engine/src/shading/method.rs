//! The shading methods as users name them: one vocabulary for `kage render`, the editor, the
//! report and the GPU path. Each technique's own enums ([`crate::bspvt::Shadows`],
//! [`crate::prt::Shadows`]) say which shadows a technique computes; this says what a user
//! chose.

use crate::bspvt;
use crate::cache::record::GlossyDirect;
use crate::named::Named;
use crate::scene::Scene;
use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

/// How radiance is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Everything the scene has, each through its technique: polygonal lights (BSPVT), the
    /// environment (PRT, glossy and metal included), one bounce (radiance cache).
    Baked,
    /// Monte Carlo ground truth (path tracing with MIS).
    Reference,
    /// Polygonal lights with BSP visibility trees and LTC (per vertex).
    Bspvt,
    /// Polygonal lights with LTC and no shadows (per vertex).
    LtcUnshadowed,
    /// Polygonal lights with LTC clipped per visible cube-map texel, no tree (per vertex).
    LtcExactVis,
    /// Environment light with PRT and shadows cast between rigid groups (per pixel in images).
    Prt,
    /// Environment light with PRT: self-shadowing only (per vertex).
    PrtSelf,
}

/// Which of a scene's lights a method shades.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lights {
    /// The polygonal lights and the environment.
    All,
    /// The polygonal lights only.
    Polygonal,
    /// The environment only.
    Environment,
}

impl Named for Method {
    const ALL: &'static [Method] = &[
        Method::Baked,
        Method::Bspvt,
        Method::LtcUnshadowed,
        Method::LtcExactVis,
        Method::Prt,
        Method::PrtSelf,
        Method::Reference,
    ];

    fn name(self) -> &'static str {
        match self {
            Method::Baked => "baked",
            Method::Reference => "reference",
            Method::Bspvt => "bspvt",
            Method::LtcUnshadowed => "ltc-unshadowed",
            Method::LtcExactVis => "ltc-exact-vis",
            Method::Prt => "prt",
            Method::PrtSelf => "prt-self",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Method::Baked => {
                "the whole look: polygonal lights (BSPVT + LTC), the environment (PRT, glossy and metal too), one bounce (radiance cache)"
            }
            Method::Reference => "Monte Carlo ground truth (path tracing with MIS)",
            Method::Bspvt => "polygonal lights: BSP visibility trees + LTC (GGX), per vertex",
            Method::LtcUnshadowed => "polygonal lights: LTC without shadows, per vertex",
            Method::LtcExactVis => "polygonal lights: LTC clipped per visible cube-map texel (the trees' ground truth)",
            Method::Prt => "environment: PRT with shadows between rigid groups (per pixel in images)",
            Method::PrtSelf => "environment: PRT with self-shadowing only, per vertex",
        }
    }
}

impl Method {
    /// The lights it shades.
    pub fn lights(self) -> Lights {
        match self {
            Method::Reference | Method::Baked => Lights::All,
            Method::Bspvt | Method::LtcUnshadowed | Method::LtcExactVis => Lights::Polygonal,
            Method::Prt | Method::PrtSelf => Lights::Environment,
        }
    }

    /// True for the methods that compute direct light per vertex (all but the reference), to
    /// which the radiance cache can add one bounce of indirect light.
    pub fn direct(self) -> bool {
        self != Method::Reference
    }

    /// True when `kage render --gpu` shades it: the WGSL compute shaders per vertex, or for
    /// `baked` the editor viewport's draw (the others run on the CPU only).
    pub fn on_gpu(self) -> bool {
        matches!(self, Method::Bspvt | Method::LtcUnshadowed | Method::Prt | Method::PrtSelf | Method::Baked)
    }

    /// The PRT shadows it computes, for the PRT methods.
    pub fn prt_shadows(self) -> Option<crate::prt::Shadows> {
        match self {
            Method::Prt | Method::Baked => Some(crate::prt::Shadows::WithOthers),
            Method::PrtSelf => Some(crate::prt::Shadows::SelfOnly),
            _ => None,
        }
    }

    /// The visibility it shades polygonal lights with, given the trees that fit the snapshot (if
    /// any) and the cube-map resolution of exact visibility; `None` for the methods that shade
    /// no polygonal light per vertex (PRT, the reference). Without trees, BSPVT is unshadowed.
    pub fn polygonal_shadows(self, trees: Option<&bspvt::Bake>, res: usize) -> Option<bspvt::Shadows<'_>> {
        match self {
            Method::Bspvt | Method::Baked => Some(trees.map_or(bspvt::Shadows::Unshadowed, bspvt::Shadows::Trees)),
            Method::LtcUnshadowed => Some(bspvt::Shadows::Unshadowed),
            Method::LtcExactVis => Some(bspvt::Shadows::Exact { res }),
            Method::Prt | Method::PrtSelf | Method::Reference => None,
        }
    }

    /// How the radiance cache lights glossy hits toward its records for this method's direct
    /// light (the baked look lights them with its own parts where it has them).
    pub fn glossy_direct(self, trees: Option<Arc<bspvt::Bake>>) -> GlossyDirect {
        match self {
            Method::Bspvt | Method::Baked => GlossyDirect::Ltc(trees),
            Method::LtcUnshadowed => GlossyDirect::Ltc(None),
            Method::Prt | Method::PrtSelf => GlossyDirect::PerVertex,
            Method::LtcExactVis | Method::Reference => GlossyDirect::Reference,
        }
    }

    /// A copy of `scene` with only the lights it shades, so that a reference for it compares
    /// like with like.
    pub fn lit(self, scene: &Scene) -> Scene {
        let mut lit = scene.duplicate();
        match self.lights() {
            Lights::All => {}
            Lights::Polygonal => lit.clear_environment(),
            Lights::Environment => lit.remove_polygon_lights(),
        }
        lit
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Method::named(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every name parses back to its method, and the names are distinct.
    #[test]
    fn names_round_trip() {
        for &m in Method::ALL {
            assert_eq!(m.name().parse::<Method>(), Ok(m));
            assert_eq!(m.to_string(), m.name());
        }
        assert!("baked-look".parse::<Method>().unwrap_err().contains("ltc-exact-vis"));
    }

    #[test]
    fn each_method_shades_its_own_lights() {
        let scene = crate::scene::default_scene();
        let count = |s: &Scene| {
            let lights = s.world.query::<&crate::scene::PolygonLight>().iter().count();
            let env = s.world.query::<&crate::scene::EnvironmentLight>().iter().count();
            (lights > 0, env > 0)
        };
        assert_eq!(count(&scene), (true, true), "the built-in scene has both kinds");
        assert_eq!(count(&Method::Reference.lit(&scene)), (true, true));
        assert_eq!(count(&Method::Baked.lit(&scene)), (true, true));
        assert_eq!(count(&Method::Bspvt.lit(&scene)), (true, false));
        assert_eq!(count(&Method::PrtSelf.lit(&scene)), (false, true));
    }
}
