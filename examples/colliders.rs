//! Colliders: hair rests on a head's own colliders (`HairColliderOf`: a skull, shoulders, a backpack),
//! on shared ones (a floor), and on another head's when a `HairCollisionFilter` includes them. Press C to
//! toggle the wireframes.
//!
//! ```sh
//! cargo run --release --features examples --example colliders
//! ```

use std::f32::consts::FRAC_PI_2;

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, HairPlugins::default()))
        .add_systems(Startup, setup)
        .add_systems(Update, (toggle_wireframes, raise_the_hand))
        .run();
}

/// The hand that lifts the hair: a collider of its own head, which the hair's head includes.
#[derive(Component)]
struct Hand;

fn setup(mut commands: Commands, mut gizmos: ResMut<GizmoConfigStore>) {
    gizmos.config_mut::<HairGizmos>().1.draw_colliders = true;

    // Long hair on a skull (an ellipsoid) and shoulders (a capsule), both this head's colliders.
    let groom = HairGroom { style: HairStyle::Long, strand_count: 1000, ..default() };
    let head = commands.spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    commands.spawn((HairCollider::ellipsoid(Vec3::new(0.078, 0.095, 0.1)), HairColliderOf(head), ChildOf(head)));
    let shoulders = Transform::from_xyz(0.0, 1.36, 0.0).with_rotation(Quat::from_rotation_z(FRAC_PI_2));
    commands.spawn((HairCollider::capsule(0.06, 0.12), shoulders, HairColliderOf(head)));
    // A backpack's top behind the shoulders, a box with rounded edges: the long hair lies on it and
    // drapes over its far edge.
    let backpack = Transform::from_xyz(0.0, 1.29, 0.13);
    commands.spawn((HairCollider::rounded_cuboid(Vec3::new(0.17, 0.05, 0.06), 0.01), backpack, HairColliderOf(head)));

    // A floor with no head: every strand meets it.
    commands.spawn(HairCollider::plane().with_friction(0.6));

    // A second body with a hand: its collider belongs to it, and the first head's hair meets it only
    // because the filter includes it.
    let other = commands.spawn((HairHead, Transform::from_xyz(0.4, 1.2, 0.0))).id();
    commands.spawn((HairCollider::sphere(0.05), HairColliderOf(other), Hand, Transform::from_xyz(0.0, 1.2, -0.25)));
    commands.entity(head).insert(HairCollisionFilter { include: vec![other], exclude: vec![] });

    commands.spawn((DirectionalLight::default(), Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y)));
    commands
        .spawn((Camera3d::default(), Transform::from_xyz(0.8, 1.5, 0.8).looking_at(Vec3::new(0.0, 1.4, 0.0), Vec3::Y)));
}

/// Sweeps the hand up through the hair behind the head and down again.
fn raise_the_hand(time: Res<Time>, mut hands: Query<&mut Transform, With<Hand>>) {
    for mut transform in &mut hands {
        transform.translation.y = 1.35 + 0.25 * (0.8 * time.elapsed_secs()).sin();
        transform.translation.z = 0.16;
    }
}

fn toggle_wireframes(keys: Res<ButtonInput<KeyCode>>, mut gizmos: ResMut<GizmoConfigStore>) {
    if keys.just_pressed(KeyCode::KeyC) {
        let config = gizmos.config_mut::<HairGizmos>().1;
        config.draw_colliders = !config.draw_colliders;
    }
}
