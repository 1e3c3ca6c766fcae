#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod collision;
pub mod detail;
pub mod followers;
pub mod gizmos;
pub mod groom;
pub mod groom_file;
pub mod head;
#[cfg(feature = "egui")]
pub mod panel;
mod parallel;
mod plugin;
pub mod render;
pub mod rod;
pub mod settings;
mod step;
pub mod strand;
pub mod strand_data;
pub mod volume;
pub mod wind;

pub use plugin::{HairPlugin, HairSimulationPlugin, HairSystems};

/// The types most users need.
pub mod prelude {
    pub use crate::collision::{
        HairCollider, HairColliderOf, HairCollisionFilter, HairCollisionPlugin, HeadColliders, SharedHairCollider,
    };
    pub use crate::detail::{HairDetail, HairDetailLevel, HairDetailPlugin, HairDetailSettings};
    pub use crate::followers::{FollowerNodes, HairFollowers};
    pub use crate::gizmos::{HairDrawSystems, HairGizmoPlugin, HairGizmos};
    pub use crate::groom::{Combing, GroomedStrand, HairGroom, HairStyle, Scalp};
    pub use crate::groom_file::{
        FileStrand, GroomFile, GroomFileError, GroomFilePlugin, GroomPlacement, HairGroomFile, PlacedGroomFile, UpAxis,
    };
    pub use crate::head::{HairHead, HeadStrands, StrandOf};
    #[cfg(feature = "egui")]
    pub use crate::panel::HairPanelPlugin;
    pub use crate::render::HairAppearance;
    #[cfg(feature = "render")]
    pub use crate::render::{HairMesh, HairRenderPlugin};
    pub use crate::rod::{ColliderShape, Rod, RodError, RodMaterial, RodWorkspace, StepError, StepParams};
    pub use crate::settings::{HairPause, HairSettings, HairStatistics};
    pub use crate::strand::{HairStrand, SimulatedStrand, StrandFault, StrandForces, StrandHealth, StrandRejected};
    pub use crate::strand_data::{
        EdgeFrame, StrandFrames, StrandNodes, StrandRestShape, StrandSnapshot, StrandSnapshotData,
    };
    pub use crate::volume::{HairVolume, HairVolumeGrids, HairVolumePlugin, RepresentedHairs};
    pub use crate::wind::{HairWind, HairWindPlugin, HairWindSource};
    pub use crate::{HairPlugin, HairSimulationPlugin, HairSystems};
}
