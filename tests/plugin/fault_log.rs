//! Strands that keep failing: quarantined with a back-off, logged once per episode, the rest summed up
//! in at most one line per second, and the other strands unaffected.

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::{FIRST_QUARANTINE, QUARANTINE_WINDOW, SimulatedStrand, StrandHealth};
use hair_sim_support::headless::{DT, drain_messages, hair_app, spawn_head, strand};
use hair_sim_support::logs;

/// Strands whose state a buggy game system writes NaN into before every step.
#[derive(Resource, Default)]
struct Poisoned(Vec<Entity>);

fn poison(poisoned: Res<Poisoned>, mut strands: Query<&mut SimulatedStrand>) {
    for &entity in &poisoned.0 {
        if let Ok(mut strand) = strands.get_mut(entity) {
            strand.rod_mut().positions_mut()[5] = DVec3::NAN;
        }
    }
}

/// A head of `count` strands (20 cm, 12 edges) and the poisoning system.
fn poisoned_app(count: usize) -> (App, Vec<Entity>) {
    let mut app = hair_app();
    app.init_resource::<Poisoned>().add_systems(FixedUpdate, poison.in_set(HairSystems::ExternalForces));
    let (_, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), count, 12);
    app.update();
    logs::take();
    (app, strands)
}

/// Log lines that report single strand faults, and those that sum faults up.
fn fault_lines(lines: &[(bevy::log::Level, String)]) -> (usize, usize) {
    let single = lines.iter().filter(|(_, line)| line.contains("failed a step")).count();
    let summaries = lines.iter().filter(|(_, line)| line.contains("more strand faults")).count();
    (single, summaries)
}

#[test]
fn a_strand_failing_on_every_step_is_quarantined_with_a_doubling_back_off() {
    let _log = logs::serial();
    let (mut app, strands) = poisoned_app(20);
    let victim = strands[3];
    app.world_mut().resource_mut::<Poisoned>().0.push(victim);
    let mut fault_steps = Vec::new();
    for step in 0..600 {
        app.update();
        let faults = drain_messages::<StrandFault>(&mut app);
        assert!(faults.iter().all(|fault| fault.strand == victim), "only the poisoned strand fails");
        if !faults.is_empty() {
            fault_steps.push(step);
        }
        let quarantined = app.world().resource::<HairStatistics>().quarantined;
        assert_eq!(quarantined, usize::from(fault_steps.len() >= 2), "step {step}");
    }
    // Faulted, faulted again at once (quarantined for 0.5 s), then retried after 0.5, 1, 2 and 4 s.
    let gaps: Vec<usize> = fault_steps.windows(2).map(|pair| pair[1] - pair[0]).collect();
    println!("10 s of a strand poisoned before every step: faults at steps {fault_steps:?}");
    assert_eq!(gaps.len(), 5, "{fault_steps:?}");
    assert_eq!(gaps[0], 1);
    for (quarantine, gap) in gaps[1..].iter().enumerate() {
        let seconds = FIRST_QUARANTINE * 2f64.powi(quarantine as i32);
        let steps = (seconds / DT).round() as usize;
        assert!((steps..=steps + 1).contains(gap), "quarantine {quarantine}: {gap} steps, {seconds} s expected");
    }
    let lines = logs::take();
    let (single, summaries) = fault_lines(&lines);
    println!("{} log lines: {single} single, {summaries} summaries; {lines:#?}", lines.len());
    assert_eq!(single, 1, "one line for the episode");
    assert!((1..=10).contains(&summaries), "at most one summary a second");
    assert_eq!(lines.len(), single + summaries, "nothing else is logged");
    for &entity in &strands {
        assert!(strand(&app, entity).rod().positions().iter().all(|p| p.is_finite()));
    }

    // Fixed: the strand is stepped again once its quarantine ends, and a second of calm ends the episode.
    app.world_mut().resource_mut::<Poisoned>().0.clear();
    let quarantine_steps = (MAX_QUARANTINE_AFTER_FIVE / DT).ceil() as usize;
    let calm_steps = (QUARANTINE_WINDOW / DT).ceil() as usize + 2;
    for _ in 0..quarantine_steps + calm_steps {
        app.update();
    }
    assert!(drain_messages::<StrandFault>(&mut app).is_empty());
    assert_eq!(app.world().resource::<HairStatistics>().quarantined, 0);
    assert_eq!(strand(&app, victim).health(), &StrandHealth::default(), "the episode is over");
    assert_eq!(fault_lines(&logs::take()), (0, 0));
    // A new fault is a new episode: logged on its own, the strand reset and running on.
    app.world_mut().resource_mut::<Poisoned>().0.push(victim);
    app.update();
    let mut messages = drain_messages::<StrandFault>(&mut app).len();
    app.world_mut().resource_mut::<Poisoned>().0.clear();
    for _ in 0..10 {
        app.update();
        messages += drain_messages::<StrandFault>(&mut app).len();
    }
    assert_eq!(messages, 1);
    assert!(!strand(&app, victim).is_quarantined());
    assert_eq!(fault_lines(&logs::take()), (1, 0));
}

/// The fifth quarantine of an episode lasts 8 s.
const MAX_QUARANTINE_AFTER_FIVE: f64 = 8.0;

#[test]
fn two_hundred_strands_failing_on_every_step_log_a_few_lines_a_second() {
    let _log = logs::serial();
    let (mut app, strands) = poisoned_app(200);
    app.world_mut().resource_mut::<Poisoned>().0 = strands.clone();
    let mut messages = 0;
    for _ in 0..180 {
        app.update();
        messages += drain_messages::<StrandFault>(&mut app).len();
    }
    let lines = logs::take();
    let (single, summaries) = fault_lines(&lines);
    println!(
        "3 s of 200 poisoned strands: {} faults ({messages} messages), {} quarantined, {} log lines ({single} single, {summaries} summaries)",
        app.world().resource::<HairStatistics>().faults,
        app.world().resource::<HairStatistics>().quarantined,
        lines.len()
    );
    let statistics = app.world().resource::<HairStatistics>();
    // Each strand: a fault, a second one (quarantined 0.5 s), and retries after 0.5 s and 1 s.
    assert_eq!(statistics.faults, 4 * 200);
    assert_eq!(messages, 4 * 200);
    assert_eq!(statistics.quarantined, 200);
    // Four single lines per second, then one summary line per second at most.
    assert!(single <= 4 * 4, "{single} single lines");
    assert!(summaries <= 3, "{summaries} summaries");
    assert_eq!(lines.len(), single + summaries);
}
