//! Hair on a skinned character: a body, a neck and a head built in code as a glTF importer would spawn
//! them (named joints, skinned meshes), and `HairOnCharacter` on the character's root putting hair on it
//! by name: the head joint carries the hair, the groom grows on the skinned scalp mesh (its roots bound to
//! the scalp's triangles, which the neck's and head's joints skin), the face and ears are baked into a
//! mesh collider, and capsules on the shoulders hold the hair falling down the back. The neck sways and
//! bends while the head turns and nods.
//!
//! ```sh
//! cargo run --release --features examples --example character
//! cargo run --release --features examples --example character -- --groom ratboy
//! ```
//!
//! Options: `--groom straight|curly|ratboy` (Ratboy: TressFX's mohawk at 0.3 of its size),
//! `--animate sway|still`, `--view front|back`, `--gpu off` (the guides stepped on the CPU; by
//! default the GPU steps them where the adapter can, its colliders met there, the face's mesh included), and picture mode `--screenshot PATH --frames N` (N frames of exactly 1/60 s,
//! then a PNG, then exit). Press C to show the colliders.

use std::f32::consts::{FRAC_PI_2, TAU};
use std::time::Duration;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;

fn main() {
    let options = match Options::from_args(std::env::args().skip(1)) {
        Ok(options) => options,
        Err(message) => {
            eprintln!("{message}\n\n{}", Options::USAGE);
            std::process::exit(2);
        }
    };
    let window = Window { title: "bevy_hair_sim: character".into(), resolution: (1280, 800).into(), ..default() };
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin { primary_window: Some(window), ..default() })
            .set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() }),
        HairPlugins::default(),
    ))
    .insert_resource(HairGpuSettings { enabled: options.gpu, ..default() })
    .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
    // The style held near the roots and hair meeting hair.
    .insert_resource(HairSettings::styled())
    .add_systems(Startup, spawn_character)
    .add_systems(Update, (move_joints, toggle_colliders, report_attachment));
    if options.screenshot.is_some() {
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)))
            .add_systems(Update, take_picture);
    }
    app.insert_resource(options).run();
}

/// Command-line options.
#[derive(Resource, Debug, Clone)]
struct Options {
    groom: Groom,
    animate: bool,
    /// Whether the camera looks at the face (true) or the back of the head.
    front: bool,
    screenshot: Option<String>,
    frames: u32,
    /// Whether the GPU steps the guides (`HairGpuPlugin`).
    gpu: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Groom {
    Straight,
    Curly,
    Ratboy,
}

impl Options {
    const USAGE: &str = "usage: character [--groom straight|curly|ratboy] [--animate sway|still] [--view front|back] [--gpu on|off] [--screenshot PATH] [--frames N]";

    fn from_args(mut args: impl Iterator<Item = String>) -> Result<Self, String> {
        let mut options =
            Self { groom: Groom::Straight, animate: true, front: true, screenshot: None, frames: 240, gpu: true };
        while let Some(flag) = args.next() {
            let value = args.next().ok_or_else(|| format!("{flag} needs a value"))?;
            match (flag.as_str(), value.as_str()) {
                ("--groom", "straight") => options.groom = Groom::Straight,
                ("--groom", "curly") => options.groom = Groom::Curly,
                ("--groom", "ratboy") => options.groom = Groom::Ratboy,
                ("--animate", "sway") => options.animate = true,
                ("--animate", "still") => options.animate = false,
                ("--view", "front") => options.front = true,
                ("--view", "back") => options.front = false,
                ("--gpu", "on") => options.gpu = true,
                ("--gpu", "off") => options.gpu = false,
                ("--screenshot", path) => options.screenshot = Some(path.to_owned()),
                ("--frames", count) => {
                    options.frames = count.parse().map_err(|_| format!("--frames needs a count, got {count}"))?
                }
                _ => return Err(format!("unknown option {flag} {value}")),
            }
        }
        Ok(options)
    }
}

/// Where the neck joint stands (world, at the bind pose), and the head joint above it, m.
const NECK: Vec3 = Vec3::new(0.0, 1.45, 0.0);
const HEAD_ABOVE_NECK: Vec3 = Vec3::new(0.0, 0.1, 0.0);
/// The skull: an ellipsoid about this point above the head joint, m.
const SKULL_CENTRE: Vec3 = Vec3::new(0.0, 0.1, 0.0);
const SKULL: Vec3 = Vec3::new(0.075, 0.092, 0.097);

/// The character's two joints, for the animation.
#[derive(Component)]
struct Joint {
    /// Its pose at the bind pose (local).
    bind: Transform,
    is_head: bool,
}

fn spawn_character(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
    assets: Res<AssetServer>,
    options: Res<Options>,
) {
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
    let hair = match options.groom {
        Groom::Straight | Groom::Curly => {
            let style = if options.groom == Groom::Straight { HairStyle::Straight } else { HairStyle::Curly };
            let scalp = Scalp { centre: SKULL_CENTRE, semi_axes: SKULL, ..default() };
            CharacterHair::Groom(HairGroom { style, scalp, strand_count: 1200, followers_per_guide: 8, ..default() })
        }
        Groom::Ratboy => {
            // TressFX's mohawk grows on a rat's head 69 cm tall (roots from its neck to its crown): at
            // 0.3 of its size, lowered to this head, each strand moved onto the scalp's nearest point.
            // (Fitting it to the scalp, `fit_to_scalp`, squeezes that tall layout into a strip.)
            let placement =
                GroomPlacement { metres_per_unit: 0.3, transform: Transform::from_xyz(0.0, -0.07, 0.0), ..default() };
            CharacterHair::File(HairGroomFile::new(assets.load("grooms/Ratboy_mohawk.tfx")).with_placement(placement))
        }
    };
    commands
        .entity(root)
        .insert(HairOnCharacter::new("Head", hair).with_scalp_mesh("Scalp").with_collider_meshes(["Face"]));

    commands.insert_resource(GlobalAmbientLight { brightness: 300.0, ..default() });
    commands.spawn((
        DirectionalLight { illuminance: 8000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(1.0, 3.0, -2.0).looking_at(Vec3::new(0.0, 1.5, 0.0), Vec3::Y),
    ));
    let eye = if options.front { Vec3::new(0.55, 1.72, -0.62) } else { Vec3::new(-0.45, 1.75, 0.7) };
    commands
        .spawn((Camera3d::default(), Transform::from_translation(eye).looking_at(Vec3::new(0.0, 1.55, 0.0), Vec3::Y)));
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

/// The top of the ellipsoid `semi_axes` about `centre`, down to 115° from the crown at the back and sides
/// and 60° at the face (`rings` rings), its triangles facing out.
fn scalp_cap(centre: Vec3, semi_axes: Vec3, rings: u32) -> Mesh {
    let segments = 2 * rings;
    let (mut positions, mut normals) = (Vec::new(), Vec::new());
    for ring in 0..=rings {
        for segment in 0..segments {
            let azimuth = TAU * segment as f32 / segments as f32;
            // Lower at the back (+z) than over the face (−z).
            let facing_front = (-azimuth.sin()).max(0.0);
            let lowest = (115.0 - 55.0 * facing_front * facing_front).to_radians();
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

/// The neck sways 6 cm and bends ±0.25 rad while the head turns ±0.7 rad and nods ±0.25 rad.
fn move_joints(time: Res<Time>, options: Res<Options>, mut joints: Query<(&Joint, &mut Transform)>) {
    if !options.animate {
        return;
    }
    let seconds = time.elapsed_secs();
    let wave = |frequency: f32| (TAU * frequency * seconds).sin();
    for (joint, mut transform) in &mut joints {
        *transform = if joint.is_head {
            joint.bind.with_rotation(Quat::from_rotation_y(0.7 * wave(0.25)) * Quat::from_rotation_x(0.25 * wave(0.55)))
        } else {
            joint
                .bind
                .with_translation(joint.bind.translation + Vec3::X * 0.06 * wave(0.15))
                .with_rotation(Quat::from_rotation_z(0.25 * wave(0.35)))
        };
    }
}

fn toggle_colliders(keys: Res<ButtonInput<KeyCode>>, mut gizmos: ResMut<GizmoConfigStore>) {
    if keys.just_pressed(KeyCode::KeyC) {
        let config = gizmos.config_mut::<HairGizmos>().1;
        config.draw_colliders = !config.draw_colliders;
    }
}

/// Says once when the hair is on.
fn report_attachment(characters: Query<&HairOnCharacterStatus, Changed<HairOnCharacterStatus>>) {
    for status in &characters {
        if let HairOnCharacterStatus::Attached { head } = status {
            info!("hair attached to the head joint {head}");
        }
    }
}

/// Frames at the start (while the renderer compiles its pipelines) and before the picture in which the
/// rendered hair is drawn; in between it is hidden, so that a software renderer spends its time on the
/// frames that count. The simulation runs all along.
const DRAWN_PICTURE_FRAMES: u32 = 8;

/// Picture mode: after the asked number of frames, saves a screenshot and exits once it is written.
fn take_picture(
    mut commands: Commands,
    options: Res<Options>,
    mut frames: Local<u32>,
    mut hair_meshes: Query<&mut Visibility, With<HairMesh>>,
    gpu: Option<Res<HairGpuStatus>>,
) {
    *frames += 1;
    let drawn = *frames <= DRAWN_PICTURE_FRAMES || *frames + DRAWN_PICTURE_FRAMES >= options.frames;
    let shown = if drawn { Visibility::Inherited } else { Visibility::Hidden };
    hair_meshes.iter_mut().for_each(|mut visibility| {
        visibility.set_if_neq(shown);
    });
    if *frames != options.frames {
        return;
    }
    let Some(path) = options.screenshot.clone() else {
        return;
    };
    if let Some(gpu) = gpu {
        info!(
            "on the GPU: {} strands, {} faults, {} nodes in contact, largest strain {:.1e}",
            gpu.strands, gpu.faults, gpu.contacts, gpu.max_strain
        );
    }
    commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path)).observe(
        |_: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
            exit.write(AppExit::Success);
        },
    );
}
