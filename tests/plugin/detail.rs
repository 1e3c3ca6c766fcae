//! Levels of detail: heads far from the camera stepped every n-th step, heads out of sight carried; roots
//! on their heads at every step, the same statics as at full detail, no pops when the level changes.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::SimulatedStrand;
use hair_sim_support::headless::{camera, hair_app, moving_pose, spawn_head};

/// The drawn nodes of `strands` in their head's rigid local frame (`R⁻¹ (x − t)`).
fn head_local_nodes(app: &App, head: Entity, strands: &[Entity]) -> Vec<Vec3> {
    let transform = app.world().get::<Transform>(head).unwrap();
    let to_local = transform.rotation.inverse();
    strands
        .iter()
        .flat_map(|&strand| app.world().get::<StrandNodes>(strand).unwrap().positions.clone())
        .map(|position| to_local * (position - transform.translation))
        .collect()
}

/// The largest distance between matching points, m.
fn largest_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max)
}

#[test]
fn a_coarser_level_steps_on_its_turns_and_keeps_the_roots_on_the_moving_head() {
    let mut app = hair_app();
    let (full_base, coarse_base) = (Vec3::new(0.0, 1.6, 0.0), Vec3::new(1.0, 1.6, 0.0));
    let (full, full_strands) = spawn_head(&mut app, Transform::from_translation(full_base), 12, 16);
    let (coarse, coarse_strands) = spawn_head(&mut app, Transform::from_translation(coarse_base), 12, 16);
    app.world_mut().entity_mut(full).insert(HairDetail::fixed(HairDetailLevel::FULL));
    app.world_mut().entity_mut(coarse).insert(HairDetail::fixed(HairDetailLevel::Stepped(4)));
    app.update();
    let anchors: Vec<[Vec3; 2]> = coarse_strands
        .iter()
        .map(|&strand| {
            let nodes = &app.world().get::<HairStrand>(strand).unwrap().nodes;
            [nodes[0], nodes[1]]
        })
        .collect();
    let (mut coarse_steps, mut worst_root) = (vec![0; coarse_strands.len()], 0.0_f32);
    // The first 12 fixed steps (the drawn clock falling 3 steps behind at a quarter of a step per step)
    // step every strand; then, counted over 120 fixed steps, the strands take turns.
    for step in 1..=132 {
        for (head, base) in [(full, full_base), (coarse, coarse_base)] {
            *app.world_mut().get_mut::<Transform>(head).unwrap() = moving_pose(base, step);
        }
        app.update();
        let statistics = app.world().resource::<HairStatistics>().clone();
        if step <= 12 {
            assert_eq!((statistics.strands, statistics.unstepped_strands), (24, 0), "at step {step}");
        } else {
            // The coarse head's 12 strands take turns: 3 of them on each fixed step.
            assert_eq!((statistics.strands, statistics.unstepped_strands), (15, 9), "at step {step}");
            for (count, &strand) in coarse_steps.iter_mut().zip(&coarse_strands) {
                *count += usize::from(app.world().get::<SimulatedStrand>(strand).unwrap().steps_now());
            }
        }
        let head = moving_pose(coarse_base, step);
        for (&strand, anchor) in coarse_strands.iter().zip(&anchors) {
            let nodes = &app.world().get::<StrandNodes>(strand).unwrap().positions;
            for (node, local) in nodes.iter().zip(anchor) {
                worst_root = worst_root.max(node.distance(head.transform_point(*local)));
            }
        }
    }
    println!(
        "the coarse strands stepped {coarse_steps:?} times in 120 steps; roots within {worst_root:.2e} m of the head"
    );
    assert!(coarse_steps.iter().all(|&count| count == 30));
    assert!(worst_root < 2e-6, "a root left its head by {worst_root} m");
    assert_eq!(app.world().get::<HairDetail>(coarse).unwrap().level(), HairDetailLevel::Stepped(4));
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    assert!(full_strands.iter().all(|&strand| app.world().get::<SimulatedStrand>(strand).unwrap().steps_now()));
}

#[test]
fn hair_at_every_level_hangs_in_the_same_static_shape() {
    let mut app = hair_app();
    let levels = [HairDetailLevel::FULL, HairDetailLevel::Stepped(2), HairDetailLevel::Stepped(4)];
    let heads: Vec<(Entity, Vec<Entity>)> = levels
        .iter()
        .enumerate()
        .map(|(index, &level)| {
            let (head, strands) = spawn_head(&mut app, Transform::from_xyz(index as f32, 1.6, 0.0), 10, 16);
            app.world_mut().entity_mut(head).insert(HairDetail::fixed(level));
            (head, strands)
        })
        .collect();
    for _ in 0..480 {
        app.update();
    }
    let shapes: Vec<Vec<Vec3>> = heads.iter().map(|(head, strands)| head_local_nodes(&app, *head, strands)).collect();
    for (level, shape) in levels.iter().zip(&shapes).skip(1) {
        let difference = largest_distance(&shapes[0], shape);
        println!("{level:?}: hanging nodes within {difference:.2e} m of full detail's");
        assert!(difference < 1e-4, "{level:?} hangs {difference} m away from full detail");
    }
    // Not trivially: the hair hangs well away from where it was spawned (straight out of the scalp).
    let spawned: Vec<Vec3> =
        heads[0].1.iter().flat_map(|&strand| app.world().get::<HairStrand>(strand).unwrap().nodes.clone()).collect();
    assert!(largest_distance(&spawned, &shapes[0]) > 0.05);
}

#[test]
fn changing_levels_moves_the_drawn_hair_no_faster_than_a_quarter_above_full_detail() {
    let mut app = hair_app();
    let (reference_base, switched_base) = (Vec3::new(0.0, 1.6, 0.0), Vec3::new(1.0, 1.6, 0.0));
    let (reference, reference_strands) = spawn_head(&mut app, Transform::from_translation(reference_base), 12, 16);
    let (switched, switched_strands) = spawn_head(&mut app, Transform::from_translation(switched_base), 12, 16);
    app.world_mut().entity_mut(reference).insert(HairDetail::fixed(HairDetailLevel::FULL));
    // Settle first, then move and switch levels every 30 steps.
    for _ in 0..240 {
        app.update();
    }
    let schedule = [
        HairDetailLevel::FULL,
        HairDetailLevel::Stepped(4),
        HairDetailLevel::Carried,
        HairDetailLevel::Stepped(2),
        HairDetailLevel::FULL,
        HairDetailLevel::Carried,
        HairDetailLevel::FULL,
    ];
    let mut previous = [(reference, &reference_strands), (switched, &switched_strands)]
        .map(|(head, strands)| head_local_nodes(&app, head, strands));
    let (mut reference_jump, mut switched_jump, mut jump_at_switch) = (0.0_f32, 0.0_f32, 0.0_f32);
    // In the first coarse phase (full detail until then, so both heads' hair moved alike), the least
    // share of a reference strand's motion (where it moves more than 1 mm) its twin on the switched head
    // moves in one step: it must not pause.
    let mut least_share = f32::INFINITY;
    for step in 1..=30 * schedule.len() {
        let level = schedule[(step - 1) / 30];
        app.world_mut().entity_mut(switched).insert(HairDetail::fixed(level));
        for (head, base) in [(reference, reference_base), (switched, switched_base)] {
            *app.world_mut().get_mut::<Transform>(head).unwrap() = moving_pose(base, step);
        }
        app.update();
        let now = [(reference, &reference_strands), (switched, &switched_strands)]
            .map(|(head, strands)| head_local_nodes(&app, head, strands));
        let jumps = [0, 1].map(|index| largest_distance(&previous[index], &now[index]));
        reference_jump = reference_jump.max(jumps[0]);
        switched_jump = switched_jump.max(jumps[1]);
        if (step - 1) % 30 == 0 && step > 1 {
            jump_at_switch = jump_at_switch.max(jumps[1]);
        }
        if (31..=60).contains(&step) {
            // Strand by strand (the same roots on both heads): each strand takes its own turns.
            let nodes = previous[0].len() / reference_strands.len();
            let moves = |index: usize| -> Vec<f32> {
                previous[index]
                    .chunks(nodes)
                    .zip(now[index].chunks(nodes))
                    .map(|(a, b)| largest_distance(a, b))
                    .collect()
            };
            for (reference, switched) in moves(0).into_iter().zip(moves(1)) {
                if reference > 1e-3 {
                    least_share = least_share.min(switched / reference);
                }
            }
        }
        previous = now;
    }
    println!(
        "largest move of a drawn node in one step, relative to its head: full detail throughout {reference_jump:.2e} m, \
         switching levels {switched_jump:.2e} m, in the steps where the level changed {jump_at_switch:.2e} m"
    );
    println!(
        "going to every fourth step, each drawn strand moved at least {least_share:.2} of its twin's motion per step"
    );
    assert!(reference_jump > 1e-3, "the moving head should move its hair");
    assert!(least_share > 0.25, "the drawn hair paused going coarser: {least_share}");
    // The drawn clock catches up at most 25 % faster than the hair moves: no more than that beyond the
    // largest motion at full detail (the two heads' hair differs once the switched one has been carried).
    let bound = (1.0 + bevy_hair_sim::detail::DRAWN_CLOCK_RATE_CHANGE as f32) * reference_jump;
    assert!(switched_jump <= bound, "{switched_jump} m against {reference_jump} m at full detail");
    assert!(jump_at_switch <= bound, "{jump_at_switch} m at a switch");
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
}

#[test]
fn the_camera_chooses_levels_by_distance_and_sight_with_a_margin() {
    let mut app = hair_app();
    // The camera at the origin looks down −z; heads ahead at 1, 5, 10 and 50 m, one 2 m behind.
    let places = [-1.0, -5.0, -10.0, -50.0, 2.0];
    let heads: Vec<Entity> =
        places.iter().map(|&z| spawn_head(&mut app, Transform::from_xyz(0.0, 0.0, z), 4, 8).0).collect();
    let levels = |app: &App| -> Vec<HairDetailLevel> {
        heads.iter().map(|&head| app.world().get::<HairDetail>(head).unwrap().level()).collect()
    };
    app.update();
    assert!(levels(&app).iter().all(|&level| level == HairDetailLevel::FULL), "no camera: full detail");

    let camera = app.world_mut().spawn(camera(Transform::IDENTITY)).id();
    app.update();
    let expected = [
        HairDetailLevel::FULL,
        HairDetailLevel::Stepped(2),
        HairDetailLevel::Stepped(4),
        HairDetailLevel::Carried,
        HairDetailLevel::Carried,
    ];
    assert_eq!(levels(&app), expected);
    let counted = app.world().resource::<HairStatistics>().heads_by_detail;
    assert_eq!(counted, bevy_hair_sim::detail::HeadsByDetail { full: 1, every_second_step: 1, rarer: 1, carried: 2 });
    let behind = app.world().get::<HairDetail>(heads[4]).unwrap();
    assert!(!behind.on_screen() && (behind.distance() - 2.0).abs() < 1e-4);
    assert!(app.world().get::<HairDetail>(heads[1]).unwrap().on_screen());
    assert_eq!(
        app.world().resource::<HairStatistics>().strands + app.world().resource::<HairStatistics>().unstepped_strands,
        20
    );

    // Within the 10 % margin of the 3 m boundary the level stays; beyond it, it changes.
    let move_head = |app: &mut App, z: f32| {
        app.world_mut().get_mut::<Transform>(heads[1]).unwrap().translation.z = z;
        app.update();
        app.world().get::<HairDetail>(heads[1]).unwrap().level()
    };
    assert_eq!(move_head(&mut app, -3.2), HairDetailLevel::Stepped(2));
    assert_eq!(move_head(&mut app, -2.6), HairDetailLevel::FULL);
    assert_eq!(move_head(&mut app, -3.2), HairDetailLevel::FULL);
    assert_eq!(move_head(&mut app, -3.4), HairDetailLevel::Stepped(2));

    // A fixed level wins; turned off, every head is at full detail; a camera turned off does not count.
    app.world_mut().entity_mut(heads[4]).insert(HairDetail::fixed(HairDetailLevel::Stepped(8)));
    app.update();
    assert_eq!(levels(&app)[4], HairDetailLevel::Stepped(8));
    app.world_mut().resource_mut::<HairDetailSettings>().enabled = false;
    app.update();
    assert_eq!(levels(&app)[..4], [HairDetailLevel::FULL; 4]);
    app.world_mut().resource_mut::<HairDetailSettings>().enabled = true;
    app.world_mut().get_mut::<Camera>(camera).unwrap().is_active = false;
    app.update();
    assert_eq!(levels(&app)[..4], [HairDetailLevel::FULL; 4]);
}

#[test]
fn invalid_detail_settings_are_reported_and_every_head_is_simulated_fully() {
    let mut app = hair_app();
    let (head, _) = spawn_head(&mut app, Transform::from_xyz(0.0, 0.0, -20.0), 4, 8);
    app.world_mut().spawn(camera(Transform::IDENTITY));
    app.update();
    assert_eq!(app.world().get::<HairDetail>(head).unwrap().level(), HairDetailLevel::Stepped(4));
    for broken in [
        HairDetailSettings { full_detail_distance: f32::NAN, ..default() },
        HairDetailSettings { max_step_interval: 0, ..default() },
        HairDetailSettings { max_step_interval: 17, ..default() },
        HairDetailSettings { carried_distance: -1.0, ..default() },
        HairDetailSettings { off_screen: HairDetailLevel::Stepped(0), ..default() },
        HairDetailSettings { hysteresis: 0.9, ..default() },
    ] {
        assert!(broken.validate().is_err(), "{broken:?}");
        app.insert_resource(broken);
        app.update();
        assert_eq!(app.world().get::<HairDetail>(head).unwrap().level(), HairDetailLevel::FULL);
    }
    app.insert_resource(HairDetailSettings::default());
    app.update();
    assert_eq!(app.world().get::<HairDetail>(head).unwrap().level(), HairDetailLevel::Stepped(4));
}

#[test]
fn a_head_teleported_between_its_turns_carries_its_hair_along() {
    let mut app = hair_app();
    let (head, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 10, 16);
    app.world_mut().entity_mut(head).insert(HairDetail::fixed(HairDetailLevel::Stepped(4)));
    // Hanging still after 8 s.
    for _ in 0..480 {
        app.update();
    }
    let before = head_local_nodes(&app, head, &strands);
    // 5 m away and turned half round, in one fixed step, on each of the four turns of the interval.
    for turn in 0..4 {
        let place = Transform::from_xyz(5.0 * (turn + 1) as f32, 1.6, 0.0)
            .with_rotation(Quat::from_rotation_y(std::f32::consts::PI * (turn + 1) as f32 / 2.0));
        *app.world_mut().get_mut::<Transform>(head).unwrap() = place;
        app.update();
        let moved = largest_distance(&before, &head_local_nodes(&app, head, &strands));
        println!("teleported on turn {turn}: drawn hair within {moved:.2e} m of its shape on the head");
        assert!(moved < 1e-4, "the hair was left behind or torn: {moved} m");
        for _ in 0..8 {
            app.update();
        }
    }
    let after = head_local_nodes(&app, head, &strands);
    let settled = largest_distance(&before, &after);
    println!("after four teleports and settling: within {settled:.2e} m of the shape before");
    assert!(settled < 1e-4, "{settled} m");
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
}
