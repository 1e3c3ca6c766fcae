//! Colliders in the Bevy layer: a head spun and shaken hard keeps its hair outside its colliders at
//! every step, other heads' colliders are met only when included, shared colliders meet every strand,
//! and bad colliders are reported and left out.

use std::f32::consts::TAU;

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::collision::ColliderMotion;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{ColliderShape, RigidPose};
use hair_sim_support::headless::{DT, hair_app, hair_app_with, strand};

/// Deepest a checked node may be inside a collider grown by the strand's thickness, m.
const TOLERANCE: f64 = 1e-4;

/// How deep `point` (world) is inside `entity`'s collider grown by `thickness`, m (0 outside), measured
/// from the entity's `GlobalTransform` as Bevy's transform propagation computes it (not from what the
/// plugin recorded).
fn depth(app: &App, entity: Entity, thickness: f64, point: DVec3) -> f64 {
    let shape = app.world().get::<HairCollider>(entity).unwrap().shape.clone();
    let (_, rotation, translation) =
        app.world().get::<GlobalTransform>(entity).unwrap().to_scale_rotation_translation();
    let local = RigidPose::new(rotation.as_dquat(), translation.as_dvec3()).to_local(point);
    if shape == ColliderShape::Plane {
        return (thickness - local.y).max(0.0);
    }
    let grown = shape.inflated(thickness);
    if !grown.contains(local) {
        return 0.0;
    }
    local.distance(grown.closest_surface_point(local).point)
}

/// The deepest free node of `strands` inside `collider`, m.
fn deepest_node(app: &App, strands: &[Entity], collider: Entity) -> f64 {
    let margin = app.world().resource::<HairSettings>().collision_margin;
    strands
        .iter()
        .flat_map(|&entity| {
            let strand = strand(app, entity);
            let thickness = f64::from(strand.collision_thickness(margin));
            let rod = strand.rod();
            (0..rod.node_count())
                .filter(|&node| !rod.is_node_prescribed(node))
                .map(move |node| depth(app, collider, thickness, rod.positions()[node]))
        })
        .fold(0.0, f64::max)
}

#[test]
fn hair_on_a_head_spun_at_2_rev_per_s_and_shaken_at_5_m_per_s_stays_outside_its_colliders() {
    let mut app = hair_app_with(TransformPlugin);
    let scalp = Scalp { semi_axes: Vec3::new(0.078, 0.095, 0.1), ..default() };
    let groom = HairGroom { scalp, strand_count: 500, segments: 16, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let skull =
        app.world_mut().spawn((HairCollider::ellipsoid(scalp.semi_axes), HairColliderOf(head), ChildOf(head))).id();
    let neck = app
        .world_mut()
        .spawn((
            HairCollider::capsule(0.045, 0.06),
            HairColliderOf(head),
            ChildOf(head),
            Transform::from_xyz(0.0, -0.13, 0.0),
        ))
        .id();
    // Let the hair fall and settle on the still head.
    for _ in 0..60 {
        app.update();
    }
    let strands: Vec<Entity> = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    assert_eq!(strands.len(), 500);

    // Two seconds: a turn about the vertical at 2 rev/s, a nod, and a sideways shake peaking at 5 m/s.
    let (mut deepest, mut most_contacts, mut fastest) = ([0.0_f64; 2], 0, 0.0_f32);
    let mut previous = Vec3::new(0.0, 1.6, 0.0);
    for step in 1..=120 {
        let time = step as f32 * DT as f32;
        let shake = 12.5;
        let translation = Vec3::new(0.4 * (shake * time).sin(), 1.6, 0.0);
        let rotation = Quat::from_rotation_y(2.0 * TAU * time) * Quat::from_rotation_x(0.5 * (TAU * time).sin());
        *app.world_mut().get_mut::<Transform>(head).unwrap() = Transform { translation, rotation, ..default() };
        app.update();
        fastest = fastest.max(translation.distance(previous) / DT as f32);
        previous = translation;
        for (worst, collider) in deepest.iter_mut().zip([skull, neck]) {
            let depth = deepest_node(&app, &strands, collider);
            assert!(depth <= TOLERANCE, "step {step}: a node is {depth:e} m inside collider {collider}");
            *worst = worst.max(depth);
        }
        let statistics = app.world().resource::<HairStatistics>();
        assert_eq!(statistics.faults, 0, "step {step}: a strand failed");
        most_contacts = most_contacts.max(statistics.contacts);
    }
    println!(
        "fastest head speed {fastest:.2} m/s; deepest node inside the skull {:e} m, the neck {:e} m; \
         most nodes in contact {most_contacts}",
        deepest[0], deepest[1]
    );
    assert!(fastest > 4.9, "the head reached {fastest} m/s");
    assert!(most_contacts > 500, "the hair lay on its colliders: {most_contacts} nodes in contact");
}

/// A head at the origin with one 20 cm strand sticking out along +X from 30 cm up, and a second head
/// with a 4 cm ball in the way of the strand as it swings down: the strand lands on the ball if it meets
/// it, and swings through it otherwise. Returns the app, the strand, the ball and both heads.
fn strand_over_another_heads_ball() -> (App, Entity, Entity, Entity, Entity) {
    let mut app = hair_app_with(TransformPlugin);
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let strand =
        app.world_mut().spawn((HairStrand::straight(Vec3::new(0.0, 0.3, 0.0), Vec3::X, 0.2, 16), StrandOf(head))).id();
    let other_head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.08, 0.2, 0.0))).id();
    let ball =
        app.world_mut().spawn((HairCollider::sphere(0.04), HairColliderOf(other_head), ChildOf(other_head))).id();
    (app, strand, ball, head, other_head)
}

/// Runs 2 s and returns the deepest the strand's nodes went inside the ball, m.
fn deepest_over_two_seconds(app: &mut App, strand: Entity, ball: Entity) -> f64 {
    (0..120).fold(0.0, |deepest: f64, _| {
        app.update();
        deepest.max(deepest_node(app, &[strand], ball))
    })
}

#[test]
fn another_heads_colliders_are_met_only_when_included_and_not_excluded() {
    type Setup = fn(&mut World, Entity, Entity, Entity);
    let cases: [(&str, Setup, bool); 6] = [
        ("another head's collider", |_, _, _, _| {}, false),
        (
            "the other head included",
            |world, head, other_head, _| {
                world.entity_mut(head).insert(HairCollisionFilter { include: vec![other_head], ..default() });
            },
            true,
        ),
        (
            "the collider itself included",
            |world, head, _, ball| {
                world.entity_mut(head).insert(HairCollisionFilter { include: vec![ball], ..default() });
            },
            true,
        ),
        (
            "included and excluded",
            |world, head, other_head, ball| {
                world.entity_mut(head).insert(HairCollisionFilter { include: vec![other_head], exclude: vec![ball] });
            },
            false,
        ),
        (
            "the collider shared",
            |world, _, _, ball| {
                world.entity_mut(ball).insert(SharedHairCollider);
            },
            true,
        ),
        (
            "shared, and its head excluded",
            |world, head, other_head, ball| {
                world.entity_mut(ball).insert(SharedHairCollider);
                world.entity_mut(head).insert(HairCollisionFilter { exclude: vec![other_head], ..default() });
            },
            false,
        ),
    ];
    for (name, setup, meets) in cases {
        let (mut app, strand, ball, head, other_head) = strand_over_another_heads_ball();
        setup(app.world_mut(), head, other_head, ball);
        let deepest = deepest_over_two_seconds(&mut app, strand, ball);
        println!("{name}: deepest node inside the ball {deepest:e} m");
        if meets {
            assert!(deepest <= TOLERANCE, "{name}: the strand went {deepest:e} m into the ball");
        } else {
            assert!(deepest > 0.01, "{name}: the strand should fall through the ball, deepest {deepest:e} m");
        }
    }
}

#[test]
fn a_collider_with_no_head_holds_free_strands_at_their_thickness() {
    let mut app = hair_app();
    app.world_mut().spawn((HairCollider::plane(), Transform::from_xyz(0.0, 0.1, 0.0)));
    let strand = app.world_mut().spawn(HairStrand::straight(Vec3::new(0.0, 0.15, 0.0), Vec3::X, 0.2, 16)).id();
    for _ in 0..120 {
        app.update();
    }
    let margin = f64::from(app.world().resource::<HairSettings>().collision_margin);
    let thickness = 40e-6 + margin;
    let rod = strand_rod_heights(&app, strand);
    let (lowest, highest) = rod.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), y| (l.min(*y), h.max(*y)));
    println!("a strand lying on a floor at 0.1 m: heights from {lowest} to {highest} m (thickness {thickness} m)");
    assert!((lowest - (0.1 + thickness)).abs() < 2e-6, "lowest node at {lowest} m");
    assert!(highest - lowest < 2e-6, "the strand lies flat: {highest} − {lowest}");
    assert_eq!(app.world().resource::<HairStatistics>().contacts, 17, "every node touches the floor");
}

/// Heights of a strand's nodes, m.
fn strand_rod_heights(app: &App, entity: Entity) -> Vec<f64> {
    strand(app, entity).rod().positions().iter().map(|position| position.y).collect()
}

#[test]
fn an_invalid_collider_is_reported_and_left_out_while_the_hair_goes_on() {
    let mut app = hair_app();
    let bad = app.world_mut().spawn(HairCollider::sphere(-0.1)).id();
    let slippery = app.world_mut().spawn(HairCollider::plane().with_friction(f32::NAN)).id();
    let strand = app.world_mut().spawn(HairStrand::straight(Vec3::ZERO, Vec3::X, 0.2, 16)).id();
    for _ in 0..10 {
        app.update();
    }
    for (entity, parameter) in [(bad, "radius"), (slippery, "friction")] {
        let motion = app.world().get::<ColliderMotion>(entity).unwrap();
        let reason = motion.rejected.as_deref().unwrap_or_default();
        assert!(reason.contains(parameter), "collider {entity}: {reason:?}");
        assert!(motion.collider.is_none());
    }
    let statistics = app.world().resource::<HairStatistics>();
    assert_eq!((statistics.faults, statistics.contacts), (0, 0));
    assert!(strand_rod_heights(&app, strand)[16] < -0.05, "the free strand fell past both");
}

#[test]
fn hair_dropped_on_boxes_sharp_and_rounded_lies_on_them_and_never_inside() {
    let mut app = hair_app_with(TransformPlugin);
    // A sharp box tilted both ways, and a rounded one turned and tilted: colliders with no head, which
    // every free strand meets.
    let tilted = Quat::from_rotation_z(0.3) * Quat::from_rotation_x(0.2);
    let sharp = app
        .world_mut()
        .spawn((
            HairCollider::cuboid(Vec3::new(0.1, 0.05, 0.08)),
            Transform::from_xyz(0.0, 1.0, 0.0).with_rotation(tilted),
        ))
        .id();
    let turned = Quat::from_rotation_y(0.5) * Quat::from_rotation_z(-0.4);
    let rounded = app
        .world_mut()
        .spawn((
            HairCollider::rounded_cuboid(Vec3::new(0.06, 0.04, 0.06), 0.02),
            Transform::from_xyz(0.5, 1.0, 0.0).with_rotation(turned),
        ))
        .id();
    // Twelve free 20 cm strands over each box, 12 to 17 cm above its centre, across it.
    let strands: Vec<Entity> = [0.0_f32, 0.5]
        .into_iter()
        .flat_map(|x| (0..12).map(move |k| (x, k)))
        .map(|(x, k)| {
            let root = Vec3::new(x - 0.1, 1.12 + 0.004 * k as f32, -0.066 + 0.012 * k as f32);
            let direction = Vec3::new(1.0, 0.0, 0.15 * (k as f32 - 5.5) / 5.5);
            app.world_mut().spawn(HairStrand::straight(root, direction, 0.2, 16)).id()
        })
        .collect();
    let mut deepest = [0.0_f64; 2];
    for step in 1..=150 {
        app.update();
        for (worst, collider) in deepest.iter_mut().zip([sharp, rounded]) {
            let depth = deepest_node(&app, &strands, collider);
            assert!(depth <= TOLERANCE, "step {step}: a node is {depth:e} m inside box {collider}");
            *worst = worst.max(depth);
        }
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0, "step {step}: a strand failed");
    }
    let contacts = app.world().resource::<HairStatistics>().contacts;
    // Lying on the boxes: the strands that stayed on are still, and the top of each box is under hair.
    let resting =
        strands.iter().filter(|&&e| strand(&app, e).rod().velocities().iter().all(|v| v.length() < 0.01)).count();
    println!(
        "24 strands dropped on two boxes: deepest node inside the sharp box {:e} m, the rounded one {:e} m; {contacts} nodes in contact, {resting} strands at rest",
        deepest[0], deepest[1]
    );
    assert!(contacts >= 48, "the hair lies on the boxes: {contacts} nodes in contact");
}
