//! Looking at the hair while tuning it: [`HairGizmoPlugin`] draws strands and colliders as gizmo lines (a
//! debug view over the rendered hair, or the only view without the renderer); behind the `egui` feature,
//! `HairPanelPlugin` is a live panel of settings and statistics; [`coverage`] measures how a head of hair
//! covers its scalp and holds together, headless; [`HairDiagnosticsPlugin`] puts the hair's figures in
//! Bevy's `DiagnosticsStore`.

pub mod coverage;
mod diagnostics;
mod gizmos;
#[cfg(feature = "egui")]
mod panel;

/// The set the gizmo lines are drawn in, now in [`crate::schedule`].
pub use crate::schedule::HairDrawSystems;
pub use diagnostics::{HairDiagnostics, HairDiagnosticsPlugin};
pub use gizmos::{HairGizmoPlugin, HairGizmos, draw_colliders, draw_strands};
#[cfg(feature = "egui")]
pub use panel::HairPanelPlugin;
