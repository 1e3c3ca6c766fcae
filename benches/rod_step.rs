//! Cost of one time step of one strand: `cargo bench --bench rod_step`.
//!
//! A 25 cm human hair (radius 40 µm, E = 3.5 GPa, ρ = 1300 kg/m³), root clamped, dt = 1/60 s, in three
//! regimes: hanging still, swinging down after release from horizontal, and root shaken and spun hard.

use bevy::math::{DQuat, DVec3};
use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};
use divan::Bencher;
use std::f64::consts::PI;

fn main() {
    divan::main();
}

fn horizontal_hair(edges: usize) -> Rod {
    let nodes: Vec<DVec3> = (0..=edges).map(|i| DVec3::new(0.1 + 0.25 * i as f64 / edges as f64, 0.0, 0.0)).collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).expect("valid strand");
    rod.clamp_root_in_place();
    rod
}

#[divan::bench(args = [16, 32, 64])]
fn hanging_still(bencher: Bencher, edges: usize) {
    let params = StepParams::default();
    let mut rod = horizontal_hair(edges);
    let mut workspace = RodWorkspace::default();
    for _ in 0..1200 {
        rod.step(&params, None, &mut workspace).expect("settles");
    }
    bencher.bench_local(|| rod.step(&params, None, &mut workspace).expect("step"));
}

#[divan::bench(args = [32])]
fn swinging_after_release(bencher: Bencher, edges: usize) {
    let params = StepParams::default();
    let start = horizontal_hair(edges);
    let mut workspace = RodWorkspace::default();
    bencher.with_inputs(|| start.clone()).bench_local_refs(|rod| {
        for _ in 0..30 {
            rod.step(&params, None, &mut workspace).expect("step");
        }
    });
}

#[divan::bench(args = [32])]
fn shaken_and_spun(bencher: Bencher, edges: usize) {
    let params = StepParams::default();
    let mut rod = horizontal_hair(edges);
    let clamp = [rod.positions()[0], rod.positions()[1]];
    let mut workspace = RodWorkspace::default();
    let mut step = 0u32;
    bencher.bench_local(|| {
        step += 1;
        let t = f64::from(step) * params.dt;
        let (turn, shift) = (DQuat::from_rotation_y(4.0 * PI * t), DVec3::new(0.1 * (6.0 * PI * t).sin(), 0.0, 0.0));
        rod.clamp_edge(0, turn * clamp[0] + shift, turn * clamp[1] + shift, turn * DVec3::Y).expect("clamp");
        rod.step(&params, None, &mut workspace).expect("step")
    });
}
