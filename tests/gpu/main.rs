//! What runs on the GPU, on a real adapter (Mesa's software Vulkan, lavapipe, on a machine without a GPU,
//! which `.ci/run` installs; without an adapter these tests fail, they never skip): the strand step
//! against the CPU's, the follower placement and drawing against the CPU's, the GPU step in the plugin;
//! and what the renderer computes on the CPU and the shader it compiles. `cargo test --test gpu`.

mod followers;
mod plugin;
mod render_layout;
mod render_shader;
mod step;
