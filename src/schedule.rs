//! The system sets of hair simulation and drawing, defined here at the bottom of the crate so that every
//! concern can place its systems in them without reaching up to the plugin that wires them all.
//!
//! [`HairSimulationPlugin`](crate::simulation::HairSimulationPlugin) configures them: the five
//! [`HairSystems`] run in order once per fixed step, each with its sub-sets chained inside it; the sets after
//! [`HairSystems::Prepare`] run only on the fixed steps that simulate hair (see
//! [`HairPause`](crate::simulation::HairPause) and
//! [`HairSettings::max_steps_per_frame`](crate::simulation::HairSettings::max_steps_per_frame)).
//!
//! ```text
//! HairSystems::Prepare         Grow → Build → Bind → Apply → Budget                    (HairPrepareSystems)
//! HairSystems::PinRoots        Track → FollowScalp → ChooseDetail → Pin, and Colliders (HairPinSystems)
//! HairSystems::ExternalForces  wind, hair–hair grid, your forces
//! HairSystems::Step            Integrate → Follow                                      (HairStepSystems)
//! HairSystems::PostStep        your checks and constraints
//! PostUpdate: HairDrawSystems  after transform propagation
//! ```

use bevy::prelude::*;

/// The steps of hair simulation, run in this order once per fixed step. Order your own systems against
/// them: edit strands before [`HairSystems::Prepare`] ends, add per-node forces in
/// [`HairSystems::ExternalForces`], read results ([`StrandNodes`](crate::simulation::StrandNodes),
/// [`StrandFrames`](crate::simulation::StrandFrames)) after [`HairSystems::Step`].
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HairSystems {
    /// Grows the hair of new or changed grooms, builds strands from new or changed
    /// [`HairStrand`](crate::simulation::HairStrand)s, binds followers, applies changed settings and edited
    /// [`StrandRestShape`](crate::simulation::StrandRestShape)s, decides whether this step runs. Always
    /// runs; its parts are the [`HairPrepareSystems`].
    Prepare,
    /// Records where every head is, chooses its level of detail, moves every strand's root edge to its
    /// anchor on its head, and records where every [`HairCollider`](crate::collision::HairCollider) is
    /// ([`HairPinSystems`]).
    PinRoots,
    /// Where the wind ([`crate::wind`]), the hair–hair interaction ([`crate::volume`]) and users add
    /// forces, air velocities and velocity changes to [`StrandForces`](crate::simulation::StrandForces);
    /// gravity comes from [`HairSettings::gravity`](crate::simulation::HairSettings::gravity).
    ExternalForces,
    /// Elastic forces (stretching, bending, twisting), contact with colliders and implicit integration of
    /// every strand, in parallel; failed strands are reset and reported; then the followers are placed
    /// ([`HairStepSystems`]). Each strand's nodes and frames are written as soon as it has stepped.
    Step,
    /// After the step: the place for checks of the new state and constraints of your own.
    PostStep,
}

/// The parts of [`HairSystems::Prepare`], chained in this order.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HairPrepareSystems {
    /// Grooms spawn their strands ([`crate::groom`]: procedural grooms and groom files).
    Grow,
    /// Strands are built from new or changed [`HairStrand`](crate::simulation::HairStrand)s.
    Build,
    /// Followers are bound to their guides ([`crate::followers`]).
    Bind,
    /// The default material and edited rest shapes are applied to the strands.
    Apply,
    /// Whether this fixed step simulates hair is decided (pause, steps per frame).
    Budget,
}

/// The parts of [`HairSystems::PinRoots`]: `Track`, `FollowScalp`, `ChooseDetail` and `Pin` chained,
/// `Colliders` beside them, `Preload` after both.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HairPinSystems {
    /// Every head's pose at this step is recorded.
    Track,
    /// Roots bound to a scalp mesh are moved with its triangles, skinned by its joints ([`crate::scalp`]).
    FollowScalp,
    /// Every head's level of detail is chosen ([`crate::detail`]), and with it which strands step now.
    ChooseDetail,
    /// Every strand's root edge is moved to its anchor on its head.
    Pin,
    /// Colliders' poses are recorded and each head's set gathered ([`crate::collision`]).
    Colliders,
    /// Rest shapes waiting for a gravity preload are preloaded, from the pinned strands and their
    /// colliders. (After it, with the `gpu` feature, the strands the GPU steps are chosen, before anything
    /// adds to their loads.)
    Preload,
}

/// The parts of [`HairSystems::Step`], chained in this order.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HairStepSystems {
    /// Every strand due is stepped (on the CPU; with the `gpu` feature, the GPU's step is ordered).
    Integrate,
    /// Follower hairs are placed along their stepped guides ([`crate::followers`]).
    Follow,
}

/// The system set in [`PostUpdate`] that draws hair (gizmo lines, the renderer's node buffers), after
/// Bevy's transform propagation.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct HairDrawSystems;
