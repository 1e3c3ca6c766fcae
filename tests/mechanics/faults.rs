//! Bad input and divergence: reported, never a panic, never NaN, and the rod recovers.

use bevy::math::DVec3;
use bevy_hair_sim::rod::{RodError, RodWorkspace, StepError, StepParams};
use hair_sim_support::hanging_hair;

#[test]
fn non_finite_forces_are_rejected_and_change_nothing() {
    let mut rod = hanging_hair();
    let before = rod.positions().to_vec();
    let mut forces = vec![DVec3::ZERO; rod.node_count()];
    forces[7] = DVec3::new(0.0, f64::NAN, 0.0);
    let error = rod.step(&StepParams::default(), Some(&forces), &mut RodWorkspace::default()).unwrap_err();
    assert!(matches!(error, StepError::InvalidInput(RodError::NonFiniteForce { node: 7, .. })), "{error}");
    assert!(error.to_string().contains("node 7"), "{error}");
    assert_eq!(rod.positions(), &before[..]);
}

#[test]
fn a_diverging_step_is_reported_rolled_back_and_the_rod_goes_on() {
    let mut rod = hanging_hair();
    let mut workspace = RodWorkspace::default();
    let params = StepParams::default();
    for _ in 0..30 {
        rod.step(&params, None, &mut workspace).unwrap();
    }
    let before = rod.positions().to_vec();
    // A finite force so large that the arithmetic overflows: the step must notice and roll back.
    let mut forces = vec![DVec3::ZERO; rod.node_count()];
    forces[10] = DVec3::new(f64::MAX, 0.0, 0.0);
    let error = rod.step(&params, Some(&forces), &mut workspace).unwrap_err();
    assert!(!matches!(error, StepError::InvalidInput(_)), "a finite force is valid input: {error}");
    assert_eq!(rod.positions(), &before[..], "rolled back to the last good state");
    assert!(rod.velocities().iter().all(|v| *v == DVec3::ZERO), "at rest");
    for _ in 0..60 {
        rod.step(&params, None, &mut workspace).expect("normal steps go on");
    }
    assert!(rod.positions().iter().all(|p| p.is_finite()));
    assert!(rod.max_strain().1 < 1e-5);
}

#[test]
fn even_a_hundred_kilonewtons_does_not_tear_a_hair_apart_in_one_step() {
    // EA of a hair is 17.6 N. The trust region limits how far one step moves, so the step stays
    // bounded rather than diverging.
    let mut rod = hanging_hair();
    let mut forces = vec![DVec3::ZERO; rod.node_count()];
    forces[10] = DVec3::new(1e5, 0.0, 0.0);
    let report = rod.step(&StepParams::default(), Some(&forces), &mut RodWorkspace::default()).unwrap();
    assert!(report.max_strain <= StepParams::default().strain_bound());
    assert!(rod.positions().iter().all(|p| p.is_finite()));
}

#[test]
fn reset_returns_the_spawned_shape_at_rest() {
    let mut rod = hanging_hair();
    let spawned = rod.positions().to_vec();
    let mut workspace = RodWorkspace::default();
    let forces = vec![DVec3::new(1e-6, 0.0, 0.0); rod.node_count()];
    for _ in 0..20 {
        rod.step(&StepParams::default(), Some(&forces), &mut workspace).unwrap();
    }
    assert!(rod.positions()[16].x > 1e-3, "the wind moved it");
    rod.reset();
    assert_eq!(rod.positions(), &spawned[..]);
    assert!(rod.elastic_energy().total() < 1e-20 && rod.kinetic_energy() == 0.0);
}
