//! The character the `character` example puts hair on, built in code as a glTF importer spawns one: a
//! root, two named joints (`Neck`, `Head` under it), skinned meshes named as a glTF's nodes (`Face` with
//! its ears, `Scalp`, `NeckSkin`, `Body`), and a capsule across the shoulders as the head's collider. Shared
//! by the example and its test on the GPU (`tests/gpu/character.rs`), so that the test meets the
//! example's character.

use std::f32::consts::{FRAC_PI_2, TAU};

use bevy::asset::RenderAssetUsages;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy_hair_sim::prelude::*;

/// Where the neck joint stands (world, at the bind pose), and the head joint above it, m.
pub const NECK: Vec3 = Vec3::new(0.0, 1.45, 0.0);
pub const HEAD_ABOVE_NECK: Vec3 = Vec3::new(0.0, 0.1, 0.0);
/// The skull: an ellipsoid about this point above the head joint, m.
pub const SKULL_CENTRE: Vec3 = Vec3::new(0.0, 0.1, 0.0);
pub const SKULL: Vec3 = Vec3::new(0.075, 0.092, 0.097);

/// One of the character's two joints, for the animation ([`swayed`]).
#[derive(Component)]
pub struct Joint {
    /// Its pose at the bind pose (local).
    pub bind: Transform,
    pub is_head: bool,
}

/// The straight or curly groom the example grows on the scalp: 1 200 guides, 8 followers each, on the
/// skull's ellipsoid.
pub fn scalp_groom(style: HairStyle) -> HairGroom {
    let scalp = Scalp { centre: SKULL_CENTRE, semi_axes: SKULL, ..default() };
    HairGroom { style, scalp, strand_count: 1200, followers_per_guide: 8, ..default() }
}

/// Spawns the character with `hair` put on its head joint by name (`HairOnCharacter`: the groom on the
/// `Scalp` mesh, the `Face` baked into a mesh collider); returns its root.
pub fn spawn_character_in_code(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
    bindposes: &mut Assets<SkinnedMeshInverseBindposes>,
    hair: CharacterHair,
) -> Entity {
    // The character's root, its two joints (named as a glTF's nodes are), and the skin.
    let root = commands.spawn((Transform::default(), Visibility::default(), Name::new("Character"))).id();
    let neck_pose = Transform::from_translation(NECK);
    let head_pose = Transform::from_translation(HEAD_ABOVE_NECK);
    // Joints are visible nodes, as a glTF importer spawns them (what hangs under them inherits that).
    let joint = |pose: Transform, name: &str, is_head: bool| {
        (pose, Visibility::default(), Name::new(name.to_owned()), Joint { bind: pose, is_head })
    };
    let neck = commands.spawn((joint(neck_pose, "Neck", false), ChildOf(root))).id();
    let head = commands.spawn((joint(head_pose, "Head", true), ChildOf(neck))).id();
    let bind_neck = neck_pose.to_matrix();
    let bind_head = bind_neck * head_pose.to_matrix();
    let inverse_bindposes = bindposes.add(vec![bind_neck.inverse(), bind_head.inverse()]);
    let skin = SkinnedMesh { inverse_bindposes, joints: vec![neck, head] };

    // Meshes in the bind pose (world), each vertex weighted between the neck (joint 0) and head (1).
    let skull_centre = NECK + HEAD_ABOVE_NECK + SKULL_CENTRE;
    let head_weight = |position: Vec3| ((position.y - NECK.y) / HEAD_ABOVE_NECK.y).clamp(0.0, 1.0);
    let skin_tone = materials.add(StandardMaterial {
        base_color: Color::srgb(0.78, 0.58, 0.47),
        perceptual_roughness: 0.7,
        ..default()
    });
    // The scalp is skin, a little darker where the hair shades it: at the hairline, where the hair thins
    // out, it reads as skin, not as a cap.
    let scalp_tone = materials.add(StandardMaterial {
        base_color: Color::srgb(0.6, 0.44, 0.35),
        perceptual_roughness: 0.8,
        ..default()
    });
    let cloth = materials.add(StandardMaterial { base_color: Color::srgb(0.25, 0.3, 0.38), ..default() });
    let mut skinned = |name: &str, mesh: Mesh, material: &Handle<StandardMaterial>, weight: &dyn Fn(Vec3) -> f32| {
        let mesh = with_skin_weights(mesh, weight);
        commands.spawn((
            Name::new(name.to_owned()),
            Mesh3d(meshes.add(mesh)),
            MeshMaterial3d(material.clone()),
            skin.clone(),
            Transform::default(),
            ChildOf(root),
        ));
    };
    // A face with ears: the skull, and an ear on each side.
    let mut face = ellipsoid(skull_centre, SKULL, 48, 32);
    for side in [-1.0, 1.0] {
        let ear =
            ellipsoid(skull_centre + Vec3::new(side * 0.074, -0.005, 0.005), Vec3::new(0.012, 0.03, 0.02), 16, 12);
        face.merge(&ear).expect("both are triangle lists with the same attributes");
    }
    skinned("Face", face, &skin_tone, &|_| 1.0);
    // The scalp: the skull's top, a millimetre out, bent by the neck at the nape.
    skinned("Scalp", scalp_cap(skull_centre, SKULL + Vec3::splat(0.001), 40), &scalp_tone, &|p| {
        0.8 + 0.2 * head_weight(p)
    });
    // The neck, bending between the two joints; the body below it.
    let neck_mesh =
        Cylinder::new(0.05, 0.22).mesh().resolution(24).segments(8).build().translated_by(NECK + Vec3::Y * 0.02);
    skinned("NeckSkin", neck_mesh, &skin_tone, &head_weight);
    let body = Capsule3d::new(0.16, 0.3)
        .mesh()
        .build()
        .scaled_by(Vec3::new(1.0, 1.0, 0.55))
        .translated_by(NECK - Vec3::Y * 0.32);
    skinned("Body", body, &cloth, &|_| 0.0);

    // The shoulders hold hair falling down the back: a capsule across them, this head's collider.
    let shoulders = Transform::from_translation(NECK - Vec3::Y * 0.15).with_rotation(Quat::from_rotation_z(FRAC_PI_2));
    commands.spawn((HairCollider::capsule(0.07, 0.12), HairColliderOf(head), shoulders));

    // The hair, put on by name once the character is there.
    commands
        .entity(root)
        .insert(HairOnCharacter::new("Head", hair).with_scalp_mesh("Scalp").with_collider_meshes(["Face"]));
    root
}

/// `mesh` with joint indices (neck 0, head 1) and weights: `head(position)` for the head, the rest the
/// neck's.
fn with_skin_weights(mesh: Mesh, head: &dyn Fn(Vec3) -> f32) -> Mesh {
    let positions = mesh.attribute(Mesh::ATTRIBUTE_POSITION).and_then(VertexAttributeValues::as_float3).unwrap_or(&[]);
    let weights: Vec<[f32; 4]> = positions
        .iter()
        .map(|&position| {
            let head = head(Vec3::from(position)).clamp(0.0, 1.0);
            [1.0 - head, head, 0.0, 0.0]
        })
        .collect();
    let indices = VertexAttributeValues::Uint16x4(vec![[0, 1, 0, 0]; weights.len()]);
    mesh.with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, indices)
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights)
}

/// A closed ellipsoid of `semi_axes` about `centre` (`segments` × `rings`).
fn ellipsoid(centre: Vec3, semi_axes: Vec3, segments: u32, rings: u32) -> Mesh {
    Sphere::new(1.0).mesh().uv(segments, rings).scaled_by(semi_axes).translated_by(centre)
}

/// The top of the ellipsoid `semi_axes` about `centre`, down to 115° from the crown at the back and 60° at
/// the face, its edge arching up to 70° over the ears as a hairline does (`rings` rings), its triangles
/// facing out. (Down to 115° at the sides too, it ran through the ears: hair grew out of them.)
fn scalp_cap(centre: Vec3, semi_axes: Vec3, rings: u32) -> Mesh {
    let segments = 2 * rings;
    let (mut positions, mut normals) = (Vec::new(), Vec::new());
    for ring in 0..=rings {
        for segment in 0..segments {
            let azimuth = TAU * segment as f32 / segments as f32;
            // Lower at the back (+z) than over the face (−z).
            let facing_front = (-azimuth.sin()).max(0.0);
            let below_crown = 115.0 - 55.0 * facing_front * facing_front;
            // The ears stand at the sides (±x, azimuth 0 and π), 2 cm either way of them along z (15° of
            // azimuth), their tops 74° from the crown: the hairline arches just over them.
            let from_ear = azimuth.cos().abs().acos().to_degrees();
            let over_ear = 1.0 - ((from_ear - 14.0) / 14.0).clamp(0.0, 1.0);
            let over_ear = over_ear * over_ear * (3.0 - 2.0 * over_ear);
            let lowest = (below_crown + (70.0 - below_crown) * over_ear).to_radians();
            let polar = lowest * ring as f32 / rings as f32;
            let unit = Vec3::new(polar.sin() * azimuth.cos(), polar.cos(), polar.sin() * azimuth.sin());
            positions.push(centre + unit * semi_axes);
            normals.push((unit / semi_axes).normalize());
        }
    }
    let at = |ring: u32, segment: u32| ring * segments + segment % segments;
    let mut indices = Vec::new();
    for ring in 0..rings {
        for segment in 0..segments {
            let (a, b, c, d) =
                (at(ring, segment), at(ring, segment + 1), at(ring + 1, segment), at(ring + 1, segment + 1));
            indices.extend([a, b, d, a, d, c]);
        }
    }
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
        .with_inserted_indices(Indices::U32(indices))
}

/// `joint`'s pose `seconds` into the sway: the neck sways 6 cm and bends ±0.25 rad while the head turns
/// ±0.7 rad and nods ±0.25 rad.
pub fn swayed(joint: &Joint, seconds: f32) -> Transform {
    let wave = |frequency: f32| (TAU * frequency * seconds).sin();
    if joint.is_head {
        joint.bind.with_rotation(Quat::from_rotation_y(0.7 * wave(0.25)) * Quat::from_rotation_x(0.25 * wave(0.55)))
    } else {
        joint
            .bind
            .with_translation(joint.bind.translation + Vec3::X * 0.06 * wave(0.15))
            .with_rotation(Quat::from_rotation_z(0.25 * wave(0.35)))
    }
}
