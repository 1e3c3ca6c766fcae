//! The time integrator's energy behaviour and order of accuracy (issue 19).

mod common;

use bevy::math::DVec3;
use bevy_hair_sim::rod::{Integrator, Rod, RodMaterial, RodWorkspace, StepParams};
use common::straight_nodes;

const LENGTH: f64 = 0.3;
const EDGES: usize = 24;
const GRAVITY: DVec3 = DVec3::new(0.0, -9.81, 0.0);

/// The rod: L = 0.3 m, r = 1 mm, E = 2e8 Pa, ρ = 1000 kg/m³, ν = 0.5, 24 edges, pinned (not
/// clamped) at its first node, horizontal.
fn pinned_rod() -> Rod {
    let material = RodMaterial::round(1e-3, 2e8, 0.5, 1000.0);
    let mut rod = Rod::new(&straight_nodes(LENGTH, EDGES, DVec3::X), DVec3::Y, material).unwrap();
    rod.pin_node(0, DVec3::ZERO).unwrap();
    rod
}

/// Kinetic, elastic and gravitational energy, J.
fn total_energy(rod: &Rod) -> f64 {
    let potential: f64 = rod.masses().iter().zip(rod.positions()).map(|(m, x)| -m * GRAVITY.dot(*x)).sum();
    rod.kinetic_energy() + rod.elastic_energy().total() + potential
}

fn undamped(dt: f64, integrator: Integrator) -> StepParams {
    StepParams { dt, integrator, gravity: GRAVITY, air_damping: 0.0, internal_damping: 0.0, ..Default::default() }
}

#[test]
fn energy_experiment() {
    for (dt, integrator) in [1.0 / 60.0, 1e-3].into_iter().flat_map(|dt| schemes().into_iter().map(move |s| (dt, s))) {
        let mut rod = pinned_rod();
        let params = undamped(dt, integrator);
        let mut workspace = RodWorkspace::default();
        let initial = total_energy(&rod);
        let steps = (1.0 / dt).round() as usize;
        let mut iterations = 0;
        for step in 0..steps {
            let report = rod.step(&params, None, &mut workspace).unwrap_or_else(|e| panic!("step {step}: {e}"));
            iterations += report.newton_iterations;
        }
        let drop = initial - total_energy(&rod);
        // Energy scale: the potential energy the rod loses swinging down, m g L/2.
        let scale = rod.masses().iter().sum::<f64>() * 9.81 * LENGTH / 2.0;
        println!(
            "{integrator:?} dt {dt:.5}: lost {:.1} % of m g L/2, {:.2} Newton iterations/step",
            100.0 * drop / scale,
            iterations as f64 / steps as f64
        );
    }
}

#[test]
fn energy_diagnosis() {
    for (label, newton, tol, e) in [
        ("default", 4, 0.01, 2e8),
        ("converged", 20, 1e-9, 2e8),
        ("stiffer 2e9", 4, 0.01, 2e9),
        ("softer 2e7", 4, 0.01, 2e7),
    ] {
        let material = RodMaterial::round(1e-3, e, 0.5, 1000.0);
        let mut rod = Rod::new(&straight_nodes(LENGTH, EDGES, DVec3::X), DVec3::Y, material).unwrap();
        rod.pin_node(0, DVec3::ZERO).unwrap();
        let params = StepParams {
            max_newton_iterations: newton,
            newton_strain_tolerance: tol,
            ..undamped(1.0 / 60.0, Integrator::Bdf2)
        };
        let mut workspace = RodWorkspace::default();
        let initial = total_energy(&rod);
        let scale = rod.masses().iter().sum::<f64>() * 9.81 * LENGTH / 2.0;
        let mut line = String::new();
        for step in 0..60 {
            rod.step(&params, None, &mut workspace).unwrap();
            if step % 6 == 5 {
                line += &format!(" {:.1}", 100.0 * (initial - total_energy(&rod)) / scale);
            }
        }
        println!("{label}: lost % every 0.1 s:{line}");
    }
}

/// Tip positions at every multiple of `every` s over `duration`, stepping at `dt`.
fn tip_path(params: &StepParams, duration: f64, every: f64) -> Vec<DVec3> {
    let mut rod = pinned_rod();
    let mut workspace = RodWorkspace::default();
    let steps = (duration / params.dt).round() as usize;
    let stride = (every / params.dt).round() as usize;
    let mut path = Vec::new();
    for step in 1..=steps {
        rod.step(params, None, &mut workspace).unwrap_or_else(|e| panic!("step {step}: {e}"));
        if step % stride == 0 {
            path.push(rod.positions()[EDGES]);
        }
    }
    path
}

#[test]
fn order_experiment() {
    let converged = |dt, integrator| StepParams {
        max_newton_iterations: 30,
        newton_strain_tolerance: 1e-10,
        ..undamped(dt, integrator)
    };
    let reference = tip_path(&converged(1e-5, Integrator::Bdf2), 1.0, 1e-3);
    for integrator in schemes() {
        for (label, tight) in [("default Newton", false)] {
            let mut line = String::new();
            for dt in [4e-3, 2e-3, 1e-3] {
                let params = if tight { converged(dt, integrator) } else { undamped(dt, integrator) };
                let path = tip_path(&params, 1.0, 4e-3);
                let at_half = path[124].distance(reference[499]);
                let worst = path.iter().enumerate().map(|(i, p)| p.distance(reference[4 * i + 3])).fold(0.0, f64::max);
                line += &format!("  dt {dt}: at 0.5 s {at_half:.2e}, worst {worst:.2e}");
            }
            println!("{integrator:?} {label}:{line}");
        }
    }
}

fn schemes() -> Vec<Integrator> {
    vec![Integrator::BackwardEuler, Integrator::Bdf2]
}

#[test]
fn error_profile() {
    let converged = |dt, integrator| StepParams {
        max_newton_iterations: 30,
        newton_strain_tolerance: 1e-10,
        ..undamped(dt, integrator)
    };
    let stiff = |p: StepParams| StepParams { strain_tolerance: 1e-13, ..p };
    let reference = tip_path(&stiff(converged(1e-5, Integrator::Bdf2)), 1.0, 1e-3);
    for dt in [4e-3, 2e-3, 1e-3] {
        let path = tip_path(&stiff(undamped(dt, Integrator::Bdf2)), 1.0, dt);
        let k = (dt / 1e-3).round() as usize;
        let worst = path.iter().enumerate().map(|(i, p)| p.distance(reference[k * i + k - 1])).fold(0.0, f64::max);
        println!(
            "tight projection dt {dt}: worst {worst:.2e} at 0.5 s {:.2e}",
            path[(0.5 / dt) as usize - 1].distance(reference[499])
        );
    }
    let path = tip_path(&stiff(undamped(1e-3, Integrator::Bdf2)), 1.0, 1e-3);
    let mut line = String::new();
    for i in (49..1000).step_by(50) {
        let speed = (reference[i] - reference[i - 1]).length() / 1e-3;
        line += &format!(
            "\n t {:.2}: error {:.2e} tip speed {speed:.2} m/s, tip {:.3?}",
            (i + 1) as f64 * 1e-3,
            path[i].distance(reference[i]),
            reference[i]
        );
    }
    println!("{line}");
}

#[test]
fn reference_vibration() {
    let converged = |dt, integrator| StepParams {
        max_newton_iterations: 30,
        newton_strain_tolerance: 1e-10,
        ..undamped(dt, integrator)
    };
    let fine = tip_path(&converged(1e-5, Integrator::Bdf2), 1.0, 1e-5);
    let coarse = tip_path(&undamped(1e-3, Integrator::Bdf2), 1.0, 1e-3);
    let half = tip_path(&undamped(5e-4, Integrator::Bdf2), 1.0, 1e-3);
    let other = tip_path(&converged(2e-5, Integrator::Bdf2), 1.0, 1e-3);
    for window in [50usize, 100, 200] {
        let (mut worst_dev, mut worst_err, mut worst_half) = (0.0f64, 0.0f64, 0.0f64);
        for i in 1..1000 {
            let centre = 100 * i + 99;
            if centre < window || centre + window >= fine.len() {
                continue;
            }
            let mean = fine[centre - window..=centre + window].iter().copied().sum::<DVec3>() / (2 * window + 1) as f64;
            worst_dev = worst_dev.max(fine[centre].distance(mean));
            worst_err = worst_err.max(coarse[i].distance(mean));
            worst_half = worst_half.max(half[i].distance(mean));
        }
        println!(
            "window ±{} µs: reference's own vibration {worst_dev:.2e}, dt 1e-3 vs smoothed {worst_err:.2e}, dt 5e-4 vs smoothed {worst_half:.2e}",
            window * 10
        );
    }
    let refs = (0..1000).map(|i| other[i].distance(fine[100 * i + 99])).fold(0.0, f64::max);
    let halfs = (0..1000).map(|i| half[i].distance(fine[100 * i + 99])).fold(0.0, f64::max);
    println!("reference 2e-5 vs 1e-5: {refs:.2e}; dt 5e-4 vs reference {halfs:.2e}");
}

#[test]
fn error_signal() {
    let converged = |dt, integrator| StepParams {
        max_newton_iterations: 30,
        newton_strain_tolerance: 1e-10,
        ..undamped(dt, integrator)
    };
    let fine = tip_path(&converged(1e-5, Integrator::Bdf2), 0.5, 1e-3);
    let coarse = tip_path(&converged(1e-3, Integrator::Bdf2), 0.5, 1e-3);
    let mut line = String::new();
    for i in 380..430 {
        let d = coarse[i] - fine[i];
        line += &format!("\n{} ms: {:+.2e} {:+.2e}  tip {:.4?}", i + 1, d.x, d.y, fine[i]);
    }
    println!("{line}");
}

#[test]
fn tolerance_experiment() {
    for tol in [0.01, 0.005, 0.003, 0.001] {
        for dt in [1.0 / 60.0, 1.0 / 120.0] {
            let mut rod = pinned_rod();
            let params = StepParams { newton_strain_tolerance: tol, ..undamped(dt, Integrator::Bdf2) };
            let mut workspace = RodWorkspace::default();
            let initial = total_energy(&rod);
            let scale = rod.masses().iter().sum::<f64>() * 9.81 * LENGTH / 2.0;
            let mut iterations = 0;
            let steps = (1.0 / dt) as usize;
            for _ in 0..steps {
                iterations += rod.step(&params, None, &mut workspace).unwrap().newton_iterations;
            }
            println!(
                "tol {tol} dt {dt:.4}: lost {:.1} %, {:.2} iterations",
                100.0 * (initial - total_energy(&rod)) / scale,
                iterations as f64 / steps as f64
            );
        }
    }
}

#[test]
fn drape_trace() {
    use bevy_hair_sim::rod::{ColliderShape, Contacts, MovingCollider, RigidPose};
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        let radius = 0.05;
        let sphere = MovingCollider::fixed(ColliderShape::sphere(radius), 1.0, RigidPose::default());
        let colliders = [sphere];
        let contacts = Contacts { colliders: &colliders, thickness: 1e-4 };
        let nodes: Vec<DVec3> = straight_nodes(0.2, 32, DVec3::X)
            .iter()
            .map(|node| *node + DVec3::new(-0.1, radius + 0.02, 0.003))
            .collect();
        let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
        let params = StepParams {
            integrator,
            max_newton_iterations: std::env::var("NEWTON").map(|v| v.parse().unwrap()).unwrap_or(4),
            ..Default::default()
        };
        let mut workspace = RodWorkspace::default();
        for step in 0..60 {
            let r = rod.step_with_contacts(&params, None, &contacts, &mut workspace).unwrap();
            if step >= 1 && step < 60 && step % 3 == 0 {
                println!(
                    "{integrator:?} {step}: contacts {} newton {} middle {:.5?} v {:.4?} ends {:.4?} {:.4?}",
                    r.contacts,
                    r.newton_iterations,
                    rod.positions()[16],
                    rod.velocities()[16],
                    rod.positions()[0],
                    rod.positions()[32]
                );
            }
        }
    }
}
