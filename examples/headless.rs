//! Hair without a window (a server, a test, a tool): `MinimalPlugins`, Bevy's `LogPlugin` to see the
//! plugin's warnings and errors, and a clock that advances one fixed step per update.
//!
//! Bevy's first `update()` only starts its clocks and runs no fixed step; every one after it runs one here.
//!
//! ```sh
//! cargo run --release --example headless
//! ```

use std::time::Duration;

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;

fn main() {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, bevy::log::LogPlugin::default(), HairPlugins::default()))
        .insert_resource(Time::<Fixed>::from_hz(60.0))
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)));
    let groom = HairGroom { strand_count: 500, segments: 16, style: HairStyle::Long, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    app.world_mut().spawn((HairCollider::sphere(0.1), HairColliderOf(head), Transform::from_xyz(0.0, 1.6, 0.0)));
    // A strand that cannot be simulated is rejected with an error line naming it (seen through LogPlugin).
    app.world_mut().spawn(HairStrand::from_nodes(vec![Vec3::ZERO, Vec3::X], Vec3::Y));

    app.update(); // starts the clocks: no fixed step yet
    for second in 1..=3 {
        for _ in 0..60 {
            app.update();
        }
        let statistics = app.world().resource::<HairStatistics>();
        println!(
            "{second} s: {} steps, {} strands, {} nodes touching the skull, {:.2} ms per step",
            statistics.steps,
            statistics.strands,
            statistics.contacts,
            1e3 * statistics.step_seconds
        );
    }
}
