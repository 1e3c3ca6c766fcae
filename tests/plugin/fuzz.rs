//! Fuzzing the public API with seeded random inputs: random strands, materials (and material directions),
//! step parameters (both integrators), boundary conditions, moving and jumping colliders (over the roots
//! too), forces (huge, non-finite), anchors (soft to stiff, near and far, non-finite), rest shapes, states written from outside; in the plugin also settings,
//! heads that jump or lose their transform, spawns, respawns and despawns, procedural grooms (combed,
//! preloaded, with followers), groom files (valid and corrupted), followers of strands of one's own
//! (valid and not), levels of detail (fixed, switching, from a moving camera, invalid), the hair–hair
//! grid (on, off, toggled, invalid), the style hold (off, up to its stiffest, invalid), wind and wind sources
//! (valid and not).
//!
//! Checked after every step: no panic, no NaN anywhere in any state, every `Ok` step within the strain
//! bound, no strand failing more than a few times in a row, and (in the plugin) a bounded number of log
//! lines, nothing a game reads non-finite (`StrandNodes`, `StrandFrames`, `FollowerNodes`), and every
//! drawn root, a guide's and each follower's, on its head within [`DRAWN_ROOT_TOLERANCE`] at every level
//! of detail, in quarantine, after resets and while the settings are invalid. `cargo test` runs a few hundred cases; the ignored `*_long` tests run 10 000 core cases and
//! 1 000 plugin scenarios (`cargo test --release --test plugin -- --ignored --nocapture fuzz::`). `FUZZ_SEED=N`
//! prints every step of core case `N`.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use bevy::asset::AssetPlugin;
use bevy::math::{DQuat, DVec2, DVec3};
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::groom::FileStrand;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{
    Anchor, ColliderShape, Contacts, Integrator, MovingCollider, RigidPose, Rod, RodError, RodWorkspace, StepError,
    StepLoads, StepParams,
};
use bevy_hair_sim::simulation::{HeadMotion, LONGER_STEP_STRAIN_TOLERANCE, SimulatedStrand};
use hair_sim_support::headless::{DT, camera, drain_messages, drawn_is_finite, hair_app_with};
use hair_sim_support::logs;

/// Most failed steps in a row of one rod in the core (counting neither invalid input nor the states this
/// test writes, nor rods pinned at both ends: a rope pulled taut between its pins can fail on every step,
/// which the plugin's quarantine answers), and of one strand in the plugin (where the second fault in a
/// row quarantines it).
const CORE_FAULTS_IN_A_ROW: u32 = 3;
const PLUGIN_FAULTS_IN_A_ROW: u32 = 2;

/// The name of an enum variant from its `Debug` text.
fn kind(debug: String) -> String {
    debug.split([' ', '(', '{']).next().unwrap_or_default().to_string()
}

/// `10^x` for `x` uniform in `[low, high)`.
fn log_uniform(rng: &mut fastrand::Rng, low: f64, high: f64) -> f64 {
    10f64.powf(low + (high - low) * rng.f64())
}

fn uniform(rng: &mut fastrand::Rng, low: f64, high: f64) -> f64 {
    low + (high - low) * rng.f64()
}

fn unit_vector(rng: &mut fastrand::Rng) -> DVec3 {
    loop {
        let v = DVec3::new(uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0), uniform(rng, -1.0, 1.0));
        if (0.01..1.0).contains(&v.length_squared()) {
            return v.normalize();
        }
    }
}

fn random_rotation(rng: &mut fastrand::Rng, largest_angle: f64) -> DQuat {
    DQuat::from_axis_angle(unit_vector(rng), uniform(rng, 0.0, largest_angle))
}

/// A non-finite or otherwise bad number, now and then.
fn sometimes_bad(rng: &mut fastrand::Rng, chance: f64, value: impl FnOnce(&mut fastrand::Rng) -> f64) -> f64 {
    let value = value(rng);
    if rng.f64() >= chance {
        return value;
    }
    *rng.choice(&[f64::NAN, f64::INFINITY, -value, 0.0, 1e300]).unwrap()
}

/// Random nodes: a random walk of 2 to 40 edges, turning up to a random largest angle (up to a full
/// fold), now and then with a zero-length edge or a NaN node.
fn random_nodes(rng: &mut fastrand::Rng) -> Vec<DVec3> {
    let edges = rng.usize(2..=40);
    let edge_length = log_uniform(rng, -4.0, -1.3);
    let largest_turn = *rng.choice(&[0.05, 0.5, 1.5, 2.9, 3.1, PI]).unwrap();
    let mut direction = unit_vector(rng);
    let mut nodes = vec![DVec3::new(uniform(rng, -1.0, 1.0), uniform(rng, 0.0, 2.0), uniform(rng, -1.0, 1.0))];
    for _ in 0..edges {
        let axis = unit_vector(rng).cross(direction).normalize_or(direction.any_orthonormal_vector());
        direction = DQuat::from_axis_angle(axis, uniform(rng, 0.0, largest_turn)) * direction;
        let length = edge_length * uniform(rng, 0.5, 1.5);
        nodes.push(*nodes.last().unwrap() + length * direction);
    }
    if rng.f64() < 0.02 {
        let node = rng.usize(1..nodes.len());
        nodes[node] = nodes[node - 1];
    }
    if rng.f64() < 0.02 {
        let node = rng.usize(..nodes.len());
        nodes[node].y = f64::NAN;
    }
    nodes
}

fn random_material(rng: &mut fastrand::Rng) -> RodMaterial {
    let radius = log_uniform(rng, -5.3, -3.0);
    let youngs_modulus = log_uniform(rng, 5.0, 10.5);
    RodMaterial {
        semi_axis_1: sometimes_bad(rng, 0.01, |_| radius),
        semi_axis_2: radius * uniform(rng, 0.5, 1.0),
        youngs_modulus: sometimes_bad(rng, 0.01, |_| youngs_modulus),
        shear_modulus: youngs_modulus / (2.0 * (1.0 + uniform(rng, 0.2, 0.5))),
        density: sometimes_bad(rng, 0.01, |rng| log_uniform(rng, 2.5, 3.5)),
    }
}

fn random_params(rng: &mut fastrand::Rng) -> StepParams {
    StepParams {
        dt: sometimes_bad(rng, 0.01, |rng| log_uniform(rng, -3.5, -1.3)),
        gravity: DVec3::new(0.0, -9.81, 0.0) + 3.0 * unit_vector(rng) * rng.f64(),
        air_damping: uniform(rng, 0.0, 10.0),
        internal_damping: if rng.bool() { log_uniform(rng, -5.0, -2.0) } else { 0.0 },
        max_newton_iterations: rng.u32(1..=6),
        max_rotation: uniform(rng, 0.05, 1.0),
        strain_allowance: uniform(rng, 0.0, 0.01),
        strain_tolerance: log_uniform(rng, -8.0, -4.0),
        max_projection_iterations: rng.u32(1..=20),
        integrator: if rng.bool() { Integrator::Bdf2 } else { Integrator::BackwardEuler },
        ..StepParams::default()
    }
}

fn random_shape(rng: &mut fastrand::Rng) -> ColliderShape {
    let size = log_uniform(rng, -2.5, -1.0);
    match rng.u8(0..4) {
        0 => ColliderShape::sphere(size),
        1 => ColliderShape::capsule(size, size * uniform(rng, 0.0, 3.0)),
        2 => ColliderShape::ellipsoid(size * DVec3::new(uniform(rng, 0.3, 1.0), uniform(rng, 0.3, 1.0), 1.0)),
        _ => ColliderShape::Plane,
    }
}

/// What the core fuzz saw.
#[derive(Debug, Default)]
struct CoreTally {
    cases: u64,
    rejected: BTreeMap<String, u64>,
    steps: u64,
    ok_steps: u64,
    errors: BTreeMap<String, u64>,
    setter_rejections: BTreeMap<String, u64>,
    largest_ok_strain: f64,
    longest_fault_run: u32,
    longest_fault_run_pinned_at_both_ends: u32,
}

fn count(map: &mut BTreeMap<String, u64>, key: String) {
    *map.entry(key).or_default() += 1;
}

/// Runs one random case of the mechanics core.
fn core_case(seed: u64, tally: &mut CoreTally) {
    let mut rng = fastrand::Rng::with_seed(seed);
    tally.cases += 1;
    let nodes = random_nodes(&mut rng);
    let mut material_direction = unit_vector(&mut rng);
    if rng.f64() < 0.05 {
        material_direction = (nodes[1] - nodes[0]).normalize_or(DVec3::X) + 1e-9 * unit_vector(&mut rng);
    } else if rng.f64() < 0.03 {
        // Zero, subnormal, or not finite.
        let tiny = 5e-324 * unit_vector(&mut rng);
        material_direction = *rng.choice(&[DVec3::ZERO, tiny, DVec3::NAN]).unwrap();
    }
    let mut rod = match Rod::new(&nodes, material_direction, random_material(&mut rng)) {
        Ok(rod) => rod,
        Err(error) => return count(&mut tally.rejected, kind(format!("{error:?}"))),
    };
    let mut rejected = |result: Result<(), RodError>| {
        if let Err(error) = result {
            count(&mut tally.setter_rejections, kind(format!("{error:?}")));
        }
    };
    // Boundary conditions: a clamped root on a moving head, pins, or none.
    let boundary = rng.u8(0..10);
    if boundary < 6 {
        rod.clamp_root_in_place();
    } else if boundary < 7 {
        rejected(rod.pin_node(0, nodes[0]));
    } else if boundary < 8 {
        let last = rod.node_count() - 1;
        rejected(rod.pin_node(0, rod.positions()[0]));
        rejected(rod.pin_node(last, rod.positions()[last]));
    }
    if rng.f64() < 0.1 {
        let vertex = rng.usize(0..rod.edge_count() + 1);
        let value = sometimes_bad(&mut rng, 0.3, |rng| uniform(rng, -30.0, 30.0));
        rejected(rod.set_rest_curvature(vertex, DVec2::new(value, 0.5 * value)));
        rejected(rod.set_rest_twist(vertex, sometimes_bad(&mut rng, 0.3, |rng| uniform(rng, -5.0, 5.0))));
    }
    if rng.f64() < 0.1 {
        let curvature = sometimes_bad(&mut rng, 0.2, |rng| log_uniform(rng, 0.0, 4.0));
        rejected(rod.set_natural_curvature(DVec2::new(curvature, 0.0)));
    }
    let params = random_params(&mut rng);
    let thickness = rod.material().semi_axis_1.max(rod.material().semi_axis_2) + 1e-3;
    // Colliders near the rod, the first often over the root.
    let mut colliders: Vec<(ColliderShape, f64, RigidPose, DVec3)> = (0..rng.usize(0..=3))
        .map(|index| {
            let near = if index == 0 && rng.bool() { nodes[0] } else { nodes[rng.usize(..nodes.len())] };
            let centre = near + 0.03 * unit_vector(&mut rng) * rng.f64();
            let velocity = unit_vector(&mut rng) * log_uniform(&mut rng, -2.0, 0.7);
            let pose = RigidPose::new(random_rotation(&mut rng, PI), centre);
            (random_shape(&mut rng), uniform(&mut rng, 0.0, 2.0), pose, velocity)
        })
        .filter(|(shape, ..)| shape.validate().is_ok())
        .collect();
    let (head_velocity, head_spin) = (
        unit_vector(&mut rng) * log_uniform(&mut rng, -2.0, 0.7),
        unit_vector(&mut rng) * uniform(&mut rng, 0.0, 10.0),
    );
    let mut workspace = RodWorkspace::default();
    let mut moving = Vec::with_capacity(colliders.len());
    let mut fault_run = 0;
    for _ in 0..rng.usize(10..=40) {
        let dt = if params.dt.is_finite() && params.dt > 0.0 { params.dt } else { 1.0 / 60.0 };
        // The head carries the clamp: moving and turning, now and then jumping.
        if boundary < 6 {
            let frame = rod.material_frame(0);
            let (mut turn, mut shift) = (DQuat::from_scaled_axis(head_spin * dt), head_velocity * dt);
            if rng.f64() < 0.02 {
                (turn, shift) = (random_rotation(&mut rng, PI), unit_vector(&mut rng));
            }
            let targets = rod.positions();
            let (start, end) = (targets[0] + shift, targets[0] + shift + turn * (targets[1] - targets[0]));
            rejected(rod.clamp_edge(0, start, end, turn * frame.m1));
        }
        moving.clear();
        for (shape, friction, pose, velocity) in &mut colliders {
            let start = *pose;
            pose.translation += *velocity * dt;
            if rng.f64() < 0.03 {
                pose.translation = nodes[rng.usize(..nodes.len())] + 0.02 * unit_vector(&mut rng);
            }
            moving.push(MovingCollider { shape: shape.clone(), friction: *friction, start, end: *pose });
        }
        // Forces: mostly none, sometimes huge or not finite.
        let mut forces = vec![DVec3::ZERO; rod.node_count()];
        let force_kind = rng.f64();
        if force_kind < 0.1 {
            forces.iter_mut().for_each(|f| *f = unit_vector(&mut rng) * log_uniform(&mut rng, -7.0, -3.0));
        } else if force_kind < 0.15 {
            let node = rng.usize(..forces.len());
            forces[node] = unit_vector(&mut rng) * log_uniform(&mut rng, 3.0, 8.0);
        } else if force_kind < 0.17 {
            let node = rng.usize(..forces.len());
            forces[node] = DVec3::new(f64::NAN, 0.0, f64::INFINITY);
        }
        // States written from outside: NaN, coincident nodes, a rigid motion that is not one.
        let mut written = false;
        let write = rng.f64();
        if write < 0.01 {
            let node = rng.usize(..rod.node_count());
            rod.positions_mut()[node] = DVec3::NAN;
            written = true;
        } else if write < 0.02 {
            let node = rng.usize(1..rod.node_count());
            rod.positions_mut()[node] = rod.positions()[node - 1];
            written = true;
        } else if write < 0.03 {
            let rotation = random_rotation(&mut rng, PI) * uniform(&mut rng, 0.5, 1.5);
            rejected(rod.transform_rigidly(rotation, unit_vector(&mut rng)));
        }
        if std::env::var("FUZZ_SEED").is_ok_and(|s| s == seed.to_string()) {
            eprintln!("positions {:?}", rod.positions());
        }
        let contacts = Contacts { colliders: &moving, thickness };
        let force_input = (force_kind >= 0.1 || rng.bool()).then_some(&forces[..]);
        // Anchors (a style hold's springs): mostly none, sometimes towards places near the nodes or far,
        // moving, from soft to far stiffer than any hold, now and then not finite.
        let anchor_kind = rng.f64();
        let anchors: Vec<Anchor> = if anchor_kind < 0.15 {
            let places: Vec<DVec3> = rod.positions().to_vec();
            places
                .into_iter()
                .map(|place| Anchor {
                    target: place + unit_vector(&mut rng) * log_uniform(&mut rng, -5.0, 0.0),
                    target_velocity: unit_vector(&mut rng) * uniform(&mut rng, 0.0, 5.0),
                    stiffness: log_uniform(&mut rng, 0.0, 7.0),
                    damping: uniform(&mut rng, 0.0, 2000.0),
                })
                .collect()
        } else if anchor_kind < 0.16 {
            vec![Anchor { stiffness: f64::NAN, ..Anchor::default() }; rod.node_count()]
        } else {
            Vec::new()
        };
        let loads = StepLoads {
            forces: force_input,
            anchors: (!anchors.is_empty()).then_some(&anchors[..]),
            ..StepLoads::default()
        };
        let result = rod.step_with_loads(&params, &loads, &contacts, &mut workspace);
        tally.steps += 1;
        if std::env::var("FUZZ_SEED").is_ok_and(|s| s == seed.to_string()) {
            eprintln!(
                "{result:?} nodes {} material {:?} params {params:?} boundary {boundary} colliders {moving:?} force {force_kind} written {written}",
                rod.node_count(),
                rod.material()
            );
        }
        let finite = rod.positions().iter().chain(rod.velocities()).all(|v| v.is_finite())
            && rod.twist_angles().iter().all(|t| t.is_finite());
        assert!(finite, "seed {seed}: a non-finite state after {result:?}");
        match result {
            Ok(report) => {
                tally.ok_steps += 1;
                fault_run = 0;
                let strain = rod.max_strain().1;
                assert!(
                    strain <= params.strain_bound() && report.max_strain == strain,
                    "seed {seed}: Ok step with strain {strain:e} above the bound {:e}",
                    params.strain_bound()
                );
                tally.largest_ok_strain = tally.largest_ok_strain.max(strain);
            }
            Err(error) => {
                count(&mut tally.errors, kind(format!("{error:?}")));
                let ours = matches!(error, StepError::InvalidInput(_)) || written;
                if !ours {
                    fault_run += 1;
                    if boundary == 7 {
                        tally.longest_fault_run_pinned_at_both_ends =
                            tally.longest_fault_run_pinned_at_both_ends.max(fault_run);
                    } else {
                        tally.longest_fault_run = tally.longest_fault_run.max(fault_run);
                        assert!(
                            fault_run <= CORE_FAULTS_IN_A_ROW,
                            "seed {seed}: {fault_run} faults in a row, the last: {error}"
                        );
                    }
                }
            }
        }
    }
}

fn fuzz_core(cases: u64, first_seed: u64) -> CoreTally {
    let mut tally = CoreTally::default();
    for seed in first_seed..first_seed + cases {
        core_case(seed, &mut tally);
    }
    println!("{tally:#?}");
    assert_eq!(tally.cases, cases);
    tally
}

#[test]
fn fuzz_the_core() {
    let tally = fuzz_core(300, 0);
    assert!(tally.ok_steps > tally.steps / 2, "most steps of valid rods succeed");
    assert!(!tally.rejected.is_empty() && !tally.errors.is_empty(), "the inputs include bad ones");
}

#[test]
#[ignore = "10 000 cases: run with --release"]
fn fuzz_the_core_long() {
    fuzz_core(10_000, 1_000_000);
}

/// What the plugin fuzz saw.
#[derive(Debug, Default)]
struct PluginTally {
    scenarios: u64,
    updates: u64,
    strand_steps: u64,
    faults: BTreeMap<String, u64>,
    largest_quarantined: usize,
    longest_fault_run: u32,
    largest_strain: f64,
    log_lines: u64,
    most_fault_lines_per_second: f64,
    /// Drawn roots checked on their heads (guides and followers), and the largest distance off, m.
    drawn_roots_checked: u64,
    largest_drawn_root_offset: f32,
    /// Drawn strands checked at each level of detail (by its `Debug` name), and while the settings were
    /// invalid.
    drawn_by_level: BTreeMap<String, u64>,
    drawn_while_settings_invalid: u64,
    follower_nodes_checked: u64,
    /// Groom files read (by kind of outcome), and strands placed from them.
    groom_files: BTreeMap<String, u64>,
    file_strands: u64,
    grid_updates: u64,
    wind_updates: u64,
    camera_updates: u64,
}

/// How far a drawn root may be from its root on the head, m: single-precision rounding at a few metres.
const DRAWN_ROOT_TOLERANCE: f32 = 1e-5;

/// A random strand description (head-local), sometimes invalid.
fn random_spec(rng: &mut fastrand::Rng) -> HairStrand {
    let nodes = random_nodes(rng);
    let root = nodes[0];
    let nodes: Vec<Vec3> = nodes.iter().map(|node| (0.1 * unit_vector(rng) + *node - root).as_vec3()).collect();
    let direction = match rng.u8(0..50) {
        0 => Vec3::ZERO,
        1 => Vec3::new(1e-45, 0.0, 0.0),
        2 => Vec3::NAN,
        _ => unit_vector(rng).as_vec3(),
    };
    let mut spec = HairStrand::from_nodes(nodes, direction);
    if rng.f64() < 0.2 {
        spec = spec.with_material(random_material(rng));
    }
    if rng.f64() < 0.1 {
        spec =
            spec.with_natural_curvature(Vec2::new(sometimes_bad(rng, 0.3, |rng| uniform(rng, 0.0, 300.0)) as f32, 0.0));
    }
    if rng.f64() < 0.1 {
        spec.gravity_preload = sometimes_bad(rng, 0.2, |rng| rng.f64()) as f32;
    }
    spec
}

/// Followers for `spec`: its curve shifted a little per follower; now and then of the wrong length, with
/// a NaN node, or with a clumping, clumping variation or scatter out of range.
fn random_followers(rng: &mut fastrand::Rng, spec: &HairStrand) -> HairFollowers {
    let curves = (0..rng.usize(1..=4))
        .map(|_| {
            let shift = (unit_vector(rng) * 0.003).as_vec3();
            let mut curve: Vec<Vec3> = spec.nodes.iter().map(|node| *node + shift).collect();
            match rng.u8(0..30) {
                0 => _ = curve.pop(),
                1 => curve[rng.usize(..spec.nodes.len())] = Vec3::NAN,
                _ => {}
            }
            curve
        })
        .collect();
    HairFollowers {
        curves,
        clumping: sometimes_bad(rng, 0.05, |rng| rng.f64()) as f32,
        clumping_variation: sometimes_bad(rng, 0.05, |rng| rng.f64()) as f32,
        scatter: sometimes_bad(rng, 0.05, |rng| 0.01 * rng.f64()) as f32,
    }
}

/// The bytes of a small groom file, `.tfx` (the flag) or `.hair`: a few curved strands over a 10 cm
/// scalp, in metres; a third of them corrupted (bytes flipped, cut short, a count changed).
fn random_groom_file(rng: &mut fastrand::Rng) -> (Vec<u8>, bool) {
    let strands = rng.usize(1..=12);
    let points = rng.usize(2..=10);
    let curve = |rng: &mut fastrand::Rng| -> Vec<Vec3> {
        let mut direction = unit_vector(rng);
        let mut point = 0.1 * direction;
        let step = log_uniform(rng, -3.0, -1.5);
        (0..points)
            .map(|_| {
                let here = point;
                direction = (direction + 0.3 * unit_vector(rng)).normalize();
                point += step * direction;
                here.as_vec3()
            })
            .collect()
    };
    let tfx = rng.bool();
    let mut bytes = Vec::new();
    let push_f32 = |bytes: &mut Vec<u8>, value: f32| bytes.extend_from_slice(&value.to_le_bytes());
    let push_u32 = |bytes: &mut Vec<u8>, value: u32| bytes.extend_from_slice(&value.to_le_bytes());
    if tfx {
        push_f32(&mut bytes, 4.0);
        push_u32(&mut bytes, strands as u32);
        push_u32(&mut bytes, points as u32);
        push_u32(&mut bytes, 160);
        bytes.resize(160, 0);
        for _ in 0..strands {
            for point in curve(rng) {
                [point.x, point.y, point.z, 0.0].into_iter().for_each(|value| push_f32(&mut bytes, value));
            }
        }
    } else {
        bytes.extend_from_slice(b"HAIR");
        push_u32(&mut bytes, strands as u32);
        push_u32(&mut bytes, (strands * points) as u32);
        push_u32(&mut bytes, 1 | 2 | 4);
        push_u32(&mut bytes, 0);
        [2e-4, 0.0, 0.3, 0.2, 0.1].into_iter().for_each(|value| push_f32(&mut bytes, value));
        bytes.resize(128, 0);
        for _ in 0..strands {
            bytes.extend_from_slice(&(points as u16 - 1).to_le_bytes());
        }
        for _ in 0..strands {
            for point in curve(rng) {
                [point.x, point.y, point.z].into_iter().for_each(|value| push_f32(&mut bytes, value));
            }
        }
        (0..strands * points).for_each(|_| push_f32(&mut bytes, 1e-4));
    }
    match rng.u8(0..9) {
        0 => bytes.truncate(rng.usize(..bytes.len())),
        1 => {
            for _ in 0..rng.usize(1..=8) {
                let at = rng.usize(..bytes.len());
                bytes[at] ^= 1 << rng.u8(0..8);
            }
        }
        2 => {
            let at = 4 * rng.usize(1..=3);
            bytes[at..at + 4].copy_from_slice(&rng.u32(..).to_le_bytes());
        }
        _ => {}
    }
    (bytes, tfx)
}

fn random_level(rng: &mut fastrand::Rng) -> HairDetailLevel {
    *rng.choice(&[
        HairDetailLevel::FULL,
        HairDetailLevel::Stepped(2),
        HairDetailLevel::Stepped(3),
        HairDetailLevel::Stepped(4),
        HairDetailLevel::Carried,
    ])
    .unwrap()
}

/// Random valid or invalid hair–hair interaction settings.
fn random_volume(rng: &mut fastrand::Rng) -> HairVolume {
    HairVolume {
        enabled: rng.bool(),
        cell_size: sometimes_bad(rng, 0.05, |rng| uniform(rng, 0.004, 0.02)) as f32,
        velocity_smoothing: uniform(rng, 0.0, 20.0) as f32,
        target_volume_fraction: uniform(rng, 0.05, 0.3) as f32,
        stiffness: sometimes_bad(rng, 0.05, |rng| uniform(rng, 0.0, 60.0)) as f32,
        keep_groomed_volume: rng.bool(),
    }
}

/// Random valid or invalid wind.
fn random_wind(rng: &mut fastrand::Rng) -> HairWind {
    HairWind {
        velocity: (unit_vector(rng) * sometimes_bad(rng, 0.05, |rng| uniform(rng, 0.0, 8.0))).as_vec3(),
        gusts: uniform(rng, 0.0, 3.0) as f32,
        turbulence: sometimes_bad(rng, 0.05, |rng| uniform(rng, 0.0, 2.0)) as f32,
        seed: rng.u64(..),
        ..default()
    }
}

/// Checks what a game reads after an update: every value finite (`StrandNodes`, `StrandFrames`,
/// `FollowerNodes`), every drawn root, a guide's and each follower's, on its head.
fn check_drawn(app: &mut App, seed: u64, settings_valid: bool, tally: &mut PluginTally) {
    let mut query = app.world_mut().query::<(
        Entity,
        &SimulatedStrand,
        &HairStrand,
        &StrandNodes,
        &StrandFrames,
        Option<&FollowerNodes>,
        Option<&HairFollowers>,
        Option<&StrandOf>,
    )>();
    let world = app.world();
    for (entity, strand, spec, nodes, frames, follower_nodes, followers, strand_of) in query.iter(world) {
        assert!(drawn_is_finite(nodes, frames, follower_nodes), "seed {seed}: strand {entity} drawn non-finite");
        tally.follower_nodes_checked += follower_nodes.map_or(0, |followers| followers.positions.len() as u64);
        count(&mut tally.drawn_by_level, format!("{:?}", strand.detail_level()));
        tally.drawn_while_settings_invalid += u64::from(!settings_valid);
        let Some(motion) = strand_of.and_then(|StrandOf(head)| world.get::<HeadMotion>(*head)) else {
            continue;
        };
        let mut check_root = |what: &str, drawn: Vec3, local: Vec3| {
            let offset = drawn.distance(motion.transform_point(local));
            tally.drawn_roots_checked += 1;
            tally.largest_drawn_root_offset = tally.largest_drawn_root_offset.max(offset);
            assert!(
                offset <= DRAWN_ROOT_TOLERANCE,
                "seed {seed}: {what} of strand {entity} drawn {offset} m off its head at {:?} (settings valid: \
                 {settings_valid}, health {:?})",
                strand.detail_level(),
                strand.health()
            );
        };
        check_root("the root", nodes.positions[0], spec.nodes[0]);
        if let (Some(follower_nodes), Some(followers)) = (follower_nodes, followers) {
            for index in 0..follower_nodes.count() {
                check_root("a follower's root", follower_nodes.follower(index)[0], followers.curves[index][0]);
            }
        }
    }
}

/// Runs one random scenario of the plugin in a headless app: heads with procedural grooms (combed,
/// preloaded, with followers) and groom files (valid and corrupted), strands of their own (with
/// followers), colliders, levels of detail (fixed, from a moving camera, invalid), the hair–hair grid,
/// wind and wind sources, both integrators, and every kind of bad input now and then.
fn plugin_scenario(seed: u64, tally: &mut PluginTally) {
    let mut rng = fastrand::Rng::with_seed(seed);
    tally.scenarios += 1;
    let mut app = hair_app_with((TransformPlugin, AssetPlugin::default()));
    logs::take();
    let mut bad_events = 0_u64;
    let mut heads: Vec<Entity> = (0..rng.usize(1..=2))
        .map(|index| {
            let style = *rng
                .choice(&[HairStyle::Straight, HairStyle::Wavy, HairStyle::Curly, HairStyle::Short, HairStyle::Long])
                .unwrap();
            let groom = HairGroom {
                strand_count: rng.usize(3..=25),
                segments: rng.usize(3..=16),
                style,
                seed: rng.u64(..),
                combing: rng.bool().then(|| Combing {
                    crown_sweep: if rng.bool() { 3.0 * rng.f32() } else { 0.6 },
                    parting_blend: if rng.bool() { 1e-4 + 0.2 * rng.f32() } else { 0.03 },
                    parting_sweep: if rng.bool() { 10.0 * rng.f32() } else { 4.0 },
                    parting: 0.1 * (rng.f32() - 0.5),
                    ..default()
                }),
                followers_per_guide: if rng.bool() { rng.usize(1..=4) } else { 0 },
                follower_clumping: rng.f32(),
                gravity_preload: if rng.bool() { rng.f32() } else { 0.0 },
                hairline_fade: if rng.bool() { 0.05 * rng.f32() } else { 0.008 },
                ..default()
            };
            let transform = Transform::from_xyz(index as f32, 1.6, 0.0);
            app.world_mut().spawn((HairHead, groom, transform)).id()
        })
        .collect();
    // A head grown from a groom file, now and then.
    if rng.f64() < 0.3 {
        let (bytes, tfx) = random_groom_file(&mut rng);
        let file = if tfx { GroomFile::from_tfx(&bytes) } else { GroomFile::from_hair(&bytes) };
        match file {
            Ok(file) => {
                count(&mut tally.groom_files, "read".to_string());
                let handle = app.world_mut().resource_mut::<Assets<GroomFile>>().add(file);
                let placement =
                    GroomPlacement { segments: rng.usize(2..=12), max_strands: rng.usize(1..=12), ..default() };
                let groom = HairGroomFile::new(handle).with_placement(placement);
                heads.push(app.world_mut().spawn((groom, Transform::from_xyz(-1.0, 1.6, 0.0))).id());
                bad_events += 1;
            }
            Err(error) => count(&mut tally.groom_files, kind(format!("{error:?}"))),
        }
    }
    for &head in &heads {
        if rng.bool() {
            app.world_mut().entity_mut(head).insert(HairDetail::fixed(random_level(&mut rng)));
        }
    }
    let mut own: Vec<Entity> = Vec::new();
    for _ in 0..rng.usize(0..=4) {
        let head = *rng.choice(&heads).unwrap();
        let spec = random_spec(&mut rng);
        let mut entity = app.world_mut().spawn((spec.clone(), StrandOf(head)));
        if rng.bool() {
            entity.insert(random_followers(&mut rng, &spec));
        }
        own.push(entity.id());
        bad_events += 2;
    }
    let mut colliders: Vec<(Entity, Vec3)> = Vec::new();
    for _ in 0..rng.usize(0..=3) {
        let head = *rng.choice(&heads).unwrap();
        let shape = random_shape(&mut rng);
        let collider = HairCollider { shape, friction: uniform(&mut rng, 0.0, 1.5) as f32 };
        let position = Vec3::new(0.0, 1.6 + uniform(&mut rng, -0.3, 0.5) as f32, 0.0);
        let velocity = (unit_vector(&mut rng) * log_uniform(&mut rng, -2.0, 0.5)).as_vec3();
        let mut entity = app.world_mut().spawn((collider, Transform::from_translation(position)));
        if rng.bool() {
            entity.insert(HairColliderOf(head));
        }
        colliders.push((entity.id(), velocity));
    }
    let camera_entity = rng.bool().then(|| app.world_mut().spawn(camera(Transform::from_xyz(0.0, 1.6, 3.0))).id());
    let mut wind_sources: Vec<Entity> = Vec::new();
    for _ in 0..rng.usize(0..=2) {
        let source = HairWindSource {
            speed: sometimes_bad(&mut rng, 0.1, |rng| uniform(rng, 0.0, 8.0)) as f32,
            radius: sometimes_bad(&mut rng, 0.1, |rng| uniform(rng, 0.02, 0.3)) as f32,
            range: sometimes_bad(&mut rng, 0.1, |rng| uniform(rng, 0.5, 4.0)) as f32,
        };
        let transform = Transform::from_xyz(0.0, 1.6, 1.0);
        wind_sources.push(app.world_mut().spawn((source, transform)).id());
        bad_events += 1;
    }
    {
        let mut settings = app.world_mut().resource_mut::<HairSettings>();
        settings.integrator = if rng.bool() { Integrator::Bdf2 } else { Integrator::BackwardEuler };
        settings.volume = random_volume(&mut rng);
        bad_events += 1;
    }
    if rng.bool() {
        *app.world_mut().resource_mut::<HairWind>() = random_wind(&mut rng);
        bad_events += 1;
    }
    let updates = rng.usize(20..=40);
    let mut fault_runs: BTreeMap<Entity, u32> = BTreeMap::new();
    let mut levels: BTreeMap<Entity, HairDetailLevel> = BTreeMap::new();
    let dt = DT;
    for _ in 0..updates {
        // Heads move, turn, jump, or lose their transform now and then.
        for &head in &heads {
            let event = rng.f64();
            let mut transform = app.world_mut().get_mut::<Transform>(head).unwrap();
            if event < 0.02 {
                transform.translation += (unit_vector(&mut rng) * 3.0).as_vec3();
            } else if event < 0.03 {
                transform.scale = Vec3::ZERO;
                bad_events += 1;
            } else if event < 0.04 {
                transform.translation.x = f32::NAN;
                bad_events += 1;
            } else {
                if !transform.is_finite() || transform.scale == Vec3::ZERO {
                    *transform = Transform::from_xyz(0.0, 1.6, 0.0);
                }
                transform.translation += (unit_vector(&mut rng) * 0.05).as_vec3();
                transform.rotate(random_rotation(&mut rng, 0.2).as_quat());
            }
            // Levels of detail: fixed ones change, now and then.
            if rng.f64() < 0.05 {
                let detail = if rng.bool() { HairDetail::fixed(random_level(&mut rng)) } else { HairDetail::default() };
                app.world_mut().entity_mut(head).insert(detail);
            }
        }
        for (collider, velocity) in &colliders {
            let jump = rng.f64() < 0.03;
            let mut transform = app.world_mut().get_mut::<Transform>(*collider).unwrap();
            if jump {
                transform.translation = Vec3::new(0.0, 1.7, 0.0);
            } else {
                transform.translation += *velocity * dt as f32;
            }
        }
        // The camera walks off and back, turns away now and then: levels change with distance and sight.
        if let Some(camera_entity) = camera_entity {
            let mut transform = app.world_mut().get_mut::<Transform>(camera_entity).unwrap();
            transform.translation += (unit_vector(&mut rng) * uniform(&mut rng, 0.0, 6.0)).as_vec3();
            let target = if rng.f64() < 0.2 { Vec3::new(0.0, 1.6, -100.0) } else { Vec3::new(0.0, 1.6, 0.0) };
            if transform.translation.distance(target) > 1e-3 {
                *transform = transform.looking_at(target, Vec3::Y);
            }
            let transform = *transform;
            app.world_mut().entity_mut(camera_entity).insert(camera(transform));
            tally.camera_updates += 1;
        }
        if rng.f64() < 0.03 {
            let mut detail_settings = app.world_mut().resource_mut::<HairDetailSettings>();
            detail_settings.full_detail_distance = sometimes_bad(&mut rng, 0.3, |rng| uniform(rng, 0.5, 5.0)) as f32;
            detail_settings.enabled = rng.bool();
            bad_events += 1;
        }
        // Settings: now and then invalid for a while; the grid and the wind change.
        let event = rng.f64();
        if event < 0.03 {
            let mut settings = app.world_mut().resource_mut::<HairSettings>();
            match rng.u8(0..6) {
                0 => settings.default_material.youngs_modulus = 0.0,
                1 => settings.gravity.y = f32::NAN,
                2 => settings.collision_margin = f32::INFINITY,
                3 => settings.volume.cell_size = 0.0,
                4 => settings.style_hold.rate = f32::NAN,
                _ => settings.collision_margin = -1.0,
            }
            bad_events += 1;
        } else if event < 0.15 {
            let mut settings = app.world_mut().resource_mut::<HairSettings>();
            let gravity = settings.gravity;
            *settings = HairSettings {
                air_damping: uniform(&mut rng, 0.0, 10.0) as f32,
                max_newton_iterations: rng.u32(1..=6),
                max_projection_iterations: rng.u32(1..=20),
                default_material: RodMaterial { youngs_modulus: log_uniform(&mut rng, 8.0, 10.0), ..default() },
                gravity: if gravity.is_finite() { gravity } else { Vec3::new(0.0, -9.81, 0.0) },
                integrator: if rng.bool() { Integrator::Bdf2 } else { Integrator::BackwardEuler },
                volume: random_volume(&mut rng),
                // Held or not, up to the stiffest hold allowed.
                style_hold: HairStyleHold {
                    rate: if rng.bool() { uniform(&mut rng, 0.0, 1000.0) as f32 } else { 0.0 },
                    reach: uniform(&mut rng, 0.0, 1.0) as f32,
                },
                ..default()
            };
            bad_events += 1;
        } else if event < 0.2 {
            app.world_mut().resource_mut::<HairSettings>().volume.enabled ^= true;
        } else if event < 0.23 {
            *app.world_mut().resource_mut::<HairWind>() = random_wind(&mut rng);
            bad_events += 1;
        }
        let settings_valid = app.world().resource::<HairSettings>().validated(dt).is_ok();
        tally.grid_updates += u64::from(settings_valid && app.world().resource::<HairSettings>().volume.enabled);
        tally.wind_updates += u64::from(!app.world().resource::<HairWind>().is_calm() || !wind_sources.is_empty());
        for &source in &wind_sources {
            if rng.f64() < 0.03 {
                app.world_mut().get_mut::<Transform>(source).unwrap().translation.y = f32::NAN;
                bad_events += 1;
            } else if rng.f64() < 0.05 {
                *app.world_mut().get_mut::<Transform>(source).unwrap() = Transform::from_xyz(0.0, 1.6, 1.0);
            }
        }
        // Strands: forces (huge, non-finite), written states, respawns, despawns, new ones, followers.
        let strands: Vec<Entity> =
            app.world_mut().query_filtered::<Entity, With<SimulatedStrand>>().iter(app.world()).collect();
        for &entity in &strands {
            let event = rng.f64();
            let world = app.world_mut();
            if event < 0.05 {
                world.get_mut::<StrandForces>(entity).unwrap().add_to_all((unit_vector(&mut rng) * 1e-4).as_vec3());
            } else if event < 0.06 {
                world.get_mut::<StrandForces>(entity).unwrap().add_to_all(Vec3::new(1e6, f32::NAN, 0.0));
            } else if event < 0.065 {
                let mut strand = world.get_mut::<SimulatedStrand>(entity).unwrap();
                let node = rng.usize(..strand.rod().node_count());
                strand.rod_mut().positions_mut()[node] = DVec3::NAN;
            } else if event < 0.07 {
                world.entity_mut(entity).insert(random_spec(&mut rng));
                bad_events += 1;
            } else if event < 0.073 {
                let spec = world.get::<HairStrand>(entity).unwrap().clone();
                world.entity_mut(entity).insert(random_followers(&mut rng, &spec));
                bad_events += 1;
            } else if event < 0.078 {
                world.despawn(entity);
            }
        }
        if rng.f64() < 0.05 {
            let head = *rng.choice(&heads).unwrap();
            app.world_mut().spawn((random_spec(&mut rng), StrandOf(head)));
            bad_events += 1;
        }

        app.update();
        tally.updates += 1;
        let faults = drain_messages::<StrandFault>(&mut app);
        // A strand that did not fail this update ends its run.
        fault_runs.retain(|strand, _| faults.iter().any(|fault| fault.strand == *strand));
        for fault in faults {
            count(&mut tally.faults, kind(format!("{:?}", fault.error)));
            let run = fault_runs.entry(fault.strand).or_default();
            *run += 1;
            tally.longest_fault_run = tally.longest_fault_run.max(*run);
            assert!(*run <= PLUGIN_FAULTS_IN_A_ROW, "seed {seed}: strand {} failed {run} steps in a row", fault.strand);
        }
        let statistics = app.world().resource::<HairStatistics>().clone();
        tally.largest_quarantined = tally.largest_quarantined.max(statistics.quarantined);
        // The strain bound of the step each strand took last: a step of several fixed steps (a coarser
        // level of detail, or the first at full detail after one) keeps edge lengths more loosely.
        let bound = StepParams::default().strain_bound();
        let longer_bound =
            StepParams { strain_tolerance: LONGER_STEP_STRAIN_TOLERANCE, ..StepParams::default() }.strain_bound();
        let mut query = app.world_mut().query::<(Entity, &SimulatedStrand)>();
        for (entity, strand) in query.iter(app.world()) {
            let level = strand.detail_level();
            let full = level == HairDetailLevel::FULL && levels.insert(entity, level) == Some(level);
            levels.insert(entity, level);
            let bound = if full { bound } else { longer_bound };
            let rod = strand.rod();
            let finite = rod.positions().iter().chain(rod.velocities()).all(|v| v.is_finite())
                && rod.twist_angles().iter().all(|t| t.is_finite());
            assert!(finite, "seed {seed}: a non-finite strand");
            let strain = rod.max_strain().1;
            assert!(
                strain <= bound,
                "seed {seed}: strain {strain:e} above the bound {bound:e} at {:?}, {:?}, last report {:?}, stepped now {}",
                strand.detail_level(),
                strand.health(),
                strand.last_report(),
                strand.steps_now()
            );
            tally.largest_strain = tally.largest_strain.max(strain);
            tally.strand_steps += 1;
        }
        check_drawn(&mut app, seed, settings_valid, tally);
    }
    let mut file_strands = app.world_mut().query_filtered::<(), With<FileStrand>>();
    tally.file_strands += file_strands.iter(app.world()).count() as u64;
    let lines = logs::take();
    let seconds = updates as f64 * dt;
    let fault_lines =
        lines.iter().filter(|(_, line)| line.contains("failed a step") || line.contains("more strand faults")).count();
    tally.log_lines += lines.len() as u64;
    tally.most_fault_lines_per_second = tally.most_fault_lines_per_second.max(fault_lines as f64 / seconds);
    // Four single lines a period and a summary, in each (started) second.
    let fault_limit = 5 * (seconds.ceil() as usize + 1);
    assert!(fault_lines <= fault_limit, "seed {seed}: {fault_lines} fault lines in {seconds} s: {lines:#?}");
    // Each bad input is reported once (a rejected strand, a head without a transform, invalid settings).
    let others = lines.len() - fault_lines;
    assert!(
        others as u64 <= bad_events + 2,
        "seed {seed}: {others} other lines for {bad_events} bad inputs: {lines:#?}"
    );
}

fn fuzz_plugin(scenarios: u64, first_seed: u64) -> PluginTally {
    let _log = logs::serial();
    let mut tally = PluginTally::default();
    for seed in first_seed..first_seed + scenarios {
        plugin_scenario(seed, &mut tally);
    }
    println!("{tally:#?}");
    tally
}

#[test]
fn fuzz_the_plugin() {
    let tally = fuzz_plugin(40, 0);
    assert_eq!(tally.scenarios, 40);
    assert!(tally.strand_steps > 1000);
    // The short run reaches every feature: each level of detail, invalid settings, followers, the grid,
    // wind, a camera and groom files read and rejected.
    for level in ["Stepped(1)", "Stepped(2)", "Stepped(4)", "Carried"] {
        assert!(tally.drawn_by_level.get(level).is_some_and(|n| *n > 0), "{level}: {:?}", tally.drawn_by_level);
    }
    assert!(tally.drawn_while_settings_invalid > 0 && tally.follower_nodes_checked > 0);
    assert!(tally.grid_updates > 0 && tally.wind_updates > 0 && tally.camera_updates > 0);
    assert!(tally.groom_files.get("read").is_some_and(|n| *n > 0) && tally.groom_files.len() > 1, "{tally:?}");
    assert!(tally.drawn_roots_checked > 10_000);
}

#[test]
#[ignore = "1 000 scenarios: run with --release"]
fn fuzz_the_plugin_long() {
    fuzz_plugin(1_000, 1_000_000);
}
