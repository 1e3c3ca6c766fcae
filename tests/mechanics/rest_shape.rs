//! The spawned shape is the rest shape, and rest curvature makes a rod curl into its natural arc.

use bevy::math::{DVec2, DVec3};
use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};
use hair_sim_support::{max_speed, run, stiff_rod_material, straight_nodes};
use std::f64::consts::PI;

fn helix(edges: usize) -> Vec<DVec3> {
    // Radius 1 cm, pitch 1.5 cm, two and a half turns.
    (0..=edges)
        .map(|i| {
            let angle = 5.0 * PI * i as f64 / edges as f64;
            DVec3::new(0.01 * angle.cos(), 0.01 * angle.sin(), 0.015 * angle / (2.0 * PI))
        })
        .collect()
}

#[test]
fn helix_without_gravity_stays_at_rest() {
    let no_gravity = StepParams { gravity: DVec3::ZERO, ..Default::default() };
    for (material, label) in [(RodMaterial::human_hair(), "human hair"), (stiff_rod_material(), "stiff rod")] {
        for clamped in [false, true] {
            let nodes = helix(32);
            let mut rod = Rod::new(&nodes, DVec3::Z, material).unwrap();
            if clamped {
                rod.clamp_root_in_place();
            }
            let mut workspace = RodWorkspace::default();
            run(&mut rod, &no_gravity, 600, &mut workspace);
            let drift = rod.positions().iter().zip(&nodes).map(|(p, q)| (*p - *q).length()).fold(0.0, f64::max);
            let relative = drift / rod.rest_length();
            println!("{label}, clamped {clamped}: drift {relative:e} of the length");
            assert!(relative < 1e-6, "{label}, clamped {clamped}: drifted {relative:e} of its length");
        }
    }
}

/// Tip of the analytic arc: it starts at the midpoint of the clamped edge 0 (where that edge's material
/// frame lives) along +X and curves towards `towards` with curvature `k` over the remaining length.
fn analytic_tip(length: f64, edges: usize, k: f64, towards: DVec3) -> DVec3 {
    let edge = length / edges as f64;
    let arc = length - 0.5 * edge;
    let radius = 1.0 / k;
    DVec3::new(0.5 * edge, 0.0, 0.0) + radius * (k * arc).sin() * DVec3::X + radius * (1.0 - (k * arc).cos()) * towards
}

fn curl(length: f64, edges: usize, natural: DVec2) -> Rod {
    let nodes = straight_nodes(length, edges, DVec3::X);
    let mut rod = Rod::new(&nodes, DVec3::Y, stiff_rod_material()).unwrap();
    rod.clamp_root_in_place();
    rod.set_natural_curvature(natural).unwrap();
    let params = StepParams { gravity: DVec3::ZERO, air_damping: 5.0, ..Default::default() };
    let mut workspace = RodWorkspace::default();
    run(&mut rod, &params, 900, &mut workspace);
    assert!(max_speed(&rod) < 1e-6, "settled: speed {:e} m/s", max_speed(&rod));
    rod
}

#[test]
fn rest_curvature_curls_a_straight_rod_into_its_arc() {
    let (length, edges) = (0.2, 40);
    // m1 = +Y for the first edge and m2 = t × m1 = +Z: κ₁ bends towards Y, κ₂ towards Z.
    for (natural, towards) in [
        (DVec2::new(PI / length, 0.0), DVec3::Y),
        (DVec2::new(0.0, 1.5 * PI / length), DVec3::Z),
        (DVec2::new(2.0 * PI / length, 0.0), DVec3::Y),
    ] {
        let rod = curl(length, edges, natural);
        let tip = rod.positions()[edges];
        let expected = analytic_tip(length, edges, natural.length(), towards);
        let miss = (tip - expected).length() / length;
        println!("κ̄ = {natural}: tip {tip}, arc {expected}, miss {:.4} % of L", 100.0 * miss);
        assert!(miss < 0.01, "κ̄ = {natural}: tip misses the arc by {:.3} % of L", 100.0 * miss);
        assert!(rod.max_strain().1 < 1e-5);
    }
}

#[test]
fn full_turn_of_rest_curvature_closes_a_circle() {
    let (length, edges) = (0.2, 40);
    let rod = curl(length, edges, DVec2::new(2.0 * PI / length, 0.0));
    // The circle closes: the tip comes back to the root, within one edge length.
    let gap = (rod.positions()[edges] - rod.positions()[0]).length();
    assert!(gap < length / edges as f64, "gap {gap:e} m");
    // Every node lies on the circle of radius L/2π centred above the clamped edge's midpoint.
    let centre = DVec3::new(0.5 * length / edges as f64, length / (2.0 * PI), 0.0);
    for p in rod.positions().iter().skip(1) {
        let off = ((*p - centre).length() - length / (2.0 * PI)).abs();
        assert!(off < 0.002 * length, "node {p} off the circle by {off:e} m");
    }
}
