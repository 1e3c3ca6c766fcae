//! A headless Bevy app with the hair plugin, stepped by hand: one fixed step of 1/60 s per update.

use bevy::camera::primitives::Frustum;
use bevy::camera::{CameraProjection, PerspectiveProjection};
use bevy::math::primitives::ViewFrustum;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::SimulatedStrand;

/// Fixed step of the test apps, s.
pub const DT: f64 = 1.0 / 60.0;

/// MinimalPlugins, the hair plugin and `extra` plugins; every `update` runs exactly one fixed step (the
/// app has had the one update that starts Bevy's clock and runs none). The app holds a share of the
/// [`logs`](crate::logs) while it lives.
pub fn hair_app_with<M>(extra: impl bevy::app::Plugins<M>) -> App {
    let mut app = App::new();
    crate::logs::share_with(&mut app);
    // Every core in the compute pool, as a game gives it (Bevy's default leaves one of two cores to it);
    // the first app of the process sets the pool for all.
    let pools = TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() };
    app.add_plugins((MinimalPlugins.set(pools), extra, HairPlugins::default()))
        .insert_resource(Time::<Fixed>::from_seconds(DT))
        .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    app.finish();
    app.cleanup();
    app.update();
    app
}

/// [`hair_app_with`] and nothing extra.
pub fn hair_app() -> App {
    hair_app_with(())
}

/// Root position and outward direction of strand `index` of `count`, spread over the top of a scalp
/// sphere of radius 0.1 m (a golden-angle spiral), in the head's local space.
pub fn scalp_root(index: usize, count: usize) -> (Vec3, Vec3) {
    let height = 1.0 - 0.9 * (index as f32 + 0.5) / count as f32;
    let around = index as f32 * 2.399_963;
    let ring = (1.0 - height * height).sqrt();
    let normal = Vec3::new(ring * around.cos(), height, ring * around.sin());
    (0.1 * normal, normal)
}

/// Spawns a head at `transform` with `count` straight strands (20 cm, `segments` edges) and returns the
/// head and its strands in spawn order.
pub fn spawn_head(app: &mut App, transform: Transform, count: usize, segments: usize) -> (Entity, Vec<Entity>) {
    let head = app.world_mut().spawn((HairHead, transform)).id();
    let strands = (0..count)
        .map(|index| {
            let (root, normal) = scalp_root(index, count);
            app.world_mut().spawn((HairStrand::straight(root, normal, 0.2, segments), StrandOf(head))).id()
        })
        .collect();
    (head, strands)
}

/// A head's pose at fixed step `step`: swaying 3 cm and turning ±0.5 rad about once a second, around `base`.
pub fn moving_pose(base: Vec3, step: usize) -> Transform {
    let time = step as f32 / 60.0;
    let sway = 0.03 * (std::f32::consts::TAU * 1.1 * time).sin();
    Transform::from_translation(base + Vec3::new(sway, 0.0, 0.0))
        .with_rotation(Quat::from_rotation_y(0.5 * (std::f32::consts::TAU * 0.9 * time).sin()))
}

/// The simulated strand of `entity`.
pub fn strand(app: &App, entity: Entity) -> &SimulatedStrand {
    app.world().get::<SimulatedStrand>(entity).unwrap_or_else(|| {
        let rejection = app.world().get::<StrandRejected>(entity);
        panic!("strand {entity} is not simulated: {rejection:?}")
    })
}

/// Every message of type `M` sent since the last call.
pub fn drain_messages<M: Message>(app: &mut App) -> Vec<M> {
    app.world_mut().resource_mut::<Messages<M>>().drain().collect()
}

/// A camera at `transform` with a 16:9 perspective frustum (for the levels of detail).
pub fn camera(transform: Transform) -> (Camera, Transform, GlobalTransform, Frustum) {
    let projection = PerspectiveProjection { aspect_ratio: 16.0 / 9.0, ..default() };
    let clip_from_world = projection.get_clip_from_view() * transform.to_matrix().inverse();
    let frustum = Frustum(ViewFrustum::from_clip_from_world(&clip_from_world));
    (Camera::default(), transform, GlobalTransform::from(transform), frustum)
}

/// Whether everything a game reads of a strand is finite: its drawn nodes (positions, the positions one
/// step before, velocities), its frames and twists, and its followers' nodes.
pub fn drawn_is_finite(nodes: &StrandNodes, frames: &StrandFrames, followers: Option<&FollowerNodes>) -> bool {
    let vectors = nodes.positions.iter().chain(&nodes.previous_positions).chain(&nodes.velocities);
    let frame_vectors = frames.tangents.iter().chain(&frames.reference_directors);
    let followers =
        followers.map_or(&[][..], |f| &f.positions).iter().chain(followers.map_or(&[][..], |f| &f.previous_positions));
    vectors.chain(frame_vectors).chain(followers).all(|v| v.is_finite())
        && frames.twist.iter().chain(&frames.reference_twist).all(|t| t.is_finite())
}
