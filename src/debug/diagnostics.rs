//! The hair's figures in Bevy's [`DiagnosticsStore`], where Bevy's own tools (the `LogDiagnosticsPlugin`,
//! overlays, editors) read a game's measurements, as avian's `PhysicsDiagnosticsPlugin` puts physics
//! there.

use bevy::diagnostic::{Diagnostic, DiagnosticPath, Diagnostics, RegisterDiagnostic};
use bevy::prelude::*;

use crate::simulation::HairStatistics;

/// Writes [`HairStatistics`] into Bevy's [`DiagnosticsStore`](bevy::diagnostic::DiagnosticsStore) every
/// frame under the paths of [`HairDiagnostics`], so that Bevy's `LogDiagnosticsPlugin` logs them and any
/// diagnostics overlay shows them beside the frame time. Not in [`crate::HairPlugins`]: add it after them.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// # use bevy_hair_sim::debug::HairDiagnosticsPlugin;
/// App::new().add_plugins((MinimalPlugins, HairPlugins::default(), HairDiagnosticsPlugin));
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct HairDiagnosticsPlugin;

/// The [`DiagnosticPath`]s the [`HairDiagnosticsPlugin`] measures, each from the [`HairStatistics`] field of
/// the same meaning.
pub struct HairDiagnostics;

impl HairDiagnostics {
    /// The hair's systems in the last fixed step that simulated hair, ms ([`HairStatistics::update_seconds`]).
    pub const UPDATE_TIME: DiagnosticPath = DiagnosticPath::const_new("hair/update_time");
    /// The strands' step alone, ms ([`HairStatistics::step_seconds`]).
    pub const STEP_TIME: DiagnosticPath = DiagnosticPath::const_new("hair/step_time");
    /// Strands stepped on the CPU in the last step ([`HairStatistics::strands`]).
    pub const STRANDS: DiagnosticPath = DiagnosticPath::const_new("hair/strands");
    /// Strands stepped elsewhere (on the GPU) in the last step ([`HairStatistics::strands_elsewhere`]).
    pub const STRANDS_ON_GPU: DiagnosticPath = DiagnosticPath::const_new("hair/strands_on_gpu");
    /// Mean Newton iterations per strand in the last step ([`HairStatistics::mean_newton_iterations`]).
    pub const NEWTON_ITERATIONS: DiagnosticPath = DiagnosticPath::const_new("hair/newton_iterations");
    /// Largest edge strain after the last step ([`HairStatistics::max_strain`]).
    pub const MAX_STRAIN: DiagnosticPath = DiagnosticPath::const_new("hair/max_strain");
    /// Nodes touching a collider after the last step ([`HairStatistics::contacts`]).
    pub const CONTACTS: DiagnosticPath = DiagnosticPath::const_new("hair/contacts");
    /// Failed strand steps since start ([`HairStatistics::faults`]).
    pub const FAULTS: DiagnosticPath = DiagnosticPath::const_new("hair/faults");
    /// The step interval a CPU budget keeps ([`HairStatistics::budget_step_interval`]), fixed steps.
    pub const BUDGET_STEP_INTERVAL: DiagnosticPath = DiagnosticPath::const_new("hair/budget_step_interval");

    /// Nodes touching a collider after the GPU's last step read back
    /// ([`HairGpuStatus::contacts`](crate::render::HairGpuStatus::contacts); `gpu` feature).
    #[cfg(feature = "gpu")]
    pub const GPU_CONTACTS: DiagnosticPath = DiagnosticPath::const_new("hair/gpu_contacts");
    /// Largest edge strain after the GPU's last step read back
    /// ([`HairGpuStatus::max_strain`](crate::render::HairGpuStatus::max_strain); `gpu` feature).
    #[cfg(feature = "gpu")]
    pub const GPU_MAX_STRAIN: DiagnosticPath = DiagnosticPath::const_new("hair/gpu_max_strain");
    /// Mean Newton iterations per strand-step on the GPU between its last two read-backs
    /// ([`HairGpuStatus::mean_newton_iterations`](crate::render::HairGpuStatus::mean_newton_iterations);
    /// `gpu` feature).
    #[cfg(feature = "gpu")]
    pub const GPU_NEWTON_ITERATIONS: DiagnosticPath = DiagnosticPath::const_new("hair/gpu_newton_iterations");
    /// The GPU's own time in the strands' step and in the hair–hair grid, in the last step read back, ms
    /// ([`HairGpuStatus::timings`](crate::render::HairGpuStatus::timings), from timestamp queries: not
    /// measured where the device has none; `gpu` feature).
    #[cfg(feature = "gpu")]
    pub const GPU_STEP_TIME: DiagnosticPath = DiagnosticPath::const_new("hair/gpu_step_time");
    #[cfg(feature = "gpu")]
    /// The hair–hair grid's part of it, ms (see [`HairDiagnostics::GPU_STEP_TIME`]).
    pub const GPU_GRID_TIME: DiagnosticPath = DiagnosticPath::const_new("hair/gpu_grid_time");
    /// The render thread's time stepping the hair on the GPU in the last frame, ms
    /// ([`HairGpuStatus::render_thread_seconds`](crate::render::HairGpuStatus::render_thread_seconds);
    /// `gpu` feature).
    #[cfg(feature = "gpu")]
    pub const GPU_RENDER_THREAD_TIME: DiagnosticPath = DiagnosticPath::const_new("hair/gpu_render_thread_time");

    /// The GPU's paths, with their suffixes.
    #[cfg(feature = "gpu")]
    const GPU: [(DiagnosticPath, &'static str); 6] = [
        (Self::GPU_CONTACTS, ""),
        (Self::GPU_MAX_STRAIN, ""),
        (Self::GPU_NEWTON_ITERATIONS, ""),
        (Self::GPU_STEP_TIME, "ms"),
        (Self::GPU_GRID_TIME, "ms"),
        (Self::GPU_RENDER_THREAD_TIME, "ms"),
    ];

    /// Every path, with the suffix its values are logged with.
    const ALL: [(DiagnosticPath, &'static str); 9] = [
        (Self::UPDATE_TIME, "ms"),
        (Self::STEP_TIME, "ms"),
        (Self::STRANDS, ""),
        (Self::STRANDS_ON_GPU, ""),
        (Self::NEWTON_ITERATIONS, ""),
        (Self::MAX_STRAIN, ""),
        (Self::CONTACTS, ""),
        (Self::FAULTS, ""),
        (Self::BUDGET_STEP_INTERVAL, ""),
    ];
}

impl Plugin for HairDiagnosticsPlugin {
    fn build(&self, app: &mut App) {
        for (path, suffix) in HairDiagnostics::ALL {
            app.register_diagnostic(Diagnostic::new(path).with_suffix(suffix));
        }
        app.add_systems(Last, measure_hair);
        #[cfg(feature = "gpu")]
        {
            for (path, suffix) in HairDiagnostics::GPU {
                app.register_diagnostic(Diagnostic::new(path).with_suffix(suffix));
            }
            app.add_systems(Last, measure_gpu);
        }
    }
}

/// Adds this frame's [`HairStatistics`] to the store.
fn measure_hair(statistics: Option<Res<HairStatistics>>, mut diagnostics: Diagnostics) {
    let Some(statistics) = statistics else { return };
    let figures = [
        (HairDiagnostics::UPDATE_TIME, statistics.update_seconds * 1e3),
        (HairDiagnostics::STEP_TIME, statistics.step_seconds * 1e3),
        (HairDiagnostics::STRANDS, statistics.strands as f64),
        (HairDiagnostics::STRANDS_ON_GPU, statistics.strands_elsewhere as f64),
        (HairDiagnostics::NEWTON_ITERATIONS, statistics.mean_newton_iterations),
        (HairDiagnostics::MAX_STRAIN, statistics.max_strain),
        (HairDiagnostics::CONTACTS, statistics.contacts as f64),
        (HairDiagnostics::FAULTS, statistics.faults as f64),
        (HairDiagnostics::BUDGET_STEP_INTERVAL, f64::from(statistics.budget_step_interval)),
    ];
    for (path, value) in figures {
        diagnostics.add_measurement(&path, || value);
    }
}

/// Adds the GPU's figures ([`HairGpuStatus`](crate::render::HairGpuStatus)) to the store, where
/// `HairGpuPlugin` runs.
#[cfg(feature = "gpu")]
fn measure_gpu(status: Option<Res<crate::render::HairGpuStatus>>, mut diagnostics: Diagnostics) {
    let Some(status) = status else { return };
    diagnostics.add_measurement(&HairDiagnostics::GPU_CONTACTS, || status.contacts as f64);
    diagnostics.add_measurement(&HairDiagnostics::GPU_MAX_STRAIN, || f64::from(status.max_strain));
    diagnostics.add_measurement(&HairDiagnostics::GPU_NEWTON_ITERATIONS, || status.mean_newton_iterations);
    if let Some(timings) = status.timings {
        diagnostics.add_measurement(&HairDiagnostics::GPU_STEP_TIME, || timings.step_seconds * 1e3);
        diagnostics.add_measurement(&HairDiagnostics::GPU_GRID_TIME, || timings.grid_seconds * 1e3);
    }
    diagnostics.add_measurement(&HairDiagnostics::GPU_RENDER_THREAD_TIME, || status.render_thread_seconds * 1e3);
}
