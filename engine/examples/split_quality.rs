//! The split search's speed against the quality of the subtrees it builds: bakes a scene once
//! (every receiver vertex, 64² faces, default ε) to collect its distinct mixed tiles (one per
//! symmetry orbit), then builds each again from scratch on one thread and prints the time per
//! tile, the leaves per tile and the within-leaf error Σ w (V − v̄)² per tile (in texels), with
//! a hash of the subtrees (equal hashes: the same trees).
//!
//! `cargo run --release -p kage-engine --example split_quality -- [SCENE.gltf | default] [PASSES]`
//! (PASSES builds of the corpus, the last one timed; 1 by default).

use kage_engine::bspvt::memo::SubtreeMemo;
use kage_engine::bspvt::node::{Node, TILE, TileKey};
use kage_engine::bspvt::tree::{build_tile, leaf_index};
use kage_engine::bspvt::{Settings, bake_vertex, occluder_bvh, reach::Reach};
use kage_engine::math::cubemap;
use kage_engine::scene::{Scene, default_scene, flatten, import};
use rayon::prelude::*;
use std::hash::{Hash, Hasher};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene = match args.next() {
        Some(path) if path != "default" => import::import(path.as_ref(), Default::default())?,
        _ => default_scene(),
    };
    let passes: usize = args.next().map(|p| p.parse()).transpose()?.unwrap_or(1).max(1);
    let tiles = corpus(&scene);
    let keys = tiles.keys();
    for _ in 1..passes {
        std::hint::black_box(keys.iter().map(|&key| build_tile(key, &tiles).len()).sum::<usize>());
    }
    let start = std::time::Instant::now();
    let built: Vec<Vec<Node>> = keys.iter().map(|&key| build_tile(key, &tiles)).collect();
    let us = start.elapsed().as_secs_f64() * 1e6 / keys.len() as f64;
    let leaves: usize = built.iter().map(|nodes| nodes.iter().filter(|n| matches!(n, Node::Leaf(_))).count()).sum();
    let error: f64 = keys.iter().zip(&built).map(|(&key, nodes)| within_leaf_error(key, nodes, &tiles)).sum();
    let mut hash = std::collections::hash_map::DefaultHasher::new();
    format!("{built:?}").hash(&mut hash);
    let n = keys.len() as f64;
    println!(
        "{} tiles: {us:.2} µs/tile, {:.4} leaves/tile, {:.4} error/tile, trees {:016x}",
        keys.len(),
        leaves as f64 / n,
        error / n,
        hash.finish()
    );
    Ok(())
}

/// The subtree memo a bake of every receiver vertex of `scene` fills.
fn corpus(scene: &Scene) -> SubtreeMemo {
    let flat = flatten(scene);
    let occluders = occluder_bvh(&flat);
    let (tiles, reach) = (SubtreeMemo::new(&Settings::default()), Reach::of_scene(&flat));
    let vertices: Vec<(usize, usize)> = flat.vertex_ids().collect();
    vertices.par_iter().for_each(|&(i, v)| {
        let (p, n) = flat.vertex(i, v);
        bake_vertex(&occluders, p, n, &tiles, &reach);
    });
    tiles
}

/// Σ w (V − v̄)² over the leaves of tile `key`'s subtree `nodes`.
fn within_leaf_error((index, live, visible): TileKey, nodes: &[Node], tiles: &SubtreeMemo) -> f64 {
    let res = tiles.settings().res;
    let k = res.div_ceil(TILE);
    let (i0, j0) = (index as usize % k * TILE, index as usize / k * TILE);
    let mut sums = std::collections::HashMap::<usize, (f64, f64)>::new();
    for b in (0..64).filter(|b| live >> b & 1 == 1) {
        let (i, j) = (i0 + b % TILE, j0 + b / TILE);
        let st = cubemap::texel_center(i, j, res);
        let (w, v) = (tiles.weight(i, j), (visible >> b & 1) as f64);
        let leaf = sums.entry(leaf_index(nodes, st.x, st.y)).or_default();
        *leaf = (leaf.0 + w, leaf.1 + w * v);
    }
    sums.values().map(|(w, wv)| wv - wv * wv / w).sum()
}
