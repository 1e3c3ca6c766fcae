//! Run-time settings of the hair simulation and the statistics it reports.

use bevy::prelude::*;

use crate::detail::HeadsByDetail;
use crate::rod::{Integrator, RodError, RodMaterial, StepParams};
use crate::volume::HairVolume;

/// Settings of the hair simulation, read at every fixed step: a change takes effect at the next step.
/// Invalid values are reported once with an error message and the simulation waits until they are fixed.
#[derive(Resource, Reflect, Debug, Clone, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairSettings {
    /// Gravitational acceleration, m/s². Default `(0, −9.81, 0)`.
    pub gravity: Vec3,
    /// The time integrator: [`Integrator::Bdf2`] (default, second order: hair swings as long as its
    /// damping says) or [`Integrator::BackwardEuler`] (first order: it damps every motion by itself, see
    /// the README's table).
    pub integrator: Integrator,
    /// Air drag across the strands `γ`, 1/s: a strand moving sideways through the air (relative to the
    /// wind, [`crate::wind::HairWind`]) slows as `e^{−γt}`. Default 3 (see [`StepParams::air_damping`]).
    pub air_damping: f32,
    /// Air drag along the strands as a fraction of the drag across them, in [0, 1]. Default 0.5 (a
    /// slender cylinder; see [`StepParams::axial_drag_ratio`]).
    pub axial_drag_ratio: f32,
    /// Internal (Rayleigh) damping of the material, s: an elastic mode of angular frequency `ω` decays at
    /// the rate `½ β ω²`. Default 0.001.
    pub internal_damping: f32,
    /// Most Newton iterations per step and strand. Calm steps take 1; violent head motion takes more.
    /// Default 4.
    pub max_newton_iterations: u32,
    /// Most iterations of the inextensibility projection per Newton iteration (at least 1; a step whose
    /// edges would end beyond the strain bound takes more, see [`StepParams::strain_bound`]). Default 16.
    pub max_projection_iterations: u32,
    /// A head that moves farther than this in one step, m, carries its hair along rigidly (a teleport)
    /// instead of dragging it. Default 0.5 (30 m/s at 60 Hz).
    pub teleport_distance: f32,
    /// Most simulation steps per rendered frame. After a long frame hitch the fixed schedule would catch
    /// up every step it missed; beyond this many, the hair skips steps instead. 0 pauses the hair.
    /// Default 4.
    pub max_steps_per_frame: u32,
    /// Collision thickness added to each strand's radius, m: how far from a collider's surface the strand's
    /// centre line stays (unless the strand sets [`crate::strand::HairStrand::collision_thickness`]).
    /// Keeps drawn lines off the collider's mesh. Default 0.001.
    pub collision_margin: f32,
    /// Material of strands that name none ([`crate::strand::HairStrand::material`]): human hair by default.
    pub default_material: RodMaterial,
    /// Hair–hair interaction: velocity smoothing and volume pressure through a grid (see
    /// [`crate::volume`]). On by default.
    pub volume: HairVolume,
}

impl Default for HairSettings {
    fn default() -> Self {
        let step = StepParams::default();
        Self {
            gravity: step.gravity.as_vec3(),
            integrator: step.integrator,
            air_damping: step.air_damping as f32,
            axial_drag_ratio: step.axial_drag_ratio as f32,
            internal_damping: step.internal_damping as f32,
            max_newton_iterations: step.max_newton_iterations,
            max_projection_iterations: step.max_projection_iterations,
            teleport_distance: 0.5,
            max_steps_per_frame: 4,
            collision_margin: 0.001,
            default_material: RodMaterial::human_hair(),
            volume: HairVolume::default(),
        }
    }
}

impl HairSettings {
    /// The mechanics core's parameters for a step of `dt` seconds, checked, and the collision margin, m;
    /// the default material is checked too.
    pub fn validated(&self, dt: f64) -> Result<(StepParams, f64), RodError> {
        let params = self.step_params(dt);
        params.validate()?;
        self.default_material.validate()?;
        self.volume.validate()?;
        let margin = f64::from(self.collision_margin);
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(RodError::InvalidCollider { parameter: "collision_margin", value: margin });
        }
        Ok((params, margin))
    }

    /// The mechanics core's parameters for a step of `dt` seconds.
    pub fn step_params(&self, dt: f64) -> StepParams {
        StepParams {
            dt,
            gravity: self.gravity.as_dvec3(),
            integrator: self.integrator,
            air_damping: f64::from(self.air_damping),
            axial_drag_ratio: f64::from(self.axial_drag_ratio),
            internal_damping: f64::from(self.internal_damping),
            max_newton_iterations: self.max_newton_iterations,
            max_projection_iterations: self.max_projection_iterations,
            ..StepParams::default()
        }
    }
}

/// Pauses the hair simulation or runs it a step at a time, for tools and debugging. While paused, heads
/// may move; their hair waits (and is dragged, or carried along if the head went farther than
/// [`HairSettings::teleport_distance`], when the simulation resumes). Strands are still built and
/// settings still applied.
#[derive(Resource, Reflect, Debug, Clone, Default, PartialEq, Eq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairPause {
    /// Whether the simulation is paused.
    pub paused: bool,
    /// Steps still to run while paused, one per fixed step (see [`HairPause::step_once`]).
    pub pending_steps: u32,
}

impl HairPause {
    /// Runs one more step while paused.
    pub fn step_once(&mut self) {
        self.pending_steps += 1;
    }
}

/// What the simulation measured, updated every step: for a statistics panel, logs and tests.
#[derive(Resource, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Resource, Debug, Default, Clone)]
pub struct HairStatistics {
    /// Strands simulated in the last step.
    pub strands: usize,
    /// Strands not simulated in the last step because their head is at a coarser level of detail (stepped
    /// on other fixed steps, or carried; see [`crate::detail`]).
    pub unstepped_strands: usize,
    /// Heads at each level of detail at the last step ([`crate::detail`]).
    pub heads_by_detail: HeadsByDetail,
    /// Nodes of those strands.
    pub nodes: usize,
    /// Steps simulated since start.
    pub steps: u64,
    /// Steps skipped because a frame asked for more than [`HairSettings::max_steps_per_frame`].
    pub skipped_steps: u64,
    /// Failed strand steps since start (each reported with a [`crate::strand::StrandFault`]).
    pub faults: u64,
    /// Strands in quarantine after the last step: they failed again soon after a failure, and are held in
    /// their rest pose on their head, not stepped, until they are retried (see [`crate::strand::SimulatedStrand`]).
    pub quarantined: usize,
    /// Largest edge strain of any strand after the last step, dimensionless.
    pub max_strain: f64,
    /// Nodes touching a collider after the last step.
    pub contacts: usize,
    /// Mean Newton iterations per strand in the last step.
    pub mean_newton_iterations: f64,
    /// Wall-clock time the last step of all strands took, s.
    pub step_seconds: f64,
    /// Follower hairs placed after the last step ([`crate::followers`]).
    pub followers: usize,
    /// Wall-clock time placing them took, s.
    pub follower_seconds: f64,
    /// Wall-clock time the hair–hair interaction took in the last step, s ([`crate::volume`]).
    pub volume_seconds: f64,
    /// Largest hair volume fraction on any head's grid after the last splat (see
    /// [`crate::volume::HairVolume::target_volume_fraction`]).
    pub max_volume_fraction: f64,
    /// Why the current settings cannot be used, while they cannot.
    pub settings_error: Option<String>,
}
