//! Where a step's time goes: an optional stopwatch in the [`RodWorkspace`] that splits each step into
//! its parts, for benchmarks and profiling. Off by default, when it costs one branch per part.
//!
//! [`RodWorkspace`]: super::RodWorkspace

use std::time::Duration;

use bevy::platform::time::Instant;

/// Wall time spent in each part of the steps taken since timing was turned on
/// ([`super::RodWorkspace::time_parts`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepTimings {
    /// Steps timed.
    pub steps: u32,
    /// Frames: carrying the strand with its root, parallel transport, reference twist, material frames.
    pub frames: Duration,
    /// Forces: elastic gradients and Hessian, damping, inertia, gravity and external forces, boundary
    /// conditions; and the bookkeeping around them (saving the state, velocities, the strain check).
    pub forces: Duration,
    /// Solve: the banded `L D Lᵀ` factorisation and its solve, the trust region and applying the update.
    pub solve: Duration,
    /// Constraints: the inextensibility projection.
    pub constraints: Duration,
    /// Collisions: finding nearby colliders, contact springs and friction, the push-out after the solve
    /// and its length projections.
    pub collisions: Duration,
}

impl StepTimings {
    /// The parts' names and times, in step order.
    pub fn parts(&self) -> [(&'static str, Duration); 5] {
        [
            ("frames", self.frames),
            ("forces", self.forces),
            ("solve", self.solve),
            ("constraints", self.constraints),
            ("collisions", self.collisions),
        ]
    }

    /// The time of all parts.
    pub fn total(&self) -> Duration {
        self.parts().iter().map(|(_, time)| *time).sum()
    }
}

/// A part of a step, for [`Stopwatch::lap`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Part {
    Frames,
    Forces,
    Solve,
    Constraints,
    Collisions,
}

/// Adds the time since its last lap to the part a lap names, while timing is on.
#[derive(Debug, Clone, Default)]
pub(crate) struct Stopwatch {
    timings: Option<StepTimings>,
    last: Option<Instant>,
}

impl Stopwatch {
    pub(crate) fn set_enabled(&mut self, enabled: bool) {
        self.timings = enabled.then(StepTimings::default);
        self.last = None;
    }

    pub(crate) fn timings(&self) -> Option<&StepTimings> {
        self.timings.as_ref()
    }

    /// Starts timing a step.
    pub(crate) fn start_step(&mut self) {
        if let Some(timings) = &mut self.timings {
            timings.steps += 1;
            self.last = Some(Instant::now());
        }
    }

    /// Counts the time since the last lap (or the step's start) as `part`'s.
    pub(crate) fn lap(&mut self, part: Part) {
        let (Some(timings), Some(last)) = (&mut self.timings, self.last) else {
            return;
        };
        let now = Instant::now();
        let slot = match part {
            Part::Frames => &mut timings.frames,
            Part::Forces => &mut timings.forces,
            Part::Solve => &mut timings.solve,
            Part::Constraints => &mut timings.constraints,
            Part::Collisions => &mut timings.collisions,
        };
        *slot += now - last;
        self.last = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use bevy::math::DVec3;

    use crate::rod::{ColliderShape, Contacts, MovingCollider, RigidPose, Rod, RodMaterial, RodWorkspace, StepParams};

    /// A 20 cm hair clamped at its root, falling onto a ball, stepped `steps` times; its final positions.
    fn drop_on_a_ball(workspace: &mut RodWorkspace, steps: usize) -> Vec<DVec3> {
        let nodes: Vec<DVec3> = (0..=16).map(|i| DVec3::new(0.2 * i as f64 / 16.0, 0.0, 0.0)).collect();
        let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
        rod.clamp_root_in_place();
        let ball = MovingCollider::fixed(
            ColliderShape::sphere(0.03),
            0.4,
            RigidPose::new(Default::default(), DVec3::new(0.12, -0.05, 0.0)),
        );
        let contacts = Contacts { colliders: &[ball], thickness: 1e-4 };
        for _ in 0..steps {
            rod.step_with_contacts(&StepParams::default(), None, &contacts, workspace).unwrap();
        }
        rod.positions().to_vec()
    }

    #[test]
    fn timing_counts_every_part_of_every_step_and_changes_nothing() {
        let mut untimed = RodWorkspace::default();
        let expected = drop_on_a_ball(&mut untimed, 60);
        assert!(untimed.part_timings().is_none(), "timing is off by default");

        let mut timed = RodWorkspace::default();
        timed.time_parts(true);
        assert_eq!(drop_on_a_ball(&mut timed, 60), expected, "timing changed the result");
        let timings = *timed.part_timings().unwrap();
        assert_eq!(timings.steps, 60);
        for (part, time) in timings.parts() {
            assert!(!time.is_zero(), "no time counted for {part}");
        }

        timed.time_parts(false);
        assert!(timed.part_timings().is_none());
    }
}
