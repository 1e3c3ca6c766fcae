//! Followers placed and hair interpolated on the GPU (`src/render/followers.wgsl`) against the CPU's
//! placement (`src/followers`) and drawing (`HairStrips::fill`), on a real adapter: Mesa's software
//! Vulkan (lavapipe) on a machine without a GPU, which `.ci/run` installs. Without any adapter the test
//! fails (Bevy's renderer cannot start); it never skips.
//!
//! Also, without a GPU: the 24-bit frame codes the CPU sends, decoded as the shader decodes them.

mod common;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use bevy::app::PluginsState;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
use bevy::time::TimeUpdateStrategy;
use bevy::window::ExitCondition;
use bevy_hair_sim::followers::{FollowerPlacement, PlaceFollowersOnCpu};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::render::feed::{decode_frame, encode_frame};
use bevy_hair_sim::render::{GuideLayout, HairStrips};

/// Fixed step, s.
const DT: f64 = 1.0 / 60.0;

/// The largest angle a frame code may be off, rad: the diamond angle's step of 2⁻²¹ a quadrant turns the
/// director by at most 2 · 2⁻²¹ rad (where `dθ/dd` is largest, at 45°), half of it by rounding; plus the
/// f32 rounding of the basis and of this measurement (a few 1e-7).
const FRAME_CODE_TOLERANCE: f32 = 1.0 / 2_097_152.0 + 1e-6;

#[test]
fn frame_codes_keep_the_director_within_their_resolution() {
    let mut rng = fastrand::Rng::with_seed(7);
    let mut unit = || {
        loop {
            let v = Vec3::new(rng.f32() * 2.0 - 1.0, rng.f32() * 2.0 - 1.0, rng.f32() * 2.0 - 1.0);
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    };
    let mut worst = 0.0_f32;
    // Random frames, and the tangents along the axes, where the basis changes axis.
    let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, Vec3::new(1.0, 1.0, 0.0).normalize()];
    for index in 0..20_000 {
        let tangent = if index < axes.len() { axes[index] } else { unit() };
        let m1 = tangent.any_orthonormal_vector();
        let (sin, cos) = (index as f32 * 0.377).sin_cos();
        let m1 = cos * m1 + sin * tangent.cross(m1);
        let decoded = decode_frame(tangent, encode_frame(tangent, m1));
        assert!((decoded.length() - 1.0).abs() < 1e-5 && decoded.dot(tangent).abs() < 1e-5);
        // The angle by its sine: in f32, `acos` of a dot product this close to 1 has steps of 3e-4 rad.
        worst = worst.max(decoded.cross(m1).length().asin());
    }
    println!("worst director error of a frame code: {worst:.2e} rad");
    assert!(worst <= FRAME_CODE_TOLERANCE, "{worst} rad");
}

/// What the read-back observer last received: the drawn node buffer.
#[derive(Resource, Clone, Default)]
struct ReadBack(Arc<Mutex<Option<Vec<f32>>>>);

/// A headless app with Bevy's renderer on whatever adapter wgpu finds, the hair plugin, one fixed step
/// per update.
fn rendering_app() -> App {
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                close_when_requested: false,
                ..default()
            })
            // The render world stays in the app (not on a thread of its own), to be seen here.
            .disable::<PipelinedRenderingPlugin>(),
        HairPlugin::default(),
    ))
    .insert_resource(Time::<Fixed>::from_seconds(DT))
    .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    // The renderer finds its adapter asynchronously, as `App::run` waits for it.
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    app.update();
    app
}

/// The pose of the shaking, turning head at `step`.
fn head_pose(step: usize) -> Transform {
    let t = step as f32 / 60.0;
    Transform::from_xyz(0.04 * (9.0 * t).sin(), 1.6, 0.02 * (5.0 * t).cos())
        .with_rotation(Quat::from_rotation_y(1.5 * t))
}

#[test]
fn followers_placed_on_the_gpu_match_the_cpu_placement() {
    let mut app = rendering_app();
    assert!(app.get_sub_app(RenderApp).is_some(), "Bevy's renderer started (a GPU adapter was found)");
    assert_eq!(*app.world().resource::<FollowerPlacement>(), FollowerPlacement::Gpu);
    let groom = HairGroom { strand_count: 150, followers_per_guide: 6, segments: 16, ..default() };
    // Placed on the CPU as well, for the comparison.
    let head = app.world_mut().spawn((HairHead, groom, PlaceFollowersOnCpu, head_pose(0))).id();
    let skull = Vec3::new(0.078, 0.095, 0.1);
    let colliders = [
        app.world_mut().spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), head_pose(0))).id(),
        app.world_mut().spawn((HairCollider::sphere(0.07), HairColliderOf(head), head_pose(0))).id(),
    ];
    // Swinging for a second, so that the followers bend, turn and are pushed out of the skull.
    for step in 1..=60 {
        for entity in [head].into_iter().chain(colliders) {
            *app.world_mut().get_mut::<Transform>(entity).unwrap() = head_pose(step);
        }
        app.update();
    }
    let (largest, node, drawn) = compare_drawn_halfway(&mut app);
    println!(
        "{drawn} drawn nodes of 150 guides and their followers: GPU against CPU, largest difference {largest:.2e} m (node {node})"
    );
    assert!(largest <= 1e-5, "the GPU's drawn node {node} is {largest} m from the CPU's");

    // Followers bound again (gathered onto their guides towards the tips): the GPU takes the new offsets.
    let guides = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    for &guide in &guides {
        app.world_mut().get_mut::<HairFollowers>(guide).unwrap().clumping = 0.8;
    }
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    for step in 61..=70 {
        for entity in [head].into_iter().chain(colliders) {
            *app.world_mut().get_mut::<Transform>(entity).unwrap() = head_pose(step);
        }
        app.update();
    }
    let (largest, node, _) = compare_drawn_halfway(&mut app);
    println!("after rebinding with clumping: largest difference {largest:.2e} m (node {node})");
    assert!(largest <= 1e-5, "after rebinding, the GPU's drawn node {node} is {largest} m from the CPU's");
}

/// Advances the app's clock half a step (no step: the drawing interpolates halfway), stops it, reads the
/// drawn node buffer back until it matches what the CPU draws from its own placement (or 120 frames have
/// passed) and returns the largest difference (m), its node and the number of drawn nodes.
fn compare_drawn_halfway(app: &mut App) -> (f32, usize, usize) {
    // On to half a step past the last step, without a step (the drawing interpolates halfway), then time
    // stands still.
    let fixed = app.world().resource::<Time<Fixed>>();
    let to_halfway = (fixed.timestep() / 2).saturating_sub(fixed.overstep());
    app.insert_resource(TimeUpdateStrategy::ManualDuration(to_halfway));
    app.update();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
    let alpha = app.world().resource::<Time<Fixed>>().overstep_fraction();
    assert!((alpha - 0.5).abs() < 1e-3, "drawn halfway between steps: {alpha}");

    // What the CPU would draw: its placement, interpolated as `HairStrips` writes it.
    let mut meshes = app.world_mut().query::<&HairMesh>();
    let hair_mesh = meshes.single(app.world()).expect("one hair mesh");
    let buffer = hair_mesh.positions_buffer().clone();
    let layout: Vec<GuideLayout> = hair_mesh.strips().guides().to_vec();
    let world = app.world();
    let mut expected = HairStrips::default();
    expected.set_layout(layout.iter().copied());
    let lookup = |entity| Some((world.get::<StrandNodes>(entity)?, world.get::<FollowerNodes>(entity)));
    expected.fill(alpha, 1, lookup).expect("hair to draw");
    let followers: usize = layout.iter().map(|guide| guide.followers as usize).sum();
    assert_eq!(layout.len(), 150);
    assert!(followers >= 600, "{followers} followers");

    let received = ReadBack::default();
    let sink = received.clone();
    let reader = app
        .world_mut()
        .spawn(Readback::buffer(buffer))
        .observe(move |event: On<ReadbackComplete>| {
            *sink.0.lock().unwrap() = Some(event.to_shader_type());
        })
        .id();
    let mut worst = (f32::INFINITY, 0);
    for _ in 0..120 {
        app.update();
        let Some(drawn) = received.0.lock().unwrap().take() else { continue };
        assert!(drawn.len() >= expected.positions().len(), "{} floats read back", drawn.len());
        let difference = |node: usize| {
            let at = |values: &[f32]| Vec3::from_slice(&values[3 * node..3 * node + 3]);
            at(&drawn).distance(at(expected.positions()))
        };
        let (largest, node) = (0..expected.node_count())
            .map(|node| (difference(node), node))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
        worst = (largest, node);
        if largest <= 1e-5 {
            break;
        }
    }
    app.world_mut().despawn(reader);
    assert!(worst.0.is_finite(), "no read-back arrived from the GPU in 120 frames");
    (worst.0, worst.1, expected.node_count())
}
