//! Roots bound to a scalp mesh: on a skinned scalp whose neck bends and sways and whose head turns and
//! nods, every root stays within 1e-5 m of its triangle's skinned point on every step, moves with that
//! point's velocity (within 1 %), and its root edge keeps its angle to the triangle; a rigid scalp mesh
//! binds once it has loaded; a skinned mesh without weights is refused and its roots follow the head.

use bevy::asset::AssetPlugin;
use bevy::math::{DMat4, DVec3};
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::scalp::ScalpRootBinding;
use hair_sim_support::headless::{DT, hair_app_with, strand};
use hair_sim_support::logs;
use hair_sim_support::sphere_cap;

/// How far a velocity differenced from single-precision transforms can be off, m/s: positions near
/// 1.7 m are known to an ulp (1.2e-7 m), and BDF2's difference weighs three of them by 3 + 4 + 1 over 2dt.
const F32_VELOCITY_NOISE: f64 = 4.0 * 1.2e-7 / DT;

/// The scalp's radius, m, and where its centre is above the head joint.
const RADIUS: f32 = 0.1;
/// Where the neck joint stands, m (world, at the bind pose), and the head joint above it.
const NECK: Vec3 = Vec3::new(0.0, 1.5, 0.0);
const HEAD_ABOVE_NECK: Vec3 = Vec3::new(0.0, 0.12, 0.0);

/// A scalp cap (the top 100° of a sphere about the head joint, 8 rings × 16 segments) in bind space
/// (the world at the bind pose), skinned to joint 0 (the neck) and 1 (the head): the head's weight falls
/// from 1 at the crown to 0.3 at the rim, so the scalp stretches as the neck bends under a turned head.
fn scalp_mesh(skinned: bool) -> Mesh {
    let (rings, segments) = (8u32, 16u32);
    let mesh = sphere_cap(NECK + HEAD_ABOVE_NECK, RADIUS, rings, segments);
    let count = mesh.count_vertices() as u32;
    let weights: Vec<[f32; 4]> = (0..count)
        .map(|vertex| {
            let head = 1.0 - 0.7 * (vertex / segments) as f32 / rings as f32;
            [1.0 - head, head, 0.0, 0.0]
        })
        .collect();
    if !skinned {
        return mesh;
    }
    mesh.with_inserted_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(vec![[0, 1, 0, 0]; count as usize]),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights)
}

/// The neck's and head's local transforms at time `time`, s: the neck sways 20 cm sideways and bends
/// ±0.4 rad, the head turns ±0.8 rad and nods ±0.3 rad.
fn joint_poses(time: f32) -> (Transform, Transform) {
    let wave = |frequency: f32| (std::f32::consts::TAU * frequency * time).sin();
    let neck = Transform::from_translation(NECK + Vec3::new(0.2 * wave(0.3), 0.0, 0.0))
        .with_rotation(Quat::from_rotation_z(0.4 * wave(0.7)));
    let head = Transform::from_translation(HEAD_ABOVE_NECK)
        .with_rotation(Quat::from_rotation_y(0.8 * wave(0.5)) * Quat::from_rotation_x(0.3 * wave(1.1)));
    (neck, head)
}

/// An app with mesh and skin assets.
fn app_with_assets() -> App {
    let mut app = hair_app_with((TransformPlugin, AssetPlugin::default()));
    app.init_asset::<Mesh>().init_asset::<SkinnedMeshInverseBindposes>();
    app
}

/// The skinned character: neck and head joints, the scalp mesh skinned to them, `strands` 15 cm strands
/// rooted on triangle centres (every `stride`-th triangle with an area) along their normals, in the head joint's
/// space. Returns the neck, the head joint and the strands.
fn spawn_character(app: &mut App, skinned_mesh: Mesh, stride: usize) -> (Entity, Entity, Vec<Entity>) {
    let (neck_pose, head_pose) = joint_poses(0.0);
    let world = app.world_mut();
    let neck = world.spawn(neck_pose).id();
    let head = world.spawn((head_pose, ChildOf(neck), HairHead)).id();
    let bind_neck = neck_pose.to_matrix();
    let bind_head = bind_neck * head_pose.to_matrix();
    let inverse_bindposes =
        world.resource_mut::<Assets<SkinnedMeshInverseBindposes>>().add(vec![bind_neck.inverse(), bind_head.inverse()]);
    let corners = triangles(&skinned_mesh);
    let mesh = world.resource_mut::<Assets<Mesh>>().add(skinned_mesh);
    let scalp = world
        .spawn((Mesh3d(mesh), Transform::default(), SkinnedMesh { inverse_bindposes, joints: vec![neck, head] }))
        .id();
    world.entity_mut(head).insert(HairScalpMesh(scalp));
    let to_head = bind_head.inverse();
    let strands = corners
        .iter()
        .filter(|&&[a, b, c]| (b - a).cross(c - a).length() > 1e-9) // The crown's fans have a corner twice.
        .step_by(stride)
        .map(|&[a, b, c]| {
            let root = to_head.transform_point3((a + b + c) / 3.0);
            let normal = to_head.transform_vector3((b - a).cross(c - a)).normalize();
            world.spawn((HairStrand::straight(root, normal, 0.15, 12), StrandOf(head))).id()
        })
        .collect();
    (neck, head, strands)
}

/// A mesh's triangles as corner positions.
fn triangles(mesh: &Mesh) -> Vec<[Vec3; 3]> {
    let positions = mesh.attribute(Mesh::ATTRIBUTE_POSITION).unwrap().as_float3().unwrap();
    let indices: Vec<usize> = mesh.indices().unwrap().iter().collect();
    indices.chunks(3).map(|t| [0, 1, 2].map(|k| Vec3::from(positions[t[k]]))).collect()
}

/// Where the bound triangle's corners are, skinned by hand (linear blend of `joint global × inverse bind
/// pose`, as Bevy's shader does) from the joints' world matrices, in double precision.
fn skinned_corners(binding: &ScalpRootBinding, skin: &[DMat4]) -> [DVec3; 3] {
    binding.corners.map(|corner| {
        (0..4)
            .map(|k| {
                f64::from(corner.weights[k])
                    * skin[usize::from(corner.joints[k])].transform_point3(corner.position.as_dvec3())
            })
            .sum()
    })
}

/// Where the bound root's skinned point is at time `time`, s (world, m).
fn skinned_point(binding: &ScalpRootBinding, time: f64) -> DVec3 {
    let (bind_neck, bind_head) = joint_poses(0.0);
    let bind_neck = bind_neck.to_matrix().as_dmat4();
    let bind_head = bind_neck * bind_head.to_matrix().as_dmat4();
    let (neck, head) = joint_poses_f64(time);
    let head = neck * head;
    let [a, b, c] = skinned_corners(binding, &[neck * bind_neck.inverse(), head * bind_head.inverse()]);
    let weights = binding.barycentric;
    weights.x * a + weights.y * b + weights.z * c
}

/// [`joint_poses`] as double-precision matrices.
fn joint_poses_f64(time: f64) -> (DMat4, DMat4) {
    let wave = |frequency: f64| (std::f64::consts::TAU * frequency * time).sin();
    let neck = DMat4::from_rotation_translation(
        bevy::math::DQuat::from_rotation_z(0.4 * wave(0.7)),
        NECK.as_dvec3() + DVec3::new(0.2 * wave(0.3), 0.0, 0.0),
    );
    let head = DMat4::from_rotation_translation(
        bevy::math::DQuat::from_rotation_y(0.8 * wave(0.5)) * bevy::math::DQuat::from_rotation_x(0.3 * wave(1.1)),
        HEAD_ABOVE_NECK.as_dvec3(),
    );
    (neck, head)
}

#[test]
fn roots_on_a_skinned_scalp_stay_on_their_triangles_and_move_with_them() {
    let mut app = app_with_assets();
    let (neck, head, strands) = spawn_character(&mut app, scalp_mesh(true), 3);
    let bind_neck = joint_poses(0.0).0.to_matrix().as_dmat4();
    let bind_head = bind_neck * joint_poses(0.0).1.to_matrix().as_dmat4();
    let mut previous: Vec<Option<DVec3>> = vec![None; strands.len()];
    let mut angles: Vec<Option<f64>> = vec![None; strands.len()];
    let mut earlier: Vec<Option<DVec3>> = vec![None; strands.len()];
    let mut off_the_head: f64 = 0.0;
    let (mut worst_distance, mut worst_velocity, mut worst_exact, mut fastest): (f64, f64, f64, f64) =
        (0.0, 0.0, 0.0, 0.0);
    for step in 1..=240 {
        let time = step as f64 * DT;
        let (neck_pose, head_pose) = joint_poses(time as f32);
        *app.world_mut().get_mut::<Transform>(neck).unwrap() = neck_pose;
        *app.world_mut().get_mut::<Transform>(head).unwrap() = head_pose;
        app.update();
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0, "step {step}: a strand failed");
        let neck_world = neck_pose.to_matrix().as_dmat4();
        let head_world = neck_world * head_pose.to_matrix().as_dmat4();
        let skin = [neck_world * bind_neck.inverse(), head_world * bind_head.inverse()];
        for (index, &entity) in strands.iter().enumerate() {
            let binding = app.world().get::<ScalpRootBinding>(entity).expect("every strand is bound");
            let [a, b, c] = skinned_corners(binding, &skin);
            let weights = binding.barycentric;
            let expected = weights.x * a + weights.y * b + weights.z * c;
            let rod = strand(&app, entity).rod();
            let (root, second) = (rod.positions()[0], rod.positions()[1]);
            let distance = root.distance(expected);
            // How far the skin carries the root from where the head alone would (the test's point).
            let with_head = (head_world * bind_head.inverse()).transform_point3(skinned_point(binding, 0.0));
            off_the_head = off_the_head.max(root.distance(with_head));
            assert!(distance < 1e-5, "step {step}, strand {index}: the root is {distance:e} m from its skinned point");
            worst_distance = worst_distance.max(distance);
            // The root edge keeps its angle to the triangle's normal.
            let angle = (second - root).angle_between((b - a).cross(c - a));
            let bound = *angles[index].get_or_insert(angle);
            assert!((angle - bound).abs() < 1e-4, "step {step}, strand {index}: the root edge turned off its triangle");
            // No jitter: the root moves as the skinned point does. The integrator's velocity of the
            // skinned points (BDF2: (3xₙ − 4xₙ₋₁ + xₙ₋₂)/2dt) once it has two steps behind it (the strand
            // was spawned at rest at step 1)...
            let velocity = rod.velocities()[0];
            if let (Some(before), Some(earlier)) = (previous[index], earlier[index]) {
                let skinned = (3.0 * expected - 4.0 * before + earlier) / (2.0 * DT);
                let error = velocity.distance(skinned);
                assert!(
                    error <= 0.01 * skinned.length() + F32_VELOCITY_NOISE,
                    "step {step}, strand {index}: root velocity {velocity} against the skinned point's {skinned}"
                );
                if skinned.length() > 0.01 {
                    worst_velocity = worst_velocity.max(error / skinned.length());
                }
                // ...and, against the true derivative (central differences of the animation), within
                // BDF2's truncation (dt²/3 · |x'''|, a millimetre a second for this nod).
                let exact = (skinned_point(binding, time + 1e-4) - skinned_point(binding, time - 1e-4)) / 2e-4;
                worst_exact = worst_exact.max(velocity.distance(exact));
                fastest = fastest.max(exact.length());
            }
            earlier[index] = previous[index];
            previous[index] = Some(expected);
        }
    }
    println!(
        "{} roots, 240 steps: farthest from the skinned point {worst_distance:.1e} m; root velocity off the skinned points' by {worst_velocity:.1e} of its size at most, off the animation's derivative by {worst_exact:.1e} m/s at most (fastest root {fastest:.2} m/s; relative errors over roots faster than 1 cm/s)",
        strands.len()
    );
    assert!(worst_exact < 0.01 * fastest, "the roots move as the animation does: {worst_exact} m/s off");
    assert!(fastest > 0.3, "the scalp moves ({fastest} m/s)");
    assert!(off_the_head > 0.01, "the skin moves roots off the head joint's rigid motion ({off_the_head} m)");
    println!("the skin carried roots up to {off_the_head:.3} m from where the head joint alone would");
}

#[test]
fn a_rigid_scalp_binds_once_loaded_and_a_skin_without_weights_is_refused() {
    let _log = logs::serial();
    // A scalp mesh without a skin, as the head's child, added once the strands are there.
    let mut app = app_with_assets();
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let offset = Vec3::new(0.0, -(NECK + HEAD_ABOVE_NECK).y, 0.0); // The cap's centre at the head's origin.
    let scalp = app.world_mut().spawn((Transform::from_translation(offset), ChildOf(head))).id();
    app.world_mut().entity_mut(head).insert(HairScalpMesh(scalp));
    let top = app.world_mut().spawn((HairStrand::straight(Vec3::Y * RADIUS, Vec3::Y, 0.15, 12), StrandOf(head))).id();
    for _ in 0..3 {
        app.update();
    }
    assert!(app.world().get::<ScalpRootBinding>(top).is_none(), "nothing to bind to before the mesh is there");
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(scalp_mesh(false));
    app.world_mut().entity_mut(scalp).insert(Mesh3d(mesh));
    app.update();
    app.update();
    let binding = app.world().get::<ScalpRootBinding>(top).expect("bound once the mesh is there").clone();
    assert_eq!(binding.mesh, scalp);
    assert!(binding.triangle < 32, "the crown's root is on a crown triangle ({})", binding.triangle);
    // Moving the scalp mesh on the head moves the root with it.
    app.world_mut().get_mut::<Transform>(scalp).unwrap().translation.x += 0.01;
    app.update();
    let root = strand(&app, top).rod().positions()[0];
    assert!((root - DVec3::new(0.01, 1.7, 0.0)).length() < 1e-5, "the root moved with the mesh: {root}");

    // A skinned scalp whose mesh has no joint weights: refused (said once), its strands follow the head.
    logs::take();
    let mut app = app_with_assets();
    let (neck, _, strands) = spawn_character(&mut app, scalp_mesh(false), 7);
    for _ in 0..5 {
        app.update();
    }
    assert!(strands.iter().all(|&entity| app.world().get::<ScalpRootBinding>(entity).is_none()));
    let refusals = logs::take().iter().filter(|(_, line)| line.contains("no joint indices and weights")).count();
    assert_eq!(refusals, 1, "the refusal is said once");
    app.world_mut().get_mut::<Transform>(neck).unwrap().translation.x += 0.05;
    app.update();
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    let root = strand(&app, strands[0]).rod().positions()[0];
    assert!(root.x > 0.04, "the roots follow the head: {root}");
}

#[test]
fn hair_on_a_character_finds_its_head_scalp_and_face_by_name() {
    let mut app = app_with_assets();
    // The scene's root first, as a glTF's scene root is, its nodes spawned later.
    let groom = HairGroom { strand_count: 40, ..default() };
    let character = app
        .world_mut()
        .spawn((
            Transform::default(),
            HairOnCharacter::new("Head", CharacterHair::Groom(groom))
                .with_scalp_mesh("Scalp")
                // The face by its glTF mesh's name, the scalp by its node's.
                .with_collider_meshes(["FaceMesh"]),
        ))
        .id();
    app.update();
    match app.world().get::<HairOnCharacterStatus>(character) {
        Some(HairOnCharacterStatus::Waiting { missing, frames }) => {
            assert_eq!(missing, &["Head", "Scalp", "FaceMesh"]);
            assert_eq!(*frames, 1);
        }
        other => panic!("waiting for the scene, got {other:?}"),
    }
    // The scene: neck and head joints, the skinned scalp as the primitive under a node named "Scalp", and a
    // face (a skinned ball in front of the head) under "Face", its primitive named as Bevy names a glTF
    // primitive, `<mesh name>.<material name>`.
    let (neck, head, _) = spawn_character(&mut app, scalp_mesh(true), usize::MAX);
    let world = app.world_mut();
    world.entity_mut(neck).insert((Name::new("Neck"), ChildOf(character)));
    world.entity_mut(head).insert(Name::new("Head")).remove::<(HairHead, HairScalpMesh)>();
    let scalp = world.query_filtered::<Entity, With<SkinnedMesh>>().single(world).unwrap();
    let skin = world.get::<SkinnedMesh>(scalp).unwrap().clone();
    world.spawn((Name::new("Scalp"), ChildOf(character))).add_child(scalp);
    let ball =
        Sphere::new(0.04).mesh().ico(8).unwrap().translated_by(NECK + HEAD_ABOVE_NECK + Vec3::new(0.0, -0.05, -0.1));
    let count = ball.count_vertices();
    let ball = ball
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(vec![[1, 0, 0, 0]; count]),
        )
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0f32, 0.0, 0.0, 0.0]; count]);
    let ball = world.resource_mut::<Assets<Mesh>>().add(ball);
    let face = world.spawn((Name::new("Face"), ChildOf(character))).id();
    world.spawn((Name::new("FaceMesh.Skin"), Mesh3d(ball), skin, Transform::default(), ChildOf(face)));
    for _ in 0..30 {
        app.update();
    }
    assert_eq!(app.world().get::<HairOnCharacterStatus>(character), Some(&HairOnCharacterStatus::Attached { head }));
    assert_eq!(app.world().get::<HairScalpMesh>(head), Some(&HairScalpMesh(scalp)));
    let strands = app.world().get::<HeadStrands>(head).expect("the groom grew on the head joint").strands().to_vec();
    assert!(strands.len() >= 40, "{} strands", strands.len());
    assert!(strands.iter().all(|&strand| app.world().get::<ScalpRootBinding>(strand).is_some()), "every root bound");
    // The face's collider: baked (on the async pool) in the head joint's space, a child of the joint, met
    // by this head's hair.
    for _ in 0..500 {
        if app.world_mut().query::<&HairCollider>().iter(app.world()).next().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
        app.update();
    }
    let mut colliders = app.world_mut().query::<(&HairCollider, &HairColliderOf, &ChildOf)>();
    let (collider, of, parent) = colliders.single(app.world()).expect("one collider, the face's");
    assert_eq!((of.0, parent.parent()), (head, head));
    // The ball's centre is 5 cm below and 10 cm in front of the head joint, in its space.
    assert!(collider.shape.contains(DVec3::new(0.0, -0.05, -0.1)));
    assert!(!collider.shape.contains(DVec3::new(0.0, -0.05, -0.05)));
}

/// A rig modelled in centimetres, spawned at 0.01, with `character` on its root. Its head joint's +X is the
/// face's direction and its +Y the crown's (as the fox's); its one mesh, "Body", is a head ellipsoid 14 cm
/// wide (joint z), 17 cm tall (joint y) and 20 cm deep (joint x), centred 8 cm in front of the joint and
/// 4 cm above it and skinned wholly to it, and a neck ball below skinned to the neck. Returns the root and
/// the head joint.
fn centimetre_rig(app: &mut App, character: HairOnCharacter) -> (Entity, Entity) {
    let root = app.world_mut().spawn((Transform::from_scale(Vec3::splat(0.01)), character)).id();
    let neck_pose = Transform::from_xyz(0.0, 150.0, 0.0);
    let head_pose = Transform::from_xyz(0.0, 12.0, 0.0).with_rotation(Quat::from_rotation_y(0.4));
    let world = app.world_mut();
    let neck = world.spawn((neck_pose, Name::new("Neck"), ChildOf(root))).id();
    let head = world.spawn((head_pose, Name::new("Head"), ChildOf(neck))).id();
    let bind_head = neck_pose.to_matrix() * head_pose.to_matrix();
    let inverse_bindposes = world
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(vec![neck_pose.to_matrix().inverse(), bind_head.inverse()]);
    let skull = Sphere::new(1.0).mesh().uv(48, 32).scaled_by(SKULL_CM).translated_by(SKULL_CENTRE_CM);
    let neck_ball = Sphere::new(5.0).mesh().ico(3).unwrap().translated_by(Vec3::new(0.0, -10.0, 0.0));
    let (skull_count, neck_count) = (skull.count_vertices(), neck_ball.count_vertices());
    let mut body = skull.transformed_by(Transform::from_matrix(bind_head));
    body.merge(&neck_ball.transformed_by(Transform::from_matrix(bind_head))).unwrap();
    let indices: Vec<[u16; 4]> =
        std::iter::repeat_n([1, 0, 0, 0], skull_count).chain(std::iter::repeat_n([0, 1, 0, 0], neck_count)).collect();
    let body = body
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(indices))
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[1.0f32, 0.0, 0.0, 0.0]; skull_count + neck_count]);
    let mesh = world.resource_mut::<Assets<Mesh>>().add(body);
    world.spawn((
        Name::new("Body"),
        Mesh3d(mesh),
        SkinnedMesh { inverse_bindposes, joints: vec![neck, head] },
        Transform::default(),
        ChildOf(root),
    ));
    (root, head)
}

/// The centimetre rig's skull in its head joint's space, cm: semi-axes 10 along x (depth), 8.5 along y
/// (height), 7 along z (width), and its centre.
const SKULL_CM: Vec3 = Vec3::new(10.0, 8.5, 7.0);
const SKULL_CENTRE_CM: Vec3 = Vec3::new(8.0, 4.0, 0.0);

/// Each strand root of `head` on the centimetre rig, in its head joint's space, cm, as a multiple of the
/// skull's radius there (1 on the skull).
fn roots_on_the_skull(app: &App, head: Entity) -> Vec<f32> {
    let joint = *app.world().get::<GlobalTransform>(head).unwrap();
    let strands = app.world().get::<HeadStrands>(head).expect("the groom grew").strands().to_vec();
    strands
        .into_iter()
        .map(|strand| {
            let local = joint.rotation().inverse() * (strand_root(app, strand) - joint.translation()) / 0.01;
            ((local - SKULL_CENTRE_CM) / SKULL_CM).length()
        })
        .collect()
}

#[test]
fn a_character_s_skull_is_fitted_to_its_head_vertices_in_metres_along_its_own_axes() {
    let mut app = app_with_assets();
    let character = HairOnCharacter::new("Head", CharacterHair::Groom(HairGroom { strand_count: 30, ..default() }))
        .with_head_axes(Vec3::X, Vec3::Y)
        .with_scalp_fitted_to_head();
    let (root, head) = centimetre_rig(&mut app, character);
    for _ in 0..5 {
        app.update();
    }
    assert_eq!(app.world().get::<HairOnCharacterStatus>(root), Some(&HairOnCharacterStatus::Attached { head }));
    let scalp = app.world().get::<HairGroom>(head).expect("the groom on the head joint").scalp;
    // In metres along the groom's axes (x left to right, y up, z back): the joint's z, y and −x.
    println!("fitted skull: centre {} m, semi-axes {} m", scalp.centre, scalp.semi_axes);
    assert!(scalp.centre.distance(Vec3::new(0.0, 0.04, -0.08)) < 1e-5, "centre {}", scalp.centre);
    assert!((scalp.semi_axes - Vec3::new(0.07, 0.085, 0.1)).abs().max_element() < 1e-5, "{}", scalp.semi_axes);
    // The groom grew on it: every root on the fitted skull, placed through the rig's scale.
    let roots = roots_on_the_skull(&app, head);
    assert_eq!(roots.len(), 30);
    assert!(roots.iter().all(|on_skull| (on_skull - 1.0).abs() < 1e-3), "{roots:?}");
}

/// glTF's convention read off the rig: the model's front `+Z` and up `+Y` in the head joint's space, through
/// the joint's inverse bind pose (the centimetre rig's head joint is turned 0.4 rad about y at its bind
/// pose: the model's `+Z` is `(−sin 0.4, 0, cos 0.4)` in it; the neck's joint, or the bind pose read the
/// wrong way round, would give `+Z` or `(sin 0.4, 0, cos 0.4)`).
#[test]
fn a_character_s_head_axes_are_read_off_its_bind_pose() {
    let mut app = app_with_assets();
    let groom = HairGroom { strand_count: 30, ..default() };
    let character = HairOnCharacter::new("Head", CharacterHair::Groom(groom)).with_gltf_head_axes();
    let (root, head) = centimetre_rig(&mut app, character);
    for _ in 0..5 {
        app.update();
    }
    assert_eq!(app.world().get::<HairOnCharacterStatus>(root), Some(&HairOnCharacterStatus::Attached { head }));
    let axes = app.world().get::<HairGroom>(head).expect("the groom on the head joint").head_axes;
    let expected = Vec3::new(-0.4_f32.sin(), 0.0, 0.4_f32.cos());
    println!("head axes from the bind pose: face {}, crown {}", axes.forward, axes.up);
    assert!(axes.forward.distance(expected) < 1e-6 && axes.up.distance(Vec3::Y) < 1e-6, "{axes:?}");
    assert_eq!(app.world().get::<HeadStrands>(head).map(|strands| strands.strands().len()), Some(30));
}

#[test]
fn a_character_of_one_skinned_mesh_grows_hair_where_its_head_joint_skins_it() {
    let mut app = app_with_assets();
    let groom = HairGroom { strand_count: 40, ..default() };
    let character = HairOnCharacter::new("Head", CharacterHair::Groom(groom))
        .with_head_axes(Vec3::X, Vec3::Y)
        .with_scalp_where_head_skins("Body")
        .with_scalp_fitted_to_head();
    let (_, head) = centimetre_rig(&mut app, character);
    for _ in 0..10 {
        app.update();
    }
    assert_eq!(app.world().get::<ScalpWhereHeadSkins>(head), Some(&ScalpWhereHeadSkins));
    // Every root on the head's triangles, none on the neck ball the same mesh holds: on the skull's mesh, a
    // UV sphere of 48 segments and 32 rings, whose flat quads lie inside the ellipsoid by up to
    // 1 − cos(π/48) cos(π/64) = 0.33 % of its radius at their centres, and never outside it.
    let roots = roots_on_the_skull(&app, head);
    let (lowest, highest) = roots.iter().fold((f32::INFINITY, 0.0_f32), |(low, high), &on| (low.min(on), high.max(on)));
    println!("{} roots, at {lowest:.4} to {highest:.4} of the skull's radius", roots.len());
    assert!(roots.len() >= 40, "{} roots", roots.len());
    assert!(lowest > 1.0 - 3.4e-3 && highest < 1.0 + 1e-5, "{roots:?}");
    let strands = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    assert!(strands.iter().all(|&strand| app.world().get::<ScalpRootBinding>(strand).is_some()), "every root bound");
}

/// A strand's root, world space, m.
fn strand_root(app: &App, entity: Entity) -> Vec3 {
    strand(app, entity).rod().positions()[0].as_vec3()
}
