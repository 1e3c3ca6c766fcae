//! Strand components: the shape a strand is spawned from, its simulated state, the forces users apply
//! to it and the pose it is drawn in.

use bevy::math::{DQuat, DVec2, DVec3};
use bevy::prelude::*;
use thiserror::Error;

use crate::rod::{PreloadReport, Rod, RodError, RodMaterial, StepError, StepLoads, StepReport};
use crate::simulation::{
    HairDetailLevel, HairSettings, HeadMotion, ScaledPose, StrandDetail, StrandFrames, StrandNodes, StrandOf,
    StrandRestShape, data::RestShapeScratch,
};

/// A hair strand to simulate, as it is spawned. Add it (with [`StrandOf`] to root it on a head) and the
/// plugin builds its simulated [`SimulatedStrand`] at the next fixed step. Changing it (or its `StrandOf`) later
/// respawns the strand.
///
/// The spawned shape is the rest shape: a curly strand spawned as a helix keeps its curls.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone, PartialEq)]
#[require(StrandForces, StrandNodes, StrandFrames, StrandRestShape)]
pub struct HairStrand {
    /// Node positions, m: in the head's local space when the strand has a head ([`StrandOf`]), in world
    /// space otherwise. Node 0 is the root, node 1 ends the root edge that the head holds. At least 3.
    pub nodes: Vec<Vec3>,
    /// Direction, in the same space, of the root edge's first material director `m1`, along which the
    /// cross-section's `semi_axis_1` lies. Must not be parallel to the root edge.
    pub material_direction: Vec3,
    /// The strand's material; `None` uses [`HairSettings::default_material`] and follows its changes.
    pub material: Option<RodMaterial>,
    /// Natural curvature `(k₁, k₂)`, 1/m, in the material frame: replaces the spawned shape's rest
    /// curvature so that, free of load, the strand curls into arcs of radius `1/|k|`. `None` keeps the
    /// spawned shape's own curvature as rest curvature.
    pub natural_curvature: Option<Vec2>,
    /// Distance from the centre line that stays outside colliders, m; `None` uses the material's larger
    /// semi-axis plus [`HairSettings::collision_margin`].
    pub collision_thickness: Option<f32>,
    /// Gravity preload, 0 to 1: how much of the spawned shape's sag under [`HairSettings::gravity`] the
    /// rest shape takes up, so that the strand keeps its spawned shape at rest (1) or sags as a strand
    /// of that rest shape would (0, the default). Computed once when the strand is built, from its shape,
    /// the gravity and the colliders it rests on (see [`crate::rod::Rod::preload_for_gravity`]); gravity
    /// is baked into the rest shape, so turning the head over or changing gravity later moves the hair.
    /// Needs a head ([`StrandOf`]): a free strand has nothing to hang from.
    pub gravity_preload: f32,
    /// Whether the gravity preload may stiffen the strand so that its shape holds (default `false`). A
    /// preloaded shape is an equilibrium, but one that hair standing up or held out sideways keeps only
    /// up to a length (9.5 cm for human hair, Greenhill's self-weight buckling length; see
    /// [`crate::rod::Rod::stiffening_to_hold`]): past it the strand buckles at the first disturbance
    /// and falls. With this set, such a strand's bending and twisting stiffness grow to the least that
    /// holds its shape, as a styling product or a clump of hairs bonded together hold a style that single
    /// hairs cannot; strands that hang keep their material. [`SimulatedStrand::stiffening`] says by how
    /// much (a strand stiffened holds twice its weight upright). Imported grooms set it ([`crate::groom::GroomPlacement::stiffen_to_hold`]).
    pub stiffen_to_hold: bool,
}

impl HairStrand {
    /// A strand through `nodes` (m; root first) whose root edge's material direction is
    /// `material_direction`.
    pub fn from_nodes(nodes: impl Into<Vec<Vec3>>, material_direction: Vec3) -> Self {
        Self {
            nodes: nodes.into(),
            material_direction,
            material: None,
            natural_curvature: None,
            collision_thickness: None,
            gravity_preload: 0.0,
            stiffen_to_hold: false,
        }
    }

    /// A straight strand `length` m long, split into `segments` edges, growing from `root` along
    /// `direction`.
    pub fn straight(root: Vec3, direction: Vec3, length: f32, segments: usize) -> Self {
        let direction = direction.normalize_or_zero();
        let edge = length / segments.max(1) as f32;
        let nodes: Vec<Vec3> = (0..=segments).map(|node| root + direction * edge * node as f32).collect();
        Self::from_nodes(nodes, direction.any_orthonormal_vector())
    }

    /// Uses `material` instead of [`HairSettings::default_material`].
    pub fn with_material(mut self, material: RodMaterial) -> Self {
        self.material = Some(material);
        self
    }

    /// Sets the natural curvature `(k₁, k₂)`, 1/m, see [`HairStrand::natural_curvature`].
    pub fn with_natural_curvature(mut self, curvature_per_metre: Vec2) -> Self {
        self.natural_curvature = Some(curvature_per_metre);
        self
    }

    /// Sets the gravity preload (0 to 1), see [`HairStrand::gravity_preload`].
    pub fn with_gravity_preload(mut self, preload: f32) -> Self {
        self.gravity_preload = preload;
        self
    }

    /// Lets the gravity preload stiffen the strand so that its shape holds, see
    /// [`HairStrand::stiffen_to_hold`].
    pub fn with_stiffening_to_hold(mut self, stiffen: bool) -> Self {
        self.stiffen_to_hold = stiffen;
        self
    }

    /// Sets the collision thickness, m, see [`HairStrand::collision_thickness`].
    pub fn with_collision_thickness(mut self, thickness: f32) -> Self {
        self.collision_thickness = Some(thickness);
        self
    }
}

/// Why a [`HairStrand`] could not be simulated.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StrandSpawnError {
    /// The shape or material was rejected by the mechanics core.
    #[error(transparent)]
    Rod(#[from] RodError),
    /// The gravity preload was outside 0 to 1, or NaN.
    #[error("the gravity preload {0} is not between 0 and 1")]
    InvalidGravityPreload(f32),
    /// The collision thickness was negative, NaN or infinite.
    #[error("the collision thickness {0} m is not zero or positive and finite")]
    InvalidCollisionThickness(f32),
    /// The natural curvature was NaN or infinite.
    #[error("the natural curvature {0} is not finite")]
    NonFiniteCurvature(Vec2),
    /// The head's world transform could not be computed.
    #[error("its head {head} has no usable transform: {reason}")]
    Head {
        /// The head entity.
        head: Entity,
        /// Why its transform could not be computed.
        reason: String,
    },
}

/// Put on a strand whose [`HairStrand`] was rejected (the reason is also logged as an error). The strand
/// is not simulated until its `HairStrand` is changed into a valid one, [`HairSettings`] change (its
/// default material may have been what was wrong), or, when it waits for its head, the head has a
/// usable transform again.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone)]
pub struct StrandRejected {
    /// What was wrong.
    pub reason: String,
    /// Whether the strand waits for its head's transform (not finite, or of zero scale) to become usable:
    /// it is then tried again at every step, and not logged (the head's own warning says why).
    pub waits_for_head: bool,
}

/// Where a strand's root edge is held in its head's local space, with its material frame.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Clone)]
pub(crate) struct RootAnchor {
    /// Root node, head-local, m (scaled with the head).
    pub position: DVec3,
    /// The root edge `x_1 − x_0`, head-local, m (turned with the head, never scaled).
    pub edge: DVec3,
    /// Direction of the root edge's material director `m1`, head-local.
    pub material_direction: DVec3,
}

impl RootAnchor {
    /// World positions of the root edge's two nodes and its material direction, for a head at `pose`.
    pub(crate) fn world(&self, pose: &ScaledPose) -> (DVec3, DVec3, DVec3) {
        let root = pose.transform_point(self.position);
        (root, root + pose.rotation * self.edge, pose.rotation * self.material_direction)
    }
}

/// How far beyond its collision thickness a node may be from a collider's surface and still count as
/// resting on it for the gravity preload ([`HairStrand::gravity_preload`]), m: hair groomed lying on a
/// skull, a layer or two above it.
pub const PRELOAD_SUPPORT_DISTANCE: f32 = 0.003;

/// Seconds after a fault within which another fault quarantines the strand, s of simulated time.
pub const QUARANTINE_WINDOW: f64 = 1.0;

/// How long a strand's first quarantine of an episode lasts, s of simulated time; each further one in the
/// same episode lasts twice as long as the one before, up to [`MAX_QUARANTINE`].
pub const FIRST_QUARANTINE: f64 = 0.5;

/// The longest quarantine, s of simulated time.
pub const MAX_QUARANTINE: f64 = 32.0;

/// A strand's record of failures: a fault episode starts with a failed step and ends once the strand
/// has stepped [`QUARANTINE_WINDOW`] seconds without failing.
#[derive(Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct StrandHealth {
    /// Failed steps in the current episode (0: none going on).
    pub faults_in_episode: u32,
    /// Quarantines in the current episode.
    pub quarantines_in_episode: u32,
    /// Simulated time of the last fault, s (the clock of the schedule the hair runs in).
    pub last_fault: f64,
    /// Simulated time until which the strand is held in quarantine, s; `None` when it is not.
    pub quarantined_until: Option<f64>,
}

/// What a strand's step needs from its start to its end ([`SimulatedStrand::begin_advance`]): the
/// head pose the step brings the rod to, and whether this is the retry after a quarantine.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AdvanceStart {
    to: ScaledPose,
    retried: bool,
}

/// What [`SimulatedStrand`]'s step did.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum StepOutcome {
    /// Stepped.
    Stepped(StepReport),
    /// In quarantine: held at its rest pose on its head, not stepped.
    Held,
    /// The step failed (see [`SimulatedStrand`]).
    Faulted {
        /// Why.
        error: StepError,
        /// Whether this fault starts an episode (it is then logged on its own).
        first_of_episode: bool,
        /// Seconds of quarantine this fault started, if it started one.
        quarantine: Option<f64>,
    },
}

/// The simulated state of a strand, built by the plugin from its [`HairStrand`]: the rod (node positions
/// and velocities, edge frames and twists, rest lengths, rest curvatures and twists, material; see
/// [`Rod`]) and its root anchor on the head, contiguous per strand. The solver's scratch memory is not
/// here: one workspace per thread serves all the strands that thread steps, and stays in its cache.
///
/// **Faults.** A step that fails (see [`StrandFault`]) puts the strand back in its rest pose on its head
/// (or, on invalid input such as a non-finite force, skips it). A strand that fails again within
/// [`QUARANTINE_WINDOW`] of a failure is quarantined: held in its rest pose on its head, following the
/// head, not stepped, for [`FIRST_QUARANTINE`] seconds, then retried; each further failure in the same
/// episode doubles the wait, up to [`MAX_QUARANTINE`]. [`SimulatedStrand::health`] has the record.
#[derive(Component, Reflect, Debug, Clone)]
#[reflect(Component, Debug)]
pub struct SimulatedStrand {
    rod: Rod,
    anchor: Option<RootAnchor>,
    spawn_head: ScaledPose,
    head: ScaledPose,
    follows_default_material: bool,
    collision_thickness: Option<f64>,
    last_report: Option<StepReport>,
    snap_pose: bool,
    health: StrandHealth,
    /// Why the root could not be clamped to the head this step, reported as the step's fault.
    #[reflect(ignore)]
    pin_error: Option<RodError>,
    /// Whether the rod was lent out through [`SimulatedStrand::rod_mut`] since its state was last checked:
    /// a strand not stepped (carried, or waiting for its turn or for valid settings) checks it before it
    /// is drawn, as a step would.
    rod_written: bool,
    /// The gravity preload factor to compute before the next step, if one is pending.
    pending_preload: Option<f32>,
    /// What the last gravity preload did.
    #[reflect(ignore)]
    preload_report: Option<PreloadReport>,
    /// Whether the gravity preload may stiffen the strand ([`HairStrand::stiffen_to_hold`]).
    stiffen_to_hold: bool,
    /// How many times stiffer than its material the strand bends and twists (1 unless stiffened to hold).
    stiffening: f64,
    /// The level of detail this step, and the drawn shape while it is kept apart from the simulation.
    #[reflect(ignore)]
    pub(crate) detail: StrandDetail,
}

impl SimulatedStrand {
    /// Builds the strand for `spec`, rooted on a head at `head` (world space when `None`).
    pub(crate) fn spawn(
        spec: &HairStrand,
        head: Option<ScaledPose>,
        default_material: &RodMaterial,
    ) -> Result<Self, StrandSpawnError> {
        let pose = head.unwrap_or_default();
        let local: Vec<DVec3> = spec.nodes.iter().map(|node| node.as_dvec3()).collect();
        let root = local.first().copied().unwrap_or_default();
        let world_root = pose.transform_point(root);
        let world: Vec<DVec3> = local.iter().map(|node| world_root + pose.rotation * (*node - root)).collect();
        let material_direction = spec.material_direction.as_dvec3();
        let material = spec.material.unwrap_or(*default_material);
        let mut rod = Rod::new(&world, pose.rotation * material_direction, material)?;
        if let Some(curvature) = spec.natural_curvature {
            if !curvature.is_finite() {
                return Err(StrandSpawnError::NonFiniteCurvature(curvature));
            }
            rod.set_natural_curvature(DVec2::new(f64::from(curvature.x), f64::from(curvature.y)))?;
        }
        if let Some(thickness) = spec.collision_thickness
            && !(thickness.is_finite() && thickness >= 0.0)
        {
            return Err(StrandSpawnError::InvalidCollisionThickness(thickness));
        }
        if !(0.0..=1.0).contains(&spec.gravity_preload) {
            return Err(StrandSpawnError::InvalidGravityPreload(spec.gravity_preload));
        }
        let anchor = head.map(|_| RootAnchor { position: root, edge: local[1] - root, material_direction });
        Ok(Self {
            rod,
            anchor,
            spawn_head: pose,
            head: pose,
            follows_default_material: spec.material.is_none(),
            collision_thickness: spec.collision_thickness.map(f64::from),
            last_report: None,
            snap_pose: true,
            health: StrandHealth::default(),
            pin_error: None,
            rod_written: false,
            pending_preload: (head.is_some() && spec.gravity_preload > 0.0).then_some(spec.gravity_preload),
            preload_report: None,
            stiffen_to_hold: spec.stiffen_to_hold,
            stiffening: 1.0,
            detail: StrandDetail::default(),
        })
    }

    /// The scale of its head when the strand was spawned (by which its root, head-local, was placed).
    pub(crate) fn spawn_scale(&self) -> DVec3 {
        self.spawn_head.scale
    }

    /// The simulated rod: node positions (m, world space) and velocities, frames, twist, rest shape.
    pub fn rod(&self) -> &Rod {
        &self.rod
    }

    /// The rod, to change it directly (its positions, boundary conditions, rest shape). The root edge is
    /// still clamped to the head at every step. A state that cannot be stepped (a non-finite position,
    /// nodes on top of each other) is found before the strand is next drawn, whether it is stepped then or
    /// not, and reported as a [`StrandFault`]: the strand is put back in its rest pose on its head.
    pub fn rod_mut(&mut self) -> &mut Rod {
        self.rod_written = true;
        &mut self.rod
    }

    /// Where the root edge is held on the head (`None` for a free strand).
    pub(crate) fn root_anchor(&self) -> Option<&RootAnchor> {
        self.anchor.as_ref()
    }

    /// Moves the root edge's anchor on the head (a root bound to a moving scalp triangle): the root node
    /// to `position` (head-local, m), the edge along the unit `direction` at its length, the material
    /// director along `material_direction`. The next clamp holds the root there. A free strand has none.
    pub(crate) fn move_root_anchor(&mut self, position: DVec3, direction: DVec3, material_direction: DVec3) {
        if let Some(anchor) = &mut self.anchor {
            anchor.position = position;
            anchor.edge = direction * anchor.edge.length();
            anchor.material_direction = material_direction;
        }
    }

    /// Gives the rod the rest shape `lengths`, `curvatures`, `twists` (see [`Rod::set_rest_shape`]); the
    /// root edge's anchor on the head takes the new length of the root edge.
    pub(crate) fn set_rest_shape(
        &mut self,
        lengths: &[f64],
        curvatures: &[DVec2],
        twists: &[f64],
    ) -> Result<(), RodError> {
        let old_root_length = self.rod.rest_lengths()[0];
        self.rod.set_rest_shape(lengths, curvatures, twists)?;
        if let Some(anchor) = &mut self.anchor {
            anchor.edge *= lengths[0] / old_root_length;
        }
        Ok(())
    }

    /// Asks for the rest shape to be preloaded against gravity before the next step, by `factor` (0 to 1;
    /// clamped), from the strand's shape then: see [`HairStrand::gravity_preload`]. For a strand with a
    /// head; a free strand is left as it is.
    pub fn preload_gravity(&mut self, factor: f32) {
        if self.anchor.is_some() {
            self.pending_preload = Some(factor.clamp(0.0, 1.0));
        }
    }

    /// What the last gravity preload did (`None` before one ran).
    pub fn preload_report(&self) -> Option<&PreloadReport> {
        self.preload_report.as_ref()
    }

    /// How many times stiffer than its material the strand bends and twists: more than 1 where the gravity
    /// preload stiffened it to hold its shape ([`HairStrand::stiffen_to_hold`]).
    pub fn stiffening(&self) -> f64 {
        self.stiffening
    }

    /// Runs a pending gravity preload under `gravity` (m/s²), with the nodes resting on colliders given
    /// the outward normals under them in `supports`, stiffening the strand first where it is asked to
    /// hold its shape; returns whether one ran.
    pub(crate) fn run_pending_preload(&mut self, gravity: DVec3, supports: &[Option<DVec3>]) -> Result<bool, RodError> {
        let Some(factor) = self.pending_preload.take() else {
            return Ok(false);
        };
        if self.stiffen_to_hold && factor > 0.0 {
            let more = self.rod.stiffening_to_hold(gravity, supports);
            if more > 1.0 {
                self.rod.set_material(self.rod.material().stiffened(more))?;
                self.stiffening *= more;
            }
        }
        self.preload_report = Some(self.rod.preload_for_gravity(gravity, supports, f64::from(factor))?);
        Ok(true)
    }

    /// Whether a gravity preload waits for the next step.
    pub(crate) fn preload_pending(&self) -> bool {
        self.pending_preload.is_some()
    }

    /// Distance from the centre line that stays outside colliders, m, with a collision margin of
    /// `margin` m ([`HairSettings::collision_margin`]): the strand's own
    /// [`HairStrand::collision_thickness`], or its larger semi-axis plus `margin`.
    pub fn collision_thickness(&self, margin: f32) -> f32 {
        self.contact_thickness(f64::from(margin)) as f32
    }

    /// [`SimulatedStrand::collision_thickness`] in double precision, for the step.
    pub(crate) fn contact_thickness(&self, margin: f64) -> f64 {
        let material = self.rod.material();
        self.collision_thickness.unwrap_or(material.semi_axis_1.max(material.semi_axis_2) + margin)
    }

    /// What the last successful step measured.
    pub fn last_report(&self) -> Option<&StepReport> {
        self.last_report.as_ref()
    }

    /// The strand's record of failures and quarantine.
    pub fn health(&self) -> &StrandHealth {
        &self.health
    }

    /// Whether the strand is held in quarantine (see [`SimulatedStrand`]).
    pub fn is_quarantined(&self) -> bool {
        self.health.quarantined_until.is_some()
    }

    /// The rigid motion that carries the strand's groomed pose ([`Rod::initial_positions`], where it was
    /// spawned) to where its head is at the end of this fixed step (once its root is pinned); `None` for
    /// a strand without a head.
    pub(crate) fn groomed_pose_motion(&self) -> Option<(DQuat, DVec3)> {
        self.anchor.is_some().then(|| self.spawn_head.rigid_motion_to(&self.detail.head))
    }

    /// The rigid motion that carries the strand's groomed pose to where its head was when this strand's
    /// coming step starts (where its rod is); `None` for a strand without a head.
    pub(crate) fn groomed_pose_motion_at_start(&self) -> Option<(DQuat, DVec3)> {
        self.anchor.is_some().then(|| self.spawn_head.rigid_motion_to(&self.head))
    }

    /// The strand's groomed pose ([`Rod::initial_positions`]) in its head's local space (rigidly, without
    /// the head's scale), where the style hold draws it; `None` for a strand without a head.
    #[cfg(feature = "gpu")]
    pub(crate) fn groomed_in_head(&self) -> Option<Vec<DVec3>> {
        self.anchor.is_some().then(|| {
            let (rotation, translation) = self.spawn_head.rigid_motion_to(&ScaledPose::default());
            self.rod.initial_positions().iter().map(|&place| rotation * place + translation).collect()
        })
    }

    /// Puts the strand back in its rest pose on its head, at rest.
    pub fn reset_to_rest(&mut self) {
        self.rod.reset();
        let (rotation, translation) = self.spawn_head.rigid_motion_to(&self.head);
        // Head poses are checked finite and their rotations normalised when recorded (`track_heads`).
        if let Err(error) = self.rod.transform_rigidly(rotation, translation) {
            warn_once!("a hair strand's rest pose could not be carried to its head: {error}");
        }
        self.snap_pose = true;
    }

    /// Follows the head to `pose`: clamps the root edge to its anchor there. A teleported head carries the
    /// whole strand along rigidly first. A pose the root cannot follow is reported by the next step.
    ///
    /// A strand not stepped at this fixed step (a coarser level of detail, see [`crate::detail`]) leaves
    /// its rod where it is, and follows the head (and any teleport in between) at its next step. While
    /// `held` (the settings are invalid) the strand is not stepped and its clock stands still: it is
    /// drawn carried with its head, and comes back as from being carried once the settings are fixed.
    pub(crate) fn follow_head(&mut self, motion: &HeadMotion, dt: f64, held: bool) {
        let Some(anchor) = self.anchor else {
            return;
        };
        let (pose, teleported) = (motion.current, motion.teleported);
        let detail = &mut self.detail;
        detail.head = pose;
        detail.held = held;
        if held {
            detail.resumed = true;
            return;
        }
        detail.elapsed += 1;
        if !detail.due {
            detail.teleported |= teleported;
            return;
        }
        let resumed = std::mem::take(&mut detail.resumed);
        let teleported = teleported || resumed || std::mem::take(&mut detail.teleported);
        if teleported {
            detail.elapsed = 1;
            if let Err(error) = self.carry_to(pose) {
                self.pin_error = Some(error);
                return;
            }
            self.snap_pose = true;
        }
        // The rod stays at `self.head` until its step brings the root to the clamp (see `advance`).
        let (start, end, material_direction) = anchor.world(&pose);
        if let Err(error) = self.rod.clamp_edge(0, start, end, material_direction) {
            self.pin_error = Some(error);
        }
        if resumed && dt > 0.0 {
            self.move_with_head(motion, dt);
        }
    }

    /// Carries the rod rigidly from the head pose it is at to `pose`, which it is then at.
    fn carry_to(&mut self, pose: ScaledPose) -> Result<(), RodError> {
        let (rotation, translation) = self.head.rigid_motion_to(&pose);
        self.rod.transform_rigidly(rotation, translation)?;
        self.head = pose;
        Ok(())
    }

    /// Gives every node the velocity it has moving rigidly with the head over the last fixed step of
    /// `dt` s, and starts the integrator afresh: hair that comes back from being carried (see
    /// [`crate::detail`]) moves with its head, not with the velocities it had when it was set aside.
    fn move_with_head(&mut self, motion: &HeadMotion, dt: f64) {
        let (rotation, translation) = motion.previous.rigid_motion_to(&motion.current);
        let back = rotation.inverse();
        let state = &mut self.rod.state;
        for (velocity, &position) in state.velocities.iter_mut().zip(&state.positions) {
            *velocity = (position - back * (position - translation)) / dt;
        }
        state.twist_rates.fill(0.0);
        state.history.dt = 0.0;
    }

    /// The start of a step at simulated time `now` (s): what [`SimulatedStrand::finish_advance`] needs,
    /// or the outcome when the strand is not to be stepped (quarantined: held in its rest pose).
    pub(crate) fn begin_advance(&mut self, now: f64) -> Result<AdvanceStart, StepOutcome> {
        self.rod_written = false;
        // The step brings the root to its clamp at the head's pose now: the rod is at that pose after it,
        // whatever happens (stepped, reset onto the head, or carried there when the step is skipped).
        let to = if self.anchor.is_some() { self.detail.head } else { self.head };
        let retried = match self.health.quarantined_until {
            Some(until) if now < until => {
                self.head = to;
                self.reset_to_rest();
                self.pin_error = None;
                return Err(StepOutcome::Held);
            }
            Some(_) => true,
            None => false,
        };
        Ok(AdvanceStart { to, retried })
    }

    /// The error that keeps the root from following its head at this step, if any: the step is then
    /// skipped ([`StepError::InvalidInput`]).
    pub(crate) fn take_pin_error(&mut self) -> Option<RodError> {
        self.pin_error.take()
    }

    /// The rod, to be stepped between [`SimulatedStrand::begin_advance`] and
    /// [`SimulatedStrand::finish_advance`].
    pub(crate) fn rod_to_step(&mut self) -> &mut Rod {
        &mut self.rod
    }

    /// The end of a step begun with [`SimulatedStrand::begin_advance`], whose rod step gave `result`:
    /// records a success, or handles the fault (see [`SimulatedStrand`]).
    pub(crate) fn finish_advance(
        &mut self,
        now: f64,
        AdvanceStart { to, retried }: AdvanceStart,
        result: Result<StepReport, StepError>,
    ) -> StepOutcome {
        let error = match result {
            Ok(report) => {
                self.head = to;
                let health = &mut self.health;
                self.last_report = Some(report);
                health.quarantined_until = None;
                if health.faults_in_episode > 0 && now - health.last_fault > QUARANTINE_WINDOW {
                    *health = StrandHealth::default();
                }
                return StepOutcome::Stepped(report);
            }
            Err(error) => error,
        };
        if !matches!(error, StepError::InvalidInput(_)) {
            // Put back in its rest pose on the head (by `fail`).
            self.head = to;
        } else if let Err(carry_error) = self.carry_to(to) {
            // Skipped: nothing moved, so the rod is carried to the head as hair not stepped is.
            warn_once!("a hair strand whose step was skipped could not be carried with its head: {carry_error}");
        }
        self.fail(error, now, retried)
    }

    /// Checks the state of a strand that is not stepped at this fixed step, if it was written from outside
    /// ([`SimulatedStrand::rod_mut`]) since it was last checked: one that cannot be stepped is handled as a
    /// failed step (reset to its rest pose on its head, quarantined if it fails again soon), so that it is
    /// never drawn. `None` when there was nothing to find.
    pub(crate) fn check_unstepped(&mut self, now: f64) -> Option<StepOutcome> {
        if !std::mem::take(&mut self.rod_written) {
            return None;
        }
        let (node, reason) = self.rod.unusable_state()?;
        Some(self.fail(StepError::UnusableState { node, reason }, now, false))
    }

    /// Takes back a strand that failed on the GPU (`error`, the last) again soon after each reset there:
    /// recorded as a fault that quarantines it at its rest pose, as a strand of the CPU's own failing again
    /// soon after a failure, so that it is retried once, later, and not failed again at once. Returns the
    /// quarantine's length, s.
    #[cfg(feature = "gpu")]
    pub(crate) fn take_back_in_quarantine(&mut self, error: StepError, now: f64) -> Option<f64> {
        match self.fail(error, now, true) {
            StepOutcome::Faulted { quarantine, .. } => quarantine,
            _ => None,
        }
    }

    /// Records a fault at `now` (s): starts or continues the episode, quarantines the strand if it failed
    /// again soon (or on a retry after quarantine, `retried`), and puts it back in its rest pose unless
    /// the step was only skipped for invalid input.
    fn fail(&mut self, error: StepError, now: f64, retried: bool) -> StepOutcome {
        let health = &mut self.health;
        let first_of_episode = health.faults_in_episode == 0;
        let again = retried || (!first_of_episode && now - health.last_fault <= QUARANTINE_WINDOW);
        health.faults_in_episode += 1;
        health.last_fault = now;
        let quarantine = again.then(|| {
            let seconds = (FIRST_QUARANTINE * 2f64.powi(health.quarantines_in_episode as i32)).min(MAX_QUARANTINE);
            health.quarantines_in_episode += 1;
            health.quarantined_until = Some(now + seconds);
            seconds
        });
        if quarantine.is_some() || !matches!(error, StepError::InvalidInput(_)) {
            self.reset_to_rest();
        }
        StepOutcome::Faulted { error, first_of_episode, quarantine }
    }

    /// Uses `material` (stiffened as the strand was to hold its shape) if the strand follows the default
    /// material.
    pub(crate) fn follow_default_material(&mut self, material: &RodMaterial) -> Result<(), RodError> {
        let material = material.stiffened(self.stiffening);
        if self.follows_default_material && *self.rod.material() != material {
            self.rod.set_material(material)?;
        }
        Ok(())
    }

    /// The level of detail the strand was simulated at in the last fixed step (see [`crate::detail`]).
    pub fn detail_level(&self) -> HairDetailLevel {
        self.detail.level
    }

    /// Whether the strand is stepped in this fixed step (decided before [`crate::schedule::HairSystems::PinRoots`]
    /// ends): at full detail always, at a coarser level on its turns.
    pub fn steps_now(&self) -> bool {
        self.detail.due
    }

    /// The length of the step the strand takes at this fixed step if it is stepped, in fixed steps (known
    /// once its root is pinned): one at full detail, the fixed steps since its last step at a coarser level.
    pub fn step_length(&self) -> u32 {
        self.detail.elapsed.max(1)
    }

    /// Sets the strand's level of detail at this fixed step, and whether it is stepped in it.
    pub(crate) fn set_detail(&mut self, level: HairDetailLevel, due: bool) {
        if self.detail.level == HairDetailLevel::Carried && level != HairDetailLevel::Carried {
            // Back from being carried: carried rigidly to its head first, then simulated from there.
            self.detail.resumed = true;
        }
        (self.detail.level, self.detail.due) = (level, due);
    }

    /// Writes the strand's [`StrandNodes`] and [`StrandFrames`] after this fixed step: the rod as it is, or
    /// at a coarser level of detail the drawn shape carried with the head (see [`crate::detail`]).
    /// `stepped` is the length in fixed steps of the step just taken, `None` if none was. Returns whether
    /// the drawn pose jumped there (spawned, reset or teleported: nothing to interpolate from).
    pub(crate) fn write_components(
        &mut self,
        stepped: Option<u32>,
        nodes: &mut StrandNodes,
        frames: &mut StrandFrames,
    ) -> bool {
        if self.detail.draws_simulation() {
            return write_strand_data(self, nodes, frames);
        }
        let snap = self.take_snap();
        let Self { detail, rod, head, .. } = self;
        detail.write_drawn(rod, head, stepped.is_some(), snap, nodes, frames);
        snap
    }

    /// Whether the drawn pose must jump to the strand (spawned, reset or teleported) rather than
    /// interpolate; clears the flag.
    pub(crate) fn take_snap(&mut self) -> bool {
        std::mem::take(&mut self.snap_pose)
    }
}

/// What acts on a strand's nodes from outside for the coming step: forces (N; a hand, a custom field,
/// the hair's volume pressure), the air's velocity (m/s; wind, see [`crate::wind`]), against which the
/// air drag of [`HairSettings::air_damping`] acts, and changes of velocity (m/s; the hair–hair velocity
/// smoothing of [`crate::volume`]). Add them in [`crate::schedule::HairSystems::ExternalForces`]; they are
/// cleared after each step. Gravity is applied by the plugin from [`HairSettings::gravity`].
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct StrandForces {
    forces: NodeVectors,
    air_velocities: NodeVectors,
    velocity_changes: NodeVectors,
}

impl StrandForces {
    /// Adds `force` (N) on `node`. Rejects a node index out of range.
    pub fn add(&mut self, node: usize, force: Vec3) -> Result<(), RodError> {
        self.forces.add(node, force)
    }

    /// Adds `force` (N) on every node.
    pub fn add_to_all(&mut self, force: Vec3) {
        self.forces.add_to_all(force);
    }

    /// The force on each node for the coming step, N (none before the strand is built).
    pub fn forces(&self) -> impl ExactSizeIterator<Item = Vec3> + '_ {
        self.forces.iter()
    }

    /// Adds `velocity` (m/s) to the air's velocity at `node`. Rejects a node index out of range.
    pub fn add_air_velocity(&mut self, node: usize, velocity: Vec3) -> Result<(), RodError> {
        self.air_velocities.add(node, velocity)
    }

    /// Adds `velocity` (m/s) to the air's velocity at every node.
    pub fn add_air_velocity_to_all(&mut self, velocity: Vec3) {
        self.air_velocities.add_to_all(velocity);
    }

    /// The air's velocity at each node for the coming step, m/s (still air: zero).
    pub fn air_velocities(&self) -> impl ExactSizeIterator<Item = Vec3> + '_ {
        self.air_velocities.iter()
    }

    /// Adds `change` (m/s) to `node`'s velocity at the start of the coming step: an impulse per mass
    /// (see [`StepLoads::velocity_changes`]). Rejects a node index out of range.
    pub fn add_velocity_change(&mut self, node: usize, change: Vec3) -> Result<(), RodError> {
        self.velocity_changes.add(node, change)
    }

    /// The change of each node's velocity at the start of the coming step, m/s: yours and the
    /// hair–hair interaction's ([`crate::volume`]).
    pub fn velocity_changes(&self) -> impl ExactSizeIterator<Item = Vec3> + '_ {
        self.velocity_changes.iter()
    }

    /// The loads for the mechanics core: only what was added since the last step. The style hold's
    /// springs are not among them: the step writes those itself (`style_hold::style_anchors`).
    pub(crate) fn loads(&self) -> StepLoads<'_> {
        StepLoads {
            forces: self.forces.active(),
            air_velocities: self.air_velocities.active(),
            velocity_changes: self.velocity_changes.active(),
            anchors: None,
        }
    }

    /// Adds `at(node)`'s velocity change (m/s) to every node's, and its force (N) when `with_forces`,
    /// for the hair–hair interaction.
    pub(crate) fn add_velocity_changes_and_forces(
        &mut self,
        with_forces: bool,
        mut at: impl FnMut(usize) -> (DVec3, DVec3),
    ) {
        for (node, change) in self.velocity_changes.values.iter_mut().enumerate() {
            let (add_change, add_force) = at(node);
            *change += add_change;
            if with_forces {
                self.forces.values[node] += add_force;
            }
        }
        self.velocity_changes.active |= !self.velocity_changes.values.is_empty();
        self.forces.active |= with_forces && !self.forces.values.is_empty();
    }

    /// The forces added since the last step (N), if any: for a step elsewhere (the GPU's).
    #[cfg(feature = "gpu")]
    pub(crate) fn active_forces(&self) -> Option<&[DVec3]> {
        self.forces.active()
    }

    /// The velocity changes added since the last step (m/s), if any: for a step elsewhere (the GPU's).
    #[cfg(feature = "gpu")]
    pub(crate) fn active_velocity_changes(&self) -> Option<&[DVec3]> {
        self.velocity_changes.active()
    }

    /// The air velocities added since the last step (m/s), if any: for a step elsewhere (the GPU's, which
    /// samples the wind itself; the wind leaves the strands stepped elsewhere out, so these are a game's).
    #[cfg(feature = "gpu")]
    pub(crate) fn active_air_velocities(&self) -> Option<&[DVec3]> {
        self.air_velocities.active()
    }

    /// Sets the air's velocity at every node (m/s) from `velocity_at(node)`, for the wind.
    pub(crate) fn add_air_velocities(&mut self, mut velocity_at: impl FnMut(usize) -> DVec3) {
        for (node, slot) in self.air_velocities.values.iter_mut().enumerate() {
            *slot += velocity_at(node);
        }
        self.air_velocities.active = !self.air_velocities.values.is_empty();
    }

    pub(crate) fn clear(&mut self) {
        self.forces.clear();
        self.air_velocities.clear();
        self.velocity_changes.clear();
    }

    fn resize(&mut self, nodes: usize) {
        self.forces.resize(nodes);
        self.air_velocities.resize(nodes);
        self.velocity_changes.resize(nodes);
    }
}

/// One vector per node, with whether any was set since the last clear (so that an untouched strand
/// costs nothing).
#[derive(Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Debug, Default, Clone)]
struct NodeVectors {
    values: Vec<DVec3>,
    active: bool,
}

impl NodeVectors {
    fn add(&mut self, node: usize, value: Vec3) -> Result<(), RodError> {
        let count = self.values.len();
        let slot = self.values.get_mut(node).ok_or(RodError::OutOfRange { what: "node", index: node, count })?;
        *slot += value.as_dvec3();
        self.active = true;
        Ok(())
    }

    fn add_to_all(&mut self, value: Vec3) {
        let value = value.as_dvec3();
        self.values.iter_mut().for_each(|slot| *slot += value);
        self.active = true;
    }

    fn iter(&self) -> impl ExactSizeIterator<Item = Vec3> + '_ {
        self.values.iter().map(|value| value.as_vec3())
    }

    fn active(&self) -> Option<&[DVec3]> {
        self.active.then_some(self.values.as_slice())
    }

    fn clear(&mut self) {
        if self.active {
            self.values.fill(DVec3::ZERO);
            self.active = false;
        }
    }

    fn resize(&mut self, nodes: usize) {
        self.values.clear();
        self.values.resize(nodes, DVec3::ZERO);
        self.active = false;
    }
}

/// A strand the CPU step leaves alone: something else steps it and writes its components (the GPU, with
/// [`HairGpuPlugin`](crate::render::HairGpuPlugin)). Its root is still pinned to its head at every step,
/// so that whoever steps it reads where its root is held from its rod. Removing the marker hands the
/// strand back to the CPU, from the state its rod has then.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct SteppedElsewhere;

/// Sent when a strand's step fails: which strand and why. A diverged strand (non-finite, over-strained,
/// degenerate) has been reset to its rest pose on its head; on invalid input (a non-finite force, a head
/// pose its root cannot follow) the step was skipped. A strand that failed again soon after is also
/// quarantined (see [`SimulatedStrand`]). The other strands are not affected.
///
/// Both a [`Message`] (read every strand's faults with a `MessageReader<StrandFault>`) and an
/// [`EntityEvent`] triggered on the strand (observe one strand's: `commands.entity(strand).observe(|fault:
/// On<StrandFault>| …)`).
#[derive(Message, EntityEvent, Debug, Clone, PartialEq)]
pub struct StrandFault {
    /// The strand entity.
    #[event_target]
    pub strand: Entity,
    /// What went wrong.
    pub error: StepError,
}

/// Strands with their spawn description, whether it was rejected, and the components built alongside
/// their rod.
type SpawnedStrands<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        Ref<'static, HairStrand>,
        Option<Ref<'static, StrandOf>>,
        Option<&'static StrandRejected>,
        &'static mut StrandForces,
        &'static mut StrandNodes,
        &'static mut StrandFrames,
        &'static mut StrandRestShape,
    ),
>;

/// Builds the simulated [`SimulatedStrand`] of every new or changed [`HairStrand`] (or one moved to another head
/// by a new [`StrandOf`]); rejects invalid ones with an error message naming the entity and the reason.
/// Rejected strands are tried again when [`HairSettings`] change (their default material may have been
/// what was wrong).
pub(crate) fn build_strands(
    mut commands: Commands,
    settings: Res<HairSettings>,
    transforms: bevy::transform::helper::TransformHelper,
    mut strands: SpawnedStrands,
) {
    for (entity, spec, strand_of, rejected, mut forces, mut nodes, mut frames, mut rest_shape) in &mut strands {
        let changed = spec.is_changed() || strand_of.as_ref().is_some_and(Ref::is_changed);
        // An invalid default material is reported once, as invalid settings, not per strand; strands that
        // use it wait for it to be fixed before they are tried again.
        let settings_reported = spec.material.is_none() && settings.default_material.validate().is_err();
        let retry = rejected.is_some_and(|rejected| rejected.waits_for_head || settings.is_changed());
        if !(changed || retry && !settings_reported) {
            continue;
        }
        let strand_of = strand_of.map(|strand_of| *strand_of);
        let head = strand_of
            .map(|StrandOf(head)| {
                transforms
                    .compute_global_transform(head)
                    .map_err(|error| error.to_string())
                    .map(|transform| ScaledPose::from(&transform))
                    .and_then(|pose| pose.is_usable().then_some(pose).ok_or("not finite, or of zero scale".to_string()))
                    .map_err(|reason| StrandSpawnError::Head { head, reason })
            })
            .transpose();
        match head.and_then(|head| SimulatedStrand::spawn(&spec, head, &settings.default_material)) {
            Ok(strand) => {
                forces.resize(strand.rod.node_count());
                nodes.update(strand.rod.state(), true);
                frames.update(strand.rod.frames(), strand.rod.twist_angles());
                rest_shape.update(&strand.rod);
                commands.entity(entity).try_remove::<StrandRejected>().try_insert(strand);
            }
            Err(error) => {
                let waits_for_head = matches!(error, StrandSpawnError::Head { .. });
                let reason = error.to_string();
                // A retry that fails for the same reason is not news.
                let news = changed || rejected.is_none_or(|rejected| rejected.reason != reason);
                if news && !waits_for_head && !settings_reported {
                    error!("hair strand {entity} rejected: {reason}");
                }
                commands
                    .entity(entity)
                    .try_remove::<SimulatedStrand>()
                    .try_insert(StrandRejected { reason, waits_for_head });
            }
        }
    }
}

/// Copies a strand's simulated state into its [`StrandNodes`] and [`StrandFrames`] (after its step);
/// returns whether the previous positions jumped to the new ones.
pub(crate) fn write_strand_data(
    strand: &mut SimulatedStrand,
    nodes: &mut StrandNodes,
    frames: &mut StrandFrames,
) -> bool {
    let snap = strand.take_snap();
    let rod = strand.rod();
    nodes.update(rod.state(), snap);
    frames.update(rod.frames(), rod.twist_angles());
    snap
}

/// Gives every strand whose [`StrandRestShape`] was edited its new rest shape; an edit the rod rejects is
/// logged and undone.
pub(crate) fn apply_rest_shape_edits(
    mut strands: Query<(Entity, &mut SimulatedStrand, &mut StrandRestShape), Changed<StrandRestShape>>,
    mut scratch: Local<RestShapeScratch>,
) {
    for (entity, mut strand, mut shape) in &mut strands {
        if !shape.differs_from(strand.rod()) {
            continue;
        }
        shape.merge_into(strand.rod(), &mut scratch);
        if let Err(error) = strand.set_rest_shape(&scratch.lengths, &scratch.curvatures, &scratch.twists) {
            error!("hair strand {entity}: the edited StrandRestShape was rejected and undone: {error}");
            shape.update(strand.rod());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn air_velocities_add_up_and_are_used_up_by_the_step() {
        let mut forces = StrandForces::default();
        forces.resize(3);
        assert!(forces.loads().air_velocities.is_none(), "still air costs the step nothing");
        // The wind's sample and a game's on top: the step's air is the sum.
        forces.add_air_velocities(|node| DVec3::new(node as f64, 0.0, 0.0));
        forces.add_air_velocity(1, Vec3::Z).unwrap();
        forces.add_air_velocity_to_all(Vec3::Y);
        let air: Vec<Vec3> = forces.air_velocities().collect();
        assert_eq!(air, [Vec3::Y, Vec3::new(1.0, 1.0, 1.0), Vec3::new(2.0, 1.0, 0.0)]);
        assert!(forces.add_air_velocity(3, Vec3::X).is_err(), "a node out of range is refused");
        forces.clear();
        assert!(forces.loads().air_velocities.is_none(), "cleared after the step");
        assert!(forces.air_velocities().all(|velocity| velocity == Vec3::ZERO));
    }
}
