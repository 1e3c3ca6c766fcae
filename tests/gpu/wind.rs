//! The wind on the GPU (`GpuStrandSolver::set_air`): gusts, eddies and a jet sampled by the step at every
//! node, against the CPU's step given the same air at every node.

use bevy::math::{DQuat, DVec3};
use bevy::prelude::{GlobalTransform, Transform, Vec3};
use bevy_hair_sim::gpu::{GpuHeadStep, GpuStrandInput, GpuStrandSolver};
use bevy_hair_sim::prelude::{HairWind, HairWindSource};
use bevy_hair_sim::rod::{AirSnapshot, Contacts, Rod, RodMaterial, RodWorkspace, StepLoads, StepParams};
use hair_sim_support::straight_nodes;

use crate::colliders::apart;
use crate::step::device;

/// The head the strands hang from, away from the origin.
const HEAD: DVec3 = DVec3::new(0.3, 1.6, -0.2);
/// Steps of 1/60 s (1.5 s).
const STEPS: usize = 90;

/// Eight strands of 20 cm in 16 edges, rooted in a row across X and hanging straight down.
fn strands() -> Vec<Rod> {
    (0..8)
        .map(|k| {
            let root = HEAD + DVec3::new(0.02 * (k as f64 - 3.5), 0.0, 0.0);
            let nodes: Vec<DVec3> = straight_nodes(0.2, 16, -DVec3::Y).into_iter().map(|p| p + root).collect();
            let mut rod = Rod::new(&nodes, DVec3::X, RodMaterial::human_hair()).unwrap();
            rod.clamp_root_in_place();
            rod
        })
        .collect()
}

/// The strands as the GPU takes them: on the one head, 0.1 mm thick, each standing for itself.
fn inputs(rods: &[Rod]) -> Vec<GpuStrandInput<'_>> {
    rods.iter()
        .map(|rod| GpuStrandInput { rod, head: 0, thickness: 1e-4, groomed: None, hairs: 1.0, groomed_fractions: None })
        .collect()
}

/// RMS distance between two sets of strands' nodes, m.
fn rms(a: &[Vec<DVec3>], b: &[Vec<DVec3>]) -> f64 {
    apart(a, b).0
}

/// Hair in a gusting, turbulent wind with a hair dryer blowing across it (eddies of 15 cm, smaller than the
/// hair, and a jet 5 cm wide): the GPU, sampling the air at every node, moves the hair as the CPU does
/// given the same air at every node; the GPU with one air velocity per head (at the head, as it was
/// before) does not.
#[test]
fn hair_in_gusts_eddies_and_a_jet_moves_as_on_the_cpu() {
    let (_turn, device, queue) = device();
    let wind = HairWind {
        velocity: Vec3::new(1.5, 0.0, 0.5),
        gusts: 1.0,
        gust_period: 1.0,
        turbulence: 1.0,
        turbulence_scale: 0.15,
        turbulence_period: 0.5,
        seed: 11,
    };
    let dryer = HairWindSource { speed: 6.0, radius: 0.05, range: 1.0 };
    let dryer_at =
        GlobalTransform::from(Transform::from_xyz(0.6, 1.5, -0.2).looking_at(Vec3::new(0.3, 1.5, -0.2), Vec3::Y));
    let params = StepParams { dt: 1.0 / 60.0, ..Default::default() };
    // The CPU's steps converged (as `tests/gpu/step.rs` compares a held strand): the equations both steps
    // solve, against which the GPU's two Newton iterations show.
    let tight = StepParams { newton_strain_tolerance: 1e-6, max_newton_iterations: 16, ..params };
    let mut rods = strands();
    let pose = [(DQuat::IDENTITY, HEAD)];
    let mut gpu = GpuStrandSolver::new(&device, &inputs(&rods), &pose).unwrap();
    let mut per_head = GpuStrandSolver::new(&device, &inputs(&rods), &pose).unwrap();
    let mut workspace = RodWorkspace::default();
    let mut air = AirSnapshot::default();
    let mut node_air = Vec::new();
    let (mut worst, mut worst_per_head, mut moved) = (0.0_f64, 0.0_f64, 0.0_f64);
    let start: Vec<Vec<DVec3>> = rods.iter().map(|rod| rod.positions().to_vec()).collect();
    for step in 1..=STEPS {
        // The air at the step's middle, as `HairWindPlugin` takes it.
        wind.snapshot_into((step as f64 - 0.5) * params.dt, [(&dryer, &dryer_at)], &mut air);
        gpu.set_air(&air).unwrap();
        gpu.step(&device, &queue, &params, &[GpuHeadStep { translation: HEAD, ..Default::default() }]).unwrap();
        let at_head = GpuHeadStep { translation: HEAD, air_velocity: air.velocity_at(HEAD), ..Default::default() };
        per_head.step(&device, &queue, &params, &[at_head]).unwrap();
        for rod in &mut rods {
            node_air.clear();
            node_air.extend(rod.positions().iter().map(|p| air.velocity_at(*p)));
            let loads = StepLoads { air_velocities: Some(&node_air), ..Default::default() };
            rod.step_with_loads(&tight, &loads, &Contacts::NONE, &mut workspace).unwrap();
        }
        if step % 10 == 0 {
            let cpu: Vec<Vec<DVec3>> = rods.iter().map(|rod| rod.positions().to_vec()).collect();
            let states = gpu.read_back(&device, &queue);
            let coarse = per_head.read_back(&device, &queue);
            assert!(states.status.iter().all(|s| s.faults == 0), "{:?}", states.status);
            let (apart, apart_per_head) = (rms(&states.positions, &cpu), rms(&coarse.positions, &cpu));
            moved = moved.max(rms(&cpu, &start));
            println!(
                "t = {:.2} s: GPU − CPU {apart:.2e} m RMS; with the air at the head only {apart_per_head:.2e} m; the CPU's hair moved {moved:.2e} m",
                step as f64 * params.dt
            );
            worst = worst.max(apart);
            worst_per_head = worst_per_head.max(apart_per_head);
        }
    }
    // The wind moves the hair far (centimetres), the GPU follows it to within a millimetre or two (its
    // two Newton iterations against the CPU's converged ones: a released strand swings within 5 mm of
    // the converged one, `released_pendulum_swings_as_on_the_cpu`), and at a third of what one air
    // velocity per head leaves at most.
    assert!(moved > 0.03, "the wind moved the hair only {moved} m");
    assert!(worst < 5e-3, "the GPU's hair is {worst} m RMS from the CPU's");
    assert!(worst * 3.0 < worst_per_head, "per node {worst:e} m, per head {worst_per_head:e} m");
}

/// A game's forces on the GPU (`GpuStrandSolver::add_forces`, what `HairGpuPlugin` hands over from
/// `StrandForces`): the eight hairs pushed sideways by a force on every node that swells and fades
/// (up to twice their weight, along X then Z), for 1.5 s, against the CPU's converged steps given the
/// same forces. The forces move the hair by centimetres; the GPU follows the CPU within what its two
/// Newton iterations leave (a few millimetres, as in the wind above), and the forces are used up by each
/// step (a step with none leaves the hair hanging as it would).
#[test]
fn forces_on_the_gpu_move_the_hair_as_on_the_cpu() {
    let (_turn, device, queue) = device();
    let params = StepParams { dt: 1.0 / 60.0, ..Default::default() };
    let tight = StepParams { newton_strain_tolerance: 1e-6, max_newton_iterations: 16, ..params };
    let mut rods = strands();
    let pose = [(DQuat::IDENTITY, HEAD)];
    let mut gpu = GpuStrandSolver::new(&device, &inputs(&rods), &pose).unwrap();
    let mut unforced = GpuStrandSolver::new(&device, &inputs(&rods), &pose).unwrap();
    let head = [GpuHeadStep { translation: HEAD, ..Default::default() }];
    let mut workspace = RodWorkspace::default();
    let (mut worst, mut effect) = (0.0_f64, 0.0_f64);
    for step in 1..=STEPS {
        let t = step as f64 * params.dt;
        let push = DVec3::new((3.0 * t).sin().max(0.0), 0.0, (2.0 * t).cos() * 0.5);
        for (index, rod) in rods.iter_mut().enumerate() {
            let forces: Vec<DVec3> = rod.masses().iter().map(|&m| 2.0 * 9.81 * m * push).collect();
            gpu.add_forces(&queue, index, &forces).unwrap();
            let loads = StepLoads { forces: Some(&forces), ..Default::default() };
            rod.step_with_loads(&tight, &loads, &Contacts::NONE, &mut workspace).unwrap();
        }
        gpu.step(&device, &queue, &params, &head).unwrap();
        unforced.step(&device, &queue, &params, &head).unwrap();
        if step % 10 == 0 {
            let cpu: Vec<Vec<DVec3>> = rods.iter().map(|rod| rod.positions().to_vec()).collect();
            let (forced, still) = (gpu.read_back(&device, &queue), unforced.read_back(&device, &queue));
            assert!(forced.status.iter().all(|s| s.faults == 0), "{:?}", forced.status);
            let (apart, moved) = (rms(&forced.positions, &cpu), rms(&still.positions, &cpu));
            println!("t = {t:.2} s: GPU − CPU {apart:.2e} m RMS; the forces moved the hair {moved:.2e} m");
            worst = worst.max(apart);
            effect = effect.max(moved);
        }
    }
    assert!(effect > 0.03, "the forces moved the hair only {effect} m");
    assert!(worst < 5e-3 && worst * 10.0 < effect, "the GPU's hair is {worst} m RMS from the CPU's");
    // Used up: the forced hair, left without forces, is stepped as the unforced one would be from there
    // (a forced step again would move it by centimetres).
    let before = gpu.read_back(&device, &queue).positions;
    gpu.step(&device, &queue, &params, &head).unwrap();
    let after = gpu.read_back(&device, &queue).positions;
    let mut reference = rods.clone();
    for rod in &mut reference {
        rod.step(&tight, None, &mut workspace).unwrap();
    }
    let cpu_moved = rms(
        &reference.iter().map(|rod| rod.positions().to_vec()).collect::<Vec<_>>(),
        &rods.iter().map(|rod| rod.positions().to_vec()).collect::<Vec<_>>(),
    );
    let gpu_moved = rms(&after, &before);
    println!("one step without forces: the GPU's hair moves {gpu_moved:.2e} m, the CPU's {cpu_moved:.2e} m");
    assert!((gpu_moved - cpu_moved).abs() < 0.25 * cpu_moved + 1e-4, "{gpu_moved} vs {cpu_moved}");
}
