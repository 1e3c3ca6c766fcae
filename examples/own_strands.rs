//! Strands of your own instead of a groom: any curve you give is a strand's rest shape, in its head's
//! local space. Here a fringe of straight strands, a row of helical curls and a braid-like pair of
//! strands with their own material, on a head that turns.
//!
//! ```sh
//! cargo run --release --features examples --example own_strands
//! ```

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, HairPlugins::default()))
        .add_systems(Startup, setup)
        .add_systems(Update, turn)
        .run();
}

fn setup(mut commands: Commands) {
    let head = commands.spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    commands.spawn((HairCollider::sphere(0.1), HairColliderOf(head), ChildOf(head)));

    // A fringe: 40 straight strands, 15 cm in 16 edges, growing forward and down from the brow.
    for i in 0..40 {
        let angle = -0.8 + 1.6 * i as f32 / 39.0;
        let normal = Vec3::new(angle.sin(), 0.5, -angle.cos()).normalize();
        commands.spawn((HairStrand::straight(0.1 * normal, normal, 0.15, 16), StrandOf(head)));
    }

    // Curls: helices of radius 6 mm and pitch 12 mm; the spawned shape is the rest shape, so they keep it.
    for i in 0..12 {
        let around = std::f32::consts::TAU * i as f32 / 12.0;
        let root = 0.1 * Vec3::new(around.cos(), 0.0, around.sin());
        let outward = root.normalize();
        let tangent = Vec3::Y.cross(outward);
        let nodes: Vec<Vec3> = (0..=48)
            .map(|node| {
                let phase = node as f32 * 0.5;
                root + outward * (0.006 * (1.0 - phase.cos())) + tangent * (0.006 * phase.sin())
                    - Vec3::Y * (0.002 * phase)
            })
            .collect();
        commands.spawn((HairStrand::from_nodes(nodes, outward), StrandOf(head)));
    }

    // Two thick, stiff strands (1 mm fibres, like a horse's tail hair), curling at 10 per metre.
    let stiff = RodMaterial::round(0.5e-3, 5e9, 0.4, 1300.0);
    for side in [-1.0_f32, 1.0] {
        let root = Vec3::new(0.03 * side, 0.09, 0.04);
        let strand = HairStrand::straight(root, Vec3::new(0.2 * side, 1.0, 0.3), 0.25, 24)
            .with_material(stiff)
            .with_natural_curvature(Vec2::new(10.0, 0.0));
        commands.spawn((strand, StrandOf(head)));
    }

    commands.spawn((DirectionalLight::default(), Transform::from_xyz(1.0, 3.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y)));
    commands
        .spawn((Camera3d::default(), Transform::from_xyz(0.0, 1.6, 0.8).looking_at(Vec3::new(0.0, 1.5, 0.0), Vec3::Y)));
}

/// Turns the head back and forth about the vertical.
fn turn(time: Res<Time>, mut heads: Query<&mut Transform, With<HairHead>>) {
    for mut transform in &mut heads {
        transform.rotation = Quat::from_rotation_y(0.8 * time.elapsed_secs().sin());
    }
}
