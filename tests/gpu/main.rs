//! What runs on the GPU, on a real adapter (Mesa's software Vulkan, lavapipe, on a machine without a GPU,
//! which `.ci/run` installs; without an adapter these tests fail, they never skip): the strand step
//! against the CPU's, the follower placement and drawing against the CPU's, the GPU step in the plugin;
//! and what the renderer computes on the CPU and the shader it compiles. `cargo test --test gpu`.

mod character;
mod colliders;
mod followers;
mod fuzz;
mod gltf_character;
mod grid;
mod plugin;
mod render_layout;
mod render_shader;
mod scaled_rigs;
mod step;
mod wind;

use bevy::app::PluginGroupBuilder;
use bevy::prelude::*;
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::window::ExitCondition;
use bevy_hair_sim::prelude::HairPlugins;

/// Bevy's default plugins on whatever adapter wgpu finds, with no window, every core in the compute pool,
/// and the render world kept in the app (not on a thread of its own) so that the tests can look at it.
fn headless_renderer() -> PluginGroupBuilder {
    DefaultPlugins
        .set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() })
        .set(WindowPlugin {
            primary_window: None,
            exit_condition: ExitCondition::DontExit,
            close_when_requested: false,
            ..default()
        })
        .disable::<PipelinedRenderingPlugin>()
}

/// Reads the buffer `buffer` back frame after frame (one `app.update()` each) until `done` accepts what
/// arrived or `frames` frames have passed; returns the last read-back, if any arrived.
fn read_back_until(
    app: &mut App,
    buffer: Handle<bevy::render::storage::ShaderBuffer>,
    frames: usize,
    mut done: impl FnMut(&[f32]) -> bool,
) -> Option<Vec<f32>> {
    use bevy::render::gpu_readback::{Readback, ReadbackComplete};
    let received: std::sync::Arc<std::sync::Mutex<Option<Vec<f32>>>> = default();
    let sink = received.clone();
    let reader = app
        .world_mut()
        .spawn(Readback::buffer(buffer))
        .observe(move |event: On<ReadbackComplete>| {
            *sink.lock().unwrap() = Some(event.to_shader_type());
        })
        .id();
    let mut last = None;
    for _ in 0..frames {
        app.update();
        if let Some(values) = received.lock().unwrap().take() {
            let finished = done(&values);
            last = Some(values);
            if finished {
                break;
            }
        }
    }
    app.world_mut().despawn(reader);
    last
}

/// Finishes adding `app`'s plugins as `App::run` does: waits for the renderer to find its adapter
/// (asynchronously), then finishes and cleans up the plugins.
fn finish_adding_plugins(app: &mut App) {
    while app.plugins_state() == bevy::app::PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
}

/// Runs one update half a step past the last fixed step, with no step (the drawing interpolates halfway),
/// then stops the clock; returns the interpolation's fraction (checked to be a half).
fn stop_halfway_between_steps(app: &mut App) -> f32 {
    use bevy::time::TimeUpdateStrategy;
    let fixed = app.world().resource::<Time<Fixed>>();
    let to_halfway = (fixed.timestep() / 2).saturating_sub(fixed.overstep());
    app.insert_resource(TimeUpdateStrategy::ManualDuration(to_halfway));
    app.update();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(std::time::Duration::ZERO));
    let alpha = app.world().resource::<Time<Fixed>>().overstep_fraction();
    assert!((alpha - 0.5).abs() < 1e-3, "drawn halfway between steps: {alpha}");
    alpha
}

/// Where the GPU draws node `node` of a follower with rest offset `offset` on a guide of nodes `x` and
/// frames `frames`: `x_g + o_t t + o_1 m1 + o_2 m2` in the frame of the guide's edge arriving at the node
/// (the root edge's at the root), `m1` taken across the drawn edge.
fn follower_node(x: &[Vec3], frames: &bevy_hair_sim::simulation::StrandFrames, node: usize, offset: Vec3) -> Vec3 {
    let edge = node.saturating_sub(1);
    let t = (x[edge + 1] - x[edge]).normalize();
    let m1 = frames.material_frame(edge).unwrap().m1;
    let m1 = (m1 - m1.dot(t) * t).normalize();
    let m2 = t.cross(m1);
    x[node] + offset.x * t + offset.y * m1 + offset.z * m2
}
