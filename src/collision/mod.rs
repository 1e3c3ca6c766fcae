//! Colliders: solids that hair rests on and cannot pass through (a skull, a neck, shoulders, a floor),
//! with Coulomb friction.
//!
//! Put a [`HairCollider`] on any entity; it moves with the entity's transform (through its parents).
//! Which strands meet it:
//! - a collider with [`HairColliderOf`] belongs to that head: its strands meet it, other heads' do not;
//! - a collider with no head (a floor, a wall), or one marked [`SharedHairCollider`], is met by every
//!   strand, free strands too;
//! - a head's [`HairCollisionFilter`] adds other heads' colliders and leaves out any collider.
//!
//! Contact is handled inside each strand's implicit step (see [`crate::rod::Contacts`]): at the start of
//! every fixed step, [`HairCollisionPlugin`] records each collider's pose and gathers, per head, the
//! colliders its strands meet with their poses at the last step and at this one, so a collider that moves
//! or turns fast sweeps hair along instead of passing through it.
//!
//! Cost: per strand and step, a ball test per node and collider of its head; per collider near the
//! strand, a cheap distance bound per nearby node and Newton iteration and exact tests only for nodes
//! that can touch it; one more Newton iteration for a strand whose node lands or starts to slide. A
//! head's colliders are gathered into one contiguous list each step, reusing its memory. Measured: the
//! collisions table of `docs/performance.md` in the repository
//! (`cargo run --release --example benchmark collisions`).

use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;

use crate::rod::{ColliderShape, MovingCollider, RigidPose};
use crate::schedule::HairPinSystems;
use crate::simulation::{HairHead, HairSettings, HeadStrands, ScaledPose};
pub use crate::simulation::{HeadColliderSet, SharedColliderSet};

#[cfg(feature = "avian")]
pub mod avian;
pub mod mesh;
#[cfg(feature = "avian")]
pub use avian::{AvianHairCollider, AvianHairColliderPart};
pub use mesh::{HairColliderFromMesh, MeshColliderBaking, MeshColliderError, MeshColliderSettings};

/// A solid that hair cannot pass through, in the local space of its entity's transform (scale included:
/// a sphere scaled unevenly becomes an ellipsoid). See the [module documentation](self) for which
/// strands meet it.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// # let mut world = World::new();
/// let head = world.spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
/// // The skull, on the head; a floor that every strand meets.
/// world.spawn((HairCollider::ellipsoid(Vec3::new(0.078, 0.095, 0.1)), HairColliderOf(head), ChildOf(head)));
/// world.spawn(HairCollider::plane().with_friction(0.6));
/// ```
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone, PartialEq)]
#[require(Transform, ColliderMotion)]
pub struct HairCollider {
    /// The solid, in the entity's local space, m.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient `μ` between hair and this collider, dimensionless (≥ 0): hair at rest
    /// on a slope of angle `α` stays put while `tan α < μ` and slides when steeper. Default
    /// [`HairCollider::DEFAULT_FRICTION`]. Hair on skin or cloth is about 0.2 to 0.6; contact is tested
    /// up to 2 (at 3, a strand landing on a ball jitters and slides off).
    pub friction: f32,
}

impl HairCollider {
    /// Friction of hair on skin and cloth, dimensionless: 0.4.
    pub const DEFAULT_FRICTION: f32 = 0.4;

    /// A collider of `shape` with the default friction.
    pub fn new(shape: ColliderShape) -> Self {
        Self { shape, friction: Self::DEFAULT_FRICTION }
    }

    /// A ball of `radius` m around the entity's origin.
    pub fn sphere(radius: f32) -> Self {
        Self::new(ColliderShape::sphere(f64::from(radius)))
    }

    /// A capsule of `radius` m around a segment `2 half_length` m long along the entity's local Y.
    pub fn capsule(radius: f32, half_length: f32) -> Self {
        Self::new(ColliderShape::capsule(f64::from(radius), f64::from(half_length)))
    }

    /// An ellipsoid with semi-axes `semi_axes` (m) along the entity's local X, Y and Z: a skull.
    pub fn ellipsoid(semi_axes: Vec3) -> Self {
        Self::new(ColliderShape::ellipsoid(semi_axes.as_dvec3()))
    }

    /// The half-space below the plane through the entity's origin with normal local +Y: a floor.
    pub fn plane() -> Self {
        Self::new(ColliderShape::Plane)
    }

    /// A box with half extents `half_extents` (m) along the entity's local X, Y and Z: a shoulder, a
    /// chair back, a hat's crown. Its sharp edges cost about twice as much to collide with as a rounded
    /// box's ([`HairCollider::rounded_cuboid`]), and four times a sphere's: a few millimetres of rounding,
    /// which real objects have anyway, halve that.
    pub fn cuboid(half_extents: Vec3) -> Self {
        Self::new(ColliderShape::cuboid(half_extents.as_dvec3()))
    }

    /// A box with half extents `half_extents` (m) whose edges and corners are rounded with radius
    /// `rounding` m (the solid reaches that far beyond the box).
    pub fn rounded_cuboid(half_extents: Vec3, rounding: f32) -> Self {
        Self::new(ColliderShape::Cuboid { half_extents: half_extents.as_dvec3(), rounding: f64::from(rounding) })
    }

    /// Uses friction coefficient `friction` (dimensionless, ≥ 0).
    pub fn with_friction(mut self, friction: f32) -> Self {
        self.friction = friction;
        self
    }

    /// This collider's shape scaled by `transform`'s scale, and the rigid pose that places it.
    pub(crate) fn placed(&self, transform: &GlobalTransform) -> (ColliderShape, RigidPose) {
        let ScaledPose { translation, rotation, scale } = ScaledPose::from(transform);
        (self.shape.scaled(scale), RigidPose::new(rotation, translation))
    }
}

/// Ties a collider to a head: that head's strands meet it (and, unless it is [`SharedHairCollider`], no
/// other head's). A relationship like [`ChildOf`], independent of the transform hierarchy: a shoulder
/// collider can be a child of the body and belong to the head that rests on it.
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq, Eq)]
#[reflect(Component, Debug, PartialEq, Clone)]
#[relationship(relationship_target = HeadColliders)]
pub struct HairColliderOf(pub Entity);

/// The colliders tied to a head with [`HairColliderOf`], kept by Bevy.
#[derive(Component, Reflect, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default)]
#[relationship_target(relationship = HairColliderOf)]
pub struct HeadColliders(Vec<Entity>);

impl HeadColliders {
    /// The collider entities tied to this head.
    pub fn colliders(&self) -> &[Entity] {
        &self.0
    }
}

/// Marks a head's collider as met by every strand, of every head and free, as a collider with no head
/// is.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct SharedHairCollider;

/// Which colliders a head's strands meet besides its own and the shared ones. Each entry is a collider
/// or a head (standing for all its colliders).
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct HairCollisionFilter {
    /// Colliders, or heads' colliders, that this head's strands also meet: another character's body.
    pub include: Vec<Entity>,
    /// Colliders, or heads' colliders, that this head's strands pass through, even its own or shared
    /// ones. Wins over `include`.
    pub exclude: Vec<Entity>,
}

/// Where a collider was at the last two fixed steps, in world space, with its shape scaled by its
/// transform; kept by the plugin.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct ColliderMotion {
    /// The collider over the last step: its world shape, friction and poses at the previous and current
    /// step. `None` until the collider has a valid shape and transform.
    pub collider: Option<MovingCollider>,
    /// Why the collider is not used, while it is not.
    pub rejected: Option<String>,
}

impl ColliderMotion {
    /// Records the pose for this step: the collider sweeps from its last pose, unless it moved farther
    /// than `teleport_distance` m, which puts it at `pose` directly.
    fn advance(&mut self, shape: ColliderShape, friction: f64, pose: RigidPose, teleport_distance: f64) {
        let start = match &self.collider {
            Some(last) if last.end.translation.distance(pose.translation) <= teleport_distance => last.end,
            _ => pose,
        };
        self.collider = Some(MovingCollider { shape, friction, start, end: pose });
        self.rejected = None;
    }

    /// Stops using the collider, logging `reason` when it is new.
    fn reject(&mut self, entity: Entity, reason: String) {
        if self.rejected.as_ref() != Some(&reason) {
            error!("hair collider {entity} is not used: {reason}");
        }
        self.collider = None;
        self.rejected = Some(reason);
    }
}

/// Collisions of hair with [`HairCollider`]s: tracks colliders and gathers each head's set every fixed
/// step, in [`crate::schedule::HairSystems::PinRoots`]; the strands' steps then keep their nodes outside. Part of
/// [`crate::HairPlugins`]; without it, hair passes through everything.
#[derive(Debug, Clone)]
pub struct HairCollisionPlugin {
    /// The fixed-timestep schedule the simulation runs in (that of [`crate::HairSimulationPlugin`]).
    pub schedule: bevy::ecs::schedule::InternedScheduleLabel,
}

impl Plugin for HairCollisionPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairCollider>()
            .register_type::<HairColliderOf>()
            .register_type::<HeadColliders>()
            .register_type::<SharedHairCollider>()
            .register_type::<HairCollisionFilter>()
            .register_type::<ColliderMotion>()
            .register_type::<ColliderShape>()
            .init_resource::<SharedColliderSet>()
            .register_required_components::<HairHead, HeadColliderSet>()
            .register_required_components::<HeadStrands, HeadColliderSet>()
            .register_type::<HairColliderFromMesh>()
            .add_systems(self.schedule, (track_colliders, gather_colliders).chain().in_set(HairPinSystems::Colliders))
            .add_systems(Update, (mesh::start_mesh_bakes, mesh::finish_mesh_bakes).chain());
        #[cfg(feature = "avian")]
        avian::build(app, self.schedule);
    }
}

/// Records every collider's world pose and shape for this step.
pub(crate) fn track_colliders(
    settings: Res<HairSettings>,
    transforms: TransformHelper,
    mut colliders: Query<(Entity, &HairCollider, &mut ColliderMotion)>,
) {
    for (entity, collider, mut motion) in &mut colliders {
        let transform = match transforms.compute_global_transform(entity) {
            Ok(transform) if transform.affine().is_finite() => transform,
            Ok(_) => {
                motion.reject(entity, "its transform is not finite".into());
                continue;
            }
            Err(error) => {
                motion.reject(entity, format!("it has no usable transform: {error}"));
                continue;
            }
        };
        let (shape, pose) = collider.placed(&transform);
        let friction = f64::from(collider.friction);
        let moving = MovingCollider::fixed(shape, friction, pose);
        match moving.validate() {
            Ok(()) => {
                motion.advance(moving.shape, friction, moving.end, f64::from(settings.teleport_distance));
            }
            Err(error) => motion.reject(entity, error.to_string()),
        }
    }
}

/// Gathers the free strands' set (the shared colliders) and each head's: its own colliders, the shared
/// ones and those its [`HairCollisionFilter`] includes, less those it excludes.
pub(crate) fn gather_colliders(
    mut heads: Query<(Entity, &mut HeadColliderSet, Option<&HairCollisionFilter>)>,
    mut shared_set: ResMut<SharedColliderSet>,
    colliders: Query<(Entity, &ColliderMotion, Option<&HairColliderOf>, Has<SharedHairCollider>)>,
    head_colliders: Query<&HeadColliders>,
    being_made: Query<Option<&MeshColliderBaking>, With<HairColliderFromMesh>>,
) {
    shared_set.0.clear();
    for (entity, motion, of, shared) in &colliders {
        if of.is_none() || shared {
            shared_set.0.add(entity, motion.collider.as_ref());
        }
    }
    for (head, mut set, filter) in &mut heads {
        set.clear();
        let excluded = |entity: Entity, of: Option<&HairColliderOf>| {
            filter.is_some_and(|filter| {
                filter.exclude.contains(&entity)
                    || of.is_some_and(|&HairColliderOf(owner)| filter.exclude.contains(&owner))
            })
        };
        let mut add = |entity: Entity| {
            if let Ok((entity, motion, of, _)) = colliders.get(entity)
                && !excluded(entity, of)
            {
                set.add(entity, motion.collider.as_ref());
            }
        };
        let own = head_colliders.get(head).map(HeadColliders::colliders).unwrap_or_default();
        own.iter().copied().for_each(&mut add);
        shared_set.0.entities().iter().copied().for_each(&mut add);
        for &included in filter.map(|filter| filter.include.as_slice()).unwrap_or_default() {
            match head_colliders.get(included) {
                Ok(theirs) => theirs.colliders().iter().copied().for_each(&mut add),
                Err(_) => add(included),
            }
        }
        // A mesh collider not baked yet (its mesh loading, or the bake running).
        let waiting = own.iter().any(|&entity| {
            being_made.get(entity).is_ok_and(|baking| matches!(baking, None | Some(MeshColliderBaking::Baking(_))))
        });
        set.set_waiting(waiting);
    }
}
