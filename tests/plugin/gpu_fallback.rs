//! The GPU's stepping is part of `HairPlugins` (`gpu` feature) and on by default; where the app cannot
//! run it (no renderer, a device without compute shaders or with too few storage buffers, as WebGL2), the
//! CPU steps every strand and `HairGpuStatus::error` says why, once.

use bevy::prelude::*;
use bevy_hair_sim::gpu::{GpuStepError, gpu_step_support};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::{SimulatedStrand, SteppedElsewhere};
use hair_sim_support::headless::{hair_app, spawn_head};

/// Without a renderer (`MinimalPlugins`), the GPU's stepping turns itself off, says why, and stays off
/// even when a game turns it on: the CPU steps the hair, which falls.
#[test]
fn without_a_renderer_the_cpu_steps_the_hair_and_says_why() {
    let mut app = hair_app();
    let (_, strands) = spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 12, 8);
    let status = app.world().resource::<HairGpuStatus>().clone();
    let why = status.error.expect("the GPU's status says why the CPU steps the hair");
    assert!(why.contains("no renderer"), "{why}");
    assert!(!app.world().resource::<HairGpuSettings>().enabled, "turned off where it cannot run");
    // A game turning it on again (a saved setting, say) changes nothing: there is no GPU to step on.
    app.insert_resource(HairGpuSettings { enabled: true, ..default() });
    for _ in 0..3 {
        app.update();
    }
    let tips: Vec<Vec3> = strands
        .iter()
        .map(|&strand| *app.world().get::<SimulatedStrand>(strand).unwrap().rod().positions().last().unwrap())
        .map(|tip| tip.as_vec3())
        .collect();
    for _ in 0..20 {
        app.update();
    }
    for (&strand, tip) in strands.iter().zip(&tips) {
        assert!(app.world().get::<SteppedElsewhere>(strand).is_none(), "no strand is handed to a GPU");
        let now = app.world().get::<SimulatedStrand>(strand).unwrap().rod().positions().last().unwrap().as_vec3();
        assert!(now.y < tip.y - 1e-3, "the CPU steps it: its tip falls ({} → {})", tip.y, now.y);
    }
    let statistics = app.world().resource::<HairStatistics>();
    assert_eq!(statistics.strands, strands.len(), "every strand stepped on the CPU");
    assert_eq!(app.world().resource::<HairGpuStatus>().strands, 0);
}

/// A device with WebGL2's limits (no compute shaders, no storage buffers) cannot run the step, and the
/// error names what it lacks; WebGPU's default limits can.
#[test]
fn webgl2_cannot_run_the_gpu_step_and_webgpu_can() {
    let webgl2 =
        wgpu::DownlevelCapabilities { flags: wgpu::DownlevelFlags::empty(), ..wgpu::DownlevelCapabilities::default() };
    match gpu_step_support(&wgpu::Limits::downlevel_webgl2_defaults(), &webgl2) {
        Err(GpuStepError::Unsupported(missing)) => {
            assert!(missing.contains("compute shaders"), "{missing}");
            assert!(missing.contains("8 storage buffers a shader stage (it has 0)"), "{missing}");
        }
        other => panic!("WebGL2 runs no compute: {other:?}"),
    }
    assert_eq!(gpu_step_support(&wgpu::Limits::default(), &wgpu::DownlevelCapabilities::default()), Ok(()));
    // A device one storage buffer short (a downlevel adapter, say) is named as such.
    let short = wgpu::Limits { max_storage_buffers_per_shader_stage: 4, ..wgpu::Limits::default() };
    let error = gpu_step_support(&short, &wgpu::DownlevelCapabilities::default()).unwrap_err();
    assert_eq!(
        error.to_string(),
        "the GPU cannot run the strand step: it lacks 8 storage buffers a shader stage (it has 4)"
    );
}
