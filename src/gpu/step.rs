//! The GPU strand step on a plain `wgpu` device: the buffers, the pipeline of `step.wgsl`, uploads,
//! dispatches and read-back. Bevy's renderer hands its own device to it
//! ([`HairGpuPlugin`](crate::render::HairGpuPlugin)); tests and benchmarks make one with [`headless_device`].

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

use bevy::math::{DQuat, DVec2, DVec3};
use wgpu::util::DeviceExt;

use super::gather::{GATHER_WORKGROUP, Gather, GpuGatherTarget};
use super::grid::{GpuGrid, GpuGridFields, GpuVolume, GridPipelines, GridStep};
use super::pipelines::{bind_whole_buffers, compute_layout, pipeline_of_module};

use crate::rod::{
    AirSnapshot, ColliderShape, DistanceField, MovingCollider, Rod, RodError, RodFrames, RodSnapshot, RodState,
    StepHistory, StepParams,
};

/// Most workgroups along one dimension of a dispatch (WebGPU's limit).
const MAX_GROUPS: u32 = 65_535;
/// Lanes of the step's pipelines (`LANES` in `step.wgsl`): one workgroup steps a strand, lane `i` owning
/// edge `i`; strands of up to 32 edges (a game's guides) go to workgroups of 32 lanes, one warp, those of
/// up to 64 to workgroups of 64, longer ones to workgroups of 128 where the device has the workgroup
/// memory for them ([`gpu_max_nodes`]).
const STEP_LANES: [usize; 3] = [32, 64, 128];
/// The most nodes a strand stepped on the GPU may have on every device that can run the step: 64 edges,
/// one per lane of the 64-lane pipeline, the band of up to 259 unknowns in 15.5 kB of workgroup memory
/// (WebGPU guarantees 16 kB).
pub const MAX_GPU_NODES: usize = 65;
/// The most nodes a strand stepped on the GPU may have on a device with 30.7 kB of workgroup memory and
/// 128 invocations a workgroup (desktop and console GPUs have 32 kB or more): 128 edges, one per lane of
/// the 128-lane pipeline ([`gpu_max_nodes`]).
pub const MAX_WIDE_GPU_NODES: usize = 129;
/// The top bit of a strand's head word (`FREE_STRAND` in `step.wgsl`): the strand is free (its root not
/// held on its head; the head a frame it is stepped in).
const FREE_STRAND: u32 = 0x8000_0000;
/// Rows of `vec4` per node in the rest buffer, the state buffer; per head; per collider.
const REST_ROWS: usize = 5;
const STATE_ROWS: usize = 7;
const HEAD_ROWS: usize = 6;
const COLLIDER_ROWS: usize = 8;
const STRAND_FLOATS: usize = 4;
/// Rows of the air before the heads' in the heads buffer, in still air ([`GpuStrandSolver::set_air`]).
const STILL_AIR_ROWS: usize = 2;
/// The arc-length fraction written for the nodes of a strand that is not held: past any reach (at most 1).
const HELD_NOWHERE: f64 = 2.0;
/// `Params` of the shader: twenty-four words.
const PARAMS_BYTES: u64 = 96;
/// Rows of `vec4<u32>` per strand in the work counters (`work` in the shader).
const WORK_ROWS: usize = 2;
/// The state's rows a read-back copies: position and θ, velocity and θ̇, reference director and twist (the
/// history, rows 2 and 3, stays on the GPU).
const READ_BACK_ROWS: [usize; 3] = [0, 1, 4];

/// Stiffness of an edge's first-order change of length in the GPU's solve, relative to the inertia of its
/// nodes `m (1/h² + γ/h)`, dimensionless. Large enough that the linear step keeps lengths to first order
/// (an edge stretches by 1/1000 of what the forces alone would stretch it, before the projection), small
/// enough that the system's condition number stays near 10³ and single precision solves it to 10⁻⁴.
pub const STRETCH_RATIO: f64 = 1e3;

/// How near to folded back two consecutive edges of a strand may be for the GPU to take it, rad short of
/// π (a turn sharper than 166°). The bending's gradients grow as `1/(1 + t⁻·t)`: at this turn they are
/// 60 times those of a straight strand and the Newton matrix 4 000 times, which single precision still
/// factorises; a strand folded flat (a tip pushed onto a shoulder, say, folds within 10⁻⁴ rad) makes the
/// factorisation fail at every step. Such strands stay on the CPU ([`crate::rod::Rod::sharpest_turn`]).
pub const GPU_FOLD_GAP: f64 = 0.25;

/// The strain single precision can resolve on a strand within a metre of its head: a position's rounding
/// (6e-8 m) over the shortest edge of 1 mm, doubled. Added to [`StepParams::strain_bound`] for the GPU's
/// check.
pub const SINGLE_PRECISION_STRAIN: f64 = 1.2e-4;

/// Newton iterations of each GPU step: the CPU's adaptive count usually stops at one on calm steps and
/// takes two to four on violent ones; the GPU takes a fixed number. (The CPU's test per strand, tried,
/// stopped 7 % of the shaken head's strands after one iteration and left a released hair's swing 2.4 mm
/// from the converged one where two iterations leave 1.6: `docs/performance.md`.)
pub const GPU_NEWTON_ITERATIONS: u32 = 2;

/// The most rounds of "push out of the colliders, project the lengths" after the solve (friction in the
/// first); they end once no node moves by more than four times its position's rounding.
pub const GPU_CONTACT_ROUNDS: u32 = 4;

/// Why a strand cannot be stepped on the GPU, or no GPU step can be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpuStepError {
    /// No adapter or device (no GPU, no software Vulkan).
    #[error("no GPU adapter or device: {0}")]
    NoDevice(String),
    /// The device cannot run the step (WebGL2, say): what it lacks ([`gpu_step_support`]).
    #[error("the GPU cannot run the strand step: it lacks {0}")]
    Unsupported(String),
    /// A strand with more nodes than the device's widest workgroup has lanes ([`gpu_max_nodes`]: at
    /// least [`MAX_GPU_NODES`], at most [`MAX_WIDE_GPU_NODES`]), or fewer than three.
    #[error("strand {strand} has {nodes} nodes; the GPU step takes 3 to {most} on this device")]
    NodeCount {
        /// The strand's index in the input.
        strand: usize,
        /// Its node count.
        nodes: usize,
        /// The most the device takes.
        most: usize,
    },
    /// A strand held otherwise than by its whole root edge: the GPU steps strands whose root edge is clamped
    /// (both its nodes and its twist) and free strands (nothing held), no others.
    #[error(
        "strand {strand} is held otherwise than by its whole root edge: the GPU steps strands with the root edge clamped, or free"
    )]
    Unrooted {
        /// The strand's index in the input.
        strand: usize,
    },
    /// A strand whose groomed places ([`GpuStrandInput::groomed`]) are not one finite point per node.
    #[error("strand {strand}'s groomed places for the style hold are not one finite point per node")]
    Groomed {
        /// The strand's index in the input.
        strand: usize,
    },
    /// A strand on a head that was not given.
    #[error("strand {strand} is on head {head}, but only {heads} heads were given")]
    NoSuchHead {
        /// The strand's index in the input.
        strand: usize,
        /// The head it names.
        head: usize,
        /// How many heads were given.
        heads: usize,
    },
    /// The colliders of a step, with their mesh colliders' distance fields, are larger than one storage
    /// buffer of the device may be (`max_storage_buffer_binding_size`; WebGPU guarantees 128 MiB).
    #[error("the colliders and their mesh fields take {bytes} bytes, more than the device's {limit} a buffer")]
    CollidersTooLarge {
        /// Bytes the colliders and their fields need.
        bytes: u64,
        /// The device's limit, bytes.
        limit: u64,
    },
    /// The air given to [`GpuStrandSolver::set_air`] has a value that is not finite.
    #[error("the air's wind, turbulence or jets are not finite")]
    InvalidAir,
    /// A head's pose, air or collider is not finite, its rotation not a unit quaternion, or its style hold's
    /// rate negative or not finite or its reach outside 0 to 1.
    #[error(
        "head {head}'s pose, air velocity or colliders are not finite (or its rotation is not unit), or its style hold or cadence is out of range"
    )]
    InvalidHead {
        /// The head's index.
        head: usize,
    },
    /// A strand whose hairs on the grid ([`GpuStrandInput::hairs`]) are negative or not finite, or whose
    /// groomed fractions are not one finite, non-negative value per node.
    #[error("strand {strand}'s hairs on the grid or groomed fractions are not finite and non-negative (one per node)")]
    GridInput {
        /// The strand's index in the input.
        strand: usize,
    },
    /// Forces given to [`GpuStrandSolver::add_forces`] (or air velocities to
    /// [`GpuStrandSolver::add_air_velocities`]) for a strand that is not uploaded, not one per node, or not
    /// finite.
    #[error(
        "the forces (or air velocities) for strand {strand} are not one finite vector per node of an uploaded strand"
    )]
    InvalidForces {
        /// The strand's index.
        strand: usize,
    },
    /// The hair–hair grid's parameters given to [`GpuStrandSolver::set_volume`] are out of range
    /// ([`GpuVolume::is_valid`]).
    #[error("the hair–hair grid's parameters are out of range")]
    InvalidVolume,
    /// The step's parameters are not valid.
    #[error(transparent)]
    InvalidParameters(#[from] RodError),
}

/// One strand given to [`GpuStrandSolver::new`]: its rod (state, rest shape, material, its root edge
/// clamped where the head holds it) and its head.
#[derive(Debug, Clone, Copy)]
pub struct GpuStrandInput<'a> {
    /// The strand, with its root edge clamped ([`Rod::clamp_edge`]) at the head's pose of
    /// [`GpuStrandSolver::new`], or free (nothing held: every node moves, the head a frame it is stepped
    /// in, whose colliders and air it meets; it needs one lane more than a held strand of its nodes,
    /// [`max_free_gpu_nodes`]).
    pub rod: &'a Rod,
    /// Index of its head in the poses given to [`GpuStrandSolver::new`] and [`GpuStrandSolver::step`].
    pub head: usize,
    /// Distance from the centre line kept outside colliders, m (the strand's radius plus a margin).
    pub thickness: f64,
    /// Where the style hold draws each node, in its head's local space (one per node, m), or `None` for a
    /// strand that is not held: a critically damped spring `−m k (x − x̄) − m c (v − v̄)` inside the solve,
    /// `x̄` the place carried with the head, as [`crate::rod::Anchor`] on the CPU, with `√k = c/2` from the
    /// head's [`GpuHeadStep::hold_rate`] and [`GpuHeadStep::hold_reach`].
    pub groomed: Option<&'a [DVec3]>,
    /// How many real hairs the strand stands for on the hair–hair grid ([`GpuStrandSolver::set_volume`]):
    /// its keratin volume and mass there are multiplied by it (as `RepresentedHairs` on the CPU; 0 leaves it
    /// out of the grid, though it still feels the others). Finite, not negative.
    pub hairs: f64,
    /// The hair volume fraction where each node lay in its groom (one per node), against which the grid's
    /// pressure measures packing where it is larger ([`GpuVolume::keep_groomed`]); `None`: 0 (not known).
    pub groomed_fractions: Option<&'a [f64]>,
}

/// A head's motion over one step: its pose at the step's end, its colliders (poses at the step's start
/// and end, in world space), and the air's velocity around its hair.
#[derive(Debug, Clone, Default)]
pub struct GpuHeadStep {
    /// The head's orientation at the end of the step.
    pub rotation: DQuat,
    /// The head's position at the end of the step, m.
    pub translation: DVec3,
    /// The colliders its hair meets.
    pub colliders: Vec<MovingCollider>,
    /// The air's velocity around the head, m/s (the drag acts on the hair's velocity relative to it),
    /// besides the air of [`GpuStrandSolver::set_air`].
    pub air_velocity: DVec3,
    /// Whether its hair is stepped in this fixed step, and how long a step it takes, or carried.
    pub cadence: GpuHairCadence,
    /// How fast the style hold draws its strands' nodes back to their groomed places
    /// ([`GpuStrandInput::groomed`]) at the root, 1/s: the angular frequency `ω` of a node's spring
    /// alone (`k = ω²`, critically damped `c = 2ω`). 0 (the default) holds nothing. Finite, not negative.
    pub hold_rate: f64,
    /// How far along each strand the hold reaches, as a fraction of its length, 0 to 1: the frequency
    /// falls off as `hold_rate (1 − smoothstep(s/(reach·L)))` and is 0 beyond, as
    /// `HairStyleHold::angular_frequency` on the CPU.
    pub hold_reach: f64,
    /// Whether its hair meets other hair on a grid of the caller's rather than on the GPU's
    /// ([`GpuStrandSolver::set_volume`]): the head is left off the GPU's grid (the plugin's heads with
    /// strands on the CPU too meet on the CPU's grid, its response sent as forces). Default `false`.
    pub meets_hair_elsewhere: bool,
}

/// What a head's hair does in a fixed step on the GPU ([`GpuHeadStep::cadence`]): its level of detail.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GpuHairCadence {
    /// Stepped, with a step as long as this many fixed steps, 1 to [`MAX_GPU_SPAN`] (1, the default:
    /// every fixed step; `n`: every `n`-th, as `HairDetailLevel::Stepped(n)` on the CPU, with backward
    /// Euler where the last step was not as long).
    Step(u32),
    /// Carried rigidly with the head from its pose at the last fixed step, not simulated, its velocity the
    /// head's rigid motion: hair out of sight, which comes back with its head's motion.
    Carried,
    /// Carried rigidly with the head like [`GpuHairCadence::Carried`], waiting for its next step at a
    /// coarser level: its velocity turns with the head and is kept, so that the next step (as long as the
    /// fixed steps since the last) goes on with the hair's own motion.
    Waiting,
}

impl Default for GpuHairCadence {
    fn default() -> Self {
        Self::Step(1)
    }
}

/// The most fixed steps one GPU step may span ([`GpuHairCadence::Step`]).
pub const MAX_GPU_SPAN: u32 = 255;

/// What a strand's last GPU step reported.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GpuStrandStatus {
    /// The largest edge strain after the step, dimensionless (after a step failed for over-strain, the
    /// strain that failed it).
    pub max_strain: f32,
    /// Why the last step failed (the strand was put back in its rest pose on its root, at rest), if it did.
    pub fault: Option<GpuFault>,
    /// Why the most recent failed step since the upload failed, if any did (read back every few steps,
    /// this still says why).
    pub last_fault: Option<GpuFault>,
    /// Steps that failed since the upload.
    pub faults: u32,
    /// Nodes touching a collider after the last step: held by a contact spring in the solve or moved by
    /// the contact after it.
    pub contacts: u32,
    /// Whether the last step could not put the strand outside its colliders with its lengths kept (it
    /// lies deep inside one that holds its root, say), and kept its state without contact instead.
    pub contact_given_up: bool,
}

/// The work a strand's GPU steps took since the upload ([`GpuStrandSolver::read_work`]): what sets the
/// step's cost on a GPU, where a dispatch runs until its slowest strand is done. Counted by the shader,
/// in wrapping `u32`s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GpuStrandWork {
    /// Steps taken.
    pub steps: u32,
    /// Newton iterations (each one assembly, factorisation and solve).
    pub newton_iterations: u32,
    /// Projection iterations onto the rest lengths (each one tridiagonal solve).
    pub projection_iterations: u32,
    /// Gauss–Seidel sweeps of the projection, where its iteration did not reduce the error.
    pub projection_sweeps: u32,
    /// Projection iterations that did not reduce the error, sweep included: spent where single
    /// precision's rounding, not the lengths, set it.
    pub projection_stalls: u32,
    /// Calls of the projection (after each Newton iteration and each contact round).
    pub projections: u32,
    /// Contact rounds (push-out, then the lengths again).
    pub contact_rounds: u32,
    /// Factorisations redone with a regularised diagonal after a non-positive pivot.
    pub factorisation_retries: u32,
}

impl GpuStrandWork {
    /// The first `strands` strands' counters from the work buffer's rows ([`WORK_ROWS`] a strand).
    fn unpack(rows: &[[u32; 4]], strands: usize) -> Vec<GpuStrandWork> {
        (0..strands)
            .map(|s| {
                let [steps, newton_iterations, projection_iterations, projection_sweeps] = rows[WORK_ROWS * s];
                let [contact_rounds, factorisation_retries, projection_stalls, projections] = rows[WORK_ROWS * s + 1];
                GpuStrandWork {
                    steps,
                    newton_iterations,
                    projection_iterations,
                    projection_sweeps,
                    projection_stalls,
                    projections,
                    contact_rounds,
                    factorisation_retries,
                }
            })
            .collect()
    }

    /// The work done between `earlier` (the same strands' counters read before) and `self`, the counters'
    /// wrapping undone.
    pub fn since(&self, earlier: &GpuStrandWork) -> GpuStrandWork {
        GpuStrandWork {
            steps: self.steps.wrapping_sub(earlier.steps),
            newton_iterations: self.newton_iterations.wrapping_sub(earlier.newton_iterations),
            projection_iterations: self.projection_iterations.wrapping_sub(earlier.projection_iterations),
            projection_sweeps: self.projection_sweeps.wrapping_sub(earlier.projection_sweeps),
            projection_stalls: self.projection_stalls.wrapping_sub(earlier.projection_stalls),
            projections: self.projections.wrapping_sub(earlier.projections),
            contact_rounds: self.contact_rounds.wrapping_sub(earlier.contact_rounds),
            factorisation_retries: self.factorisation_retries.wrapping_sub(earlier.factorisation_retries),
        }
    }

    /// The work of every strand summed.
    pub fn total(work: &[GpuStrandWork]) -> GpuStrandWork {
        work.iter().fold(GpuStrandWork::default(), |sum, w| GpuStrandWork {
            steps: sum.steps.wrapping_add(w.steps),
            newton_iterations: sum.newton_iterations.wrapping_add(w.newton_iterations),
            projection_iterations: sum.projection_iterations.wrapping_add(w.projection_iterations),
            projection_sweeps: sum.projection_sweeps.wrapping_add(w.projection_sweeps),
            projection_stalls: sum.projection_stalls.wrapping_add(w.projection_stalls),
            projections: sum.projections.wrapping_add(w.projections),
            contact_rounds: sum.contact_rounds.wrapping_add(w.contact_rounds),
            factorisation_retries: sum.factorisation_retries.wrapping_add(w.factorisation_retries),
        })
    }

    /// Each count per step taken (0 with no step).
    pub fn per_step(&self) -> [f64; 7] {
        let steps = f64::from(self.steps.max(1));
        [
            self.newton_iterations,
            self.projection_iterations,
            self.projection_sweeps,
            self.projection_stalls,
            self.projections,
            self.contact_rounds,
            self.factorisation_retries,
        ]
        .map(|count| f64::from(count) / steps)
    }
}

/// Why a GPU step failed for a strand.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GpuFault {
    /// A position or twist was not finite at `node`.
    NonFinite {
        /// The first node found.
        node: u32,
    },
    /// Edge `edge` was strained past the bound.
    OverStrained {
        /// The most strained edge.
        edge: u32,
    },
    /// The Newton system did not factorise even regularised.
    NotPositiveDefinite,
}

/// The strands' state read back from the GPU, in world space.
#[derive(Debug, Clone, Default)]
pub struct GpuStrandStates {
    /// Per strand, its node positions, m.
    pub positions: Vec<Vec<DVec3>>,
    /// Per strand, its node velocities, m/s.
    pub velocities: Vec<Vec<DVec3>>,
    /// Per strand, its edges' twist angles θ, rad.
    pub twists: Vec<Vec<f64>>,
    /// Per strand, its edges' twist rates dθ/dt, rad/s.
    pub twist_rates: Vec<Vec<f64>>,
    /// Per strand, its edges' reference directors (unit, across the edge).
    pub reference_directors: Vec<Vec<DVec3>>,
    /// Per strand, the reference twist at each vertex, rad.
    pub reference_twists: Vec<Vec<f64>>,
    /// Per strand, its last step's report.
    pub status: Vec<GpuStrandStatus>,
    /// The largest hair volume fraction at a point of any head's hair–hair grid in the last step that
    /// built one ([`GpuStrandSolver::set_volume`]; 0 without a grid).
    pub max_volume_fraction: f32,
    /// Every strand's work since the upload, summed ([`GpuStrandWork::total`]; wrapping, so compare two
    /// read-backs with [`GpuStrandWork::since`]).
    pub work: GpuStrandWork,
    /// The GPU's time in the last step, from timestamp queries; `None` where the device has none
    /// (`wgpu::Features::TIMESTAMP_QUERY`).
    pub timings: Option<GpuStepTimings>,
}

/// The GPU's time in one step, measured by timestamp queries on the GPU itself.
#[derive(Debug, Clone, Copy, PartialEq, Default, bevy::reflect::Reflect)]
pub struct GpuStepTimings {
    /// The hair–hair grid's passes (0 without the grid), s.
    pub grid_seconds: f64,
    /// The strands' step, s.
    pub step_seconds: f64,
}

impl GpuStrandStates {
    /// Strand `strand` as a rod's snapshot ([`Rod::restore`] takes it): positions, velocities, twists
    /// and frames from the GPU, no two-step history (the CPU's next step, if any, starts with backward
    /// Euler) and no contact forces. `None` past the last strand, or where only the status was read back.
    pub fn snapshot(&self, strand: usize) -> Option<RodSnapshot> {
        self.clone_strand(strand)?.take_snapshot(0)
    }

    /// [`GpuStrandStates::snapshot`], moving the strand's vectors out instead of copying them (they are
    /// left empty, and a second call returns `None`).
    pub fn take_snapshot(&mut self, strand: usize) -> Option<RodSnapshot> {
        let positions = std::mem::take(self.positions.get_mut(strand)?);
        if positions.is_empty() {
            return None;
        }
        let tangents = positions.windows(2).map(|ends| (ends[1] - ends[0]).normalize_or_zero()).collect();
        let nodes = positions.len();
        let take = |values: &mut Vec<Vec<f64>>| std::mem::take(&mut values[strand]);
        let (twist, twist_rates, reference_twist) =
            (take(&mut self.twists), take(&mut self.twist_rates), take(&mut self.reference_twists));
        Some(RodSnapshot {
            state: RodState {
                positions,
                velocities: std::mem::take(&mut self.velocities[strand]),
                twist,
                twist_rates,
                contact_normal_forces: vec![0.0; nodes],
                history: StepHistory {
                    dt: 0.0,
                    positions: vec![DVec3::ZERO; nodes],
                    velocities: vec![DVec3::ZERO; nodes],
                },
            },
            frames: RodFrames {
                tangents,
                reference_directors: std::mem::take(&mut self.reference_directors[strand]),
                reference_twist,
            },
        })
    }

    /// Strand `strand` alone, its state copied (`None` past the last strand or without its state).
    fn clone_strand(&self, strand: usize) -> Option<GpuStrandStates> {
        Some(GpuStrandStates {
            positions: vec![self.positions.get(strand)?.clone()],
            velocities: vec![self.velocities[strand].clone()],
            twists: vec![self.twists[strand].clone()],
            twist_rates: vec![self.twist_rates[strand].clone()],
            reference_directors: vec![self.reference_directors[strand].clone()],
            reference_twists: vec![self.reference_twists[strand].clone()],
            status: self.status.get(strand).copied().into_iter().collect(),
            max_volume_fraction: self.max_volume_fraction,
            work: self.work,
            timings: self.timings,
        })
    }
}

/// Whether a device with `limits` on an adapter with `downlevel` capabilities can run the step: compute
/// shaders, 8 storage buffers a stage, 16 kB of workgroup memory (the 64-lane pipeline's band takes
/// 15.5 kB) and workgroups of 64 invocations, as WebGPU guarantees and WebGL2 does not. The error names
/// what is missing ([`GpuStepError::Unsupported`]).
pub fn gpu_step_support(limits: &wgpu::Limits, downlevel: &wgpu::DownlevelCapabilities) -> Result<(), GpuStepError> {
    let mut missing = Vec::new();
    if !downlevel.flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS) {
        missing.push("compute shaders".to_string());
    }
    let needs = [
        ("storage buffers a shader stage", limits.max_storage_buffers_per_shader_stage, 8),
        ("bytes of workgroup memory", limits.max_compute_workgroup_storage_size, 16_384),
        ("invocations a workgroup", limits.max_compute_invocations_per_workgroup, STEP_LANES[1] as u32),
        ("invocations along X", limits.max_compute_workgroup_size_x, STEP_LANES[1] as u32),
        ("workgroups a dimension", limits.max_compute_workgroups_per_dimension, MAX_GROUPS),
    ];
    for (what, has, needed) in needs {
        if has < needed {
            missing.push(format!("{needed} {what} (it has {has})"));
        }
    }
    if missing.is_empty() { Ok(()) } else { Err(GpuStepError::Unsupported(missing.join(", "))) }
}

/// A device and queue of their own, headless, on whatever adapter wgpu finds (a discrete GPU, or Mesa's
/// software Vulkan, lavapipe, on a machine without one), for tests and benchmarks.
pub fn headless_device() -> Result<(wgpu::Device, wgpu::Queue, wgpu::AdapterInfo), GpuStepError> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = bevy::tasks::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))
    .map_err(|error| GpuStepError::NoDevice(error.to_string()))?;
    let info = adapter.get_info();
    let mut limits = wgpu::Limits::default();
    limits.max_storage_buffers_per_shader_stage = limits.max_storage_buffers_per_shader_stage.max(8);
    // The adapter's workgroup memory, for the 128-lane pipeline where it has room (as Bevy asks for the
    // adapter's limits).
    limits.max_compute_workgroup_storage_size =
        limits.max_compute_workgroup_storage_size.max(adapter.limits().max_compute_workgroup_storage_size);
    let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
    let (device, queue) = bevy::tasks::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("hair strand step"),
        required_features: features,
        required_limits: limits,
        ..Default::default()
    }))
    .map_err(|error| GpuStepError::NoDevice(error.to_string()))?;
    Ok((device, queue, info))
}

/// The shader's source.
pub const STEP_SHADER: &str = include_str!("step.wgsl");

/// Strands stepped on the GPU: their buffers (row planes of node-contiguous strands, positions relative to
/// their heads), the step's pipelines, and the heads' poses the strands were last stepped to.
pub struct GpuStrandSolver {
    pipelines: Arc<GpuStepPipelines>,
    /// Per pipeline of [`STEP_LANES`] the device has: its bind group, and its parameters (which list it
    /// steps).
    bind_groups: Vec<wgpu::BindGroup>,
    params: Vec<wgpu::Buffer>,
    state: wgpu::Buffer,
    status: wgpu::Buffer,
    heads: wgpu::Buffer,
    colliders: wgpu::Buffer,
    work: wgpu::Buffer,
    strand_words: wgpu::Buffer,
    strand_floats: wgpu::Buffer,
    rest: wgpu::Buffer,
    strand_count: usize,
    /// Nodes of each strand, and the head of each.
    strands: Arc<StrandLayout>,
    /// Each head's pose after the last step: rotation and translation (the origin of its strands' positions).
    head_poses: Vec<(DQuat, DVec3)>,
    /// The step length the last dispatch used, s (a change restarts BDF2).
    last_dt: f64,
    /// Scratch for the per-step uploads.
    head_rows: Vec<[f32; 4]>,
    /// The air every head's hair moves in ([`GpuStrandSolver::set_air`]), as rows of the heads buffer
    /// before the heads' own: (uniform wind, modes as bits), (jets as bits, 0, 0, 0), two rows a mode
    /// ((k, φ), (a, 0)), three a jet ((origin, speed), (axis, range), (radius, 0, 0, 0)).
    air_rows: Vec<[f32; 4]>,
    /// Rows of `vec4` the heads buffer has room for, the air's included.
    head_buffer_rows: usize,
    collider_rows: Vec<[f32; 4]>,
    /// Colliders the buffer holds rows for; the mesh fields' samples follow them.
    collider_capacity: usize,
    /// Rows of `vec4` the collider buffer has room for, fields included.
    collider_buffer_rows: usize,
    /// The mesh colliders' distance fields whose samples the collider buffer holds, in order, and the row
    /// where each starts (kept alive, so that a field's address names it while it is there).
    fields: Vec<(Arc<DistanceField>, usize)>,
    /// Scratch: the fields of this step's colliders.
    step_fields: Vec<(Arc<DistanceField>, usize)>,
    /// Read-back buffers the CPU has finished with, for the next read-backs.
    staging: Arc<Mutex<Vec<wgpu::Buffer>>>,
    /// Time spent in wgpu's submissions and polls since [`GpuStrandSolver::take_driver_seconds`], s.
    driver_seconds: f64,
    /// The hair–hair grid's parameters ([`GpuStrandSolver::set_volume`]) and its buffers once made.
    volume: Option<GpuVolume>,
    grid: Option<GpuGrid>,
    /// Scratch for [`GpuStrandSolver::add_forces`].
    force_rows: Vec<[f32; 4]>,
    /// Scratch: each head's translation before the step and its step's length, for the grid.
    grid_heads: Vec<(DVec3, f64)>,
    /// Where the device has timestamp queries: the step's three timestamps (before the grid, before the
    /// strands' step, after it) and the buffer they are resolved into after every step.
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer)>,
}

/// Timestamps a step writes ([`GpuStrandSolver`]'s `timestamps`): before the grid's passes, before the
/// strands' step, after it.
const STEP_TIMESTAMPS: u32 = 3;

/// The step's and the gather's pipelines on one device, built once ([`GpuStepPipelines::new`] compiles the
/// step's shader, a few hundred milliseconds on a driver: a hitch if it happened in play) and shared by every
/// [`GpuStrandSolver`] made on that device ([`GpuStrandSolver::from_upload`]); the plugin builds them at
/// its first upload and never again.
pub struct GpuStepPipelines {
    layout: wgpu::BindGroupLayout,
    /// The step with 32 lanes a workgroup, with 64, and with 128 where the device can ([`STEP_LANES`],
    /// [`gpu_max_nodes`]).
    steps: Vec<wgpu::ComputePipeline>,
    gather: Gather,
    grid: GridPipelines,
}

impl GpuStepPipelines {
    /// Compiles the step's and the gather's shaders on `device`.
    pub fn new(device: &wgpu::Device) -> Arc<Self> {
        // Bindings: parameters; strand words, floats, rest shape (read); state (written); heads, colliders
        // (read); status, work counters (written).
        let read_only = [true, true, true, false, true, true, false, false];
        let layout = compute_layout(device, "hair strand step", Some(PARAMS_BYTES), &read_only);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("hair strand step"),
            source: wgpu::ShaderSource::Wgsl(STEP_SHADER.into()),
        });
        let limits = device.limits();
        let steps = STEP_LANES
            .iter()
            .filter(|&&lanes| lanes_fit(&limits, lanes))
            .map(|&lanes| {
                let constants = [("LANES", lanes as f64)];
                // The step writes every workgroup value before it reads it.
                let options =
                    wgpu::PipelineCompilationOptions { constants: &constants, zero_initialize_workgroup_memory: false };
                pipeline_of_module(device, "hair strand step", &module, "step", &layout, &options)
            })
            .collect();
        Arc::new(Self { layout, steps, gather: Gather::new(device), grid: GridPipelines::new(device) })
    }

    /// The most nodes a strand stepped with these pipelines may have ([`gpu_max_nodes`] of their device).
    pub fn max_nodes(&self) -> usize {
        STEP_LANES[self.steps.len().max(1) - 1] + 1
    }
}

/// The workgroup memory the step's pipeline of `lanes` lanes uses, bytes: the band and right-hand side of
/// up to `4 lanes + 3` unknowns, 11 floats wide, and four arrays over the nodes (`step.wgsl`).
const fn step_workgroup_bytes(lanes: usize) -> usize {
    let unknowns = 4 * lanes + 3;
    4 * (unknowns * 11 + unknowns) + (lanes + 1) * (16 + 4 + 16 + 16) + 8
}

/// Whether a device with `limits` can run the step's pipeline of `lanes` lanes.
fn lanes_fit(limits: &wgpu::Limits, lanes: usize) -> bool {
    step_workgroup_bytes(lanes) <= limits.max_compute_workgroup_storage_size as usize
        && lanes <= limits.max_compute_invocations_per_workgroup as usize
        && lanes <= limits.max_compute_workgroup_size_x as usize
}

/// The most nodes a strand stepped on the GPU may have on a device with `limits` (that can run the step,
/// [`gpu_step_support`]): [`MAX_WIDE_GPU_NODES`] where the device has the workgroup memory and invocations
/// for workgroups of 128 lanes (30.7 kB, as desktop GPUs have), [`MAX_GPU_NODES`] otherwise.
pub fn gpu_max_nodes(limits: &wgpu::Limits) -> usize {
    STEP_LANES.iter().filter(|&&lanes| lanes_fit(limits, lanes)).max().map_or(MAX_GPU_NODES, |&lanes| lanes + 1)
}

/// The most nodes a free strand (no root held) may have where a held one may have `max_nodes`
/// ([`gpu_max_nodes`]): one fewer, since its first node needs a lane of its own.
pub fn max_free_gpu_nodes(max_nodes: usize) -> usize {
    max_nodes - 1
}

/// Whether `rod` is held by its whole root edge (`Some(true)`: nodes 0 and 1 and the first twist clamped,
/// nothing else), free (`Some(false)`: nothing held), or otherwise (`None`: the GPU cannot step it).
pub(crate) fn root_held(rod: &Rod) -> Option<bool> {
    let constraints = rod.constraints();
    let (nodes, twists) = (&constraints.node_targets, &constraints.twist_targets);
    let others_free = nodes.iter().skip(2).all(Option::is_none) && twists.iter().skip(1).all(Option::is_none);
    match (nodes[0].is_some(), nodes[1].is_some(), twists[0].is_some()) {
        (true, true, true) if others_free => Some(true),
        (false, false, false) if others_free => Some(false),
        _ => None,
    }
}

/// The lanes a strand's step needs: one per edge, and one more for a free strand's first node.
fn lanes_needed(nodes: usize, held: bool) -> usize {
    if held { nodes - 1 } else { nodes }
}

/// The strands as packed for [`GpuStrandSolver::from_upload`]: made from the rods on the CPU (in the main
/// world, say), turned into buffers where the device is.
#[derive(Debug, Clone)]
pub struct GpuStrandUpload {
    words: Vec<[u32; 4]>,
    floats: Vec<[f32; 4]>,
    rest: Vec<[f32; 4]>,
    state: Vec<[f32; 4]>,
    layout: Arc<StrandLayout>,
    head_poses: Vec<(DQuat, DVec3)>,
}

/// Nodes of each strand, where each starts in the row planes, their sum (a plane's length, at least 1),
/// how many each pipeline steps, and the head of each.
#[derive(Debug)]
struct StrandLayout {
    node_counts: Vec<usize>,
    /// The lanes each strand's step needs (one per edge, one more for a free strand).
    lanes: Vec<usize>,
    first_nodes: Vec<usize>,
    total_nodes: usize,
    /// Strands stepped by each pipeline of [`STEP_LANES`] (listed in that order).
    list_lengths: [usize; STEP_LANES.len()],
    strand_heads: Vec<usize>,
    /// The hair–hair grid's fixed-point units of mass (kg) and volume (m³).
    grid_units: (f64, f64),
}

/// A collider shape's rows in the step's collider buffer after its poses (its kind and sizes, and for a
/// mesh its field's grid), with `field_row` the row where a mesh's field samples start.
fn shape_rows(shape: &ColliderShape, field_row: usize) -> [[f32; 4]; 4] {
    // The least radius of curvature, finite for a plane (a large number, which no edge reaches).
    let curvature = shape.smallest_curvature_radius().min(1e30);
    let zero = [0.0; 4];
    let simple = |row: [f32; 4], extra: f64| [row, vec4(DVec3::new(extra, 0.0, 0.0), curvature), zero, zero];
    match *shape {
        ColliderShape::Sphere { radius } => simple([radius as f32, 0.0, 0.0, 0.0], 0.0),
        ColliderShape::Capsule { radius, half_length } => simple([radius as f32, half_length as f32, 0.0, 1.0], 0.0),
        ColliderShape::Ellipsoid { semi_axes } => simple(vec4(semi_axes, 2.0), 0.0),
        ColliderShape::Plane => simple([0.0, 0.0, 0.0, 3.0], 0.0),
        ColliderShape::Cuboid { half_extents, rounding } => simple(vec4(half_extents, 4.0), rounding),
        ColliderShape::Mesh { ref field, scale, inflation } => {
            let counts = field.sample_counts().map(|n| f32::from_bits(n as u32));
            [
                vec4(scale, 5.0),
                [inflation as f32, field.cell_size() as f32, f32::from_bits(field_row as u32), curvature as f32],
                vec4(field.bounds().0, 0.0),
                [counts[0], counts[1], counts[2], 0.0],
            ]
        }
    }
}

fn vec4(v: DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

impl GpuStrandUpload {
    /// Packs `strands` (each rooted on one of the heads at `head_poses`: rotation and translation, m) in
    /// the GPU's layout. Rejects strands the GPU cannot step ([`GpuStepError`]).
    pub fn new(strands: &[GpuStrandInput], head_poses: &[(DQuat, DVec3)]) -> Result<Self, GpuStepError> {
        let strand_count = strands.len();
        let mut held = Vec::with_capacity(strand_count);
        for (index, strand) in strands.iter().enumerate() {
            let nodes = strand.rod.node_count();
            let Some(root_held) = root_held(strand.rod) else {
                return Err(GpuStepError::Unrooted { strand: index });
            };
            let most = if root_held { MAX_WIDE_GPU_NODES } else { max_free_gpu_nodes(MAX_WIDE_GPU_NODES) };
            if !(3..=most).contains(&nodes) {
                return Err(GpuStepError::NodeCount { strand: index, nodes, most });
            }
            if strand.head >= head_poses.len() {
                return Err(GpuStepError::NoSuchHead { strand: index, head: strand.head, heads: head_poses.len() });
            }
            held.push(root_held);
            if strand
                .groomed
                .is_some_and(|groomed| groomed.len() != nodes || !groomed.iter().all(|place| place.is_finite()))
            {
                return Err(GpuStepError::Groomed { strand: index });
            }
            let fractions_usable = strand.groomed_fractions.is_none_or(|fractions| {
                fractions.len() == nodes && fractions.iter().all(|f| f.is_finite() && *f >= 0.0)
            });
            if !(strand.hairs.is_finite() && strand.hairs >= 0.0 && fractions_usable) {
                return Err(GpuStepError::GridInput { strand: index });
            }
        }
        // Row planes of node-contiguous strands, none padded: row `k` of node `i` of strand `s` at
        // `k * total + first[s] + i`.
        let first_nodes: Vec<usize> = strands
            .iter()
            .scan(0, |next, strand| {
                let first = *next;
                *next += strand.rod.node_count();
                Some(first)
            })
            .collect();
        let total = strands.iter().map(|s| s.rod.node_count()).sum::<usize>().max(1);
        let padded = strand_count.max(1);
        let mut words = vec![[0_u32; 4]; padded];
        // The dispatch lists (`w` of the words): the strands by the narrowest pipeline they fit, narrowest
        // first.
        let lanes: Vec<usize> =
            strands.iter().zip(&held).map(|(strand, &held)| lanes_needed(strand.rod.node_count(), held)).collect();
        let class =
            |s: usize| STEP_LANES.iter().position(|&pipeline| lanes[s] <= pipeline).unwrap_or(STEP_LANES.len() - 1);
        let mut list_lengths = [0; STEP_LANES.len()];
        (0..strand_count).for_each(|s| list_lengths[class(s)] += 1);
        let lists: Vec<usize> =
            (0..STEP_LANES.len()).flat_map(|k| (0..strand_count).filter(move |&s| class(s) == k)).collect();
        let mut floats = vec![[0.0_f32; 4]; padded * STRAND_FLOATS];
        let mut rest = vec![[0.0_f32; 4]; total * REST_ROWS];
        let mut state = vec![[0.0_f32; 4]; total * STATE_ROWS];
        // The grid's fixed-point units: the heaviest node's mass and volume on the grid (so that every
        // node's share is resolved to 2⁻³² of it), 1 where there is none.
        let mut grid_units = (0.0_f64, 0.0_f64);
        for (s, strand) in strands.iter().enumerate() {
            let rod = strand.rod;
            let (rotation, translation) = head_poses[strand.head];
            let inverse = rotation.inverse();
            let local = |world: DVec3| inverse * (world - translation);
            let nodes = rod.node_count();
            let first = first_nodes[s];
            let head_word = strand.head as u32 | if held[s] { 0 } else { FREE_STRAND };
            words[s] = [nodes as u32, head_word, first as u32, lists[s] as u32];
            let stiffness = rod.stiffness();
            let constraints = rod.constraints();
            floats[s * STRAND_FLOATS] = [
                stiffness.stretching as f32,
                stiffness.bending_1 as f32,
                stiffness.bending_2 as f32,
                stiffness.twisting as f32,
            ];
            // Where the root is held (for a free strand, unused: its nodes and reference director as they are).
            let positions = &rod.state().positions;
            let root = [0, 1].map(|k| constraints.node_targets[k].unwrap_or(positions[k]));
            let direction = constraints.twist_targets[0].unwrap_or(rod.frames().reference_directors[0]);
            floats[s * STRAND_FLOATS + 1] = vec4(local(root[0]), strand.thickness);
            floats[s * STRAND_FLOATS + 2] = vec4(local(root[1]), strand.hairs);
            let per_kilogram = 1.0 / rod.material().density;
            floats[s * STRAND_FLOATS + 3] = vec4(inverse * direction, per_kilogram);
            let rod_state = rod.state();
            let frames = rod.frames();
            let shape = rod.rest_shape();
            let inertia = rod.inertia();
            // Arc length from the root as a fraction of the strand's length, for the hold's fade (past 1
            // where the strand is not held).
            let mut along = if strand.groomed.is_some() { 0.0 } else { HELD_NOWHERE };
            let length = rod.rest_length();
            for node in 0..nodes {
                let edge = node < nodes - 1;
                let at = |row: usize| row * total + first + node;
                let curvature = shape.curvatures.get(node).copied().unwrap_or(DVec2::ZERO);
                let voronoi = shape.voronoi_lengths.get(node).copied().filter(|l| *l > 0.0).unwrap_or(1.0);
                rest[at(0)] = [
                    if edge { shape.lengths[node] as f32 } else { 0.0 },
                    voronoi as f32,
                    curvature.x as f32,
                    curvature.y as f32,
                ];
                rest[at(1)] = [
                    shape.twists.get(node).copied().unwrap_or(0.0) as f32,
                    inertia.masses[node] as f32,
                    if edge { inertia.twist_inertias[node] as f32 } else { 0.0 },
                    strand.groomed_fractions.and_then(|fractions| fractions.get(node)).copied().unwrap_or(0.0) as f32,
                ];
                grid_units.0 = grid_units.0.max(strand.hairs * inertia.masses[node]);
                grid_units.1 = grid_units.1.max(strand.hairs * inertia.masses[node] * per_kilogram);
                let twist = if edge { rod_state.twist[node] } else { 0.0 };
                let director = if edge { inverse * frames.reference_directors[node] } else { DVec3::X };
                let reference_twist = frames.reference_twist.get(node).copied().unwrap_or(0.0);
                rest[at(2)] = vec4(local(rod_state.positions[node]), twist);
                rest[at(3)] = vec4(director, reference_twist);
                let groomed = strand.groomed.and_then(|groomed| groomed.get(node)).copied().unwrap_or_default();
                rest[at(4)] = vec4(groomed, along);
                if edge {
                    along += shape.lengths[node] / length;
                }
                let row = |row: usize| row * total + first + node;
                let rate = if edge { rod_state.twist_rates[node] } else { 0.0 };
                state[row(0)] = vec4(rotation * local(rod_state.positions[node]), twist);
                state[row(1)] = vec4(rod_state.velocities[node], rate);
                state[row(4)] = vec4(rotation * director, reference_twist);
            }
        }
        Ok(Self {
            words,
            floats,
            rest,
            state,
            layout: Arc::new(StrandLayout {
                node_counts: strands.iter().map(|s| s.rod.node_count()).collect(),
                lanes,
                first_nodes,
                total_nodes: total,
                list_lengths,
                strand_heads: strands.iter().map(|s| s.head).collect(),
                grid_units: (
                    if grid_units.0 > 0.0 { grid_units.0 } else { 1.0 },
                    if grid_units.1 > 0.0 { grid_units.1 } else { 1.0 },
                ),
            }),
            head_poses: head_poses.to_vec(),
        })
    }

    /// How many strands it holds.
    pub fn strand_count(&self) -> usize {
        self.layout.node_counts.len()
    }
}

impl GpuStrandSolver {
    /// Uploads `strands` (each rooted on one of the heads at `head_poses`: rotation and translation, m) and
    /// builds the step's pipeline on `device`. The strands start from their rods' states with no history
    /// (the first GPU step is backward Euler, as the CPU's first). A fault puts a strand back in the pose
    /// it has here, relative to its head.
    pub fn new(
        device: &wgpu::Device,
        strands: &[GpuStrandInput],
        head_poses: &[(DQuat, DVec3)],
    ) -> Result<Self, GpuStepError> {
        Self::from_upload(device, &GpuStepPipelines::new(device), GpuStrandUpload::new(strands, head_poses)?)
    }

    /// Builds the buffers of `upload` on `device`, stepped with `pipelines` (built on the same device).
    /// Refuses strands longer than the device's pipelines take ([`GpuStepPipelines::max_nodes`]).
    pub fn from_upload(
        device: &wgpu::Device,
        pipelines: &Arc<GpuStepPipelines>,
        upload: GpuStrandUpload,
    ) -> Result<Self, GpuStepError> {
        let GpuStrandUpload { words, floats, rest, state, layout: strands, head_poses } = upload;
        // (A pipeline of `n` lanes steps held strands of `n + 1` nodes, free ones of `n`.)
        let most_lanes = pipelines.max_nodes() - 1;
        if let Some(strand) = (0..strands.lanes.len()).find(|&s| strands.lanes[s] > most_lanes) {
            let (nodes, held) = (strands.node_counts[strand], strands.lanes[strand] < strands.node_counts[strand]);
            let most = if held { pipelines.max_nodes() } else { max_free_gpu_nodes(pipelines.max_nodes()) };
            return Err(GpuStepError::NodeCount { strand, nodes, most });
        }
        let strand_count = strands.node_counts.len();
        let storage = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | usage,
            })
        };
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let strand_words = storage("hair strand words", bytemuck::cast_slice(&words), wgpu::BufferUsages::empty());
        let strand_floats = storage("hair strand floats", bytemuck::cast_slice(&floats), wgpu::BufferUsages::empty());
        let rest = storage("hair rest shape", bytemuck::cast_slice(&rest), wgpu::BufferUsages::empty());
        let state = storage("hair strand state", bytemuck::cast_slice(&state), copy);
        let status = storage("hair strand status", &vec![0_u8; 16 * strand_count.max(1)], copy);
        let work = storage("hair step work", &vec![0_u8; 16 * WORK_ROWS * strand_count.max(1)], copy);
        let head_buffer_rows = STILL_AIR_ROWS + HEAD_ROWS * head_poses.len().max(1);
        let heads = storage("hair heads", &vec![0_u8; 16 * head_buffer_rows], copy);
        let collider_capacity = 4;
        let colliders = storage(
            "hair colliders",
            &vec![0_u8; 16 * COLLIDER_ROWS * collider_capacity],
            wgpu::BufferUsages::COPY_DST,
        );
        let params: Vec<wgpu::Buffer> = (0..pipelines.steps.len())
            .map(|_| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("hair step parameters"),
                    size: PARAMS_BYTES,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let bind_groups = step_bind_groups(
            device,
            pipelines,
            &params,
            [&strand_words, &strand_floats, &rest, &state, &heads, &colliders, &status, &work],
        );
        Ok(Self {
            pipelines: pipelines.clone(),
            bind_groups,
            params,
            state,
            status,
            heads,
            colliders,
            work,
            strand_words,
            strand_floats,
            rest,
            strand_count,
            strands,
            head_poses,
            last_dt: 0.0,
            head_rows: Vec::new(),
            air_rows: vec![[0.0; 4]; STILL_AIR_ROWS],
            head_buffer_rows,
            collider_rows: Vec::new(),
            collider_capacity,
            collider_buffer_rows: COLLIDER_ROWS * collider_capacity,
            fields: Vec::new(),
            step_fields: Vec::new(),
            staging: Arc::default(),
            driver_seconds: 0.0,
            volume: None,
            grid: None,
            force_rows: Vec::new(),
            grid_heads: Vec::new(),
            timestamps: device.features().contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
                let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("hair step timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: STEP_TIMESTAMPS,
                });
                let resolved = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("hair step timestamps"),
                    size: 8 * u64::from(STEP_TIMESTAMPS),
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                (queries, resolved)
            }),
        })
    }

    /// Writes timestamp `index` of the step into `encoder` (an empty pass that writes it as it begins),
    /// where the device has timestamp queries.
    fn mark_time(&self, encoder: &mut wgpu::CommandEncoder, index: u32) {
        if let Some((queries, _)) = &self.timestamps {
            let writes = wgpu::ComputePassTimestampWrites {
                query_set: queries,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            };
            drop(encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("hair step timestamp"),
                timestamp_writes: Some(writes),
            }));
        }
    }

    /// The time [`GpuStrandSolver::step`] spent in wgpu's `submit` and `poll` since the last call, s: the
    /// driver's share of the CPU's time (on a software adapter such as lavapipe, the GPU's work itself,
    /// which runs there).
    pub fn take_driver_seconds(&mut self) -> f64 {
        std::mem::take(&mut self.driver_seconds)
    }

    /// How many strands are stepped.
    pub fn strand_count(&self) -> usize {
        self.strand_count
    }

    /// Strand `strand`'s node count (0 past the last).
    pub fn node_count(&self, strand: usize) -> usize {
        self.strands.node_counts.get(strand).copied().unwrap_or(0)
    }

    /// Each strand's head (its index among the heads given at upload).
    pub fn strand_heads(&self) -> &[usize] {
        &self.strands.strand_heads
    }

    /// The bind groups again, after a buffer was made anew.
    fn bind_again(&mut self, device: &wgpu::Device) {
        self.bind_groups = step_bind_groups(
            device,
            &self.pipelines,
            &self.params,
            [
                &self.strand_words,
                &self.strand_floats,
                &self.rest,
                &self.state,
                &self.heads,
                &self.colliders,
                &self.status,
                &self.work,
            ],
        );
    }

    /// The air every head's hair moves in from the next step on, besides each head's
    /// [`GpuHeadStep::air_velocity`]: the wind's uniform part, its turbulence and its jets, sampled by the
    /// step at each node where it was at the step's start, as [`crate::wind::HairWindPlugin`] samples it
    /// on the CPU (which interpolates the turbulence between nodes a quarter of its scale apart). Still
    /// air until set. Refuses air with a value that is not finite (and keeps the air it had).
    pub fn set_air(&mut self, air: &AirSnapshot) -> Result<(), GpuStepError> {
        let finite = air.uniform.is_finite()
            && air.modes.iter().all(|m| m.wave_vector.is_finite() && m.amplitude.is_finite() && m.phase.is_finite())
            && air.jets.iter().all(|j| {
                j.origin.is_finite()
                    && j.axis.is_finite()
                    && j.speed.is_finite()
                    && j.radius.is_finite()
                    && j.range.is_finite()
            });
        if !finite {
            return Err(GpuStepError::InvalidAir);
        }
        let bits = |count: usize| f32::from_bits(count as u32);
        let uniform = air.uniform.as_vec3();
        self.air_rows.clear();
        self.air_rows.push([uniform.x, uniform.y, uniform.z, bits(air.modes.len())]);
        self.air_rows.push([bits(air.jets.len()), 0.0, 0.0, 0.0]);
        for mode in &air.modes {
            self.air_rows.push(vec4(mode.wave_vector, mode.phase));
            self.air_rows.push(vec4(mode.amplitude, 0.0));
        }
        for jet in &air.jets {
            self.air_rows.push(vec4(jet.origin, jet.speed));
            self.air_rows.push(vec4(jet.axis, jet.range));
            self.air_rows.push([jet.radius as f32, 0.0, 0.0, 0.0]);
        }
        Ok(())
    }

    /// Hair–hair interaction through a grid from the next step on (`None`, the default: none): each
    /// stepped head's hair splatted to its own grid, and every free node given the grid's velocity
    /// smoothing and volume pressure before the step, as [`crate::volume`] does on the CPU (the module
    /// `gpu::grid`'s documentation says how it is laid out). Each strand stands on the grid for its
    /// [`GpuStrandInput::hairs`]. Refuses parameters out of range (and keeps those it had).
    pub fn set_volume(&mut self, volume: Option<GpuVolume>) -> Result<(), GpuStepError> {
        if volume.is_some_and(|volume| !volume.is_valid()) {
            return Err(GpuStepError::InvalidVolume);
        }
        self.volume = volume;
        Ok(())
    }

    /// Forces on strand `strand`'s nodes for its next step (one per node, N, world space): a game's loads
    /// (`StrandForces` on the CPU), besides gravity, drag and the grid's pressure. Written into the queue
    /// now, so they take effect in the next step recorded after this call in which the strand's head is
    /// stepped, and are used up by it. Refuses a strand out of range, a wrong count or a force that is not
    /// finite (and writes nothing).
    pub fn add_forces(&mut self, queue: &wgpu::Queue, strand: usize, forces: &[DVec3]) -> Result<(), GpuStepError> {
        self.write_node_row(queue, strand, 5, forces)
    }

    /// Adds `velocities` (m/s, one per node of `strand`) to the air's velocity at the strand's nodes in the
    /// next step (the drag acts on the velocity relative to it, as `StrandForces::add_air_velocity` on the
    /// CPU), besides the wind of [`GpuStrandSolver::set_air`]; used up by that step. Written with `queue`
    /// before the step is submitted.
    pub fn add_air_velocities(
        &mut self,
        queue: &wgpu::Queue,
        strand: usize,
        velocities: &[DVec3],
    ) -> Result<(), GpuStepError> {
        self.write_node_row(queue, strand, 6, velocities)
    }

    /// Writes one finite vector per node of `strand` into state row `row`, which the next step reads and
    /// clears.
    fn write_node_row(
        &mut self,
        queue: &wgpu::Queue,
        strand: usize,
        row: usize,
        values: &[DVec3],
    ) -> Result<(), GpuStepError> {
        let nodes = self.node_count(strand);
        if nodes == 0 || values.len() != nodes || !values.iter().all(|value| value.is_finite()) {
            return Err(GpuStepError::InvalidForces { strand });
        }
        self.force_rows.clear();
        self.force_rows.extend(values.iter().map(|&value| vec4(value, 0.0)));
        let at = row * self.strands.total_nodes + self.strands.first_nodes[strand];
        queue.write_buffer(&self.state, 16 * at as u64, bytemuck::cast_slice(&self.force_rows));
        Ok(())
    }

    /// Each head's grid as the last step left it (empty before the first step with a grid), waiting for
    /// the GPU: for tests and debugging views.
    pub fn read_grid(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Vec<GpuGridFields> {
        self.grid.as_ref().map(|grid| grid.read(device, queue)).unwrap_or_default()
    }

    /// Writes the colliders of `heads` into the collider buffer (their poses relative to their heads' new
    /// translations, their shapes), and the samples of their mesh fields after them when the set of fields
    /// changed; grows the buffer (and binds it again) when they do not fit.
    fn place_colliders(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        heads: &[GpuHeadStep],
    ) -> Result<(), GpuStepError> {
        let collider_count: usize = heads.iter().map(|head| head.colliders.len()).sum();
        let capacity = self.collider_capacity.max(collider_count.next_power_of_two());
        // The fields in the order their colliders come, each once, from the row after the colliders'.
        self.step_fields.clear();
        let mut row = COLLIDER_ROWS * capacity;
        for collider in heads.iter().flat_map(|head| &head.colliders) {
            if let ColliderShape::Mesh { field, .. } = &collider.shape
                && !self.step_fields.iter().any(|(known, _)| Arc::ptr_eq(known, field))
            {
                self.step_fields.push((field.clone(), row));
                row += field.samples().len().div_ceil(4);
            }
        }
        let bytes = 16 * row as u64;
        let limit = device.limits().max_storage_buffer_binding_size;
        if bytes > limit {
            return Err(GpuStepError::CollidersTooLarge { bytes, limit });
        }
        let same_fields = self.fields.len() == self.step_fields.len()
            && self.fields.iter().zip(&self.step_fields).all(|(a, b)| Arc::ptr_eq(&a.0, &b.0) && a.1 == b.1);
        let grown = row > self.collider_buffer_rows;
        if grown {
            self.collider_buffer_rows = row.next_power_of_two();
            self.colliders = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hair colliders"),
                size: (16 * self.collider_buffer_rows) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.bind_again(device);
        }
        self.collider_capacity = capacity;
        if grown || !same_fields {
            for (field, row) in &self.step_fields {
                queue.write_buffer(&self.colliders, 16 * *row as u64, bytemuck::cast_slice(field.samples()));
            }
            std::mem::swap(&mut self.fields, &mut self.step_fields);
        }
        self.collider_rows.clear();
        for head in heads {
            for collider in &head.colliders {
                let relative = |translation: DVec3| translation - head.translation;
                let rotation = |q: DQuat| q.as_quat().to_array();
                let field_row = match &collider.shape {
                    ColliderShape::Mesh { field, .. } => {
                        self.fields.iter().find(|(known, _)| Arc::ptr_eq(known, field)).map_or(0, |(_, row)| *row)
                    }
                    _ => 0,
                };
                self.collider_rows.extend([
                    vec4(relative(collider.start.translation), 0.0),
                    rotation(collider.start.rotation),
                    vec4(relative(collider.end.translation), collider.friction),
                    rotation(collider.end.rotation),
                ]);
                self.collider_rows.extend(shape_rows(&collider.shape, field_row));
            }
        }
        if !self.collider_rows.is_empty() {
            queue.write_buffer(&self.colliders, 0, bytemuck::cast_slice(&self.collider_rows));
        }
        Ok(())
    }

    /// Records one fixed step of `params.dt` of every strand into `encoder`, with each head moving to its
    /// pose in `heads` (one per head given to [`GpuStrandSolver::new`], in order) and its hair stepped or
    /// carried as its [`GpuHeadStep::cadence`] says, after writing the step's parameters, heads and
    /// colliders into the queue. Submit the encoder before recording the next step. Rejects invalid
    /// parameters, heads with a non-finite pose, air or collider or a cadence out of range, and colliders
    /// with mesh fields too large for one buffer of the device; nothing changes then.
    pub fn record_step(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        params: &StepParams,
        heads: &[GpuHeadStep],
    ) -> Result<(), GpuStepError> {
        params.validate()?;
        if heads.len() != self.head_poses.len() {
            return Err(RodError::WrongLength { expected: self.head_poses.len(), actual: heads.len() }.into());
        }
        for (index, head) in heads.iter().enumerate() {
            let finite_pose = |pose: &crate::rod::RigidPose| pose.translation.is_finite() && pose.rotation.is_finite();
            let usable = head.translation.is_finite()
                && head.rotation.is_finite()
                && (head.rotation.length() - 1.0).abs() < 1e-3
                && head.air_velocity.is_finite()
                && head.hold_rate.is_finite()
                && head.hold_rate >= 0.0
                && (0.0..=1.0).contains(&head.hold_reach)
                && !matches!(head.cadence, GpuHairCadence::Step(span) if span == 0 || span > MAX_GPU_SPAN)
                && head
                    .colliders
                    .iter()
                    .all(|c| finite_pose(&c.start) && finite_pose(&c.end) && c.friction.is_finite());
            if !usable {
                return Err(GpuStepError::InvalidHead { head: index });
            }
        }
        self.place_colliders(device, queue, heads)?;
        self.head_rows.clear();
        self.head_rows.extend_from_slice(&self.air_rows);
        let mut first = 0;
        for (head, before) in heads.iter().zip(&self.head_poses) {
            let count = head.colliders.len() as u32;
            self.head_rows.extend([
                head.rotation.as_quat().to_array(),
                vec4(before.1 - head.translation, 0.0),
                vec4(head.air_velocity, 0.0),
                [f32::from_bits(first), f32::from_bits(count), head.hold_rate as f32, head.hold_reach as f32],
                before.0.as_quat().to_array(),
                {
                    // As the shader reads it (`CARRIED`, `WAITING`).
                    let span = match head.cadence {
                        GpuHairCadence::Step(span) => span,
                        GpuHairCadence::Carried => 0,
                        GpuHairCadence::Waiting => u32::MAX,
                    };
                    let translation = head.translation.as_vec3();
                    [translation.x, translation.y, translation.z, f32::from_bits(span)]
                },
            ]);
            first += count;
        }
        // The grid is built where the hair was at the step's start: around each head's translation then.
        self.grid_heads.clear();
        for (head, before) in heads.iter().zip(&self.head_poses) {
            // (A head with no step's length this fixed step is off the grid.)
            let span = match head.cadence {
                _ if head.meets_hair_elsewhere => 0.0,
                GpuHairCadence::Step(span) => f64::from(span),
                GpuHairCadence::Carried | GpuHairCadence::Waiting => 0.0,
            };
            self.grid_heads.push((before.1, span * params.dt));
        }
        for (pose, head) in self.head_poses.iter_mut().zip(heads) {
            *pose = (head.rotation, head.translation);
        }
        if self.head_rows.len() > self.head_buffer_rows {
            self.head_buffer_rows = self.head_rows.len().next_power_of_two();
            self.heads = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hair heads"),
                size: (16 * self.head_buffer_rows) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.bind_again(device);
        }
        queue.write_buffer(&self.heads, 0, bytemuck::cast_slice(&self.head_rows));
        let restart = (params.dt - self.last_dt).abs() > 1e-9 * params.dt;
        self.last_dt = params.dt;
        let gravity = params.gravity.as_vec3();
        let mut words: [u32; 24] = [
            (params.dt as f32).to_bits(),
            gravity.x.to_bits(),
            gravity.y.to_bits(),
            gravity.z.to_bits(),
            (params.air_damping as f32).to_bits(),
            (params.axial_drag_ratio as f32).to_bits(),
            (params.internal_damping as f32).to_bits(),
            (params.max_rotation as f32).to_bits(),
            ((params.strain_bound() + SINGLE_PRECISION_STRAIN) as f32).to_bits(),
            (STRETCH_RATIO as f32).to_bits(),
            self.strand_count as u32,
            GPU_NEWTON_ITERATIONS,
            params.max_projection_iterations,
            GPU_CONTACT_ROUNDS,
            u32::from(params.integrator == crate::rod::Integrator::Bdf2),
            u32::from(restart),
            (params.strain_tolerance as f32).to_bits(),
            self.strands.total_nodes as u32,
            0,
            0,
            self.air_rows.len() as u32,
            0,
            0,
            0,
        ];
        // The grid's velocity changes and forces, before the step reads them.
        self.mark_time(encoder, 0);
        if let Some(volume) = self.volume.as_ref() {
            let grid = self.grid.get_or_insert_with(|| {
                let buffers = [&self.strand_words, &self.strand_floats, &self.rest, &self.state];
                GpuGrid::new(device, &self.pipelines.grid, self.head_poses.len(), buffers)
            });
            let step = GridStep {
                volume,
                heads: &self.grid_heads,
                strands: self.strand_count,
                total_nodes: self.strands.total_nodes,
                units: self.strands.grid_units,
            };
            grid.record(queue, encoder, &self.pipelines.grid, &step);
        }
        self.mark_time(encoder, 1);
        // One workgroup per strand, in one pass: the strands of each pipeline's list.
        let writes = self.timestamps.as_ref().map(|(queries, _)| wgpu::ComputePassTimestampWrites {
            query_set: queries,
            beginning_of_pass_write_index: None,
            end_of_pass_write_index: Some(2),
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("hair strand step"),
            timestamp_writes: writes,
        });
        let mut start = 0;
        // (A list past the device's pipelines is empty: `from_upload` refused strands that would be in it.)
        for (class, &length) in self.strands.list_lengths.iter().enumerate().take(self.params.len()) {
            words[18] = start as u32;
            words[19] = length as u32;
            queue.write_buffer(&self.params[class], 0, bytemuck::cast_slice(&words));
            start += length;
            if length == 0 {
                continue;
            }
            let (x, y) = workgroups(length as u32, 1);
            pass.set_pipeline(&self.pipelines.steps[class]);
            pass.set_bind_group(0, &self.bind_groups[class], &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        drop(pass);
        if let Some((queries, resolved)) = &self.timestamps {
            encoder.resolve_query_set(queries, 0..STEP_TIMESTAMPS, resolved, 0);
        }
        Ok(())
    }

    /// One step, submitted at once: [`GpuStrandSolver::record_step`] in an encoder of its own.
    pub fn step(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        params: &StepParams,
        heads: &[GpuHeadStep],
    ) -> Result<wgpu::SubmissionIndex, GpuStepError> {
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hair strand step") });
        self.record_step(device, queue, &mut encoder, params, heads)?;
        let commands = encoder.finish();
        let started = std::time::Instant::now();
        let submission = queue.submit([commands]);
        // Let wgpu retire finished work (without it, submissions' bookkeeping piles up).
        let _ = device.poll(wgpu::PollType::Poll);
        self.driver_seconds += started.elapsed().as_secs_f64();
        Ok(submission)
    }

    /// Reads every strand's state back, waiting for the GPU (for tests, benchmarks and on-demand
    /// read-back; the plugin reads back asynchronously with [`GpuStrandSolver::request_read_back`]).
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> GpuStrandStates {
        let mut pending = self.request_read_back(device, queue, true);
        loop {
            let _ = device.poll(wgpu::PollType::wait_indefinitely());
            if let Some(states) = pending.try_take() {
                return states;
            }
        }
    }

    /// Copies every strand's state as the submitted steps leave it (positions, velocities, twists and
    /// frames: not the history, which stays on the GPU) into a buffer the CPU can map, and asks for it to
    /// be mapped: [`GpuReadBack::try_take`] has it once the GPU is done and the device was polled (Bevy's
    /// renderer polls it every frame). The buffer is reused by later read-backs once its states were taken.
    /// Without `state`, only each strand's status ([`GpuStrandStates::status`]; 16 bytes a strand, for
    /// the faults) is read back, and the other fields come back empty.
    pub fn request_read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue, state: bool) -> GpuReadBack {
        let state_bytes = self.read_back_state_bytes(state);
        let status_bytes = self.status.size();
        // Then the grid's heads, for its densest point; the work counters; the last step's timestamps.
        let grid_bytes = self.grid.as_ref().map_or(0, |grid| grid.heads_buffer().size());
        let work_bytes = self.work.size();
        let timestamp_bytes = self.timestamps.as_ref().map_or(0, |(_, resolved)| resolved.size());
        let size = state_bytes + status_bytes + grid_bytes + work_bytes + timestamp_bytes;
        let reused = self.staging.lock().ok().and_then(|mut pool| {
            let found = pool.iter().position(|buffer| buffer.size() == size)?;
            Some(pool.swap_remove(found))
        });
        let staging = reused.unwrap_or_else(|| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hair read-back"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        });
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hair read-back") });
        // Row planes 0 and 1 (contiguous in the state), then plane 4.
        if state {
            let plane = self.plane_bytes();
            encoder.copy_buffer_to_buffer(&self.state, 0, &staging, 0, 2 * plane);
            encoder.copy_buffer_to_buffer(&self.state, 4 * plane, &staging, 2 * plane, plane);
        }
        encoder.copy_buffer_to_buffer(&self.status, 0, &staging, state_bytes, status_bytes);
        if let Some(grid) = &self.grid {
            encoder.copy_buffer_to_buffer(grid.heads_buffer(), 0, &staging, state_bytes + status_bytes, grid_bytes);
        }
        let work_at = state_bytes + status_bytes + grid_bytes;
        encoder.copy_buffer_to_buffer(&self.work, 0, &staging, work_at, work_bytes);
        if let Some((_, resolved)) = &self.timestamps {
            encoder.copy_buffer_to_buffer(resolved, 0, &staging, work_at + work_bytes, timestamp_bytes);
        }
        queue.submit([encoder.finish()]);
        let mapped = Arc::new(AtomicU8::new(MAP_PENDING));
        let signal = mapped.clone();
        staging.slice(..).map_async(wgpu::MapMode::Read, move |result| {
            signal.store(if result.is_ok() { MAP_DONE } else { MAP_FAILED }, Ordering::Release);
        });
        GpuReadBack {
            staging: Some(staging),
            pool: self.staging.clone(),
            state_bytes,
            status_bytes,
            grid_bytes,
            work_bytes,
            timestamp_period: self.timestamps.is_some().then(|| f64::from(queue.get_timestamp_period()) * 1e-9),
            mapped,
            strands: self.strands.clone(),
            translations: self.strands.strand_heads.iter().map(|&head| self.head_poses[head].1).collect(),
        }
    }

    /// Bytes a read-back moves from the GPU ([`GpuStrandSolver::request_read_back`]), with the state or
    /// without.
    pub fn read_back_bytes(&self, state: bool) -> u64 {
        self.read_back_state_bytes(state) + self.status.size()
    }

    /// The state's bytes a read-back copies: rows 0, 1 and 4 of every node with the state, none without.
    fn read_back_state_bytes(&self, state: bool) -> u64 {
        if state { READ_BACK_ROWS.len() as u64 * self.plane_bytes() } else { 0 }
    }

    /// The bytes of one row plane of the state (a `vec4` per node of every strand).
    fn plane_bytes(&self) -> u64 {
        16 * self.strands.total_nodes as u64
    }

    /// Each strand's work since the upload ([`GpuStrandWork`]), waiting for the GPU: for tests and
    /// benchmarks, which bound and print what the step costs on any adapter.
    pub fn read_work(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Vec<GpuStrandWork> {
        let bytes = self.work.size();
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hair step work read-back"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("hair step work") });
        encoder.copy_buffer_to_buffer(&self.work, 0, &staging, 0, bytes);
        queue.submit([encoder.finish()]);
        staging.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        let _ = device.poll(wgpu::PollType::wait_indefinitely());
        let data = staging.slice(..).get_mapped_range();
        GpuStrandWork::unpack(bytemuck::cast_slice(&data), self.strand_count)
    }

    /// The buffers [`GpuStrandSolver::gather_target`] binds, for a caller that wants them itself: each
    /// strand's state (row planes of `vec4<f32>` over every strand's nodes, see `step.wgsl`) and its status.
    pub fn state_buffers(&self) -> (&wgpu::Buffer, &wgpu::Buffer) {
        (&self.state, &self.status)
    }

    /// Binds what [`GpuStrandSolver::record_gather`] writes for one head's guides: `guides` lists, in the
    /// order the follower placement lays them out, each guide's strand (an index into the strands given
    /// at upload) and its first node in the placement's guide nodes, then one past the last node;
    /// `guide_data` is the placement's step data (positions from word 0, the guide words from
    /// `guides_offset`), `guide_frames` its director per guide node (`render/followers.wgsl`).
    pub fn gather_target(
        &self,
        device: &wgpu::Device,
        guides: &[[u32; 2]],
        guide_data: &wgpu::Buffer,
        guide_frames: &wgpu::Buffer,
    ) -> GpuGatherTarget {
        let solver = [&self.strand_words, &self.strand_floats, &self.state, &self.status];
        self.pipelines.gather.target(device, solver, guides, guide_data, guide_frames)
    }

    /// Records the gather of one head's guides (`target`, on head `head` of the upload) after the steps
    /// recorded or submitted before it: each guide's nodes in world space (the head's translation after
    /// the last step added), its thickness and flags (a guide whose strand faulted in the last step
    /// snaps), and the material director `m1` of each node's edge.
    pub fn record_gather(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &GpuGatherTarget,
        head: usize,
        guides_offset: u32,
    ) {
        let translation = self.head_poses.get(head).map_or(DVec3::ZERO, |pose| pose.1).as_vec3();
        let words: [u32; 8] = [
            self.strands.total_nodes as u32,
            target.guides,
            guides_offset,
            0,
            translation.x.to_bits(),
            translation.y.to_bits(),
            translation.z.to_bits(),
            0,
        ];
        queue.write_buffer(&target.params, 0, bytemuck::cast_slice(&words));
        let (x, y) = workgroups(target.guides, GATHER_WORKGROUP);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("hair guides gathered"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipelines.gather.pipeline);
        pass.set_bind_group(0, &target.bind_group, &[]);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// The step's bind groups, one per pipeline of [`STEP_LANES`]: its parameters, then `buffers` (strand words,
/// floats, rest shape, state, heads, colliders, status, work counters).
fn step_bind_groups(
    device: &wgpu::Device,
    pipelines: &GpuStepPipelines,
    params: &[wgpu::Buffer],
    buffers: [&wgpu::Buffer; 8],
) -> Vec<wgpu::BindGroup> {
    params
        .iter()
        .map(|params| {
            let all: Vec<&wgpu::Buffer> = std::iter::once(params).chain(buffers).collect();
            bind_whole_buffers(device, "hair strand step", &pipelines.layout, &all)
        })
        .collect()
}

/// The workgroups of `size` invocations of a dispatch over `invocations`: along X up to the limit, then rows
/// along Y.
pub(super) fn workgroups(invocations: u32, size: u32) -> (u32, u32) {
    let groups = invocations.div_ceil(size).max(1);
    if groups > MAX_GROUPS { (MAX_GROUPS, groups.div_ceil(MAX_GROUPS)) } else { (groups, 1) }
}

/// The states of [`GpuReadBack::mapped`].
const MAP_PENDING: u8 = 0;
const MAP_DONE: u8 = 1;
const MAP_FAILED: u8 = 2;

/// A read-back on its way from the GPU ([`GpuStrandSolver::request_read_back`]).
pub struct GpuReadBack {
    /// The buffer mapped for the CPU: `None` once handed back to the pool.
    staging: Option<wgpu::Buffer>,
    /// Where the buffer goes when its states were taken, for the next read-back.
    pool: Arc<Mutex<Vec<wgpu::Buffer>>>,
    state_bytes: u64,
    status_bytes: u64,
    grid_bytes: u64,
    work_bytes: u64,
    /// Seconds per timestamp tick, where the read-back carries the last step's timestamps.
    timestamp_period: Option<f64>,
    /// Set by the mapping's callback.
    mapped: Arc<AtomicU8>,
    strands: Arc<StrandLayout>,
    /// Each strand's head's translation when the read-back was asked for: the origin of its positions.
    translations: Vec<DVec3>,
}

impl GpuReadBack {
    /// The states, once the GPU has copied them and the device was polled since; `None` before. After
    /// it returned them (or the mapping failed: a lost device), `None` again.
    pub fn try_take(&mut self) -> Option<GpuStrandStates> {
        if self.mapped.load(Ordering::Acquire) != MAP_DONE {
            return None;
        }
        self.mapped.store(MAP_FAILED, Ordering::Release);
        let staging = self.staging.take()?;
        let data = staging.slice(..).get_mapped_range();
        let state_bytes = self.state_bytes as usize;
        let state = (state_bytes > 0).then(|| bytemuck::cast_slice(&data[..state_bytes]));
        let status_end = state_bytes + self.status_bytes as usize;
        let grid_end = status_end + self.grid_bytes as usize;
        let work_end = grid_end + self.work_bytes as usize;
        let mut states = self.unpack(state, bytemuck::cast_slice(&data[state_bytes..status_end]));
        states.max_volume_fraction = GpuGrid::densest(bytemuck::cast_slice(&data[status_end..grid_end]));
        states.work = GpuStrandWork::total(&GpuStrandWork::unpack(
            bytemuck::cast_slice(&data[grid_end..work_end]),
            self.strands.node_counts.len(),
        ));
        if let Some(period) = self.timestamp_period {
            let ticks: &[u64] = bytemuck::cast_slice(&data[work_end..]);
            let seconds = |from: usize| ticks[from + 1].saturating_sub(ticks[from]) as f64 * period;
            states.timings = Some(GpuStepTimings { grid_seconds: seconds(0), step_seconds: seconds(1) });
        }
        drop(data);
        staging.unmap();
        if let Ok(mut pool) = self.pool.lock() {
            pool.push(staging);
        }
        Some(states)
    }

    /// Whether the mapping failed or its states were taken: nothing more will come.
    pub fn is_finished(&self) -> bool {
        self.mapped.load(Ordering::Acquire) == MAP_FAILED
    }

    /// The strands' state from the read-back's rows and the status buffer's contents, unpacked on Bevy's
    /// compute pool in blocks of strands where it has threads.
    fn unpack(&self, state: Option<&[[f32; 4]]>, status: &[[u32; 4]]) -> GpuStrandStates {
        const BLOCK: usize = 256;
        let strands = self.strands.node_counts.len();
        let blocks = strands.div_ceil(BLOCK);
        let unpack_block =
            |block: usize| self.unpack_range(state, status, block * BLOCK..((block + 1) * BLOCK).min(strands));
        let parts: Vec<GpuStrandStates> = match bevy::tasks::ComputeTaskPool::try_get() {
            Some(pool) if pool.thread_num() > 1 && blocks > 1 => pool.scope(|scope| {
                for block in 0..blocks {
                    let unpack_block = &unpack_block;
                    scope.spawn(async move { unpack_block(block) });
                }
            }),
            _ => (0..blocks).map(unpack_block).collect(),
        };
        let mut states = GpuStrandStates::default();
        for part in parts {
            states.positions.extend(part.positions);
            states.velocities.extend(part.velocities);
            states.twists.extend(part.twists);
            states.twist_rates.extend(part.twist_rates);
            states.reference_directors.extend(part.reference_directors);
            states.reference_twists.extend(part.reference_twists);
            states.status.extend(part.status);
        }
        states
    }

    /// The strands in `range`, as [`GpuReadBack::unpack`].
    fn unpack_range(
        &self,
        state: Option<&[[f32; 4]]>,
        status: &[[u32; 4]],
        range: std::ops::Range<usize>,
    ) -> GpuStrandStates {
        let (counts, firsts, total) = (&self.strands.node_counts, &self.strands.first_nodes, self.strands.total_nodes);
        let mut states = GpuStrandStates::default();
        for s in range {
            if let Some(state) = state {
                let (nodes, first, translation) = (counts[s], firsts[s], self.translations[s]);
                // Row planes 0, 1 and 4 of the state, in that order (`READ_BACK_ROWS`).
                let row = |node: usize, row: usize| state[row * total + first + node];
                let local = |v: [f32; 4]| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
                let edges = nodes - 1;
                states.positions.push((0..nodes).map(|i| translation + local(row(i, 0))).collect());
                states.velocities.push((0..nodes).map(|i| local(row(i, 1))).collect());
                states.twists.push((0..edges).map(|i| row(i, 0)[3] as f64).collect());
                states.twist_rates.push((0..edges).map(|i| row(i, 1)[3] as f64).collect());
                states.reference_directors.push((0..edges).map(|i| local(row(i, 2))).collect());
                states.reference_twists.push((0..nodes).map(|i| row(i, 2)[3] as f64).collect());
            }
            let [flags, at, strain, faults] = status[s];
            let reason = |bits: u32| {
                if bits & 2 != 0 {
                    Some(GpuFault::NonFinite { node: at })
                } else if bits & 4 != 0 {
                    Some(GpuFault::OverStrained { edge: at })
                } else if bits & 8 != 0 {
                    Some(GpuFault::NotPositiveDefinite)
                } else {
                    None
                }
            };
            states.status.push(GpuStrandStatus {
                contacts: (flags >> 8) & 0xff,
                contact_given_up: flags & 16 != 0,
                max_strain: f32::from_bits(strain),
                fault: reason(flags),
                last_fault: reason(faults >> 28),
                faults: faults & 0x0fff_ffff,
            });
        }
        states
    }
}
