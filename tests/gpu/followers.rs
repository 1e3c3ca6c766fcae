//! Followers placed and hair interpolated on the GPU (`src/render/followers.wgsl`) against the CPU's
//! placement (`src/followers`) and drawing (`HairStrips::fill`), on a real adapter: Mesa's software
//! Vulkan (lavapipe) on a machine without a GPU, which `.ci/run` installs; and what the hair shader
//! draws there: motion vectors, the coverage under a jittered view (TAA), light through the hair. Without
//! any adapter the tests fail (Bevy's renderer cannot start); they never skip.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use bevy::core_pipeline::prepass::MotionVectorPrepass;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::storage::ShaderBuffer;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::followers::{FollowerPlacement, PlaceFollowersOnCpu};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::render::{GuideLayout, HairStrips};
use bevy_hair_sim::simulation::{PackedStrandPose, SimulatedStrand, packed::walk_directors};

/// Fixed step, s.
const DT: f64 = 1.0 / 60.0;

/// The largest angle (rad) a director walked from a packed pose may be from the strand's material frame
/// about the drawn edge: the root's code (2⁻²¹ rad), then per vertex at most 1e-6 rad (half a step of the
/// twist's code, 1.9e-7; the f32 rounding of `θ^i − θ^{i−1} + m_i` for angles of a few rad, 3 × 2.4e-7;
/// the transport and renormalisation in f32, 1e-7), adding up over the 24 vertices of a strand.
const WALKED_DIRECTOR_TOLERANCE: f32 = 1.0 / 2_097_152.0 + 24.0 * 1e-6;

/// What the read-back observer last received: the drawn node buffer.
#[derive(Resource, Clone, Default)]
struct ReadBack(Arc<Mutex<Option<Vec<f32>>>>);

/// A headless app with Bevy's renderer on whatever adapter wgpu finds, the hair plugin, one fixed step
/// per update.
fn rendering_app() -> App {
    let mut app = App::new();
    // The CPU's step (the GPU's is on by default where the adapter can run it).
    app.add_plugins((crate::headless_renderer(), HairPlugins::default()))
        .insert_resource(HairGpuSettings { enabled: false, ..default() })
        .insert_resource(Time::<Fixed>::from_seconds(DT))
        .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    crate::finish_adding_plugins(&mut app);
    app.update();
    app
}

/// The rounded box on the head (m): wider than the skull's 7.8 cm at the temples.
const BOX_HALF_EXTENTS: Vec3 = Vec3::new(0.08, 0.03, 0.05);
const BOX_ROUNDING: f32 = 0.01;

/// How many follower nodes the CPU placed on the surface of the head's rounded box, grown by the
/// strand's thickness (within 1 µm).
fn followers_on_the_box(app: &App, head: Entity) -> usize {
    let pose = *app.world().get::<Transform>(head).unwrap();
    let margin = app.world().resource::<HairSettings>().collision_margin;
    let guides = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    guides
        .iter()
        .map(|&guide| {
            let thickness = app.world().get::<SimulatedStrand>(guide).unwrap().collision_thickness(margin);
            let followers = app.world().get::<FollowerNodes>(guide).unwrap();
            followers
                .positions
                .iter()
                .filter(|position| {
                    let local = pose.rotation.inverse() * (**position - pose.translation);
                    let q = local.abs() - BOX_HALF_EXTENTS;
                    let distance = q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - BOX_ROUNDING - thickness;
                    distance.abs() < 1e-6
                })
                .count()
        })
        .sum()
}

/// The pose of the shaking, turning head at `step`.
fn head_pose(step: usize) -> Transform {
    let t = step as f32 / 60.0;
    Transform::from_xyz(0.04 * (9.0 * t).sin(), 1.6, 0.02 * (5.0 * t).cos())
        .with_rotation(Quat::from_rotation_y(1.5 * t))
}

#[test]
fn followers_placed_on_the_gpu_match_the_cpu_placement() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
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
        // A rounded box wider than the skull at the temples: hair on the sides lies on it.
        app.world_mut()
            .spawn((HairCollider::rounded_cuboid(BOX_HALF_EXTENTS, BOX_ROUNDING), HairColliderOf(head), head_pose(0)))
            .id(),
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
    // Some followers were pushed out of the box onto its surface (and so through the shader's cuboid).
    let on_box = followers_on_the_box(&app, head);
    println!("{on_box} follower nodes placed on the rounded box's surface");
    assert!(on_box > 0, "no follower lies on the box: the test does not reach the cuboid");
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
    let alpha = crate::stop_halfway_between_steps(app);

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

    let mut worst = (f32::INFINITY, 0);
    crate::read_back_until(app, buffer, 120, |drawn| {
        assert!(drawn.len() >= expected.positions().len(), "{} floats read back", drawn.len());
        let difference = |node: usize| {
            let at = |values: &[f32]| Vec3::from_slice(&values[3 * node..3 * node + 3]);
            at(drawn).distance(at(expected.positions()))
        };
        worst = (0..expected.node_count())
            .map(|node| (difference(node), node))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
        worst.0 <= 1e-5
    });
    assert!(worst.0.is_finite(), "no read-back arrived from the GPU in 120 frames");
    (worst.0, worst.1, expected.node_count())
}

/// Without a GPU: the frames the GPU walks from the poses the step packs (`walk_directors`, which `frames`
/// in `followers.wgsl` follows line by line) against the strands' own material frames, on curly hair
/// (rest curvature and twist) on a shaking, turning head for two seconds.
#[test]
fn frames_walked_from_packed_poses_are_the_material_frames() {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, HairPlugins::default()))
        .insert_resource(Time::<Fixed>::from_seconds(DT))
        .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    let groom = HairGroom { strand_count: 60, segments: 24, style: HairStyle::Curly, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, head_pose(0))).id();
    for _ in 0..3 {
        app.update();
    }
    let strands = app.world().get::<HeadStrands>(head).expect("the groom grew").strands().to_vec();
    assert_eq!(strands.len(), 60);
    for &strand in &strands {
        app.world_mut().entity_mut(strand).insert(PackedStrandPose::default());
    }
    let margin = HairSettings::default().collision_margin;
    let (mut worst, mut checked, mut directors) = (0.0_f32, 0, Vec::new());
    for step in 1..=120 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(step);
        app.update();
        if step % 10 != 0 {
            continue;
        }
        let mut query = app.world_mut().query::<(&PackedStrandPose, &StrandNodes, &StrandFrames, &SimulatedStrand)>();
        for (pose, nodes, frames, strand) in query.iter(app.world()) {
            let positions: &[Vec3] = bytemuck::cast_slice(pose.positions());
            assert_eq!(positions, &nodes.positions[..], "the pose's nodes are the strand's");
            assert_eq!(pose.thickness(), strand.collision_thickness(margin));
            assert_eq!(pose.flags(), 0, "frames usable, stepped from the step before");
            walk_directors(pose, &mut directors);
            assert_eq!(directors.len(), positions.len());
            for (node, walked) in directors.iter().enumerate() {
                let edge = node.saturating_sub(1);
                let expected = frames.material_frame(edge).unwrap().m1;
                // The walk's tangent is the edge's direction in the drawn nodes (as on the GPU); the twist
                // about it is what the codes carry.
                let tangent = (positions[edge + 1] - positions[edge]).normalize();
                let across = (expected - expected.dot(tangent) * tangent).normalize();
                worst = worst.max(walked.cross(across).length().asin());
                checked += 1;
            }
        }
    }
    println!("{checked} directors walked from packed poses: largest angle from the material frame {worst:.2e} rad");
    assert!(checked >= 60 * 12 * 25);
    assert!(worst <= WALKED_DIRECTOR_TOLERANCE, "{worst} rad");
}

/// What the CPU draws of `app`'s one hair mesh at the fixed clock's fraction `alpha` of a step (its own
/// follower placement, interpolated as `HairStrips` writes it).
fn drawn_on_the_cpu(app: &mut App, alpha: f32) -> Vec<f32> {
    let mut meshes = app.world_mut().query::<&HairMesh>();
    let layout: Vec<GuideLayout> = meshes.single(app.world()).expect("one hair mesh").strips().guides().to_vec();
    let world = app.world();
    let mut expected = HairStrips::default();
    expected.set_layout(layout.iter().copied());
    let lookup = |entity| Some((world.get::<StrandNodes>(entity)?, world.get::<FollowerNodes>(entity)));
    expected.fill(alpha, 1, lookup).expect("hair to draw");
    expected.positions().to_vec()
}

/// The largest distance, m, between the nodes of two position lists (`x y z` per node), and its node.
fn largest_difference(drawn: &[f32], expected: &[f32]) -> (f32, usize) {
    assert!(drawn.len() >= expected.len(), "{} floats read back for {}", drawn.len(), expected.len());
    let at = |values: &[f32], node: usize| Vec3::from_slice(&values[3 * node..3 * node + 3]);
    (0..expected.len() / 3)
        .map(|node| (at(drawn, node).distance(at(expected, node)), node))
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
}

/// Reads `buffer` back from the frame `app.update()` draws next, and goes on updating (time standing
/// still) until it arrives.
fn read_back_next_frame(app: &mut App, buffers: [Handle<ShaderBuffer>; 2]) -> [Vec<f32>; 2] {
    let received = [ReadBack::default(), ReadBack::default()];
    let readers = buffers.map(|buffer| app.world_mut().spawn(Readback::buffer(buffer)).id());
    for (reader, slot) in readers.iter().zip(&received) {
        let sink = slot.clone();
        app.world_mut().entity_mut(*reader).observe(move |event: On<ReadbackComplete>| {
            let mut slot = sink.0.lock().unwrap();
            // The first frame's read-back only: later frames drew with time standing still.
            if slot.is_none() {
                *slot = Some(event.to_shader_type());
            }
        });
    }
    for _ in 0..120 {
        app.update();
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
        if received.iter().all(|slot| slot.0.lock().unwrap().is_some()) {
            break;
        }
    }
    for reader in readers {
        app.world_mut().despawn(reader);
    }
    received.map(|slot| slot.0.lock().unwrap().take().expect("a read-back from the GPU in 120 frames"))
}

#[test]
fn the_motion_vectors_draw_each_hair_from_where_it_was_drawn_the_frame_before() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let mut app = rendering_app();
    assert!(app.get_sub_app(RenderApp).is_some(), "Bevy's renderer started (a GPU adapter was found)");
    let groom = HairGroom { strand_count: 150, followers_per_guide: 6, segments: 16, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, PlaceFollowersOnCpu, head_pose(0))).id();
    for step in 1..=60 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(step);
        app.update();
    }
    // With no camera drawing motion vectors, the frame before is not kept (nothing is copied).
    let mut meshes = app.world_mut().query::<&HairMesh>();
    let hair_mesh = meshes.single(app.world()).expect("one hair mesh");
    let buffers = [hair_mesh.positions_buffer().clone(), hair_mesh.previous_positions_buffer().clone()];
    let [drawn, previous] = read_back_next_frame(&mut app, buffers.clone());
    assert!(drawn.iter().any(|&value| value != 0.0), "the hair is drawn");
    assert!(previous.iter().all(|&value| value == 0.0), "the frame before was kept with no camera asking for it");
    // A camera that draws motion vectors: from now on the frame before is kept. Its first frame has none
    // kept: the hair starts still there (its frame before is made this frame's), not from zeros.
    app.world_mut().spawn((Camera3d::default(), MotionVectorPrepass));
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(61);
    let [drawn, previous] = read_back_next_frame(&mut app, buffers.clone());
    let (first, node) = largest_difference(&previous, &drawn);
    assert_eq!(first, 0.0, "on the first frame with motion vectors, node {node} moved {first} m");
    for step in 62..=70 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(step);
        app.update();
    }
    // A quarter of a step on, twice, without a step: the drawing moves between the last two steps' poses.
    let quarter = Duration::from_secs_f64(DT / 4.0);
    let fixed = app.world().resource::<Time<Fixed>>();
    let to_quarter = quarter.saturating_sub(fixed.overstep());
    app.insert_resource(TimeUpdateStrategy::ManualDuration(to_quarter));
    app.update();
    let first = app.world().resource::<Time<Fixed>>().overstep_fraction();
    let before = drawn_on_the_cpu(&mut app, first);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(quarter));
    let [drawn, previous] = read_back_next_frame(&mut app, buffers.clone());
    let second = app.world().resource::<Time<Fixed>>().overstep_fraction();
    let now = drawn_on_the_cpu(&mut app, second);
    let (moved, _) = largest_difference(&now, &before);
    let (off_now, node_now) = largest_difference(&drawn, &now);
    let (off_before, node_before) = largest_difference(&previous, &before);
    println!(
        "drawn at {first:.2} then {second:.2} of a step: the hair moved up to {moved:.2e} m; this frame's buffer \
         {off_now:.2e} m from the CPU's drawing (node {node_now}), last frame's {off_before:.2e} m (node {node_before})"
    );
    assert!(moved > 1e-3, "the hair moved between the two frames ({moved} m): the test sees no motion");
    assert!(off_now <= 1e-5, "this frame's drawn node {node_now} is {off_now} m from the CPU's");
    assert!(off_before <= 1e-5, "the previous positions' node {node_before} is {off_before} m from last frame's");

    // Time standing still, the next frame's previous positions are this frame's: no motion.
    let [drawn, previous] = read_back_next_frame(&mut app, buffers);
    let (still, node) = largest_difference(&previous, &drawn);
    assert_eq!(still, 0.0, "standing still, node {node} moved {still} m between frames");
}

#[test]
fn hair_placed_on_the_gpu_starts_still_under_motion_vectors_and_then_moves() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let mut app = rendering_app();
    assert!(app.get_sub_app(RenderApp).is_some(), "Bevy's renderer started (a GPU adapter was found)");
    // The followers placed where they are drawn, on the GPU (the renderer's default).
    let groom = HairGroom { strand_count: 150, followers_per_guide: 6, segments: 16, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, head_pose(0))).id();
    for step in 1..=30 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(step);
        app.update();
    }
    let mut meshes = app.world_mut().query::<&HairMesh>();
    let hair_mesh = meshes.single(app.world()).expect("one hair mesh");
    let buffers = [hair_mesh.positions_buffer().clone(), hair_mesh.previous_positions_buffer().clone()];
    // Until the GPU's pipelines are built (asynchronously), nothing is drawn.
    let drawn_yet = |app: &mut App| read_back_next_frame(app, buffers.clone())[0].iter().any(|&value| value != 0.0);
    assert!((0..20).any(|_| drawn_yet(&mut app)), "the GPU never drew the hair");
    // The first frame a camera draws motion vectors: the frame before is what the GPU just placed and drew
    // (without it, zeros: every vector from the origin).
    app.world_mut().spawn((Camera3d::default(), MotionVectorPrepass));
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(31);
    let [drawn, previous] = read_back_next_frame(&mut app, buffers.clone());
    assert!(drawn.iter().any(|&value| value != 0.0), "the hair is drawn");
    let (first, node) = largest_difference(&previous, &drawn);
    assert_eq!(first, 0.0, "on the first frame with motion vectors, node {node} moved {first} m");
    // The next frame, a step on: the frame before is kept, and the hair moved from it.
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose(32);
    let [drawn_next, previous_next] = read_back_next_frame(&mut app, buffers);
    let (moved, _) = largest_difference(&drawn_next, &previous_next);
    let (kept, node) = largest_difference(&previous_next, &drawn);
    println!("placed on the GPU: the hair moved up to {moved:.2e} m in the frame after the first");
    assert!(moved > 1e-3, "the hair did not move ({moved} m): the test sees no motion");
    assert_eq!(kept, 0.0, "the frame before is not what was drawn: node {node} {kept} m off");
}

/// An sRGB image of `width` × `height` pixels, black, that a camera can draw into and the test read back.
fn render_target(app: &mut App, width: u32, height: u32) -> Handle<Image> {
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages};
    let mut target = Image::new_fill(
        Extent3d { width, height, depth_or_array_layers: 1 },
        TextureDimension::D2,
        &[0; 4],
        TextureFormat::Rgba8UnormSrgb,
        default(),
    );
    target.texture_descriptor.usage |=
        TextureUsages::RENDER_ATTACHMENT | TextureUsages::COPY_SRC | TextureUsages::TEXTURE_BINDING;
    app.world_mut().resource_mut::<Assets<Image>>().add(target)
}

/// The pixels (RGBA8, row after row) of `image`, as the next frame draws it.
fn read_back_image(app: &mut App, image: Handle<Image>) -> Vec<u8> {
    let received = Arc::new(Mutex::new(None::<Vec<u8>>));
    let sink = received.clone();
    let reader = app
        .world_mut()
        .spawn(Readback::texture(image))
        .observe(move |event: On<ReadbackComplete>| {
            sink.lock().unwrap().get_or_insert_with(|| event.data.clone());
        })
        .id();
    for _ in 0..120 {
        app.update();
        if received.lock().unwrap().is_some() {
            break;
        }
    }
    app.world_mut().despawn(reader);
    received.lock().unwrap().take().expect("a read-back from the GPU in 120 frames")
}

#[test]
fn without_multisampling_the_hair_s_coverage_is_drawn_anew_for_each_jitter_of_the_view_and_kept_without() {
    use bevy::camera::RenderTarget;
    use bevy::render::camera::TemporalJitter;
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let mut app = rendering_app();
    assert!(app.get_sub_app(RenderApp).is_some(), "Bevy's renderer started (a GPU adapter was found)");
    // 200 guides seen from 0.6 m on a 320 × 240 image (pixels of 2 mm), drawn a fraction of a pixel thick:
    // each hair is drawn one pixel wide on that share of its pixels, by chance.
    let image = render_target(&mut app, 320, 240);
    let groom = HairGroom { strand_count: 200, followers_per_guide: 0, segments: 12, ..default() };
    // Hairs drawn a tenth of a pixel thick or so: each covers its pixels by chance.
    let appearance = HairAppearance { thickness_scale: 0.01, ..default() };
    app.world_mut().spawn((HairHead, groom, appearance, Transform::default()));
    app.world_mut()
        .spawn((DirectionalLight::default(), Transform::from_xyz(1.0, 2.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y)));
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            Camera { clear_color: Color::BLACK.into(), ..default() },
            RenderTarget::Image(image.clone().into()),
            Msaa::Off,
            TemporalJitter::default(),
            Transform::from_xyz(0.0, 0.0, 0.6).looking_at(Vec3::ZERO, Vec3::Y),
        ))
        .id();
    // The hair stands still (no gravity, no step changes it): only the view's jitter changes.
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    for _ in 0..5 {
        app.update();
    }
    let frame_with = |app: &mut App, offset: Vec2| {
        app.world_mut().get_mut::<TemporalJitter>(camera).unwrap().offset = offset;
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
        read_back_image(app, image.clone())
    };
    let hair = |pixels: &[u8]| -> Vec<bool> { pixels.chunks_exact(4).map(|pixel| pixel[..3] != [0, 0, 0]).collect() };
    // The first frames draw nothing while the pipelines compile.
    for _ in 0..60 {
        if hair(&frame_with(&mut app, Vec2::ZERO)).contains(&true) {
            break;
        }
    }
    // Offsets of a ten-thousandth of a pixel: the geometry covers the same pixel centres, only the seed differs.
    let still = [hair(&frame_with(&mut app, Vec2::ZERO)), hair(&frame_with(&mut app, Vec2::ZERO))];
    let jittered = [Vec2::new(1e-4, 0.0), Vec2::new(2e-4, 0.0), Vec2::new(0.0, 1e-4)]
        .map(|offset| hair(&frame_with(&mut app, offset)));
    let count = |pixels: &[bool]| pixels.iter().filter(|&&hair| hair).count();
    let differing = |a: &[bool], b: &[bool]| a.iter().zip(b).filter(|(a, b)| a != b).count();
    let drawn = count(&still[0]);
    println!(
        "{drawn} of {} pixels hair without jitter; with the three jitters {:?}; pixels that differ from the first: {} without jitter, {:?} with",
        still[0].len(),
        jittered.each_ref().map(|pixels| count(pixels)),
        differing(&still[0], &still[1]),
        jittered.each_ref().map(|pixels| differing(&still[0], pixels)),
    );
    assert!(drawn > 1000, "the hair covers {drawn} pixels: the test does not see it");
    assert_eq!(
        differing(&still[0], &still[1]),
        0,
        "without jitter the hair's pixels changed from one frame to the next"
    );
    for pixels in &jittered {
        let (changed, now) = (differing(&still[0], pixels), count(pixels));
        // Drawn anew, a pixel hair by chance `c` before changes with chance `2c(1 − c)`: as many pixels
        // change as are drawn, for hairs of little coverage that seldom overlap. Drawn the same, none.
        assert!(
            changed * 2 > drawn,
            "a new jitter changed only {changed} of {drawn} hair pixels: the draw does not follow it"
        );
        let ratio = now as f64 / drawn as f64;
        assert!(
            (0.85..1.15).contains(&ratio),
            "a new jitter drew {now} hair pixels against {drawn}: the coverage changed"
        );
    }
}

/// A rendering app with a head of 600 guides grown and held still, lit only by one shadowed directional
/// light from `light_from` (towards the origin), and a camera drawing into an image: the head, the image.
fn lit_head(light_from: Vec3) -> (App, Entity, Handle<Image>) {
    use bevy::camera::RenderTarget;
    use bevy::light::CascadeShadowConfigBuilder;
    let mut app = rendering_app();
    assert!(app.get_sub_app(RenderApp).is_some(), "Bevy's renderer started (a GPU adapter was found)");
    let image = render_target(&mut app, 320, 240);
    let groom = HairGroom { strand_count: 600, followers_per_guide: 4, segments: 12, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, HairAppearance::default(), Transform::default())).id();
    // Its shadow map's texels a millimetre wide.
    app.world_mut().insert_resource(GlobalAmbientLight::NONE);
    app.world_mut().spawn((
        DirectionalLight { illuminance: 10_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_translation(light_from).looking_at(Vec3::ZERO, Vec3::Y),
        CascadeShadowConfigBuilder { num_cascades: 1, maximum_distance: 1.5, ..default() }.build(),
    ));
    app.world_mut().spawn((
        Camera3d::default(),
        Camera { clear_color: Color::BLACK.into(), ..default() },
        RenderTarget::Image(image.clone().into()),
        // Bevy's default tonemapping needs a lookup table the tests do not build.
        bevy::core_pipeline::tonemapping::Tonemapping::None,
        Transform::from_xyz(0.45, 0.1, 0.4).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    // A few steps to grow the groom; then time stands still.
    for _ in 0..5 {
        app.update();
    }
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
    (app, head, image)
}

/// The image [`lit_head`]'s camera draws once the head's appearance is changed by `change` (a few frames
/// to take it), the first frames waited out while the pipelines compile.
fn frame_of(app: &mut App, head: Entity, image: &Handle<Image>, change: impl Fn(&mut HairAppearance)) -> Vec<u8> {
    let mut appearance = app.world_mut().get::<HairAppearance>(head).unwrap().clone();
    change(&mut appearance);
    let changed = *app.world().get::<HairAppearance>(head).unwrap() != appearance;
    if changed {
        *app.world_mut().get_mut::<HairAppearance>(head).unwrap() = appearance;
    }
    for _ in 0..if changed { 3 } else { 0 } {
        app.update();
    }
    for _ in 0..60 {
        let pixels = read_back_image(app, image.clone());
        if pixels.chunks_exact(4).any(|pixel| pixel[..3] != [0, 0, 0]) {
            return pixels;
        }
    }
    panic!("nothing was drawn in 60 frames");
}

/// The pixels of `frame` where hair was drawn (not the black background), by index.
fn hair_pixels(frame: &[u8]) -> Vec<usize> {
    (0..frame.len() / 4).filter(|&pixel| frame[4 * pixel..4 * pixel + 3] != [0, 0, 0]).collect()
}

/// `pixel`'s brightness in `frame`, the mean of its three channels (0–255).
fn brightness(frame: &[u8], pixel: usize) -> f64 {
    frame[4 * pixel..4 * pixel + 3].iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0
}

/// The mean brightness of `pixels` in `frame` (0–255).
fn mean_brightness(frame: &[u8], pixels: &[usize]) -> f64 {
    pixels.iter().map(|&pixel| brightness(frame, pixel)).sum::<f64>() / pixels.len() as f64
}

#[test]
fn light_reaches_into_the_hair_the_deeper_the_further_it_penetrates() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    // The only light: from above, behind and to the left.
    let (mut app, head, image) = lit_head(Vec3::new(-1.0, 3.0, -2.0));
    let frame_with = |app: &mut App, penetration: f32| {
        frame_of(app, head, &image, |appearance| appearance.light_penetration = penetration)
    };
    let hard = frame_with(&mut app, 0.0);
    let hair = hair_pixels(&hard);
    let hard = mean_brightness(&hard, &hair);
    let rows: Vec<(f32, f64)> = [0.002, 0.008, 0.05]
        .into_iter()
        .map(|penetration| (penetration, mean_brightness(&frame_with(&mut app, penetration), &hair)))
        .collect();
    println!(
        "{} hair pixels; mean brightness (0–255): hard shadows {hard:.2}; by light penetration (m) {rows:?}",
        hair.len()
    );
    assert!(hair.len() > 3000, "{} hair pixels: the test does not see the hair", hair.len());
    for pair in rows.windows(2) {
        let ((shallow, darker), (deep, lighter)) = (pair[0], pair[1]);
        assert!(
            lighter > 1.05 * darker,
            "light penetrating {deep} m lights the hair {lighter:.2}, {shallow} m {darker:.2}: no deeper"
        );
    }
    // The shadow map's hard shadow, offset 2 cm towards the light (Bevy's default depth bias), leaves lit the
    // hair behind less than 2 cm of hair; light that penetrates 2 mm darkens it.
    assert!(hard > 1.2 * rows[0].1, "hard shadows light the hair {hard:.2}, 2 mm of penetration {:.2}", rows[0].1);
}

#[test]
fn filtered_highlights_keep_their_light_and_lose_their_glints() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    // The only light: from above and beside the camera, so that the hair facing it shows its highlights.
    let (mut app, head, image) = lit_head(Vec3::new(1.0, 2.0, 1.5));
    let frames = [0.0, 1.0]
        .map(|filtering| frame_of(&mut app, head, &image, |appearance| appearance.highlight_filtering = filtering));
    // Hair pixels: drawn in either frame (the two draw the same hair, only lit differently).
    let mut hair = hair_pixels(&frames[0]);
    hair.extend(hair_pixels(&frames[1]));
    hair.sort_unstable();
    hair.dedup();
    let (width, height) = (320, 240);
    let [unfiltered, filtered] = frames.map(|frame| {
        let brightness = |pixel: usize| brightness(&frame, pixel);
        let mean = mean_brightness(&frame, &hair);
        // Glints: hair pixels brighter by 30 levels (of 255) than the mean of the 8 around them.
        let glint = |&&pixel: &&usize| {
            let (x, y) = (pixel % width, pixel / width);
            if x == 0 || y == 0 || x + 1 == width || y + 1 == height {
                return false;
            }
            let around = [(0, 0), (1, 0), (2, 0), (0, 1), (2, 1), (0, 2), (1, 2), (2, 2)]
                .map(|(dx, dy)| brightness((y + dy - 1) * width + x + dx - 1));
            brightness(pixel) > around.iter().sum::<f64>() / 8.0 + 30.0
        };
        (mean, hair.iter().filter(glint).count())
    });
    println!(
        "{} hair pixels; unfiltered: mean brightness {:.2}, {} glints; filtered: mean {:.2}, {} glints",
        hair.len(),
        unfiltered.0,
        unfiltered.1,
        filtered.0,
        filtered.1
    );
    assert!(hair.len() > 3000, "{} hair pixels: the test does not see the hair", hair.len());
    assert!(unfiltered.1 > 50, "{} glints unfiltered: the test does not see the highlights", unfiltered.1);
    // The highlights' light is spread, not lost: the hair as a whole is as bright within a tenth.
    assert!(
        (filtered.0 / unfiltered.0 - 1.0).abs() < 0.1,
        "filtering changed the hair's mean brightness from {:.2} to {:.2}",
        unfiltered.0,
        filtered.0
    );
    // A third of the glints or more are gone.
    assert!(
        3 * filtered.1 <= 2 * unfiltered.1,
        "{} glints filtered against {} unfiltered: the glints stay",
        filtered.1,
        unfiltered.1
    );
}
