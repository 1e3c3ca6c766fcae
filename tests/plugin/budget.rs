//! The CPU budget (`HairCpuBudget`): the hair stepped less often to keep it, with its roots on the head and
//! its hair as dense on the grid; without a budget, or with one every update keeps, the step bit for bit as
//! it was; an invalid budget refused by name.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::SimulatedStrand;
use bevy_hair_sim::volume::HairVolumeGrids;
use hair_sim_support::headless::{hair_app, moving_pose, strand};
use hair_sim_support::logs;

/// The head's pose at fixed step `step`: at 1.6 m, swaying and turning ([`moving_pose`]).
fn moving_head(step: usize) -> Transform {
    moving_pose(Vec3::new(0.0, 1.6, 0.0), step)
}

/// An app with a groom of `strands` combed guides × 16 edges on a skull collider, the grid on, within
/// `budget`; the head, its strands after the groom grew.
fn budgeted_head(strands: usize, budget: HairCpuBudget) -> (App, Entity, Vec<Entity>) {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().volume.enabled = true;
    app.insert_resource(budget);
    let groom = HairGroom { strand_count: strands, segments: 16, ..default() };
    let skull = groom.scalp.semi_axes;
    let head = app.world_mut().spawn((HairHead, groom, moving_head(0))).id();
    app.world_mut().spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), ChildOf(head)));
    app.update();
    let strands = app.world().get::<HeadStrands>(head).expect("hair grew").strands().to_vec();
    (app, head, strands)
}

/// Every drawn node of `strands`, strand after strand.
fn drawn_nodes(app: &App, strands: &[Entity]) -> Vec<Vec3> {
    strands.iter().flat_map(|&entity| app.world().get::<StrandNodes>(entity).unwrap().positions.clone()).collect()
}

#[test]
fn a_budget_no_update_can_keep_steps_the_hair_at_the_coarsest_interval_with_its_roots_on_the_head() {
    // A microsecond a step: no machine keeps it, so the budget goes to its coarsest interval and stays.
    let budget = HairCpuBudget { milliseconds: Some(1e-3), max_step_interval: 4 };
    let (mut app, head, strands) = budgeted_head(200, budget);
    let anchors: Vec<[Vec3; 2]> = strands
        .iter()
        .map(|&entity| {
            let rod = strand(&app, entity).rod();
            let to_local = moving_head(0).compute_affine().inverse();
            [0, 1].map(|node| to_local.transform_point3(rod.positions()[node].as_vec3()))
        })
        .collect();
    let (mut worst_root, mut intervals, mut stepped) = (0.0_f32, Vec::new(), Vec::new());
    for step in 1..=240 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = moving_head(step);
        app.update();
        let statistics = app.world().resource::<HairStatistics>();
        assert!(statistics.update_seconds > 0.0, "the update is measured");
        intervals.push(statistics.budget_step_interval);
        if step > 120 {
            stepped.push(statistics.strands);
            assert_eq!(app.world().get::<HairDetail>(head).unwrap().level(), HairDetailLevel::Stepped(4));
            assert!(statistics.max_volume_fraction > 0.0, "the hair stepped meets the other hair on the grid");
        }
        let pose = moving_head(step);
        for (&entity, anchor) in strands.iter().zip(&anchors) {
            let nodes = &app.world().get::<StrandNodes>(entity).unwrap().positions;
            for (node, local) in nodes.iter().zip(anchor) {
                worst_root = worst_root.max(node.distance(pose.transform_point(*local)));
            }
        }
    }
    let first_coarse = intervals.iter().position(|&interval| interval == 4);
    println!(
        "the budget went to every 4th step at step {first_coarse:?} (intervals {:?}); strands stepped per step from 121 on: {}–{}; roots within {worst_root:.2e} m",
        {
            let mut seen = intervals.clone();
            seen.dedup();
            seen
        },
        stepped.iter().min().unwrap(),
        stepped.iter().max().unwrap()
    );
    // 16 updates measured, then the coarsest interval: it never comes back finer, as every update is over.
    assert!(first_coarse.is_some_and(|step| step <= 20), "{intervals:?}");
    assert!(intervals[first_coarse.unwrap()..].iter().all(|&interval| interval == 4), "{intervals:?}");
    // The strands take turns: a quarter of them at each fixed step.
    assert_eq!(stepped.iter().sum::<usize>(), 120 * 200 / 4);
    assert!(stepped.iter().all(|&count| (40..=60).contains(&count)), "{stepped:?}");
    assert!(worst_root < 2e-6, "a root left its head by {worst_root} m");
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    let finite = strands.iter().all(|&entity| strand(&app, entity).rod().positions().iter().all(|p| p.is_finite()));
    assert!(finite);
}

#[test]
fn without_a_budget_or_with_one_every_update_keeps_the_hair_steps_bit_for_bit_as_it_did() {
    let runs = [HairCpuBudget::default(), HairCpuBudget::milliseconds(1e6)].map(|budget| {
        let (mut app, head, strands) = budgeted_head(60, budget);
        for step in 1..=150 {
            *app.world_mut().get_mut::<Transform>(head).unwrap() = moving_head(step);
            app.update();
            assert_eq!(app.world().resource::<HairStatistics>().budget_step_interval, 1);
            assert_eq!(app.world().resource::<HairStatistics>().strands, 60, "every strand at every step");
        }
        drawn_nodes(&app, &strands)
    });
    assert_eq!(runs[0], runs[1]);
}

#[test]
fn hair_at_a_coarser_level_is_as_dense_on_the_grid_as_at_full_detail() {
    // 1 000 combed strands settled at full detail, then stepped every 4th step: a quarter of them splatted at
    // each fixed step, each standing for four steps' hairs.
    let (mut app, head, strands) = budgeted_head(1000, HairCpuBudget::default());
    for _ in 0..60 {
        app.update();
    }
    let fractions = |app: &App| -> Vec<f32> {
        let grids = app.world().resource::<HairVolumeGrids>();
        let nodes = drawn_nodes(app, &strands);
        nodes.iter().map(|&node| grids.volume_fraction_at(Some(head), node)).collect()
    };
    let mean = |values: &[f32]| values.iter().sum::<f32>() / values.len() as f32;
    let full = fractions(&app);
    app.world_mut().entity_mut(head).insert(HairDetail::fixed(HairDetailLevel::Stepped(4)));
    // 12 fixed steps while the drawn clock falls behind (every strand stepped), then turns.
    let mut coarse_means = Vec::new();
    for step in 1..=24 {
        app.update();
        if step > 16 {
            let statistics = app.world().resource::<HairStatistics>();
            assert_eq!(statistics.strands + statistics.unstepped_strands, 1000);
            assert!((200..=300).contains(&statistics.strands), "a quarter stepped: {}", statistics.strands);
            coarse_means.push(mean(&fractions(&app)));
        }
    }
    let ratios: Vec<f32> = coarse_means.iter().map(|coarse| coarse / mean(&full)).collect();
    println!("mean volume fraction at the nodes, full detail {:.4}; every 4th step / full: {ratios:.3?}", mean(&full));
    assert!(mean(&full) > 0.0);
    assert!(ratios.iter().all(|ratio| (0.9..=1.1).contains(ratio)), "{ratios:?}");
}

#[test]
fn an_invalid_budget_is_refused_by_name_once_and_the_hair_runs_without_it() {
    let _log = logs::serial();
    let (mut app, _, strands) = budgeted_head(20, HairCpuBudget::default());
    let broken = [
        (HairCpuBudget::milliseconds(f32::NAN), "milliseconds"),
        (HairCpuBudget::milliseconds(-1.0), "milliseconds"),
        (HairCpuBudget::milliseconds(0.0), "milliseconds"),
        (HairCpuBudget { milliseconds: Some(1e-3), max_step_interval: 0 }, "max_step_interval"),
        (HairCpuBudget { milliseconds: Some(1e-3), max_step_interval: 17 }, "max_step_interval"),
    ];
    for (budget, parameter) in broken {
        let error = budget.validate().expect_err("refused").to_string();
        assert!(error.contains(parameter), "{error}");
        app.insert_resource(budget);
        logs::take();
        for _ in 0..40 {
            app.update();
            let statistics = app.world().resource::<HairStatistics>();
            assert_eq!((statistics.budget_step_interval, statistics.strands), (1, 20), "{budget:?}");
        }
        let lines = logs::take();
        println!("{budget:?}: {lines:?}");
        assert_eq!(lines.len(), 1, "one line: {lines:?}");
        assert!(lines[0].1.contains("HairCpuBudget rejected") && lines[0].1.contains(parameter), "{lines:?}");
    }
    let finite = strands.iter().all(|&entity| strand(&app, entity).rod().positions().iter().all(|p| p.is_finite()));
    assert!(finite);
}

#[test]
fn a_strand_of_a_budgeted_head_steps_on_its_turns_only() {
    let budget = HairCpuBudget { milliseconds: Some(1e-3), max_step_interval: 3 };
    let (mut app, head, strands) = budgeted_head(30, budget);
    for step in 1..=80 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = moving_head(step);
        app.update();
    }
    assert_eq!(app.world().resource::<HairStatistics>().budget_step_interval, 3);
    let mut turns = vec![0; strands.len()];
    for _ in 0..30 {
        app.update();
        for (count, &entity) in turns.iter_mut().zip(&strands) {
            *count += usize::from(app.world().get::<SimulatedStrand>(entity).unwrap().steps_now());
        }
    }
    assert!(turns.iter().all(|&count| count == 10), "every strand once every third step: {turns:?}");
}
