//! Hair on a rig of its own scale and axes (a character modelled in centimetres and spawned at a scale of
//! 0.01, a head joint whose face looks along its own `+X`): the same groom, in metres along its design
//! axes, is the same hair in the world as on an unscaled head facing Bevy's `−Z`.

use bevy::prelude::*;
use hair_sim_support::headless::hair_app;

use bevy_hair_sim::prelude::*;

/// Where both heads are, and how they turn (world).
fn head_pose(step: usize) -> Transform {
    let t = step as f32 / 60.0;
    Transform::from_xyz(0.03 * (8.0 * t).sin(), 1.6, 0.02 * (5.0 * t).cos())
        .with_rotation(Quat::from_rotation_y(0.3 + 1.2 * t) * Quat::from_rotation_x(0.2 * (3.0 * t).sin()))
}

/// The groom both heads wear (metres, its design axes), with followers placed on the CPU.
fn groom() -> HairGroom {
    HairGroom {
        strand_count: 48,
        followers_per_guide: 3,
        segments: 12,
        // Each follower's clumping and scatter are drawn from its root's head-local bits, which differ
        // between the rig and the plain head: none, so that the followers can be compared.
        follower_clumping_variation: 0.0,
        follower_scatter: 0.0,
        scalp: Scalp { centre: Vec3::new(0.0, 0.01, 0.005), semi_axes: Vec3::new(0.078, 0.095, 0.1), ..default() },
        ..default()
    }
}

/// The rig's head joint: its face looks along its local `+X` and its crown along its local `+Z`.
const RIG_FORWARD: Vec3 = Vec3::X;
const RIG_UP: Vec3 = Vec3::Z;

/// An app with a rig scaled `scale` (a root, and a head joint under it placed 5 cm above the root in the
/// world), the joint turned so that the head's face and crown are where the unscaled head's are; the
/// groom on the joint and a skull and shoulders placed in the world. Returns the app, the rig's root and
/// the head joint.
fn rig(scale: f32) -> (App, Entity, Entity) {
    let mut app = hair_app();
    let axes = HeadAxes::new(RIG_FORWARD, RIG_UP);
    let design_to_joint = axes.rotation().unwrap();
    let root = app.world_mut().spawn(root_pose(0, scale)).id();
    let joint = Transform::from_translation(Vec3::new(0.0, 0.05, 0.0) / scale)
        .with_rotation(design_to_joint.inverse())
        .with_scale(Vec3::ONE);
    let head = app.world_mut().spawn((HairHead, HairGroom { head_axes: axes, ..groom() }, joint, ChildOf(root))).id();
    spawn_body(&mut app, head);
    (app, root, head)
}

/// The rig's root at `step`: the head pose less the joint's offset, scaled `scale`.
fn root_pose(step: usize, scale: f32) -> Transform {
    let pose = head_pose(step);
    Transform {
        translation: pose.translation - pose.rotation * Vec3::new(0.0, 0.05, 0.0),
        scale: Vec3::splat(scale),
        ..pose
    }
}

/// A skull ellipsoid and shoulders (a capsule below the head) tied to `head`, placed in the world where
/// the head is at step 0 and moved with it.
fn spawn_body(app: &mut App, head: Entity) {
    let pose = head_pose(0);
    app.world_mut().spawn((HairCollider::ellipsoid(Vec3::new(0.075, 0.09, 0.095)), HairColliderOf(head), pose));
    let shoulders = Transform::from_translation(pose.translation + pose.rotation * Vec3::new(0.0, -0.25, 0.02))
        .with_rotation(pose.rotation * Quat::from_rotation_z(std::f32::consts::FRAC_PI_2));
    app.world_mut().spawn((HairCollider::capsule(0.09, 0.17), HairColliderOf(head), shoulders));
}

/// An unscaled head facing `−Z` with the groom.
fn plain_head() -> (App, Entity) {
    let mut app = hair_app();
    let head = app.world_mut().spawn((HairHead, groom(), head_pose(0))).id();
    spawn_body(&mut app, head);
    (app, head)
}

/// Every guide node, then every follower node, of `head`'s strands in their order, world space.
fn hair_nodes(app: &App, head: Entity) -> (Vec<Vec3>, Vec<Vec3>) {
    let guides = app.world().get::<HeadStrands>(head).expect("the groom grew").strands().to_vec();
    let nodes = guides.iter().flat_map(|&guide| app.world().get::<StrandNodes>(guide).unwrap().positions.clone());
    let followers = guides.iter().flat_map(|&guide| app.world().get::<FollowerNodes>(guide).unwrap().positions.clone());
    (nodes.collect(), followers.collect())
}

/// The largest distance between matching points of two lists, m.
fn largest_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max)
}

#[test]
fn a_groom_on_a_scaled_turned_rig_is_the_same_hair_as_on_an_unscaled_head() {
    for scale in [0.01, 100.0] {
        let (mut plain, plain_head) = plain_head();
        let (mut rigged, root, head) = rig(scale);
        // Grown, preloaded and draped over the shoulders; then the heads shake and turn for a second.
        for step in 0..=60 {
            if step > 0 {
                *plain.world_mut().get_mut::<Transform>(plain_head).unwrap() = head_pose(step);
                *rigged.world_mut().get_mut::<Transform>(root).unwrap() = root_pose(step, scale);
            }
            plain.update();
            rigged.update();
            if ![2, 10, 60].contains(&step) {
                continue;
            }
            let (plain_nodes, plain_followers) = hair_nodes(&plain, plain_head);
            let (rig_nodes, rig_followers) = hair_nodes(&rigged, head);
            assert_eq!(plain_nodes.len(), 48 * 13);
            assert_eq!(plain_followers.len(), 48 * 3 * 13);
            let guides = largest_distance(&plain_nodes, &rig_nodes);
            let followers = largest_distance(&plain_followers, &rig_followers);
            println!(
                "scale {scale}, step {step}: the rig's hair from the plain head's: guides {guides:.1e} m, followers {followers:.1e} m"
            );
            let tolerance = if step <= 10 { ROUNDING_TOLERANCE } else { SHAKEN_TOLERANCE };
            assert!(guides <= tolerance, "guides {guides} m apart at scale {scale}, step {step}");
            assert!(followers <= tolerance, "followers {followers} m apart at scale {scale}, step {step}");
        }
        // The strands are stepped at full length: hair is sized in metres, not in the rig's units.
        let strand = rigged.world().get::<HeadStrands>(head).unwrap().strands()[0];
        let plain_strand = plain.world().get::<HeadStrands>(plain_head).unwrap().strands()[0];
        let length = |app: &App, strand| {
            let x = &app.world().get::<StrandNodes>(strand).unwrap().positions;
            x.windows(2).map(|edge| edge[0].distance(edge[1])).sum::<f32>()
        };
        assert!((length(&rigged, strand) - length(&plain, plain_strand)).abs() < 1e-4);
    }
}

/// How far apart the two heads' hair may be while it is grown and for the first sixth of a second of
/// shaking, m. They differ only in rounding: the rig's root placed through its scale (`x / s · s` in
/// `f32`: an ulp of 1.6 m, 1.2e-7 m) and its frames turned through the joint's rotation and back (a few
/// ulps of the 0.3 m strands); measured 5e-7 grown and 9e-7 after 10 steps.
const ROUNDING_TOLERANCE: f32 = 1e-5;

/// How far apart after a second of shaking, m. A rounding difference does not stay one: a node that
/// touches the skull or shoulders a step earlier on one head, or a Newton iteration more, moves the strand
/// by up to a contact's push-out (measured here: 6e-5 m after 20 steps, 5e-4 m after 60; a CPU restarted
/// from its own state rounded to `f32` drifts by millimetres in two seconds, `tests/gpu/plugin.rs`). The
/// wrong scale moves hair by the rig's units for metres (metres at 0.01, hundredths of its size at 100).
const SHAKEN_TOLERANCE: f32 = 2e-3;

#[test]
fn a_head_scaled_unevenly_is_told_once_and_its_hair_grown_at_the_mean_scale() {
    let _log = hair_sim_support::logs::serial();
    let mut app = hair_app();
    // Half as wide as it is tall and deep: hair keeps its shape as a head turns, so it cannot follow.
    let scale = Vec3::new(0.005, 0.01, 0.01);
    let groom = HairGroom { strand_count: 20, segments: 8, combing: None, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0).with_scale(scale))).id();
    for _ in 0..5 {
        app.update();
    }
    let lines = hair_sim_support::logs::take();
    let told: Vec<_> = lines.iter().filter(|(_, line)| line.contains("differs between its axes")).collect();
    assert_eq!(told.len(), 1, "told once: {lines:?}");
    assert!(told[0].1.contains(&head.to_string()), "{told:?}");
    // Grown at the mean scale (0.00833): roots on the default 10 cm skull in metres, placed through the
    // head's own scale, so within the skull scaled by the axes' ratios to the mean.
    let strands = app.world().get::<HeadStrands>(head).expect("the hair grew").strands().to_vec();
    assert_eq!(strands.len(), 20);
    let mean = scale.element_sum() / 3.0;
    for strand in strands {
        let root = app.world().get::<StrandNodes>(strand).unwrap().positions[0] - Vec3::new(0.0, 1.6, 0.0);
        let on_skull = (root / (0.1 * scale / mean)).length();
        assert!((on_skull - 1.0).abs() < 1e-4, "a root at {on_skull} of the scaled skull");
    }
}
