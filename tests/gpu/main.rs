//! What runs on the GPU, on a real adapter (Mesa's software Vulkan, lavapipe, on a machine without a GPU,
//! which `.ci/run` installs; without an adapter these tests fail, they never skip): the strand step
//! against the CPU's, the follower placement and drawing against the CPU's, the GPU step in the plugin;
//! and what the renderer computes on the CPU and the shader it compiles. `cargo test --test gpu`.

mod followers;
mod gltf_character;
mod plugin;
mod render_layout;
mod render_shader;
mod scaled_rigs;
mod step;

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
