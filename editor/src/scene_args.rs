//! Scene selection shared by every subcommand: a glTF file or the built-in scene, plus an
//! optional environment map.

use anyhow::Result;
use kage_engine::scene::{self, EnvMap, EnvironmentLight, Scene, import::ImportOptions};
use std::path::PathBuf;

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
}

impl SceneArgs {
    /// Loads the scene and applies the environment options.
    pub fn load(&self) -> Result<Scene> {
        let mut scene = match &self.scene {
            Some(path) => scene::import::import(path, ImportOptions { drop_degenerate: self.drop_degenerate })?,
            None => scene::default_scene(),
        };
        for w in &scene.warnings {
            eprintln!("warning: {w}");
        }
        if let Some(path) = &self.env {
            scene.set_environment(EnvironmentLight::new(EnvMap::load(path)?));
        }
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
        Ok(scene)
    }
}
