//! Materials as glTF defines them: base-colour (sRGB) and metallic-roughness textures, vertex
//! colours, `TEXCOORD_1` and `KHR_texture_transform` — imported, applied per pixel by the baked
//! look and per point by the reference, and kept by packs. The scene is
//! `assets/scenes/textured_materials.gltf` (`scripts/make_textured_materials.py`).

use glam::{Vec2, Vec3};
use kage_engine::math::relative_rmse;
use kage_engine::raster;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::FlatScene;
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{EnvMap, EnvironmentLight, MaterialMaps, Scene, flatten};
use kage_tests::{asset, with_baked_look};

fn scene() -> Scene {
    let s = import(&asset("scenes/textured_materials.gltf"), ImportOptions::default()).unwrap();
    s.with_environment(EnvironmentLight::new(EnvMap::load(&asset("envmaps/city.hdr")).unwrap()))
}

fn instance(flat: &FlatScene, name: &str, scene: &Scene) -> usize {
    let node = scene
        .world
        .query::<(&kage_engine::scene::Name, &kage_engine::scene::PrimitiveId)>()
        .iter()
        .find(|(n, _)| n.0 == name)
        .map(|(_, id)| *id)
        .unwrap_or_else(|| panic!("no node {name}"));
    flat.instances.iter().position(|i| i.id == node).unwrap()
}

#[test]
fn textures_colours_and_uv_sets_are_imported() {
    let s = scene();
    let flat = flatten(&s);
    // The floor's checker is sRGB: byte 200 decodes to 0.578.
    let floor = &flat.instances[instance(&flat, "floor", &s)];
    let checker = &flat.textures[floor.maps.base_color.unwrap().texture as usize];
    assert!((checker.texels[0].x - 0.577_580_5).abs() < 1e-6, "{:?}", checker.texels[0]);
    // The sphere's metallic-roughness texture is linear data: byte 70 is 70/255.
    let sphere = instance(&flat, "sphere", &s);
    let mr = flat.instances[sphere].maps.metallic_roughness.unwrap();
    assert_eq!(flat.textures[mr.texture as usize].texels[0], Vec3::new(0.0, 70.0 / 255.0, 1.0));
    // A vertex inside a metal band (v = 1/12) and one inside a rough dielectric band (v = 1/3).
    let at = |v: f32| {
        let k = flat.mesh(sphere).uvs.iter().position(|uv| (uv.y - v).abs() < 1e-6 && uv.x > 0.1).unwrap();
        flat.vertex_material(sphere, k)
    };
    let (metal, rough) = (at(1.0 / 12.0), at(1.0 / 3.0));
    assert_eq!((metal.metallic, metal.roughness), (1.0, 70.0 / 255.0));
    assert_eq!((rough.metallic, rough.roughness), (0.0, 200.0 / 255.0));
    assert_eq!(metal.base_color, Vec3::new(1.0, 0.78, 0.34), "the factor stays");
    // The box's faces carry vertex colours; the poster reads TEXCOORD_1 through a transform.
    let cube = instance(&flat, "box", &s);
    assert_eq!(flat.mesh(cube).colors.len(), 24);
    assert_eq!(flat.vertex_material(cube, 0).base_color, Vec3::new(0.9, 0.2, 0.15));
    let poster = flat.instances[instance(&flat, "poster", &s)].maps.base_color.unwrap();
    assert_eq!(poster.texcoord, 1);
    assert!((poster.uv(Vec2::ZERO, Vec2::ZERO) - Vec2::new(0.5, 0.0)).length() < 1e-6, "offset");
    assert!((poster.transform.matrix2.x_axis.length() - 2.0).abs() < 1e-5, "scale");
}

/// The baked look's direct light against the reference's, per pixel over geometry, on the
/// textured scene under `city.hdr` and its quad light (160×90, reference at 256 spp). The floor
/// is refined to 2,000 vertices so that the lights' shadows on it resolve (receiver refinement
/// is its own matter); the checker (32² texels, 16 per tile) still varies inside its triangles.
/// Measured: 5.4 % with the materials per pixel; 46 % with the same look's per-vertex values
/// interpolated (materials per vertex: the poster has 4 vertices); 120 % with the textures
/// left out of the look.
#[test]
fn the_baked_look_applies_materials_per_pixel_like_the_reference() {
    let mut s = scene();
    s.refine_instances("floor", 2000).unwrap();
    let renderer = Renderer::new(&s);
    let camera = s.first_camera().unwrap();
    let (w, h) = (160, 90);
    let settings = Settings { spp: 256, seed: 3, max_bounces: 0, min_bounces: 0 };
    let truth: Vec<Vec3> = renderer.render_image(&camera, w, h, &settings, &|_| {}).iter().map(|e| e.mean).collect();
    let hits = raster::shade_image(&renderer, &camera, w, h, 4, &|_| Vec3::ONE);
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&hits).filter(|(_, m)| **m == Vec3::ONE).map(|(p, _)| *p).collect() };
    // (per pixel, per vertex) relative RMSE of the look of `scene`.
    let errors = |scene: &Scene| {
        with_baked_look(scene, camera.eye(), |look, _| {
            let r = Renderer::new(scene);
            let per_vertex = raster::vertex_image(&r, &camera, w, h, 4, &look.vertex_values());
            (
                relative_rmse(&pick(&look.render(&r, &camera, w, h, 4)), &pick(&truth)),
                relative_rmse(&pick(&per_vertex), &pick(&truth)),
            )
        })
    };
    let (per_pixel, per_vertex) = errors(&s);
    let mut plain = s.duplicate();
    let maps: Vec<hecs::Entity> = plain.world.query::<(hecs::Entity, &MaterialMaps)>().iter().map(|(e, _)| e).collect();
    maps.into_iter().for_each(|e| _ = plain.world.remove_one::<MaterialMaps>(e));
    let (untextured, _) = errors(&plain);
    assert!(per_pixel < 0.07, "baked against the reference per pixel: {per_pixel:.4}");
    assert!(per_vertex > 3.0 * per_pixel, "materials per vertex: {per_vertex:.4}, per pixel: {per_pixel:.4}");
    assert!(untextured > 10.0 * per_pixel, "textures ignored: {untextured:.4}, applied: {per_pixel:.4}");
}

/// PRT's images (`kage render --method prt`) take the material per sample too: the floor's
/// checker stays sharp between the floor's vertices. The environment alone (the quad light
/// removed, the materials' specular layers off, so that the reference's direct light is PRT's
/// diffuse term) over the floor's pixels (160×90, reference at 256 spp). Measured: 14.2 % per
/// sample (the rest is order 4's shadows and the reference's noise), 49 % with PRT's values
/// interpolated from the vertices, as its images were before.
#[test]
fn prt_images_apply_materials_per_pixel() {
    use kage_engine::prt;
    let mut s = scene();
    s.remove_polygon_lights();
    // No specular layer: the reference's light is then PRT's diffuse term alone.
    s.world.query_mut::<&mut kage_engine::scene::Material>().into_iter().for_each(|m| m.specular = 0.0);
    let renderer = Renderer::new(&s);
    let camera = s.first_camera().unwrap();
    let (w, h) = (160, 90);
    let settings = Settings { spp: 256, seed: 3, max_bounces: 0, min_bounces: 0 };
    let truth: Vec<Vec3> = renderer.render_image(&camera, w, h, &settings, &|_| {}).iter().map(|e| e.mean).collect();
    let floor = instance(&renderer.flat, "floor", &s);
    let on_floor =
        raster::shade_image(&renderer, &camera, w, h, 4, &|hit| Vec3::splat(f32::from(hit.instance == floor)));
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&on_floor).filter(|(_, m)| m.x == 1.0).map(|(p, _)| *p).collect() };
    let ps = prt::Settings { order: 4, regions: 16, ..prt::Settings::default() };
    let bake = prt::bake(&s, &renderer.flat, &ps, &|_| {});
    let lighting = prt::Lighting::new(&s, &ps).expect("the scene has an environment");
    let parts = prt::Parts { bake: &bake, lighting: &lighting, settings: &ps };
    let frame = prt::Frame::prepare(&s, &renderer.flat, parts, prt::Shadows::WithOthers, camera.eye());
    let per_sample = relative_rmse(&pick(&frame.render(&renderer, &camera, w, h, 4)), &pick(&truth));
    let values = frame.vertex_values(&renderer.flat);
    let per_vertex = relative_rmse(&pick(&raster::vertex_image(&renderer, &camera, w, h, 4, &values)), &pick(&truth));
    assert!(per_sample < 0.17, "PRT against the reference on the floor: {per_sample:.4}");
    assert!(per_vertex > 3.0 * per_sample, "materials per vertex: {per_vertex:.4}, per sample: {per_sample:.4}");
}

/// The radiance cache leaves to direct gathering a receiver whose roughness texture makes it
/// smoother than the cache serves anywhere (the banded sphere: factor 1, metal bands 0.27).
#[test]
fn a_roughness_texture_decides_where_the_cache_falls_back() {
    let s = scene();
    let r = Renderer::new(&s);
    let settings = kage_engine::cache::Settings::default();
    let sphere = instance(&r.flat, "sphere", &s);
    assert!(kage_engine::cache::falls_back(&r, &settings, sphere), "its metal bands are smooth");
    let mut plain = s.duplicate();
    let maps: Vec<hecs::Entity> = plain.world.query::<(hecs::Entity, &MaterialMaps)>().iter().map(|(e, _)| e).collect();
    maps.into_iter().for_each(|e| _ = plain.world.remove_one::<MaterialMaps>(e));
    let r = Renderer::new(&plain);
    assert!(!kage_engine::cache::falls_back(&r, &settings, sphere), "roughness 1 alone is served by the cache");
}
