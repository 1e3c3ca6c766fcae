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

use std::time::Duration;

use bevy::mesh::skinning::SkinnedMeshInverseBindposes;
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;

#[path = "support/character_in_code.rs"]
mod character_in_code;
use character_in_code::{Joint, scalp_groom, spawn_character_in_code, swayed};

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

fn spawn_character(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
    assets: Res<AssetServer>,
    options: Res<Options>,
) {
    let hair = match options.groom {
        Groom::Straight => CharacterHair::Groom(scalp_groom(HairStyle::Straight)),
        Groom::Curly => CharacterHair::Groom(scalp_groom(HairStyle::Curly)),
        Groom::Ratboy => {
            // TressFX's mohawk grows on a rat's head 69 cm tall (roots from its neck to its crown): at
            // 0.3 of its size, lowered to this head, each strand moved onto the scalp's nearest point.
            // (Fitting it to the scalp, `fit_to_scalp`, squeezes that tall layout into a strip.)
            let placement =
                GroomPlacement { metres_per_unit: 0.3, transform: Transform::from_xyz(0.0, -0.07, 0.0), ..default() };
            CharacterHair::File(HairGroomFile::new(assets.load("grooms/Ratboy_mohawk.tfx")).with_placement(placement))
        }
    };
    spawn_character_in_code(&mut commands, &mut meshes, &mut materials, &mut bindposes, hair);

    commands.insert_resource(GlobalAmbientLight { brightness: 300.0, ..default() });
    commands.spawn((
        DirectionalLight { illuminance: 8000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(1.0, 3.0, -2.0).looking_at(Vec3::new(0.0, 1.5, 0.0), Vec3::Y),
    ));
    let eye = if options.front { Vec3::new(0.55, 1.72, -0.62) } else { Vec3::new(-0.45, 1.75, 0.7) };
    commands
        .spawn((Camera3d::default(), Transform::from_translation(eye).looking_at(Vec3::new(0.0, 1.55, 0.0), Vec3::Y)));
}

/// The neck and head swaying ([`swayed`]).
fn move_joints(time: Res<Time>, options: Res<Options>, mut joints: Query<(&Joint, &mut Transform)>) {
    if !options.animate {
        return;
    }
    for (joint, mut transform) in &mut joints {
        *transform = swayed(joint, time.elapsed_secs());
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
