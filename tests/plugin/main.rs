//! The plugin in headless Bevy apps stepped one fixed step per update (`hair_sim_support::headless`):
//! heads, strands, colliders, the grid, wind, levels of detail, faults and the log, grooms and their
//! files, and the crate's layout. `cargo test --test plugin`.

mod bevy_tools;
mod budget;
mod collision;
mod combed;
mod controls;
mod detail;
mod fault_log;
mod followers;
mod fuzz;
mod fuzz_regressions;
mod gpu_fallback;
mod groom_file;
mod layout;
mod lifecycle;
mod links;
mod mesh_colliders;
mod names_beside_avian;
mod plugin_faults;
mod robustness;
mod scaled_rigs;
mod scalp_binding;
mod scalp_groom;
mod strand_data;
mod style_hold;
mod volume;
mod wind;

use hair_sim_support::counting_allocator::CountingAllocator;

/// Counting, for the largest allocation a corrupt groom file makes (`groom_file`).
#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;
