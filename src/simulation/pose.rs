//! A world pose with scale: where a head, or a collider, is.

use bevy::math::{DQuat, DVec3};
use bevy::prelude::*;

/// A world pose with scale in double precision, `x ↦ translation + rotation · (scale ⊙ x)`: a head's, or a
/// collider's.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub(crate) struct ScaledPose {
    /// World position of the head's origin, m.
    pub translation: DVec3,
    /// World orientation.
    pub rotation: DQuat,
    /// Scale of the head's local space (moves anchors, never stretches strands).
    pub scale: DVec3,
}

impl Default for ScaledPose {
    fn default() -> Self {
        Self { translation: DVec3::ZERO, rotation: DQuat::IDENTITY, scale: DVec3::ONE }
    }
}

impl From<&GlobalTransform> for ScaledPose {
    fn from(transform: &GlobalTransform) -> Self {
        let (scale, rotation, translation) = transform.to_scale_rotation_translation();
        Self { translation: translation.as_dvec3(), rotation: rotation.as_dquat().normalize(), scale: scale.as_dvec3() }
    }
}

impl ScaledPose {
    /// World position of the head-local point `local`, m.
    pub fn transform_point(&self, local: DVec3) -> DVec3 {
        self.translation + self.rotation * (self.scale * local)
    }

    /// Whether strands can follow this pose: finite, with a unit rotation (a zero scale leaves the
    /// rotation undefined).
    pub fn is_usable(&self) -> bool {
        self.translation.is_finite()
            && self.scale.is_finite()
            && self.rotation.is_finite()
            && self.rotation.is_normalized()
    }

    /// The rigid motion `(R, t)`, `x ↦ R x + t`, that carries what is attached to `self` along to `other`
    /// (scale changes are not followed).
    pub fn rigid_motion_to(&self, other: &ScaledPose) -> (DQuat, DVec3) {
        let rotation = (other.rotation * self.rotation.inverse()).normalize();
        (rotation, other.translation - rotation * self.translation)
    }
}
