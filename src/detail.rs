//! Levels of detail: crowds of heads at a game's budget. Each head's hair is stepped at a rate chosen from
//! its distance to the nearest camera and whether any camera sees it; hair far away is stepped every
//! second or fourth step, hair out of sight or very far is carried with its head without being simulated.
//!
//! **Scheme.**
//! - A head at level [`HairDetailLevel::Stepped`]`(n)` has its strands stepped on every `n`-th fixed step,
//!   with a step of `n · dt`: the same implicit scheme, stable at any step, at `1/n` of the cost. Its
//!   strands take their turns on different fixed steps (a quarter of them on each, at every fourth step),
//!   so every fixed step costs about the same: no spike every `n`-th step.
//! - Between two of its steps the hair is **drawn from its head's frame**: the nodes are kept in the
//!   head's (rigid) local space and carried with the head every fixed step, so the roots stay on the
//!   head however fast it moves. The drawn shape is interpolated between the shapes of the strand's last
//!   steps (keyframes), at a drawn clock that runs `n − 1` fixed steps behind: never extrapolated, and
//!   smooth relative to the head.
//! - At [`HairDetailLevel::Carried`] a head's hair is not simulated at all: it keeps its shape in its head's
//!   frame and follows the head rigidly. When the head comes back, its strands are carried rigidly to
//!   where the head is and simulated from there.
//! - **No pops.** When the level changes, the drawn clock runs at most [`DRAWN_CLOCK_RATE_CHANGE`] (25 %)
//!   faster or slower than the fixed steps until it has its new lag, so the drawn hair never moves more
//!   than 25 % faster than the hair itself; the simulation never jumps either (a longer or shorter step
//!   starts from where the hair is).
//! - **What is lost at a coarser level:** motion faster than the longer step resolves (the implicit step
//!   damps it, as at a lower frame rate; a longer step also takes one Newton iteration and projects the
//!   edge lengths to 1e-6 instead of 1e-8, which damps a little more), the hair–hair interaction of
//!   [`crate::volume`] (only heads at full detail take part in their grid), and up to `n − 1` fixed
//!   steps of delay in the hair's motion relative to its head. Going coarser, the hair's motion relative
//!   to its head slows by a quarter for `4 (n − 1)` fixed steps while the drawn clock falls behind, the
//!   strand meanwhile stepped every fixed step (so that its drawn shape always has a keyframe ahead).
//! - **Coming back from being carried** the hair starts with its head's motion (each node the velocity
//!   of the head's rigid motion over the last fixed step), not with the velocities it had when it was
//!   set aside.
//!
//! **Choice.** [`HairDetailSettings`] say at which distances the levels change (with a margin against
//! flickering between two levels); a head's [`HairDetail`] shows the level in use and can fix one.
//! Distances are to the nearest active [`Camera`]; a head is out of sight when no active camera's
//! [`Frustum`] reaches a ball around it as large as its hair. Without any camera (a server, a test),
//! every head is at full detail.

use bevy::camera::primitives::{Frustum, Sphere};
use bevy::math::DVec3;
use bevy::prelude::*;

use crate::head::{HeadMotion, HeadStrands, ScaledPose, StrandOf};
use crate::rod::{Rod, RodError, StepParams};
use crate::settings::HairStatistics;
use crate::strand::SimulatedStrand;
use crate::strand_data::{StrandFrames, StrandNodes, copy_converted, snap_previous};

/// How a head's hair is simulated.
#[derive(Reflect, Debug, Clone, Copy, PartialEq, Eq)]
#[reflect(Debug, Clone, PartialEq)]
pub enum HairDetailLevel {
    /// Stepped on every `n`-th fixed step, with a step `n` times as long (1: every step, full detail).
    Stepped(u32),
    /// Not simulated: carried rigidly with its head, in the shape it last had.
    Carried,
}

impl HairDetailLevel {
    /// Every fixed step: full detail.
    pub const FULL: Self = Self::Stepped(1);

    /// Fixed steps per simulation step (`None` when carried).
    pub fn step_interval(self) -> Option<u32> {
        match self {
            Self::Stepped(interval) => Some(interval.max(1)),
            Self::Carried => None,
        }
    }

    /// How coarse the level is, for comparing levels: the step interval, carried coarsest.
    fn coarseness(self) -> u32 {
        self.step_interval().unwrap_or(u32::MAX)
    }
}

impl Default for HairDetailLevel {
    fn default() -> Self {
        Self::FULL
    }
}

/// How many heads are at each level of detail, counted at every fixed step that simulates hair
/// ([`crate::settings::HairStatistics::heads_by_detail`]).
#[derive(Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct HeadsByDetail {
    /// Stepped every fixed step.
    pub full: usize,
    /// Stepped every second fixed step.
    pub every_second_step: usize,
    /// Stepped every third fixed step or more rarely.
    pub rarer: usize,
    /// Carried, not simulated.
    pub carried: usize,
}

impl HeadsByDetail {
    /// Counts one more head at `level`.
    pub fn add(&mut self, level: HairDetailLevel) {
        let count = match level.step_interval() {
            Some(1) => &mut self.full,
            Some(2) => &mut self.every_second_step,
            Some(_) => &mut self.rarer,
            None => &mut self.carried,
        };
        *count += 1;
    }
}

/// Put on heads by the plugin ([`crate::head::HairHead`] requires it): the level of detail its hair is
/// simulated at, and what it was chosen from. Set [`HairDetail::fixed`] to choose the level yourself.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct HairDetail {
    /// A level to keep whatever the distance (`None`, the default: chosen from [`HairDetailSettings`]).
    pub fixed: Option<HairDetailLevel>,
    level: HairDetailLevel,
    distance: f32,
    on_screen: bool,
    reach: f32,
}

impl HairDetail {
    /// A head whose hair is always simulated at `level`.
    pub fn fixed(level: HairDetailLevel) -> Self {
        Self { fixed: Some(level), ..default() }
    }

    /// The level in use at the last fixed step.
    pub fn level(&self) -> HairDetailLevel {
        self.level
    }

    /// Distance from the head's origin to the nearest active camera at the last fixed step, m (infinite
    /// without one).
    pub fn distance(&self) -> f32 {
        self.distance
    }

    /// Whether an active camera's frustum reached the head's hair at the last fixed step (true without
    /// cameras, or with cameras that have no [`Frustum`]).
    pub fn on_screen(&self) -> bool {
        self.on_screen
    }

    /// Radius of a ball around the head's origin that holds its hair, m: what the sight test uses
    /// (measured every 16 fixed steps).
    pub fn reach(&self) -> f32 {
        self.reach
    }
}

/// When hair is simulated at a coarser level of detail (see the [module documentation](self)). Read at
/// every fixed step; invalid values are reported once and every head is simulated at full detail until
/// they are fixed.
#[derive(Resource, Reflect, Debug, Clone, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairDetailSettings {
    /// Whether levels are chosen from distance and sight. Off: every head at full detail, except those
    /// with a [`HairDetail::fixed`] level. Default on.
    pub enabled: bool,
    /// Heads within this distance of a camera are stepped every fixed step, m. Beyond, the step interval
    /// doubles with each doubling of the distance (every second step up to twice this distance, every
    /// fourth up to four times, …), up to [`HairDetailSettings::max_step_interval`]. Default 3.
    pub full_detail_distance: f32,
    /// The longest step interval, fixed steps (1 to 16). Default 4 (at 60 Hz, hair stepped at 15 Hz).
    pub max_step_interval: u32,
    /// Heads farther than this from every camera are carried, not simulated, m (infinite: never).
    /// Default 30.
    pub carried_distance: f32,
    /// The level of heads no camera sees. Default [`HairDetailLevel::Carried`]: hair out of sight costs
    /// nothing; a shadow cast by it keeps its last shape.
    pub off_screen: HairDetailLevel,
    /// Relative margin against flickering between two levels, 0 to 0.5: a head moves to a coarser level
    /// only once it is this much farther than the level's distance, and back only once it is this much
    /// nearer. Default 0.1.
    pub hysteresis: f32,
}

impl Default for HairDetailSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            full_detail_distance: 3.0,
            max_step_interval: 4,
            carried_distance: 30.0,
            off_screen: HairDetailLevel::Carried,
            hysteresis: 0.1,
        }
    }
}

/// The longest step interval [`HairDetailSettings::max_step_interval`] may ask for.
pub const MAX_STEP_INTERVAL: u32 = 16;

impl HairDetailSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), RodError> {
        let invalid = |parameter: &'static str, value: f64, requirement: &'static str| {
            Err(RodError::InvalidStepParameter { parameter, value, requirement })
        };
        let interval_ok = |interval: u32| (1..=MAX_STEP_INTERVAL).contains(&interval);
        if !(self.full_detail_distance.is_finite() && self.full_detail_distance > 0.0) {
            return invalid("full_detail_distance", self.full_detail_distance.into(), "positive and finite");
        }
        if !interval_ok(self.max_step_interval) {
            return invalid("max_step_interval", self.max_step_interval.into(), "from 1 to 16");
        }
        if self.carried_distance.is_nan() || self.carried_distance <= 0.0 {
            return invalid("carried_distance", self.carried_distance.into(), "positive (infinite: never)");
        }
        if let HairDetailLevel::Stepped(interval) = self.off_screen
            && !interval_ok(interval)
        {
            return invalid("off_screen", interval.into(), "a step interval from 1 to 16");
        }
        if !(0.0..=0.5).contains(&self.hysteresis) {
            return invalid("hysteresis", self.hysteresis.into(), "from 0 to 0.5");
        }
        Ok(())
    }

    /// The level for a head `distance` m from the nearest camera, seen or not, with no hysteresis.
    pub fn level_at(&self, distance: f32, on_screen: bool) -> HairDetailLevel {
        if !on_screen {
            return self.off_screen;
        }
        if distance > self.carried_distance {
            return HairDetailLevel::Carried;
        }
        let mut interval = 1;
        while interval < self.max_step_interval && distance > self.full_detail_distance * interval as f32 {
            interval *= 2;
        }
        HairDetailLevel::Stepped(interval.min(self.max_step_interval))
    }

    /// The level for a head at `distance`, seen or not, that is at `current`: the level of the distance,
    /// unless the head is within [`HairDetailSettings::hysteresis`] of the distance where it would change.
    pub fn next_level(&self, current: HairDetailLevel, distance: f32, on_screen: bool) -> HairDetailLevel {
        let coarser = self.level_at(distance * (1.0 - self.hysteresis), on_screen);
        if coarser.coarseness() > current.coarseness() {
            return coarser;
        }
        let finer = self.level_at(distance * (1.0 + self.hysteresis), on_screen);
        if finer.coarseness() < current.coarseness() {
            return finer;
        }
        current
    }
}

/// Levels of detail for crowds (see the [module documentation](self)); part of [`crate::HairPlugin`].
/// Without it every head is simulated at full detail.
#[derive(Debug, Clone)]
pub struct HairDetailPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: bevy::ecs::schedule::InternedScheduleLabel,
}

impl Plugin for HairDetailPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairDetail>()
            .register_type::<HairDetailSettings>()
            .init_resource::<HairDetailSettings>()
            .add_systems(
                self.schedule,
                choose_hair_detail
                    .in_set(crate::HairSystems::PinRoots)
                    .after(crate::head::track_heads)
                    .before(crate::step::pin_roots),
            );
    }
}

/// Fixed steps between two measurements of a head's reach ([`HairDetail::reach`]).
const REACH_PERIOD: u64 = 16;

/// What [`choose_hair_detail`] keeps from step to step: the fixed steps counted, the last error
/// reported, and scratch lists reused so that no step allocates.
#[derive(Default)]
pub(crate) struct DetailMemory {
    fixed_step: u64,
    reported: Option<String>,
    viewers: Vec<Viewer>,
}

/// What one camera says about distance and sight.
pub(crate) struct Viewer {
    position: Vec3,
    frustum: Option<Frustum>,
}

/// Chooses every head's level for this fixed step, and tells each of its strands whether it is stepped
/// in this one.
pub(crate) fn choose_hair_detail(
    settings: Res<HairDetailSettings>,
    cameras: Query<(&Camera, &GlobalTransform, Option<&Frustum>)>,
    mut heads: Query<HeadItem>,
    mut strands: Query<(Entity, &mut SimulatedStrand, &StrandOf)>,
    mut statistics: ResMut<HairStatistics>,
    mut memory: Local<DetailMemory>,
) {
    let DetailMemory { fixed_step, reported, viewers } = &mut *memory;
    *fixed_step += 1;
    let valid = match settings.validate() {
        Ok(()) => {
            *reported = None;
            true
        }
        Err(error) => {
            let message = error.to_string();
            if reported.as_ref() != Some(&message) {
                error!("HairDetailSettings rejected, every head is at full detail until they are fixed: {message}");
                *reported = Some(message);
            }
            false
        }
    };
    viewers.clear();
    let active = cameras.iter().filter(|(camera, ..)| camera.is_active);
    viewers.extend(
        active.map(|(_, transform, frustum)| Viewer { position: transform.translation(), frustum: frustum.copied() }),
    );
    let mut heads_by_detail = HeadsByDetail::default();
    for (_, motion, head_strands, mut detail) in &mut heads {
        let centre = motion.translation();
        // A ball around the head that holds its hair: the farthest root plus that strand's length
        // (measured again every `REACH_PERIOD` fixed steps: it changes only with the hair's rest shape).
        let reach = if detail.reach > 0.0 && !(*fixed_step).is_multiple_of(REACH_PERIOD) {
            detail.reach
        } else {
            let reach_of = |(_, strand, _): (Entity, &SimulatedStrand, &StrandOf)| {
                let rod = strand.rod();
                rod.positions()[0].as_vec3().distance(centre) + rod.rest_lengths().iter().sum::<f64>() as f32
            };
            head_strands
                .strands()
                .iter()
                .filter_map(|&entity| strands.get(entity).ok())
                .map(reach_of)
                .fold(0.0, f32::max)
        };
        let distance = viewers.iter().map(|viewer| viewer.position.distance(centre)).fold(f32::INFINITY, f32::min);
        let ball = Sphere { center: centre.into(), radius: reach };
        let on_screen = viewers.is_empty()
            || viewers.iter().any(|viewer| viewer.frustum.is_none_or(|frustum| frustum.intersects_sphere(&ball, true)));
        let level = match detail.fixed {
            Some(level) => level,
            None if !valid || !settings.enabled || viewers.is_empty() => HairDetailLevel::FULL,
            None => settings.next_level(detail.level, distance, on_screen),
        };
        let new = HairDetail { level, distance, on_screen, reach, ..*detail };
        detail.set_if_neq(new);
        heads_by_detail.add(level);
    }
    statistics.heads_by_detail = heads_by_detail;
    let heads = heads.as_readonly();
    let step = *fixed_step;
    strands.par_iter_mut().for_each(|(entity, mut strand, &StrandOf(head))| {
        let level = heads.get(head).map_or(HairDetailLevel::FULL, |(.., detail)| detail.level);
        // Each strand takes its own turn (by entity): a head's strands are spread evenly over the fixed
        // steps of its interval, so that every fixed step costs about as much.
        let due = level
            .step_interval()
            .is_some_and(|interval| step.wrapping_add(entity.to_bits()).is_multiple_of(u64::from(interval)));
        let due = due || strand.detail.falling_behind(level);
        strand.set_detail(level, due);
    });
}

/// What [`choose_hair_detail`] reads and writes of a head.
type HeadItem = (Entity, &'static HeadMotion, &'static HeadStrands, &'static mut HairDetail);

/// Projection accuracy of a step longer than one fixed step (see [`StepParams::strain_tolerance`]): at a
/// coarser level of detail the edge lengths are kept to 1e-6 instead of 1e-8, which saves projection
/// iterations on the larger motion of a longer step.
pub const LONGER_STEP_STRAIN_TOLERANCE: f64 = 1e-6;

/// The parameters of a step of `steps` fixed steps (more than one, at a coarser level of detail): `steps`
/// times as long, one Newton iteration (the longer step's larger motion would otherwise take more,
/// costing what the coarser level saves), the edge lengths kept to [`LONGER_STEP_STRAIN_TOLERANCE`].
pub(crate) fn longer_step_params(params: &StepParams, steps: u32) -> StepParams {
    StepParams {
        dt: params.dt * f64::from(steps),
        max_newton_iterations: 1,
        strain_tolerance: params.strain_tolerance.max(LONGER_STEP_STRAIN_TOLERANCE),
        ..*params
    }
}

/// How close to its lag, in fixed steps, the drawn clock counts as there.
const LAG_TOLERANCE: f64 = 1e-6;

/// How much faster or slower than the simulation the drawn hair's clock may run while it catches up with
/// a finer level of detail or falls back to a coarser one (see [`DrawnShape`]): 0.25, so a lag of three
/// fixed steps is made up in twelve, the hair meanwhile moving at most 25 % faster than it does.
pub const DRAWN_CLOCK_RATE_CHANGE: f64 = 0.25;

/// A strand's part in the levels of detail: its level at this fixed step, whether it is stepped in it, and
/// its drawn shape while that is kept apart from the simulated one.
#[derive(Debug, Clone)]
pub(crate) struct StrandDetail {
    /// The level at this fixed step.
    pub(crate) level: HairDetailLevel,
    /// Whether the strand is stepped at this fixed step.
    pub(crate) due: bool,
    /// Fixed steps since the rod's state: the length of its next step, in fixed steps.
    pub(crate) elapsed: u32,
    /// Whether the head teleported since the rod last followed it: the rod is carried rigidly to its
    /// head before its next step.
    pub(crate) teleported: bool,
    /// Whether the strand comes back from being carried: carried rigidly to its head and given its
    /// head's motion before its next step.
    pub(crate) resumed: bool,
    /// The head's pose at this fixed step.
    pub(crate) head: ScaledPose,
    /// The drawn shape while it is kept apart from the simulated one (below full detail, and until the
    /// drawn shape has caught up after coming back to it).
    drawn: Option<Box<DrawnShape>>,
}

impl Default for StrandDetail {
    fn default() -> Self {
        Self {
            level: HairDetailLevel::FULL,
            due: true,
            elapsed: 0,
            teleported: false,
            resumed: false,
            head: default(),
            drawn: None,
        }
    }
}

/// A strand's shape after one of its steps, in its head's rigid local space (`R⁻¹ (x − t)`: strands do
/// not scale with their heads).
#[derive(Debug, Clone, Default)]
struct Keyframe {
    /// The fixed step it was taken at (the strand's own count).
    time: f64,
    nodes: Vec<Vec3>,
}

/// The drawn hair of a strand below full detail: the shapes of its last steps (keyframes, head-local) and
/// a drawn clock that runs behind the fixed steps by one step interval less one, so that the drawn shape
/// is always between two keyframes, never extrapolated. When the level changes, the clock runs up to
/// [`DRAWN_CLOCK_RATE_CHANGE`] faster or slower until it has the new lag: the hair's motion relative to its
/// head never jumps.
#[derive(Debug, Clone, Default)]
struct DrawnShape {
    /// Fixed steps counted since the drawn shape was set apart.
    clock: f64,
    /// The drawn clock, in the same fixed steps.
    drawn_time: f64,
    /// Keyframes, oldest first; the first is at or before the drawn clock.
    keyframes: std::collections::VecDeque<Keyframe>,
    /// Keyframes no longer needed, kept for their memory.
    spare: Vec<Keyframe>,
    /// The drawn nodes, head-local.
    nodes: Vec<Vec3>,
    /// The edges' tangents and reference directors after the last step, head-local.
    tangents: Vec<Vec3>,
    directors: Vec<Vec3>,
}

impl DrawnShape {
    /// Adds the keyframe of `rod` (at the head pose `rod_head`) at the current clock; after a snap, the
    /// only one, with the drawn clock on it.
    fn add_keyframe(&mut self, rod: &Rod, rod_head: &ScaledPose, snap: bool) {
        if snap {
            self.spare.extend(self.keyframes.drain(..));
            self.drawn_time = self.clock;
        }
        let to_local = rod_head.rotation.inverse();
        let mut keyframe = self.spare.pop().unwrap_or_default();
        keyframe.time = self.clock;
        let local = |point: DVec3| (to_local * (point - rod_head.translation)).as_vec3();
        copy_converted(&mut keyframe.nodes, &rod.state().positions, local);
        copy_converted(&mut self.tangents, &rod.frames().tangents, |t| (to_local * t).as_vec3());
        copy_converted(&mut self.directors, &rod.frames().reference_directors, |u| (to_local * u).as_vec3());
        if self.keyframes.back().is_some_and(|last| last.nodes.len() != keyframe.nodes.len()) {
            // A new node count: nothing to interpolate from.
            self.spare.extend(self.keyframes.drain(..));
            self.drawn_time = self.clock;
        }
        self.keyframes.push_back(keyframe);
    }

    /// Moves the drawn clock towards `lag` fixed steps behind the clock, by one step give or take
    /// [`DRAWN_CLOCK_RATE_CHANGE`], never past the last keyframe nor before the first; writes the drawn
    /// nodes there; lets go of keyframes the drawn clock has passed.
    fn advance(&mut self, lag: f64) {
        if self.keyframes.len() == 1
            && self.drawn_time == self.keyframes[0].time
            && self.nodes.len() == self.keyframes[0].nodes.len()
        {
            // Settled on the only keyframe (carried, or waiting for the next step): nothing moves.
            return;
        }
        let wanted = self.clock - lag;
        let step = (wanted - self.drawn_time).clamp(1.0 - DRAWN_CLOCK_RATE_CHANGE, 1.0 + DRAWN_CLOCK_RATE_CHANGE);
        let (first, last) = match (self.keyframes.front(), self.keyframes.back()) {
            (Some(first), Some(last)) => (first.time, last.time),
            _ => return,
        };
        self.drawn_time = (self.drawn_time + step).clamp(first, last);
        while self.keyframes.len() > 1 && self.keyframes[1].time <= self.drawn_time {
            let passed = self.keyframes.pop_front().expect("more than one keyframe");
            self.spare.push(passed);
        }
        let before = &self.keyframes[0];
        match self.keyframes.get(1) {
            Some(after) => {
                let fraction = (self.drawn_time - before.time) / (after.time - before.time);
                self.nodes.clear();
                self.nodes.extend(before.nodes.iter().zip(&after.nodes).map(|(a, b)| a.lerp(*b, fraction as f32)));
            }
            None => self.nodes.clone_from(&before.nodes),
        }
    }

    /// Whether the drawn shape is the last keyframe, taken now.
    fn caught_up(&self) -> bool {
        self.keyframes.len() == 1 && self.drawn_time == self.clock
    }
}

impl StrandDetail {
    /// Takes the length of the step about to be taken, in fixed steps (at least one).
    pub(crate) fn take_elapsed(&mut self) -> u32 {
        std::mem::take(&mut self.elapsed).max(1)
    }

    /// Whether the strand is still falling behind to `level`'s lag (see [`DrawnShape`]): until its drawn
    /// clock is `n − 1` fixed steps behind, a strand going to every `n`-th step is stepped every fixed
    /// step, so that its drawn shape always has a keyframe ahead to move to and never pauses.
    pub(crate) fn falling_behind(&self, level: HairDetailLevel) -> bool {
        let Some(interval) = level.step_interval() else { return false };
        let lag = self.drawn.as_ref().map_or(0.0, |drawn| drawn.clock - drawn.drawn_time);
        lag < f64::from(interval - 1) - LAG_TOLERANCE
    }

    /// Whether the drawn shape is the simulated one (full detail, caught up): the components are then
    /// written straight from the rod.
    pub(crate) fn draws_simulation(&self) -> bool {
        self.drawn.is_none() && self.level == HairDetailLevel::FULL && self.due
    }

    /// Writes the drawn shape into `nodes` and `frames`, world space at this step's head pose (see
    /// [`DrawnShape`]); `rod` (at the head pose `rod_head`) is a new keyframe when `stepped` (or when the
    /// drawn shape is set apart now). `snap` starts the drawn shape afresh on the rod.
    pub(crate) fn write_drawn(
        &mut self,
        rod: &Rod,
        rod_head: &ScaledPose,
        stepped: bool,
        snap: bool,
        nodes: &mut StrandNodes,
        frames: &mut StrandFrames,
    ) {
        let fresh = self.drawn.is_none();
        let drawn = self.drawn.get_or_insert_with(Box::default);
        if !fresh {
            drawn.clock += 1.0;
        }
        if fresh || stepped {
            drawn.add_keyframe(rod, rod_head, fresh || snap);
            copy_converted(&mut nodes.velocities, &rod.state().velocities, DVec3::as_vec3);
            copy_converted(&mut frames.twist, rod.twist_angles(), |angle| angle as f32);
            copy_converted(&mut frames.reference_twist, &rod.frames().reference_twist, |angle| angle as f32);
        }
        // One step interval less one behind: at a step, the drawn shape sets out from the keyframe before.
        let lag = f64::from(self.level.step_interval().map_or(0, |interval| interval - 1));
        drawn.advance(lag);

        let (rotation, translation) = (Mat3::from_quat(self.head.rotation.as_quat()), self.head.translation.as_vec3());
        std::mem::swap(&mut nodes.previous_positions, &mut nodes.positions);
        copy_converted(&mut nodes.positions, &drawn.nodes, |node| rotation * node + translation);
        snap_previous(&mut nodes.previous_positions, &nodes.positions, snap);
        copy_converted(&mut frames.tangents, &drawn.tangents, |t| rotation * t);
        copy_converted(&mut frames.reference_directors, &drawn.directors, |u| rotation * u);
        if self.level == HairDetailLevel::FULL && drawn.caught_up() {
            // From the next step on, the rod is drawn as it is.
            self.drawn = None;
        }
    }
}
