//! The six defects an outside fuzz found in the grid, levels of detail, followers, wind, preload and
//! combing, each as it was reproduced: every test here failed before its fix (`docs/testing.md`).

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::groom::{GroomError, MAX_GROOM_SEGMENTS};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{ColliderShape, Rod, RodError, RodWorkspace, StepError, StepParams};
use bevy_hair_sim::simulation::SimulatedStrand;
use hair_sim_support::headless::{DT, drain_messages, drawn_is_finite, hair_app, hair_app_with, spawn_head, strand};
use hair_sim_support::{logs, straight_nodes};

/// Where the root of `strand` (head-local `HairStrand` nodes) is on its head now, world space.
fn root_on_head(app: &App, strand: Entity) -> Vec3 {
    let head = app.world().get::<StrandOf>(strand).unwrap().0;
    let transform = app.world().get::<Transform>(head).unwrap();
    transform.transform_point(app.world().get::<HairStrand>(strand).unwrap().nodes[0])
}

/// The largest distance of a drawn root (`StrandNodes`, and each follower's first node) from its root
/// on the head, m.
fn largest_root_offset(app: &App, strands: &[Entity]) -> f32 {
    strands
        .iter()
        .map(|&entity| {
            let root = root_on_head(app, entity);
            let drawn = app.world().get::<StrandNodes>(entity).unwrap().positions[0];
            drawn.distance(root)
        })
        .fold(0.0, f32::max)
}

/// Every value a game reads of `strands` is finite: their nodes, frames and followers.
fn assert_drawn_finite(app: &App, strands: &[Entity], when: &str) {
    for &entity in strands {
        let world = app.world();
        let (nodes, frames) = (world.get::<StrandNodes>(entity).unwrap(), world.get::<StrandFrames>(entity).unwrap());
        let finite = drawn_is_finite(nodes, frames, world.get::<FollowerNodes>(entity));
        assert!(finite, "{when}: strand {entity} drawn non-finite");
    }
}

/// A head moving along +X at `speed` m/s, turning slowly: its transform at fixed step `step`.
fn moving(speed: f32, step: usize) -> Transform {
    let t = step as f32 * DT as f32;
    Transform::from_xyz(speed * t, 1.6, 0.0).with_rotation(Quat::from_rotation_y(0.5 * t))
}

/// Defect 1: a zero (or subnormal) material direction passed `|perpendicular| >= sin(1e-3)·|direction|`
/// as 0 >= 0, and zero was normalised into NaN frames.
#[test]
fn a_zero_material_direction_is_rejected_and_a_tiny_one_is_a_direction() {
    let nodes = straight_nodes(0.1, 8, DVec3::NEG_Y);
    let material = RodMaterial::human_hair();
    for zero in [DVec3::ZERO, DVec3::new(0.0, -0.0, 0.0)] {
        let error = Rod::new(&nodes, zero, material).unwrap_err();
        assert!(matches!(error, RodError::InvalidMaterialDirection { edge: 0, .. }), "{error}");
    }
    // A subnormal direction has a direction: it is taken, with the frame it names.
    let rod = Rod::new(&nodes, DVec3::new(5e-324, 0.0, 0.0), material).unwrap();
    assert!((rod.material_frame(0).m1 - DVec3::X).length() < 1e-12, "{:?}", rod.material_frame(0));
    let mut rod = rod;
    assert!(matches!(
        rod.clamp_edge(0, nodes[0], nodes[1], DVec3::ZERO),
        Err(RodError::InvalidMaterialDirection { edge: 0, .. })
    ));
    // Huge directions are directions too.
    let huge = Rod::new(&nodes, DVec3::new(1e300, 0.0, 1e300), material).unwrap();
    let expected = DVec3::new(1.0, 0.0, 1.0).normalize();
    assert!((huge.material_frame(0).m1 - expected).length() < 1e-12, "{:?}", huge.material_frame(0));
    rod.clamp_edge(0, nodes[0], nodes[1], DVec3::new(0.0, 0.0, 1e-310)).unwrap();
    rod.step(&StepParams::default(), None, &mut RodWorkspace::default()).expect("a tiny clamp direction steps");
    assert!((rod.material_frame(0).m1 - DVec3::Z).length() < 1e-9, "{:?}", rod.material_frame(0));

    // In the plugin the strand is rejected, with its reason, and its followers are never placed.
    let mut app = hair_app();
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let nodes: Vec<Vec3> = (0..=8).map(|i| Vec3::new(0.0, 0.1, 0.0) + Vec3::Y * 0.01 * i as f32).collect();
    let follower: Vec<Vec3> = nodes.iter().map(|node| *node + Vec3::X * 0.002).collect();
    let zero = HairStrand { material_direction: Vec3::ZERO, ..HairStrand::from_nodes(nodes.clone(), Vec3::X) };
    let followers = HairFollowers { curves: vec![follower], ..HairFollowers::default() };
    let rejected = app.world_mut().spawn((zero, followers, StrandOf(head))).id();
    let tiny = app.world_mut().spawn((HairStrand::from_nodes(nodes, Vec3::new(1e-45, 0.0, 0.0)), StrandOf(head))).id();
    for _ in 0..3 {
        app.update();
    }
    let rejection = app.world().get::<StrandRejected>(rejected).expect("the zero direction is rejected");
    assert!(rejection.reason.contains("material direction"), "{}", rejection.reason);
    assert!(app.world().get::<SimulatedStrand>(rejected).is_none());
    assert!(app.world().get::<FollowerNodes>(rejected).unwrap().positions.is_empty());
    let frame = app.world().get::<StrandFrames>(tiny).unwrap().material_frame(0).unwrap();
    assert!((frame.m1 - Vec3::X).length() < 1e-5, "{frame:?}");
    assert_drawn_finite(&app, &[tiny], "a subnormal direction");
}

/// Groomed heads with followers and a skull collider: the app and the strands of its head.
fn groomed_with_followers(strands: usize) -> (App, Entity, Vec<Entity>) {
    let mut app = hair_app_with(TransformPlugin);
    let groom = HairGroom { strand_count: strands, segments: 8, followers_per_guide: 3, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let skull = HairCollider { shape: ColliderShape::Sphere { radius: 0.09 }, friction: 0.3 };
    app.world_mut().spawn((skull, HairColliderOf(head), ChildOf(head), Transform::default()));
    app.update();
    app.update();
    let strands = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    (app, head, strands)
}

/// Defect 2: followers were placed while the settings were invalid, with the invalid margin: an
/// infinite `collision_margin` made every follower node NaN.
#[test]
fn followers_are_never_placed_with_an_invalid_collision_margin() {
    let (mut app, _, strands) = groomed_with_followers(12);
    assert!(app.world().get::<FollowerNodes>(strands[0]).unwrap().count() > 0, "the groom has followers");
    for margin in [f32::INFINITY, f32::NAN, -1.0] {
        app.world_mut().resource_mut::<HairSettings>().collision_margin = margin;
        for _ in 0..3 {
            app.update();
            assert_drawn_finite(&app, &strands, &format!("collision margin {margin}"));
        }
        let error = app.world().resource::<HairStatistics>().settings_error.clone();
        assert!(error.is_some_and(|error| error.contains("collision_margin")), "margin {margin} is reported");
        app.world_mut().resource_mut::<HairSettings>().collision_margin = 0.001;
        app.update();
    }
}

/// Defect 3: NaN written through `rod_mut().positions_mut()` on a carried strand reached `StrandNodes`:
/// carried strands are not stepped, so their state was never checked.
#[test]
fn a_state_poisoned_on_a_carried_strand_never_reaches_what_the_game_reads() {
    let mut app = hair_app();
    let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 4, 8);
    app.world_mut().entity_mut(head).insert(HairDetail::fixed(HairDetailLevel::Carried));
    for _ in 0..5 {
        app.update();
    }
    drain_messages::<StrandFault>(&mut app);
    app.world_mut().get_mut::<SimulatedStrand>(strands[1]).unwrap().rod_mut().positions_mut()[4] = DVec3::NAN;
    app.update();
    assert_drawn_finite(&app, &strands, "carried, poisoned");
    let faults = drain_messages::<StrandFault>(&mut app);
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert_eq!(faults[0].strand, strands[1]);
    assert!(matches!(faults[0].error, StepError::UnusableState { node: 4, .. }), "{}", faults[0].error);
    assert!(strand(&app, strands[1]).rod().positions().iter().all(|p| p.is_finite()), "reset to its rest pose");

    // Poisoned again, and back at full detail at once: nothing non-finite in the updates after.
    app.world_mut().get_mut::<SimulatedStrand>(strands[2]).unwrap().rod_mut().positions_mut()[6] = DVec3::NAN;
    app.world_mut().entity_mut(head).insert(HairDetail::fixed(HairDetailLevel::FULL));
    for update in 0..4 {
        app.update();
        assert_drawn_finite(&app, &strands, &format!("update {update} back at full detail"));
    }
    assert!(largest_root_offset(&app, &strands) < 1e-5);
}

/// Defect 4: drawn roots left the head at coarser levels of detail: a step skipped for invalid input
/// keyframed the rod where it was before the head moved, the drawn shape did not follow the head after a
/// reset or in quarantine, and roots stopped following while the settings were invalid.
#[test]
fn drawn_roots_stay_on_the_moving_head_at_every_level_through_skips_resets_quarantine_and_invalid_settings() {
    let mut worst = Vec::new();
    for level in [HairDetailLevel::FULL, HairDetailLevel::Stepped(2), HairDetailLevel::Stepped(4)] {
        let mut app = hair_app_with(TransformPlugin);
        let (head, strands) = spawn_head(&mut app, moving(1.0, 0), 6, 8);
        app.world_mut().entity_mut(head).insert(HairDetail::fixed(level));
        let mut largest: f32 = 0.0;
        for step in 1..=160 {
            app.world_mut().entity_mut(head).insert(moving(1.0, step));
            // Strand 0: a non-finite force on every step (each skipped). Strand 1: a poisoned state every
            // tenth step (reset, then quarantined). Settings invalid from step 60 to 100.
            app.world_mut().get_mut::<StrandForces>(strands[0]).unwrap().add_to_all(Vec3::NAN);
            if step % 10 == 0 {
                let mut poisoned = app.world_mut().get_mut::<SimulatedStrand>(strands[1]).unwrap();
                poisoned.rod_mut().positions_mut()[3] = DVec3::NAN;
            }
            let gravity = if (60..100).contains(&step) { Vec3::NAN } else { Vec3::new(0.0, -9.81, 0.0) };
            app.world_mut().resource_mut::<HairSettings>().gravity = gravity;
            app.update();
            assert_drawn_finite(&app, &strands, &format!("{level:?}, step {step}"));
            largest = largest.max(largest_root_offset(&app, &strands));
        }
        assert!(strand(&app, strands[1]).health().quarantines_in_episode > 0, "strand 1 was quarantined");
        worst.push((level, largest));
    }
    assert!(worst.iter().all(|(_, offset)| *offset < 1e-5), "drawn roots off their head, m: {worst:?}");
}

/// Defect 5: invalid settings did not pause the strands' clocks: the first step after they were fixed
/// covered every fixed step skipped, past `MAX_DT` after ~59 of them, and every strand faulted.
#[test]
fn fixing_the_settings_after_a_long_pause_resumes_with_one_fixed_step() {
    for level in [HairDetailLevel::FULL, HairDetailLevel::Stepped(4)] {
        let mut app = hair_app();
        let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 8, 8);
        app.world_mut().entity_mut(head).insert(HairDetail::fixed(level));
        for _ in 0..10 {
            app.update();
        }
        app.world_mut().resource_mut::<HairSettings>().max_newton_iterations = 0;
        for _ in 0..120 {
            app.update();
        }
        assert!(app.world().resource::<HairStatistics>().settings_error.is_some());
        app.world_mut().resource_mut::<HairSettings>().max_newton_iterations = 4;
        drain_messages::<StrandFault>(&mut app);
        let mut faults = Vec::new();
        for _ in 0..8 {
            app.update();
            faults.extend(drain_messages::<StrandFault>(&mut app));
        }
        assert!(faults.is_empty(), "{level:?}: {} faults, the first {:?}", faults.len(), faults.first());
        for &entity in &strands {
            assert!(strand(&app, entity).last_report().is_some(), "{level:?}: strand {entity} steps again");
        }
    }
}

/// Defect 6: `HairWindSource` was not validated: a NaN speed or radius gave every strand it reached a
/// `NonFiniteAirVelocity` fault and a quarantine, and nothing named the source.
#[test]
fn an_invalid_wind_source_is_reported_once_by_name_and_blows_nothing() {
    let _log = logs::serial();
    let mut app = hair_app_with(TransformPlugin);
    let (_, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 10, 8);
    let fan = |speed: f32, radius: f32, range: f32| {
        (HairWindSource { speed, radius, range }, Transform::from_xyz(0.0, 1.6, 1.0))
    };
    let sources: Vec<Entity> = [fan(f32::NAN, 0.2, 3.0), fan(5.0, f32::NAN, 3.0), fan(5.0, 0.2, -1.0)]
        .into_iter()
        .map(|source| app.world_mut().spawn(source).id())
        .collect();
    let good = app.world_mut().spawn(fan(3.0, 0.2, 3.0)).id();
    let moved_by = |app: &App| strands.iter().map(|&e| strand(app, e).rod().velocities()[8].z).fold(0.0, f64::min);
    logs::take();
    let mut faults = Vec::new();
    for _ in 0..60 {
        app.update();
        faults.extend(drain_messages::<StrandFault>(&mut app));
    }
    assert!(faults.is_empty(), "{} faults, the first {:?}", faults.len(), faults.first());
    assert!(moved_by(&app) < -0.01, "the valid fan still blows the hair along −Z");
    let lines = logs::take();
    for source in &sources {
        let naming = lines.iter().filter(|(_, line)| line.contains(&format!("{source}"))).count();
        assert_eq!(naming, 1, "source {source} is named once: {lines:#?}");
    }
    assert!(!lines.iter().any(|(_, line)| line.contains(&format!("{good}"))), "{lines:#?}");
    assert_drawn_finite(&app, &strands, "invalid wind sources");
}

/// Beyond the six: every input added since the fuzz before is validated. A groom of absurd size, a groom
/// file placed with absurd values, and followers that cannot be bound each give an error, never a panic
/// or an allocation the size of the request; rejected followers are reported once, not at every
/// settings change.
#[test]
fn groom_sizes_placements_and_followers_are_validated() {
    let huge = HairGroom { segments: usize::MAX, ..default() };
    assert!(matches!(huge.grow(), Err(GroomError::TooManySegments(_))));
    let crowd = HairGroom { strand_count: usize::MAX, followers_per_guide: 2, ..default() };
    assert!(matches!(crowd.grow(), Err(GroomError::TooManyHairs { .. })));
    let fine = HairGroom { strand_count: 10, segments: MAX_GROOM_SEGMENTS, combing: None, ..default() };
    assert_eq!(fine.grow().unwrap().len(), 10);

    let tfx = include_bytes!("../../assets/grooms/Ratboy_mohawk.tfx");
    let file = GroomFile::from_tfx(tfx).unwrap();
    for placement in [
        GroomPlacement { segments: usize::MAX, ..default() },
        GroomPlacement { segments: 1, ..default() },
        GroomPlacement { metres_per_unit: f32::NAN, ..default() },
        GroomPlacement { transform: Transform::from_scale(Vec3::ZERO), ..default() },
    ] {
        assert!(matches!(placement.validate(), Err(GroomError::InvalidPlacement { .. })), "{placement:?}");
        assert_eq!(file.placed_strands(&placement, &RodMaterial::human_hair()).guides.len(), 0);
    }
    let mirrored = GroomPlacement { transform: Transform::from_scale(Vec3::new(-0.01, 0.01, 0.01)), ..default() };
    assert!(
        mirrored.validate().is_ok() && !file.placed_strands(&mirrored, &RodMaterial::human_hair()).guides.is_empty()
    );

    let _log = logs::serial();
    let mut app = hair_app();
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let nodes: Vec<Vec3> = (0..=6).map(|i| Vec3::new(0.0, 0.1 + 0.01 * i as f32, 0.0)).collect();
    let short = HairFollowers { curves: vec![nodes[..5].to_vec()], ..HairFollowers::default() };
    let guide = app.world_mut().spawn((HairStrand::from_nodes(nodes, Vec3::X), short, StrandOf(head))).id();
    logs::take();
    for update in 0..10 {
        app.world_mut().resource_mut::<HairSettings>().air_damping = 1.0 + update as f32;
        app.update();
    }
    // (Other tests of this binary log at the same time: only the guide's lines count.)
    let lines = logs::take();
    let about_guide: Vec<_> = lines.iter().filter(|(_, line)| line.contains(&format!("{guide}"))).collect();
    assert_eq!(about_guide.len(), 1, "{about_guide:#?}");
    let followers = app.world().get::<FollowerNodes>(guide).unwrap();
    assert!(followers.rejection().is_some_and(|reason| reason.contains("5 nodes")), "{:?}", followers.rejection());
    assert_eq!(followers.count(), 0);
}
