//! Hair on a real glTF character, loaded through the asset server as a game loads one, playing its own
//! clips: by default the mannequin made for this crate (`assets/models/Mannequin.glb`), a humanoid
//! modelled in centimetres and spawned at a scale of 0.01, its head joint's axes its own. The hair is put
//! on as the crate guide puts it: by the names of the head joint, the scalp mesh and the face, its axes read
//! off the rig's bind pose and its skull fitted to the head's vertices, with no number measured by hand.
//! `--character fox` puts a mane on Bevy's animated fox instead (its skull read off the model by hand: its
//! head joint skins its snout and ears as much as its cranium).
//!
//! ```sh
//! cargo run --release --features examples --example gltf_character
//! cargo run --release --features examples --example gltf_character -- --clip walk --view back
//! cargo run --release --features examples --example gltf_character -- --character fox
//! ```
//!
//! Options: `--character mannequin|fox`, `--clip idle|walk|look` (the mannequin's clips; the fox's are
//! `survey|walk|run`), `--view front|back`, `--gpu on|off` (the guides stepped on the GPU where the
//! adapter can, the default, or on the CPU), and picture mode `--screenshot PATH --frames N` (N frames of
//! exactly 1/60 s, then a PNG, then exit). Press C to show the colliders.
//!
//! The mannequin: made by this crate's `assets/models/make_mannequin.py`, CC0. The fox: CC0 model by
//! PixelMannen, rigging and animation by @tomkranis (CC-BY 4.0), glTF conversion by @AsoboStudio and
//! @scurest (CC-BY 4.0); see `assets/models/Fox.LICENSE.md`.

use std::f32::consts::PI;
use std::time::Duration;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::time::TimeUpdateStrategy;
use bevy::world_serialization::WorldInstanceReady;
use bevy_hair_sim::prelude::*;

/// The characters, as the asset server finds them under `assets/`.
const MANNEQUIN: &str = "models/Mannequin.glb";
const FOX: &str = "models/Fox.glb";

fn main() {
    let options = match Options::from_args(std::env::args().skip(1)) {
        Ok(options) => options,
        Err(message) => {
            eprintln!("{message}\n\n{}", Options::USAGE);
            std::process::exit(2);
        }
    };
    let window = Window { title: "bevy_hair_sim: glTF character".into(), resolution: (1280, 800).into(), ..default() };
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
    .insert_resource(GlobalAmbientLight { color: Color::WHITE, brightness: 400.0, ..default() })
    .add_systems(Startup, (spawn_character, spawn_stage))
    .add_systems(Update, (toggle_colliders, report_attachment));
    if options.screenshot.is_some() {
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)))
            .add_systems(Update, take_picture);
    }
    app.insert_resource(options).run();
}

/// Command-line options.
#[derive(Resource, Debug, Clone)]
struct Options {
    /// Whether the fox is loaded (true) or the mannequin.
    fox: bool,
    /// Which of the character's clips plays (its index in the file).
    clip: usize,
    /// Whether the camera looks at the character's face (true) or from behind.
    front: bool,
    /// Whether the GPU steps the guides (`HairGpuPlugin`).
    gpu: bool,
    screenshot: Option<String>,
    frames: u32,
}

impl Options {
    const USAGE: &str = "usage: gltf_character [--character mannequin|fox] [--clip idle|walk|look (mannequin) | survey|walk|run (fox)] [--view front|back] [--gpu on|off] [--screenshot PATH] [--frames N]";

    fn from_args(mut args: impl Iterator<Item = String>) -> Result<Self, String> {
        let mut options = Self { fox: false, clip: 1, front: true, gpu: true, screenshot: None, frames: 240 };
        let mut clip = None;
        while let Some(flag) = args.next() {
            let value = args.next().ok_or_else(|| format!("{flag} needs a value"))?;
            match (flag.as_str(), value.as_str()) {
                ("--character", "mannequin") => options.fox = false,
                ("--character", "fox") => options.fox = true,
                ("--clip", name) => clip = Some(name.to_owned()),
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
        // The clips in each file's order.
        let clips: &[&str] = if options.fox { &["survey", "walk", "run"] } else { &["idle", "walk", "look"] };
        if let Some(clip) = clip {
            options.clip = clips.iter().position(|&name| name == clip).ok_or_else(|| {
                format!("the {} has no clip {clip:?}: it has {clips:?}", if options.fox { "fox" } else { "mannequin" })
            })?;
        }
        Ok(options)
    }
}

/// The clip to play once the fox's scene has spawned.
#[derive(Component)]
struct ClipToPlay {
    graph: Handle<AnimationGraph>,
    index: AnimationNodeIndex,
}

/// The fox's mane: short hair combed back over the crown and down the neck, in metres along the groom's
/// axes (the face `−Z`, the crown `+Y`). The skull is read off the model: an ellipsoid around the fox's
/// low-poly cranium, 9.5 cm in front of the head joint (which sits at the back of the skull) and 4.5 cm
/// above it, 17 cm across, 20 cm tall and 23 cm long, its top a centimetre above the head's top facets (a
/// smooth skull inside flat facets would hide the hair under them). (`HairOnCharacter::with_scalp_fitted_to_head`
/// fits the skull to the head's skinned vertices instead, which suits a head that is mostly skull; the
/// fox's head vertices take in its snout and ears, and the skull fitted to them is 24 × 34 × 32 cm: the hair
/// then sits on a dome above its head, as a wig would.)
fn fox_mane() -> HairGroom {
    HairGroom {
        scalp: Scalp {
            centre: Vec3::new(0.0, 0.045, -0.095),
            semi_axes: Vec3::new(0.085, 0.1, 0.115),
            nape_height: -0.1,
            brow_height: 0.55,
        },
        strand_count: 400,
        followers_per_guide: 6,
        segments: 12,
        style: HairStyle::Short,
        ..default()
    }
}

/// The mannequin's hair: long straight hair, 1 200 guides with 8 followers each, on its scalp mesh.
fn mannequin_hair() -> HairGroom {
    HairGroom { strand_count: 1200, followers_per_guide: 8, ..default() }
}

/// Loads the character as a glTF scene, with the hair on its head joint.
fn spawn_character(
    mut commands: Commands,
    assets: Res<AssetServer>,
    options: Res<Options>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
) {
    let path = if options.fox { FOX } else { MANNEQUIN };
    let (graph, index) =
        AnimationGraph::from_clip(assets.load(GltfAssetLabel::Animation(options.clip).from_asset(path)));
    let hair = if options.fox {
        // The fox's head joint +X runs down the snout, its +Y up through the crown.
        HairOnCharacter::new("b_Head_05", CharacterHair::Groom(fox_mane())).with_head_axes(Vec3::X, Vec3::Y)
    } else {
        // As the crate guide does it: the names, and nothing measured by hand.
        HairOnCharacter::new("Head", CharacterHair::Groom(mannequin_hair()))
            .with_gltf_head_axes()
            .with_scalp_fitted_to_head()
            .with_scalp_mesh("Scalp")
            .with_collider_meshes(["Face"])
    };
    commands
        .spawn((
            WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset(path))),
            // Both are modelled in centimetres.
            Transform::from_scale(Vec3::splat(0.01)),
            ClipToPlay { graph: graphs.add(graph), index },
            hair,
        ))
        .observe(play_clip_when_ready)
        .observe(put_colliders_on_the_mannequins_shoulders);
}

/// The mannequin's shoulders hold the hair that falls on them: a capsule across them on its `Chest` joint,
/// measured in the model's centimetres as `make_mannequin.py` makes it (the joint 124 cm up, the
/// shoulders' balls 6 cm in radius 16.5 cm above it and 17.5 cm either side), a collider of the head's.
fn put_colliders_on_the_mannequins_shoulders(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    options: Res<Options>,
    children: Query<&Children>,
    names: Query<&Name>,
) {
    if options.fox {
        return;
    }
    let named = |wanted: &str| {
        children
            .iter_descendants(ready.entity)
            .find(|&entity| names.get(entity).is_ok_and(|name| name.as_str() == wanted))
    };
    let (Some(head), Some(chest)) = (named("Head"), named("Chest")) else {
        warn!("the mannequin has no Head or Chest joint: its shoulders hold no hair");
        return;
    };
    let across = Transform::from_xyz(0.0, 16.5, -1.0).with_rotation(Quat::from_rotation_z(PI / 2.0));
    commands.spawn((HairCollider::capsule(6.5, 17.5), HairColliderOf(head), ChildOf(chest), across));
}

/// Starts the clip on the scene's animation player once the scene has spawned.
fn play_clip_when_ready(
    ready: On<WorldInstanceReady>,
    mut commands: Commands,
    children: Query<&Children>,
    clips: Query<&ClipToPlay>,
    mut players: Query<&mut AnimationPlayer>,
) {
    let Ok(clip) = clips.get(ready.entity) else { return };
    for child in children.iter_descendants(ready.entity) {
        if let Ok(mut player) = players.get_mut(child) {
            player.play(clip.index).repeat();
            commands.entity(child).insert(AnimationGraphHandle(clip.graph.clone()));
        }
    }
}

/// A camera on the fox's head, a floor and a sun.
fn spawn_stage(
    mut commands: Commands,
    options: Res<Options>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    // Both face +Z. The fox's head is about 0.6 m up and 0.4 m forward; the mannequin's 1.65 m up.
    let (eye, target) = match (options.fox, options.front) {
        (true, true) => (Vec3::new(0.45, 0.8, 1.1), Vec3::new(0.0, 0.6, 0.4)),
        (true, false) => (Vec3::new(-0.45, 1.05, -0.55), Vec3::new(0.0, 0.6, 0.4)),
        (false, true) => (Vec3::new(0.3, 1.72, 0.55), Vec3::new(0.0, 1.6, 0.0)),
        (false, false) => (Vec3::new(-0.3, 1.74, -0.6), Vec3::new(0.0, 1.57, 0.0)),
    };
    commands.spawn((Camera3d::default(), Transform::from_translation(eye).looking_at(target, Vec3::Y)));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(20.0, 20.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.3, 0.4, 0.3))),
    ));
    commands.spawn((
        DirectionalLight { illuminance: 8_000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_rotation(Quat::from_euler(EulerRot::ZYX, 0.0, 1.0, -PI / 4.0)),
    ));
}

fn toggle_colliders(keys: Res<ButtonInput<KeyCode>>, mut gizmos: ResMut<GizmoConfigStore>) {
    if keys.just_pressed(KeyCode::KeyC) {
        let config = gizmos.config_mut::<HairGizmos>().1;
        config.draw_colliders = !config.draw_colliders;
    }
}

/// Says once when the hair is on, and what is still missing while it waits.
fn report_attachment(characters: Query<&HairOnCharacterStatus, Changed<HairOnCharacterStatus>>) {
    for status in &characters {
        if let HairOnCharacterStatus::Attached { head } = status {
            info!("hair attached to the character's head joint {head}");
        }
    }
}

/// Picture mode: after the asked number of frames, saves a screenshot and exits once it is written.
fn take_picture(mut commands: Commands, options: Res<Options>, mut frames: Local<u32>) {
    *frames += 1;
    if *frames != options.frames {
        return;
    }
    let Some(path) = options.screenshot.clone() else { return };
    commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path)).observe(
        |_: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
            exit.write(AppExit::Success);
        },
    );
}
