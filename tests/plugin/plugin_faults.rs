//! Faults in a headless app: a poisoned strand is reset alone, a teleported head carries its hair, a
//! frame hitch does not run away, invalid strands are rejected with a reason.

use std::time::Duration;

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::SimulatedStrand;
use hair_sim_support::headless::{drain_messages, hair_app, spawn_head, strand};

#[test]
fn a_strand_poisoned_with_nan_is_reset_and_reported_and_its_neighbours_are_unaffected() {
    let setup = || {
        let mut app = hair_app();
        let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 10, 12);
        app.world_mut().get_mut::<Transform>(head).unwrap().rotate_z(0.3);
        for _ in 0..30 {
            app.update();
        }
        (app, strands)
    };
    let (mut clean, strands) = setup();
    let (mut poisoned, _) = setup();
    let victim = strands[3];
    // Observed on the strand too: the fault is an event triggered on it.
    let observed: std::sync::Arc<std::sync::Mutex<Vec<Entity>>> = default();
    let seen = observed.clone();
    for &strand in &strands {
        let seen = seen.clone();
        poisoned.world_mut().entity_mut(strand).observe(move |fault: On<StrandFault>| {
            seen.lock().unwrap().push(fault.strand);
        });
    }
    poisoned.world_mut().get_mut::<SimulatedStrand>(victim).unwrap().rod_mut().positions_mut()[5] = DVec3::NAN;
    clean.update();
    poisoned.update();

    let faults = drain_messages::<StrandFault>(&mut poisoned);
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert_eq!(faults[0].strand, victim);
    assert_eq!(*observed.lock().unwrap(), [victim], "observed on the victim alone, once");
    assert_eq!(poisoned.world().resource::<HairStatistics>().faults, 1);

    // Reset to its rest pose on the (rotated) head: its spawn shape, turned and moved with the head.
    let head_world =
        GlobalTransform::from(Transform::from_xyz(0.0, 1.6, 0.0).with_rotation(Quat::from_rotation_z(0.3)));
    let spec = poisoned.world().get::<HairStrand>(victim).unwrap();
    let root = head_world.transform_point(spec.nodes[0]);
    for (node, position) in strand(&poisoned, victim).rod().positions().iter().enumerate() {
        let rest = root + head_world.rotation() * (spec.nodes[node] - spec.nodes[0]);
        assert!(position.distance(rest.as_dvec3()) < 1e-6, "node {node} at {position}, rest pose {rest}");
    }
    for &other in strands.iter().filter(|&&entity| entity != victim) {
        assert_eq!(strand(&poisoned, other).rod().positions(), strand(&clean, other).rod().positions());
    }
    for _ in 0..30 {
        poisoned.update();
    }
    assert!(drain_messages::<StrandFault>(&mut poisoned).is_empty(), "the reset strand carries on");
}

#[test]
fn a_teleported_head_carries_its_hair_along() {
    let setup = || {
        let mut app = hair_app();
        let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 50, 16);
        for _ in 0..90 {
            app.update();
        }
        (app, head, strands)
    };
    let (mut staying, _, strands) = setup();
    let (mut jumping, head, _) = setup();
    let jump = Vec3::new(100.0, 0.0, -20.0);
    jumping.world_mut().get_mut::<Transform>(head).unwrap().translation += jump;
    staying.update();
    jumping.update();

    // The teleported hair moves as if the head had stayed, shifted by the jump.
    let (mut worst_offset, mut worst_speed_change, mut worst_strain, mut fastest) =
        (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for &entity in &strands {
        let (carried, reference) = (strand(&jumping, entity).rod(), strand(&staying, entity).rod());
        for (new, old) in carried.positions().iter().zip(reference.positions()) {
            worst_offset = worst_offset.max((*new - *old - jump.as_dvec3()).length());
        }
        for (new, old) in carried.velocities().iter().zip(reference.velocities()) {
            worst_speed_change = worst_speed_change.max((*new - *old).length());
            fastest = fastest.max(new.length());
        }
        worst_strain = worst_strain.max(carried.max_strain().1);
    }
    println!(
        "after a 102 m teleport: nodes {worst_offset:e} m and velocities {worst_speed_change:e} m/s off the \
         hair that stayed (fastest node {fastest:.3} m/s), strain {worst_strain:e}"
    );
    assert!(worst_offset < 1e-6, "the hair arrives with its head");
    assert!(worst_speed_change < 1e-6, "the hair is not whipped");
    assert!(worst_strain < 1e-3, "strain {worst_strain}");
    assert_eq!(jumping.world().resource::<HairStatistics>().faults, 0);
}

#[test]
fn a_long_frame_hitch_runs_a_bounded_number_of_steps() {
    let mut app = hair_app();
    spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 10, 8);
    app.update();
    app.world_mut().resource_mut::<Time<Virtual>>().set_max_delta(Duration::from_secs(10));
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs(3)));
    let steps_before = app.world().resource::<HairStatistics>().steps;
    app.update();
    let statistics = app.world().resource::<HairStatistics>();
    let limit = app.world().resource::<HairSettings>().max_steps_per_frame;
    println!("a 3 s frame: {} steps simulated, {} skipped", statistics.steps - steps_before, statistics.skipped_steps);
    assert_eq!(statistics.steps - steps_before, u64::from(limit));
    assert!(statistics.skipped_steps >= 170, "the rest of the 180 missed steps are skipped");
    assert_eq!(statistics.faults, 0);
}

#[test]
fn invalid_strands_are_rejected_with_a_reason_and_the_rest_run() {
    let mut app = hair_app();
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let good = app.world_mut().spawn((HairStrand::straight(Vec3::Y * 0.1, Vec3::Y, 0.2, 8), StrandOf(head))).id();
    let cases = [
        (HairStrand::from_nodes([Vec3::ZERO, Vec3::X], Vec3::Y), "at least 3 nodes"),
        (HairStrand::from_nodes([Vec3::ZERO, Vec3::X, Vec3::NAN], Vec3::Y), "not finite"),
        (HairStrand::from_nodes([Vec3::ZERO, Vec3::X, Vec3::X], Vec3::Y), "edge 1 has length"),
        (
            HairStrand::straight(Vec3::ZERO, Vec3::X, 0.2, 4)
                .with_material(RodMaterial { semi_axis_1: 0.0, ..default() }),
            "semi_axis_1",
        ),
        (HairStrand::from_nodes([Vec3::ZERO, Vec3::X, 2.0 * Vec3::X], Vec3::X), "material direction"),
        (HairStrand::straight(Vec3::ZERO, Vec3::X, 0.2, 4).with_natural_curvature(Vec2::NAN), "natural curvature"),
    ];
    let rejected: Vec<(Entity, &str)> =
        cases.into_iter().map(|(spec, reason)| (app.world_mut().spawn((spec, StrandOf(head))).id(), reason)).collect();
    for _ in 0..3 {
        app.update();
    }
    for (entity, reason) in &rejected {
        let rejection = app.world().get::<StrandRejected>(*entity).expect("rejected");
        assert!(rejection.reason.contains(reason), "{entity}: {} should mention {reason}", rejection.reason);
        assert!(app.world().get::<SimulatedStrand>(*entity).is_none());
    }
    assert!(app.world().get::<SimulatedStrand>(good).is_some());
    assert_eq!(app.world().resource::<HairStatistics>().strands, 1);

    // Fixing the spawn description brings the strand to life.
    let (fixed, _) = rejected[0];
    app.world_mut().get_mut::<HairStrand>(fixed).unwrap().nodes.push(2.0 * Vec3::X);
    app.update();
    assert!(app.world().get::<StrandRejected>(fixed).is_none());
    assert!(app.world().get::<SimulatedStrand>(fixed).is_some());
}
