//! Colliders baked from meshes: hair dropped on a baked ball, a baked box and a baked head with ears
//! (not convex) at the default resolution never sits more than 1 mm inside the *mesh* (measured against
//! the true shape, not the baked field); a `HairColliderFromMesh` bakes its entity's mesh once it has
//! loaded; bad meshes are refused with their reason.

use bevy::asset::{AssetPlugin, RenderAssetUsages};
use bevy::math::DVec3;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::collision::{MeshColliderBaking, MeshColliderError};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::closest_point_on_triangle;
use hair_sim_support::headless::{hair_app_with, strand};

/// The deepest a node may sit inside the mesh, m: 1 mm.
const DEEPEST: f64 = 1e-3;

/// A head with ears: a 9 × 11 × 10 cm ellipsoid with a 3 cm bump on either side (not convex), as a
/// closed UV-sphere mesh of `rings` rings, star-shaped around its origin.
fn head_with_ears(rings: u32) -> Mesh {
    let radius = |d: Vec3| {
        let skull = 1.0 / (d / Vec3::new(0.09, 0.11, 0.1)).length();
        skull
            + 0.03 * (-(d - Vec3::X).length_squared() / 0.02).exp()
            + 0.03 * (-(d + Vec3::X).length_squared() / 0.02).exp()
    };
    let (positions, triangles) = hair_sim_support::star_shaped(|d| f64::from(radius(d.as_vec3())), rings);
    let positions: Vec<Vec3> = positions.iter().map(|p| p.as_vec3()).collect();
    let indices: Vec<u32> = triangles.into_iter().flatten().collect();
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_indices(Indices::U32(indices))
}

/// A mesh's triangles as corner positions, m.
fn triangles(mesh: &Mesh) -> Vec<[DVec3; 3]> {
    let positions = mesh.attribute(Mesh::ATTRIBUTE_POSITION).unwrap().as_float3().unwrap();
    let indices: Vec<usize> = mesh.indices().unwrap().iter().collect();
    indices.chunks(3).map(|t| [0, 1, 2].map(|k| Vec3::from(positions[t[k]]).as_dvec3())).collect()
}

/// How deep the local point `point` is inside the closed mesh `triangles` that is star-shaped around
/// its origin (0 outside): inside when the ray from the origin through it meets the surface beyond it;
/// then the distance to the nearest triangle.
fn depth_in_star_shaped(triangles: &[[DVec3; 3]], point: DVec3) -> f64 {
    let direction = point.normalize();
    let hit = triangles.iter().find_map(|&[a, b, c]| {
        // Möller–Trumbore, from the origin.
        let (ab, ac) = (b - a, c - a);
        let p = direction.cross(ac);
        let det = ab.dot(p);
        if det.abs() < 1e-15 {
            return None;
        }
        let s = -a;
        let u = s.dot(p) / det;
        let q = s.cross(ab);
        let v = direction.dot(q) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then(|| ac.dot(q) / det).filter(|&t| t > 0.0)
    });
    match hit {
        Some(surface) if point.length() < surface => triangles
            .iter()
            .map(|&[a, b, c]| point.distance(closest_point_on_triangle(point, a, b, c)))
            .fold(f64::INFINITY, f64::min),
        _ => 0.0,
    }
}

/// Drops sixteen free 20 cm strands across the collider (its centre at 1 m), for 2 s, and returns the
/// deepest any node sat inside the true shape (`depth`, in the collider's frame) and the nodes in contact
/// at the end.
fn drop_hair(collider: HairCollider, rotation: Quat, top: f32, depth: impl Fn(DVec3) -> f64) -> (f64, usize) {
    let mut app = hair_app_with(TransformPlugin);
    let centre = Vec3::new(0.0, 1.0, 0.0);
    app.world_mut().spawn((collider, Transform::from_translation(centre).with_rotation(rotation)));
    let strands: Vec<Entity> = (0..16)
        .map(|k| {
            let root = Vec3::new(-0.1, 1.0 + top + 0.01 + 0.003 * k as f32, -0.06 + 0.008 * k as f32);
            let direction = Vec3::new(1.0, 0.0, 0.2 * (k as f32 - 7.5) / 7.5);
            app.world_mut().spawn(HairStrand::straight(root, direction, 0.2, 16)).id()
        })
        .collect();
    let to_local = |world: DVec3| rotation.inverse().as_dquat() * (world - centre.as_dvec3());
    let mut deepest: f64 = 0.0;
    for step in 1..=120 {
        app.update();
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0, "step {step}: a strand failed");
        if step % 4 == 0 {
            for &entity in &strands {
                for &node in strand(&app, entity).rod().positions() {
                    deepest = deepest.max(depth(to_local(node)));
                }
            }
        }
    }
    (deepest, app.world().resource::<HairStatistics>().contacts)
}

#[test]
fn hair_dropped_on_baked_meshes_never_sits_a_millimetre_inside_them() {
    let settings = MeshColliderSettings::default();
    // A ball: an icosphere of 8 820 triangles, about 0.05 mm inside the true sphere between its corners.
    let ball = HairCollider::from_mesh(&Sphere::new(0.1).mesh().ico(20).unwrap(), settings).unwrap();
    let (ball_depth, ball_contacts) = drop_hair(ball, Quat::IDENTITY, 0.1, |p| (0.1 - p.length()).max(0.0));
    // A box, tilted both ways.
    let half = DVec3::new(0.1, 0.05, 0.08);
    let cuboid = HairCollider::from_mesh(&Cuboid::from_size(2.0 * half.as_vec3()).mesh().build(), settings).unwrap();
    let tilt = Quat::from_rotation_z(0.3) * Quat::from_rotation_x(0.2);
    let (box_depth, box_contacts) = drop_hair(cuboid, tilt, 0.12, |p| {
        let q = p.abs() - half;
        (-q.max_element()).max(0.0)
    });
    // A head with ears.
    let mesh = head_with_ears(40);
    let head = HairCollider::from_mesh(&mesh, settings).unwrap();
    let corners = triangles(&mesh);
    // The measure sees inside: about 9 cm deep at the centre, a few millimetres inside an ear's tip
    // (12 cm out; 1 cm in along the axis, less sideways), 0 just outside.
    let centre_depth = depth_in_star_shaped(&corners, DVec3::new(1e-4, 1e-4, 1e-4));
    assert!((centre_depth - 0.09).abs() < 3e-3, "{centre_depth}");
    let ear_depth = depth_in_star_shaped(&corners, DVec3::new(0.11, 0.0, 0.0));
    assert!(ear_depth > 3e-3 && ear_depth <= 0.0101, "{ear_depth}");
    assert_eq!(depth_in_star_shaped(&corners, DVec3::new(0.0, 0.115, 0.0)), 0.0);
    let (head_depth, head_contacts) =
        drop_hair(
            head,
            Quat::IDENTITY,
            0.11,
            |p| if p.length() > 0.15 { 0.0 } else { depth_in_star_shaped(&corners, p) },
        );
    println!(
        "deepest inside, m: ball {ball_depth:e} ({ball_contacts} contacts), box {box_depth:e} ({box_contacts}), head with ears {head_depth:e} ({head_contacts})"
    );
    for (name, depth, contacts) in
        [("ball", ball_depth, ball_contacts), ("box", box_depth, box_contacts), ("head", head_depth, head_contacts)]
    {
        assert!(depth < DEEPEST, "{name}: a node sat {depth:e} m inside");
        assert!(contacts >= 16, "{name}: the hair lies on it ({contacts} nodes in contact)");
    }
}

/// An app with mesh assets, to load meshes into.
fn app_with_meshes() -> App {
    let mut app = hair_app_with((TransformPlugin, AssetPlugin::default()));
    app.init_asset::<Mesh>();
    app
}

#[test]
fn a_mesh_collider_is_baked_once_its_mesh_is_there_and_a_bad_one_is_reported() {
    let mut app = app_with_meshes();
    let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
    let good = meshes.add(Sphere::new(0.1).mesh().ico(3).unwrap());
    let lines = meshes.add(Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default()));
    let friction = 0.7;
    let from_mesh = HairColliderFromMesh { friction, ..default() };
    let baked = app.world_mut().spawn((Mesh3d(good), from_mesh, Transform::from_xyz(0.0, 1.0, 0.0))).id();
    let refused = app.world_mut().spawn((Mesh3d(lines), from_mesh)).id();
    for _ in 0..500 {
        app.update();
        if app.world().get::<HairCollider>(baked).is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let collider = app.world().get::<HairCollider>(baked).expect("baked within 500 frames");
    assert_eq!(collider.friction, friction);
    assert!(
        collider.shape.contains(DVec3::new(0.0, 0.09, 0.0)) && !collider.shape.contains(DVec3::new(0.0, 0.11, 0.0))
    );
    assert!(matches!(app.world().get::<MeshColliderBaking>(baked), Some(MeshColliderBaking::Baked)));
    for _ in 0..200 {
        if matches!(app.world().get::<MeshColliderBaking>(refused), Some(MeshColliderBaking::Failed(_))) {
            break;
        }
        app.update();
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    match app.world().get::<MeshColliderBaking>(refused) {
        Some(MeshColliderBaking::Failed(MeshColliderError::NotTriangles(PrimitiveTopology::LineList))) => {}
        other => panic!("a line list is refused as not triangles, got {other:?}"),
    }
    assert!(app.world().get::<HairCollider>(refused).is_none());
    // The baked collider is used by the plugin from the next fixed step: tracked with the entity's pose.
    app.update();
    let motion = app.world().get::<bevy_hair_sim::collision::ColliderMotion>(baked).unwrap();
    let moving = motion.collider.as_ref().expect("the baked collider is in use");
    assert!((moving.end.translation - DVec3::new(0.0, 1.0, 0.0)).length() < 1e-12);
}

#[test]
fn meshes_that_cannot_be_baked_say_why() {
    let settings = MeshColliderSettings::default();
    let empty = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default());
    assert_eq!(HairCollider::from_mesh(&empty, settings), Err(MeshColliderError::NoPositions));
    let flat = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![Vec3::ZERO; 3]);
    assert_eq!(HairCollider::from_mesh(&flat, settings), Err(MeshColliderError::NoExtent));
    let partial = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z])
        .with_inserted_indices(Indices::U32(vec![0, 1, 2, 3]));
    assert_eq!(HairCollider::from_mesh(&partial, settings), Err(MeshColliderError::PartialTriangle(4)));
    let out_of_range = partial.clone().with_inserted_indices(Indices::U32(vec![0, 1, 7]));
    assert!(matches!(
        HairCollider::from_mesh(&out_of_range, settings),
        Err(MeshColliderError::Field(bevy_hair_sim::rod::DistanceFieldError::IndexOutOfRange { vertex: 7, .. }))
    ));
    let not_finite = partial.with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![Vec3::ZERO, Vec3::X, Vec3::NAN]);
    let not_finite = not_finite.with_inserted_indices(Indices::U32(vec![0, 1, 2]));
    assert!(matches!(
        HairCollider::from_mesh(&not_finite, settings),
        Err(MeshColliderError::Field(bevy_hair_sim::rod::DistanceFieldError::NonFiniteVertex { vertex: 2, .. }))
    ));
    let coarse = MeshColliderSettings { resolution: 3, ..settings };
    assert_eq!(
        HairCollider::from_mesh(&Sphere::new(0.1).mesh().ico(2).unwrap(), coarse),
        Err(MeshColliderError::ResolutionTooLow(3))
    );
}

#[test]
fn a_preloaded_strand_waits_for_its_heads_mesh_collider_and_then_rests_on_it() {
    let mut app = app_with_meshes();
    // A ball head whose collider is baked from a mesh that is not there yet.
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().reserve_handle();
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.0, 0.0))).id();
    app.world_mut().spawn((Mesh3d(mesh.clone()), HairColliderFromMesh::default(), HairColliderOf(head), ChildOf(head)));
    // A strand combed over the ball's top, 1.5 mm above it (within its contact thickness and the preload's
    // support distance), then hanging down its side.
    let radius = 0.1015;
    let nodes: Vec<Vec3> = (0..=24)
        .map(|node| {
            let angle = 0.1 + 1.6 * node as f32 / 24.0;
            Vec3::new(radius * angle.sin(), radius * angle.cos(), 0.0)
        })
        .collect();
    let hair = app
        .world_mut()
        .spawn((HairStrand::from_nodes(nodes.clone(), Vec3::Z).with_gravity_preload(1.0), StrandOf(head)))
        .id();
    for _ in 0..20 {
        app.update();
    }
    // Waiting: not preloaded, not stepped.
    let waiting = strand(&app, hair);
    assert!(waiting.preload_report().is_none(), "preloaded before its collider was there");
    let world = |node: Vec3| (node + Vec3::Y).as_dvec3();
    let moved = waiting.rod().positions().iter().zip(&nodes).map(|(p, n)| p.distance(world(*n))).fold(0.0, f64::max);
    // As placed, to single precision (a step would have sagged it by millimetres).
    assert!(moved < 1e-6, "stepped while waiting: moved {moved} m");
    // The mesh arrives and is baked: the preload rests the strand on it.
    app.world_mut().resource_mut::<Assets<Mesh>>().insert(mesh.id(), Sphere::new(0.1).mesh().ico(5).unwrap()).unwrap();
    for _ in 0..500 {
        app.update();
        if strand(&app, hair).preload_report().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let report = *strand(&app, hair).preload_report().expect("preloaded once baked");
    assert!(report.supported_nodes >= 10, "{report:?}");
}
