//! Packs as Bevy assets: the loader reads and checks a pack with `kage-runtime` and decodes
//! its textures into labeled images; spawning ([`crate::spawn`]) builds the meshes and
//! materials.

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext, RenderAssetUsages};
use bevy::image::{CompressedImageFormats, ImageAddressMode, ImageSampler, ImageSamplerDescriptor, ImageType};
use bevy::prelude::*;
use kage_runtime::pack::{Pack, schema};
use kage_runtime::texture::Wrap;
use std::sync::Arc;

/// A pack read and checked, with its textures as images.
#[derive(Asset, TypePath)]
pub struct KagePack {
    /// The pack's contents.
    pub pack: Arc<Pack>,
    /// Per core glTF texture: the image decoded as colour (sRGB) and as data (linear), each
    /// when some material reads it so.
    pub images: Vec<[Option<Handle<Image>>; 2]>,
}

/// Reads packs. A pack is a `.glb`, loaded as `KagePack` (`asset_server.load::<KagePack>(path)`):
/// the requested type picks this loader. Its own extension is only `kage.glb`, so untyped and
/// labeled loads of `*.glb` files (`model.glb#Scene0`) keep reaching Bevy's glTF loader.
#[derive(Default, TypePath)]
pub struct KagePackLoader;

/// Why a pack did not load.
#[derive(Debug)]
pub struct PackError(String);

impl std::fmt::Display for PackError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PackError {}

impl AssetLoader for KagePackLoader {
    type Asset = KagePack;
    type Settings = ();
    type Error = PackError;

    async fn load(&self, reader: &mut dyn Reader, _: &(), cx: &mut LoadContext<'_>) -> Result<KagePack, PackError> {
        let path = cx.path().to_string();
        let mut bytes = Vec::new();
        reader.read_to_end(&mut bytes).await.map_err(|e| PackError(format!("{path}: {e}")))?;
        let pack = Pack::read(&bytes).map_err(|e| PackError(format!("{path}: not a kage pack: {e}")))?;
        for w in &pack.warnings {
            warn!("{path}: {w}");
        }
        let images = decode_images(&pack, cx).map_err(|e| PackError(format!("{path}: {e}")))?;
        Ok(KagePack { pack: Arc::new(pack), images })
    }

    fn extensions(&self) -> &[&str] {
        &["kage.glb"]
    }
}

/// Each core texture a material reads, decoded once per colour space (sRGB base colours,
/// linear metallic-roughness) as a labeled image.
fn decode_images(pack: &Pack, cx: &mut LoadContext<'_>) -> Result<Vec<[Option<Handle<Image>>; 2]>, String> {
    let mut images = vec![[None, None]; pack.textures.len()];
    for m in pack.instances.iter().map(|i| &i.material) {
        let slots = [(&m.base_color_texture, 0), (&m.metallic_roughness_texture, 1)];
        for (slot, space) in slots.into_iter().filter_map(|(s, k)| s.as_ref().map(|s| (s, k))) {
            let t = slot.index as usize;
            if images.get(t).is_some_and(|i: &[Option<_>; 2]| i[space].is_none()) {
                let image = decode(pack, slot, space == 0)?;
                images[t][space] = Some(cx.add_labeled_asset(format!("texture{t}/{space}"), image));
            }
        }
    }
    Ok(images)
}

/// The image of texture slot `s`, with its wrap modes.
fn decode(pack: &Pack, s: &schema::TextureSlot, srgb: bool) -> Result<Image, String> {
    let t = pack.textures.get(s.index as usize).ok_or_else(|| format!("no texture {}", s.index))?;
    let address = |w: Wrap| match w {
        Wrap::Clamp => ImageAddressMode::ClampToEdge,
        Wrap::Mirror => ImageAddressMode::MirrorRepeat,
        Wrap::Repeat => ImageAddressMode::Repeat,
    };
    let sampler = ImageSampler::Descriptor(ImageSamplerDescriptor {
        address_mode_u: address(t.wrap[0]),
        address_mode_v: address(t.wrap[1]),
        ..ImageSamplerDescriptor::linear()
    });
    Image::from_buffer(
        &t.image,
        ImageType::MimeType(&t.mime_type),
        CompressedImageFormats::NONE,
        srgb,
        sampler,
        RenderAssetUsages::RENDER_WORLD,
    )
    .map_err(|e| format!("texture {}: {e}", s.index))
}
