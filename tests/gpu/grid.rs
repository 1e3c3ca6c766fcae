//! The hair–hair grid on the GPU (`GpuStrandSolver::set_volume`, `grid.wgsl`): its fields against the
//! equations of `volume::grid` summed in double precision here and against the CPU's `VolumeGrid`, and
//! hair meeting hair stepped on the GPU against the CPU's step given the CPU grid's response.

use std::collections::HashMap;

use bevy::math::{DQuat, DVec3};
use bevy_hair_sim::gpu::{GpuHeadStep, GpuStrandInput, GpuStrandSolver, GpuVolume};
use bevy_hair_sim::rod::{Contacts, Rod, RodMaterial, RodWorkspace, StepLoads, StepParams};
use bevy_hair_sim::volume::{GridParticle, VolumeGrid, VolumeParams};
use hair_sim_support::straight_nodes;

use crate::colliders::apart;
use crate::step::device;

/// The head the strands hang from, away from the origin and off the grid's cells.
const HEAD: DVec3 = DVec3::new(0.3137, 1.6021, -0.2059);
/// Single precision's unit roundoff.
const U: f64 = f32::EPSILON as f64 / 2.0;
/// The hairs each strand stands for on the grid (a guide's share of a head).
const HAIRS: f64 = 100.0;

/// A bunch of 25 strands of 12 to 20 cm in 16 edges, rooted 3 mm apart in a square at the head, held out
/// along X and tilted down by 0 to 35°, so that they fall and swing at different rates through each other.
fn bunch() -> Vec<Rod> {
    (0..25)
        .map(|k| {
            let (i, j) = ((k % 5) as f64, (k / 5) as f64);
            let root = HEAD + DVec3::new(0.0, 0.003 * (i - 2.0), 0.003 * (j - 2.0));
            let tilt = 0.6 * (k as f64 / 24.0);
            let direction = DVec3::new(tilt.cos(), -tilt.sin(), 0.1 * (i - 2.0) * 0.1);
            let length = 0.12 + 0.08 * ((k * 7) % 25) as f64 / 24.0;
            let nodes: Vec<DVec3> =
                straight_nodes(length, 16, direction.normalize()).into_iter().map(|p| p + root).collect();
            let mut rod = Rod::new(&nodes, DVec3::Z, RodMaterial::human_hair()).unwrap();
            rod.clamp_root_in_place();
            rod
        })
        .collect()
}

fn inputs(rods: &[Rod]) -> Vec<GpuStrandInput<'_>> {
    rods.iter()
        .map(|rod| GpuStrandInput {
            rod,
            head: 0,
            thickness: 1e-4,
            groomed: None,
            hairs: HAIRS,
            groomed_fractions: None,
        })
        .collect()
}

fn volume() -> GpuVolume {
    GpuVolume { cell_size: 0.005, smoothing_rate: 40.0, target_fraction: 0.08, stiffness: 50.0, keep_groomed: false }
}

fn volume_params(volume: &GpuVolume, dt: f64) -> VolumeParams {
    VolumeParams {
        cell_size: volume.cell_size,
        smoothing_rate: volume.smoothing_rate,
        target_fraction: volume.target_fraction,
        stiffness: volume.stiffness,
        dt,
    }
}

/// The rods' nodes as the CPU's grid sees them (`volume/mod.rs`): the root edge's nodes with no mass for
/// the smoothing.
fn particles(rods: &[Rod]) -> Vec<GridParticle> {
    let mut particles = Vec::new();
    for rod in rods {
        let density = rod.material().density;
        for (node, ((&position, &velocity), &mass)) in
            rod.positions().iter().zip(rod.velocities()).zip(rod.masses()).enumerate()
        {
            particles.push(GridParticle {
                position,
                velocity,
                mass: if rod.is_node_prescribed(node) { 0.0 } else { HAIRS * mass },
                volume: HAIRS * mass / density,
                groomed_fraction: 0.0,
            });
        }
    }
    particles
}

/// At one grid point, in double precision: the trilinear sums of mass, momentum and volume, and the sums
/// with every weight 1 (mass, volume, mass times speed, nodes): what an error in the weights scales with.
#[derive(Default, Clone, Copy)]
struct Sums {
    mass: f64,
    momentum: DVec3,
    volume: f64,
    near_mass: f64,
    near_volume: f64,
    near_momentum: f64,
    nodes: f64,
}

fn reference_sums(particles: &[GridParticle], origin: DVec3, cell: f64) -> HashMap<[usize; 3], Sums> {
    let mut sums: HashMap<[usize; 3], Sums> = HashMap::new();
    for p in particles {
        let local = (p.position - origin) / cell;
        let corner = local.floor();
        let fraction = local - corner;
        for k in 0..8 {
            let upper = [k & 1, (k >> 1) & 1, k >> 2];
            let weight: f64 = (0..3).map(|a| if upper[a] == 1 { fraction[a] } else { 1.0 - fraction[a] }).product();
            let at = [0, 1, 2].map(|a| corner[a] as usize + upper[a]);
            let s = sums.entry(at).or_default();
            s.mass += weight * p.mass;
            s.momentum += weight * p.mass * p.velocity;
            s.volume += weight * p.volume;
            s.near_mass += p.mass;
            s.near_volume += p.volume;
            s.near_momentum += p.mass * p.velocity.length();
            s.nodes += 1.0;
        }
    }
    sums
}

/// The GPU's grid, built from a bunch of falling, swinging strands (25 strands of 60 hairs each, packed
/// beyond the target fraction so that the pressure pushes), holds at every point the fields of the
/// equations summed here in double precision, within what single precision and the fixed-point sums
/// allow (derived below); so does the CPU's `VolumeGrid`, to rounding.
#[test]
fn the_grid_on_the_gpu_has_the_cpus_fields() {
    let (_turn, device, queue) = device();
    let params = StepParams { dt: 1.0 / 60.0, ..Default::default() };
    let mut rods = bunch();
    // Moving: a few steps of falling on the CPU, so that the strands' velocities differ.
    let mut workspace = RodWorkspace::default();
    for _ in 0..6 {
        for rod in &mut rods {
            rod.step(&params, None, &mut workspace).unwrap();
        }
    }
    let mut gpu = GpuStrandSolver::new(&device, &inputs(&rods), &[(DQuat::IDENTITY, HEAD)]).unwrap();
    let volume = volume();
    gpu.set_volume(Some(volume)).unwrap();
    gpu.step(&device, &queue, &params, &[GpuHeadStep { translation: HEAD, ..Default::default() }]).unwrap();
    let grids = gpu.read_grid(&device, &queue);
    assert_eq!(grids.len(), 1);
    let grid = &grids[0];
    // Built where the hair was at the step's start: the rods as uploaded.
    let particles = particles(&rods);
    let mut cpu = VolumeGrid::default();
    let vp = volume_params(&volume, params.dt);
    cpu.build(&particles, &vp);
    // No coarsening for a bunch a few centimetres wide: the cell in single precision.
    assert!((grid.cell_size - volume.cell_size).abs() <= U * volume.cell_size, "cell {}", grid.cell_size);
    // Its points on world multiples of the cell, as the CPU's.
    let cell = volume.cell_size;
    let origin = (grid.origin / cell).round() * cell;
    assert!((origin - grid.origin).abs().max_element() < 1e-6, "origin {:?} off the cells", grid.origin);
    let sums = reference_sums(&particles, origin, cell);
    assert!(grid.pressed, "the bunch is packed beyond its target fraction");

    // The weights' error: a position is rounded to `u |x|` (relative to the head), shifted and scaled
    // into cells (three more roundings of the largest coordinate in cells); each of the three factors of a
    // weight errs by that, their product by three times it.
    let largest = particles.iter().map(|p| (p.position - HEAD).abs().max_element()).fold(0.0, f64::max);
    let cells = grid.dims.iter().copied().max().unwrap() as f64;
    let factor = (4.0 * (largest + cell) / cell + 2.0 * cells) * U;
    let weight_error = 3.0 * factor + 3.0 * U;
    let dt = params.dt;
    let rate = volume.smoothing_rate * dt;
    let cell_volume = cell.powi(3);
    let (mut checked, mut worst) = (0, [0.0_f64; 3]);
    let mut pressures: HashMap<[usize; 3], (f64, f64)> = HashMap::new();
    for k in 0..grid.dims[2] {
        for j in 0..grid.dims[1] {
            for i in 0..grid.dims[0] {
                let point = grid.point([i, j, k]).unwrap();
                let s = sums.get(&[i, j, k]).copied().unwrap_or_default();
                // The equations in double precision.
                let fraction = s.volume / cell_volume;
                let smoothing =
                    if s.mass > 0.0 { 1.0 - (-rate * (fraction / vp.target_fraction).min(1.0)).exp() } else { 0.0 };
                let velocity = if s.mass > 0.0 { s.momentum / s.mass } else { DVec3::ZERO };
                let smoothed = smoothing * velocity;
                // The CPU's grid at the same point agrees to rounding.
                let position = origin + cell * DVec3::new(i as f64, j as f64, k as f64);
                let cpu_fraction = cpu.volume_fraction_at(position);
                let (cpu_smoothed, _) = cpu.response(position, DVec3::ZERO, 0.0);
                assert!((cpu_fraction - fraction).abs() <= 1e-9 * (1.0 + fraction), "{cpu_fraction} {fraction}");
                assert!((cpu_smoothed - smoothed).length() <= 1e-9 * (1.0 + smoothed.length()));
                // The bounds: weights (above), the fixed-point sums (a quantum, 2⁻³² of the heaviest node's
                // share, per node), single precision's rounding of the sums and of the formulas.
                let quantum = HAIRS * rods[0].masses().iter().copied().fold(0.0, f64::max) * 2f64.powi(-32);
                let volume_quantum = quantum / rods[0].material().density;
                let fraction_bound = weight_error * s.near_volume / cell_volume
                    + s.nodes * volume_quantum / cell_volume
                    + 8.0 * U * fraction;
                let velocity_bound = if s.mass > 0.0 {
                    (weight_error * (s.near_momentum + velocity.length() * s.near_mass) + 2.0 * s.nodes * quantum)
                        / s.mass
                        + 8.0 * U * velocity.length()
                } else {
                    0.0
                };
                let smoothing_bound = rate / vp.target_fraction * fraction_bound + 8.0 * U;
                let smoothed_bound =
                    smoothing * velocity_bound + velocity.length() * smoothing_bound + 8.0 * U * smoothed.length();
                let errors = [
                    (f64::from(point.volume_fraction) - fraction).abs(),
                    (f64::from(point.smoothing) - smoothing).abs(),
                    (point.smoothed_velocity.as_dvec3() - smoothed).length(),
                ];
                let bounds = [fraction_bound, smoothing_bound, smoothed_bound];
                for axis in 0..3 {
                    assert!(
                        errors[axis] <= bounds[axis].max(1e-30),
                        "point {:?}: field {axis} GPU {:?} vs {:?}, error {:.3e} over its bound {:.3e}",
                        [i, j, k],
                        point,
                        (fraction, smoothing, smoothed),
                        errors[axis],
                        bounds[axis]
                    );
                    if bounds[axis] > 0.0 {
                        worst[axis] = worst[axis].max(errors[axis] / bounds[axis]);
                    }
                }
                checked += usize::from(s.volume > 0.0);
                // The pressure, from the fraction: `K/φ₀` times its error where packed beyond `φ₀`.
                let pressure = volume.stiffness * (fraction / vp.target_fraction - 1.0).max(0.0);
                let packed = fraction.max(f64::from(point.volume_fraction)) > vp.target_fraction;
                let pressure_bound = if packed { volume.stiffness / vp.target_fraction * fraction_bound } else { 0.0 }
                    + 8.0 * U * pressure;
                let pressure_error = (f64::from(point.pressure) - pressure).abs();
                assert!(pressure_error <= pressure_bound, "point {:?}: pressure {pressure_error:.3e} off", [i, j, k]);
                pressures.insert([i, j, k], (f64::from(point.pressure), pressure_bound));
            }
        }
    }
    // The pressure's push `∇p / max(φ, φ₀)` from the GPU's pressures (central differences, as the GPU's
    // nodes take it) is the CPU's, within the pressures' bounds.
    let mut pushes = 0;
    for &[i, j, k] in pressures.keys() {
        if grid.point([i, j, k]).unwrap().volume_fraction == 0.0 {
            continue;
        }
        let position = origin + cell * DVec3::new(i as f64, j as f64, k as f64);
        let (_, cpu_push) = cpu.response(position, DVec3::ZERO, -1.0);
        let beside = |c: [i64; 3]| {
            let c = c.map(|v| usize::try_from(v).unwrap_or(usize::MAX));
            pressures.get(&c).copied().unwrap_or((0.0, 0.0))
        };
        let (mut push, mut bound) = (DVec3::ZERO, 0.0);
        for axis in 0..3 {
            let (mut up, mut down) = ([i, j, k].map(|v| v as i64), [i, j, k].map(|v| v as i64));
            up[axis] += 1;
            down[axis] -= 1;
            let ((p_up, b_up), (p_down, b_down)) = (beside(up), beside(down));
            push[axis] = (p_up - p_down) / (2.0 * cell);
            bound += (b_up + b_down) / (2.0 * cell);
        }
        let packing = f64::from(grid.point([i, j, k]).unwrap().volume_fraction).max(vp.target_fraction);
        push /= packing;
        assert!(
            // (The CPU's push read at a grid point through its interpolation carries its neighbours' at 1e-13
            // weights: a floor of a millionth of the push of hair packed at twice its target.)
            (push - cpu_push).length()
                <= 2.0 * bound / packing
                    + 1e-4 * cpu_push.length()
                    + 1e-6 * volume.stiffness / (cell * vp.target_fraction),
            "push at {:?}: GPU {push:?}, CPU {cpu_push:?}, bound {bound:.3e}",
            [i, j, k]
        );
        pushes += usize::from(cpu_push.length() > 1.0);
    }
    assert!(pushes > 20, "the pressure pushes at {pushes} points");
    let max_fraction = cpu.max_volume_fraction();
    println!(
        "{checked} points with hair of {} in a {:?} grid, {pushes} pushed by the pressure, largest fraction {max_fraction:.3} (GPU {:.3}); worst error over its bound: fraction {:.2}, smoothing {:.2}, α u {:.2}",
        grid.points.len(),
        grid.dims,
        grid.max_volume_fraction,
        worst[0],
        worst[1],
        worst[2]
    );
    assert!(checked > 200, "the bunch covers hundreds of points: {checked}");
    assert!((f64::from(grid.max_volume_fraction) - max_fraction).abs() <= 1e-3 * max_fraction);
}

/// The CPU's step with the grid's response, as `HairVolumePlugin` gives it: the smoothing as velocity
/// changes and the pressure as forces, the root edge left alone.
fn step_cpu_with_grid(rods: &mut [Rod], grid: &mut VolumeGrid, params: &StepParams, vp: &VolumeParams) {
    let particles = particles(rods);
    grid.build(&particles, vp);
    let mut workspace = RodWorkspace::default();
    for rod in rods.iter_mut() {
        let density = rod.material().density;
        let (changes, forces): (Vec<DVec3>, Vec<DVec3>) = (0..rod.node_count())
            .map(|node| {
                if rod.is_node_prescribed(node) {
                    (DVec3::ZERO, DVec3::ZERO)
                } else {
                    grid.response(rod.positions()[node], rod.velocities()[node], rod.masses()[node] / density)
                }
            })
            .unzip();
        let loads = StepLoads { velocity_changes: Some(&changes), forces: Some(&forces), ..Default::default() };
        rod.step_with_loads(params, &loads, &Contacts::NONE, &mut workspace).unwrap();
    }
}

/// The bunch falling and swinging through itself for 1.5 s, with the grid's smoothing and pressure, on
/// the GPU and on the CPU (converged), and each without the grid: the grid moves the hair by centimetres
/// on the CPU, and the GPU with its grid follows the CPU with its grid as closely as the GPU without one
/// follows the CPU without one (their two Newton iterations against the CPU's converged ones), not by the
/// grid's effect.
#[test]
fn hair_meeting_hair_on_the_gpu_moves_as_on_the_cpu() {
    let (_turn, device, queue) = device();
    let params = StepParams { dt: 1.0 / 60.0, ..Default::default() };
    let tight = StepParams { newton_strain_tolerance: 1e-6, max_newton_iterations: 16, ..params };
    let rods = bunch();
    let pose = [(DQuat::IDENTITY, HEAD)];
    let mut gpu = GpuStrandSolver::new(&device, &inputs(&rods), &pose).unwrap();
    let mut gpu_alone = GpuStrandSolver::new(&device, &inputs(&rods), &pose).unwrap();
    let volume = volume();
    gpu.set_volume(Some(volume)).unwrap();
    let vp = volume_params(&volume, params.dt);
    let (mut cpu, mut cpu_alone) = (rods.clone(), rods);
    let mut grid = VolumeGrid::default();
    let mut workspace = RodWorkspace::default();
    let head = [GpuHeadStep { translation: HEAD, ..Default::default() }];
    let (mut worst, mut worst_alone, mut effect) = (0.0_f64, 0.0_f64, 0.0_f64);
    for step in 1..=90 {
        gpu.step(&device, &queue, &params, &head).unwrap();
        gpu_alone.step(&device, &queue, &params, &head).unwrap();
        step_cpu_with_grid(&mut cpu, &mut grid, &tight, &vp);
        for rod in &mut cpu_alone {
            rod.step(&tight, None, &mut workspace).unwrap();
        }
        if step % 10 == 0 {
            let nodes = |rods: &[Rod]| rods.iter().map(|rod| rod.positions().to_vec()).collect::<Vec<_>>();
            let (with, without) = (nodes(&cpu), nodes(&cpu_alone));
            let states = gpu.read_back(&device, &queue);
            let alone = gpu_alone.read_back(&device, &queue);
            assert!(states.status.iter().all(|s| s.faults == 0), "{:?}", states.status);
            let (apart_with, apart_alone) = (apart(&states.positions, &with).0, apart(&alone.positions, &without).0);
            let grid_moved = apart(&with, &without).0;
            println!(
                "t = {:.2} s: with the grid GPU − CPU {apart_with:.2e} m RMS, without {apart_alone:.2e} m; the grid moved the CPU's hair {grid_moved:.2e} m",
                step as f64 * params.dt
            );
            worst = worst.max(apart_with);
            worst_alone = worst_alone.max(apart_alone);
            effect = effect.max(grid_moved);
        }
    }
    assert!(effect > 0.005, "the grid moves the hair by millimetres: {effect:.3e} m");
    assert!(worst < 0.2 * effect, "the GPU's grid is the CPU's: {worst:.3e} m apart, the grid's effect {effect:.3e} m");
    assert!(
        worst <= 2.0 * worst_alone,
        "the grid adds no more than single precision's share: {worst:.3e} m with it, {worst_alone:.3e} m without"
    );
}
