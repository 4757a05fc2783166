//! Same seed → bit-identical results on 1 and 2 threads; a different seed differs.

use glam::Vec3;
use kage_engine::reference::{Estimate, Renderer, Settings};
use kage_engine::scene::default_scene;

fn bits(e: &[Estimate]) -> Vec<u32> {
    e.iter().flat_map(|e| e.mean.to_array().into_iter().chain(e.std_error.to_array())).map(f32::to_bits).collect()
}

fn render(threads: usize, seed: u64) -> (Vec<u32>, Vec<u32>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let scene = default_scene();
        let r = Renderer::new(&scene);
        let s = Settings { spp: 4, seed, max_bounces: 1, min_bounces: 0 };
        let cam = scene.first_camera().unwrap();
        let img = r.render_image(&cam, 48, 27, &s, &|_| {});
        let verts: Vec<Estimate> = r.render_vertices(Vec3::new(0.0, 4.0, 8.0), &s, &|_| {}).concat();
        (bits(&img), bits(&verts))
    })
}

#[test]
fn renders_are_bit_identical_across_thread_counts() {
    let one = render(1, 7);
    let two = render(2, 7);
    assert!(one == two, "1 thread and 2 threads differ");
    let other = render(2, 8);
    assert!(one.0 != other.0 && one.1 != other.1, "the seed matters");
}
