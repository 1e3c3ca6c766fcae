//! Strand components: the shape a strand is spawned from, its simulated state, the forces users apply
//! to it and the pose it is drawn in.

use bevy::math::{DVec2, DVec3};
use bevy::prelude::*;
use thiserror::Error;

use crate::head::{HeadPose, StrandOf};
use crate::rod::{Contacts, Rod, RodError, RodMaterial, RodWorkspace, StepError, StepParams, StepReport};
use crate::settings::HairSettings;

/// A hair strand to simulate, as it is spawned. Add it (with [`StrandOf`] to root it on a head) and the
/// plugin builds its simulated [`Strand`] at the next fixed step. Changing it (or its `StrandOf`) later
/// respawns the strand.
///
/// The spawned shape is the rest shape: a curly strand spawned as a helix keeps its curls.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone, PartialEq)]
#[require(StrandForces, StrandPose)]
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
/// is not simulated until its `HairStrand` is changed into a valid one.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone)]
pub struct StrandRejected {
    /// What was wrong.
    pub reason: String,
}

/// Where a strand's root edge is held in its head's local space, with its material frame.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Clone)]
pub struct RootAnchor {
    /// Root node, head-local, m (scaled with the head).
    pub position: DVec3,
    /// The root edge `x_1 − x_0`, head-local, m (turned with the head, never scaled).
    pub edge: DVec3,
    /// Direction of the root edge's material director `m1`, head-local.
    pub material_direction: DVec3,
}

impl RootAnchor {
    /// World positions of the root edge's two nodes and its material direction, for a head at `pose`.
    pub fn world(&self, pose: &HeadPose) -> (DVec3, DVec3, DVec3) {
        let root = pose.transform_point(self.position);
        (root, root + pose.rotation * self.edge, pose.rotation * self.material_direction)
    }
}

/// The simulated state of a strand, built by the plugin from its [`HairStrand`]: the rod (node positions
/// and velocities, edge frames and twists, rest lengths, rest curvatures and twists, material; see
/// [`Rod`]) and its root anchor on the head, contiguous per strand. The solver's scratch memory is not
/// here: one workspace per thread serves all the strands that thread steps, and stays in its cache.
#[derive(Component, Reflect, Debug, Clone)]
#[reflect(Component, Debug)]
pub struct Strand {
    rod: Rod,
    anchor: Option<RootAnchor>,
    spawn_head: HeadPose,
    head: HeadPose,
    follows_default_material: bool,
    collision_thickness: Option<f64>,
    last_report: Option<StepReport>,
    snap_pose: bool,
}

impl Strand {
    /// Builds the strand for `spec`, rooted on a head at `head` (world space when `None`).
    pub fn spawn(
        spec: &HairStrand,
        head: Option<HeadPose>,
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
            rod.set_natural_curvature(DVec2::new(f64::from(curvature.x), f64::from(curvature.y)));
        }
        if let Some(thickness) = spec.collision_thickness
            && !(thickness.is_finite() && thickness >= 0.0)
        {
            return Err(StrandSpawnError::InvalidCollisionThickness(thickness));
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
        })
    }

    /// The simulated rod: node positions (m, world space) and velocities, frames, twist, rest shape.
    pub fn rod(&self) -> &Rod {
        &self.rod
    }

    /// The rod, to change it directly (its positions, boundary conditions, rest shape). The root edge is
    /// still clamped to the head at every step.
    pub fn rod_mut(&mut self) -> &mut Rod {
        &mut self.rod
    }

    /// Where the root edge is held on the head, in the head's local space; `None` for a free strand.
    pub fn anchor(&self) -> Option<&RootAnchor> {
        self.anchor.as_ref()
    }

    /// The head's world pose at the last step (identity for a free strand).
    pub fn head_pose(&self) -> &HeadPose {
        &self.head
    }

    /// Distance from the centre line that stays outside colliders, m, with a collision margin of
    /// `margin` m: the strand's own [`HairStrand::collision_thickness`], or its larger semi-axis plus
    /// `margin`.
    pub fn collision_thickness(&self, margin: f64) -> f64 {
        let material = self.rod.material();
        self.collision_thickness.unwrap_or(material.semi_axis_1.max(material.semi_axis_2) + margin)
    }

    /// What the last successful step measured.
    pub fn last_report(&self) -> Option<&StepReport> {
        self.last_report.as_ref()
    }

    /// Puts the strand back in its rest pose on its head, at rest.
    pub fn reset_to_rest(&mut self) {
        self.rod.reset();
        let (rotation, translation) = self.spawn_head.rigid_motion_to(&self.head);
        self.rod.transform_rigidly(rotation, translation);
        self.snap_pose = true;
    }

    /// Follows the head to `pose`: clamps the root edge to its anchor there. A teleported head carries the
    /// whole strand along rigidly first.
    pub(crate) fn follow_head(&mut self, pose: HeadPose, teleported: bool) -> Result<(), RodError> {
        let Some(anchor) = self.anchor else {
            return Ok(());
        };
        if teleported {
            let (rotation, translation) = self.head.rigid_motion_to(&pose);
            self.rod.transform_rigidly(rotation, translation);
            self.snap_pose = true;
        }
        self.head = pose;
        let (start, end, material_direction) = anchor.world(&pose);
        self.rod.clamp_edge(0, start, end, material_direction)
    }

    /// Advances the strand by one step, kept outside the colliders of `contacts`, with the calling
    /// thread's `workspace`. A step that fails on invalid input (a non-finite force) changes nothing;
    /// any other failure (divergence) resets the strand to its rest pose on its head.
    pub(crate) fn advance(
        &mut self,
        params: &StepParams,
        forces: &StrandForces,
        contacts: &Contacts,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        let result = self.rod.step_with_contacts(params, forces.active(), contacts, workspace);
        match &result {
            Ok(report) => self.last_report = Some(*report),
            Err(StepError::InvalidInput(_)) => {}
            Err(_) => self.reset_to_rest(),
        }
        result
    }

    /// Uses `material` if the strand follows the default material.
    pub(crate) fn follow_default_material(&mut self, material: &RodMaterial) -> Result<(), RodError> {
        if self.follows_default_material && self.rod.material() != material {
            self.rod.set_material(*material)?;
        }
        Ok(())
    }

    /// Whether the drawn pose must jump to the strand (spawned, reset or teleported) rather than
    /// interpolate; clears the flag.
    pub(crate) fn take_snap(&mut self) -> bool {
        std::mem::take(&mut self.snap_pose)
    }
}

/// External forces on a strand's nodes for the coming step, N (wind, a hand, a custom field). Add them
/// in [`crate::HairSystems::ExternalForces`]; they are cleared after each step. Gravity is applied by the
/// plugin from [`HairSettings::gravity`].
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct StrandForces {
    forces: Vec<DVec3>,
    active: bool,
}

impl StrandForces {
    /// Adds `force` (N) on `node`. Rejects a node index out of range.
    pub fn add(&mut self, node: usize, force: Vec3) -> Result<(), RodError> {
        let count = self.forces.len();
        let slot = self.forces.get_mut(node).ok_or(RodError::OutOfRange { what: "node", index: node, count })?;
        *slot += force.as_dvec3();
        self.active = true;
        Ok(())
    }

    /// Adds `force` (N) on every node.
    pub fn add_to_all(&mut self, force: Vec3) {
        let force = force.as_dvec3();
        self.forces.iter_mut().for_each(|slot| *slot += force);
        self.active = true;
    }

    /// The forces on each node, N (empty before the strand is built).
    pub fn forces(&self) -> &[DVec3] {
        &self.forces
    }

    fn active(&self) -> Option<&[DVec3]> {
        self.active.then_some(self.forces.as_slice())
    }

    pub(crate) fn clear(&mut self) {
        if self.active {
            self.forces.fill(DVec3::ZERO);
            self.active = false;
        }
    }

    fn resize(&mut self, nodes: usize) {
        self.forces.clear();
        self.forces.resize(nodes, DVec3::ZERO);
        self.active = false;
    }
}

/// A strand's node positions at the last two steps, m, single precision: what is drawn, interpolated
/// between steps.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct StrandPose {
    /// Node positions after the previous step.
    pub previous: Vec<Vec3>,
    /// Node positions after the last step.
    pub current: Vec<Vec3>,
}

impl StrandPose {
    /// Node positions a fraction `alpha` (0 to 1) of the way from the previous step to the last.
    pub fn interpolated(&self, alpha: f32) -> impl Iterator<Item = Vec3> + '_ {
        self.previous.iter().zip(&self.current).map(move |(previous, current)| previous.lerp(*current, alpha))
    }

    pub(crate) fn update(&mut self, positions: &[DVec3], snap: bool) {
        std::mem::swap(&mut self.previous, &mut self.current);
        self.current.clear();
        self.current.extend(positions.iter().map(|position| position.as_vec3()));
        if snap || self.previous.len() != self.current.len() {
            self.previous.clone_from(&self.current);
        }
    }
}

/// Sent when a strand's step fails: which strand and why. A diverged strand (non-finite, over-strained,
/// degenerate) has been reset to its rest pose on its head; on invalid input (a non-finite force) the
/// step was skipped. The other strands are not affected.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct StrandFault {
    /// The strand entity.
    pub strand: Entity,
    /// What went wrong.
    pub error: StepError,
}

/// Strands whose spawn description is new or changed, with the components built alongside their rod.
type ChangedStrands<'w, 's> = Query<
    'w,
    's,
    (Entity, &'static HairStrand, Option<&'static StrandOf>, &'static mut StrandForces, &'static mut StrandPose),
    Or<(Changed<HairStrand>, Changed<StrandOf>)>,
>;

/// Builds the simulated [`Strand`] of every new or changed [`HairStrand`] (or one moved to another head
/// by a new [`StrandOf`]); rejects invalid ones with an
/// error message naming the entity and the reason.
pub(crate) fn build_strands(
    mut commands: Commands,
    settings: Res<HairSettings>,
    transforms: bevy::transform::helper::TransformHelper,
    mut strands: ChangedStrands,
) {
    for (entity, spec, strand_of, mut forces, mut pose) in &mut strands {
        let head = strand_of
            .map(|&StrandOf(head)| {
                transforms
                    .compute_global_transform(head)
                    .map(|transform| HeadPose::from(&transform))
                    .map_err(|error| StrandSpawnError::Head { head, reason: error.to_string() })
            })
            .transpose();
        match head.and_then(|head| Strand::spawn(spec, head, &settings.default_material)) {
            Ok(strand) => {
                forces.resize(strand.rod.node_count());
                pose.update(strand.rod.positions(), true);
                commands.entity(entity).try_remove::<StrandRejected>().try_insert(strand);
            }
            Err(error) => {
                error!("hair strand {entity} rejected: {error}");
                commands.entity(entity).try_remove::<Strand>().try_insert(StrandRejected { reason: error.to_string() });
            }
        }
    }
}
