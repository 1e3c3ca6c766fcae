//! The systems of one simulation step: pin roots to heads, step every strand in parallel, report
//! faults, write the drawn poses.

use bevy::math::DVec3;
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::utils::Parallel;

use arrayvec::ArrayVec;
use bevy::ecs::query::QueryItem;
use bevy::tasks::ComputeTaskPool;

use crate::parallel::run_in_parallel;
use crate::rod::{
    Anchor, Contacts, LANES, LockstepStrand, LockstepWorkspace, MovingCollider, Rod, StepError, StepLoads, StepParams,
    StepReport, held_reach,
};
use crate::simulation::style_hold::style_anchors;
use crate::simulation::{
    HairPause, HairSettings, HairStatistics, HairStyleHold, HeadMotion, PRELOAD_SUPPORT_DISTANCE, PackedStrandPose,
    SimulatedStrand, StepOutcome, SteppedElsewhere, StrandColliders, StrandFault, StrandForces, StrandFrames,
    StrandNodes, StrandOf, StrandRestShape, longer_step_params,
};

/// How many steps the current rendered frame has simulated, to bound the catch-up after a hitch.
#[derive(Resource, Debug, Default)]
pub(crate) struct StepBudget {
    steps_this_frame: u32,
    stepping: bool,
}

/// Starts a new rendered frame's step count.
pub(crate) fn reset_step_budget(mut budget: ResMut<StepBudget>) {
    budget.steps_this_frame = 0;
}

/// [`HairSettings`] as checked at this fixed step, for every system of the step.
#[derive(Resource, Debug, Clone)]
pub(crate) struct CheckedSettings {
    /// The step's parameters while the settings are valid; `None` while they are not: the hair is then
    /// held, drawn carried with its heads, its clocks stopped (see [`check_settings`]).
    pub(crate) params: Option<StepParams>,
    /// The collision margin of the last valid settings, m (the current one while they are valid).
    pub(crate) collision_margin: f64,
    /// The style hold of the last valid settings.
    pub(crate) style_hold: HairStyleHold,
}

impl Default for CheckedSettings {
    fn default() -> Self {
        let settings = HairSettings::default();
        Self { params: None, collision_margin: f64::from(settings.collision_margin), style_hold: settings.style_hold }
    }
}

/// Checks [`HairSettings`] for this fixed step, once for every system that reads them. Invalid settings
/// are reported once (an error line and [`HairStatistics::settings_error`]); until they are fixed the
/// hair is held: not stepped, drawn carried rigidly with its heads (roots on the head however it moves),
/// its clocks stopped, and it resumes with the heads' motion, as hair comes back from being carried.
pub(crate) fn check_settings(
    time: Res<Time>,
    settings: Res<HairSettings>,
    mut checked: ResMut<CheckedSettings>,
    mut statistics: ResMut<HairStatistics>,
) {
    match settings.validated(time.delta_secs_f64()) {
        Ok((params, margin)) => {
            checked.params = Some(params);
            checked.collision_margin = margin;
            checked.style_hold = settings.style_hold;
            statistics.settings_error = None;
        }
        Err(error) => {
            checked.params = None;
            let message = error.to_string();
            if statistics.settings_error.as_ref() != Some(&message) {
                error!("HairSettings rejected, hair is held on its heads until they are fixed: {message}");
                statistics.settings_error = Some(message);
            }
        }
    }
}

/// Decides whether this fixed step simulates hair: not while paused (unless a single step is pending), and
/// at most [`HairSettings::max_steps_per_frame`] per frame.
pub(crate) fn open_step(
    settings: Res<HairSettings>,
    mut pause: ResMut<HairPause>,
    mut budget: ResMut<StepBudget>,
    mut statistics: ResMut<HairStatistics>,
) {
    if pause.paused {
        budget.stepping = pause.pending_steps > 0;
        pause.pending_steps = pause.pending_steps.saturating_sub(1);
        return;
    }
    budget.stepping = budget.steps_this_frame < settings.max_steps_per_frame;
    if budget.stepping {
        budget.steps_this_frame += 1;
    } else {
        statistics.skipped_steps += 1;
    }
}

/// Run condition of the step's system sets: whether [`open_step`] allowed this step.
pub(crate) fn stepping(budget: Res<StepBudget>) -> bool {
    budget.stepping
}

/// Gives strands that follow [`HairSettings::default_material`] its new value when it changes (an
/// invalid one is reported by [`check_settings`], which holds the hair until it is fixed).
pub(crate) fn apply_default_material(settings: Res<HairSettings>, mut strands: Query<(Entity, &mut SimulatedStrand)>) {
    if !settings.is_changed() || settings.default_material.validate().is_err() {
        return;
    }
    for (entity, mut strand) in &mut strands {
        if let Err(error) = strand.follow_default_material(&settings.default_material) {
            error!("HairSettings::default_material rejected for strand {entity}: {error}");
            return;
        }
    }
}

/// Runs the pending gravity preloads (strands just built with [`HairStrand::gravity_preload`], or asked
/// with [`SimulatedStrand::preload_gravity`]): from each strand's shape now, the gravity of
/// [`HairSettings`] and the colliders of its head, the nodes within [`PRELOAD_SUPPORT_DISTANCE`] of one
/// resting on it. Writes the new rest shape into [`StrandRestShape`]. While the settings are invalid
/// (reported once by [`check_settings`]), or a collider of the strand's head is still being made (a mesh
/// collider loading or baking), the preloads wait, and the strands with them.
///
/// [`HairStrand::gravity_preload`]: crate::simulation::HairStrand::gravity_preload
pub(crate) fn preload_rest_shapes(
    checked: Res<CheckedSettings>,
    mut strands: Query<(Entity, &mut SimulatedStrand, &mut StrandRestShape, Option<&StrandOf>)>,
    colliders: StrandColliders,
) {
    let Some(params) = checked.params else {
        return;
    };
    let (gravity, margin) = (params.gravity, checked.collision_margin);
    strands.par_iter_mut().for_each(|(entity, mut strand, mut rest_shape, strand_of)| {
        // Hair rests on its colliders: the preload waits for any still being made.
        if !strand.preload_pending() || colliders.waiting(strand_of) {
            return;
        }
        let supports = preload_supports(strand.rod(), colliders.of(strand_of), strand.contact_thickness(margin));
        match strand.run_pending_preload(gravity, &supports) {
            Ok(_) => rest_shape.update(strand.rod()),
            Err(error) => error!("hair strand {entity}: gravity preload failed, its rest shape is unchanged: {error}"),
        }
    });
}

/// For each node of `rod`, the outward normal of the first of `colliders` it rests on (within `thickness`
/// plus [`PRELOAD_SUPPORT_DISTANCE`] of it), if any. As in the step, a collider that holds the root inside
/// it leaves the nodes near the root (as far along the strand as [`held_reach`] says) free of it: hair
/// grows out of it.
fn preload_supports(rod: &Rod, colliders: &[MovingCollider], thickness: f64) -> Vec<Option<DVec3>> {
    let reach = thickness + f64::from(PRELOAD_SUPPORT_DISTANCE);
    let held: Vec<f64> = colliders
        .iter()
        .map(|collider| {
            let root = collider.end.to_local(rod.positions()[0]);
            held_reach(&collider.shape.inflated(thickness), root).unwrap_or(0.0)
        })
        .collect();
    let mut arc = 0.0;
    rod.positions()
        .iter()
        .enumerate()
        .map(|(node, &position)| {
            arc += if node > 0 { rod.rest_lengths()[node - 1] } else { 0.0 };
            colliders.iter().zip(&held).find_map(|(collider, &held)| {
                let local = collider.end.to_local(position);
                (arc > held && collider.shape.inflated(reach).contains(local))
                    .then(|| collider.end.rotation * collider.shape.closest_surface_point(local).normal)
            })
        })
        .collect()
}

/// Clamps every strand's root edge to its anchor on its head, carrying the strand along when the head
/// teleported (a root that cannot follow is reported as the strand's fault at its step). A strand not
/// stepped at this fixed step (a coarser level of detail, or every strand while the settings are
/// invalid) follows at its next step.
pub(crate) fn pin_roots(
    time: Res<Time>,
    checked: Res<CheckedSettings>,
    mut strands: Query<(&mut SimulatedStrand, &StrandOf)>,
    heads: Query<&HeadMotion>,
) {
    let dt = time.delta_secs_f64();
    let held = checked.params.is_none();
    strands.par_iter_mut().for_each(|(mut strand, &StrandOf(head))| {
        if let Ok(motion) = heads.get(head) {
            strand.follow_head(motion, dt, held);
        }
    });
}

/// What one thread keeps from step to step: the solver's scratch memory, which stays in that core's
/// cache for every strand it steps, the style hold's springs of the strands it is stepping, and the
/// tally of those strands.
#[derive(Default)]
pub(crate) struct StepThread {
    workspace: LockstepWorkspace,
    tally: StepTally,
    /// The style hold's springs of each strand of the batch being stepped ([`style_anchors`]).
    anchors: [Vec<Anchor>; LANES],
}

/// What the strands stepped by one thread measured.
#[derive(Default)]
struct StepTally {
    strands: usize,
    nodes: usize,
    newton_iterations: u64,
    contacts: usize,
    max_strain: f64,
    /// Poses packed, and the time the timed ones of them took, s (see [`pack_pose`]).
    poses: u32,
    timed_pose_seconds: f64,
    quarantined: usize,
    /// Strands not stepped at this fixed step (a coarser level of detail).
    unstepped: usize,
    faults: Vec<Fault>,
}

/// A failed strand step, as the thread that stepped it saw it.
struct Fault {
    message: StrandFault,
    first_of_episode: bool,
    quarantine: Option<f64>,
}

/// Fault lines logged one by one per [`FAULT_LOG_PERIOD`]; the rest are summed up in one line.
const FAULT_LINES_PER_PERIOD: u32 = 4;

/// The period of the fault log's summary, s of simulated time.
const FAULT_LOG_PERIOD: f64 = 1.0;

/// Keeps the log readable while strands fail: each strand's first fault of an episode is logged on its
/// own (at most [`FAULT_LINES_PER_PERIOD`] per period), everything else is counted and summed up in one
/// line per [`FAULT_LOG_PERIOD`] at most.
#[derive(Default)]
pub(crate) struct FaultLog {
    period_start: f64,
    lines: u32,
    unlogged_faults: u64,
    quarantines: u64,
}

impl FaultLog {
    fn record(&mut self, now: f64, fault: &Fault) {
        if !self.admit(fault.first_of_episode, fault.quarantine.is_some()) {
            return;
        }
        let StrandFault { strand, error } = &fault.message;
        let consequence = match (error, fault.quarantine) {
            (_, Some(seconds)) => format!("it is quarantined for {seconds} s"),
            (StepError::InvalidInput(_), None) => "its step was skipped".to_string(),
            _ => "it was reset to its rest pose".to_string(),
        };
        warn!("hair strand {strand} failed a step, {consequence}: {error}");
        self.summarise(now);
    }

    /// Counts a fault; true when it gets a line of its own (the first of its strand's episode, and lines
    /// are left in this period).
    pub(crate) fn admit(&mut self, first_of_episode: bool, quarantined: bool) -> bool {
        if quarantined {
            self.quarantines += 1;
        }
        if !(first_of_episode && self.lines < FAULT_LINES_PER_PERIOD) {
            self.unlogged_faults += 1;
            return false;
        }
        self.lines += 1;
        true
    }

    /// Logs the period's summary when the period is over and something went unlogged.
    pub(crate) fn summarise(&mut self, now: f64) {
        if now - self.period_start < FAULT_LOG_PERIOD {
            return;
        }
        if self.unlogged_faults > 0 {
            warn!(
                "hair: {} more strand faults in the last {:.1} s ({} quarantines); StrandFault messages have each one",
                self.unlogged_faults,
                now - self.period_start,
                self.quarantines,
            );
        }
        *self = FaultLog { period_start: now, ..default() };
    }
}

/// Every how many poses a thread packs it times one for [`HairStatistics::pose_seconds`] (a clock read
/// costs half a packing).
const POSE_TIMING_INTERVAL: u32 = 8;

/// Packs a strand's pose for the GPU from its components just written (in this core's cache), with its
/// contact thickness (m) and whether it snapped; times every [`POSE_TIMING_INTERVAL`]-th.
fn pack_pose(
    pose: &mut PackedStrandPose,
    nodes: &StrandNodes,
    frames: &StrandFrames,
    (thickness, snapped): (f64, bool),
    tally: &mut StepTally,
) {
    tally.poses += 1;
    if tally.poses % POSE_TIMING_INTERVAL != 1 {
        pose.write(nodes, frames, thickness as f32, snapped);
        return;
    }
    // The clock read twice first: what one read costs is taken off the time the packing took.
    let (before, started) = (Instant::now(), Instant::now());
    pose.write(nodes, frames, thickness as f32, snapped);
    let (taken, clock) = (started.elapsed(), started - before);
    tally.timed_pose_seconds += taken.as_secs_f64() - clock.as_secs_f64();
}

/// Tasks of strands per compute thread in [`step_strands`].
const STEP_TASKS_PER_THREAD: usize = 64;

/// What [`step_strands`] reads and writes of each strand.
type StepItem = (
    Entity,
    &'static mut SimulatedStrand,
    &'static mut StrandForces,
    &'static mut StrandNodes,
    &'static mut StrandFrames,
    Option<&'static mut PackedStrandPose>,
    Option<&'static StrandOf>,
);

/// What every strand's step shares in [`step_strands`].
struct StepContext<'a> {
    params: Option<StepParams>,
    collision_margin: f64,
    style_hold: HairStyleHold,
    now: f64,
    colliders: &'a StrandColliders<'a, 'a>,
}

/// Steps every strand in parallel, against the colliders of its head (the shared ones for a strand
/// with no head), four strands of one node count at a time in SIMD lanes ([`LockstepWorkspace`]); a
/// strand whose step fails is reset or quarantined (see [`SimulatedStrand`]) and reported with a
/// [`StrandFault`] message (and in the log, see [`FaultLog`]), and the others go on. A strand whose
/// head is at a coarser level of detail is stepped only on its turns, by as many fixed steps as have
/// passed, and drawn carried with its head in between (see [`crate::detail`]); while the settings are
/// invalid every strand is drawn so (see [`check_settings`]). A strand not stepped whose state was
/// written from outside has it checked before it is drawn. Strands [`SteppedElsewhere`] are left alone.
#[allow(clippy::too_many_arguments)]
pub(crate) fn step_strands(
    time: Res<Time>,
    checked: Res<CheckedSettings>,
    mut statistics: ResMut<HairStatistics>,
    strands: Query<StepItem, Without<SteppedElsewhere>>,
    elsewhere: Query<(), With<SteppedElsewhere>>,
    colliders: StrandColliders,
    mut fault_messages: MessageWriter<StrandFault>,
    mut commands: Commands,
    mut threads: Local<Parallel<StepThread>>,
    mut fault_log: Local<FaultLog>,
    mut order: Local<Vec<(StepOrder, Entity)>>,
) {
    let valid = checked.params;
    let started = Instant::now();
    let now = time.elapsed_secs_f64();
    // Strands stepped now first, those of one node count and one step length side by side, so that they
    // share lockstep batches (at a coarser level of detail a head's strands take their turns by entity,
    // and neighbours in entity order are due on different fixed steps); the order changes no strand's
    // result (a strand in a batch ends bit for bit where it would alone).
    order.clear();
    order.extend(strands.iter().map(|(entity, strand, ..)| {
        let detail = &strand.detail;
        ((!detail.due, strand.rod().node_count(), detail.elapsed), entity)
    }));
    order.sort_unstable();
    // Small tasks: strands cost unequal amounts (contacts, and levels of detail that step some heads now
    // and others not), and big tasks leave one thread waiting on another.
    let thread_count = ComputeTaskPool::try_get().map_or(1, |pool| pool.thread_num()).max(1);
    let per_task = order.len().div_ceil(thread_count * STEP_TASKS_PER_THREAD).next_multiple_of(LANES).max(LANES);
    let context = StepContext {
        params: valid,
        collision_margin: checked.collision_margin,
        style_hold: checked.style_hold,
        now,
        colliders: &colliders,
    };
    let (strands, threads_ref) = (&strands, &*threads);
    run_in_parallel(thread_count, order.chunks(per_task), |task| {
        threads_ref.scope(|thread| {
            for batch in task.chunks(LANES) {
                // SAFETY: each entity is in `order` once (a query yields each of its entities once), and
                // each chunk of `order` goes to one task: no two items alive at once are of one entity.
                let mut items: ArrayVec<_, LANES> =
                    batch.iter().filter_map(|&(_, entity)| unsafe { strands.get_unchecked(entity) }.ok()).collect();
                step_batch(&context, &mut items, thread);
            }
        });
    });

    let (mut strands_stepped, mut nodes_stepped, mut newton_iterations, mut contacts, mut max_strain) =
        (0, 0, 0, 0, 0.0_f64);
    let (mut quarantined, mut unstepped, mut pose_seconds) = (0, 0, 0.0);
    for StepThread { tally, .. } in threads.iter_mut() {
        unstepped += tally.unstepped;
        strands_stepped += tally.strands;
        nodes_stepped += tally.nodes;
        newton_iterations += tally.newton_iterations;
        contacts += tally.contacts;
        max_strain = max_strain.max(tally.max_strain);
        quarantined += tally.quarantined;
        // The timed poses are the 1st, 9th, 17th, … of each thread.
        let timed = tally.poses.div_ceil(POSE_TIMING_INTERVAL);
        if timed > 0 {
            pose_seconds += tally.timed_pose_seconds * f64::from(tally.poses) / f64::from(timed);
        }
        for fault in tally.faults.drain(..) {
            fault_log.record(now, &fault);
            statistics.faults += 1;
            commands.trigger(fault.message.clone());
            fault_messages.write(fault.message);
        }
        // Start the next step from zero, keeping the fault list's memory.
        *tally = StepTally { faults: std::mem::take(&mut tally.faults), ..default() };
    }
    fault_log.summarise(now);
    statistics.quarantined = quarantined;
    statistics.unstepped_strands = unstepped;
    statistics.strands_elsewhere = elsewhere.iter().len();
    statistics.step_seconds = started.elapsed().as_secs_f64();
    statistics.pose_seconds = pose_seconds.max(0.0);
    // Held by invalid settings, the hair was not simulated.
    statistics.steps += u64::from(valid.is_some());
    statistics.strands = strands_stepped;
    statistics.nodes = nodes_stepped;
    statistics.max_strain = max_strain;
    statistics.contacts = contacts;
    statistics.mean_newton_iterations =
        if strands_stepped > 0 { newton_iterations as f64 / strands_stepped as f64 } else { 0.0 };
}

/// Where a strand goes in the step's order: not due after due, then by node count and step length (fixed
/// steps since its last step), so that strands that can share a lockstep batch are side by side.
type StepOrder = (bool, usize, u32);

/// A strand of a lockstep batch, as the query gives it.
type BatchItem<'w, 's> = QueryItem<'w, 's, StepItem>;

/// Steps up to [`LANES`] strands: those due to take a step of one length (one fixed step, or several at a
/// coarser level of detail) together in lockstep, any other alone, and records each in the thread's tally.
fn step_batch(context: &StepContext, items: &mut [BatchItem], thread: &mut StepThread) {
    let StepThread { workspace, tally, anchors } = thread;
    let contacts_of = |strand: &SimulatedStrand, strand_of: Option<&StrandOf>| Contacts {
        colliders: context.colliders.of(strand_of),
        thickness: strand.contact_thickness(context.collision_margin),
    };
    // What each strand does: not stepped (drawn carried with its head), done before its rod is
    // stepped, or its rod stepped by some fixed steps.
    let mut steps = [0; LANES];
    let mut starts = [None; LANES];
    let mut outcomes: [Option<StepOutcome>; LANES] = Default::default();
    for (index, (entity, strand, forces, nodes, frames, pose, _)) in items.iter_mut().enumerate() {
        let stepped = context.params.is_some() && strand.detail.due && !strand.preload_pending();
        if !stepped {
            // A coarser level of detail, invalid settings, or a preload waiting for a collider: not
            // stepped now, drawn carried with its head, once its state is known to be drawable.
            forces.clear();
            if let Some(StepOutcome::Faulted { error, first_of_episode, quarantine }) =
                strand.check_unstepped(context.now)
            {
                let message = StrandFault { strand: *entity, error };
                tally.faults.push(Fault { message, first_of_episode, quarantine });
            }
            write_strand(strand, None, (nodes, frames, pose.as_deref_mut()), context.collision_margin, tally);
            tally.unstepped += 1;
            tally.quarantined += usize::from(strand.is_quarantined());
            continue;
        }
        steps[index] = strand.detail.take_elapsed();
        match strand.begin_advance(context.now) {
            Err(outcome) => outcomes[index] = Some(outcome),
            Ok(start) => match strand.take_pin_error() {
                Some(error) => {
                    let result = Err(StepError::InvalidInput(error));
                    outcomes[index] = Some(strand.finish_advance(context.now, start, result));
                }
                None => starts[index] = Some(start),
            },
        }
    }
    let Some(params) = context.params else {
        return;
    };
    // The style hold's springs, written here while each strand's memory is near (a quarantined strand
    // retried is not held).
    let mut held = [false; LANES];
    for (index, (_, strand, ..)) in items.iter().enumerate() {
        if starts[index].is_some() && !strand.is_quarantined() {
            let dt = params.dt * f64::from(steps[index]);
            held[index] = style_anchors(&context.style_hold, strand, dt, &mut anchors[index]);
        }
    }
    // The rods: those of one step in lockstep, the others alone with their longer step.
    let mut results: [Option<Result<StepReport, StepError>>; LANES] = Default::default();
    {
        let mut together = ArrayVec::<_, LANES>::new();
        let mut lanes = ArrayVec::<usize, LANES>::new();
        let mut together_length = None;
        for (index, (_, strand, forces, .., strand_of)) in items.iter_mut().enumerate() {
            if starts[index].is_none() {
                continue;
            }
            let contacts = contacts_of(strand, *strand_of);
            let loads = StepLoads { anchors: held[index].then_some(&anchors[index][..]), ..forces.loads() };
            let strand = LockstepStrand { rod: strand.rod_to_step(), loads, contacts };
            // Strands of the batch's first step length in lockstep, any other alone (the order puts
            // strands of one step length together, so a batch rarely mixes them).
            let length = *together_length.get_or_insert(steps[index]);
            if steps[index] == length {
                together.push(strand);
                lanes.push(index);
            } else {
                let longer = longer_step_params(&params, steps[index]);
                results[index] = workspace.step(&longer, &mut [strand])[0].take();
            }
        }
        let batch_params = match together_length {
            Some(length) if length > 1 => longer_step_params(&params, length),
            _ => params,
        };
        for (index, result) in lanes.into_iter().zip(workspace.step(&batch_params, &mut together)) {
            results[index] = result;
        }
    }
    for (index, (entity, strand, forces, nodes, frames, pose, _)) in items.iter_mut().enumerate() {
        let outcome = match (starts[index], results[index].take()) {
            (Some(start), Some(result)) => strand.finish_advance(context.now, start, result),
            _ => match outcomes[index].take() {
                Some(outcome) => outcome,
                None => continue,
            },
        };
        forces.clear();
        let parts = (&mut **nodes, &mut **frames, pose.as_deref_mut());
        write_strand(strand, Some(steps[index]), parts, context.collision_margin, tally);
        tally.strands += 1;
        tally.nodes += strand.rod().node_count();
        tally.quarantined += usize::from(strand.is_quarantined());
        match outcome {
            StepOutcome::Stepped(report) => {
                tally.newton_iterations += u64::from(report.newton_iterations);
                tally.contacts += report.contacts as usize;
                tally.max_strain = tally.max_strain.max(report.max_strain);
            }
            StepOutcome::Held => {}
            StepOutcome::Faulted { error, first_of_episode, quarantine } => tally.faults.push(Fault {
                message: StrandFault { strand: *entity, error },
                first_of_episode,
                quarantine,
            }),
        }
    }
}

/// Writes a strand's components and packed pose (while the strand is in this core's cache), after
/// `stepped` fixed steps or none, with its contact thickness for `collision_margin` (m).
fn write_strand(
    strand: &mut SimulatedStrand,
    stepped: Option<u32>,
    (nodes, frames, pose): (&mut StrandNodes, &mut StrandFrames, Option<&mut PackedStrandPose>),
    collision_margin: f64,
    tally: &mut StepTally,
) {
    let snapped = strand.write_components(stepped, nodes, frames);
    if let Some(pose) = pose {
        let thickness = strand.contact_thickness(collision_margin);
        pack_pose(pose, nodes, frames, (thickness, snapped), tally);
    }
}
