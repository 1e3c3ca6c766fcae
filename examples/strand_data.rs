//! Reading and editing a strand's data through queries, headless: its nodes (`StrandNodes`), its edges'
//! material frames (`StrandFrames`), its rest shape (`StrandRestShape`, edited here to curl the strand),
//! and a `StrandSnapshot` to save the strand and resume it exactly.
//!
//! ```sh
//! cargo run --example strand_data
//! ```

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;

fn main() {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, bevy::log::LogPlugin::default(), HairPlugins::default()))
        .insert_resource(Time::<Fixed>::from_hz(60.0))
        // Every update advances the clocks by one fixed step (after the first, which starts them).
        .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let strand =
        app.world_mut().spawn((HairStrand::straight(Vec3::new(0.0, 0.1, 0.0), Vec3::Z, 0.2, 16), StrandOf(head))).id();
    for _ in 0..60 {
        app.update();
    }

    // Read: node positions (m, world space) and the tip's material frame.
    let mut strands = app.world_mut().query::<(&StrandNodes, &StrandFrames)>();
    let (nodes, frames) = strands.get(app.world(), strand).unwrap();
    let tip_frame = frames.material_frame(frames.tangents.len() - 1).unwrap();
    println!("after 1 s the tip hangs at {:.3} m; its edge points along {:.2}", nodes.positions[16], tip_frame.tangent);

    // Save it, to come back to this moment.
    let mut saveable = app.world_mut().query::<StrandSnapshotData>();
    let saved = StrandSnapshot::of(saveable.get(app.world(), strand).unwrap());

    // Edit: give every vertex a rest turn of 0.3 rad along κ₁; the next steps curl the strand up.
    let mut rest_shapes = app.world_mut().query::<&mut StrandRestShape>();
    let mut rest_shape = rest_shapes.get_mut(app.world_mut(), strand).unwrap();
    let curvature = 2.0 * (0.5_f32 * 0.3).tan();
    let vertices = rest_shape.curvatures.len() - 1;
    for vertex in 1..vertices {
        rest_shape.curvatures[vertex] = Vec2::new(curvature, 0.0);
    }
    for _ in 0..120 {
        app.update();
    }
    let curled = app.world().get::<StrandNodes>(strand).unwrap().positions[16];
    println!("curled, the tip is at {curled:.3} m");

    // Restore: the strand is back as it was saved, straight rest shape included.
    app.world_mut().entity_mut(strand).insert(saved);
    for _ in 0..120 {
        app.update();
    }
    let restored = app.world().get::<StrandNodes>(strand).unwrap().positions[16];
    println!("restored and stepped on, the tip hangs at {restored:.3} m again");
}
