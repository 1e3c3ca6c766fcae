//! The time integrators against numbers: energy kept by a swinging rod, order of accuracy against a
//! fine-step reference, the numerical damping of a pendulum against the formulas in the README, and
//! settling after a shake with the physical damping on.

use bevy::math::{DQuat, DVec3};
use bevy_hair_sim::rod::{Integrator, Rod, RodMaterial, RodWorkspace, StepParams};
use hair_sim_support::{max_speed, stiff_rod_material, straight_nodes};

const LENGTH: f64 = 0.3;
const EDGES: usize = 24;
const GRAVITY: DVec3 = DVec3::new(0.0, -9.81, 0.0);

/// The test rod: L = 0.3 m, r = 1 mm, E = 2e8 Pa, ρ = 1000 kg/m³, ν = 0.5, 24 edges, pinned (not
/// clamped) at its first node, horizontal.
fn pinned_rod() -> Rod {
    let material = RodMaterial::round(1e-3, 2e8, 0.5, 1000.0);
    let mut rod = Rod::new(&straight_nodes(LENGTH, EDGES, DVec3::X), DVec3::Y, material).unwrap();
    rod.pin_node(0, DVec3::ZERO).unwrap();
    rod
}

/// Kinetic, elastic and gravitational energy, J, the gravitational energy from the pin's height.
fn total_energy(rod: &Rod) -> f64 {
    let potential: f64 = rod.masses().iter().zip(rod.positions()).map(|(m, x)| -m * GRAVITY.dot(*x)).sum();
    rod.kinetic_energy() + rod.elastic_energy().total() + potential
}

/// No physical damping at all.
fn undamped(dt: f64, integrator: Integrator) -> StepParams {
    StepParams { dt, integrator, gravity: GRAVITY, air_damping: 0.0, internal_damping: 0.0, ..Default::default() }
}

/// The share of the released rod's energy left after 1 s: the energy above the rod's lowest state
/// (hanging straight down, `m g L/2` below the start), which is all it can lose.
fn energy_kept_after_one_second(params: &StepParams) -> f64 {
    let mut rod = pinned_rod();
    let mut workspace = RodWorkspace::default();
    let lowest = total_energy(&rod) - rod.masses().iter().sum::<f64>() * 9.81 * LENGTH / 2.0;
    let available = total_energy(&rod) - lowest;
    for step in 0..(1.0 / params.dt).round() as usize {
        rod.step(params, None, &mut workspace).unwrap_or_else(|error| panic!("step {step}: {error}"));
    }
    (total_energy(&rod) - lowest) / available
}

#[test]
fn a_swinging_rod_keeps_its_energy_with_bdf2_and_loses_it_with_backward_euler() {
    let mut kept = Vec::new();
    for dt in [1.0 / 60.0, 1e-3] {
        for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
            let share = energy_kept_after_one_second(&undamped(dt, integrator));
            println!("dt = {dt:.5} s, {integrator:?}: {:.1} % of the energy after 1 s", 100.0 * share);
            kept.push(share);
        }
    }
    let [euler_60, bdf2_60, euler_1000, bdf2_1000] = kept[..] else { unreachable!() };
    assert!(bdf2_60 >= 0.90, "BDF2 at 60 Hz keeps {:.1} % (at least 90 %)", 100.0 * bdf2_60);
    assert!(bdf2_1000 >= 0.99, "BDF2 at 1 kHz keeps {:.1} % (at least 99 %)", 100.0 * bdf2_1000);
    assert!(bdf2_60 <= 1.0 + 1e-3 && bdf2_1000 <= 1.0 + 1e-3, "no energy is created");
    // The reason for the change: backward Euler removes most of it by itself.
    assert!(euler_60 < 0.5 && euler_1000 < 0.95, "backward Euler: {euler_60}, {euler_1000}");
}

/// Tip positions at every multiple of `every` s over `duration`, stepping at `params.dt`.
fn tip_path(params: &StepParams, duration: f64, every: f64) -> Vec<DVec3> {
    let mut rod = pinned_rod();
    let mut workspace = RodWorkspace::default();
    let steps = (duration / params.dt).round() as usize;
    let stride = (every / params.dt).round() as usize;
    let mut path = Vec::new();
    for step in 1..=steps {
        rod.step(params, None, &mut workspace).unwrap_or_else(|error| panic!("step {step}: {error}"));
        if step % stride == 0 {
            path.push(rod.positions()[EDGES]);
        }
    }
    path
}

#[test]
fn bdf2_converges_at_second_order_to_a_fine_step_reference() {
    // The reference: BDF2 at 10 µs with its Newton iterations converged, the tip every millisecond.
    let converged =
        |dt| StepParams { max_newton_iterations: 30, newton_strain_tolerance: 1e-10, ..undamped(dt, Integrator::Bdf2) };
    let reference = tip_path(&converged(1e-5), 1.0, 1e-3);
    let mut at_half_second = Vec::new();
    for dt in [4e-3, 2e-3, 1e-3] {
        // Every step's tip against the reference at the same time.
        let path = tip_path(&undamped(dt, Integrator::Bdf2), 1.0, dt);
        let stride = (dt / 1e-3).round() as usize;
        let exact = |step: usize| reference[stride * (step + 1) - 1];
        let errors: Vec<f64> = path.iter().enumerate().map(|(step, tip)| tip.distance(exact(step))).collect();
        let worst = errors.iter().copied().fold(0.0, f64::max);
        let half = errors[500 / stride - 1];
        println!("BDF2, dt = {dt}: tip error at 0.5 s {half:.2e} m, worst over 1 s {worst:.2e} m");
        at_half_second.push((half, worst));
    }
    for pair in at_half_second.windows(2) {
        let ratio = pair[0].0 / pair[1].0;
        assert!(ratio >= 3.5, "halving dt shrinks the error at 0.5 s by {ratio:.2} (at least 3.5)");
    }
    let euler = tip_path(&undamped(1e-3, Integrator::BackwardEuler), 1.0, 1e-3);
    let euler_worst = euler.iter().zip(&reference).map(|(tip, exact)| tip.distance(*exact)).fold(0.0, f64::max);
    let worst = at_half_second[2].1;
    println!("backward Euler, dt = 0.001: worst over 1 s {euler_worst:.2e} m");
    // Measured 3.2e-4 m: the third and fourth bending modes (about 250 rad/s, ω dt = 0.25) of this floppy
    // rod are damped by BDF2 at 1 ms while the reference keeps them (`docs/testing.md`, the integrator).
    assert!(worst < 4e-4, "BDF2 at 1 ms stays within {worst:.2e} m of the reference");
    assert!(worst < euler_worst / 20.0, "BDF2 {worst:.2e} m against backward Euler {euler_worst:.2e} m");
}

/// Amplitude lost per second by an undamped oscillation of angular frequency `omega` (rad/s) stepped at
/// `dt` (s), as the README's table: from the schemes' amplification factors for `y' = iωy`.
fn numerical_damping_rate(integrator: Integrator, omega: f64, dt: f64) -> f64 {
    let z = omega * dt;
    let modulus = match integrator {
        // |1/(1 − iz)|.
        Integrator::BackwardEuler => 1.0 / (1.0 + z * z).sqrt(),
        // The larger root of (3/2 − iz) ζ² − 2ζ + 1/2 = 0: ζ = (2 + √(1 + 2iz)) / (3 − 2iz).
        Integrator::Bdf2 => {
            let (r, phi) = ((1.0 + 4.0 * z * z).sqrt().sqrt(), 0.5 * (2.0 * z).atan());
            let numerator = ((2.0 + r * phi.cos()).powi(2) + (r * phi.sin()).powi(2)).sqrt();
            numerator / (9.0 + 4.0 * z * z).sqrt()
        }
    };
    -modulus.ln() / dt
}

#[test]
fn a_pendulum_loses_amplitude_at_the_rate_the_readme_gives() {
    // A stiff 30 cm rod pinned at its top swings as a rigid pendulum, ω = √(3g / 2L) ≈ 7 rad/s (its
    // bending modes are hundreds of times faster), 0.05 rad from the vertical, no physical damping.
    let dt = 1.0 / 60.0;
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        let tilt = DQuat::from_rotation_z(0.05);
        let nodes: Vec<DVec3> = straight_nodes(LENGTH, 12, DVec3::NEG_Y).iter().map(|node| tilt * *node).collect();
        let mut rod = Rod::new(&nodes, DVec3::Z, stiff_rod_material()).unwrap();
        rod.pin_node(0, DVec3::ZERO).unwrap();
        let params = undamped(dt, integrator);
        let mut workspace = RodWorkspace::default();
        // Swing peaks (the tip's |x| at its turning points) and when they happen.
        let mut peaks = Vec::new();
        let mut previous = [rod.positions()[12].x; 2];
        for step in 1..=(10.0 / dt) as usize {
            rod.step(&params, None, &mut workspace).unwrap();
            let x = rod.positions()[12].x;
            if previous[1].abs() > previous[0].abs() && previous[1].abs() >= x.abs() {
                peaks.push((step as f64 * dt - dt, previous[1].abs()));
            }
            previous = [previous[1], x];
        }
        let (first, last) = (peaks[1], peaks[peaks.len() - 1]);
        let measured_rate = (first.1 / last.1).ln() / (last.0 - first.0);
        let period = 2.0 * (last.0 - first.0) / (peaks.len() - 2) as f64;
        let omega = std::f64::consts::TAU / period;
        let predicted = numerical_damping_rate(integrator, omega, dt);
        println!(
            "{integrator:?}: ω = {omega:.3} rad/s (rigid pendulum {:.3}), amplitude lost at {measured_rate:.4}/s, \
             formula {predicted:.4}/s",
            (1.5 * 9.81 / LENGTH).sqrt()
        );
        match integrator {
            Integrator::BackwardEuler => assert!(
                (measured_rate / predicted - 1.0).abs() < 0.05,
                "backward Euler damps at {measured_rate}/s, the formula says {predicted}/s"
            ),
            // BDF2's 0.003/s is a 3 % loss over the 10 s: measured within a factor of 3 (the projection's
            // tolerance, `StepParams::strain_tolerance`, adds its own bit; at 1e-6 it added 0.02/s).
            Integrator::Bdf2 => assert!(
                measured_rate < 3.0 * predicted,
                "BDF2 damps at {measured_rate}/s, the formula says {predicted}/s"
            ),
        }
    }
}

#[test]
fn shaken_hair_comes_to_rest_with_the_physical_damping() {
    // A 20 cm human hair on a root shaken 3 cm sideways at 2 Hz for 1 s, then held still: how long
    // until every node moves slower than 1 mm/s, with the default air and internal damping.
    let dt = 1.0 / 60.0;
    let mut settling = Vec::new();
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        let mut rod = Rod::new(&straight_nodes(0.2, 16, DVec3::NEG_Y), DVec3::X, RodMaterial::human_hair()).unwrap();
        let root = [rod.positions()[0], rod.positions()[1]];
        let params = StepParams { integrator, ..Default::default() };
        let mut workspace = RodWorkspace::default();
        let mut rest = None;
        for step in 0..1200 {
            let t = step as f64 * dt;
            let shift = if t < 1.0 {
                DVec3::new(0.03 * (std::f64::consts::TAU * 2.0 * t).sin(), 0.0, 0.0)
            } else {
                DVec3::ZERO
            };
            rod.clamp_edge(0, root[0] + shift, root[1] + shift, DVec3::X).unwrap();
            rod.step(&params, None, &mut workspace).unwrap();
            if t > 1.0 && rest.is_none() && max_speed(&rod) < 1e-3 {
                rest = Some(t - 1.0);
            }
        }
        let rest = rest.unwrap_or_else(|| panic!("{integrator:?}: still moving at {} m/s after 19 s", max_speed(&rod)));
        println!("{integrator:?}: at rest (below 1 mm/s) {rest:.2} s after the shaking stops");
        settling.push(rest);
    }
    assert!(settling[1] > settling[0], "BDF2 damps less by itself: {settling:?}");
    assert!(settling[1] < 8.0, "BDF2's hair settles within 8 s: {settling:?}");
}
