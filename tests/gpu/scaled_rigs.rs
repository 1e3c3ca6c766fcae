//! Hair on a scaled rig drawn where it is simulated, on every draw path: followers placed on the CPU,
//! followers placed on the GPU, and the strands stepped on the GPU. A character modelled in centimetres
//! is spawned at a scale of 0.01 (and one at 100): the drawn nodes, read back from the GPU, are the
//! strands' nodes and their followers', and every follower's root is on the head where its curve puts it.

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::followers::FollowerPlacement;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::render::{GuideLayout, HairStrips};

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
    // The GPU steps the hair by default: the CPU's paths turn it off.
    let enabled = matches!(path, DrawPath::GpuStep);
    app.insert_resource(HairGpuSettings { enabled, read_back: GpuReadBackRate::EveryStep, ..default() });
    app.insert_resource(Time::<Fixed>::from_seconds(DT)).insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    crate::finish_adding_plugins(&mut app);
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
    // A hard hairline: every hair drawn (the GPU leaves the nodes of hairs thinned out at a faded hairline
    // unwritten).
    let groom = HairGroom { strand_count: 32, followers_per_guide: 3, segments: 12, hairline_fade: 0.0, ..default() };
    let joint = Transform::from_xyz(0.0, 0.05 / scale, 0.0);
    let head = app.world_mut().spawn((HairHead, groom, joint, ChildOf(root), PlaceFollowersOnCpu)).id();
    (root, head)
}

/// What the GPU-stepped hair should draw of `head` now (world space, the layout's order), from its
/// read-back components: each guide's nodes, then each follower's, `x_g + o_t t + o_1 m1 + o_2 m2` in the
/// frame of the guide's edge arriving at the node (the root edge's at the root).
fn drawn_from_components(app: &App) -> Vec<Vec3> {
    let mut drawn = Vec::new();
    for guide in layout(app) {
        let nodes = app.world().get::<StrandNodes>(guide.entity).unwrap();
        let frames = app.world().get::<StrandFrames>(guide.entity).unwrap();
        let followers = app.world().get::<FollowerNodes>(guide.entity).unwrap();
        let x = &nodes.positions;
        drawn.extend(x.iter().copied());
        assert_eq!(guide.followers as usize, followers.count());
        for follower in followers.rest_offsets().chunks_exact(x.len()) {
            for (node, offset) in follower.iter().enumerate() {
                drawn.push(crate::follower_node(x, frames, node, *offset));
            }
        }
    }
    drawn
}

/// What the CPU draws of the hair at the fixed clock's fraction `alpha` of a step: the strands' nodes and
/// their followers placed on the CPU, interpolated between the last two steps (`HairStrips::fill`).
fn drawn_interpolated(app: &App, alpha: f32) -> Vec<Vec3> {
    let world = app.world();
    let mut expected = HairStrips::default();
    expected.set_layout(layout(app));
    let lookup = |entity| Some((world.get::<StrandNodes>(entity)?, world.get::<FollowerNodes>(entity)));
    expected.fill(alpha, 1, lookup).expect("hair to draw");
    expected.positions().chunks_exact(3).map(Vec3::from_slice).collect()
}

/// The hair mesh's layout: 32 guides.
fn layout(app: &App) -> Vec<GuideLayout> {
    let mut meshes = app.world().try_query::<&HairMesh>().unwrap();
    let layout: Vec<GuideLayout> = meshes.single(app.world()).expect("one hair mesh").strips().guides().to_vec();
    assert_eq!(layout.len(), 32);
    layout
}

/// The largest distance (m) of a follower's root from where `head` puts its curve's root, with the
/// followers' nodes `drawn` in the layout's order (guide, then its followers, `nodes` each).
fn followers_off_their_roots(app: &App, head: Entity, drawn: &[Vec3], nodes: usize) -> f32 {
    let head_transform = app.world().get::<GlobalTransform>(head).unwrap();
    let mut at = 0;
    let mut largest = 0.0_f32;
    for guide in layout(app) {
        at += nodes;
        for curve in &app.world().get::<HairFollowers>(guide.entity).unwrap().curves {
            largest = largest.max(drawn[at].distance(head_transform.transform_point(curve[0])));
            at += nodes;
        }
    }
    largest
}

/// The drawn nodes read back from the GPU, as the buffer holds them (where the hair was stepped; the hair
/// mesh's transform carries them onto the head as it is drawn), read frame after frame (time standing
/// still) until they are `expected` or 120 frames have passed (the GPU draws a frame or two behind);
/// checks the hair mesh's transform is rigid.
fn read_back_drawn(app: &mut App, expected: &[Vec3]) -> Vec<Vec3> {
    let mut meshes = app.world_mut().query::<(&HairMesh, &GlobalTransform)>();
    let (hair_mesh, transform) = meshes.single(app.world()).unwrap();
    let (scale, _, _) = transform.to_scale_rotation_translation();
    assert!((scale - Vec3::ONE).abs().max_element() < 1e-5, "the hair mesh is drawn scaled by {scale}");
    let buffer = hair_mesh.positions_buffer().clone();
    let nodes = |values: &[f32]| -> Vec<Vec3> { values.chunks_exact(3).map(Vec3::from_slice).collect() };
    let drawn = crate::read_back_until(app, buffer, 120, |values| {
        let drawn = nodes(values);
        drawn.len() >= expected.len() && largest_difference(&drawn, expected).0 <= DRAWN_TOLERANCE
    });
    nodes(&drawn.expect("the drawn nodes were read back"))
}

/// The largest distance (m) between a drawn node and the expected one, and its node.
fn largest_difference(drawn: &[Vec3], expected: &[Vec3]) -> (f32, usize) {
    expected
        .iter()
        .zip(drawn)
        .enumerate()
        .map(|(node, (expected, drawn))| (expected.distance(*drawn), node))
        .fold((0.0, 0), |a, b| if b.0 > a.0 || b.0.is_nan() { b } else { a })
}

#[test]
fn hair_on_a_scaled_rig_is_drawn_where_it_is_simulated_on_every_draw_path() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    for path in [DrawPath::CpuFollowers, DrawPath::GpuFollowers, DrawPath::GpuStep] {
        for scale in [0.01, 100.0] {
            let mut app = app(path);
            let (root, head) = spawn_rig(&mut app, scale);
            for step in 1..=60 {
                *app.world_mut().get_mut::<Transform>(root).unwrap() = root_pose(step, scale);
                app.update();
            }
            let (expected, placed) = if matches!(path, DrawPath::GpuStep) {
                // Paused until the components hold the last step, read back; then one more step, after
                // which what is drawn (the interpolation's fraction 0) is that step's placement.
                app.world_mut().resource_mut::<HairPause>().paused = true;
                for _ in 0..60 {
                    app.update();
                    if app.world().resource::<HairGpuStatus>().read_back_age == Some(0) {
                        break;
                    }
                }
                assert_eq!(app.world().resource::<HairGpuStatus>().read_back_age, Some(0), "read back");
                let expected = drawn_from_components(&app);
                app.world_mut().resource_mut::<HairPause>().step_once();
                app.update();
                (expected.clone(), expected)
            } else {
                // Half a step on without a step, then time stands still: drawn halfway between the steps.
                let alpha = crate::stop_halfway_between_steps(&mut app);
                (drawn_interpolated(&app, alpha), drawn_interpolated(&app, 1.0))
            };
            // Where the last step placed the followers' roots: where the head puts them.
            let off_root = followers_off_their_roots(&app, head, &placed, 13);
            let drawn = read_back_drawn(&mut app, &expected);
            assert!(drawn.len() >= expected.len(), "{} nodes drawn, {} expected", drawn.len(), expected.len());
            let (largest, node) = largest_difference(&drawn, &expected);
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
