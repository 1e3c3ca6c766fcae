//! Pure twist of a rod clamped at both ends, against `E = GJ Φ² / (2 L′)`.

use bevy::math::{DQuat, DVec3};
use bevy_hair_sim::rod::{Rod, RodWorkspace, StepParams};
use hair_sim_support::{run, stiff_rod_material, straight_nodes};
use std::f64::consts::PI;

/// A straight rod along X clamped at both ends, its last edge turned about X by `angle` in `increments`
/// equal steps (one per time step), then left to settle. Returns the rod.
fn twisted(length: f64, edges: usize, angle: f64, increments: usize) -> Rod {
    let nodes = straight_nodes(length, edges, DVec3::X);
    let mut rod = Rod::new(&nodes, DVec3::Y, stiff_rod_material()).unwrap();
    rod.clamp_root_in_place();
    let params = StepParams { gravity: DVec3::ZERO, ..Default::default() };
    let mut workspace = RodWorkspace::default();
    let last = edges - 1;
    for increment in 1..=increments {
        let turn = DQuat::from_rotation_x(angle * increment as f64 / increments as f64);
        rod.clamp_edge(last, nodes[last], nodes[edges], turn * DVec3::Y).unwrap();
        run(&mut rod, &params, 1, &mut workspace);
    }
    run(&mut rod, &params, 120, &mut workspace);
    rod
}

#[test]
fn twist_energy_matches_gj_phi_squared_over_two_l() {
    let (length, edges) = (0.2, 20);
    // L′ runs between the midpoints of the two clamped edges.
    let free_length = length - length / edges as f64;
    let twisting = stiff_rod_material().stiffness().twisting;
    for (angle, increments) in [(PI / 2.0, 1), (-PI / 3.0, 1), (2.0 * PI, 16), (3.0 * PI, 24)] {
        let rod = twisted(length, edges, angle, increments);
        let energy = rod.elastic_energy();
        let expected = twisting * angle * angle / (2.0 * free_length);
        let error = energy.twisting / expected - 1.0;
        println!(
            "Φ = {angle:.4}: E_twist = {:.6e} J, GJΦ²/2L′ = {expected:.6e} J, {:+.4} %",
            energy.twisting,
            100.0 * error
        );
        assert!(error.abs() < 0.01, "Φ = {angle}: twist energy off by {:.3} %", 100.0 * error);
        assert!(energy.bending < 1e-6 * energy.twisting, "the rod stays straight");
        // The twist is uniform: every vertex carries Φ/(N−1).
        for vertex in 1..edges {
            let (_, tau) = rod.vertex_curvature_and_twist(vertex);
            assert!((tau - angle / (edges - 1) as f64).abs() < 1e-3 * angle.abs(), "vertex {vertex}: τ = {tau}");
        }
    }
}
