//! The strands stepped on the GPU inside a Bevy app ([`HairGpuPlugin`]): the main world chooses the
//! strands and sends each fixed step's head poses, colliders and air; the render world steps them with
//! [`GpuStrandSolver`] on Bevy's own device (one submission per step, before the render graph), gathers
//! them into the follower placement's buffers (`render/followers.rs`), and reads them back now and then
//! through a channel to the main world.

use std::f64::consts::PI;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};

use bevy::ecs::entity::{EntityHashMap, EntityHashSet};
use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::math::{DQuat, DVec3};
use bevy::prelude::*;
use bevy::render::renderer::{RenderAdapter, RenderDevice, RenderQueue};
use bevy::render::{ExtractSchedule, MainWorld, Render, RenderApp, RenderSystems};

use super::draw::GpuStepCount;
use crate::detail::{HairDetail, HairDetailLevel};
use crate::followers::{FollowerPlacement, HairFollowers, PlaceFollowersOnCpu};
use crate::gpu::{
    GPU_FOLD_GAP, GpuFault, GpuHairCadence, GpuHeadStep, GpuReadBack, GpuStepError, GpuStepPipelines, GpuStepTimings,
    GpuStrandInput, GpuStrandSolver, GpuStrandStates, GpuStrandStatus, GpuStrandUpload, GpuStrandWork, GpuVolume,
    MAX_GPU_NODES, MAX_GPU_SPAN, SINGLE_PRECISION_STRAIN, gpu_max_nodes, gpu_step_support, max_free_gpu_nodes,
    root_held,
};
use crate::rod::{AirSnapshot, Integrator, RodError, StepError, StepParams};
use crate::schedule::{HairPinSystems, HairStepSystems, HairSystems};
use crate::simulation::{
    CheckedSettings, FaultLog, HairHead, HairSettings, HairStatistics, HeadMotion, HeadStrands, QUARANTINE_WINDOW,
    SimulatedStrand, SteppedElsewhere, StrandColliders, StrandFault, StrandForces, StrandFrames, StrandNodes, StrandOf,
    write_strand_data,
};
use crate::volume::{RepresentedHairs, groomed_fractions as groomed_fractions_of, represented_hairs};
use crate::wind::{HairWind, HairWindSource};

/// Steps the hair on the GPU ([`crate::gpu`]: the same discrete elastic rods in single precision, one
/// workgroup per strand), on the device of Bevy's renderer; part of [`crate::HairPlugins`] with the `gpu`
/// feature (on by default), so a game with Bevy's renderer steps its hair on the GPU with nothing more:
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// App::new().add_plugins((DefaultPlugins, HairPlugins::default()));
/// ```
///
/// **Where it cannot run**, the CPU steps every strand, and [`HairGpuStatus::error`] says why (logged once,
/// at start): an app without Bevy's renderer (`MinimalPlugins`, a server), or a device that cannot run the
/// step ([`crate::gpu::gpu_step_support`]: WebGL2, a device without compute shaders or with fewer than 8
/// storage buffers a stage). [`HairGpuSettings::enabled`] chooses the CPU in an app that could:
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// App::new()
///     .add_plugins((DefaultPlugins, HairPlugins::default()))
///     .insert_resource(HairGpuSettings { enabled: false, ..default() });
/// ```
///
/// **Which strands.** Every built strand rooted on a [`HairHead`] with 3 to [`gpu_max_nodes`] nodes
/// ([`MAX_GPU_NODES`], 65, on every device; [`MAX_WIDE_GPU_NODES`](crate::gpu::MAX_WIDE_GPU_NODES), 129,
/// where the device has the workgroup memory, as desktop GPUs do), and every free strand (a
/// [`HairStrand`](crate::simulation::HairStrand) with no [`StrandOf`]) with one node fewer
/// ([`max_free_gpu_nodes`]), once its gravity preload is done and its state is one a step can start from,
/// without two edges folded within [`GPU_FOLD_GAP`] of flat onto each other (which single precision cannot
/// step). Such a strand gets [`SteppedElsewhere`], so the CPU step leaves it; the others stay on the CPU
/// (longer strands; a folded or quarantined one until it unfolds or its quarantine ends, looked over again
/// each step). The strands are chosen once their rest shapes are preloaded ([`HairPinSystems::Preload`]),
/// before anything adds to their loads: a strand goes to the GPU from the state it was preloaded in, and
/// meets the GPU's wind and grid alone from its first step there. Free strands are stepped in the world's
/// frame (single precision resolves 0.1 µm within a metre of the origin, 60 µm at a kilometre), meet the
/// shared colliders (those of no head) as on the CPU, are on no hair–hair grid (as on the CPU), and are read
/// back every step while any is on the GPU (no head's mesh draws them: a game reads their components). A head
/// whose guides are all on the GPU has its followers placed and its hair drawn from the GPU's state directly
/// (the hair mesh is then not frustum-culled: its bounds are not known on the CPU); a head with some on the
/// CPU is drawn from the components. Adding or removing strands uploads the set again, each from its last
/// read-back state; writing a GPU strand's rod or components from outside has no effect (the GPU's state is
/// the truth, and the next read-back overwrites them).
///
/// **What the GPU meets.** Each head's colliders, its own and the shared ones, of every shape: spheres,
/// capsules, ellipsoids (at their closest point), planes, boxes (rounded or not) and meshes (their baked
/// distance fields, uploaded once and sampled trilinearly), nodes and the edges dipping in between them,
/// with the CPU's rule for a collider holding a root inside it (the strand near the root is left free of
/// it). The air is the wind ([`HairWind`], [`HairWindSource`]) sampled by the step at every node, its
/// gusts, eddies and jets included, as on the CPU (which interpolates the eddies between nodes a quarter
/// of their size apart; the GPU takes every node). The hair–hair grid ([`HairSettings::volume`]) is the
/// GPU's own, each head's hair splatted and smoothed and pressed there as on the CPU (`gpu::grid`); a head
/// with strands on both sides meets on the CPU's grid alone, its GPU strands splatted there as last read
/// back (a step or two late: such a head is read back every step) and the grid's response sent to them as
/// forces, the head left off the GPU's grid.
/// A game's forces, velocity changes and air velocities ([`StrandForces::add`],
/// [`StrandForces::add_velocity_change`], [`StrandForces::add_air_velocity`]) act on GPU strands in their
/// next step, as on the CPU (a velocity change as the force `m Δv / h` the implicit step sees it as, exact
/// but on a step that restarts BDF2; an air velocity added to the wind the GPU samples at the node); the
/// followers' own collisions on the CPU do not.
/// The style hold
/// ([`HairSettings::style_hold`]) is: the same springs inside the GPU's solve, towards each strand's
/// groomed pose carried with its head.
///
/// **Levels of detail** ([`crate::detail`]): a head at [`HairDetailLevel::Stepped`]`(n)` has its hair
/// stepped on every `n`-th fixed step (heads take turns) with a step as long, one Newton iteration more
/// for each fixed step it spans past the first, and carried with its head in between, its own motion kept
/// for its next step; a head at [`HairDetailLevel::Carried`] (out of sight, far away) has its hair carried
/// rigidly with it, not simulated ([`GpuHairCadence`]). The drawn hair is the GPU's state: at a coarser
/// level its motion relative to the head moves on at its steps, not in between (the CPU draws its own
/// keyframes there). A strand of a head carried since it was spawned waits on the CPU's side until its
/// head is first simulated.
///
/// **The GPU's state is the truth.** The hair is drawn from it where it is, so by default nothing is read
/// back but each strand's status every fourth step (16 bytes a strand, for the faults):
/// [`HairGpuSettings::read_back`] is [`GpuReadBackRate::OnDemand`], and [`StrandNodes`], [`StrandFrames`]
/// and the strands' rods keep their last read-back state. A game that reads them asks for them every n-th
/// step ([`GpuReadBackRate::EveryNthStep`]) or once ([`HairGpuSettings::read_back_now`]). They are read
/// back after every step whatever the setting where something on the CPU reads them every step: a head
/// drawn from its components (one with some strands on the CPU), followers placed on the CPU
/// ([`FollowerPlacement::Cpu`], [`PlaceFollowersOnCpu`]). Before the strands on the GPU change (added,
/// removed, handed back, the GPU turned off), their state is read back, and the new set is uploaded from
/// it. A read-back is asynchronous: the GPU copies the state into a reused buffer the CPU maps once the
/// GPU is done, and the first frame that finds it mapped writes the components. With pipelined rendering
/// that is two frames after the step (the render world runs a frame behind the main world, and the copy
/// is mapped by the next frame); [`HairGpuStatus::read_back_age`] says how many steps old the components
/// are.
///
/// **Faults** found on the GPU (a non-finite value, an edge strained past the bound, a system that does not
/// factorise) put the strand back in the pose it was uploaded in, on its root, at rest, there; they arrive
/// with the next read-back as [`StrandFault`] messages and log lines, as from the CPU's step, and the other
/// strands go on. A strand that fails three times, each read back within [`QUARANTINE_WINDOW`] of the one
/// before (the pose it is reset to fails again soon), is handed back to the CPU for good, in quarantine
/// there (held at its rest pose, retried later) as a strand of the CPU's that fails again soon after a
/// failure; the read-backs still on their way say nothing more.
/// A strand that cannot be put outside its colliders with its lengths kept keeps its
/// solved state for that step instead of failing ([`HairGpuStatus::contact_given_up`]).
///
/// [`FollowerPlacement::Cpu`]: crate::followers::FollowerPlacement::Cpu
/// [`PlaceFollowersOnCpu`]: crate::followers::PlaceFollowersOnCpu
#[derive(Debug, Clone)]
pub struct HairGpuPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: InternedScheduleLabel,
}

/// How the GPU steps the hair; change it at any time.
#[derive(Resource, Reflect, Debug, Clone, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairGpuSettings {
    /// Whether the GPU steps the strands it can. Off, every strand goes back to the CPU, from its last
    /// read-back state.
    pub enabled: bool,
    /// How often [`StrandNodes`], [`StrandFrames`] and the strands' rods are read back from the GPU (by
    /// default only on demand: see [`HairGpuPlugin`] for when they are read back anyway).
    pub read_back: GpuReadBackRate,
    /// Read back once after the next step whatever the rate (cleared when it is sent).
    pub read_back_now: bool,
}

impl Default for HairGpuSettings {
    fn default() -> Self {
        Self { enabled: true, read_back: GpuReadBackRate::OnDemand, read_back_now: false }
    }
}

/// How often the GPU's strands are read back into the ECS ([`HairGpuSettings::read_back`]).
#[derive(Reflect, Debug, Clone, Copy, PartialEq, Eq)]
pub enum GpuReadBackRate {
    /// After every step: the components are as current as the latency allows (3.2 MB per step for
    /// 2 000 strands × 32 edges, and their unpacking on the CPU).
    EveryStep,
    /// After every `n`-th step (`n` ≥ 1).
    EveryNthStep(u32),
    /// Only when [`HairGpuSettings::read_back_now`] asks (the default): the components keep their last
    /// read-back state.
    OnDemand,
}

/// What the GPU's stepping did, for a game's panel or log.
#[derive(Resource, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairGpuStatus {
    /// Strands the GPU steps now.
    pub strands: usize,
    /// Steps sent to the GPU.
    pub steps: u64,
    /// Read-backs written into the components.
    pub read_backs: u64,
    /// How many steps older than the last step sent the components' state was when last read back.
    pub read_back_age: Option<u64>,
    /// Strand steps that failed on the GPU (each also a [`StrandFault`]).
    pub faults: u64,
    /// Strands whose last read-back step could not put them outside their colliders with their lengths
    /// kept (deep inside a collider that holds the root): they stayed whole, inside, for that step.
    pub contact_given_up: usize,
    /// Nodes touching a collider after the last step read back (every fourth step at least): held by a
    /// contact spring or moved by the contact (the GPU's [`HairStatistics::contacts`]).
    pub contacts: usize,
    /// The largest edge strain of any strand after the last step read back, dimensionless (the GPU's
    /// [`HairStatistics::max_strain`]).
    pub max_strain: f32,
    /// The largest hair volume fraction at a point of the GPU's hair–hair grid in the last step read back
    /// (the GPU's [`HairStatistics::max_volume_fraction`]; 0 with the grid off).
    pub max_volume_fraction: f32,
    /// Mean Newton iterations per strand-step on the GPU between the last two read-backs (the GPU's
    /// [`HairStatistics::mean_newton_iterations`]: [`crate::gpu::GPU_NEWTON_ITERATIONS`] a fixed step,
    /// one more for each further fixed step a coarser level of detail's step spans; 0 before two
    /// read-backs of one upload).
    pub mean_newton_iterations: f64,
    /// The GPU's own time in the last step read back, from timestamp queries on the GPU: the strands'
    /// step and the hair–hair grid's passes (the GPU's [`HairStatistics::step_seconds`] and
    /// [`HairStatistics::volume_seconds`]); `None` where the device has no timestamp queries
    /// (`wgpu::Features::TIMESTAMP_QUERY`, which Bevy asks for where the adapter has it).
    pub timings: Option<GpuStepTimings>,
    /// Why the GPU does not step the hair, when it does not (no adapter, strands it rejected).
    pub error: Option<String>,
    /// Sets of strands uploaded to the GPU (at the start, and each time the strands it steps change).
    pub uploads: u32,
    /// How many times the step's pipelines were built (their shaders compiled, a hitch): once, at the
    /// first upload; never again for later uploads or changed settings.
    pub pipeline_builds: u32,
    /// The main world's time in the plugin's systems during the last update (read-backs written into the
    /// components, strands chosen, steps ordered), s.
    pub main_thread_seconds: f64,
    /// The render world's time in the plugin's system during the last frame it reported (uploads, steps
    /// recorded and submitted, read-backs unpacked), s.
    pub render_thread_seconds: f64,
    /// The part of [`HairGpuStatus::render_thread_seconds`] spent in wgpu's submissions and polls, s: the
    /// driver's (on a software adapter such as lavapipe, the GPU's work itself, which runs there).
    pub render_driver_seconds: f64,
}

/// One fixed step for the render world.
struct GpuStepOrder {
    params: StepParams,
    heads: Vec<GpuHeadStep>,
    /// The wind and its sources at the step's middle, sampled at every node by the step.
    air: AirSnapshot,
    /// The hair–hair grid's parameters, when it is on.
    volume: Option<GpuVolume>,
    /// The forces games added to strands stepped now ([`StrandForces`]): each strand's index and its
    /// nodes' forces, N.
    forces: Vec<(usize, Vec<DVec3>)>,
    /// The air velocities games added to strands stepped now ([`StrandForces::add_air_velocity`]): each
    /// strand's index and its nodes' air velocities, m/s.
    air_velocities: Vec<(usize, Vec<DVec3>)>,
    /// Whether to read the state back after it (otherwise the status alone, every `STATUS_STEPS` steps).
    read_back: bool,
    /// Its number among the steps sent.
    step: u64,
}

/// A new set of strands for the render world.
struct GpuUploadOrder {
    upload: GpuStrandUpload,
    strands: Arc<Vec<Entity>>,
}

/// What the main world sends and remembers of the strands on the GPU.
#[derive(Resource, Default)]
struct GpuStepQueue {
    upload: Option<GpuUploadOrder>,
    steps: Vec<GpuStepOrder>,
    /// The strands on the GPU, in the upload's order, and their heads.
    strands: Arc<Vec<Entity>>,
    heads: Vec<Entity>,
    /// Each strand on the GPU's index in the upload and its head's index.
    strand_index: EntityHashMap<(usize, usize)>,
    /// The step (its number among those sent) at which each head's hair was last stepped, not carried.
    heads_stepped: Vec<u64>,
    /// The strands' work counters summed, as last read back from this upload (`None` before).
    work: Option<GpuStrandWork>,
    /// Faults each strand has had on the GPU since the upload, as last read back.
    faults: Vec<u32>,
    /// Each strand's streak of faults: how many came each within [`QUARANTINE_WINDOW`] of the one before,
    /// and when the last was read back (s). Kept across uploads (another strand leaving the GPU uploads
    /// the set again, and a strand failing again and again must not start afresh each time).
    fault_streaks: EntityHashMap<(u32, f64)>,
    /// Strands that failed [`GPU_FAULT_STREAK`] times in a streak: stepped on the CPU from then on.
    handed_back: EntityHashSet,
    /// Bumped at each upload (the renderer lays its heads out again).
    generation: u32,
    /// Steps sent since the start.
    steps_sent: u64,
    since_read_back: u32,
    /// The step whose state the components hold, if any was read back.
    read_back_step: Option<u64>,
    /// Whether the set of strands must be looked over at the next step.
    dirty: bool,
    /// Whether this app cannot step on the GPU (no renderer, or a device that cannot run the step): then
    /// nothing is uploaded, whatever [`HairGpuSettings::enabled`] says.
    unavailable: bool,
    /// The most nodes a strand on this device's GPU may have ([`gpu_max_nodes`]; [`MAX_GPU_NODES`] until
    /// the device is known).
    max_nodes: usize,
    /// A new set of strands waits for the read-back of this step, so that the strands staying on the GPU
    /// are uploaded from their state there.
    upload_waits_for: Option<u64>,
    /// Whether something on the CPU reads the GPU strands' components every step (a head with strands on
    /// the CPU too is drawn from its components).
    components_read: bool,
    /// Per head of `heads`: whether it has strands on the CPU too (its hair meets on the CPU's grid).
    mixed_heads: Vec<bool>,
}

/// What the render world sends back.
enum GpuMessage {
    /// The strands' status after `step`, and their state if `full`.
    ReadBack {
        step: u64,
        strands: Arc<Vec<Entity>>,
        states: Box<GpuStrandStates>,
        full: bool,
    },
    Error(String),
    /// The step's pipelines were built.
    PipelinesBuilt,
    /// The render world's time in `step_on_gpu` this frame, and the part of it in wgpu's submissions and
    /// polls, s.
    RenderTime(f64, f64),
}

/// When the plugin's systems in the fixed schedule started this step.
#[derive(Resource, Default)]
struct GpuSystemsClock(Option<std::time::Instant>);

/// The main world's end of the read-backs.
#[derive(Resource)]
struct GpuReadBackReceiver(Mutex<Receiver<GpuMessage>>);

impl Plugin for HairGpuPlugin {
    fn build(&self, app: &mut App) {
        let (sender, receiver) = channel();
        app.register_type::<HairGpuSettings>()
            .register_type::<HairGpuStatus>()
            .init_resource::<HairGpuSettings>()
            .init_resource::<HairGpuStatus>()
            .insert_resource(GpuStepQueue { max_nodes: MAX_GPU_NODES, ..default() })
            .init_resource::<GpuStepCount>()
            .init_resource::<GpuSystemsClock>()
            .insert_resource(GpuReadBackReceiver(Mutex::new(receiver)))
            .add_systems(PreUpdate, apply_read_backs)
            // The strands are chosen once their roots are pinned and their rest shapes preloaded, before
            // anything adds to their loads: a strand goes to the GPU from the state it was preloaded in (the
            // CPU never steps it), and meets the GPU's wind and grid alone from its first step there (the
            // CPU's leave `SteppedElsewhere` strands out).
            .add_systems(
                self.schedule,
                (start_clock, choose_gpu_strands, stop_clock)
                    .chain()
                    .in_set(HairSystems::PinRoots)
                    .after(HairPinSystems::Preload),
            )
            .add_systems(
                self.schedule,
                (start_clock, order_gpu_step, stop_clock).chain().in_set(HairStepSystems::Integrate),
            );
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            fall_back_to_the_cpu(app, "there is no renderer (add Bevy's DefaultPlugins before HairPlugins)");
            return;
        };
        render_app
            .insert_resource(GpuHairRender { sender: Some(sender), ..default() })
            .add_systems(ExtractSchedule, extract_gpu_steps)
            .add_systems(
                Render,
                step_on_gpu.in_set(RenderSystems::PrepareResources).before(super::followers::prepare_gpu_followers),
            );
    }

    fn finish(&self, app: &mut App) {
        Self::check_device(app);
    }
}

impl HairGpuPlugin {
    /// Once the renderer has its device: falls back to the CPU if the device cannot run the step.
    fn check_device(app: &mut App) {
        let Some(render_app) = app.get_sub_app(RenderApp) else { return };
        let world = render_app.world();
        let (Some(device), Some(adapter)) =
            (world.get_resource::<RenderDevice>(), world.get_resource::<RenderAdapter>())
        else {
            fall_back_to_the_cpu(app, "the renderer has no device");
            return;
        };
        let limits = device.limits();
        if let Err(error) = gpu_step_support(&limits, &adapter.get_downlevel_capabilities()) {
            fall_back_to_the_cpu(app, &error.to_string());
        } else {
            app.world_mut().resource_mut::<GpuStepQueue>().max_nodes = gpu_max_nodes(&limits);
        }
    }
}

/// Turns the GPU's stepping off for good in this app, saying why once: the CPU steps every strand.
fn fall_back_to_the_cpu(app: &mut App, why: &str) {
    info!("HairGpuPlugin: {why}; the CPU steps the hair");
    app.world_mut().resource_mut::<GpuStepQueue>().unavailable = true;
    app.world_mut().resource_mut::<HairGpuStatus>().error = Some(why.to_string());
    app.world_mut().resource_mut::<HairGpuSettings>().enabled = false;
}

/// The head free strands (no [`StrandOf`]) are stepped in on the GPU: the world's frame (identity, at the
/// origin), with the shared colliders.
const FREE_STRANDS: Entity = Entity::PLACEHOLDER;

/// Starts the clock of the plugin's systems in the fixed schedule ([`HairGpuStatus::main_thread_seconds`]).
fn start_clock(mut clock: ResMut<GpuSystemsClock>) {
    clock.0 = Some(std::time::Instant::now());
}

/// Adds the fixed-schedule systems' time to [`HairGpuStatus::main_thread_seconds`].
fn stop_clock(mut clock: ResMut<GpuSystemsClock>, mut status: ResMut<HairGpuStatus>) {
    if let Some(started) = clock.0.take() {
        status.main_thread_seconds += started.elapsed().as_secs_f64();
    }
}

/// Looks the strands over when they may have changed (or some could not go at the last look: not preloaded
/// yet, folded, quarantined) and uploads the set the GPU can step: rooted or free, 3 to [`gpu_max_nodes`]
/// nodes, preloaded, not folded within [`GPU_FOLD_GAP`] of flat (unless already on the GPU), not
/// quarantined, not handed back after failing on the GPU. Marks them [`SteppedElsewhere`], and unmarks the
/// others.
#[allow(clippy::too_many_arguments)]
fn choose_gpu_strands(
    mut commands: Commands,
    settings: Res<HairGpuSettings>,
    hair_settings: Res<HairSettings>,
    mut queue: ResMut<GpuStepQueue>,
    mut status: ResMut<HairGpuStatus>,
    mut count: ResMut<GpuStepCount>,
    added: Query<(), Added<SimulatedStrand>>,
    mut removed: RemovedComponents<SimulatedStrand>,
    strands: Query<(Entity, &SimulatedStrand, Option<&StrandOf>, Has<SteppedElsewhere>)>,
    heads: Query<&HeadMotion, With<HairHead>>,
    head_strands: Query<&HeadStrands>,
    grid_hairs: Query<(Option<&RepresentedHairs>, Option<&HairFollowers>)>,
) {
    let queue = &mut *queue;
    queue.dirty |= settings.is_changed() || hair_settings.is_changed() || !added.is_empty();
    queue.dirty |= removed.read().count() > 0;
    if !queue.dirty {
        return;
    }
    queue.dirty = false;
    let mut chosen: Vec<(Entity, Entity, &SimulatedStrand)> = Vec::new();
    if settings.enabled && !queue.unavailable {
        for (entity, strand, strand_of, on_gpu) in &strands {
            let nodes = strand.rod().node_count();
            // Rooted, with its root edge clamped where the head holds it (a strand of a head carried since it
            // was spawned has not been pinned yet: it waits for its first step on the CPU's side); or free,
            // with no head and nothing held (stepped in the world's frame, `FREE_STRANDS`).
            let held = root_held(strand.rod());
            let (head, most, rooted) = match strand_of {
                Some(&StrandOf(head)) => (
                    head,
                    queue.max_nodes,
                    strand.root_anchor().is_some() && held == Some(true) && heads.contains(head),
                ),
                None => (
                    FREE_STRANDS,
                    max_free_gpu_nodes(queue.max_nodes),
                    strand.root_anchor().is_none() && held == Some(false),
                ),
            };
            if strand.preload_pending() || strand.rod().unusable_state().is_some() {
                // Looked over again until the preload is done, or until the CPU's step has put the
                // unusable state back in the rest pose (a fault resets a strand on the GPU to the state
                // it was uploaded in, so that must be one a step can start from).
                queue.dirty = true;
            } else if rooted && (3..=most).contains(&nodes) && !queue.handed_back.contains(&entity) {
                // A strand on the CPU that is folded (a tip pushed onto the face) or quarantined now is looked
                // over again at the next fixed step, until it can go. (One on the GPU stays there: a fold
                // that fails it there is the GPU's faults' to hand back.)
                let folded = !on_gpu && strand.rod().sharpest_turn().1 >= PI - GPU_FOLD_GAP;
                if folded || strand.is_quarantined() {
                    queue.dirty = true;
                } else {
                    chosen.push((head, entity, strand));
                }
            }
        }
    }
    chosen.sort_by_key(|&(head, entity, _)| (head, entity));
    let same = chosen.len() == queue.strands.len() && chosen.iter().zip(queue.strands.iter()).all(|(c, s)| c.1 == *s);
    if same {
        queue.upload_waits_for = None;
        return;
    }
    // The strands on the GPU now are uploaded again (or handed to the CPU) from their state there: read
    // back first, unless the GPU stopped answering.
    if !queue.strands.is_empty() {
        let asked = *queue.upload_waits_for.get_or_insert(queue.steps_sent + 1);
        let arrived = queue.read_back_step.is_some_and(|step| step >= asked);
        if !arrived && queue.steps_sent < asked + UPLOAD_WAIT_STEPS {
            queue.dirty = true;
            return;
        }
    }
    queue.upload_waits_for = None;
    let mut head_list: Vec<Entity> = chosen.iter().map(|c| c.0).collect();
    head_list.dedup();
    let poses: Vec<(DQuat, DVec3)> = head_list
        .iter()
        .map(|&head| {
            heads.get(head).map_or((DQuat::IDENTITY, DVec3::ZERO), |m| (m.current.rotation, m.current.translation))
        })
        .collect();
    let margin = f64::from(hair_settings.collision_margin);
    let groomed: Vec<Option<Vec<DVec3>>> = chosen.iter().map(|&(.., strand)| strand.groomed_in_head()).collect();
    // The hairs each strand stands for on the GPU's grid, and where each node lay in its groom (measured
    // head by head, whether or not the grid is on now, so that turning it on needs no new upload).
    let hairs: Vec<f64> = chosen
        .iter()
        .map(|&(_, entity, _)| {
            grid_hairs.get(entity).map_or(1.0, |(represented, followers)| represented_hairs(represented, followers))
        })
        .collect();
    // (Settings that are not valid now are reported by the CPU's check; the groom is measured on the
    // default cells then: on a cell that is not a length the grid is empty and would measure no packing.)
    let volume = if hair_settings.volume.validate().is_ok() { hair_settings.volume } else { default() };
    let volume_params = volume.params(1.0 / 60.0);
    let mut groomed_fractions: Vec<Vec<f64>> = Vec::with_capacity(chosen.len());
    let mut start = 0;
    for run in chosen.chunk_by(|a, b| a.0 == b.0) {
        let rods: Vec<_> =
            run.iter().zip(&hairs[start..]).map(|(&(.., strand), &hairs)| (strand.rod(), hairs)).collect();
        groomed_fractions.extend(groomed_fractions_of(&rods, &volume_params));
        start += run.len();
    }
    let inputs: Vec<GpuStrandInput> = chosen
        .iter()
        .zip(&groomed)
        .zip(hairs.iter().zip(&groomed_fractions))
        .map(|((&(head, _, strand), groomed), (&hairs, fractions))| GpuStrandInput {
            rod: strand.rod(),
            head: head_list.binary_search(&head).unwrap_or(0),
            thickness: strand.contact_thickness(margin),
            groomed: groomed.as_deref(),
            hairs,
            groomed_fractions: Some(fractions),
        })
        .collect();
    let upload = if chosen.is_empty() { None } else { Some(GpuStrandUpload::new(&inputs, &poses)) };
    // A head with strands left on the CPU is drawn from its components, and its hair meets on the CPU's
    // grid (`chosen` runs head by head, as `head_list`).
    queue.mixed_heads = chosen
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| head_strands.get(run[0].0).is_ok_and(|strands| strands.strands().len() > run.len()))
        .collect();
    // Free strands are drawn by no head's mesh: what a game reads of them are their components.
    queue.components_read = queue.mixed_heads.contains(&true) || head_list.contains(&FREE_STRANDS);
    let on_gpu: Vec<Entity> = match upload {
        Some(Ok(upload)) => {
            let entities: Arc<Vec<Entity>> = Arc::new(chosen.iter().map(|c| c.1).collect());
            info!("HairGpuPlugin: {} strands of {} heads stepped on the GPU", entities.len(), head_list.len());
            queue.upload = Some(GpuUploadOrder { upload, strands: entities.clone() });
            status.uploads += 1;
            queue.strands = entities;
            queue.work = None;
            status.error = None;
            queue.strands.to_vec()
        }
        Some(Err(error)) => {
            error!("HairGpuPlugin: the GPU cannot step this hair, the CPU does: {error}");
            status.error = Some(error.to_string());
            queue.strands = Arc::default();
            Vec::new()
        }
        None => {
            queue.strands = Arc::default();
            Vec::new()
        }
    };
    queue.strand_index = if on_gpu.is_empty() {
        EntityHashMap::default()
    } else {
        inputs.iter().zip(&chosen).enumerate().map(|(index, (input, chosen))| (chosen.1, (index, input.head))).collect()
    };
    queue.heads = if on_gpu.is_empty() { Vec::new() } else { head_list };
    queue.heads_stepped = vec![queue.steps_sent; queue.heads.len()];
    queue.faults = vec![0; on_gpu.len()];
    let strand_index = &queue.strand_index;
    queue.fault_streaks.retain(|entity, _| strand_index.contains_key(entity));
    queue.read_back_step = None;
    queue.steps.clear();
    queue.generation = queue.generation.wrapping_add(1);
    count.generation = queue.generation;
    status.strands = on_gpu.len();
    let on_gpu: EntityHashSet = on_gpu.into_iter().collect();
    for (entity, _, _, marked) in &strands {
        let wanted = on_gpu.contains(&entity);
        match (wanted, marked) {
            (true, false) => {
                commands.entity(entity).insert(SteppedElsewhere);
            }
            (false, true) => {
                commands.entity(entity).remove::<SteppedElsewhere>();
            }
            _ => {}
        }
    }
}

/// Sends this fixed step to the render world: each head's pose, its colliders the GPU meets, the air at it
/// and the style hold, and whether to read back after it.
#[allow(clippy::too_many_arguments)]
fn order_gpu_step(
    time: Res<Time>,
    checked: Res<CheckedSettings>,
    hair_settings: Res<HairSettings>,
    mut settings: ResMut<HairGpuSettings>,
    mut queue: ResMut<GpuStepQueue>,
    mut status: ResMut<HairGpuStatus>,
    mut count: ResMut<GpuStepCount>,
    heads: Query<(&HeadMotion, Option<&HairDetail>)>,
    colliders: StrandColliders,
    wind: Option<Res<HairWind>>,
    sources: Query<(&HairWindSource, &GlobalTransform)>,
    placement: Option<Res<FollowerPlacement>>,
    followers_on_cpu: Query<(), With<PlaceFollowersOnCpu>>,
    mut strand_forces: Query<(Entity, &mut StrandForces, &SimulatedStrand), With<SteppedElsewhere>>,
    (mut faults, mut commands, mut fault_log): (MessageWriter<StrandFault>, Commands, Local<FaultLog>),
) {
    let Some(params) = checked.params else { return };
    if queue.strands.is_empty() {
        return;
    }
    let queue = &mut *queue;
    let now = time.elapsed_secs_f64();
    // Valid whenever the checked parameters are (invalid settings hold the hair until fixed).
    let hold = hair_settings.style_hold;
    let mut steps = Vec::with_capacity(queue.heads.len());
    let step = queue.steps_sent + 1;
    for (index, &head) in queue.heads.iter().enumerate() {
        if head == FREE_STRANDS {
            // The world's frame, stepped every fixed step, the shared colliders (as on the CPU), no hold, and
            // off the GPU's grid (the CPU's has no free strands either).
            let met = colliders.of(None).to_vec();
            steps.push(GpuHeadStep { colliders: met, meets_hair_elsewhere: true, ..default() });
            continue;
        }
        let Ok((motion, detail)) = heads.get(head) else {
            steps.push(GpuHeadStep::default());
            continue;
        };
        // At a coarser level of detail, stepped every `n`-th fixed step (heads taking turns, so that every
        // fixed step steps about as many) with a step as long as the fixed steps since its last, at most
        // `n` (back from being carried, a step of one), carried with its own motion kept in between; out
        // of sight, carried.
        let cadence = match detail.map_or(HairDetailLevel::FULL, HairDetail::level) {
            HairDetailLevel::Stepped(interval) if (step + index as u64).is_multiple_of(u64::from(interval.max(1))) => {
                let since = step.saturating_sub(queue.heads_stepped[index]).clamp(1, u64::from(interval.max(1)));
                queue.heads_stepped[index] = step;
                GpuHairCadence::Step(since.min(u64::from(MAX_GPU_SPAN)) as u32)
            }
            HairDetailLevel::Stepped(_) => GpuHairCadence::Waiting,
            HairDetailLevel::Carried => GpuHairCadence::Carried,
        };
        let pose = motion.current;
        let met = colliders.of(Some(&StrandOf(head))).to_vec();
        steps.push(GpuHeadStep {
            rotation: pose.rotation,
            translation: pose.translation,
            colliders: met,
            air_velocity: DVec3::ZERO,
            cadence,
            hold_rate: f64::from(hold.rate),
            hold_reach: f64::from(hold.reach),
            meets_hair_elsewhere: queue.mixed_heads.get(index).copied().unwrap_or(false),
        });
    }
    // As `HairWindPlugin` blows it on the CPU (which reports an invalid wind or source): at the step's
    // middle, where each node was at its start.
    let mut air = AirSnapshot::default();
    if let Some(wind) = wind.as_ref().filter(|wind| wind.validate().is_ok()) {
        let valid = sources.iter().filter(|(source, transform)| {
            let affine = transform.affine();
            source.validate().is_ok() && affine.matrix3.is_finite() && affine.translation.is_finite()
        });
        wind.snapshot_into(now - 0.5 * time.delta_secs_f64(), valid, &mut air);
    }
    queue.since_read_back += 1;
    // Read every step by the CPU: followers placed there, or a head drawn from its components.
    let components_read = queue.components_read
        || placement.is_none_or(|placement| *placement == FollowerPlacement::Cpu)
        || !followers_on_cpu.is_empty();
    let upload_waits = queue.upload_waits_for.is_some_and(|step| step == queue.steps_sent + 1);
    let read_back = std::mem::take(&mut settings.bypass_change_detection().read_back_now)
        || components_read
        || upload_waits
        || match settings.read_back {
            GpuReadBackRate::EveryStep => true,
            GpuReadBackRate::EveryNthStep(n) => queue.since_read_back >= n.max(1),
            GpuReadBackRate::OnDemand => false,
        };
    if read_back {
        queue.since_read_back = 0;
    }
    queue.steps_sent += 1;
    status.steps = queue.steps_sent;
    status.read_back_age = queue.read_back_step.map(|step| queue.steps_sent - step);
    count.steps = queue.steps_sent;
    let volume = hair_settings.volume.enabled.then(|| GpuVolume {
        cell_size: f64::from(hair_settings.volume.cell_size),
        smoothing_rate: f64::from(hair_settings.volume.velocity_smoothing),
        target_fraction: f64::from(hair_settings.volume.target_volume_fraction),
        stiffness: f64::from(hair_settings.volume.stiffness),
        keep_groomed: hair_settings.volume.keep_groomed_volume,
    });
    // The forces games added (`StrandForces`), for the strands stepped now; all are used up by this step,
    // as on the CPU. A force that is not finite is reported as the CPU reports it, and left out (the
    // strand steps on without it, where the CPU skips its step).
    let (mut forces, mut air_velocities) = (Vec::new(), Vec::new());
    for (entity, mut strand_forces, strand) in &mut strand_forces {
        let loads = (strand_forces.active_forces(), strand_forces.active_velocity_changes());
        let stepped = queue
            .strand_index
            .get(&entity)
            .filter(|&&(_, head)| matches!(steps.get(head).map(|step| step.cadence), Some(GpuHairCadence::Step(_))));
        // The air velocities a game added (the CPU's wind leaves GPU strands out): with the wind the GPU
        // samples at each node. One that is not finite is reported as the CPU reports it, and the strand's
        // are left out.
        let air = strand_forces.active_air_velocities();
        if let (Some(air), Some(&(index, _))) = (air, stepped) {
            match air.iter().position(|velocity| !velocity.is_finite()) {
                None => air_velocities.push((index, air.to_vec())),
                Some(node) => {
                    let error = StepError::InvalidInput(RodError::NonFiniteAirVelocity { node, velocity: air[node] });
                    if fault_log.admit(true, false) {
                        warn!(
                            "hair strand {entity} failed a step on the GPU, its air velocities were left out: {error}"
                        );
                    }
                    status.faults += 1;
                    let fault = StrandFault { strand: entity, error };
                    commands.trigger(fault.clone());
                    faults.write(fault);
                }
            }
        }
        if loads != (None, None)
            && let Some(&(index, head)) = stepped
            && let Some(GpuHairCadence::Step(span)) = steps.get(head).map(|step| step.cadence)
        {
            // A velocity change `Δv` at the step's start is, to the implicit step, the force `m Δv / h` (the
            // inertia `M (x − x̂ − h v̂)/h²` with `v̂` moved by `Δv`), `h` the scheme's step: exact but for a
            // step that restarts BDF2 (after a change of the step's length), which takes `h = Δt`.
            let dt = params.dt * f64::from(span);
            let h = if params.integrator == Integrator::Bdf2 { 2.0 / 3.0 * dt } else { dt };
            let masses = strand.rod().masses();
            let mut total = loads.0.map_or_else(|| vec![DVec3::ZERO; masses.len()], <[DVec3]>::to_vec);
            if let Some(changes) = loads.1 {
                for ((force, change), mass) in total.iter_mut().zip(changes).zip(masses) {
                    *force += mass * *change / h;
                }
            }
            let all = total.len() == masses.len();
            match total.iter().position(|force| !force.is_finite()) {
                None if all => forces.push((index, total)),
                None => {}
                Some(node) => {
                    let error = StepError::InvalidInput(match (loads.0, loads.1) {
                        (Some(forces), _) if !forces[node].is_finite() => {
                            RodError::NonFiniteForce { node, force: forces[node] }
                        }
                        (_, Some(changes)) => RodError::NonFiniteVelocityChange { node, change: changes[node] },
                        _ => RodError::NonFiniteForce { node, force: total[node] },
                    });
                    if fault_log.admit(true, false) {
                        warn!("hair strand {entity} failed a step on the GPU, its forces were left out: {error}");
                    }
                    status.faults += 1;
                    let fault = StrandFault { strand: entity, error };
                    commands.trigger(fault.clone());
                    faults.write(fault);
                }
            }
        }
        strand_forces.clear();
    }
    fault_log.summarise(now);
    queue.steps.push(GpuStepOrder {
        params,
        heads: steps,
        air,
        volume,
        forces,
        air_velocities,
        read_back,
        step: queue.steps_sent,
    });
}

/// Writes the read-backs that arrived into the strands' rods and components, and reports the faults the
/// GPU found.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn apply_read_backs(
    receiver: Res<GpuReadBackReceiver>,
    mut queue: ResMut<GpuStepQueue>,
    mut status: ResMut<HairGpuStatus>,
    mut statistics: ResMut<HairStatistics>,
    checked: Res<CheckedSettings>,
    mut strands: Query<(&mut SimulatedStrand, &mut StrandNodes, &mut StrandFrames), With<SteppedElsewhere>>,
    mut faults: MessageWriter<StrandFault>,
    mut commands: Commands,
    time: Res<Time>,
    mut fault_log: Local<FaultLog>,
) {
    let started = std::time::Instant::now();
    let Ok(receiver) = receiver.0.lock() else { return };
    let now = time.elapsed_secs_f64();
    let queue = &mut *queue;
    for message in receiver.try_iter() {
        let (step, entities, states, full) = match message {
            GpuMessage::ReadBack { step, strands, states, full } => (step, strands, states, full),
            GpuMessage::PipelinesBuilt => {
                status.pipeline_builds += 1;
                continue;
            }
            GpuMessage::RenderTime(seconds, driver) => {
                status.render_thread_seconds = seconds;
                status.render_driver_seconds = driver;
                continue;
            }
            GpuMessage::Error(error) => {
                if status.error.as_ref() != Some(&error) {
                    error!("HairGpuPlugin: {error}");
                    status.error = Some(error);
                }
                continue;
            }
        };
        // A read-back of an earlier upload is stale.
        if !Arc::ptr_eq(&entities, &queue.strands) {
            continue;
        }
        let mut states = *states;
        for (index, &entity) in entities.iter().enumerate() {
            // The state, where it was read back (the status alone, 16 bytes a strand, touches no component).
            if full && !queue.handed_back.contains(&entity) {
                let Ok((mut strand, mut nodes, mut frames)) = strands.get_mut(entity) else { continue };
                if let Some(snapshot) = states.take_snapshot(index)
                    && strand.rod_mut().restore(&snapshot).is_ok()
                {
                    // The GPU's state as it is: the GPU carries a coarser level's hair with its head itself,
                    // where the CPU would draw its own keyframes.
                    write_strand_data(&mut strand, &mut nodes, &mut frames);
                }
            }
            let report = states.status[index];
            // A strand already handed back is leaving the GPU: read-backs of steps sent before the new upload
            // say nothing the CPU's quarantine has not taken over.
            if report.faults <= queue.faults[index] || queue.handed_back.contains(&entity) {
                queue.faults[index] = queue.faults[index].max(report.faults);
                continue;
            }
            let Ok((mut strand, mut nodes, mut frames)) = strands.get_mut(entity) else { continue };
            queue.faults[index] = report.faults;
            let (streak, last) = queue.fault_streaks.entry(entity).or_insert((0, 0.0));
            *streak = if *streak > 0 && now - *last <= QUARANTINE_WINDOW { *streak + 1 } else { 1 };
            *last = now;
            let streak = *streak;
            status.faults += 1;
            statistics.faults += 1;
            let bound = checked.params.as_ref().map_or(0.0, StepParams::strain_bound);
            let error = step_error(&report, bound);
            let handed_back = streak >= GPU_FAULT_STREAK;
            let quarantine = if handed_back {
                // It failed again at once after each reset: the CPU takes it in quarantine, as it does a strand
                // of its own that fails again soon after a failure.
                queue.handed_back.insert(entity);
                queue.dirty = true;
                let seconds = strand.take_back_in_quarantine(error.clone(), now);
                write_strand_data(&mut strand, &mut nodes, &mut frames);
                seconds
            } else {
                None
            };
            if fault_log.admit(streak == 1 || handed_back, quarantine.is_some()) {
                let consequence = match quarantine {
                    Some(seconds) => format!(
                        "it failed again soon after each reset on the GPU, is stepped on the CPU from now on, and is quarantined there for {seconds} s"
                    ),
                    None => "it was reset to its rest pose".to_string(),
                };
                warn!("hair strand {entity} failed a step on the GPU, {consequence}: {error}");
            }
            let fault = StrandFault { strand: entity, error };
            commands.trigger(fault.clone());
            faults.write(fault);
        }
        fault_log.summarise(now);
        status.contact_given_up = states.status.iter().filter(|report| report.contact_given_up).count();
        status.contacts = states.status.iter().map(|report| report.contacts as usize).sum();
        status.max_strain = states.status.iter().map(|report| report.max_strain).fold(0.0, f32::max);
        status.max_volume_fraction = states.max_volume_fraction;
        status.timings = states.timings;
        if let Some(earlier) = queue.work.replace(states.work) {
            let work = states.work.since(&earlier);
            if work.steps > 0 {
                status.mean_newton_iterations = work.per_step()[0];
            }
        }
        if full {
            status.read_backs += 1;
            queue.read_back_step = Some(step);
            status.read_back_age = Some(queue.steps_sent.saturating_sub(step));
        }
    }
    // The first of the plugin's systems in an update: the clock starts again here.
    status.main_thread_seconds = started.elapsed().as_secs_f64();
}

/// Steps between two read-backs of the strands' status when their state is not read back: their faults
/// arrive at most this many steps late (and a few frames, as every read-back).
const STATUS_STEPS: u64 = 4;

/// Steps a new set of strands waits for the read-back of the old one before it is uploaded anyway (from
/// the components as they are): a GPU that stopped answering does not hold the hair's changes forever.
const UPLOAD_WAIT_STEPS: u64 = 30;

/// Faults on the GPU, each read back within [`QUARANTINE_WINDOW`] of the one before, after which a strand is
/// handed back to the CPU for good: the pose it is reset to on the GPU fails again soon, and the CPU's fault
/// handling (quarantined, retried) takes over.
const GPU_FAULT_STREAK: u32 = 3;

/// The CPU's name for the last fault the GPU found on a strand (`strain_bound`: the step's, without the
/// single-precision floor the GPU adds). The strain of an over-strained step is known when that step was
/// the last one read back; otherwise it was at least the GPU's limit.
fn step_error(report: &GpuStrandStatus, strain_bound: f64) -> StepError {
    let limit = strain_bound + SINGLE_PRECISION_STRAIN;
    match report.last_fault {
        Some(GpuFault::NonFinite { node }) => StepError::NonFinite { node: node as usize },
        Some(GpuFault::OverStrained { edge }) => {
            let strain = if report.fault.is_some() { f64::from(report.max_strain) } else { limit };
            StepError::OverStrained { edge: edge as usize, strain, limit }
        }
        Some(GpuFault::NotPositiveDefinite) | None => StepError::NotPositiveDefinite { dof: 0 },
    }
}

/// The render world's side: the solver on Bevy's device and what the main world sent.
#[derive(Resource, Default)]
pub(super) struct GpuHairRender {
    pub(super) solver: Option<GpuStrandSolver>,
    /// The step's pipelines on Bevy's device, built at the first upload and kept for every later one.
    pipelines: Option<Arc<GpuStepPipelines>>,
    /// The strands in the solver's order, and each one's index by entity.
    strands: Arc<Vec<Entity>>,
    pub(super) index: EntityHashMap<u32>,
    /// Each strand's head, as uploaded.
    pub(super) strand_heads: Vec<usize>,
    /// Bumped at each upload.
    pub(super) generation: u32,
    upload: Option<GpuUploadOrder>,
    orders: Vec<GpuStepOrder>,
    /// Read-backs on their way: the step, the strands, the read-back and whether it has their state.
    read_backs: Vec<(u64, Arc<Vec<Entity>>, GpuReadBack, bool)>,
    sender: Option<Sender<GpuMessage>>,
}

/// Moves the main world's upload and steps into the render world.
fn extract_gpu_steps(mut main_world: ResMut<MainWorld>, mut render: ResMut<GpuHairRender>) {
    let Some(mut queue) = main_world.get_resource_mut::<GpuStepQueue>() else { return };
    if let Some(upload) = queue.upload.take() {
        render.upload = Some(upload);
        render.orders.clear();
    }
    let steps = std::mem::take(&mut queue.steps);
    render.orders.extend(steps);
}

/// Uploads a new set of strands, steps them by every fixed step the main world sent, asks for a
/// read-back after the last step that wants one, and sends the read-backs that arrived.
fn step_on_gpu(mut render: ResMut<GpuHairRender>, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
    let started = std::time::Instant::now();
    let render = &mut *render;
    let (device, queue): (&wgpu::Device, &wgpu::Queue) = (device.wgpu_device(), &queue);
    let send = |sender: &Option<Sender<GpuMessage>>, message| {
        if let Some(sender) = sender {
            let _ = sender.send(message);
        }
    };
    if let Some(GpuUploadOrder { upload, strands }) = render.upload.take() {
        if render.pipelines.is_none() {
            render.pipelines = Some(GpuStepPipelines::new(device));
            send(&render.sender, GpuMessage::PipelinesBuilt);
        }
        let pipelines = render.pipelines.as_ref().expect("built above");
        // (The main world chose strands the device takes, `GpuStepQueue::max_nodes`.)
        render.solver = GpuStrandSolver::from_upload(device, pipelines, upload)
            .map_err(|error| send(&render.sender, GpuMessage::Error(gpu_step_error(&error))))
            .ok();
        render.index = strands.iter().enumerate().map(|(index, &entity)| (entity, index as u32)).collect();
        render.strand_heads = render.solver.as_ref().map(|s| s.strand_heads().to_vec()).unwrap_or_default();
        render.strands = strands;
        render.generation = render.generation.wrapping_add(1);
        render.read_backs.clear();
    }
    let stepped = !render.orders.is_empty();
    let mut driver = 0.0;
    if let Some(solver) = render.solver.as_mut() {
        // The state after the last step that asks for it; else the status after the frame's last step
        // that is a multiple of `STATUS_STEPS`.
        let (mut read_back, mut status_only) = (None, None);
        for order in render.orders.drain(..) {
            if let Err(error) = solver.set_air(&order.air) {
                send(&render.sender, GpuMessage::Error(gpu_step_error(&error)));
            }
            if let Err(error) = solver.set_volume(order.volume) {
                send(&render.sender, GpuMessage::Error(gpu_step_error(&error)));
            }
            for (strand, forces) in &order.forces {
                if let Err(error) = solver.add_forces(queue, *strand, forces) {
                    send(&render.sender, GpuMessage::Error(gpu_step_error(&error)));
                }
            }
            for (strand, velocities) in &order.air_velocities {
                if let Err(error) = solver.add_air_velocities(queue, *strand, velocities) {
                    send(&render.sender, GpuMessage::Error(gpu_step_error(&error)));
                }
            }
            match solver.step(device, queue, &order.params, &order.heads) {
                Ok(_) if order.read_back => read_back = Some(order.step),
                Ok(_) if order.step % STATUS_STEPS == 0 => status_only = Some(order.step),
                Ok(_) => {}
                Err(error) => send(&render.sender, GpuMessage::Error(gpu_step_error(&error))),
            }
        }
        // The read-back's copies are recorded in microseconds; the rest of the call is its submission.
        let requested = std::time::Instant::now();
        if let Some(step) = read_back {
            let pending = solver.request_read_back(device, queue, true);
            render.read_backs.push((step, render.strands.clone(), pending, true));
        } else if let Some(step) = status_only {
            let pending = solver.request_read_back(device, queue, false);
            render.read_backs.push((step, render.strands.clone(), pending, false));
        }
        driver += requested.elapsed().as_secs_f64() + solver.take_driver_seconds();
    } else {
        render.orders.clear();
    }
    if !render.read_backs.is_empty() {
        let polled = std::time::Instant::now();
        let _ = device.poll(wgpu::PollType::Poll);
        driver += polled.elapsed().as_secs_f64();
        let sender = &render.sender;
        render.read_backs.retain_mut(|(step, strands, read_back, full)| {
            if let Some(states) = read_back.try_take() {
                let message = GpuMessage::ReadBack {
                    step: *step,
                    strands: strands.clone(),
                    states: Box::new(states),
                    full: *full,
                };
                send(sender, message);
            }
            !read_back.is_finished()
        });
    }
    if stepped {
        send(&render.sender, GpuMessage::RenderTime(started.elapsed().as_secs_f64(), driver));
    }
}

/// The message for a step the GPU could not take.
fn gpu_step_error(error: &GpuStepError) -> String {
    format!("a GPU step was not taken: {error}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gpu_faults_are_named_as_the_cpu_names_them() {
        let bound = 1e-3;
        let limit = bound + SINGLE_PRECISION_STRAIN;
        let report = |fault, last_fault, max_strain| GpuStrandStatus {
            max_strain,
            fault,
            last_fault,
            faults: 1,
            ..Default::default()
        };
        let over = Some(GpuFault::OverStrained { edge: 7 });
        // Read back on the failed step: its strain.
        match step_error(&report(over, over, 0.25), bound) {
            StepError::OverStrained { edge: 7, strain, limit: l } => {
                assert_eq!((strain, l), (f64::from(0.25_f32), limit));
            }
            other => panic!("{other:?}"),
        }
        // Read back later: at least the limit (the strain read is the current one, not the failing one).
        match step_error(&report(None, over, 1e-6), bound) {
            StepError::OverStrained { edge: 7, strain, .. } => assert_eq!(strain, limit),
            other => panic!("{other:?}"),
        }
        let nan = Some(GpuFault::NonFinite { node: 3 });
        assert_eq!(step_error(&report(None, nan, 0.0), bound), StepError::NonFinite { node: 3 });
        let indefinite = Some(GpuFault::NotPositiveDefinite);
        assert_eq!(step_error(&report(indefinite, indefinite, 0.0), bound), StepError::NotPositiveDefinite { dof: 0 });
    }

    #[test]
    fn a_strand_failing_again_soon_on_the_gpu_is_handed_back_to_the_cpu_in_quarantine() {
        use bevy::ecs::system::RunSystemOnce;
        // The main world's half alone (no renderer): read-backs arrive through a channel the test holds.
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, crate::HairPlugins::default()));
        let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
        let strand = app
            .world_mut()
            .spawn((crate::simulation::HairStrand::straight(Vec3::Y * 0.1, Vec3::X, 0.2, 8), StrandOf(head)))
            .id();
        app.insert_resource(bevy::time::TimeUpdateStrategy::FixedTimesteps(1));
        app.update();
        app.update();
        assert!(app.world().get::<SimulatedStrand>(strand).is_some(), "the strand is built");
        app.world_mut().entity_mut(strand).insert(SteppedElsewhere);
        let (sender, receiver) = channel();
        app.insert_resource(GpuReadBackReceiver(Mutex::new(receiver)));
        let strands = Arc::new(vec![strand]);
        {
            let mut queue = app.world_mut().resource_mut::<GpuStepQueue>();
            queue.strands = strands.clone();
            queue.faults = vec![0];
        }
        let indefinite = Some(GpuFault::NotPositiveDefinite);
        let read_back = |app: &mut App, strands: &Arc<Vec<Entity>>, step: u64, faults: u32| {
            let report = GpuStrandStatus { fault: indefinite, last_fault: indefinite, faults, ..default() };
            // No positions: nothing to restore, only the report.
            let states = GpuStrandStates { status: vec![report], ..default() };
            sender
                .send(GpuMessage::ReadBack { step, strands: strands.clone(), states: Box::new(states), full: false })
                .unwrap();
            app.world_mut().run_system_once(apply_read_backs).unwrap();
            let messages = app.world_mut().resource_mut::<Messages<StrandFault>>().drain().count();
            (messages, app.world().resource::<GpuStepQueue>().handed_back.contains(&strand))
        };
        let wait = |app: &mut App, seconds: f64| {
            app.world_mut().resource_mut::<Time>().advance_by(std::time::Duration::from_secs_f64(seconds));
        };
        // Failing, then not (the same count); failing again after the window: a new streak.
        assert_eq!(read_back(&mut app, &strands, 1, 1), (1, false));
        assert_eq!(read_back(&mut app, &strands, 2, 1), (0, false));
        wait(&mut app, 1.5 * QUARANTINE_WINDOW);
        assert_eq!(read_back(&mut app, &strands, 3, 2), (1, false));
        // The second within the window, then a read-back without a fault (which does not end the streak).
        wait(&mut app, 0.5 * QUARANTINE_WINDOW);
        assert_eq!(read_back(&mut app, &strands, 4, 3), (1, false));
        wait(&mut app, 0.5 * QUARANTINE_WINDOW);
        assert_eq!(read_back(&mut app, &strands, 5, 3), (0, false));
        // The set uploaded again (another strand left the GPU, say): the GPU counts its faults from 0, and
        // the streak goes on.
        let strands = Arc::new(vec![strand]);
        {
            let mut queue = app.world_mut().resource_mut::<GpuStepQueue>();
            queue.strands = strands.clone();
            queue.faults = vec![0];
        }
        // The third, within the window of the second (two faults in one read-back count as one): handed
        // back (`choose_gpu_strands` leaves it out from now on).
        wait(&mut app, 0.5 * QUARANTINE_WINDOW);
        assert_eq!(read_back(&mut app, &strands, 6, 2), (1, true));
        assert_eq!(app.world().resource::<HairGpuStatus>().faults, 4);
        // Held in quarantine on the CPU; the read-backs of steps sent before it left the GPU say nothing more.
        let health = app.world().get::<SimulatedStrand>(strand).unwrap().health();
        assert!(health.quarantined_until.is_some_and(|until| until > 0.0), "{health:?}");
        assert_eq!(read_back(&mut app, &strands, 7, 3), (0, true));
        assert_eq!(read_back(&mut app, &strands, 8, 4), (0, true));
        assert_eq!(app.world().resource::<HairGpuStatus>().faults, 4);
    }
}
