#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod rod;

/// The types most users need.
pub mod prelude {
    pub use crate::rod::{Rod, RodError, RodMaterial, RodWorkspace, StepError, StepParams};
}
