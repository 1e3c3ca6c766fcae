//! Run-time settings of the hair simulation and the statistics it reports.

use bevy::prelude::*;

use super::cadence::HeadsByDetail;
use crate::rod::{Integrator, RodError, RodMaterial, StepParams};

/// Settings of the hair simulation, read at every fixed step: a change takes effect at the next step.
/// Invalid values are reported once with an error message ([`HairStatistics::settings_error`]); until they
/// are fixed the hair is held: not simulated, drawn carried rigidly with its heads, its clocks stopped, and
/// it resumes with its heads' motion.
#[derive(Resource, Reflect, Debug, Clone, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairSettings {
    /// Gravitational acceleration, m/s². Default `(0, −9.81, 0)`.
    pub gravity: Vec3,
    /// The time integrator: [`Integrator::Bdf2`] (default, second order: hair swings as long as its
    /// damping says) or [`Integrator::BackwardEuler`] (first order: it damps every motion by itself; see
    /// [`Integrator`] for how much).
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
    /// centre line stays (unless the strand sets [`crate::simulation::HairStrand::collision_thickness`]).
    /// Keeps drawn lines off the collider's mesh. Default 0.001.
    pub collision_margin: f32,
    /// Material of strands that name none ([`crate::simulation::HairStrand::material`]): human hair by default.
    pub default_material: RodMaterial,
    /// Hair–hair interaction: velocity smoothing and volume pressure through a grid (see
    /// [`crate::volume`], which [`HairVolumePlugin`](crate::volume::HairVolumePlugin) runs). Off by default; on in [`HairSettings::styled`].
    pub volume: HairVolume,
    /// Holding each strand near its groomed shape carried with its head, strongest at the root (see
    /// [`HairStyleHold`]). Off by default; on in [`HairSettings::styled`].
    pub style_hold: HairStyleHold,
}

/// The style hold's rate of [`HairSettings::styled`], 1/s.
pub const STYLED_HOLD_RATE: f32 = 200.0;

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
            style_hold: HairStyleHold::default(),
        }
    }
}

impl HairSettings {
    /// The settings a game starts from for hair that looks styled, and the example scene is shown with:
    /// the defaults with the style held at 200/s ([`HairStyleHold`]: strongest at the roots, fading to the
    /// tips) and hair meeting hair on the grid ([`HairVolume`], its velocity smoothing). Shaken, 0.55 % of
    /// the example's guides stray from the hair instead of 38 % without them (`benchmark coverage`); the
    /// grid costs a sixth of a step. [`HairSettings::default`] is the reference behaviour, free rods and
    /// colliders only, which the mechanics are checked against.
    ///
    /// ```
    /// # use bevy::prelude::*;
    /// # use bevy_hair_sim::prelude::*;
    /// App::new().add_plugins((MinimalPlugins, HairPlugins::default())).insert_resource(HairSettings::styled());
    /// ```
    pub fn styled() -> Self {
        Self {
            volume: HairVolume { enabled: true, ..default() },
            style_hold: HairStyleHold { rate: STYLED_HOLD_RATE, ..default() },
            ..default()
        }
    }

    /// The mechanics core's parameters for a step of `dt` seconds, checked, and the collision margin, m;
    /// the default material is checked too.
    pub fn validated(&self, dt: f64) -> Result<(StepParams, f64), RodError> {
        let params = self.step_params(dt);
        params.validate()?;
        self.default_material.validate()?;
        self.volume.validate()?;
        self.style_hold.validate()?;
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
    /// Strands [`SteppedElsewhere`](crate::simulation::SteppedElsewhere) at the last step (on the GPU with
    /// `HairGpuPlugin`), not counted in the other figures.
    pub strands_elsewhere: usize,
    /// Heads at each level of detail at the last step ([`crate::detail`]).
    pub heads_by_detail: HeadsByDetail,
    /// Nodes of those strands.
    pub nodes: usize,
    /// Steps simulated since start.
    pub steps: u64,
    /// Steps skipped because a frame asked for more than [`HairSettings::max_steps_per_frame`].
    pub skipped_steps: u64,
    /// Failed strand steps since start (each reported with a [`crate::simulation::StrandFault`]).
    pub faults: u64,
    /// Strands in quarantine after the last step: they failed again soon after a failure, and are held in
    /// their rest pose on their head, not stepped, until they are retried (see [`crate::simulation::SimulatedStrand`]).
    pub quarantined: usize,
    /// Largest edge strain of any strand after the last step, dimensionless.
    pub max_strain: f64,
    /// Nodes touching a collider after the last step.
    pub contacts: usize,
    /// Mean Newton iterations per strand in the last step.
    pub mean_newton_iterations: f64,
    /// Wall-clock time the last step of all strands took, s.
    pub step_seconds: f64,
    /// Of that, the time spent packing strand poses for the GPU, summed over threads, s.
    ///
    /// Only strands that have a [`PackedStrandPose`] are packed. Every eighth pose a thread packs is
    /// timed (a clock read costs half a packing; its own cost, measured alongside, is taken off) and the
    /// rest counted at their mean.
    ///
    /// [`PackedStrandPose`]: crate::simulation::PackedStrandPose
    pub pose_seconds: f64,
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
    /// Wall-clock time of the hair's systems in the last fixed step that simulated hair, s: from growing
    /// grooms and building strands to the placed followers, what [`HairCpuBudget`](crate::detail::HairCpuBudget) keeps
    /// (measured by the `HairDetailPlugin`).
    pub update_seconds: f64,
    /// The step interval the [`HairCpuBudget`](crate::detail::HairCpuBudget) steps every head at at least,
    /// fixed steps: 1 when it coarsens nothing (or there is none), 0 before the first fixed step.
    pub budget_step_interval: u32,
}

/// Holding hair in its groomed style, in [`HairSettings::style_hold`]: each node of a rooted strand is
/// tied to where its groomed pose ([`crate::rod::Rod::initial_positions`], carried rigidly with the head)
/// puts it, strongest at the root and fading to nothing at [`HairStyleHold::reach`] along the strand.
/// What holds real hair in a style (the follicle's angle, hair resting on hair and the friction between
/// them, a styling product) is stylised as the shape constraint of game hair systems (TressFX's global
/// shape constraints): the combed layer stays on the scalp, the crown does not open, and the tips still
/// swing.
///
/// Each step, node `i` at arc length `s` from the root is drawn towards `x̄_i`, its groomed place at the
/// end of the step, by a critically damped zero-length spring inside the step's implicit solve
/// ([`crate::rod::Anchor`]): stiffness `m_i ω_i²` and damping `2 m_i ω_i` relative to the groomed place's
/// velocity, `ω_i = rate (1 − smoothstep(s/(reach·L)))` (`L` the strand's length). Its angular frequency
/// fades from `rate` at the root to nothing at the reach, fast enough that the tips still swing. Being in
/// the solve, the springs hold against the strand's own free tail and inertia in the same step, at any
/// rate without going unstable. A held node gives way to a steady force `F` by `F/(m_i ω_i²)`: under
/// gravity it rests `g/ω_i²` below its place, 0.25 mm at the root at 200/s, 2.7 mm at 60/s, with either
/// integrator. Strands stepped on the GPU (`HairGpuPlugin`) are held by the same springs in its solve.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct HairStyleHold {
    /// How fast a node at the root is drawn back to its groomed place, 1/s, from 0 (off) to 1 000: the
    /// angular frequency of its spring alone. Default 0.
    pub rate: f32,
    /// How far along each strand the hold reaches, as a fraction of its length, from 0 to 1: its angular
    /// frequency falls off as `1 − smoothstep(s/(reach·L))` (half at half the reach) and is 0 beyond.
    /// Default 1: the hold fades all along the strand and the tips swing. Held only near the root, a
    /// strand is dragged out of its style by its own free tail (held over half its length at 200/s, a
    /// shaken combed groom's nodes an eighth to three eighths of the way along stay 7.6 mm RMS from their
    /// places; over all of it, 0.8 mm: `tests/plugin/style_hold.rs`).
    pub reach: f32,
}

impl Default for HairStyleHold {
    fn default() -> Self {
        Self { rate: 0.0, reach: 1.0 }
    }
}

impl HairStyleHold {
    /// Checks both parameters' ranges.
    pub fn validate(&self) -> Result<(), RodError> {
        let checks: [(&'static str, f32, f32, f32, &'static str); 2] = [
            ("style_hold.rate", self.rate, 0.0, 1e3, "must be from 0 to 1 000 1/s"),
            ("style_hold.reach", self.reach, 0.0, 1.0, "must be from 0 to 1"),
        ];
        for (parameter, value, low, high, requirement) in checks {
            if !(low..=high).contains(&value) {
                return Err(RodError::InvalidStepParameter { parameter, value: f64::from(value), requirement });
            }
        }
        Ok(())
    }

    /// The angular frequency of the hold's spring at `along` (0 at the root, 1 at the tip) of the strand's
    /// length, 1/s: `rate (1 − smoothstep(along/reach))`.
    pub fn angular_frequency(&self, along: f64) -> f64 {
        let reach = f64::from(self.reach);
        if reach <= 0.0 || along >= reach {
            return 0.0;
        }
        let x = along / reach;
        // 1 − smoothstep: full over the first part of the reach, no kink where it ends.
        f64::from(self.rate) * (1.0 - x * x * (3.0 - 2.0 * x))
    }
}

/// The hair–hair interaction's parameters, in [`HairSettings::volume`].
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct HairVolume {
    /// Whether hair interacts with hair. Default false: the grid costs a sixth to a fifth of a step (6 to 7
    /// ms for 2 000 strands × 32 edges on two cores), and what it buys by default, the velocity
    /// smoothing, shows in motion more than at rest.
    pub enabled: bool,
    /// Spacing of the grid's points, m, from 2 mm to 20 cm: smaller resolves thinner layers of hair and
    /// costs more (the grid spans each head's hair). Default 0.005, which resolves a layer of hair for
    /// the pressure; 0.01 costs a third less and is enough for the smoothing alone.
    pub cell_size: f32,
    /// Velocity smoothing rate, 1/s: where hair is packed at its target fraction, a node's velocity
    /// relative to the hair around it decays as `e^{−rate·t}` (less where the hair is sparser; a lone
    /// strand is not smoothed). 0 turns the smoothing off. Default 5.
    pub velocity_smoothing: f32,
    /// The fraction of space that hair at rest fills, in (0, 1]: denser hair pushes back. Loose human
    /// hair fills about a tenth of its volume; lower gives more volume. Default 0.1.
    pub target_volume_fraction: f32,
    /// Pressure of hair packed at twice its target fraction, Pa (the pressure grows linearly from zero
    /// at the target). 0 turns the pressure off. Default 0. With [`HairVolume::keep_groomed_volume`] off,
    /// 50 with 5 mm cells gives a head of 100 000 hairs a layer of 6 mm instead of 1. It is
    /// an explicit force (the grid is built before the step): the stiffer it is, the smaller the cells
    /// and the longer the step, the likelier it jitters; the tests run 50 Pa on 5 mm cells at 60 Hz.
    pub stiffness: f32,
    /// Whether hair packed as densely as it was groomed is at rest: the pressure pushes only where hair
    /// is packed beyond both the target and its groom's own packing (measured where each node lay when
    /// its strand was made). Default true: the grooms lay their hair in thin layers, packed far beyond
    /// any target, and measured against the target alone the pressure rearranges a combed style to give
    /// it volume (see [`crate::volume`]). Off, a groom laid flat swells to the target fraction.
    pub keep_groomed_volume: bool,
}

impl Default for HairVolume {
    fn default() -> Self {
        Self {
            enabled: false,
            cell_size: 0.005,
            velocity_smoothing: 5.0,
            target_volume_fraction: 0.1,
            stiffness: 0.0,
            keep_groomed_volume: true,
        }
    }
}

impl HairVolume {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), RodError> {
        let checks: [(&'static str, f32, f32, f32, &'static str); 4] = [
            ("volume.cell_size", self.cell_size, 0.002, 0.2, "must be from 0.002 to 0.2 m"),
            ("volume.velocity_smoothing", self.velocity_smoothing, 0.0, 1e4, "must be from 0 to 10 000 1/s"),
            ("volume.target_volume_fraction", self.target_volume_fraction, 1e-3, 1.0, "must be from 0.001 to 1"),
            ("volume.stiffness", self.stiffness, 0.0, 1e5, "must be from 0 to 100 000 Pa"),
        ];
        for (parameter, value, low, high, requirement) in checks {
            if !(low..=high).contains(&value) {
                return Err(RodError::InvalidStepParameter { parameter, value: f64::from(value), requirement });
            }
        }
        Ok(())
    }
}
