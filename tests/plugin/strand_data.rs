//! Strand data as components: nodes, frames and rest shape read through queries, the rest shape edited
//! through a query and picked up by the next steps, and a strand saved and restored bit for bit.

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{RodError, RodSnapshot};
use hair_sim_support::headless::{hair_app, spawn_head, strand};

/// A head at the origin with one straight 10 cm strand of 10 edges along +x, in zero gravity.
fn weightless_strand() -> (App, Entity) {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let spec = HairStrand::straight(Vec3::new(0.0, 0.1, 0.0), Vec3::X, 0.1, 10);
    let entity = app.world_mut().spawn((spec, StrandOf(head))).id();
    app.update();
    (app, entity)
}

/// Turning angle between consecutive edges at each interior vertex, rad.
fn turning_angles(positions: &[Vec3]) -> Vec<f32> {
    let tangents: Vec<Vec3> = positions.windows(2).map(|pair| (pair[1] - pair[0]).normalize()).collect();
    tangents.windows(2).map(|pair| pair[0].dot(pair[1]).clamp(-1.0, 1.0).acos()).collect()
}

#[test]
fn nodes_frames_and_rest_shape_are_read_through_queries() {
    let (mut app, entity) = weightless_strand();
    app.update();
    let mut query = app.world_mut().query::<(&StrandNodes, &StrandFrames, &StrandRestShape)>();
    let (nodes, frames, rest_shape) = query.get(app.world(), entity).unwrap();
    let rod = strand(&app, entity).rod();

    let expected: Vec<Vec3> = rod.positions().iter().map(|p| p.as_vec3()).collect();
    assert_eq!(nodes.positions, expected, "positions are the rod's, rounded to f32");
    assert_eq!(nodes.velocities.len(), 11);
    assert_eq!(frames.tangents.len(), 10);
    for edge in 0..rod.edge_count() {
        let ours = frames.material_frame(edge).unwrap();
        let theirs = rod.material_frame(edge);
        for (a, b) in [(ours.tangent, theirs.tangent), (ours.m1, theirs.m1), (ours.m2, theirs.m2)] {
            assert!(a.as_dvec3().distance(b) < 1e-6, "edge {edge}: {a} against {b}");
        }
        assert!((ours.m1.dot(ours.tangent)).abs() < 1e-6 && (ours.m1.length() - 1.0).abs() < 1e-6);
    }
    assert!(frames.material_frame(rod.edge_count()).is_none());
    assert_eq!(rest_shape.lengths.len(), 10);
    assert!(rest_shape.lengths.iter().all(|&length| (length - 0.01).abs() < 1e-7));
    let curvatures: Vec<Vec2> = rod.rest_curvatures().iter().map(|k| k.as_vec2()).collect();
    assert_eq!(rest_shape.curvatures, curvatures);
}

#[test]
fn an_edited_rest_curvature_curls_the_strand_into_an_arc_at_the_next_steps() {
    let (mut app, entity) = weightless_strand();
    let straight = app.world().get::<StrandNodes>(entity).unwrap().positions.clone();
    assert!(turning_angles(&straight).iter().all(|&angle| angle < 1e-4), "spawned straight");

    // A turn of 0.2 rad at every vertex: integrated curvature 2 tan(0.1) along κ₁.
    let turn = 0.2_f32;
    let curvature = 2.0 * (0.5 * turn).tan();
    {
        let mut query = app.world_mut().query::<&mut StrandRestShape>();
        let mut rest_shape = query.get_mut(app.world_mut(), entity).unwrap();
        let vertices = rest_shape.curvatures.len() - 1;
        for vertex in 1..vertices {
            rest_shape.curvatures[vertex] = Vec2::new(curvature, 0.0);
        }
    }
    app.update();
    let rod = strand(&app, entity).rod();
    assert!(rod.rest_curvatures()[1..10].iter().all(|&k| k.x == f64::from(curvature) && k.y == 0.0));

    for _ in 0..600 {
        app.update();
    }
    let nodes = app.world().get::<StrandNodes>(entity).unwrap();
    let angles = turning_angles(&nodes.positions);
    println!("turning angles after 10 s: {angles:?}");
    for (vertex, angle) in angles.iter().enumerate() {
        assert!((angle - turn).abs() < 1e-3, "vertex {}: {angle} rad, not {turn}", vertex + 1);
    }
    // The tip of an arc of 9 turns of 0.2 rad is far from where the straight strand's was.
    assert!(nodes.positions[10].distance(straight[10]) > 0.03);
}

#[test]
fn an_edit_keeps_the_entries_it_did_not_touch_in_double_precision() {
    let mut app = hair_app();
    let spec = HairStrand::straight(Vec3::ZERO, Vec3::X, 0.1, 10).with_natural_curvature(Vec2::new(20.0, 3.0));
    let entity = app.world_mut().spawn(spec).id();
    app.update();
    let before = strand(&app, entity).rod().rest_curvatures().to_vec();
    assert_ne!(before[4], before[4].as_vec2().as_dvec2(), "a value f32 cannot hold");

    app.world_mut().get_mut::<StrandRestShape>(entity).unwrap().curvatures[3] = Vec2::new(0.5, -0.25);
    app.update();
    let after = strand(&app, entity).rod().rest_curvatures();
    assert_eq!(after[3], DVec3::new(0.5, -0.25, 0.0).truncate());
    for vertex in (1..10).filter(|&vertex| vertex != 3) {
        assert_eq!(after[vertex], before[vertex], "vertex {vertex} untouched, bit for bit");
    }
}

#[test]
fn an_edit_the_rod_cannot_take_is_undone_and_the_strand_goes_on() {
    let (mut app, entity) = weightless_strand();
    let before = strand(&app, entity).rod().rest_shape().clone();
    for edit in [
        |shape: &mut StrandRestShape| shape.curvatures[2] = Vec2::NAN,
        |shape: &mut StrandRestShape| shape.curvatures[5] = Vec2::new(30.0, 0.0), // a turn of 172°
        |shape: &mut StrandRestShape| shape.lengths[4] = 0.0,
        |shape: &mut StrandRestShape| shape.twists.push(0.0),
    ] {
        edit(&mut app.world_mut().get_mut::<StrandRestShape>(entity).unwrap());
        app.update();
        assert_eq!(strand(&app, entity).rod().rest_shape(), &before, "the rod's rest shape is unchanged");
        let shown = app.world().get::<StrandRestShape>(entity).unwrap();
        assert_eq!(shown.curvatures, before.curvatures.iter().map(|k| k.as_vec2()).collect::<Vec<_>>());
        assert_eq!(shown.lengths, before.lengths.iter().map(|&l| l as f32).collect::<Vec<_>>());
        assert_eq!(shown.twists.len(), 11, "the component is put back to the rest shape in use");
    }
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    assert!(app.world().get::<StrandRejected>(entity).is_none());
}

#[test]
fn longer_rest_lengths_grow_the_strand() {
    let (mut app, entity) = weightless_strand();
    for length in &mut app.world_mut().get_mut::<StrandRestShape>(entity).unwrap().lengths {
        *length *= 1.5;
    }
    for _ in 0..120 {
        app.update();
    }
    let rod = strand(&app, entity).rod();
    let length: f64 = rod.positions().windows(2).map(|pair| pair[0].distance(pair[1])).sum();
    println!("grown from 0.1 m to {length} m");
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0, "grown without a failed step");
    assert!((length - 0.15).abs() < 0.15 * 1e-3, "{length} m");
    let total_mass: f64 = rod.masses().iter().sum();
    let expected = RodMaterial::human_hair().stiffness().linear_density * 0.15;
    assert!((total_mass / expected - 1.0).abs() < 1e-6, "mass follows the length: {total_mass} kg");
}

/// Every strand's rod positions and twist angles.
fn state(app: &mut App, strands: &[Entity]) -> Vec<(Vec<DVec3>, Vec<f64>)> {
    strands
        .iter()
        .map(|&entity| {
            let rod = strand(app, entity).rod();
            (rod.positions().to_vec(), rod.twist_angles().to_vec())
        })
        .collect()
}

#[test]
fn a_strand_restored_at_step_100_repeats_steps_101_to_200_bit_for_bit() {
    let mut app = hair_app();
    // Little air, so that the hair still swings between steps 100 and 200.
    app.world_mut().resource_mut::<HairSettings>().air_damping = 0.1;
    let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 24, 16);
    app.world_mut().spawn((HairCollider::sphere(0.1), HairColliderOf(head), Transform::from_xyz(0.0, 1.6, 0.0)));
    for _ in 0..100 {
        app.update();
    }
    let mut query = app.world_mut().query::<(Entity, StrandSnapshotData)>();
    let saved: Vec<(Entity, StrandSnapshot)> =
        query.iter(app.world()).map(|(entity, data)| (entity, StrandSnapshot::of(data))).collect();
    assert_eq!(saved.len(), strands.len());
    let at_100 = state(&mut app, &strands);

    let mut first_run = Vec::new();
    for _ in 0..100 {
        app.update();
        first_run.push(state(&mut app, &strands));
    }
    let moved = at_100.iter().zip(&first_run[99]).map(|(a, b)| a.0[16].distance(b.0[16])).fold(0.0, f64::max);
    assert!(moved > 0.01, "the hair fell and swung between the two steps: {moved} m");
    assert!(app.world().resource::<HairStatistics>().contacts > 0, "and touched the head");

    for (entity, snapshot) in saved {
        app.world_mut().entity_mut(entity).insert(snapshot);
    }
    assert_eq!(state(&mut app, &strands), at_100);
    for (step, expected) in first_run.iter().enumerate() {
        app.update();
        assert!(state(&mut app, &strands) == *expected, "step {} differs", 101 + step);
    }
}

#[test]
fn a_rod_snapshot_fits_only_its_own_rod() {
    let mut hair = hair_sim_support::hanging_hair();
    let snapshot = hair.snapshot();
    let other = bevy_hair_sim::rod::Rod::new(
        &hair_sim_support::straight_nodes(0.1, 8, DVec3::X),
        DVec3::Y,
        RodMaterial::human_hair(),
    )
    .unwrap();
    let mut other = other;
    let before = other.snapshot();
    let error = other.restore(&snapshot).unwrap_err();
    assert!(matches!(error, RodError::SnapshotMismatch { nodes: 9, snapshot_nodes: 17 }), "{error}");
    assert_eq!(other.snapshot(), before, "unchanged");
    assert!(hair.restore(&RodSnapshot { state: snapshot.state.clone(), ..default() }).is_err(), "incomplete");
    assert!(hair.restore(&snapshot).is_ok());
}
