//! Drawing strands as line strips with Bevy's gizmos, interpolated between fixed steps.

use bevy::color::Mix;
use bevy::gizmos::GizmoPlugin;
use bevy::gizmos::config::GizmoConfigGroup;
use bevy::prelude::*;

use crate::strand::{Strand, StrandPose};

/// The gizmo group hair is drawn in, with its colours. Change it (and the line width, depth bias, …) at
/// run time through `GizmoConfigStore::config_mut::<HairGizmos>()`.
#[derive(Reflect, GizmoConfigGroup, Debug, Clone, PartialEq)]
#[reflect(Default, Debug, Clone)]
pub struct HairGizmos {
    /// Colour at each strand's root.
    pub root_color: Color,
    /// Colour at each strand's tip; nodes in between blend linearly.
    pub tip_color: Color,
}

impl Default for HairGizmos {
    /// Dark brown roots, lighter tips.
    fn default() -> Self {
        Self { root_color: Color::srgb(0.18, 0.10, 0.05), tip_color: Color::srgb(0.55, 0.38, 0.22) }
    }
}

impl HairGizmos {
    /// Named natural hair colours (root and tip), for menus: black, dark brown, brown, auburn, blonde,
    /// grey.
    pub fn presets() -> [(&'static str, Self); 6] {
        let preset = |root: [f32; 3], tip: [f32; 3]| Self {
            root_color: Color::srgb_from_array(root),
            tip_color: Color::srgb_from_array(tip),
        };
        [
            ("black", preset([0.03, 0.03, 0.03], [0.13, 0.11, 0.10])),
            ("dark brown", preset([0.10, 0.06, 0.03], [0.30, 0.19, 0.11])),
            ("brown", Self::default()),
            ("auburn", preset([0.30, 0.09, 0.03], [0.68, 0.30, 0.12])),
            ("blonde", preset([0.50, 0.38, 0.20], [0.92, 0.80, 0.52])),
            ("grey", preset([0.42, 0.42, 0.42], [0.86, 0.86, 0.84])),
        ]
    }
}

/// Draws every simulated strand as a line strip in [`PostUpdate`], in the [`HairGizmos`] group. Needs
/// Bevy's `GizmoPlugin` (part of `DefaultPlugins`; add `AssetPlugin` and `GizmoPlugin` to a headless app).
/// Without it, hair is simulated but not drawn, and a warning says so.
#[derive(Debug, Clone, Copy, Default)]
pub struct HairGizmoPlugin;

/// The system set in [`PostUpdate`] that draws hair.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct HairDrawSystems;

impl Plugin for HairGizmoPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairGizmos>();
    }

    fn finish(&self, app: &mut App) {
        if !app.is_plugin_added::<GizmoPlugin>() {
            warn!("HairGizmoPlugin: Bevy's GizmoPlugin is missing, so hair is simulated but not drawn");
            return;
        }
        app.init_gizmo_group::<HairGizmos>().add_systems(PostUpdate, draw_strands.in_set(HairDrawSystems));
    }
}

/// Draws each strand at the pose a fraction of the way between its last two steps that the fixed clock has
/// run past the last step, so that hair moves smoothly when frames come faster than steps.
pub fn draw_strands(
    mut gizmos: Gizmos<HairGizmos>,
    fixed_time: Res<Time<Fixed>>,
    strands: Query<&StrandPose, With<Strand>>,
) {
    let alpha = fixed_time.overstep_fraction().clamp(0.0, 1.0);
    let root = gizmos.config_ext.root_color.to_linear();
    let tip = gizmos.config_ext.tip_color.to_linear();
    for pose in &strands {
        let last = pose.current.len().saturating_sub(1).max(1) as f32;
        let colors = (0..pose.current.len()).map(|node| root.mix(&tip, node as f32 / last));
        gizmos.linestrip_gradient(pose.interpolated(alpha).zip(colors));
    }
}
