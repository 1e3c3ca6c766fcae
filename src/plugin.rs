//! The plugins: [`HairPlugin`] (the group a game adds), [`HairSimulationPlugin`] and the public
//! [`HairSystems`] sets.

use bevy::app::PluginGroupBuilder;
use bevy::ecs::schedule::{InternedScheduleLabel, ScheduleLabel};
use bevy::prelude::*;

use crate::collision::HairCollisionPlugin;
use crate::detail::HairDetailPlugin;
use crate::followers::{FollowerNodes, HairFollowers, bind_followers, place_followers};
use crate::gizmos::HairGizmoPlugin;
use crate::groom::{GroomedStrand, HairGroom, grow_groomed_hair};
use crate::groom_file::GroomFilePlugin;
use crate::head::{HairHead, HeadMotion, HeadStrands, StrandOf, track_heads};
use crate::settings::{HairPause, HairSettings, HairStatistics};
use crate::step::{
    StepBudget, apply_default_material, open_step, pin_roots, preload_rest_shapes, reset_step_budget, step_strands,
    stepping,
};
use crate::strand::{HairStrand, SimulatedStrand, StrandFault, StrandForces, StrandRejected, build_strands};
use crate::strand_data::{EdgeFrame, StrandFrames, StrandNodes, StrandRestShape, apply_rest_shape_edits};
use crate::volume::HairVolumePlugin;
use crate::wind::HairWindPlugin;

/// Everything a game needs for hair: simulation ([`HairSimulationPlugin`]), collisions
/// ([`HairCollisionPlugin`]), levels of detail for crowds ([`HairDetailPlugin`]), hair–hair interaction ([`HairVolumePlugin`]), wind ([`HairWindPlugin`]),
/// debug lines ([`HairGizmoPlugin`]), groom files ([`GroomFilePlugin`]) and, with the crate's `render`
/// feature, hair drawn with Bevy's PBR (`HairRenderPlugin`). Add it once, after Bevy's plugins:
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// App::new().add_plugins((MinimalPlugins, HairPlugin::default()));
/// ```
///
/// Simulation runs in [`FixedUpdate`] unless [`HairPlugin::new`] names another fixed-timestep schedule;
/// its rate is Bevy's `Time<Fixed>` (64 Hz by default; `Time::<Fixed>::from_hz(60.0)` for 60).
#[derive(Debug, Clone)]
pub struct HairPlugin {
    schedule: InternedScheduleLabel,
}

impl HairPlugin {
    /// Simulates hair in `schedule`, which must run inside Bevy's fixed main loop (`FixedUpdate`,
    /// `FixedPreUpdate`, `FixedPostUpdate` or one of your own run from it).
    pub fn new(schedule: impl ScheduleLabel) -> Self {
        Self { schedule: schedule.intern() }
    }

    /// Task pools that give Bevy's compute pool, where strands are stepped in parallel, every core. Bevy's
    /// default gives it what its IO and async pools leave: a single thread on a 2-core machine, 2 of 4.
    /// The IO and async threads sleep while idle, so sharing cores with them costs little.
    ///
    /// ```no_run
    /// # use bevy::prelude::*;
    /// # use bevy_hair_sim::prelude::*;
    /// App::new().add_plugins((
    ///     DefaultPlugins.set(TaskPoolPlugin { task_pool_options: HairPlugin::task_pool_options() }),
    ///     HairPlugin::default(),
    /// ));
    /// ```
    pub fn task_pool_options() -> TaskPoolOptions {
        Self::task_pool_options_with_threads(bevy::tasks::available_parallelism())
    }

    /// [`HairPlugin::task_pool_options`] with `threads` compute threads.
    pub fn task_pool_options_with_threads(threads: usize) -> TaskPoolOptions {
        let mut options = TaskPoolOptions::default();
        options.compute.min_threads = threads.max(1);
        options.compute.max_threads = threads.max(1);
        options
    }
}

impl Default for HairPlugin {
    fn default() -> Self {
        Self::new(FixedUpdate)
    }
}

impl PluginGroup for HairPlugin {
    fn build(self) -> PluginGroupBuilder {
        let group = PluginGroupBuilder::start::<Self>()
            .add(HairSimulationPlugin { schedule: self.schedule })
            .add(HairCollisionPlugin { schedule: self.schedule })
            .add(HairDetailPlugin { schedule: self.schedule })
            .add(HairVolumePlugin { schedule: self.schedule })
            .add(HairWindPlugin { schedule: self.schedule })
            .add(HairGizmoPlugin)
            .add(GroomFilePlugin { schedule: self.schedule });
        #[cfg(feature = "render")]
        let group = group.add(crate::render::HairRenderPlugin);
        group
    }
}

/// The steps of hair simulation, run in this order once per fixed step. Order your own systems against
/// them: edit strands before [`HairSystems::Prepare`] ends, add per-node forces in
/// [`HairSystems::ExternalForces`], read results ([`StrandNodes`], [`StrandFrames`]) after
/// [`HairSystems::Step`].
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HairSystems {
    /// Grows the hair of new or changed [`HairGroom`]s, builds strands from new or changed
    /// [`HairStrand`]s, applies changed settings and edited [`StrandRestShape`]s, decides whether this
    /// step runs (see [`HairPause`] and [`HairSettings::max_steps_per_frame`]). Always runs.
    Prepare,
    /// Moves every strand's root edge to its anchor on its head, and records where every
    /// [`crate::collision::HairCollider`] is.
    PinRoots,
    /// Where the wind ([`crate::wind::HairWind`]), the hair–hair interaction ([`crate::volume`]) and
    /// users add forces, air velocities and velocity changes to [`StrandForces`]; gravity comes from
    /// [`HairSettings::gravity`].
    ExternalForces,
    /// Elastic forces (stretching, bending, twisting), contact with colliders and implicit integration of
    /// every strand, in parallel; failed strands are reset and reported. Each strand's [`StrandNodes`] and
    /// [`StrandFrames`] are written as soon as it has stepped.
    Step,
    /// After the step: the place for checks of the new state and constraints of your own.
    PostStep,
}

/// The hair simulation: strands as entities rooted on heads, stepped in a fixed-timestep schedule.
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
                 HairPlugin::task_pool_options() gives it all of them",
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
            .register_type::<StrandNodes>()
            .register_type::<StrandFrames>()
            .register_type::<EdgeFrame>()
            .register_type::<StrandRestShape>()
            .register_type::<HairFollowers>()
            .register_type::<FollowerNodes>()
            .register_type::<StrandRejected>()
            .register_type::<HairGroom>()
            .register_type::<GroomedStrand>()
            .register_type::<HairSettings>()
            .register_type::<HairPause>()
            .register_type::<HairStatistics>()
            .init_resource::<HairSettings>()
            .init_resource::<HairPause>()
            .init_resource::<HairStatistics>()
            .init_resource::<StepBudget>()
            .add_message::<StrandFault>()
            .add_systems(First, reset_step_budget);

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
                .run_if(stepping),
        )
        .add_systems(
            schedule,
            (
                (
                    grow_groomed_hair,
                    build_strands,
                    bind_followers,
                    apply_default_material,
                    apply_rest_shape_edits,
                    open_step,
                )
                    .chain()
                    .in_set(HairSystems::Prepare),
                (track_heads, pin_roots).chain().in_set(HairSystems::PinRoots),
                (preload_rest_shapes, step_strands, place_followers).chain().in_set(HairSystems::Step),
            ),
        );
    }
}
