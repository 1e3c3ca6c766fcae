//! A head of simulated hair that you can orbit around and move.
//!
//! ```sh
//! cargo run --release --features egui --example head     # with the live settings panel
//! cargo run --release --features render --example head   # without it
//! ```
//!
//! Drag with the left mouse button to orbit and scroll to zoom. Arrow keys or WASD move the head, Q and E
//! turn it, Space starts or stops its automatic sway. The window title shows the simulation's statistics.
//!
//! With `HAIR_SCREENSHOT=shot.png` in the environment, the example saves a screenshot after three
//! seconds and exits: a way to look at it on a machine with no display (see `shared/visual-check.md`).

use std::f32::consts::TAU;

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_hair_sim::prelude::*;

/// Strands on the head.
const STRANDS: usize = 1500;
/// Edges per strand.
const SEGMENTS: usize = 20;
/// Radius of the head, m.
const HEAD_RADIUS: f32 = 0.1;
/// Length of the hair, m.
const HAIR_LENGTH: f32 = 0.16;
/// Height of the head's centre, m.
const HEAD_HEIGHT: f32 = 1.6;

fn main() {
    let window = Window { title: "bevy_hair_sim".into(), ..default() };
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins.set(WindowPlugin { primary_window: Some(window), ..default() }),
        HairPlugin::default(),
    ));
    #[cfg(feature = "egui")]
    app.add_plugins(HairPanelPlugin);
    app.insert_resource(Time::<Fixed>::from_hz(60.0))
        .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
        .insert_resource(HeadSway { enabled: true, time: 0.0 })
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, (orbit_camera, steer_head, show_statistics, screenshot_and_exit))
        .run();
}

/// The camera's orbit around the head.
#[derive(Component)]
struct Orbit {
    yaw: f32,
    pitch: f32,
    distance: f32,
}

/// Whether the head sways by itself, and for how long it has.
#[derive(Resource)]
struct HeadSway {
    enabled: bool,
    time: f32,
}

/// Where the player has moved the head (the sway is added on top).
#[derive(Component, Default)]
struct HeadPlacement {
    position: Vec3,
    heading: f32,
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((Camera3d::default(), Transform::default(), Orbit { yaw: 0.6, pitch: 0.15, distance: 0.9 }));
    commands.spawn((
        DirectionalLight { illuminance: 8000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(6.0, 6.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.25, 0.26, 0.28))),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Capsule3d::new(0.16, 0.9))),
        MeshMaterial3d(materials.add(Color::srgb(0.2, 0.3, 0.45))),
        Transform::from_xyz(0.0, 0.76, 0.0),
    ));

    let skin = materials.add(Color::srgb(0.87, 0.69, 0.58));
    let placement = HeadPlacement { position: Vec3::new(0.0, HEAD_HEIGHT, 0.0), heading: 0.0 };
    commands
        .spawn((
            HairHead,
            Transform::from_translation(placement.position),
            placement,
            Mesh3d(meshes.add(Sphere::new(HEAD_RADIUS).mesh().uv(48, 24))),
            MeshMaterial3d(skin),
        ))
        .with_related_entities::<StrandOf>(|head| {
            for index in 0..STRANDS {
                let (root, normal) = scalp_root(index);
                head.spawn(HairStrand::straight(root, normal, HAIR_LENGTH, SEGMENTS));
            }
        });
}

/// Root position (head-local, m) and outward normal of strand `index`: a golden-angle spiral over the
/// scalp, leaving the face (front, below the brow) bare.
fn scalp_root(index: usize) -> (Vec3, Vec3) {
    let mut candidate = index;
    loop {
        let height = 1.0 - 1.2 * (candidate as f32 + 0.5) / (1.6 * STRANDS as f32);
        let around = candidate as f32 * 2.399_963;
        let ring = (1.0 - height * height).max(0.0).sqrt();
        let normal = Vec3::new(ring * around.sin(), height, ring * around.cos());
        let on_face = normal.z > 0.35 && normal.y < 0.45;
        if !on_face {
            return (HEAD_RADIUS * normal, normal);
        }
        candidate += STRANDS;
    }
}

fn orbit_camera(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    heads: Query<&Transform, (With<HairHead>, Without<Orbit>)>,
    mut cameras: Query<(&mut Transform, &mut Orbit)>,
) {
    let focus = heads.iter().next().map_or(Vec3::new(0.0, HEAD_HEIGHT, 0.0), |head| head.translation);
    for (mut transform, mut orbit) in &mut cameras {
        if buttons.pressed(MouseButton::Left) {
            orbit.yaw -= 0.005 * motion.delta.x;
            orbit.pitch = (orbit.pitch + 0.005 * motion.delta.y).clamp(-1.4, 1.4);
        }
        orbit.distance = (orbit.distance * (1.0 - 0.1 * scroll.delta.y)).clamp(0.3, 5.0);
        let offset = Quat::from_euler(EulerRot::YXZ, orbit.yaw, -orbit.pitch, 0.0) * Vec3::Z * orbit.distance;
        *transform = Transform::from_translation(focus + offset).looking_at(focus, Vec3::Y);
    }
}

fn steer_head(
    time: Res<Time>,
    keys: Res<ButtonInput<KeyCode>>,
    mut sway: ResMut<HeadSway>,
    mut heads: Query<(&mut Transform, &mut HeadPlacement), With<HairHead>>,
) {
    if keys.just_pressed(KeyCode::Space) {
        sway.enabled = !sway.enabled;
    }
    if sway.enabled {
        sway.time += time.delta_secs();
    }
    // −1, 0 or 1 from a pair of key sets.
    let axis = |positive: &[KeyCode], negative: &[KeyCode]| {
        f32::from(u8::from(keys.any_pressed(positive.iter().copied())))
            - f32::from(u8::from(keys.any_pressed(negative.iter().copied())))
    };
    let forward = axis(&[KeyCode::ArrowUp, KeyCode::KeyW], &[KeyCode::ArrowDown, KeyCode::KeyS]);
    let right = axis(&[KeyCode::ArrowRight, KeyCode::KeyD], &[KeyCode::ArrowLeft, KeyCode::KeyA]);
    let turn = axis(&[KeyCode::KeyQ], &[KeyCode::KeyE]);
    let step = time.delta_secs();
    for (mut transform, mut placement) in &mut heads {
        placement.position += 0.6 * step * Vec3::new(right, 0.0, -forward);
        placement.heading += 2.0 * step * turn;
        let phase = TAU * 0.7 * sway.time;
        let sway_offset = Vec3::new(0.12 * phase.sin(), 0.03 * (2.0 * phase).sin(), 0.0);
        let sway_turn = 0.5 * (0.5 * phase).sin();
        transform.translation = placement.position + sway_offset;
        transform.rotation =
            Quat::from_rotation_y(placement.heading + sway_turn) * Quat::from_rotation_z(0.15 * phase.cos());
    }
}

fn show_statistics(
    time: Res<Time>,
    statistics: Res<HairStatistics>,
    mut windows: Query<&mut Window>,
    mut since_update: Local<f32>,
) {
    *since_update += time.delta_secs();
    if *since_update < 0.5 {
        return;
    }
    *since_update = 0.0;
    let title = format!(
        "bevy_hair_sim: {} strands, step {:.1} ms, {:.0} fps, {:.2} Newton iterations, strain {:.1e}, {} faults",
        statistics.strands,
        1e3 * statistics.step_seconds,
        1.0 / time.delta_secs().max(1e-6),
        statistics.mean_newton_iterations,
        statistics.max_strain,
        statistics.faults,
    );
    for mut window in &mut windows {
        window.title.clone_from(&title);
    }
}

fn screenshot_and_exit(
    mut commands: Commands,
    time: Res<Time>,
    mut frames_since_shot: Local<Option<u32>>,
    mut exit: MessageWriter<AppExit>,
) {
    let Ok(path) = std::env::var("HAIR_SCREENSHOT") else {
        return;
    };
    match frames_since_shot.as_mut() {
        None if time.elapsed_secs() > 3.0 => {
            commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path));
            *frames_since_shot = Some(0);
        }
        None => {}
        Some(frames) if *frames > 30 => {
            exit.write(AppExit::Success);
        }
        Some(frames) => *frames += 1,
    }
}
