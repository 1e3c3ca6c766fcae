//! The example scene's head and body (`examples/head.rs`), in one place for the example, the benchmark
//! that measures it and the tests that grow hair on it. Lengths in m.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;

/// Height of the neck joint the head turns about, over the body's origin.
pub const NECK_HEIGHT: f32 = 1.5;

/// The skull, head-local.
pub const SCALP: Scalp = Scalp {
    centre: Vec3::new(0.0, 0.12, 0.01),
    semi_axes: Vec3::new(0.078, 0.095, 0.1),
    nape_height: -0.35,
    brow_height: 0.45,
};

/// Face and jaw, in front of and below the skull (the face looks along −Z): centre and semi-axes of an
/// ellipsoid, head-local.
pub const FACE: (Vec3, Vec3) = (Vec3::new(0.0, 0.065, -0.035), Vec3::new(0.062, 0.075, 0.07));

/// The eyeballs' centres, head-local, and their radius.
pub const EYES: [Vec3; 2] = [Vec3::new(-0.03, 0.115, -0.084), Vec3::new(0.03, 0.115, -0.084)];
pub const EYE_RADIUS: f32 = 0.011;

/// A capsule of the body the hair rests on.
#[derive(Debug, Clone, Copy)]
pub struct BodyCapsule {
    pub radius: f32,
    /// Half the length of its axis.
    pub half_length: f32,
    /// Centre, over the body's origin.
    pub centre: Vec3,
    /// Whether its axis lies across the body (along X) instead of upright (along Y).
    pub across: bool,
}

/// Neck, shoulders and torso.
pub const BODY: [BodyCapsule; 3] = [
    BodyCapsule { radius: 0.045, half_length: 0.05, centre: Vec3::new(0.0, 1.47, 0.0), across: false },
    BodyCapsule { radius: 0.06, half_length: 0.12, centre: Vec3::new(0.0, 1.36, 0.0), across: true },
    BodyCapsule { radius: 0.12, half_length: 0.35, centre: Vec3::new(0.0, 0.93, 0.0), across: false },
];

impl BodyCapsule {
    /// Where it is on the body.
    pub fn transform(&self) -> Transform {
        let rotation = if self.across { Quat::from_rotation_z(std::f32::consts::FRAC_PI_2) } else { Quat::IDENTITY };
        Transform::from_translation(self.centre).with_rotation(rotation)
    }

    /// Its collider.
    pub fn collider(&self) -> HairCollider {
        HairCollider::capsule(self.radius, self.half_length)
    }
}
