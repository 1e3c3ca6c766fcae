//! Real-time hair simulation for the Bevy game engine, built on Discrete Elastic Rods.
//!
//! The mechanics live in [`rod`], a Bevy-free core that steps one strand at a time.

#![warn(missing_docs)]

pub mod rod;

/// The types most users need.
pub mod prelude {
    pub use crate::rod::{Rod, RodError, RodMaterial, RodWorkspace, StepError, StepParams};
}
