//! Real human hair at a game's time step: stable under violent root motion, hangs when long,
//! sticks out when short.

use bevy::math::{DQuat, DVec3};
use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};
use hair_sim_support::{max_speed, run, stiff_rod_material, straight_nodes};
use std::f64::consts::PI;

/// A head at the origin whose hair root sits 10 cm out along its local X, the hair pointing outwards
/// horizontally. Returns the rod and its clamp in head space (start, end, material direction).
fn hair_on_head(length: f64, edges: usize, material: RodMaterial) -> (Rod, [DVec3; 3]) {
    let root = DVec3::new(0.1, 0.0, 0.0);
    let nodes: Vec<DVec3> = straight_nodes(length, edges, DVec3::X).into_iter().map(|p| p + root).collect();
    let rod = Rod::new(&nodes, DVec3::Y, material).unwrap();
    (rod, [nodes[0], nodes[1], DVec3::Y])
}

/// Head pose at time `t` while moving: shaken 10 cm along X at 3 Hz and spun about Y at 2 rev/s.
fn shaken_and_spun(t: f64) -> (DQuat, DVec3) {
    (DQuat::from_rotation_y(2.0 * PI * 2.0 * t), DVec3::new(0.1 * (2.0 * PI * 3.0 * t).sin(), 0.0, 0.0))
}

/// Moves the root clamp with the head pose and steps once; returns the strain measured from positions.
fn step_with_head(
    rod: &mut Rod,
    clamp: &[DVec3; 3],
    pose: (DQuat, DVec3),
    params: &StepParams,
    ws: &mut RodWorkspace,
) -> f64 {
    let (rotation, translation) = pose;
    rod.clamp_edge(0, rotation * clamp[0] + translation, rotation * clamp[1] + translation, rotation * clamp[2])
        .unwrap();
    if let Err(error) = rod.step(params, None, ws) {
        panic!("step failed: {error}");
    }
    assert!(rod.positions().iter().all(|p| p.is_finite()));
    rod.positions()
        .windows(2)
        .zip(rod.rest_lengths())
        .map(|(pair, rest)| ((pair[1] - pair[0]).length() / rest - 1.0).abs())
        .fold(0.0, f64::max)
}

#[test]
fn shaken_and_spun_hair_stays_finite_unstretched_and_comes_to_rest() {
    let params = StepParams::default();
    let (mut rod, clamp) = hair_on_head(0.25, 32, RodMaterial::human_hair());
    let mut workspace = RodWorkspace::default();
    let steps = (10.0 / params.dt) as usize;
    let mut worst_strain: f64 = 0.0;
    let mut fastest: f64 = 0.0;
    for step in 1..=steps {
        let pose = shaken_and_spun(step as f64 * params.dt);
        let strain = step_with_head(&mut rod, &clamp, pose, &params, &mut workspace);
        worst_strain = worst_strain.max(strain);
        fastest = fastest.max(max_speed(&rod));
    }
    println!("10 s of shaking: largest strain {worst_strain:e}, fastest node {fastest:.2} m/s");
    assert!(worst_strain < 1e-3, "strain {worst_strain:e}");
    assert!(fastest > 1.0, "the hair really was whipped around ({fastest} m/s)");
    let final_pose = shaken_and_spun(steps as f64 * params.dt);
    let mut speed_after = Vec::new();
    for step in 1..=(5.0 / params.dt) as usize {
        worst_strain = worst_strain.max(step_with_head(&mut rod, &clamp, final_pose, &params, &mut workspace));
        if step % 60 == 0 {
            speed_after.push(max_speed(&rod));
        }
    }
    let listed: Vec<String> = speed_after.iter().map(|s| format!("{s:.2e}")).collect();
    println!("largest node speed each second after the head stops (m/s): {}", listed.join(", "));
    assert!(worst_strain < 1e-3);
    assert!(*speed_after.last().unwrap() < 1e-3, "at rest 5 s after the motion stops: {speed_after:?}");
}

#[test]
fn long_hair_hangs_and_short_hair_sticks_out() {
    let params = StepParams::default();
    let mut workspace = RodWorkspace::default();
    let mut settle = |length: f64, edges: usize| {
        let nodes = straight_nodes(length, edges, DVec3::X);
        let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
        rod.clamp_root_in_place();
        run(&mut rod, &params, 600, &mut workspace);
        assert!(max_speed(&rod) < 1e-3, "settled");
        rod.positions()[edges]
    };
    let long_tip = settle(0.25, 32);
    println!("25 cm hair: tip at {long_tip} (drop {:.1} % of its length)", -100.0 * long_tip.y / 0.25);
    assert!(long_tip.y < -0.6 * 0.25, "a 25 cm hair hangs: tip {long_tip}");
    assert!(long_tip.x < 0.5 * 0.25, "and hangs down, not out: tip {long_tip}");
    let short_tip = settle(0.03, 32);
    let droop = (-short_tip.y).atan2(short_tip.x).to_degrees();
    println!("3 cm hair: tip at {short_tip}, {droop:.2}° below horizontal");
    assert!(droop > 0.0 && droop < 30.0, "a 3 cm hair sticks out: {droop}° below horizontal");
}

#[test]
fn whole_range_of_lengths_resolutions_and_materials_is_stable_at_a_sixtieth_of_a_second() {
    let params = StepParams::default();
    let mut workspace = RodWorkspace::default();
    for (material, label) in [(RodMaterial::human_hair(), "hair"), (stiff_rod_material(), "1 mm rod")] {
        for length in [0.05, 0.4] {
            for edges in [8, 64] {
                let (mut rod, clamp) = hair_on_head(length, edges, material);
                let mut worst: f64 = 0.0;
                for step in 1..=120 {
                    let pose = shaken_and_spun(step as f64 * params.dt);
                    worst = worst.max(step_with_head(&mut rod, &clamp, pose, &params, &mut workspace));
                }
                println!("{label}, {length} m, {edges} edges: largest strain {worst:e}");
                assert!(worst < 1e-3, "{label}, {length} m, {edges} edges: strain {worst:e}");
            }
        }
    }
}
