//! The GPU step fed at random (seeded, so every failure replays): strands of every length the GPU takes, on
//! heads that shake, turn and jump, among colliders of every shape (baked meshes included) that move with
//! them, in gusts, eddies and jets, stepped, waiting or carried at random. Whatever happens, what a game
//! reads stays finite, a strand that did not fail keeps its root edge on its head, and a failure is
//! reported in its status, not as a NaN or a panic.

use bevy::math::{DQuat, DVec3};
use bevy::platform::sync::Arc;
use bevy::prelude::{GlobalTransform, Transform, Vec3};
use bevy_hair_sim::gpu::{GpuHairCadence, GpuHeadStep, GpuStrandInput, GpuStrandSolver, MAX_GPU_NODES};
use bevy_hair_sim::prelude::{HairWind, HairWindSource};
use bevy_hair_sim::rod::{
    AirSnapshot, ColliderShape, DistanceField, MovingCollider, RigidPose, Rod, RodMaterial, StepParams,
};
use hair_sim_support::{star_shaped, straight_nodes};

use crate::step::device;

fn unit_vector(rng: &mut fastrand::Rng) -> DVec3 {
    loop {
        let v = DVec3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5) * 2.0;
        if let Some(unit) = v.try_normalize().filter(|_| v.length() <= 1.0) {
            return unit;
        }
    }
}

fn random_shape(rng: &mut fastrand::Rng, mesh: &Arc<DistanceField>) -> ColliderShape {
    let size = |rng: &mut fastrand::Rng| 0.02 + 0.15 * rng.f64();
    match rng.usize(0..7) {
        0 => ColliderShape::sphere(size(rng)),
        1 => ColliderShape::capsule(size(rng), size(rng)),
        2 => ColliderShape::ellipsoid(DVec3::new(size(rng), size(rng), size(rng))),
        3 => ColliderShape::Plane,
        4 => ColliderShape::cuboid(DVec3::new(size(rng), size(rng), size(rng))),
        5 => ColliderShape::Cuboid {
            half_extents: DVec3::new(size(rng), size(rng), size(rng)),
            rounding: 0.02 * rng.f64(),
        },
        _ => ColliderShape::Mesh {
            field: mesh.clone(),
            scale: DVec3::splat(0.5 + rng.f64()),
            inflation: 0.005 * rng.f64(),
        },
    }
}

/// A head's next pose after `previous`: shaken by up to 3 cm and turned by up to 0.2 rad, or now and then
/// jumped a metre and half a turn.
fn head_pose(rng: &mut fastrand::Rng, previous: (DQuat, DVec3)) -> (DQuat, DVec3) {
    if rng.f64() < 0.03 {
        // A teleport: a metre away, half a turn round.
        return (DQuat::from_axis_angle(unit_vector(rng), 3.0 * rng.f64()), previous.1 + unit_vector(rng));
    }
    let turn = DQuat::from_axis_angle(unit_vector(rng), 0.2 * rng.f64());
    ((turn * previous.0).normalize(), previous.1 + 0.03 * unit_vector(rng))
}

#[test]
fn the_gpu_step_fed_at_random_stays_finite_and_rooted() {
    let (_turn, device, queue) = device();
    let (positions, triangles) = star_shaped(|d| 0.08 * (1.0 + 0.3 * d.x.abs()), 12);
    let mesh = Arc::new(DistanceField::bake(&positions, &triangles, 0.008).unwrap());
    let (mut steps, mut faults, mut carried, mut meshes) = (0, 0, 0, 0);
    let mut reasons = std::collections::BTreeMap::<String, usize>::new();
    for case in 0..12_u64 {
        let mut rng = fastrand::Rng::with_seed(case);
        let heads = rng.usize(1..=2);
        let mut poses: Vec<(DQuat, DVec3)> =
            (0..heads).map(|h| (DQuat::IDENTITY, DVec3::new(h as f64, 1.6, 0.0))).collect();
        let rods: Vec<(Rod, usize)> = (0..rng.usize(1..=8))
            .map(|_| {
                let head = rng.usize(0..heads);
                let edges = rng.usize(2..MAX_GPU_NODES);
                let root = poses[head].1 + 0.1 * unit_vector(&mut rng);
                let nodes: Vec<DVec3> = straight_nodes(0.05 + 0.4 * rng.f64(), edges, unit_vector(&mut rng))
                    .into_iter()
                    .map(|p| p + root)
                    .collect();
                let mut rod = Rod::new(
                    &nodes,
                    unit_vector(&mut rng).cross(DVec3::X).try_normalize().unwrap_or(DVec3::Y),
                    RodMaterial::human_hair(),
                )
                .or_else(|_| Rod::new(&nodes, DVec3::Z, RodMaterial::human_hair()))
                .unwrap();
                rod.clamp_root_in_place();
                (rod, head)
            })
            .collect();
        let inputs: Vec<GpuStrandInput> = rods
            .iter()
            .map(|(rod, head)| GpuStrandInput {
                rod,
                head: *head,
                thickness: 1e-4 * rng.f64(),
                groomed: None,
                hairs: 1.0,
                groomed_fractions: None,
            })
            .collect();
        let mut gpu = GpuStrandSolver::new(&device, &inputs, &poses).unwrap();
        // Each head's colliders, placed relative to it.
        let shapes: Vec<Vec<(ColliderShape, DVec3, f64)>> = (0..heads)
            .map(|_| {
                (0..rng.usize(0..=3))
                    .map(|_| (random_shape(&mut rng, &mesh), 0.15 * unit_vector(&mut rng), rng.f64()))
                    .collect()
            })
            .collect();
        meshes += shapes.iter().flatten().filter(|(shape, ..)| matches!(shape, ColliderShape::Mesh { .. })).count();
        let wind = HairWind {
            velocity: Vec3::new(rng.f32() * 3.0, 0.0, rng.f32()),
            gusts: rng.f32(),
            turbulence: rng.f32(),
            seed: case,
            ..Default::default()
        };
        let dryer = HairWindSource { speed: 8.0 * rng.f32(), radius: 0.05, range: 1.0 };
        let dryer_at =
            GlobalTransform::from(Transform::from_xyz(0.3, 1.6, 0.5).looking_at(Vec3::new(0.0, 1.6, 0.0), Vec3::Y));
        let params = StepParams { dt: 1.0 / 60.0, ..Default::default() };
        let mut air = AirSnapshot::default();
        for step in 1..=60 {
            let before = poses.clone();
            for pose in &mut poses {
                *pose = head_pose(&mut rng, *pose);
            }
            let head_steps: Vec<GpuHeadStep> = (0..heads)
                .map(|h| {
                    let at = |(rotation, translation): (DQuat, DVec3), offset: DVec3| RigidPose {
                        rotation,
                        translation: translation + rotation * offset,
                    };
                    let colliders = shapes[h]
                        .iter()
                        .map(|(shape, offset, friction)| MovingCollider {
                            shape: shape.clone(),
                            friction: *friction,
                            start: at(before[h], *offset),
                            end: at(poses[h], *offset),
                        })
                        .collect();
                    let cadence = match rng.usize(0..6) {
                        0 => GpuHairCadence::Carried,
                        1 => GpuHairCadence::Waiting,
                        2 => GpuHairCadence::Step(rng.u32(2..=4)),
                        _ => GpuHairCadence::Step(1),
                    };
                    carried += usize::from(matches!(cadence, GpuHairCadence::Carried | GpuHairCadence::Waiting));
                    GpuHeadStep {
                        rotation: poses[h].0,
                        translation: poses[h].1,
                        colliders,
                        cadence,
                        hold_rate: if rng.bool() { 100.0 * rng.f64() } else { 0.0 },
                        hold_reach: rng.f64(),
                        ..Default::default()
                    }
                })
                .collect();
            wind.snapshot_into(step as f64 * params.dt, [(&dryer, &dryer_at)], &mut air);
            gpu.set_air(&air).unwrap();
            gpu.step(&device, &queue, &params, &head_steps).unwrap();
            steps += 1;
            if step % 10 != 0 {
                continue;
            }
            let states = gpu.read_back(&device, &queue);
            for (s, (rod, head)) in rods.iter().enumerate() {
                let status = states.status[s];
                assert!(
                    states.positions[s].iter().chain(&states.velocities[s]).all(|v| v.is_finite())
                        && states.twists[s].iter().all(|t| t.is_finite())
                        && status.max_strain.is_finite(),
                    "case {case}, step {step}, strand {s}: not finite: {status:?}"
                );
                faults += usize::from(status.fault.is_some());
                if let Some(fault) = status.fault {
                    *reasons
                        .entry(format!("{fault:?}").split([' ', '{']).next().unwrap_or_default().to_string())
                        .or_insert(0) += 1;
                }
                // The root edge on its head (where the head holds it, relative to its pose now).
                let (rotation, translation) = poses[*head];
                let (start_rotation, start_translation) = (DQuat::IDENTITY, DVec3::new(*head as f64, 1.6, 0.0));
                for node in 0..2 {
                    let local = start_rotation.inverse() * (rod.positions()[node] - start_translation);
                    let target = translation + rotation * local;
                    let off = states.positions[s][node].distance(target);
                    assert!(
                        off < 1e-5 * (1.0 + translation.length()),
                        "case {case}, step {step}, strand {s}: root node {node} {off} m off"
                    );
                }
            }
        }
    }
    // Measured: 720 steps; 43 strand faults seen at the read-backs, all over-strained (heads jumping a
    // metre and half a turn in a step, or shaken 3 cm a step, strain their hair past the bound; each is
    // reset on its root and reported); 396 head-steps carried or waiting; two mesh colliders.
    println!(
        "{steps} steps, {faults} faults seen ({reasons:?}), {carried} head-steps carried or waiting, {meshes} mesh colliders"
    );
    assert!(carried > 0 && meshes > 0, "the cases reach carrying and mesh colliders");
}

/// The plugin with the GPU stepping (its default) fed at random, as `tests/plugin/fuzz.rs` feeds the CPU's:
/// six seeded scenarios of one or two heads with grooms of every style (followers, combing, preload),
/// colliders of every shape moving and jumping, heads that move, turn, jump a few metres or lose their
/// scale, levels of detail changing, the hair–hair grid on, off and with a cell of 0 (invalid settings),
/// wind, and forces and air velocities added to strands now and then, some not finite. The components are read back after
/// every step. Whatever happens: every strand's nodes and frames stay finite, the GPU keeps stepping
/// (no error), each fault is reported (a `StrandFault`), no strand fails in more than three updates
/// running (three faults soon after each other hand it to the CPU, in quarantine), and non-finite forces and air velocities are reported,
/// not applied. (The
/// inputs are seeded; when a read-back arrives is not, so the faults counted vary a little from run to run.)
#[test]
fn the_plugin_on_the_gpu_fed_at_random_stays_finite() {
    use bevy::prelude::*;
    use bevy::time::TimeUpdateStrategy;
    use bevy_hair_sim::prelude::*;
    use bevy_hair_sim::simulation::{SimulatedStrand, SteppedElsewhere, StrandFault, StrandForces};
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let (mut faults_seen, mut forces_rejected, mut air_rejected, mut on_gpu_steps) =
        (0_usize, 0_usize, 0_usize, 0_usize);
    let mut kinds: std::collections::BTreeMap<String, usize> = Default::default();
    for seed in 0..6_u64 {
        let mut rng = fastrand::Rng::with_seed(seed);
        let mut app = App::new();
        app.add_plugins((crate::headless_renderer(), HairPlugins::default()))
            .insert_resource(Time::<Fixed>::from_seconds(1.0 / 60.0))
            .insert_resource(TimeUpdateStrategy::FixedTimesteps(1))
            .insert_resource(HairGpuSettings { read_back: GpuReadBackRate::EveryStep, ..default() });
        crate::finish_adding_plugins(&mut app);
        app.update();
        let heads: Vec<Entity> = (0..rng.usize(1..=2))
            .map(|index| {
                let style = *rng.choice(&HairStyle::ALL).unwrap();
                let groom = HairGroom {
                    strand_count: rng.usize(8..=40),
                    segments: rng.usize(4..=32),
                    style,
                    seed: rng.u64(..),
                    followers_per_guide: rng.usize(0..=3),
                    gravity_preload: rng.f32(),
                    ..default()
                };
                app.world_mut().spawn((HairHead, groom, Transform::from_xyz(index as f32, 1.6, 0.0))).id()
            })
            .collect();
        let mut colliders = Vec::new();
        for _ in 0..rng.usize(0..=3) {
            let size = 0.03 + 0.1 * rng.f32();
            let collider = match rng.usize(0..5) {
                0 => HairCollider::sphere(size),
                1 => HairCollider::capsule(size, size),
                2 => HairCollider::ellipsoid(Vec3::splat(size)),
                3 => HairCollider::cuboid(Vec3::new(size, 0.5 * size, size)),
                _ => HairCollider::plane(),
            };
            let head = *rng.choice(&heads).unwrap();
            let at = Transform::from_xyz(0.0, 1.6 - 0.3 * rng.f32(), 0.0);
            colliders.push(app.world_mut().spawn((collider, at, HairColliderOf(head))).id());
        }
        {
            let mut settings = app.world_mut().resource_mut::<HairSettings>();
            *settings = HairSettings::styled();
            settings.volume.enabled = rng.bool();
        }
        if rng.bool() {
            *app.world_mut().resource_mut::<HairWind>() =
                HairWind { velocity: Vec3::new(2.0, 0.0, 1.0), gusts: 1.0, turbulence: 1.0, ..default() };
        }
        let mut runs: std::collections::BTreeMap<Entity, u32> = Default::default();
        for _ in 0..40 {
            for &head in &heads {
                let event = rng.f64();
                let mut transform = app.world_mut().get_mut::<Transform>(head).unwrap();
                if event < 0.03 {
                    transform.translation += Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * 6.0;
                } else if event < 0.04 {
                    transform.scale = Vec3::ZERO;
                } else {
                    if transform.scale == Vec3::ZERO {
                        transform.scale = Vec3::ONE;
                    }
                    transform.translation.x += 0.02 * (rng.f32() - 0.5);
                    transform.rotate_y(0.2 * (rng.f32() - 0.5));
                }
                if rng.f64() < 0.05 {
                    let level = *rng
                        .choice(&[
                            HairDetailLevel::FULL,
                            HairDetailLevel::Stepped(2),
                            HairDetailLevel::Stepped(4),
                            HairDetailLevel::Carried,
                        ])
                        .unwrap();
                    app.world_mut().entity_mut(head).insert(HairDetail::fixed(level));
                }
            }
            for &collider in &colliders {
                let jump = rng.f64() < 0.05;
                let mut transform = app.world_mut().get_mut::<Transform>(collider).unwrap();
                transform.translation.y += if jump { 0.3 } else { 0.01 * (rng.f32() - 0.5) };
            }
            let event = rng.f64();
            if event < 0.05 {
                app.world_mut().resource_mut::<HairSettings>().volume.cell_size = 0.0;
            } else if event < 0.2 {
                let mut settings = app.world_mut().resource_mut::<HairSettings>();
                settings.volume = HairSettings::styled().volume;
                settings.volume.enabled = rng.bool();
                settings.volume.stiffness = 100.0 * rng.f32();
            }
            let strands: Vec<Entity> =
                app.world_mut().query_filtered::<Entity, With<SteppedElsewhere>>().iter(app.world()).collect();
            on_gpu_steps += strands.len();
            for &strand in &strands {
                let event = rng.f64();
                let mut forces = app.world_mut().get_mut::<StrandForces>(strand).unwrap();
                if event < 0.05 {
                    forces.add_to_all(Vec3::new(rng.f32() - 0.5, 0.0, rng.f32() - 0.5) * 1e-5);
                } else if event < 0.06 {
                    forces.add_to_all(Vec3::new(1e6, f32::NAN, 0.0));
                } else if event < 0.1 {
                    forces.add_air_velocity_to_all(Vec3::new(rng.f32() - 0.5, 0.0, rng.f32() - 0.5) * 4.0);
                } else if event < 0.11 {
                    forces.add_air_velocity_to_all(Vec3::new(f32::INFINITY, 0.0, 0.0));
                }
            }
            app.update();
            let faults: Vec<StrandFault> = app.world_mut().resource_mut::<Messages<StrandFault>>().drain().collect();
            // A game's bad input is refused each time it is sent; failed steps make the runs (updates running
            // in which the strand failed, however many read-backs the update took in).
            let refused_input = |fault: &StrandFault| {
                let kind = format!("{:?}", fault.error);
                kind.contains("NonFiniteForce") || kind.contains("NonFiniteAirVelocity")
            };
            let failed: std::collections::BTreeMap<Entity, &StrandFault> =
                faults.iter().filter(|fault| !refused_input(fault)).map(|fault| (fault.strand, fault)).collect();
            runs.retain(|strand, _| failed.contains_key(strand));
            for fault in &faults {
                faults_seen += 1;
                let kind = format!("{:?}", fault.error);
                forces_rejected += usize::from(kind.contains("NonFiniteForce"));
                air_rejected += usize::from(kind.contains("NonFiniteAirVelocity"));
                *kinds.entry(kind.split([' ', '(', '{']).next().unwrap_or_default().to_string()).or_default() += 1;
            }
            for (&strand, fault) in &failed {
                let run = runs.entry(strand).or_default();
                *run += 1;
                assert!(
                    *run <= 3,
                    "seed {seed}: strand {strand} failed {run} updates running, the last {:?}",
                    fault.error
                );
            }
            let mut strands = app.world_mut().query::<(Entity, &SimulatedStrand, &StrandNodes, &StrandFrames)>();
            for (entity, strand, nodes, frames) in strands.iter(app.world()) {
                let finite = nodes.positions.iter().all(|p| p.is_finite())
                    && (0..nodes.positions.len().saturating_sub(1))
                        .all(|edge| frames.material_frame(edge).is_none_or(|frame| frame.m1.is_finite()));
                assert!(finite, "seed {seed}: strand {entity} reads non-finite ({:?})", strand.health());
            }
            let status = app.world().resource::<HairGpuStatus>();
            assert!(status.error.is_none(), "seed {seed}: {:?}", status.error);
        }
    }
    println!(
        "{on_gpu_steps} strand-updates on the GPU, {faults_seen} faults reported ({kinds:?}), {forces_rejected} of them forces that were not finite, {air_rejected} air velocities"
    );
    assert!(on_gpu_steps > 1000 && forces_rejected > 0, "the scenarios reach the GPU and the bad forces");
    assert!(air_rejected > 0, "the scenarios reach the bad air velocities");
}
