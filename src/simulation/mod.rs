//! The simulation core of the ECS layer: heads, strands, their data as components, the run-time settings,
//! the step cadence that levels of detail set, the contact slots the step reads, and the step itself.
//! [`HairSimulationPlugin`] wires it into a fixed-timestep schedule.
//!
//! # Heads and strands
//! A [`HairHead`] is any body hair grows from; its `Transform` (through any parents) moves the roots of its
//! strands at every fixed step. A strand is an entity with a [`HairStrand`] (its nodes in its head's local
//! space, its material, its natural curl) and a [`StrandOf`] naming its head; the head lists its strands in
//! [`HeadStrands`], and despawning it despawns them. Heads are expected to be rigid: a head's scale moves
//! the anchors on its surface but does not stretch its strands.
//!
//! Each strand is built into a [`SimulatedStrand`]: a discrete elastic rod ([`crate::rod::Rod`], double
//! precision) whose root edge is clamped to its anchor on the head. After every step the plugin writes its
//! single-precision view: [`StrandNodes`] (positions, velocities, the positions one step before, for
//! drawing between steps) and [`StrandFrames`] (tangents, material frames, twist). [`StrandRestShape`] is the
//! shape the strand has no elastic energy in; edit it to restyle a strand in place. [`StrandSnapshot`] saves
//! a strand so that it repeats its future bit for bit. On a strand with a [`PackedStrandPose`] (the
//! renderer gives one to each guide whose followers the GPU places) the step also packs its pose into one
//! array of 32-bit words for a GPU, while the strand is in the core's cache.
//!
//! # Loads
//! Gravity ([`HairSettings::gravity`]), air drag relative to the wind ([`HairSettings::air_damping`]) and
//! internal damping act on every strand; a game adds forces, air velocities and velocity changes per node to
//! [`StrandForces`] in [`HairSystems::ExternalForces`].
//! [`HairStrand::gravity_preload`] solves the rest shape so that a styled strand keeps its shape under
//! gravity instead of sagging.
//!
//! # Faults
//! A strand whose step fails (a Newton step that does not converge, a non-finite load, a root that cannot
//! follow its head) is rolled back to its state before the step, reported once with a [`StrandFault`]
//! message and a log line, and retried; one that fails again soon after is held in its rest pose on its head
//! (quarantine, [`StrandHealth`]) for an interval that doubles up to [`MAX_QUARANTINE`] seconds. The rest of
//! the hair keeps going. Strands that cannot be built are reported with [`StrandRejected`].
//!
//! # Cadence
//! Every strand has a level ([`HairDetailLevel`]): stepped every `n`-th fixed step with a step `n` times as
//! long, or carried rigidly with its head. The core keeps the cadence and the shape drawn between steps;
//! [`crate::detail`] chooses the levels. Without it every strand is at full detail.

//!
//! # Strand data: reading, editing, saving
//! Query [`StrandNodes`], [`StrandFrames`] and [`StrandRestShape`] like any component (single precision,
//! world space, written after every step). **Edit `StrandRestShape`** to restyle a strand in place: the
//! change is picked up before the next step (an edit the rod cannot take is logged and undone). A
//! [`StrandSnapshot`] copies out everything a strand's future depends on; inserting it back resumes the
//! strand bit for bit. The double-precision rod behind them is [`SimulatedStrand::rod`];
//! [`SimulatedStrand::rod_mut`] changes it directly (a node pinned to a hand, a scripted pose).
//!
//! ```
//! use bevy::prelude::*;
//! use bevy::time::TimeUpdateStrategy;
//! use bevy_hair_sim::prelude::*;
//!
//! let mut app = App::new();
//! app.add_plugins((MinimalPlugins, HairPlugins::default()))
//!     .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
//! let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
//! let strand = app.world_mut().spawn((HairStrand::straight(Vec3::Y * 0.1, Vec3::Z, 0.2, 16), StrandOf(head))).id();
//! for _ in 0..30 {
//!     app.update();
//! }
//! // Read: the tip's position and its edge's material frame.
//! let mut query = app.world_mut().query::<(&StrandNodes, &StrandFrames)>();
//! let (nodes, frames) = query.get(app.world(), strand).unwrap();
//! let tip = nodes.positions[16];
//! let frame = frames.material_frame(15).unwrap();
//! assert!(tip.y < 1.69 && frame.m1.dot(frame.tangent).abs() < 1e-5, "it sags, its frame is orthonormal");
//!
//! // Save, then curl the strand by editing its rest curvature (0.3 rad of turn per vertex).
//! let saved = StrandSnapshot::of(app.world_mut().query::<StrandSnapshotData>().get(app.world(), strand).unwrap());
//! let mut rest_shape = app.world_mut().get_mut::<StrandRestShape>(strand).unwrap();
//! for curvature in &mut rest_shape.curvatures[1..16] {
//!     *curvature = Vec2::new(2.0 * 0.15_f32.tan(), 0.0);
//! }
//! for _ in 0..60 {
//!     app.update();
//! }
//! assert!(app.world().get::<StrandNodes>(strand).unwrap().positions[16].distance(tip) > 0.01, "it curled");
//!
//! // Restore: back to the moment it was saved, straight rest shape included.
//! app.world_mut().entity_mut(strand).insert(saved);
//! assert_eq!(app.world().get::<StrandNodes>(strand).unwrap().positions[16], tip);
//! ```

mod cadence;
mod contacts;
mod data;
mod head;
// The GPU's wire format of a strand's pose: public for the crate's GPU tests and benchmark, not an API.
#[doc(hidden)]
pub mod packed;
mod pose;
mod settings;
mod snapshot;
mod step;
mod strand;
mod style_hold;

use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::prelude::*;
use bevy::transform::TransformSystems;

pub use cadence::{DRAWN_CLOCK_RATE_CHANGE, HairDetailLevel, HeadsByDetail, LONGER_STEP_STRAIN_TOLERANCE};
pub(crate) use cadence::{StrandDetail, longer_step_params};
pub(crate) use contacts::StrandColliders;
pub use contacts::{HeadColliderSet, SharedColliderSet};
pub(crate) use data::snap_previous;
pub use data::{EdgeFrame, StrandFrames, StrandNodes, StrandRestShape};
pub use head::{HairHead, HeadMotion, HeadStrands, StrandOf};
pub use packed::PackedStrandPose;
pub(crate) use pose::ScaledPose;
pub use settings::{HairPause, HairSettings, HairStatistics, HairStyleHold, HairVolume};
pub use snapshot::{StrandSnapshot, StrandSnapshotData, StrandSnapshotDataItem};
pub(crate) use step::CheckedSettings;
#[cfg(feature = "gpu")]
pub(crate) use step::FaultLog;
pub(crate) use strand::StepOutcome;
#[cfg(feature = "gpu")]
pub(crate) use strand::write_strand_data;
pub use strand::{
    FIRST_QUARANTINE, HairStrand, MAX_QUARANTINE, PRELOAD_SUPPORT_DISTANCE, QUARANTINE_WINDOW, SimulatedStrand,
    SteppedElsewhere, StrandFault, StrandForces, StrandHealth, StrandRejected, StrandSpawnError,
};

use crate::schedule::{HairDrawSystems, HairPinSystems, HairPrepareSystems, HairStepSystems, HairSystems};

/// The hair simulation: strands as entities rooted on heads, stepped in a fixed-timestep schedule. It
/// configures every set of [`crate::schedule`] and runs the core's systems in them; the other concerns'
/// plugins ([`crate::HairPlugins`] adds them all) put theirs in the same sets.
#[derive(Debug, Clone)]
pub struct HairSimulationPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: InternedScheduleLabel,
}

impl Plugin for HairSimulationPlugin {
    fn finish(&self, _app: &mut App) {
        let cores = bevy::tasks::available_parallelism();
        if let Some(pool) = bevy::tasks::ComputeTaskPool::try_get()
            && pool.thread_num() < cores
        {
            info!(
                "hair is stepped on Bevy's compute pool: {} of {cores} cores; \
                 HairPlugins::task_pool_options() gives it all of them",
                pool.thread_num()
            );
        }
    }

    fn build(&self, app: &mut App) {
        app.register_type::<HairHead>()
            .register_type::<StrandOf>()
            .register_type::<HeadStrands>()
            .register_type::<HeadMotion>()
            .register_type::<HairStrand>()
            .register_type::<SimulatedStrand>()
            .register_type::<StrandForces>()
            .register_type::<SteppedElsewhere>()
            .register_type::<StrandNodes>()
            .register_type::<StrandFrames>()
            .register_type::<PackedStrandPose>()
            .register_type::<EdgeFrame>()
            .register_type::<StrandRestShape>()
            .register_type::<StrandRejected>()
            .register_type::<HairSettings>()
            .register_type::<HairStyleHold>()
            .register_type::<HairPause>()
            .register_type::<HairStatistics>()
            .init_resource::<HairSettings>()
            .init_resource::<HairPause>()
            .init_resource::<HairStatistics>()
            .init_resource::<step::StepBudget>()
            .init_resource::<step::CheckedSettings>()
            .add_message::<StrandFault>()
            .add_systems(First, step::reset_step_budget)
            .configure_sets(PostUpdate, HairDrawSystems.after(TransformSystems::Propagate));

        let schedule = self.schedule;
        app.configure_sets(
            schedule,
            (
                HairSystems::Prepare,
                HairSystems::PinRoots,
                HairSystems::ExternalForces,
                HairSystems::Step,
                HairSystems::PostStep,
            )
                .chain(),
        )
        .configure_sets(
            schedule,
            (HairSystems::PinRoots, HairSystems::ExternalForces, HairSystems::Step, HairSystems::PostStep)
                .run_if(step::stepping),
        )
        .configure_sets(
            schedule,
            (
                HairPrepareSystems::Grow,
                HairPrepareSystems::Build,
                HairPrepareSystems::Bind,
                HairPrepareSystems::Apply,
                HairPrepareSystems::Budget,
            )
                .chain()
                .in_set(HairSystems::Prepare),
        )
        .configure_sets(
            schedule,
            (HairPinSystems::Track, HairPinSystems::FollowScalp, HairPinSystems::ChooseDetail, HairPinSystems::Pin)
                .chain()
                .in_set(HairSystems::PinRoots),
        )
        .configure_sets(schedule, HairPinSystems::Colliders.in_set(HairSystems::PinRoots))
        .configure_sets(
            schedule,
            HairPinSystems::Preload
                .in_set(HairSystems::PinRoots)
                .after(HairPinSystems::Pin)
                .after(HairPinSystems::Colliders),
        )
        .configure_sets(
            schedule,
            (HairStepSystems::Integrate, HairStepSystems::Follow).chain().in_set(HairSystems::Step),
        )
        .add_systems(
            schedule,
            (
                strand::build_strands.in_set(HairPrepareSystems::Build),
                (step::apply_default_material, strand::apply_rest_shape_edits)
                    .chain()
                    .in_set(HairPrepareSystems::Apply),
                (step::check_settings, step::open_step).chain().in_set(HairPrepareSystems::Budget),
                head::track_heads.in_set(HairPinSystems::Track),
                step::pin_roots.in_set(HairPinSystems::Pin),
                step::preload_rest_shapes.in_set(HairPinSystems::Preload),
                step::step_strands.in_set(HairStepSystems::Integrate),
            ),
        );
    }
}
