//! Every control of the example's panel changes what the simulation does: the test writes the same
//! resources and components the panel writes (`HairSettings`, `HairPause`, `HairGroom`, `SimulatedStrand`) and
//! checks the effect against an unchanged run.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::SimulatedStrand;
use hair_sim_support::headless::{hair_app, strand};

/// What a run measured.
#[derive(Debug, Clone, Copy)]
struct Outcome {
    /// Mean drop of the strands' tips below where they were grown, m.
    tip_drop: f64,
    /// Kinetic energy of all strands, J.
    kinetic_energy: f64,
    /// Steps run, from the statistics.
    steps: u64,
    /// Newton iterations per strand in the last step, from the statistics.
    mean_newton_iterations: f64,
}

/// A head grown with `groom` on an app whose settings `change` edits, run for `steps` steps: the head
/// turns during the first half and holds still during the second.
fn run(groom: HairGroom, steps: usize, change: impl FnOnce(&mut HairSettings)) -> Outcome {
    let mut app = hair_app();
    change(&mut app.world_mut().resource_mut::<HairSettings>());
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0), groom)).id();
    app.update();
    let grown_tips: Vec<f64> = groomed_strands(&app, head).map(|entity| tip(&app, entity).y).collect();
    for step in 0..steps {
        let angle = 0.6 * (step.min(steps / 2) as f32 * 0.1).sin();
        app.world_mut().get_mut::<Transform>(head).unwrap().rotation = Quat::from_rotation_y(angle);
        app.update();
    }
    let tips: Vec<f64> = groomed_strands(&app, head).map(|entity| tip(&app, entity).y).collect();
    let kinetic_energy = groomed_strands(&app, head).map(|entity| strand(&app, entity).rod().kinetic_energy()).sum();
    let statistics = app.world().resource::<HairStatistics>();
    Outcome {
        tip_drop: grown_tips.iter().zip(&tips).map(|(grown, now)| grown - now).sum::<f64>() / tips.len() as f64,
        kinetic_energy,
        steps: statistics.steps,
        mean_newton_iterations: statistics.mean_newton_iterations,
    }
}

fn groomed_strands(app: &App, head: Entity) -> impl Iterator<Item = Entity> + '_ {
    app.world().get::<HeadStrands>(head).map_or(&[][..], HeadStrands::strands).iter().copied()
}

fn tip(app: &App, entity: Entity) -> bevy::math::DVec3 {
    *strand(app, entity).rod().positions().last().unwrap()
}

/// A small groom of short hair: stiff enough that its sag tells the material apart.
/// The grooms these tests tune: grown straight out along the scalp's normal and not preloaded, so that
/// gravity, damping and the material show in how they sag (combed, preloaded grooms: `tests/plugin/combed.rs`).
fn uncombed() -> HairGroom {
    HairGroom { combing: None, gravity_preload: 0.0, ..default() }
}

fn short_hair() -> HairGroom {
    HairGroom { strand_count: 40, segments: 8, style: HairStyle::Short, ..uncombed() }
}

#[test]
fn gravity_and_damping_change_the_motion() {
    let baseline = run(HairGroom { strand_count: 40, segments: 8, ..uncombed() }, 30, |_| {});
    let weightless = run(HairGroom { strand_count: 40, segments: 8, ..uncombed() }, 30, |s| s.gravity = Vec3::ZERO);
    let still_air = run(HairGroom { strand_count: 40, segments: 8, ..uncombed() }, 30, |s| s.air_damping = 0.0);
    let thick_air = run(HairGroom { strand_count: 40, segments: 8, ..uncombed() }, 30, |s| s.air_damping = 30.0);
    // Internal damping acts on elastic vibration: short hair on the turning head rings.
    let elastic = run(short_hair(), 30, |s| s.air_damping = 0.0);
    let viscous = run(short_hair(), 30, |s| {
        s.air_damping = 0.0;
        s.internal_damping = 0.02;
    });
    for (name, outcome) in [
        ("baseline", baseline),
        ("weightless", weightless),
        ("still air", still_air),
        ("thick air", thick_air),
        ("elastic", elastic),
        ("viscous", viscous),
    ] {
        println!("{name:>10}: tip drop {:.4} m, kinetic energy {:.3e} J", outcome.tip_drop, outcome.kinetic_energy);
    }
    assert!(baseline.tip_drop > 0.05, "hair grown straight out falls under gravity");
    assert!(weightless.tip_drop.abs() < 0.1 * baseline.tip_drop, "without gravity it hardly falls");
    assert!(thick_air.kinetic_energy < 0.5 * still_air.kinetic_energy, "air damping slows the hair");
    assert!(viscous.kinetic_energy < 0.5 * elastic.kinetic_energy, "internal damping slows the hair");
}

#[test]
fn the_material_changes_how_far_short_hair_sags() {
    let human = RodMaterial::human_hair();
    let radius = human.semi_axis_1;
    let poisson_ratio = human.youngs_modulus / (2.0 * human.shear_modulus) - 1.0;
    let with = |radius: f64, youngs_modulus: f64, density: f64| {
        let material = RodMaterial::round(radius, youngs_modulus, poisson_ratio, density);
        run(short_hair(), 60, move |settings| settings.default_material = material).tip_drop
    };
    let baseline = with(radius, human.youngs_modulus, human.density);
    let softer = with(radius, 0.1 * human.youngs_modulus, human.density);
    let thicker = with(2.0 * radius, human.youngs_modulus, human.density);
    let heavier = with(radius, human.youngs_modulus, 3.0 * human.density);
    println!("tip drop: human {baseline:.5} m, E/10 {softer:.5}, 2r {thicker:.5}, 3ρ {heavier:.5}");
    // Cantilever sag goes as ρ r² / (E r⁴): tenfold softer sags about tenfold, twice as thick a quarter.
    assert!(softer > 4.0 * baseline, "a softer fibre sags more");
    assert!(thicker < 0.5 * baseline, "a thicker fibre sags less");
    assert!(heavier > 2.0 * baseline, "a denser fibre sags more");
}

#[test]
fn solver_limits_apply() {
    let groom = HairGroom { strand_count: 20, segments: 8, ..uncombed() };
    let capped = run(groom.clone(), 10, |settings| settings.max_newton_iterations = 1);
    assert!(capped.mean_newton_iterations <= 1.0, "{} Newton iterations", capped.mean_newton_iterations);
    let stopped = run(groom, 10, |settings| settings.max_steps_per_frame = 0);
    assert_eq!(stopped.steps, 0, "no step runs with no steps allowed per frame");
}

#[test]
fn groom_count_segments_and_style_respawn_the_hair() {
    let mut app = hair_app();
    let groom = HairGroom { strand_count: 30, segments: 6, ..uncombed() };
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0), groom)).id();
    let hand_made = app.world_mut().spawn((HairStrand::straight(Vec3::Y * 0.1, Vec3::Y, 0.1, 4), StrandOf(head))).id();
    app.update();
    let statistics = app.world().resource::<HairStatistics>();
    assert_eq!((statistics.strands, statistics.nodes), (31, 30 * 7 + 5));

    app.world_mut().get_mut::<HairGroom>(head).unwrap().strand_count = 45;
    app.update();
    app.world_mut().get_mut::<HairGroom>(head).unwrap().segments = 10;
    app.update();
    let statistics = app.world().resource::<HairStatistics>();
    assert_eq!((statistics.strands, statistics.nodes), (46, 45 * 11 + 5));
    assert!(app.world().get::<SimulatedStrand>(hand_made).is_some(), "a strand spawned by hand is kept");

    // Curly hair keeps its curls while the head moves: its bending stays near its rest curvature, far
    // above what straight hair bends to in the same motion.
    let curvature = |app: &App, rest: bool| -> f64 {
        let mut sum = 0.0;
        for entity in groomed_strands(app, head).filter(|&entity| entity != hand_made) {
            let rod = strand(app, entity).rod();
            for vertex in 1..rod.edge_count() {
                sum += if rest { rod.rest_curvatures()[vertex] } else { rod.vertex_curvature_and_twist(vertex).0 }
                    .length();
            }
        }
        sum
    };
    let shake = |app: &mut App| {
        for step in 0..120 {
            let time = step as f32 / 60.0;
            let mut transform = app.world_mut().get_mut::<Transform>(head).unwrap();
            transform.translation.x = 0.1 * (6.0 * time).sin();
            transform.rotation = Quat::from_rotation_y(0.8 * (5.0 * time).sin());
            app.update();
        }
    };
    shake(&mut app);
    let straight = curvature(&app, false);
    app.world_mut().get_mut::<HairGroom>(head).unwrap().style = HairStyle::Curly;
    app.update();
    let rest = curvature(&app, true);
    shake(&mut app);
    let curly = curvature(&app, false);
    // Curvatures are the discrete, integrated ones: 2 tan(turning angle / 2) per vertex.
    println!(
        "curvature summed over 405 vertices: curly at rest {rest:.1}, curly moving {curly:.1}, straight moving {straight:.1}"
    );
    assert!(rest > 0.5 * 405.0, "curly hair turns by more than half a radian per vertex at rest");
    assert!((curly / rest - 1.0).abs() < 0.25, "the curls are kept: {curly} against {rest} at rest");
    assert!(straight < 0.3 * curly, "straight hair bends far less ({straight}) than curls ({curly})");
}

#[test]
fn short_hair_stands_out_and_long_hair_hangs() {
    let mut app = hair_app();
    let groom = HairGroom { strand_count: 60, segments: 12, style: HairStyle::Short, ..uncombed() };
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0), groom)).id();
    // How far the strands point along their root normal, as a fraction of their length, once settled.
    let outwards = |app: &mut App| -> f64 {
        for _ in 0..90 {
            app.update();
        }
        let strands: Vec<Entity> = groomed_strands(app, head).collect();
        let mut fraction = 0.0;
        for &entity in &strands {
            let rod = strand(app, entity).rod();
            let positions = rod.positions();
            let normal = (positions[1] - positions[0]).normalize();
            fraction += (positions[rod.edge_count()] - positions[0]).dot(normal) / rod.rest_length();
        }
        fraction / strands.len() as f64
    };
    let short = outwards(&mut app);
    app.world_mut().get_mut::<HairGroom>(head).unwrap().style = HairStyle::Long;
    let long = outwards(&mut app);
    println!("tips along the root normal: short {short:.3} of their length, long {long:.3}");
    assert!(short > 0.9, "short hair stands out");
    assert!(long < 0.5, "long hair falls");
}

#[test]
fn pause_single_step_and_reset() {
    let mut app = hair_app();
    let groom = HairGroom { strand_count: 10, segments: 8, ..uncombed() };
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0), groom)).id();
    app.update();
    let strands: Vec<Entity> = groomed_strands(&app, head).collect();
    let rest: Vec<Vec<Vec3>> = strands
        .iter()
        .map(|&entity| {
            app.world().get::<HairStrand>(entity).unwrap().nodes.iter().map(|node| node + 1.6 * Vec3::Y).collect()
        })
        .collect();
    for _ in 0..20 {
        app.update();
    }
    let steps = app.world().resource::<HairStatistics>().steps;
    let tip_before = tip(&app, strands[0]);

    app.world_mut().resource_mut::<HairPause>().paused = true;
    for _ in 0..5 {
        app.update();
    }
    assert_eq!(app.world().resource::<HairStatistics>().steps, steps, "no step while paused");
    assert_eq!(tip(&app, strands[0]), tip_before, "the hair waits while paused");

    app.world_mut().resource_mut::<HairPause>().step_once();
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(app.world().resource::<HairStatistics>().steps, steps + 1, "one single step");
    assert_ne!(tip(&app, strands[0]), tip_before, "the single step moved the hair");

    // The panel's reset button: every strand back in its rest pose, at rest.
    for &entity in &strands {
        app.world_mut().get_mut::<SimulatedStrand>(entity).unwrap().reset_to_rest();
    }
    for (&entity, rest) in strands.iter().zip(&rest) {
        let rod = strand(&app, entity).rod();
        let offset =
            rod.positions().iter().zip(rest).map(|(now, rest)| now.distance(rest.as_dvec3())).fold(0.0, f64::max);
        assert!(offset < 1e-6, "strand {entity} is {offset} m from its rest pose");
        assert_eq!(rod.kinetic_energy(), 0.0);
    }

    app.world_mut().resource_mut::<HairPause>().paused = false;
    app.update();
    assert_eq!(app.world().resource::<HairStatistics>().steps, steps + 2, "running again");
}
