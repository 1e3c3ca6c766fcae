//! The game's avian3d colliders as hair colliders (`avian` feature; `cargo test --features avian --test
//! avian_colliders`): each shape hair can meet becomes hair colliders that hold exactly the points avian's
//! holds, they follow their entity, change with it and go with it, and hair dropped on them stays out.
#![cfg(feature = "avian")]

use avian3d::parry::math::Pose;
use avian3d::prelude::{Collider, Friction};
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::collision::{AvianHairColliderPart, ColliderMotion};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::ColliderShape;
use hair_sim_support::headless::{hair_app_with, strand};

/// The hair colliders made for `entity`.
fn parts(app: &mut App, entity: Entity) -> Vec<Entity> {
    let mut query = app.world_mut().query_filtered::<(Entity, &ChildOf), With<AvianHairColliderPart>>();
    query.iter(app.world()).filter(|(_, child_of)| child_of.parent() == entity).map(|(part, _)| part).collect()
}

/// Whether `point` (world) is inside any of the hair colliders `parts`, as the plugin tracked them this
/// step.
fn inside_hair(app: &App, parts: &[Entity], point: Vec3) -> bool {
    parts.iter().any(|&part| {
        let collider = app.world().get::<ColliderMotion>(part).unwrap().collider.clone().expect("the part is used");
        collider.shape.contains(collider.end.to_local(point.as_dvec3()))
    })
}

/// Whether `point` (world) is inside avian's `collider` on an entity at `transform`.
fn inside_avian(collider: &Collider, transform: &GlobalTransform, point: Vec3) -> bool {
    let (scale, rotation, translation) = transform.to_scale_rotation_translation();
    // The scale as set (rounding off the last bits, which avian would take for a scale to approximate).
    let scale = (scale * 1e4).round() / 1e4;
    let mut scaled = collider.clone();
    scaled.set_scale(scale, 8);
    scaled.shape_scaled().contains_point(&Pose::from_parts(translation, rotation), point)
}

#[test]
fn avian_shapes_become_hair_colliders_holding_the_same_points() {
    let mut app = hair_app_with(TransformPlugin);
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let turned = Quat::from_rotation_z(0.7) * Quat::from_rotation_x(-0.4);
    let colliders = [
        ("ball", Collider::sphere(0.1)),
        ("capsule", Collider::capsule(0.05, 0.2)),
        (
            "capsule between two points",
            Collider::capsule_endpoints(0.04, Vec3::new(-0.1, 0.0, 0.05), Vec3::new(0.1, 0.08, -0.02)),
        ),
        ("cuboid", Collider::cuboid(0.2, 0.1, 0.16)),
        ("rounded cuboid", Collider::round_cuboid(0.12, 0.08, 0.1, 0.03)),
        (
            "compound",
            Collider::compound(vec![
                (Vec3::new(0.1, 0.0, 0.0), Quat::from_rotation_y(0.3), Collider::cuboid(0.1, 0.05, 0.08)),
                (Vec3::new(-0.08, 0.05, 0.0), Quat::IDENTITY, Collider::sphere(0.06)),
                (Vec3::ZERO, Quat::from_rotation_x(1.0), Collider::capsule(0.03, 0.15)),
            ]),
        ),
    ];
    let spawned: Vec<(&str, Entity, usize)> = colliders
        .into_iter()
        .enumerate()
        .map(|(index, (label, collider))| {
            let expected = if label == "compound" { 3 } else { 1 };
            // Turned, moved, and the compound scaled with its entity's parent (evenly: under an uneven scale a
            // ball becomes an ellipsoid here and a polyhedron in avian; and under any scale avian keeps a
            // rounded cuboid's border radius, where the hair collider scales it with the box).
            let transform = Transform::from_xyz(0.8 * index as f32, 1.0, 0.3).with_rotation(turned);
            let parent = app
                .world_mut()
                .spawn(Transform::from_scale(Vec3::splat(if label == "compound" { 1.5 } else { 1.0 })))
                .id();
            let entity =
                app.world_mut().spawn((collider, AvianHairCollider::of(head), transform, ChildOf(parent))).id();
            (label, entity, expected)
        })
        .collect();
    app.update();
    for (label, entity, expected) in spawned {
        let parts = parts(&mut app, entity);
        assert_eq!(parts.len(), expected, "{label}");
        for &part in &parts {
            assert_eq!(app.world().get::<HairColliderOf>(part), Some(&HairColliderOf(head)), "{label}");
        }
        let collider = app.world().get::<Collider>(entity).unwrap().clone();
        let transform = *app.world().get::<GlobalTransform>(entity).unwrap();
        // Points through the collider's bounds: avian and the hair colliders agree on each, but for points
        // within 0.1 mm of the surface (where f32 and the approximations of scaled shapes may differ).
        let (mut inside, mut checked) = (0, 0);
        for i in 0..4000 {
            let t = i as f32;
            let unit = Vec3::new((t * 0.618_034).fract(), (t * 0.754_878).fract(), (t * 0.569_84).fract());
            let point = transform.translation() + (unit - Vec3::splat(0.5)) * 0.45;
            let near_surface = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::NEG_X, Vec3::NEG_Y, Vec3::NEG_Z].iter().any(|&d| {
                inside_avian(&collider, &transform, point + 1e-4 * d) != inside_avian(&collider, &transform, point)
            });
            if near_surface {
                continue;
            }
            let avian = inside_avian(&collider, &transform, point);
            assert_eq!(inside_hair(&app, &parts, point), avian, "{label}: {point} inside avian's collider: {avian}");
            inside += usize::from(avian);
            checked += 1;
        }
        println!("{label}: {checked} points agree, {inside} of them inside");
        assert!(inside > 50, "{label}: only {inside} points inside");
    }
}

#[test]
fn a_half_space_becomes_a_floor_and_parts_follow_changes_and_removal() {
    let mut app = hair_app_with(TransformPlugin);
    // A floor tilted 0.2 rad, met by every strand (no head), with avian's friction.
    let tilt = Quat::from_rotation_z(0.2);
    let floor = app
        .world_mut()
        .spawn((
            Collider::half_space(Vec3::Y),
            Friction::new(0.7),
            AvianHairCollider::default(),
            Transform::from_rotation(tilt),
        ))
        .id();
    app.update();
    let [part] = parts(&mut app, floor)[..] else { panic!("one part") };
    assert!(app.world().get::<HairColliderOf>(part).is_none());
    let motion = app.world().get::<ColliderMotion>(part).unwrap().collider.clone().unwrap();
    assert_eq!(motion.shape, ColliderShape::Plane);
    assert!((motion.friction - 0.7).abs() < 1e-6);
    // The plane's normal is the half-space's, turned with its entity.
    let normal = motion.end.rotation * bevy::math::DVec3::Y;
    assert!(normal.distance(tilt.as_dquat() * bevy::math::DVec3::Y) < 1e-6, "{normal}");
    assert!(motion.end.translation.length() < 1e-9);

    // A changed collider is made again; a shape hair cannot meet is left out.
    *app.world_mut().get_mut::<Collider>(floor).unwrap() = Collider::compound(vec![
        (Vec3::ZERO, Quat::IDENTITY, Collider::sphere(0.2)),
        (Vec3::X, Quat::IDENTITY, Collider::cylinder(0.1, 0.3)),
    ]);
    app.update();
    let remade = parts(&mut app, floor);
    assert_eq!(remade.len(), 1, "the ball only");
    assert!(app.world().get_entity(part).is_err(), "the old part is gone");
    assert_eq!(app.world().get::<HairCollider>(remade[0]).unwrap().shape, ColliderShape::sphere(f64::from(0.2_f32)));

    // No longer a hair collider: its parts go.
    app.world_mut().entity_mut(floor).remove::<AvianHairCollider>();
    app.update();
    assert!(parts(&mut app, floor).is_empty());
    assert!(app.world().get_entity(remade[0]).is_err());
}

#[test]
fn hair_dropped_on_avian_colliders_lies_on_them() {
    let mut app = hair_app_with(TransformPlugin);
    let shoulder = app
        .world_mut()
        .spawn((
            // A slab 30 cm square with a ball at one end: hair lands on the slab and drapes over the ball.
            Collider::compound(vec![
                (Vec3::ZERO, Quat::IDENTITY, Collider::round_cuboid(0.3, 0.06, 0.3, 0.02)),
                (Vec3::new(0.1, 0.08, 0.0), Quat::IDENTITY, Collider::sphere(0.04)),
            ]),
            AvianHairCollider::default(),
            Transform::from_xyz(0.0, 1.0, 0.0).with_rotation(Quat::from_rotation_z(0.15)),
        ))
        .id();
    let strands: Vec<Entity> = (0..10)
        .map(|k| {
            let root = Vec3::new(-0.12, 1.2, -0.1 + 0.022 * k as f32);
            app.world_mut().spawn(HairStrand::straight(root, Vec3::X, 0.2, 16)).id()
        })
        .collect();
    for _ in 0..150 {
        app.update();
    }
    let parts = parts(&mut app, shoulder);
    let margin = app.world().resource::<HairSettings>().collision_margin;
    let mut deepest = 0.0_f64;
    for &entity in &strands {
        let strand = strand(&app, entity);
        let thickness = f64::from(strand.collision_thickness(margin));
        for position in strand.rod().positions() {
            for &part in &parts {
                let collider = app.world().get::<ColliderMotion>(part).unwrap().collider.clone().unwrap();
                let grown = collider.shape.inflated(thickness);
                let local = collider.end.to_local(*position);
                if grown.contains(local) {
                    deepest = deepest.max(local.distance(grown.closest_surface_point(local).point));
                }
            }
        }
    }
    let contacts = app.world().resource::<HairStatistics>().contacts;
    println!("10 strands on an avian compound: deepest node inside {deepest:e} m, {contacts} nodes in contact");
    assert!(deepest <= 1e-4, "a node is {deepest} m inside");
    assert!(contacts >= 20, "the hair lies on the collider: {contacts} nodes in contact");
}

/// Every name of this crate's prelude, used beside avian's real prelude (both glob-imported): a name in
/// both would be ambiguous here and fail to compile. (`tests/plugin/names_beside_avian.rs` checks stand-ins of
/// avian's and bevy_rapier's names without the feature.)
mod beside_avians_prelude {
    use avian3d::prelude::*;
    use bevy_hair_sim::prelude::*;
    use std::any::type_name;

    #[test]
    fn every_name_of_ours_can_be_used_beside_avians_prelude() {
        let ours = [
            type_name::<HairPlugins>(),
            type_name::<AvianHairCollider>(),
            type_name::<HairCollider>(),
            type_name::<HairColliderOf>(),
            type_name::<HairCollisionFilter>(),
            type_name::<HairCollisionPlugin>(),
            type_name::<HeadColliders>(),
            type_name::<SharedHairCollider>(),
            type_name::<HairGizmoPlugin>(),
            type_name::<HairGizmos>(),
            type_name::<HairCpuBudget>(),
            type_name::<HairDetail>(),
            type_name::<HairDetailLevel>(),
            type_name::<HairDetailPlugin>(),
            type_name::<HairDetailSettings>(),
            type_name::<FollowerNodes>(),
            type_name::<FollowerPlacement>(),
            type_name::<HairFollowers>(),
            type_name::<HairFollowersPlugin>(),
            type_name::<PlaceFollowersOnCpu>(),
            type_name::<Combing>(),
            type_name::<GroomFile>(),
            type_name::<GroomPlacement>(),
            type_name::<HairGroom>(),
            type_name::<HairGroomFile>(),
            type_name::<HairGroomPlugin>(),
            type_name::<HairStyle>(),
            type_name::<Scalp>(),
            type_name::<UpAxis>(),
            type_name::<HairAppearance>(),
            type_name::<HairRenderPlugin>(),
            type_name::<RodMaterial>(),
            type_name::<HairDrawSystems>(),
            type_name::<HairPinSystems>(),
            type_name::<HairPrepareSystems>(),
            type_name::<HairStepSystems>(),
            type_name::<HairSystems>(),
            type_name::<HairHead>(),
            type_name::<HairPause>(),
            type_name::<HairSettings>(),
            type_name::<HairSimulationPlugin>(),
            type_name::<HairStatistics>(),
            type_name::<HairStrand>(),
            type_name::<HeadStrands>(),
            type_name::<StrandFault>(),
            type_name::<StrandForces>(),
            type_name::<StrandFrames>(),
            type_name::<StrandNodes>(),
            type_name::<StrandOf>(),
            type_name::<StrandRejected>(),
            type_name::<StrandRestShape>(),
            type_name::<StrandSnapshot>(),
            type_name::<StrandSnapshotData>(),
            type_name::<HairVolume>(),
            type_name::<HairVolumePlugin>(),
            type_name::<HairWind>(),
            type_name::<HairWindPlugin>(),
            type_name::<HairWindSource>(),
        ];
        assert!(ours.iter().all(|name| name.starts_with("bevy_hair_sim::")), "{ours:?}");
        // And avian's most used names, from the same glob imports.
        let theirs = [
            type_name::<Collider>(),
            type_name::<ColliderOf>(),
            type_name::<RigidBody>(),
            type_name::<Position>(),
            type_name::<Rotation>(),
            type_name::<Friction>(),
            type_name::<LinearVelocity>(),
            type_name::<Gravity>(),
            type_name::<Sensor>(),
        ];
        assert!(theirs.iter().all(|name| name.starts_with("avian3d::")), "{theirs:?}");
    }
}
