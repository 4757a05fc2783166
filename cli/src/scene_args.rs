//! Scene selection shared by every subcommand: a glTF file or the built-in scene, plus an
//! optional environment map.

use anyhow::Result;
use glam::{Quat, Vec3};
use kage_engine::scene::{self, EnvMap, EnvironmentLight, Scene, import::ImportOptions};
use std::path::PathBuf;

/// Vertices receiver refinement may add to a scene by default: the two-triangle floor's shadows
/// within 4 % with it, the built-in scene's bake ≈ 2.3× the vertices (docs/receivers.md).
pub const DEFAULT_RECEIVER_BUDGET: usize = 6000;

/// Which scene to load.
#[derive(clap::Args, Debug, Clone)]
pub struct SceneArgs {
    /// A .gltf or .glb file (default: the built-in scene).
    pub scene: Option<PathBuf>,
    /// Equirectangular environment map (.hdr or .exr); replaces the scene's environment.
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Environment radiance multiplier.
    #[arg(long)]
    pub env_intensity: Option<f32>,
    /// Environment rotation about +Y in degrees.
    #[arg(long)]
    pub env_rotation: Option<f32>,
    /// Drop zero-area triangles with a warning instead of rejecting the file.
    #[arg(long)]
    pub drop_degenerate: bool,
    /// Let the scene's buffer and image URIs read files under DIR, not only under the scene
    /// file's own folder (for scenes that share textures with a sibling folder).
    #[arg(long, value_name = "DIR")]
    pub allow_root: Option<PathBuf>,
    /// Move a rigid group (top-level node name or group index) by x,y,z, e.g.
    /// `--move group_bunny=0.5,0,0`; repeatable.
    #[arg(long = "move", value_name = "NODE=x,y,z", value_parser = parse_move)]
    pub moves: Vec<(String, Vec3)>,
    /// Rotate a rigid group about its own origin by an axis and an angle in degrees, e.g.
    /// `--rotate group_box_sphere=0,1,0,90`; applied before --move; repeatable.
    #[arg(long = "rotate", value_name = "NODE=ax,ay,az,degrees", value_parser = parse_rotate)]
    pub rotations: Vec<(String, Quat)>,
    /// Move a light (its node's name, or its index among the lights) by x,y,z, e.g.
    /// `--move-light light=0,0,-0.5`; repeatable. A light with a declared reach stays in it.
    #[arg(long = "move-light", value_name = "NODE=x,y,z", value_parser = parse_move)]
    pub light_moves: Vec<(String, Vec3)>,
    /// Turn a light about its centre by an axis and an angle in degrees, e.g.
    /// `--rotate-light light=1,0,0,20`; applied before --move-light; repeatable.
    #[arg(long = "rotate-light", value_name = "NODE=ax,ay,az,degrees", value_parser = parse_rotate)]
    pub light_rotations: Vec<(String, Quat)>,
    /// Refine the mesh of the instances (or group) named NODE to VERTICES vertices by
    /// longest-edge bisection on its Phong surface, e.g. `--refine teapot=17000`; repeatable.
    #[arg(long = "refine", value_name = "NODE=VERTICES", value_parser = parse_refine)]
    pub refinements: Vec<(String, usize)>,
    /// Refine every receiver where the lights' and the environment's shadows need vertices,
    /// until interpolation meets --refine-tolerance, adding at most VERTICES to each instance
    /// (adaptive: for each light where it is, or over its declared reach; docs/receivers.md).
    /// Default 6000 (0 turns it off; the editor refines again before each bake).
    #[arg(long, value_name = "VERTICES", env = "KAGE_REFINE_RECEIVERS")]
    pub refine_receivers: Option<usize>,
    /// Largest visibility error (0–1, a share of the light) interpolation between an edge's
    /// ends may make at its midpoint after --refine-receivers.
    #[arg(long, value_name = "ERROR", default_value_t = kage_engine::receivers::Settings::default().tolerance)]
    pub refine_tolerance: f32,
}

fn parse_numbers(s: &str, n: usize) -> Result<(String, Vec<f32>), String> {
    let (node, rest) = s.split_once('=').ok_or_else(|| format!("expected NODE=..., got '{s}'"))?;
    let v: Vec<f32> = rest
        .split(',')
        .map(|c| c.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}"))?;
    if v.len() != n || !v.iter().all(|c| c.is_finite()) {
        return Err(format!("expected {n} finite numbers after '{node}=', got '{rest}'"));
    }
    Ok((node.to_string(), v))
}

fn parse_move(s: &str) -> Result<(String, Vec3), String> {
    let (node, v) = parse_numbers(s, 3)?;
    Ok((node, Vec3::new(v[0], v[1], v[2])))
}

fn parse_refine(s: &str) -> Result<(String, usize), String> {
    let (node, count) = s.split_once('=').ok_or_else(|| format!("expected NODE=VERTICES, got '{s}'"))?;
    let count = count.trim().parse::<usize>().map_err(|e| format!("'{s}': {e}"))?;
    Ok((node.to_string(), count))
}

fn parse_rotate(s: &str) -> Result<(String, Quat), String> {
    let (node, v) = parse_numbers(s, 4)?;
    let axis = Vec3::new(v[0], v[1], v[2]);
    if axis.length_squared() == 0.0 {
        return Err(format!("'{s}': the rotation axis is zero"));
    }
    Ok((node, Quat::from_axis_angle(axis.normalize(), v[3].to_radians())))
}

impl SceneArgs {
    /// How the scene file (and, in the editor, its re-imports) is read.
    pub fn import_options(&self) -> ImportOptions {
        ImportOptions {
            drop_degenerate: self.drop_degenerate,
            allow_root: self.allow_root.clone(),
            ..Default::default()
        }
    }

    /// Loads the scene, applies the environment options and refines receivers (by default
    /// with [`DEFAULT_RECEIVER_BUDGET`]).
    pub fn load(&self) -> Result<Scene> {
        self.load_refined(true, None)
    }

    /// As [`Self::load`], the receivers' refinement read from `store`'s memos when it holds it
    /// and kept there otherwise (`kage_bake_db::memo::refinement`).
    pub fn load_kept(&self, store: Option<&kage_bake_db::Store>) -> Result<Scene> {
        self.load_refined(true, store)
    }

    /// As [`Self::load`] without receiver refinement (the editor refines the scene itself,
    /// and again after edits: [`Self::receiver_settings`]).
    pub fn load_unrefined(&self) -> Result<Scene> {
        self.load_refined(false, None)
    }

    /// Whether the environment's intensity or rotation is given.
    pub fn poses_environment(&self) -> bool {
        self.env_intensity.is_some() || self.env_rotation.is_some()
    }

    /// Applies the run-time changes asked for — the environment's intensity and rotation,
    /// groups turned and moved, lights turned and moved — to a loaded scene or a pack's.
    pub fn pose(&self, scene: &mut Scene) -> Result<()> {
        for env in scene.world.query_mut::<&mut EnvironmentLight>() {
            if let Some(i) = self.env_intensity {
                anyhow::ensure!(
                    i.is_finite() && i >= 0.0,
                    "--env-intensity must be a finite non-negative number, got {i}"
                );
                env.intensity = i;
            }
            if let Some(deg) = self.env_rotation {
                anyhow::ensure!(deg.is_finite(), "--env-rotation must be finite, got {deg}");
                env.rotation = deg.to_radians();
            }
        }
        for (node, q) in &self.rotations {
            let g = scene.find_group(node)?;
            scene.pose_group(g, *q, Vec3::ZERO);
        }
        for (node, offset) in &self.moves {
            let g = scene.find_group(node)?;
            scene.pose_group(g, Quat::IDENTITY, *offset);
        }
        let turns = self.light_rotations.iter().map(|(n, q)| (n, Vec3::ZERO, *q));
        for (node, offset, turn) in turns.chain(self.light_moves.iter().map(|(n, o)| (n, *o, Quat::IDENTITY))) {
            for light in scene.find_lights(node)? {
                let local =
                    scene.light_moved(light, offset, turn).map_err(|e| anyhow::anyhow!("light '{node}': {e}"))?;
                scene.place_light(light, local);
            }
        }
        Ok(())
    }

    /// The options a pack cannot take (it carries its scene, environment and refinement),
    /// named in an error when given (`--refine-receivers`, which `KAGE_REFINE_RECEIVERS` may
    /// set for every command, is left unused).
    pub fn check_for_pack(&self) -> Result<()> {
        let given = [
            ("--env", self.env.is_some()),
            ("--refine", !self.refinements.is_empty()),
            ("--drop-degenerate", self.drop_degenerate),
            ("--allow-root", self.allow_root.is_some()),
        ];
        match given.iter().find(|(_, on)| *on) {
            Some((name, _)) => {
                anyhow::bail!("{name} does not apply to a pack (it carries its scene, environment and refined meshes)")
            }
            None => Ok(()),
        }
    }

    /// Receiver refinement as asked for (`None`: off).
    pub fn receiver_settings(&self) -> Result<Option<kage_engine::receivers::Settings>> {
        let budget = self.refine_receivers.unwrap_or(DEFAULT_RECEIVER_BUDGET);
        let tolerance = self.refine_tolerance;
        anyhow::ensure!(
            tolerance > 0.0 && tolerance < 1.0,
            "--refine-tolerance is a visibility error in (0, 1), got {tolerance}"
        );
        Ok((budget > 0).then(|| kage_engine::receivers::Settings { budget, tolerance, ..Default::default() }))
    }

    fn load_refined(&self, refine: bool, store: Option<&kage_bake_db::Store>) -> Result<Scene> {
        let mut scene = match &self.scene {
            Some(path) => crate::progress::with_sized_bar("importing", |progress| {
                scene::import::import_reporting(path, self.import_options(), progress)
            })?,
            None => scene::default_scene(),
        };
        for w in &scene.warnings {
            eprintln!("warning: {w}");
        }
        if let Some(path) = &self.env {
            scene.set_environment(EnvironmentLight::new(EnvMap::load(path)?));
        }
        for (node, target) in &self.refinements {
            let n = scene.refine_instances(node, *target)?;
            eprintln!("refined {n} instance(s) of '{node}' to {target} vertices");
        }
        self.pose(&mut scene)?;
        if let Some(settings) = self.receiver_settings()?.filter(|_| refine) {
            refine_receivers(&mut scene, &settings, store)?;
        }
        Ok(scene)
    }
}

/// Refines `scene`'s receivers (through `store`'s memos when given) under a progress bar, and
/// prints what it did: the refinement line, and the instances it refined (the first
/// [`LISTED`]).
fn refine_receivers(
    scene: &mut Scene,
    settings: &kage_engine::receivers::Settings,
    store: Option<&kage_bake_db::Store>,
) -> Result<()> {
    let instances = scene.world.query_mut::<&scene::MeshRef>().into_iter().count();
    let capped = settings.for_instances(instances);
    if capped.budget < settings.budget {
        eprintln!(
            "warning: receiver refinement: {instances} instances at {} vertices each would add more than {}; each instance's cap lowered to {} (--refine-receivers sets it)",
            settings.budget,
            kage_engine::receivers::SCENE_ALLOWANCE,
            capped.budget
        );
    }
    let started = std::time::Instant::now();
    let (report, kept) = crate::progress::with_bar(instances, "refining", |progress| match store {
        Some(store) => kage_bake_db::memo::refinement::refine(store, scene, settings, progress),
        None => Ok((kage_engine::receivers::refine_reporting(scene, settings, progress)?, 0)),
    })?;
    let (before, after) = report.iter().fold((0, 0), |(b, a), (x, y)| (b + x, a + y));
    let from = kage_bake_db::memo::refinement::kept_note(kept, report.len());
    eprintln!(
        "refined receivers: {before} → {after} vertices in {:.2} s (at most {} more each, tolerance {}{from})",
        started.elapsed().as_secs_f64(),
        capped.budget,
        settings.tolerance
    );
    let grown: Vec<_> = report.iter().enumerate().filter(|(_, (b, a))| a > b).collect();
    for (i, (b, a)) in grown.iter().take(LISTED) {
        eprintln!("  instance {i:3}: {b} → {a} vertices (+{})", a - b);
    }
    if grown.len() > LISTED {
        eprintln!("  … {} more instances refined", grown.len() - LISTED);
    }
    Ok(())
}

/// Refined instances listed one per line; the rest are counted.
const LISTED: usize = 32;
