//! The mechanics core: Discrete Elastic Rods (Bergou, Wardetzky, Robinson, Audoly, Grinspun 2008),
//! free of Bevy's ECS, on `f64` glam vectors, in SI units.
//!
//! A [`Rod`] is one strand: a discrete framed curve with stretching, bending (two principal
//! stiffnesses, rest curvature) and twisting energies derived from a [`RodMaterial`]. [`Rod::step`]
//! advances it by an implicit step (BDF2, see [`Integrator`]) with an inextensibility projection,
//! stable at a game's time step for real hair; boundary conditions ([`Rod::clamp_edge`], [`Rod::pin_node`]) tie it to a head or to
//! anything else.
//!
//! ```
//! use bevy::math::DVec3;
//! use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};
//!
//! // A 10 cm hair sticking out sideways, root clamped.
//! let nodes: Vec<DVec3> = (0..=16).map(|i| DVec3::new(0.1 * i as f64 / 16.0, 0.0, 0.0)).collect();
//! let mut hair = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair())?;
//! hair.clamp_root_in_place();
//! let mut workspace = RodWorkspace::default();
//! for _ in 0..60 {
//!     hair.step(&StepParams::default(), None, &mut workspace)?;
//! }
//! assert!(hair.positions()[16].y < 0.0, "the tip sags under gravity");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod air;
mod banded;
mod collider;
mod contact;
mod curve;
mod distance_field;
mod energy;
mod error;
pub mod frames;
mod inertia;
mod lanes;
mod lockstep;
mod material;
mod params;
mod preload;
mod projection;
mod solver;
mod state;
mod timing;

#[cfg(test)]
pub(crate) mod test_support;

/// Copies `source` into `destination`, reusing its memory (scratch that grows once, then never allocates).
pub(crate) fn copy_into<T: Copy>(destination: &mut Vec<T>, source: &[T]) {
    destination.clear();
    destination.extend_from_slice(source);
}

pub use air::{AirJet, AirMode, AirSnapshot};
pub use banded::{BandedMatrix, NotPositiveDefinite};
pub use collider::{ColliderShape, MovingCollider, RigidPose, SurfacePoint};
pub(crate) use contact::held_reach;
pub use contact::{Contacts, STICKING_SLIP_SPEED};
pub use curve::{MAX_REST_TWIST, MAX_TURNING_ANGLE, MIN_MATERIAL_DIRECTION_ANGLE, MaterialFrame, Rod};
pub use distance_field::{
    DistanceField, DistanceFieldError, MAX_SAMPLES as MAX_DISTANCE_FIELD_SAMPLES, barycentric,
    closest_point_on_triangle,
};
pub use energy::ElasticEnergy;
pub use error::{RodError, StepError};
pub use lockstep::{LANES, LockstepResults, LockstepStrand, LockstepWorkspace};
pub use material::{MATERIAL_RANGES, RodMaterial, Stiffness};
pub use params::{Integrator, MAX_DT, MAX_GRAVITY, StepParams};
pub use preload::{FLIP_MARGIN, MAX_PRELOAD_TURN, PreloadReport, SELF_WEIGHT_BUCKLING, TWIST_HOLDING};
pub use solver::{Anchor, EXTRA_PROJECTION_ITERATIONS, RodWorkspace, StepLoads, StepReport};
pub use state::{RestShape, RodConstraints, RodFrames, RodInertia, RodSnapshot, RodState, StepHistory};
pub use timing::StepTimings;
