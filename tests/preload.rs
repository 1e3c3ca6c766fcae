//! Gravity preloading in the mechanics core: a groomed strand keeps its shape under gravity, half a
//! preload sags half-way, and the hair still responds physically when gravity turns.

mod common;

use bevy::math::DVec3;
use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};
use common::run;

/// A 12 cm human hair in 16 edges, clamped at the root: leaving the root sideways (+x), then curving
/// down and forwards along a quarter circle of radius 8 cm.
fn groomed_hair() -> Rod {
    let nodes: Vec<DVec3> = (0..=16)
        .map(|node| {
            let angle = std::f64::consts::FRAC_PI_2 * node as f64 / 16.0;
            DVec3::new(0.08 * angle.sin(), 0.08 * (angle.cos() - 1.0), 0.02 * angle)
        })
        .collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    rod
}

/// Largest distance of a node from where it was groomed after `seconds` under `params`, m.
fn drift(rod: &mut Rod, params: &StepParams, seconds: f64) -> f64 {
    let groomed = rod.positions().to_vec();
    let mut workspace = RodWorkspace::default();
    run(rod, params, (seconds / params.dt).round() as usize, &mut workspace);
    rod.positions().iter().zip(&groomed).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max)
}

#[test]
fn a_preloaded_strand_keeps_its_groomed_shape_and_half_a_preload_sags_half_way() {
    let params = StepParams { dt: 1.0 / 60.0, ..StepParams::default() };
    let supported = vec![None; 17];
    let sag = drift(&mut groomed_hair(), &params, 3.0);

    let mut half = groomed_hair();
    half.preload_for_gravity(params.gravity, &supported, 0.5).unwrap();
    let half_sag = drift(&mut half, &params, 3.0);

    let mut full = groomed_hair();
    let report = full.preload_for_gravity(params.gravity, &supported, 1.0).unwrap();
    let full_sag = drift(&mut full, &params, 3.0);
    println!(
        "largest drift after 3 s: {sag:.4} m without preload, {half_sag:.4} m at 0.5, {full_sag:.2e} m at 1 ({report:?})"
    );

    assert!(sag > 0.02, "without preload the hair sags: {sag} m");
    assert!(full_sag < 1e-4, "preloaded, it holds its shape within 0.1 mm: {full_sag} m");
    assert!(half_sag > 0.2 * sag && half_sag < 0.8 * sag, "half a preload sags part of the way: {half_sag} m");
    assert_eq!(report.bounded_vertices, 0);
}

#[test]
fn a_preloaded_strand_falls_when_gravity_turns_upside_down() {
    let params = StepParams { dt: 1.0 / 60.0, ..StepParams::default() };
    let mut rod = groomed_hair();
    rod.preload_for_gravity(params.gravity, &vec![None; 17], 1.0).unwrap();
    let upside_down = StepParams { gravity: -params.gravity, ..params };
    let moved = drift(&mut rod, &upside_down, 2.0);
    println!("with gravity reversed the preloaded hair moves {moved:.3} m");
    assert!(moved > 0.02, "the rest shape holds the groom only against the gravity it was made for: {moved} m");
}

#[test]
fn a_strand_held_out_too_far_is_bounded_and_sags() {
    // 40 cm held straight out sideways: the root would need rest curls tighter than its edges.
    let nodes: Vec<DVec3> = (0..=16).map(|node| DVec3::new(0.025 * node as f64, 0.0, 0.0)).collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    let params = StepParams { dt: 1.0 / 60.0, ..StepParams::default() };
    let report = rod.preload_for_gravity(params.gravity, &vec![None; 17], 1.0).unwrap();
    println!("{report:?}");
    assert!(report.bounded_vertices > 0);
    let limit = 2.0 * (0.5 * bevy_hair_sim::rod::MAX_PRELOAD_TURN).tan();
    assert!(rod.rest_curvatures().iter().all(|k| k.length() <= limit + 1e-12));
    let sag = drift(&mut rod, &params, 3.0);
    assert!(sag > 0.01 && sag.is_finite(), "it sags to where the bounded rest shape holds it: {sag} m");
}
