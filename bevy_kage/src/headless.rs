//! Rendering a pack without a window, for tests and measurements: an app with the plugin and
//! no window, a camera at the pack's camera drawing into a linear `Rgba32Float` image (HDR, no
//! tonemapping, no MSAA, exposure 1), and the image read back.

use crate::spawn::{camera_view, exposure_ev100};
use crate::{KagePack, KagePlugin, KageScene, ShadeOn};
use bevy::app::PluginsState;
use bevy::asset::LoadState;
use bevy::camera::{Exposure, Hdr, RenderTarget};
use bevy::core_pipeline::tonemapping::{DebandDither, Tonemapping};
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::mesh::RenderMesh;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::{PipelineCache, TextureFormat, TextureUsages};
use bevy::render::view::Msaa;
use bevy::window::ExitCondition;
use bevy::winit::WinitPlugin;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A windowless app showing one pack through its camera into an image.
pub struct Headless {
    /// The app (update it to render a frame).
    pub app: App,
    /// The image the camera draws into.
    pub target: Handle<Image>,
}

/// How a windowless app renders its frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rendering {
    /// On the app's thread, in step with its updates: a frame shows the world as just updated,
    /// and [`Headless::settled`] also waits for Bevy's pipelines and mesh uploads (for tests).
    InStep,
    /// On a thread of its own, overlapping the next update, as a windowed app renders (for
    /// timing); the render world is then out of reach, and `settled` waits for the image alone.
    Pipelined,
}

/// An app with Bevy's default plugins and the kage plugin, no window, no ambient light and a
/// transparent clear colour, reading assets from `folder`, rendering as `rendering` says; its
/// plugins built.
pub fn windowless(folder: &Path, shade_on: ShadeOn, rendering: Rendering) -> App {
    let plugins = DefaultPlugins
        .set(AssetPlugin { file_path: folder.to_string_lossy().into_owned(), ..default() })
        .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
        .disable::<WinitPlugin>();
    let plugins = match rendering {
        Rendering::InStep => plugins.disable::<PipelinedRenderingPlugin>(),
        Rendering::Pipelined => plugins,
    };
    let mut app = App::new();
    app.add_plugins(plugins)
        .add_plugins(KagePlugin { shade_on })
        .insert_resource(GlobalAmbientLight::NONE)
        .insert_resource(ClearColor(Color::NONE));
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    app
}

impl Headless {
    /// Loads the pack at `path` and waits until it is spawned, its camera drawing into a
    /// `width` × `height` image, the lights shaded as `shade_on` says, frames rendered as
    /// `rendering` says; the loader's error if it fails to load.
    pub fn open(
        path: &Path,
        (width, height): (u32, u32),
        shade_on: ShadeOn,
        rendering: Rendering,
    ) -> Result<Self, String> {
        let (Some(folder), Some(file)) = (path.parent(), path.file_name()) else {
            return Err(format!("{}: not a file", path.display()));
        };
        let mut app = windowless(folder, shade_on, rendering);
        let file = file.to_string_lossy().into_owned();
        let mut target = Image::new_target_texture(width, height, TextureFormat::Rgba32Float, None);
        target.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let target = app.world_mut().resource_mut::<Assets<Image>>().add(target);
        let handle = app.world().resource::<AssetServer>().load::<KagePack>(file);
        let scene = app
            .world_mut()
            .spawn((KageScene { pack: handle.clone(), camera: false }, Transform::default(), Visibility::default()))
            .id();
        let view = loop {
            app.update();
            if let Some(LoadState::Failed(e)) = app.world().resource::<AssetServer>().get_load_state(&handle) {
                return Err(e.to_string());
            }
            if let Some(p) = app.world().resource::<Assets<KagePack>>().get(&handle) {
                let camera =
                    p.pack.camera.as_ref().ok_or_else(|| format!("{}: the pack has no camera", path.display()))?;
                break camera_view(camera);
            }
        };
        // The pack's environment as the background, once the scene has spawned.
        while !app.world().entity(scene).contains::<crate::shade::Shading>() {
            app.update();
        }
        let skybox = app.world().entity(scene).get::<crate::KageEnvironment>().map(|e| e.skybox());
        // The camera is spawned with its target: set afterwards, it may never draw.
        let camera = app
            .world_mut()
            .spawn((
                Camera3d::default(),
                view,
                RenderTarget::Image(target.clone().into()),
                Hdr,
                Tonemapping::None,
                DebandDither::Disabled,
                Msaa::Off,
                Exposure { ev100: exposure_ev100(0.0) },
            ))
            .id();
        if let Some(s) = skybox {
            app.world_mut().entity_mut(camera).insert(s);
        }
        Ok(Self { app, target })
    }

    /// The image once every mesh is on the GPU, no pipeline is still being compiled, and
    /// three frames in a row show the same lit picture (Bevy uploads meshes and compiles their
    /// pipelines in the background: until both are done, what needs them is not drawn — the
    /// skybox may show without the meshes); `None` after `timeout`. Rows from the top, linear
    /// RGBA.
    pub fn settled(&mut self, timeout: Duration) -> Option<Vec<Vec4>> {
        let start = Instant::now();
        let (mut last, mut same) = (self.read_back()?, 0);
        while start.elapsed() < timeout {
            std::thread::sleep(Duration::from_millis(20));
            let next = self.read_back()?;
            let lit = next.iter().any(|p| p.max_element() > 0.0);
            same = if next == last && lit && self.ready() { same + 1 } else { 0 };
            if same >= 2 {
                return Some(next);
            }
            last = next;
        }
        None
    }

    /// Whether the render world holds every mesh the app draws and has no pipeline waiting
    /// to be compiled (true when rendering is pipelined: its world is on its own thread).
    fn ready(&mut self) -> bool {
        let world = self.app.world_mut();
        let meshes: Vec<AssetId<Mesh>> = world.query::<&Mesh3d>().iter(world).map(|m| m.id()).collect();
        let Some(render) = self.app.get_sub_app(RenderApp).map(|r| r.world()) else { return true };
        let uploaded = render
            .get_resource::<RenderAssets<RenderMesh>>()
            .is_some_and(|r| meshes.iter().all(|m| r.get(*m).is_some()));
        let idle = render.get_resource::<PipelineCache>().is_none_or(|c| c.waiting_pipelines().next().is_none());
        uploaded && idle
    }

    /// The image after the next frames (`None` if it is never read back).
    pub fn read_back(&mut self) -> Option<Vec<Vec4>> {
        let data: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
        let sink = data.clone();
        let reader = self
            .app
            .world_mut()
            .spawn(Readback::texture(self.target.clone()))
            .observe(move |e: On<ReadbackComplete>| {
                *sink.lock().expect("not poisoned") = Some(e.data.clone());
            })
            .id();
        let bytes = (0..1000).find_map(|_| {
            self.app.update();
            data.lock().expect("not poisoned").take()
        });
        self.app.world_mut().despawn(reader);
        let floats: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes?);
        Some(floats.chunks_exact(4).map(Vec4::from_slice).collect())
    }
}
