//! Hair on a scaled rig drawn where it is simulated, on every draw path: followers placed on the CPU,
//! followers placed on the GPU, and the strands stepped on the GPU. A character modelled in centimetres
//! is spawned at a scale of 0.01 (and one at 100): the drawn nodes, read back from the GPU, are the
//! strands' nodes and their followers', and every follower's root is on the head where its curve puts it.

use std::sync::{Arc, Mutex};

use bevy::app::PluginsState;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::followers::FollowerPlacement;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::render::GuideLayout;

/// Fixed step, s.
const DT: f64 = 1.0 / 60.0;

/// The largest distance (m) between a drawn node and the node it draws: as `tests/gpu/plugin.rs`'s
/// `DRAWN_TOLERANCE` (`f32` rounding of positions near 1.6 m, WGSL's `sin`/`cos` times follower offsets
/// of millimetres); the wrong scale moves a drawn follower by centimetres to metres.
const DRAWN_TOLERANCE: f32 = 1e-5;

/// How the hair is drawn.
#[derive(Debug, Clone, Copy)]
enum DrawPath {
    /// Followers placed on the CPU, drawn from the buffer the CPU fills.
    CpuFollowers,
    /// Followers placed on the GPU where they are drawn.
    GpuFollowers,
    /// The strands stepped on the GPU, their followers placed there.
    GpuStep,
}

/// A headless app with Bevy's renderer drawing by `path`, one fixed step per update.
fn app(path: DrawPath) -> App {
    let mut app = App::new();
    if matches!(path, DrawPath::CpuFollowers) {
        app.insert_resource(FollowerPlacement::Cpu);
    }
    app.add_plugins((crate::headless_renderer(), HairPlugins::default()));
    if matches!(path, DrawPath::GpuStep) {
        app.add_plugins(HairGpuPlugin::default())
            .insert_resource(HairGpuSettings { read_back: GpuReadBackRate::EveryStep, ..default() });
    }
    app.insert_resource(Time::<Fixed>::from_seconds(DT)).insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    app.update();
    app
}

/// The rig's root at `step`, scaled `scale`: swaying and turning at 1.6 m.
fn root_pose(step: usize, scale: f32) -> Transform {
    let t = step as f32 / 60.0;
    Transform::from_xyz(0.03 * (8.0 * t).sin(), 1.6, 0.02 * (5.0 * t).cos())
        .with_rotation(Quat::from_rotation_y(1.2 * t))
        .with_scale(Vec3::splat(scale))
}

/// Spawns the rig (a root scaled `scale`, its head joint 5 cm above it in the world) with a groom of 32
/// guides and 3 followers each on the joint; returns the root and the head joint.
fn spawn_rig(app: &mut App, scale: f32) -> (Entity, Entity) {
    let root = app.world_mut().spawn(root_pose(0, scale)).id();
    let groom = HairGroom { strand_count: 32, followers_per_guide: 3, segments: 12, ..default() };
    let joint = Transform::from_xyz(0.0, 0.05 / scale, 0.0);
    let head = app.world_mut().spawn((HairHead, groom, joint, ChildOf(root), PlaceFollowersOnCpu)).id();
    (root, head)
}

/// What should be drawn of `head`'s hair (world space), in the layout's order: each guide's nodes, then
/// each follower's, `x_g + o_t t + o_1 m1 + o_2 m2` in the frame of the guide's edge arriving at the node
/// (the root edge's at the root). Also the followers' roots where the head puts their curves' roots.
fn drawn_expected(app: &App, head: Entity) -> (Vec<Vec3>, Vec<(usize, Vec3)>) {
    let mut meshes = app.world().try_query::<&HairMesh>().unwrap();
    let layout: Vec<GuideLayout> = meshes.single(app.world()).expect("one hair mesh").strips().guides().to_vec();
    assert_eq!(layout.len(), 32);
    let head_transform = app.world().get::<GlobalTransform>(head).unwrap();
    let (mut drawn, mut roots) = (Vec::new(), Vec::new());
    for guide in &layout {
        let nodes = app.world().get::<StrandNodes>(guide.entity).unwrap();
        let frames = app.world().get::<StrandFrames>(guide.entity).unwrap();
        let followers = app.world().get::<FollowerNodes>(guide.entity).unwrap();
        let curves = &app.world().get::<HairFollowers>(guide.entity).unwrap().curves;
        let x = &nodes.positions;
        drawn.extend(x.iter().copied());
        assert_eq!(guide.followers as usize, followers.count());
        for (follower, curve) in followers.rest_offsets().chunks_exact(x.len()).zip(curves) {
            roots.push((drawn.len(), head_transform.transform_point(curve[0])));
            for (node, offset) in follower.iter().enumerate() {
                let edge = node.saturating_sub(1);
                let t = (x[edge + 1] - x[edge]).normalize();
                let m1 = frames.material_frame(edge).unwrap().m1;
                let m1 = (m1 - m1.dot(t) * t).normalize();
                let m2 = t.cross(m1);
                drawn.push(x[node] + offset.x * t + offset.y * m1 + offset.z * m2);
            }
        }
    }
    (drawn, roots)
}

/// The drawn nodes read back from the GPU (over a few frames without steps), world space: the buffer's
/// positions through the hair mesh's transform.
fn read_back_drawn(app: &mut App) -> Vec<Vec3> {
    let mut meshes = app.world_mut().query::<(&HairMesh, &GlobalTransform)>();
    let (hair_mesh, _) = meshes.single(app.world()).unwrap();
    let buffer = hair_mesh.positions_buffer().clone();
    let received: Arc<Mutex<Option<Vec<f32>>>> = Arc::default();
    let sink = received.clone();
    let reader = app
        .world_mut()
        .spawn(Readback::buffer(buffer))
        .observe(move |event: On<ReadbackComplete>| {
            *sink.lock().unwrap() = Some(event.to_shader_type());
        })
        .id();
    let mut drawn = None;
    for _ in 0..60 {
        app.update();
        if let Some(values) = received.lock().unwrap().take() {
            drawn = Some(values);
            break;
        }
    }
    app.world_mut().despawn(reader);
    let (_, transform) = meshes.single(app.world()).unwrap();
    let (scale, _, _) = transform.to_scale_rotation_translation();
    assert!((scale - Vec3::ONE).abs().max_element() < 1e-5, "the hair mesh is drawn scaled by {scale}");
    let drawn = drawn.expect("the drawn nodes were read back");
    drawn.chunks_exact(3).map(|node| transform.transform_point(Vec3::from_slice(node))).collect()
}

#[test]
fn hair_on_a_scaled_rig_is_drawn_where_it_is_simulated_on_every_draw_path() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    for path in [DrawPath::CpuFollowers, DrawPath::GpuFollowers, DrawPath::GpuStep] {
        for scale in [0.01, 100.0] {
            let mut app = app(path);
            let (root, head) = spawn_rig(&mut app, scale);
            for step in 1..=20 {
                *app.world_mut().get_mut::<Transform>(root).unwrap() = root_pose(step, scale);
                app.update();
            }
            // Paused: the components hold the last step (read back, on the GPU's path) and are drawn as they are.
            app.world_mut().resource_mut::<HairPause>().paused = true;
            for _ in 0..3 {
                app.update();
            }
            let (expected, roots) = drawn_expected(&app, head);
            let drawn = read_back_drawn(&mut app);
            assert!(drawn.len() >= expected.len(), "{} nodes drawn, {} expected", drawn.len(), expected.len());
            let (largest, node) = expected
                .iter()
                .zip(&drawn)
                .enumerate()
                .map(|(node, (expected, drawn))| (expected.distance(*drawn), node))
                .fold((0.0, 0), |a, b| if b.0 > a.0 || b.0.is_nan() { b } else { a });
            let off_root = roots.iter().map(|&(node, root)| drawn[node].distance(root)).fold(0.0, f32::max);
            // The hair lies on a head 10 cm across in the world, whatever the rig's units.
            let head_at = app.world().get::<GlobalTransform>(head).unwrap().translation();
            let reach = drawn[..expected.len()].iter().map(|node| node.distance(head_at)).fold(0.0, f32::max);
            println!(
                "{path:?}, scale {scale}: {} nodes drawn, largest distance from the nodes {largest:.1e} m (node {node}), followers' roots {off_root:.1e} m from theirs, every node within {reach:.2} m of the head",
                expected.len()
            );
            assert!(largest <= DRAWN_TOLERANCE, "{path:?} at scale {scale}: drawn node {node} is {largest} m off");
            assert!(off_root <= DRAWN_TOLERANCE, "{path:?} at scale {scale}: a follower's root is {off_root} m off");
            assert!(reach < 0.5, "{path:?} at scale {scale}: hair drawn {reach} m from the head");
        }
    }
}
