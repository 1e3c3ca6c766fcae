//! `cargo bench --bench gpu_step`: the strand step on the GPU (`bevy_hair_sim::gpu`), GPU time per step
//! from submit to done (the queue waited on after each step), for heads of 2 000 and 10 000 guides of 32
//! edges resting on a skull, on whatever adapter wgpu finds (lavapipe where there is no GPU). Prints one row
//! per size, with the adapter's name.

use std::time::Instant;

use bevy::math::{DQuat, DVec3};
use bevy_hair_sim::gpu::{GpuHeadStep, GpuStrandInput, GpuStrandSolver, headless_device};
use bevy_hair_sim::rod::{ColliderShape, MovingCollider, RigidPose, Rod, RodMaterial, StepParams};

/// `count` strands of 20 cm in 32 edges rooted over the top of a 10 cm skull at `head`, growing outwards.
fn groom(count: usize, head: DVec3) -> Vec<Rod> {
    (0..count)
        .map(|index| {
            let height = 1.0 - 0.9 * (index as f64 + 0.5) / count as f64;
            let around = index as f64 * 2.399_963;
            let ring = (1.0 - height * height).sqrt();
            let normal = DVec3::new(ring * around.cos(), height, ring * around.sin());
            let nodes: Vec<DVec3> = (0..=32).map(|i| head + normal * (0.1001 + 0.2 * i as f64 / 32.0)).collect();
            let mut rod = Rod::new(&nodes, normal.any_orthonormal_vector(), RodMaterial::human_hair()).unwrap();
            rod.clamp_root_in_place();
            rod
        })
        .collect()
}

fn main() {
    let (device, queue, info) = headless_device().expect("a GPU adapter");
    println!("adapter: {} ({:?}, {:?}, driver {})", info.name, info.device_type, info.backend, info.driver_info);
    let head = DVec3::new(0.0, 1.6, 0.0);
    let params = StepParams::default();
    let skull = MovingCollider {
        shape: ColliderShape::Sphere { radius: 0.1 },
        friction: 0.3,
        start: RigidPose { rotation: DQuat::IDENTITY, translation: head },
        end: RigidPose { rotation: DQuat::IDENTITY, translation: head },
    };
    let step =
        GpuHeadStep { rotation: DQuat::IDENTITY, translation: head, colliders: vec![skull], ..Default::default() };
    println!("{:>8} {:>6} {:>12} {:>14}", "guides", "edges", "ms/step", "µs/strand");
    for (count, steps) in [(2_000, 20), (10_000, 5)] {
        let rods = groom(count, head);
        let inputs: Vec<GpuStrandInput> = rods
            .iter()
            .map(|rod| GpuStrandInput {
                rod,
                head: 0,
                thickness: 1e-4,
                groomed: None,
                hairs: 1.0,
                groomed_fractions: None,
            })
            .collect();
        let mut solver = GpuStrandSolver::new(&device, &inputs, &[(DQuat::IDENTITY, head)]).unwrap();
        // The first step compiles the pipeline on some drivers: not timed.
        solver.step(&device, &queue, &params, std::slice::from_ref(&step)).unwrap();
        let _ = device.poll(wgpu::PollType::wait_indefinitely());
        let start = Instant::now();
        for _ in 0..steps {
            solver.step(&device, &queue, &params, std::slice::from_ref(&step)).unwrap();
            let _ = device.poll(wgpu::PollType::wait_indefinitely());
        }
        let per_step = start.elapsed().as_secs_f64() / steps as f64;
        let faults: u32 = solver.read_back(&device, &queue).status.iter().map(|s| s.faults).sum();
        println!(
            "{count:>8} {:>6} {:>12.3} {:>14.3}   (faults {faults})",
            32,
            1e3 * per_step,
            1e6 * per_step / count as f64
        );
    }
}
