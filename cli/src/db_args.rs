//! Where the bake database lives: `--db PATH`, or `SCENE_DIR/.kage/bake.redb` (the built-in
//! scene: `./.kage/bake.redb`).

use crate::scene_args::SceneArgs;
use kage_bake_db::Store;
use std::path::PathBuf;

/// The `--db` option.
#[derive(clap::Args, Debug, Clone)]
pub struct DbArgs {
    /// Bake database (default: SCENE_DIR/.kage/bake.redb).
    #[arg(long)]
    pub db: Option<PathBuf>,
}

impl DbArgs {
    /// The database path for `scene`.
    pub fn path(&self, scene: &SceneArgs) -> PathBuf {
        self.db.clone().unwrap_or_else(|| {
            let dir = scene.scene.as_ref().and_then(|p| p.parent().map(PathBuf::from)).unwrap_or_default();
            dir.join(".kage").join("bake.redb")
        })
    }

    /// Opens (creating) the database.
    pub fn open(&self, scene: &SceneArgs) -> anyhow::Result<Store> {
        Ok(Store::open(&self.path(scene))?)
    }

    /// Opens the database if `--db` was given or the default one exists (a scene that was
    /// never baked renders from an in-memory bake instead).
    pub fn open_if_used(&self, scene: &SceneArgs) -> anyhow::Result<Option<Store>> {
        let path = self.path(scene);
        if self.db.is_some() || path.exists() { Ok(Some(Store::open(&path)?)) } else { Ok(None) }
    }
}
