//! Small-deflection cantilever under its own weight against Euler–Bernoulli theory.

use bevy::math::DVec3;
use bevy_hair_sim::rod::{Rod, RodWorkspace, StepParams};
use hair_sim_support::{max_speed, run, stiff_rod_material, straight_nodes};

const LENGTH: f64 = 0.2;

/// Euler–Bernoulli tip deflection `δ = q L⁴ / (8 EI)`, m.
fn analytic_deflection() -> f64 {
    let stiffness = stiff_rod_material().stiffness();
    let load = stiffness.linear_density * 9.81;
    load * LENGTH.powi(4) / (8.0 * stiffness.bending_1)
}

/// Static tip deflection of a DER cantilever with `edges` edges, first edge clamped horizontal.
fn settled_deflection(edges: usize) -> f64 {
    let nodes = straight_nodes(LENGTH, edges, DVec3::X);
    let mut rod = Rod::new(&nodes, DVec3::Y, stiff_rod_material()).unwrap();
    rod.clamp_root_in_place();
    let params = StepParams { dt: 1.0 / 60.0, air_damping: 5.0, ..Default::default() };
    let mut workspace = RodWorkspace::default();
    run(&mut rod, &params, 600, &mut workspace);
    assert!(max_speed(&rod) < 1e-7, "settled: speed {:e} m/s", max_speed(&rod));
    -rod.positions()[edges].y
}

#[test]
fn tip_deflection_matches_der_convergence_and_extrapolates_to_euler_bernoulli() {
    let delta = analytic_deflection();
    assert!((delta - 7.848e-4).abs() < 1e-7, "δ = {delta:e} m");
    let mut measured = Vec::new();
    for (edges, expected_percent) in [(10, -19.0), (20, -9.75), (50, -3.96)] {
        let deflection = settled_deflection(edges);
        let error_percent = 100.0 * (deflection / delta - 1.0);
        println!("{edges} edges: δ = {deflection:.6e} m, {error_percent:+.3} % of Euler–Bernoulli");
        assert!(
            (error_percent - expected_percent).abs() < 0.5,
            "{edges} edges: {error_percent:.3} %, expected {expected_percent} % ± 0.5"
        );
        measured.push((edges as f64, deflection));
    }
    // The error is first order in 1/N: δ_N ≈ δ (1 + c/N), so δ ≈ (N₂ δ_N₂ − N₁ δ_N₁) / (N₂ − N₁).
    let (n1, d1) = measured[1];
    let (n2, d2) = measured[2];
    let extrapolated = (n2 * d2 - n1 * d1) / (n2 - n1);
    let error = extrapolated / delta - 1.0;
    println!("extrapolated from 20 and 50 edges: {extrapolated:.6e} m, {:+.3} %", 100.0 * error);
    assert!(error.abs() < 0.005, "extrapolation misses δ by {:.3} %", 100.0 * error);
}
