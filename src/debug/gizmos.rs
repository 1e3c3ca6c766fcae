//! Drawing strands as line strips with Bevy's gizmos, interpolated between fixed steps.

use bevy::color::Mix;
use bevy::gizmos::GizmoPlugin;
use bevy::gizmos::config::{GizmoConfigGroup, GizmoConfigStore};
use bevy::math::Affine3A;
use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;

use crate::collision::{ColliderMotion, HairCollider};
use crate::followers::FollowerNodes;
use crate::rod::ColliderShape;
use crate::schedule::HairDrawSystems;
use crate::simulation::{HeadMotion, SimulatedStrand, StrandNodes, StrandOf};

/// The gizmo group hair is drawn in, with its colours. Change it (and the line width, depth bias, …) at
/// run time through `GizmoConfigStore::config_mut::<HairGizmos>()`.
#[derive(Reflect, GizmoConfigGroup, Debug, Clone, PartialEq)]
#[reflect(Default, Debug, Clone)]
pub struct HairGizmos {
    /// Colour at each strand's root.
    pub root_color: Color,
    /// Colour at each strand's tip; nodes in between blend linearly.
    pub tip_color: Color,
    /// Whether every [`crate::collision::HairCollider`] is drawn as a wireframe (its solid, without the
    /// strands' collision thickness), for tuning colliders against a mesh. Default off.
    pub draw_colliders: bool,
    /// Colour of the collider wireframes.
    pub collider_color: Color,
    /// Whether follower hairs ([`crate::followers`]) are drawn, besides the simulated strands; off shows
    /// the guides alone. Default on.
    pub draw_followers: bool,
    /// Whether strands are drawn as lines at all. On by default, unless the app draws hair with the
    /// hair renderer (`HairRenderPlugin`, `render` feature, with Bevy's PBR): the [`HairGizmoPlugin`] then
    /// starts with it off, making the lines a debug view over the rendered hair (the colliders are still
    /// drawn when asked).
    pub draw_strands: bool,
}

impl Default for HairGizmos {
    /// Dark brown roots, lighter tips.
    fn default() -> Self {
        Self {
            root_color: Color::srgb(0.18, 0.10, 0.05),
            tip_color: Color::srgb(0.55, 0.38, 0.22),
            draw_colliders: false,
            collider_color: Color::srgb(0.2, 0.9, 0.4),
            draw_followers: true,
            draw_strands: true,
        }
    }
}

impl HairGizmos {
    /// Named natural hair colours (root and tip), for menus: black, dark brown, brown, auburn, blonde,
    /// grey.
    pub fn presets() -> [(&'static str, Self); 6] {
        let preset = |root: [f32; 3], tip: [f32; 3]| Self {
            root_color: Color::srgb_from_array(root),
            tip_color: Color::srgb_from_array(tip),
            ..default()
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

impl Plugin for HairGizmoPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairGizmos>();
    }

    fn finish(&self, app: &mut App) {
        if !app.is_plugin_added::<GizmoPlugin>() {
            warn!("HairGizmoPlugin: Bevy's GizmoPlugin is missing, so hair is simulated but not drawn");
            return;
        }
        app.init_gizmo_group::<HairGizmos>()
            .add_systems(PostUpdate, (draw_strands, draw_colliders).in_set(HairDrawSystems));
        if renders_hair(app)
            && let Some(mut store) = app.world_mut().get_resource_mut::<GizmoConfigStore>()
            && let Some((_, lines)) = store.get_config_mut::<HairGizmos>()
        {
            // The rendered hair is the view; the lines become a debug view, off until asked for.
            lines.draw_strands = false;
        }
    }
}

/// Whether the app draws hair with the hair renderer (which needs Bevy's PBR).
fn renders_hair(app: &App) -> bool {
    #[cfg(feature = "render")]
    {
        app.is_plugin_added::<crate::render::HairRenderPlugin>() && app.is_plugin_added::<bevy::pbr::PbrPlugin>()
    }
    #[cfg(not(feature = "render"))]
    {
        let _ = app;
        false
    }
}

/// What [`draw_strands`] reads of a strand: its nodes, its followers' and its head.
type DrawnStrandLines = (&'static StrandNodes, Option<&'static FollowerNodes>, Option<&'static StrandOf>);

/// Draws each strand at the pose a fraction of the way between its last two steps that the fixed clock has
/// run past the last step, so that hair moves smoothly when frames come faster than steps, carried onto
/// its head as the head is now ([`HeadMotion::drawn_to_now`], as the renderer draws it). Followers are
/// drawn where the CPU placed them: under the renderer, which places them on the GPU, only those of heads
/// marked [`PlaceFollowersOnCpu`](crate::followers::PlaceFollowersOnCpu).
pub fn draw_strands(
    mut gizmos: Gizmos<HairGizmos>,
    fixed_time: Res<Time<Fixed>>,
    strands: Query<DrawnStrandLines, With<SimulatedStrand>>,
    heads: Query<&HeadMotion>,
    transforms: TransformHelper,
) {
    if !gizmos.config_ext.draw_strands {
        return;
    }
    let alpha = fixed_time.overstep_fraction().clamp(0.0, 1.0);
    let root = gizmos.config_ext.root_color.to_linear();
    let tip = gizmos.config_ext.tip_color.to_linear();
    let draw_followers = gizmos.config_ext.draw_followers;
    // The carry of the last head met: a head's strands usually come one after another.
    let mut last_head: Option<(Entity, Affine3A)> = None;
    for (nodes, followers, head) in &strands {
        let carry = match (head, last_head) {
            (None, _) => Affine3A::IDENTITY,
            (Some(&StrandOf(head)), Some((last, carry))) if head == last => carry,
            (Some(&StrandOf(head)), _) => {
                // From the head's transform as it is (also where nothing propagates transforms).
                let now = transforms.compute_global_transform(head);
                let carry = match (heads.get(head), now) {
                    (Ok(motion), Ok(now)) => motion.drawn_to_now(alpha, &now),
                    _ => Affine3A::IDENTITY,
                };
                last_head = Some((head, carry));
                carry
            }
        };
        let count = nodes.positions.len();
        let last = count.saturating_sub(1).max(1) as f32;
        let colors = move || (0..count).map(move |node| root.mix(&tip, node as f32 / last));
        let carried = |point: Vec3| carry.transform_point3(point);
        gizmos.linestrip_gradient(nodes.interpolated(alpha).map(carried).zip(colors()));
        let Some(followers) = followers.filter(|_| draw_followers) else {
            continue;
        };
        for follower in 0..followers.count() {
            gizmos.linestrip_gradient(followers.interpolated(follower, alpha).map(carried).zip(colors()));
        }
    }
}

/// Draws every collider in use, when [`HairGizmos::draw_colliders`] is on: a [`HairCollider`] where its
/// transform puts it in this frame (as its mesh is drawn, and the hair with it), the others (baked from
/// meshes, from avian) where the last step met them; spheres and ellipsoids as three great ellipses,
/// capsules as wire capsules, planes as a 2 m grid.
pub fn draw_colliders(
    mut gizmos: Gizmos<HairGizmos>,
    colliders: Query<(Entity, &ColliderMotion, Option<&HairCollider>)>,
    transforms: TransformHelper,
) {
    if !gizmos.config_ext.draw_colliders {
        return;
    }
    let color = gizmos.config_ext.collider_color;
    let quarter = std::f32::consts::FRAC_PI_2;
    for (entity, motion, own) in &colliders {
        let Some(met) = motion.collider.as_ref() else { continue };
        let now = own.zip(transforms.compute_global_transform(entity).ok()).map(|(own, now)| own.placed(&now));
        let (shape, pose) = now.unwrap_or_else(|| (met.shape.clone(), met.end));
        let isometry = Isometry3d::new(pose.translation.as_vec3(), pose.rotation.as_quat());
        match shape {
            ColliderShape::Sphere { radius } => {
                gizmos.sphere(isometry, radius as f32, color);
            }
            ColliderShape::Ellipsoid { semi_axes } => {
                let semi_axes = semi_axes.as_vec3();
                for (turn, half_size) in [
                    (Quat::IDENTITY, semi_axes.xy()),
                    (Quat::from_rotation_y(quarter), semi_axes.zy()),
                    (Quat::from_rotation_x(quarter), semi_axes.xz()),
                ] {
                    let ellipse = Isometry3d::new(isometry.translation, isometry.rotation * turn);
                    gizmos.ellipse(ellipse, half_size, color);
                }
            }
            ColliderShape::Capsule { radius, half_length } => {
                gizmos.primitive_3d(&Capsule3d::new(radius as f32, 2.0 * half_length as f32), isometry, color);
            }
            ColliderShape::Plane => {
                let flat = Isometry3d::new(isometry.translation, isometry.rotation * Quat::from_rotation_x(-quarter));
                gizmos.grid(flat, UVec2::splat(20), Vec2::splat(0.1), color);
            }
            // The box the rounding grows, as wide as the solid across its faces.
            ColliderShape::Cuboid { half_extents, rounding } => {
                let size = 2.0 * (half_extents + bevy::math::DVec3::splat(rounding)).as_vec3();
                let transform = Transform::from_isometry(isometry).with_scale(size);
                gizmos.cube(transform, color);
            }
            // The box the field was baked in.
            ColliderShape::Mesh { ref field, scale, .. } => {
                let (low, high) = field.bounds();
                let centre = isometry.translation + isometry.rotation * (0.5 * (low + high) * scale).as_vec3a();
                let transform = Transform::from_translation(centre.into())
                    .with_rotation(isometry.rotation)
                    .with_scale(((high - low) * scale).as_vec3());
                gizmos.cube(transform, color);
            }
        }
    }
}
