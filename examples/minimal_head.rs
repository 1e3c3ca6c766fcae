//! The least a game needs for hair: the plugin, a head with a groom, a collider for its skull, a light
//! and a camera. Move the head's `Transform` and its hair follows.
//!
//! ```sh
//! cargo run --release --features examples --example minimal_head
//! ```

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;

fn main() {
    App::new()
        .add_plugins((
            // Strands are stepped in parallel on Bevy's compute pool; this gives it every core.
            DefaultPlugins.set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() }),
            HairPlugins::default(),
        ))
        // The groomed style held near the roots, and hair meeting hair (the defaults are the reference
        // mechanics, without either).
        .insert_resource(HairSettings::styled())
        .add_systems(Startup, setup)
        .add_systems(Update, nod)
        .run();
}

fn setup(mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>, mut materials: ResMut<Assets<StandardMaterial>>) {
    // 2 000 wavy strands of human hair over a 10 cm skull; the face (−Z) is left bare.
    let groom = HairGroom { style: HairStyle::Wavy, ..default() };
    let skin = materials.add(Color::srgb(0.85, 0.66, 0.55));
    let head = commands
        .spawn((
            HairHead,
            groom,
            Transform::from_xyz(0.0, 1.6, 0.0),
            Mesh3d(meshes.add(Sphere::new(0.1))),
            MeshMaterial3d(skin),
        ))
        .id();
    // The skull the hair rests on: this head's collider (`HairColliderOf`), moving with it (`ChildOf`).
    commands.spawn((HairCollider::sphere(0.1), HairColliderOf(head), ChildOf(head)));
    commands.spawn((DirectionalLight::default(), Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y)));
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.6, 0.9).looking_at(Vec3::new(0.0, 1.55, 0.0), Vec3::Y),
    ));
}

/// Nods the head, to show the hair following it.
fn nod(time: Res<Time>, mut heads: Query<&mut Transform, With<HairHead>>) {
    for mut transform in &mut heads {
        transform.rotation = Quat::from_rotation_x(0.4 * (2.0 * time.elapsed_secs()).sin());
    }
}
