//! The game's physics colliders as hair colliders (the `avian` feature): put [`AvianHairCollider`] beside
//! an avian3d [`Collider`] and hair meets it, without the shape being written twice.
//!
//! ```
//! # use avian3d::prelude::Collider;
//! # use bevy::prelude::*;
//! # use bevy_hair_sim::prelude::*;
//! # let mut world = World::new();
//! let head = world.spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
//! // The character's shoulders in its physics: the head's hair rests on them.
//! world.spawn((
//!     Collider::capsule(0.06, 0.3),
//!     AvianHairCollider::of(head),
//!     Transform::from_xyz(0.0, 1.35, 0.0).with_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2)),
//! ));
//! // The floor, met by every strand.
//! world.spawn((Collider::half_space(Vec3::Y), AvianHairCollider::default()));
//! ```
//!
//! **What becomes what.** Each part of the avian shape becomes a [`HairCollider`] on a child entity of the
//! collider's entity, placed where the part is, so it moves (and scales) with it: a ball a sphere, a
//! capsule a capsule (its axis turned onto the child's Y), a cuboid a cuboid, a rounded cuboid a rounded
//! one, a half-space a plane, and a compound each of its parts. Shapes hair cannot meet yet (cylinders,
//! cones, convex hulls, meshes, height fields, voxels) are left out, reported once per collider. The
//! friction is avian's [`Friction`] (its dynamic coefficient) where the entity has one, else
//! [`HairCollider::DEFAULT_FRICTION`]. A changed `Collider`, `Friction` or [`AvianHairCollider`] makes the
//! parts again; removing [`AvianHairCollider`] (or the `Collider`) removes them.

use avian3d::parry::shape::{SharedShape, TypedShape};
use avian3d::prelude::{Collider, Friction};
use bevy::prelude::*;

use super::{HairCollider, HairColliderOf};
use crate::rod::ColliderShape;

/// Makes the avian3d [`Collider`] on this entity a hair collider too (see the [module documentation](self)).
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct AvianHairCollider {
    /// The head whose strands meet it, as [`HairColliderOf`] ties a collider to a head; `None` (the
    /// default): every strand meets it, as a collider with no head.
    pub head: Option<Entity>,
}

impl AvianHairCollider {
    /// Met by the strands of `head`.
    pub fn of(head: Entity) -> Self {
        Self { head: Some(head) }
    }
}

/// A hair collider made from the avian collider of the entity it belongs to (its parent).
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq, Eq)]
#[reflect(Component, Debug, Clone, PartialEq)]
pub struct AvianHairColliderPart;

/// The parts made for an [`AvianHairCollider`], to remove them when it changes.
#[derive(Component, Debug, Default)]
struct AvianHairColliderParts(Vec<Entity>);

/// What [`make_avian_hair_colliders`] reads of an avian collider.
type AvianColliders<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        Ref<'static, Collider>,
        Ref<'static, AvianHairCollider>,
        Option<Ref<'static, Friction>>,
        Option<&'static AvianHairColliderParts>,
    ),
>;

/// An entity whose [`AvianHairCollider`] or [`Collider`] is gone.
type NoLongerAvianHairCollider = Or<(Without<AvianHairCollider>, Without<Collider>)>;

/// Makes the hair colliders of every new or changed [`AvianHairCollider`], and removes those of removed
/// ones.
fn make_avian_hair_colliders(
    mut commands: Commands,
    colliders: AvianColliders,
    mut removed_markers: RemovedComponents<AvianHairCollider>,
    mut removed_colliders: RemovedComponents<Collider>,
    stale: Query<&AvianHairColliderParts, NoLongerAvianHairCollider>,
) {
    for entity in removed_markers.read().chain(removed_colliders.read()) {
        if let Ok(parts) = stale.get(entity) {
            for &part in &parts.0 {
                commands.entity(part).try_despawn();
            }
            commands.entity(entity).try_remove::<AvianHairColliderParts>();
        }
    }
    let mut shapes = Vec::new();
    for (entity, collider, marker, friction, parts) in &colliders {
        let changed = collider.is_changed() || marker.is_changed() || friction.as_ref().is_some_and(Ref::is_changed);
        if !changed && parts.is_some() {
            continue;
        }
        for &part in parts.map_or(&[][..], |parts| &parts.0) {
            commands.entity(part).try_despawn();
        }
        shapes.clear();
        let mut left_out = Vec::new();
        hair_shapes(collider.shape(), Transform::IDENTITY, &mut shapes, &mut left_out);
        if !left_out.is_empty() {
            warn!(
                "avian collider {entity}: hair cannot meet its {} yet; those parts are left out",
                left_out.join(", ")
            );
        }
        let friction =
            friction.map_or(HairCollider::DEFAULT_FRICTION, |friction| friction.dynamic_coefficient.max(0.0));
        let made = shapes
            .drain(..)
            .map(|(shape, transform)| {
                let mut part = commands.spawn((
                    Name::new("Hair collider from avian"),
                    HairCollider::new(shape).with_friction(friction),
                    AvianHairColliderPart,
                    transform,
                    ChildOf(entity),
                ));
                if let Some(head) = marker.head {
                    part.insert(HairColliderOf(head));
                }
                part.id()
            })
            .collect();
        commands.entity(entity).insert(AvianHairColliderParts(made));
    }
}

/// The hair colliders of an avian (parry) `shape` placed at `pose` in its collider's space, added to
/// `shapes`; the names of the parts hair cannot meet added to `left_out`.
fn hair_shapes(
    shape: &SharedShape,
    pose: Transform,
    shapes: &mut Vec<(ColliderShape, Transform)>,
    left_out: &mut Vec<&'static str>,
) {
    let mut push = |shape, transform| shapes.push((shape, transform));
    match shape.as_typed_shape() {
        TypedShape::Ball(ball) => push(ColliderShape::sphere(f64::from(ball.radius)), pose),
        TypedShape::Capsule(capsule) => {
            let (a, b) = (capsule.segment.a, capsule.segment.b);
            let axis = b - a;
            let rotation = Quat::from_rotation_arc(Vec3::Y, axis.normalize_or(Vec3::Y));
            let centre = Transform::from_translation(0.5 * (a + b)).with_rotation(rotation);
            push(ColliderShape::capsule(f64::from(capsule.radius), 0.5 * f64::from(axis.length())), pose * centre);
        }
        TypedShape::Cuboid(cuboid) => push(ColliderShape::cuboid(cuboid.half_extents.as_dvec3()), pose),
        TypedShape::RoundCuboid(rounded) => push(
            ColliderShape::Cuboid {
                half_extents: rounded.inner_shape.half_extents.as_dvec3(),
                rounding: f64::from(rounded.border_radius),
            },
            pose,
        ),
        TypedShape::HalfSpace(half_space) => {
            let rotation = Quat::from_rotation_arc(Vec3::Y, half_space.normal.normalize_or(Vec3::Y));
            push(ColliderShape::Plane, pose * Transform::from_rotation(rotation));
        }
        TypedShape::Compound(compound) => {
            for (part_pose, part) in compound.shapes() {
                let part_pose = Transform::from_translation(part_pose.translation).with_rotation(part_pose.rotation);
                hair_shapes(part, pose * part_pose, shapes, left_out);
            }
        }
        TypedShape::Cylinder(_) => left_out.push("cylinder"),
        TypedShape::Cone(_) => left_out.push("cone"),
        TypedShape::ConvexPolyhedron(_) => left_out.push("convex hull"),
        TypedShape::TriMesh(_) => left_out.push("triangle mesh"),
        TypedShape::HeightField(_) => left_out.push("height field"),
        TypedShape::Voxels(_) => left_out.push("voxels"),
        _ => left_out.push("shape of this kind"),
    }
}

/// The game's avian3d colliders as hair colliders (see the [module documentation](self)): makes the
/// parts of every [`AvianHairCollider`] at the start of each fixed step, before the colliders are
/// tracked. Part of [`crate::collision::HairCollisionPlugin`] with the `avian` feature.
pub(super) fn build(app: &mut App, schedule: bevy::ecs::schedule::InternedScheduleLabel) {
    app.register_type::<AvianHairCollider>().register_type::<AvianHairColliderPart>().add_systems(
        schedule,
        make_avian_hair_colliders.in_set(crate::schedule::HairPinSystems::Colliders).before(super::track_colliders),
    );
}
