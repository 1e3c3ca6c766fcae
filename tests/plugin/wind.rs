//! Air drag relative to the air, and the wind: a strand in steady wind hangs where the drag law says,
//! gusts and turbulence repeat bit for bit with their seed, and no wind changes nothing.

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{Contacts, Rod, RodWorkspace, StepLoads, StepParams};
use hair_sim_support::headless::{hair_app, spawn_head, strand};
use hair_sim_support::logs;
use hair_sim_support::straight_nodes;

/// The direction (root to tip) a pinned straight strand settles along in a steady wind `wind` under
/// gravity `g`, found by the core; air drag `gamma` (1/s) across and `ratio` of it along the strand.
fn settled_direction(wind: DVec3, gamma: f64, ratio: f64) -> DVec3 {
    let mut rod = Rod::new(&straight_nodes(0.2, 20, DVec3::NEG_Y), DVec3::X, RodMaterial::human_hair()).unwrap();
    rod.pin_node(0, DVec3::ZERO).unwrap();
    let params = StepParams { air_damping: gamma, axial_drag_ratio: ratio, ..Default::default() };
    let air = vec![wind; rod.node_count()];
    let loads = StepLoads { air_velocities: Some(&air), ..StepLoads::default() };
    let mut workspace = RodWorkspace::default();
    for _ in 0..900 {
        rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
    }
    let speed = rod.velocities().iter().map(|v| v.length()).fold(0.0, f64::max);
    assert!(speed < 1e-4, "settled: {speed} m/s");
    (rod.positions()[20] - rod.positions()[0]).normalize()
}

/// The direction `d` in the plane of gravity (−Y) and a wind along +X in which a straight strand feels a
/// load along itself: the drag per mass is `γ (U − (1 − r)(U·d) d)`, and with gravity it must be
/// parallel to `d` (bisection on the angle from the vertical, independent of the law's algebra).
fn predicted_direction(speed: f64, gamma: f64, ratio: f64) -> DVec3 {
    let direction = |angle: f64| DVec3::new(angle.sin(), -angle.cos(), 0.0);
    let torque = |angle: f64| {
        let d = direction(angle);
        let wind = DVec3::new(speed, 0.0, 0.0);
        let load = DVec3::new(0.0, -9.81, 0.0) + gamma * (wind - (1.0 - ratio) * wind.dot(d) * d);
        load.cross(d).z
    };
    let (mut low, mut high) = (0.0, std::f64::consts::FRAC_PI_2);
    for _ in 0..60 {
        let middle = 0.5 * (low + high);
        if torque(low) * torque(middle) <= 0.0 { high = middle } else { low = middle }
    }
    direction(0.5 * (low + high))
}

#[test]
fn a_strand_in_steady_wind_hangs_along_the_effective_gravity() {
    // Drag the same per mass in every direction: it hangs along g + γU.
    let (gamma, wind) = (3.0, DVec3::new(2.0, 0.0, 0.0));
    let settled = settled_direction(wind, gamma, 1.0);
    let effective = (DVec3::new(0.0, -9.81, 0.0) + gamma * wind).normalize();
    let error = settled.angle_between(effective).to_degrees();
    println!("uniform drag: settled {settled}, g + γU along {effective}: {error:.3}°");
    assert!(error < 1.0, "{error}° off g + γU");
    assert!((predicted_direction(2.0, gamma, 1.0).angle_between(effective)).to_degrees() < 1e-6);

    // A cylinder's drag, half as strong along it: at rest the part along the strand only adds to its
    // tension, so the balance (and the strand) lies along g + γU all the same.
    let settled = settled_direction(wind, gamma, 0.5);
    let predicted = predicted_direction(2.0, gamma, 0.5);
    let error = settled.angle_between(predicted).to_degrees();
    let angle = |d: DVec3| d.x.atan2(-d.y).to_degrees();
    println!(
        "cylinder drag (r = ½): settled at {:.2}° from the vertical, predicted {:.2}° (uniform: {:.2}°)",
        angle(settled),
        angle(predicted),
        angle(effective)
    );
    assert!(error < 1.0, "{error}° off the predicted balance");
    assert!(predicted.angle_between(effective).to_degrees() < 1e-6, "the balance ignores drag along the strand");
}

#[test]
fn still_air_given_as_zeros_changes_nothing() {
    let rod = || {
        let mut rod = Rod::new(&straight_nodes(0.2, 16, DVec3::X), DVec3::Y, RodMaterial::human_hair()).unwrap();
        rod.clamp_root_in_place();
        rod
    };
    let (mut still, mut zeros) = (rod(), rod());
    let air = vec![DVec3::ZERO; still.node_count()];
    let params = StepParams::default();
    let mut workspace = RodWorkspace::default();
    for _ in 0..120 {
        still.step(&params, None, &mut workspace).unwrap();
        let loads = StepLoads { air_velocities: Some(&air), ..StepLoads::default() };
        zeros.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
        assert_eq!(still.positions(), zeros.positions());
    }
}

/// Every node of every strand of a 40-strand head after 90 steps in `wind` (none: the default, calm).
fn hair_after(wind: Option<HairWind>) -> Vec<DVec3> {
    let mut app = hair_app();
    if let Some(wind) = wind {
        app.insert_resource(wind);
    }
    let (_, strands) = spawn_head(&mut app, Transform::from_rotation(Quat::from_rotation_y(0.3)), 40, 12);
    for _ in 0..90 {
        app.update();
    }
    strands.iter().flat_map(|&entity| strand(&app, entity).rod().positions().to_vec()).collect()
}

#[test]
fn gusts_and_turbulence_repeat_bit_for_bit_with_their_seed() {
    let gusty = |seed| HairWind {
        velocity: Vec3::new(1.5, 0.0, -1.0),
        gusts: 1.0,
        gust_period: 0.5,
        turbulence: 0.8,
        turbulence_scale: 0.2,
        seed,
        ..default()
    };
    let still = hair_after(None);
    let first = hair_after(Some(gusty(11)));
    let again = hair_after(Some(gusty(11)));
    let other = hair_after(Some(gusty(12)));
    assert_eq!(first, again, "the same seed, the same hair");
    let moved = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
    println!(
        "largest difference: wind vs still {:.4} m, seed 11 vs 12 {:.4} m",
        moved(&first, &still),
        moved(&first, &other)
    );
    assert!(moved(&first, &still) > 0.01, "the wind moves the hair");
    assert!(moved(&first, &other) > 1e-3, "another seed, other gusts and eddies");
    // A calm wind (any gusts need a mean wind) adds nothing: the same as the default, bit for bit.
    assert_eq!(hair_after(Some(HairWind { gusts: 2.0, ..default() })), still);
}

#[test]
fn an_invalid_wind_is_reported_once_and_ignored() {
    let _log = logs::serial();
    let mut app = hair_app();
    app.insert_resource(HairWind { velocity: Vec3::new(f32::NAN, 0.0, 0.0), ..default() });
    let (_, strands) = spawn_head(&mut app, Transform::default(), 4, 8);
    for _ in 0..10 {
        app.update();
    }
    let rod = strand(&app, strands[0]).rod();
    assert!(rod.positions().iter().all(|p| p.is_finite()), "no NaN reaches the hair");
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    let lines = logs::take();
    let wind_lines = lines.iter().filter(|(_, line)| line.contains("HairWind::velocity")).count();
    assert_eq!(wind_lines, 1, "reported once in 10 steps: {lines:?}");
}
