//! Heads: the bodies hair is rooted on, and the relationship that ties strands to them.

use bevy::math::Affine3A;
use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;

use super::pose::ScaledPose;
use super::settings::HairSettings;

/// A head, or any body hair grows from. Its [`Transform`] (through any parents) moves the roots of its
/// strands every fixed step. Strands are attached with [`StrandOf`]; despawning the head despawns them.
///
/// Heads are expected to be rigid: a head's scale moves the root anchors on its surface but does not
/// stretch its strands.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
#[require(Transform, HeadMotion)]
pub struct HairHead;

/// Roots a strand on a head: the strand's [`HairStrand`](super::HairStrand) nodes are given in the head's
/// local space, and its root edge follows the head. A relationship like [`ChildOf`]: the head gets
/// [`HeadStrands`] listing its strands.
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq, Eq)]
#[reflect(Component, Debug, PartialEq, Clone)]
#[relationship(relationship_target = HeadStrands)]
pub struct StrandOf(pub Entity);

/// The strands rooted on a head, kept by Bevy from their [`StrandOf`]. Despawning the head despawns them.
#[derive(Component, Reflect, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default)]
#[relationship_target(relationship = StrandOf, linked_spawn)]
#[require(HeadMotion)]
pub struct HeadStrands(Vec<Entity>);

impl HeadStrands {
    /// The strand entities rooted on this head.
    pub fn strands(&self) -> &[Entity] {
        &self.0
    }
}

/// Where a head was at the last two fixed steps, kept by the plugin; tells whether it teleported.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct HeadMotion {
    /// Pose at the current step.
    pub(crate) current: ScaledPose,
    /// Pose at the previous step.
    pub(crate) previous: ScaledPose,
    /// Whether the head moved farther than [`HairSettings::teleport_distance`] since the previous step.
    pub(crate) teleported: bool,
    tracked: bool,
}

impl HeadMotion {
    /// World position of the head's origin at this step, m.
    pub fn translation(&self) -> Vec3 {
        self.current.translation.as_vec3()
    }

    /// World orientation of the head at this step.
    pub fn rotation(&self) -> Quat {
        self.current.rotation.as_quat()
    }

    /// Where the head-local point `local` (m) is at this step, world space: where a root given there is
    /// held (the head's scale moves the point, as it moves the roots).
    pub fn transform_point(&self, local: Vec3) -> Vec3 {
        self.current.transform_point(local.as_dvec3()).as_vec3()
    }

    /// How far the head's origin moved since the previous step, m.
    pub fn displacement(&self) -> Vec3 {
        (self.current.translation - self.previous.translation).as_vec3()
    }

    /// Whether the head moved farther than [`HairSettings::teleport_distance`] since the previous step; its
    /// strands were then carried along rigidly instead of being whipped.
    pub fn teleported(&self) -> bool {
        self.teleported
    }

    /// The rigid motion that carries hair drawn a fraction `alpha` of the way from the previous step to
    /// the last (as the drawing interpolates it) onto the head where it is now, `now` (its
    /// `GlobalTransform` this frame). Hair is stepped where the head was at the fixed steps, but a game
    /// usually moves its heads after them (in `Update`, or with its animation in `PostUpdate`), so
    /// drawn where it was stepped the hair would trail its head by one to two steps: a head turning at
    /// 8 rad/s leaves it 1 to 2 cm behind on the scalp. Drawn through this motion, the roots sit on the scalp
    /// as it is drawn, and the hair keeps the motion it was stepped with relative to the head. The
    /// identity when the head has not moved since, or has no usable transform.
    pub fn drawn_to_now(&self, alpha: f32, now: &GlobalTransform) -> Affine3A {
        let now = ScaledPose::from(now);
        if !(self.tracked && now.is_usable()) {
            return Affine3A::IDENTITY;
        }
        // A head that teleported is drawn where it arrived (the hair jumped with it).
        let alpha = if self.teleported { 1.0 } else { f64::from(alpha.clamp(0.0, 1.0)) };
        let drawn = ScaledPose {
            translation: self.previous.translation.lerp(self.current.translation, alpha),
            rotation: self.previous.rotation.slerp(self.current.rotation, alpha).normalize(),
            scale: self.previous.scale.lerp(self.current.scale, alpha),
        };
        let (rotation, translation) = drawn.rigid_motion_to(&now);
        Affine3A::from_rotation_translation(rotation.as_quat(), translation.as_vec3())
    }

    fn advance(&mut self, pose: ScaledPose, teleport_distance: f64) {
        self.previous = if self.tracked { self.current } else { pose };
        self.current = pose;
        self.teleported = self.tracked && pose.translation.distance(self.previous.translation) > teleport_distance;
        self.tracked = true;
    }
}

/// Records every head's world pose for this step, from its `Transform` and its parents' (so a head that
/// moved during this frame is followed at once, before Bevy propagates transforms).
pub(crate) fn track_heads(
    settings: Res<HairSettings>,
    transforms: TransformHelper,
    mut heads: Query<(Entity, &mut HeadMotion), With<HeadStrands>>,
) {
    for (head, mut motion) in &mut heads {
        match transforms.compute_global_transform(head).map(|transform| ScaledPose::from(&transform)) {
            Ok(pose) if pose.is_usable() => motion.advance(pose, f64::from(settings.teleport_distance)),
            Ok(_) => warn_once!(
                "hair head {head} has a non-finite or zero-scale transform; its strands keep their last root, and new ones wait"
            ),
            Err(error) => {
                warn_once!("hair head {head} has no usable transform ({error}); its strands stay where they are")
            }
        }
    }
}
