//! The Bevy layer in a headless app: roots follow heads, settings apply at once, strands come and go,
//! runs repeat exactly, and every strand is drawn.

use bevy::asset::AssetPlugin;
use bevy::gizmos::{GizmoAsset, GizmoHandles, GizmoPlugin};
use bevy::math::DVec3;
use bevy::mesh::MeshPlugin;
use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::Rod;
use bevy_hair_sim::simulation::{HeadMotion, SimulatedStrand};
use hair_sim_support::headless::{DT, drain_messages, hair_app, hair_app_with, spawn_head, strand};

/// The world positions the root edge's two nodes must have for a head whose world transform is `head`.
fn expected_root_edge(head: &GlobalTransform, spec: &HairStrand) -> [Vec3; 2] {
    let root = head.transform_point(spec.nodes[0]);
    [root, root + head.rotation() * (spec.nodes[1] - spec.nodes[0])]
}

#[test]
fn roots_follow_a_moving_head_that_is_the_child_of_a_moving_parent() {
    let mut app = hair_app();
    let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 0.3, 0.0), 100, 16);
    let parent = app.world_mut().spawn(Transform::from_xyz(0.0, 1.3, 0.0)).id();
    app.world_mut().entity_mut(head).insert(ChildOf(parent));

    let mut worst: f64 = 0.0;
    for step in 0..120 {
        let time = step as f32 * DT as f32;
        let parent_transform = Transform::from_xyz(0.4 * (2.0 * time).sin(), 1.3, 0.3 * (3.0 * time).cos())
            .with_rotation(Quat::from_rotation_y(1.5 * time));
        let head_transform = Transform::from_xyz(0.0, 0.3 + 0.05 * (5.0 * time).sin(), 0.0)
            .with_rotation(Quat::from_rotation_x(0.6 * (4.0 * time).sin()));
        *app.world_mut().get_mut::<Transform>(parent).unwrap() = parent_transform;
        *app.world_mut().get_mut::<Transform>(head).unwrap() = head_transform;
        app.update();

        let head_world = GlobalTransform::from(parent_transform) * GlobalTransform::from(head_transform);
        for &entity in &strands {
            let spec = app.world().get::<HairStrand>(entity).unwrap();
            let positions = strand(&app, entity).rod().positions();
            for (node, expected) in expected_root_edge(&head_world, spec).into_iter().enumerate() {
                worst = worst.max(positions[node].distance(expected.as_dvec3()));
            }
        }
    }
    println!("largest distance of a root node from its anchor over 120 steps: {worst:e} m");
    assert!(worst <= 1e-6, "a root node was {worst:e} m from its anchor");
    let tip_speed = strand(&app, strands[0]).rod().velocities().last().unwrap().length();
    assert!(tip_speed > 0.05, "the hair moves with the head ({tip_speed} m/s)");
}

/// Mass-weighted mean velocity of a strand, m/s.
fn mean_velocity(rod: &Rod) -> DVec3 {
    let mass: f64 = rod.masses().iter().sum();
    rod.masses().iter().zip(rod.velocities()).map(|(m, v)| *m * *v).sum::<DVec3>() / mass
}

#[test]
fn settings_changed_at_run_time_apply_at_the_next_step() {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    let free = app.world_mut().spawn(HairStrand::straight(Vec3::new(0.0, 2.0, 0.0), Vec3::X, 0.2, 12)).id();
    for _ in 0..5 {
        app.update();
    }
    assert_eq!(mean_velocity(strand(&app, free).rod()), DVec3::ZERO, "no gravity, no motion");

    let gravity = Vec3::new(2.0, -5.0, 1.0);
    {
        let mut settings = app.world_mut().resource_mut::<HairSettings>();
        settings.gravity = gravity;
        settings.air_damping = 0.0;
    }
    app.update();
    let velocity = mean_velocity(strand(&app, free).rod());
    let dt = app.world().resource::<Time<Fixed>>().timestep().as_secs_f64();
    // BDF2 (the default integrator) from rest with a force that was zero the step before: `v = ⅔ g dt`
    // (its effective step `⅔ dt` times the acceleration; backward Euler would give `g dt`).
    let expected = gravity.as_dvec3() * (2.0 / 3.0 * dt);
    println!("mean velocity after one step: {velocity} (expected ⅔ g dt = {expected})");
    assert!((velocity - expected).length() < 1e-9 * expected.length(), "{velocity} vs {expected}");

    // An invalid setting pauses the simulation with a reason; fixing it resumes.
    app.world_mut().resource_mut::<HairSettings>().air_damping = -1.0;
    let before = strand(&app, free).rod().positions().to_vec();
    app.update();
    let reason = app.world().resource::<HairStatistics>().settings_error.clone().expect("the error is reported");
    assert!(reason.contains("air_damping"), "{reason}");
    assert_eq!(strand(&app, free).rod().positions(), before.as_slice(), "paused while invalid");
    app.world_mut().resource_mut::<HairSettings>().air_damping = 3.0;
    app.update();
    assert_eq!(app.world().resource::<HairStatistics>().settings_error, None);
    assert_ne!(strand(&app, free).rod().positions(), before.as_slice(), "running again");

    // A new default material reaches the strands that use it at the next step.
    let thick = RodMaterial::round(80e-6, 3.5e9, 0.4, 1300.0);
    app.world_mut().resource_mut::<HairSettings>().default_material = thick;
    app.update();
    assert_eq!(*strand(&app, free).rod().material(), thick);
}

/// Number of entities with a simulated strand.
fn simulated_strands(app: &mut App) -> usize {
    app.world_mut().query::<&SimulatedStrand>().iter(app.world()).count()
}

#[test]
fn strands_and_heads_come_and_go_while_running() {
    let mut app = hair_app();
    let (head_a, mut strands_a) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 20, 8);
    let (head_b, strands_b) = spawn_head(&mut app, Transform::from_xyz(1.0, 1.6, 0.0), 20, 8);
    for step in 0..40 {
        if step % 3 == 0 {
            let root = Vec3::new(0.0, 0.1, 0.0);
            let added = app.world_mut().spawn((HairStrand::straight(root, Vec3::Y, 0.1, 6), StrandOf(head_a))).id();
            strands_a.push(added);
        }
        if step % 4 == 1 {
            let removed = strands_a.remove(step % strands_a.len());
            app.world_mut().despawn(removed);
        }
        if step == 20 {
            app.world_mut().despawn(head_b);
        }
        app.update();
    }
    assert!(strands_b.iter().all(|&entity| app.world().get_entity(entity).is_err()), "head B's strands are gone");
    assert_eq!(simulated_strands(&mut app), strands_a.len(), "no strand leaked");
    let mut listed = app.world().get::<HeadStrands>(head_a).unwrap().strands().to_vec();
    listed.sort();
    strands_a.sort();
    assert_eq!(listed, strands_a);
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    assert!(drain_messages::<StrandFault>(&mut app).is_empty());
}

#[test]
fn two_runs_with_the_same_inputs_are_bit_identical() {
    let run = || {
        let mut app = hair_app();
        let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 60, 16);
        for step in 0..300 {
            let time = step as f32 * DT as f32;
            let mut transform = app.world_mut().get_mut::<Transform>(head).unwrap();
            transform.translation.x = 0.3 * (4.0 * time).sin();
            transform.rotation = Quat::from_rotation_y(2.0 * time);
            app.update();
        }
        strands.iter().flat_map(|&entity| strand(&app, entity).rod().positions().to_vec()).collect::<Vec<_>>()
    };
    let (first, second) = (run(), run());
    assert_eq!(first.len(), 60 * 17);
    let differing =
        first.iter().zip(&second).filter(|(a, b)| a.to_array().map(f64::to_bits) != b.to_array().map(f64::to_bits));
    assert_eq!(differing.count(), 0, "every node of every strand has the same bits in both runs");
}

#[test]
fn every_strand_is_drawn_as_an_interpolated_line_strip() {
    let mut app = hair_app_with((AssetPlugin::default(), MeshPlugin, GizmoPlugin));
    let (_, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 25, 10);
    for _ in 0..10 {
        app.update();
    }
    let gizmo_strips = |app: &App| {
        let handle = app.world().resource::<GizmoHandles>().handles()[&std::any::TypeId::of::<HairGizmos>()].clone();
        let asset = app.world().resource::<Assets<GizmoAsset>>().get(&handle.expect("hair was drawn")).unwrap();
        asset.buffer().buffer().strip_positions.clone()
    };
    let drawn = gizmo_strips(&app);
    let strips: Vec<&[Vec3]> = drawn.split(|point| point.is_nan()).filter(|strip| !strip.is_empty()).collect();
    assert_eq!(strips.len(), strands.len(), "one line strip per strand");
    for (strip, &entity) in strips.iter().zip(&strands) {
        assert_eq!(strip.len(), 11, "every node of the strand is a vertex of its strip");
        let root = strand(&app, entity).rod().positions()[0].as_vec3();
        assert!(strip.iter().any(|point| point.distance(root) < 1e-5), "the strip starts at its strand's root");
    }

    // Half a step later the strip lies between the last two steps.
    app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(std::time::Duration::from_secs_f64(1.5 * DT)));
    app.update();
    let alpha = app.world().resource::<Time<Fixed>>().overstep_fraction();
    assert!(alpha > 0.1 && alpha < 0.9, "the frame falls between steps ({alpha})");
    let drawn = gizmo_strips(&app);
    let pose = app.world().get::<StrandNodes>(strands[0]).unwrap();
    let tip = pose.previous_positions[10].lerp(pose.positions[10], alpha);
    assert!(pose.previous_positions[10].distance(pose.positions[10]) > 1e-5, "the tip moved during the step");
    assert!(drawn[10].distance(tip) < 1e-6, "tip drawn at {} instead of {tip}", drawn[10]);
}

#[test]
fn a_strand_given_to_another_head_is_rooted_there() {
    let mut app = hair_app();
    let (_, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 4, 8);
    let other = app.world_mut().spawn((HairHead, Transform::from_xyz(2.0, 1.0, 0.0))).id();
    for _ in 0..5 {
        app.update();
    }
    app.world_mut().entity_mut(strands[1]).insert(StrandOf(other));
    app.update();
    let spec = app.world().get::<HairStrand>(strands[1]).unwrap();
    let expected = expected_root_edge(&GlobalTransform::from_xyz(2.0, 1.0, 0.0), spec);
    let positions = strand(&app, strands[1]).rod().positions();
    assert!(positions[0].distance(expected[0].as_dvec3()) < 1e-6, "root at {} not {}", positions[0], expected[0]);
    let tip_to_head = positions.last().unwrap().distance(DVec3::new(2.0, 1.0, 0.0));
    assert!(tip_to_head < 0.31, "the whole strand moved to its new head ({tip_to_head} m from it)");
    assert_eq!(app.world().get::<HeadStrands>(other).unwrap().strands(), &[strands[1]]);
}

#[test]
fn hair_drawn_between_steps_is_carried_onto_the_head_where_it_is_now() {
    let mut app = hair_app();
    let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 40, 12);
    // The head turns 0.1 rad per step about y and drifts sideways, as a head shaken hard does.
    let pose = |step: usize| {
        Transform::from_xyz(0.01 * step as f32, 1.6, 0.0).with_rotation(Quat::from_rotation_y(0.1 * step as f32))
    };
    for step in 0..10 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = pose(step);
        app.update();
    }
    let motion = *app.world().get::<HeadMotion>(head).unwrap();
    let anchor = |transform: &Transform, entity: Entity| {
        transform.transform_point(app.world().get::<HairStrand>(entity).unwrap().nodes[0])
    };
    // Not moved since the last step: drawn where stepped.
    let last = GlobalTransform::from(pose(9));
    assert!(motion.drawn_to_now(1.0, &last).abs_diff_eq(bevy::math::Affine3A::IDENTITY, 1e-5));
    // Moved on after the step, as a game's `Update` moves it: a step and a half further.
    let now = pose(9).with_rotation(Quat::from_rotation_y(1.05)).with_translation(Vec3::new(0.105, 1.6, 0.0));
    // The drawing interpolates positions along the chord between the two steps; a root on a circle of
    // radius r turned by 0.1 rad lies at most r (1 − cos 0.05) from its chord.
    let radius = strands.iter().map(|&entity| anchor(&Transform::IDENTITY, entity).xz().length()).fold(0.0, f32::max);
    let sagitta = radius * (1.0 - 0.05_f32.cos());
    for alpha in [0.0, 0.5, 1.0] {
        let carry = motion.drawn_to_now(alpha, &GlobalTransform::from(now));
        let mut worst: f32 = 0.0;
        for &entity in &strands {
            let nodes = app.world().get::<StrandNodes>(entity).unwrap();
            let drawn = nodes.previous_positions[0].lerp(nodes.positions[0], alpha);
            worst = worst.max(carry.transform_point3(drawn).distance(anchor(&now, entity)));
        }
        println!("alpha {alpha}: carried roots at most {worst:e} m from their anchors on the head now");
        let bound = if alpha == 0.5 { sagitta + 1e-6 } else { 1e-5 };
        assert!(worst <= bound, "alpha {alpha}: a carried root is {worst:e} m off (bound {bound:e})");
    }
    // Uncarried, the roots would trail the head by a step and a half: the bald scalp a turning head shows.
    let nodes = app.world().get::<StrandNodes>(strands[0]).unwrap();
    assert!(nodes.positions[0].distance(anchor(&now, strands[0])) > 0.01);
}

#[test]
fn colliders_are_drawn_where_their_transforms_put_them_in_the_frame() {
    // The head moves in `Update`, after the fixed step (as a game animates it): its skull collider met the
    // hair where the head was at the step, and is drawn where the head is in the frame, with its mesh.
    #[derive(Component)]
    struct Moved;
    let mut app = hair_app_with((AssetPlugin::default(), MeshPlugin, GizmoPlugin));
    app.add_systems(Update, |mut heads: Query<&mut Transform, With<Moved>>| {
        heads.iter_mut().for_each(|mut head| head.translation.x += 0.05);
    });
    let (head, _) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 4, 8);
    app.world_mut().entity_mut(head).insert(Moved);
    app.world_mut().spawn((HairCollider::sphere(0.1), Transform::default(), HairColliderOf(head), ChildOf(head)));
    app.world_mut().resource_mut::<GizmoConfigStore>().config_mut::<HairGizmos>().1.draw_colliders = true;
    for _ in 0..5 {
        app.update();
    }
    let now = app.world().get::<Transform>(head).unwrap().translation;
    let handle = app.world().resource::<GizmoHandles>().handles()[&std::any::TypeId::of::<HairGizmos>()].clone();
    let asset = app.world().resource::<Assets<GizmoAsset>>().get(&handle.expect("drawn")).unwrap();
    let buffer = asset.buffer().buffer();
    let points: Vec<Vec3> =
        buffer.list_positions.iter().chain(buffer.strip_positions.iter()).copied().filter(|p| p.is_finite()).collect();
    // The sphere's lines, apart from the strands' (which start on the scalp 0.1 m from the head's origin
    // and hang below it).
    let on_sphere = points.iter().filter(|p| (p.distance(now) - 0.1).abs() < 1e-4).count();
    let at_step = now - Vec3::X * 0.05;
    let on_stepped = points.iter().filter(|p| (p.distance(at_step) - 0.1).abs() < 1e-4).count();
    println!("{on_sphere} points on the sphere where the head is now, {on_stepped} where it was at the step");
    assert!(on_sphere > 50, "the collider is not drawn where the head is now ({on_sphere} points)");
    assert!(on_stepped < on_sphere / 4, "the collider is still drawn where the step met it ({on_stepped} points)");
}
