//! The step cadence of each strand, which levels of detail ([`crate::detail`]) set: whether a strand is
//! stepped at this fixed step, how long its step is, and the shape drawn between its steps (keyframes in its
//! head's frame and a drawn clock). Core state: the step reads it whether or not levels of detail are on.

use bevy::math::DVec3;
use bevy::prelude::*;

use super::data::{StrandFrames, StrandNodes, copy_converted, snap_previous};
use super::pose::ScaledPose;
use crate::rod::{Rod, StepParams};

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
    pub(crate) fn coarseness(self) -> u32 {
        self.step_interval().unwrap_or(u32::MAX)
    }
}

impl Default for HairDetailLevel {
    fn default() -> Self {
        Self::FULL
    }
}

/// How many heads are at each level of detail, counted at every fixed step that simulates hair
/// ([`crate::simulation::HairStatistics::heads_by_detail`]).
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
/// a finer level of detail or falls back to a coarser one (see [`crate::detail`]): 0.25, so a lag of three
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
    /// Whether the strand is held at this fixed step because the settings are invalid: not stepped, drawn
    /// carried with its head (see `check_settings`).
    pub(crate) held: bool,
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
            held: false,
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
    /// [`DRAWN_CLOCK_RATE_CHANGE`], never past the last keyframe nor before the first; lets go of keyframes
    /// the drawn clock has passed.
    fn advance(&mut self, lag: f64) {
        if self.keyframes.len() == 1 && self.drawn_time == self.keyframes[0].time {
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
    }

    /// Writes the drawn nodes at the drawn clock into `out`, turned by `rotation` and moved by
    /// `translation` (head-local to world): the keyframes either side interpolated, in one pass.
    fn write_nodes(&self, out: &mut Vec<Vec3>, rotation: Mat3, translation: Vec3) {
        let Some(before) = self.keyframes.front() else { return };
        match self.keyframes.get(1) {
            Some(after) => {
                let fraction = ((self.drawn_time - before.time) / (after.time - before.time)) as f32;
                out.clear();
                out.extend(
                    before.nodes.iter().zip(&after.nodes).map(|(a, b)| rotation * a.lerp(*b, fraction) + translation),
                );
            }
            None => copy_converted(out, &before.nodes, |node| rotation * node + translation),
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
        self.drawn.is_none() && self.level == HairDetailLevel::FULL && self.due && !self.held
    }

    /// Writes the drawn shape into `nodes` and `frames`, world space at this step's head pose (see
    /// [`DrawnShape`]); `rod` (at the head pose `rod_head`) is a new keyframe when `stepped` (or when the
    /// drawn shape is set apart now). `snap` starts the drawn shape afresh on the rod (stepped or not).
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
        // A snap without a step is a reset: the drawn shape starts afresh on the reset rod too.
        if fresh || stepped || snap {
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
        drawn.write_nodes(&mut nodes.positions, rotation, translation);
        snap_previous(&mut nodes.previous_positions, &nodes.positions, snap);
        copy_converted(&mut frames.tangents, &drawn.tangents, |t| rotation * t);
        copy_converted(&mut frames.reference_directors, &drawn.directors, |u| rotation * u);
        if self.level == HairDetailLevel::FULL && !self.held && drawn.caught_up() {
            // From the next step on, the rod is drawn as it is.
            self.drawn = None;
        }
    }
}
