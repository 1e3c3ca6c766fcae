//! Hair with volume (issue 20): the grid's velocity smoothing and volume pressure in the plugin.

mod common;

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use common::headless::hair_app;

/// A head at 1.6 m with `groom` on a skull sphere collider of the scalp's size, the grid on or off.
fn groomed_head(groom: HairGroom, grid: bool) -> (App, Entity) {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().volume.enabled = grid;
    if let Ok(cell) = std::env::var("CELL") {
        app.world_mut().resource_mut::<HairSettings>().volume.cell_size = cell.parse().unwrap();
    }
    if let Ok(k) = std::env::var("STIFF") {
        app.world_mut().resource_mut::<HairSettings>().volume.stiffness = k.parse().unwrap();
    }
    let skull = groom.scalp.semi_axes;
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    app.world_mut().spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), Transform::from_xyz(0.0, 1.6, 0.0)));
    app.update();
    (app, head)
}

fn strands_of(app: &App, head: Entity) -> Vec<Entity> {
    app.world().get::<HeadStrands>(head).map(|strands| strands.strands().to_vec()).unwrap_or_default()
}

/// 90th percentile of the distance from the skull (radius 0.1 m at 1.6 m) of the nodes over its top half, m.
fn layer_thickness(app: &App, strands: &[Entity]) -> (f32, f32) {
    let centre = Vec3::new(0.0, 1.6, 0.0);
    let mut distances: Vec<f32> = strands
        .iter()
        .flat_map(|&entity| app.world().get::<StrandNodes>(entity).unwrap().positions.clone())
        .filter(|node| node.y > centre.y)
        .map(|node| node.distance(centre) - 0.1)
        .collect();
    distances.sort_by(f32::total_cmp);
    (distances[distances.len() / 2], distances[distances.len() * 9 / 10])
}

#[test]
fn experiment() {
    for (style, grid) in [(HairStyle::Straight, true), (HairStyle::Long, true)] {
        let groom = HairGroom { strand_count: 1000, segments: 16, style, hair_count: 100_000, ..default() };
        let (mut app, head) = groomed_head(groom, grid);
        app.update();
        let strands = strands_of(&app, head);
        for second in 0..3 {
            for _ in 0..60 {
                app.update();
            }
            let stats = app.world().resource::<HairStatistics>();
            let (median, p90) = layer_thickness(&app, &strands);
            let grids = app.world().resource::<HairVolumeGrids>();
            let mut all: Vec<(f32, usize, Vec3)> = strands
                .iter()
                .flat_map(|&entity| app.world().get::<StrandNodes>(entity).unwrap().positions.clone().into_iter().enumerate())
                .map(|(i, node)| (grids.volume_fraction_at(Some(head), node), i, node))
                .collect();
            all.sort_by(|a, b| b.0.total_cmp(&a.0));
            let max_at_nodes = all[0].0;
            for (phi, i, node) in all.iter().step_by(all.len() / 200).take(8) {
                println!("   φ {phi:.3} node {i} at {:.3?} r {:.1} mm", node - Vec3::new(0.0, 1.6, 0.0), (node.distance(Vec3::new(0.0, 1.6, 0.0)) - 0.1) * 1e3);
            }
            println!(
                "{style:?} grid {grid} t={}s median {:.2} mm p90 {:.2} mm max φ grid {:.3} at nodes {:.3} step {:.1} ms volume {:.2} ms faults {} strain {:.1e}",
                second + 1, median * 1e3, p90 * 1e3, stats.max_volume_fraction, max_at_nodes, stats.step_seconds * 1e3, stats.volume_seconds * 1e3, stats.faults, stats.max_strain
            );
        }
    }
}
