//! One fixed step of the whole plugin: `cargo bench --bench hair_step`.
//!
//! The scene of `support/src/bench_scene.rs` (25 cm human hairs on a swaying, turning head, gravity on,
//! dt = 1/60 s, one compute thread per core), after the hair has fallen and started to swing. The table
//! of all sizes, the parallel efficiency and the memory per node: `cargo run --release --example benchmark`.

use divan::Bencher;
use hair_sim_support::bench_scene::Scene;

fn main() {
    divan::main();
}

/// Strands on the head, 32 edges each.
#[divan::bench(args = [100, 1000, 2000])]
fn strands_of_32_edges(bencher: Bencher, strands: usize) {
    let mut scene = Scene::new(strands, 32, None);
    scene.warm_up();
    bencher.counter(divan::counter::ItemsCount::new(strands * 33)).bench_local(|| scene.step());
}

/// Edges per strand, 1 000 strands.
#[divan::bench(args = [16, 64])]
fn edges_of_1000_strands(bencher: Bencher, edges: usize) {
    let mut scene = Scene::new(1000, edges, None);
    scene.warm_up();
    bencher.counter(divan::counter::ItemsCount::new(1000 * (edges + 1))).bench_local(|| scene.step());
}

/// 2 000 strands of 32 edges resting on 5 colliders (skull, face, neck, shoulders, torso).
#[divan::bench]
fn strands_on_5_colliders(bencher: Bencher) {
    let mut scene = Scene::new(2000, 32, None).with_colliders(5);
    scene.warm_up();
    bencher.counter(divan::counter::ItemsCount::new(2000_usize * 33)).bench_local(|| scene.step());
}
