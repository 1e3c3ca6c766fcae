//! Hair with volume: the grid's velocity smoothing conserves momentum and leaves uniform motion alone
//! ([`VolumeGrid`] directly), a full head of hair rests in a layer of several millimetres instead of one
//! at the collision margin, and long hair swinging past itself keeps its layers (the plugin).

use bevy::math::DVec3;
use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{Contacts, Integrator, Rod, RodMaterial, RodWorkspace, StepLoads, StepParams};
use bevy_hair_sim::simulation::SimulatedStrand;
use bevy_hair_sim::volume::{GridParticle, HairVolumeGrids, VolumeGrid, VolumeParams};
use hair_sim_support::headless::hair_app;

/// The grid's parameters of the tests: 5 mm cells, smoothing at 5/s, target 0.1, 50 Pa, 60 Hz.
fn params() -> VolumeParams {
    VolumeParams { cell_size: 0.005, smoothing_rate: 5.0, target_fraction: 0.1, stiffness: 50.0, dt: 1.0 / 60.0 }
}

/// `count` particles in a 3 cm ball, each moving at `drift` plus a random velocity of up to `spread`
/// m/s, hair-like masses and volumes (packed above the target near the centre), every tenth prescribed.
fn cloud(count: usize, drift: DVec3, spread: f64) -> Vec<GridParticle> {
    let mut random = fastrand::Rng::with_seed(7);
    let mut unit = || DVec3::new(random.f64() - 0.5, random.f64() - 0.5, random.f64() - 0.5) * 2.0;
    (0..count)
        .map(|index| {
            let position = unit() * 0.015 + DVec3::new(0.3, 1.2, -0.1);
            let velocity = drift + unit() * spread;
            let mass = if index % 10 == 0 { 0.0 } else { 2e-7 * (1.0 + unit().x.abs()) };
            GridParticle { position, velocity, mass, volume: 1e-9, groomed_fraction: 0.0 }
        })
        .collect()
}

/// Velocity changes of `particles` from a grid built on them.
fn smoothing_changes(particles: &[GridParticle]) -> Vec<DVec3> {
    let mut grid = VolumeGrid::default();
    grid.build(particles, &params());
    particles.iter().map(|particle| grid.response(particle.position, particle.velocity, 0.0).0).collect()
}

/// A cell that is not a positive length (0, NaN) places an empty grid and ends: coarsening it would never
/// fit the hair.
#[test]
fn a_cell_that_is_not_a_length_places_an_empty_grid() {
    let particles = cloud(500, DVec3::ZERO, 0.5);
    for cell_size in [0.0, -0.005, f64::NAN, f64::INFINITY] {
        let mut grid = VolumeGrid::default();
        grid.build(&particles, &VolumeParams { cell_size, ..params() });
        let (change, force) = grid.response(particles[1].position, particles[1].velocity, 1e-9);
        assert_eq!((grid.max_volume_fraction(), change, force), (0.0, DVec3::ZERO, DVec3::ZERO), "cell {cell_size}");
    }
}

#[test]
fn velocity_smoothing_conserves_momentum_and_narrows_the_velocities_within_cells() {
    let particles = cloud(5000, DVec3::new(0.4, -0.2, 0.1), 0.5);
    let changes = smoothing_changes(&particles);
    let momentum: DVec3 = particles.iter().map(|p| p.mass * p.velocity).sum();
    let change: DVec3 = particles.iter().zip(&changes).map(|(p, dv)| p.mass * *dv).sum();
    let moved: f64 = particles.iter().zip(&changes).map(|(p, dv)| p.mass * dv.length()).sum();
    let scale: f64 = particles.iter().map(|p| p.mass * p.velocity.length()).sum();
    println!("momentum {momentum}, its change {change}; mean |Δv| share {:.3}", moved / scale);
    assert!(change.length() <= 1e-9 * momentum.length(), "momentum changed by {change}");
    assert!(moved > 0.01 * scale, "the smoothing did something: {moved} of {scale}");
    // Spread within each cell (mass-weighted variance about the cell's mean velocity) shrinks.
    let cell = |p: &GridParticle| (p.position / params().cell_size).floor().as_ivec3();
    let spread = |velocity: &dyn Fn(usize) -> DVec3| {
        let mut cells = std::collections::HashMap::<IVec3, (f64, DVec3, f64)>::new();
        for (index, p) in particles.iter().enumerate() {
            let entry = cells.entry(cell(p)).or_default();
            entry.0 += p.mass;
            entry.1 += p.mass * velocity(index);
            entry.2 += p.mass * velocity(index).length_squared();
        }
        cells.values().map(|(m, mv, mvv)| if *m > 0.0 { mvv - mv.length_squared() / m } else { 0.0 }).sum::<f64>()
    };
    let before = spread(&|index| particles[index].velocity);
    let after = spread(&|index| particles[index].velocity + changes[index]);
    println!("spread within cells: {before:.3e} → {after:.3e}");
    assert!(after < 0.97 * before, "the spread within cells narrowed: {before} → {after}");
}

#[test]
fn velocity_smoothing_leaves_uniform_motion_and_free_fall_alone() {
    for velocity in [DVec3::new(1.5, -0.3, 0.7), DVec3::new(0.0, -3.0, 0.0)] {
        let particles = cloud(3000, velocity, 0.0);
        let worst = smoothing_changes(&particles).iter().map(|dv| dv.length()).fold(0.0, f64::max);
        assert!(worst <= 1e-12 * velocity.length(), "{velocity}: a node's velocity changed by {worst}");
    }
}

#[test]
fn a_velocity_change_moves_the_predicted_velocity_by_exactly_itself_in_both_integrators() {
    // A free, straight 10 cm hair at rest in weightless still air: a uniform velocity change is a rigid
    // translation, which the step carries out exactly.
    let nodes: Vec<DVec3> = (0..=10).map(|i| DVec3::new(0.01 * i as f64, 0.0, 0.0)).collect();
    let change = DVec3::new(0.02, -0.05, 0.01);
    let changes = vec![change; nodes.len()];
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        let params = StepParams { gravity: DVec3::ZERO, air_damping: 0.0, integrator, ..StepParams::default() };
        let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
        let mut workspace = RodWorkspace::default();
        // A step at rest first, so that BDF2 has a step to look back on.
        rod.step(&params, None, &mut workspace).unwrap();
        let before = rod.positions().to_vec();
        let loads = StepLoads { velocity_changes: Some(&changes), ..StepLoads::default() };
        rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
        // Backward Euler moves by dt Δv; BDF2 by h Δv = ⅔ dt Δv in its first step after the change.
        let h = if integrator == Integrator::Bdf2 { 2.0 / 3.0 * params.dt } else { params.dt };
        for (node, (&after, &start)) in rod.positions().iter().zip(&before).enumerate() {
            let moved = after - start;
            assert!((moved - h * change).length() < 1e-12, "{integrator:?} node {node} moved {moved}");
            assert!((rod.velocities()[node] - change).length() < 1e-9, "{integrator:?}: {}", rod.velocities()[node]);
        }
    }
    // Prescribed nodes ignore it; a non-finite change is rejected and changes nothing.
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    let mut workspace = RodWorkspace::default();
    let params = StepParams { gravity: DVec3::ZERO, ..StepParams::default() };
    let loads = StepLoads { velocity_changes: Some(&changes), ..StepLoads::default() };
    rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
    assert_eq!(rod.positions()[0], nodes[0]);
    let mut bad = changes.clone();
    bad[4] = DVec3::new(f64::NAN, 0.0, 0.0);
    let snapshot = rod.snapshot();
    let loads = StepLoads { velocity_changes: Some(&bad), ..StepLoads::default() };
    let error = rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap_err();
    assert!(error.to_string().contains("velocity change"), "{error}");
    assert_eq!(rod.snapshot(), snapshot);
}

#[test]
fn pressure_pushes_out_of_hair_packed_beyond_its_target_and_not_below_it() {
    let mut grid = VolumeGrid::default();
    let centre = DVec3::new(0.3, 1.2, -0.1);
    for (volume, packed) in [(1e-9, true), (1e-12, false)] {
        let particles: Vec<GridParticle> =
            cloud(5000, DVec3::ZERO, 0.0).into_iter().map(|p| GridParticle { volume, ..p }).collect();
        grid.build(&particles, &params());
        let outward: f64 = particles
            .iter()
            .map(|p| grid.response(p.position, p.velocity, 1e-10).1.dot((p.position - centre).normalize()))
            .sum();
        println!("max volume fraction {:.3}, outward force {outward:.3e} N", grid.max_volume_fraction());
        if packed {
            assert!(grid.max_volume_fraction() > 2.0 * params().target_fraction);
            assert!(outward > 0.0, "packed hair is pushed outwards: {outward}");
        } else {
            assert!(grid.max_volume_fraction() < params().target_fraction);
            assert_eq!(outward, 0.0, "loose hair feels no pressure");
        }
    }
}

#[test]
fn hair_packed_as_groomed_feels_no_pressure_and_hair_packed_tighter_is_pushed_out() {
    // The packed cloud above, its groomed fraction measured where each particle lies: there the pressure
    // does not push; squeezed to 80 % of its size (about twice as dense), it pushes outwards (less than
    // the same cloud measured against the target alone, which is packed beyond it more).
    let centre = DVec3::new(0.3, 1.2, -0.1);
    let mut grid = VolumeGrid::default();
    let groomed_cloud = cloud(5000, DVec3::ZERO, 0.0);
    grid.build(&groomed_cloud, &params());
    let groomed: Vec<GridParticle> = groomed_cloud
        .iter()
        .map(|p| GridParticle { groomed_fraction: grid.densest_fraction_around(p.position), ..*p })
        .collect();
    let outward = |grid: &VolumeGrid, particles: &[GridParticle]| -> f64 {
        particles
            .iter()
            .map(|p| grid.response(p.position, p.velocity, 1e-10).1.dot((p.position - centre).normalize()))
            .sum()
    };
    let squeeze = |particles: &[GridParticle]| -> Vec<GridParticle> {
        particles.iter().map(|p| GridParticle { position: centre + 0.8 * (p.position - centre), ..*p }).collect()
    };
    let mut pushes = Vec::new();
    for particles in [groomed_cloud.clone(), groomed.clone(), squeeze(&groomed_cloud), squeeze(&groomed)] {
        grid.build(&particles, &params());
        pushes.push(outward(&grid, &particles));
    }
    println!(
        "outward force against the target / the groomed packing: as groomed {:.3e} / {:.3e} N, squeezed {:.3e} / {:.3e} N",
        pushes[0], pushes[1], pushes[2], pushes[3]
    );
    assert!(pushes[1].abs() < 1e-6 * pushes[0], "as groomed, no push: {pushes:?}");
    assert!(pushes[3] > 0.0 && pushes[3] > 1e3 * pushes[1].abs(), "squeezed, it pushes out: {pushes:?}");
}

/// A head at 1.6 m with `groom` on a skull sphere collider of the scalp's size; the grid off or on (its
/// default velocity smoothing, the cells of [`params`]), with the volume pressure of [`params`] or none,
/// measured against the groom's own packing ([`HairVolume::keep_groomed_volume`]) or not.
fn groomed_head(groom: HairGroom, grid: bool, pressure: bool, keep_groomed: bool) -> (App, Entity, Vec<Entity>) {
    let mut app = hair_app();
    let volume = &mut app.world_mut().resource_mut::<HairSettings>().volume;
    volume.enabled = grid;
    volume.stiffness = if pressure { params().stiffness as f32 } else { 0.0 };
    volume.cell_size = params().cell_size as f32;
    volume.keep_groomed_volume = keep_groomed;
    let skull = groom.scalp.semi_axes;
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    app.world_mut().spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), ChildOf(head)));
    app.update();
    app.update();
    let strands = app.world().get::<HeadStrands>(head).expect("hair grew").strands().to_vec();
    (app, head, strands)
}

/// Every node of every strand, world space, strand after strand.
fn nodes(app: &App, strands: &[Entity]) -> Vec<Vec<Vec3>> {
    strands.iter().map(|&entity| app.world().get::<StrandNodes>(entity).unwrap().positions.clone()).collect()
}

/// The `share` quantile of `values`.
fn quantile(mut values: Vec<f32>, share: f32) -> f32 {
    values.sort_by(f32::total_cmp);
    values[((values.len() - 1) as f32 * share) as usize]
}

#[test]
fn a_full_head_of_hair_rests_in_a_layer_with_volume_instead_of_at_the_collision_margin() {
    // 1 000 simulated strands standing for 100 000 hairs, combed onto a 10 cm skull, settled for 2 s, the
    // pressure measured against the target fraction alone.
    let groom = HairGroom { strand_count: 1000, segments: 16, hair_count: 100_000, ..default() };
    let centre = Vec3::new(0.0, 1.6, 0.0);
    let mut thickness = Vec::new();
    for grid in [false, true] {
        let (mut app, head, strands) = groomed_head(groom.clone(), grid, true, false);
        for _ in 0..120 {
            app.update();
        }
        let shape = nodes(&app, &strands);
        let over_the_top = shape.iter().flatten().filter(|node| node.y > centre.y);
        let distances: Vec<f32> = over_the_top.map(|node| node.distance(centre) - 0.1).collect();
        let (median, p90) = (quantile(distances.clone(), 0.5), quantile(distances, 0.9));
        let grids = app.world().resource::<HairVolumeGrids>();
        // The volume fraction where the hair rests: at every free node (the root edge is held).
        let fractions: Vec<f32> = shape
            .iter()
            .flat_map(|strand| &strand[2..])
            .map(|&node| grids.volume_fraction_at(Some(head), node))
            .collect();
        let target = params().target_fraction as f32;
        let (p99, max) = if grid {
            (quantile(fractions.clone(), 0.99) / target, quantile(fractions, 1.0) / target)
        } else {
            (0.0, 0.0)
        };
        println!(
            "grid {grid}: over the top half, nodes {:.2} mm (median) and {:.2} mm (90th percentile) from the skull; \
             volume fraction / target at free nodes: 99th percentile {p99:.2}, max {max:.2}; faults {}",
            1e3 * median,
            1e3 * p90,
            app.world().resource::<HairStatistics>().faults
        );
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
        if grid {
            // Measured 1.56 and 2.19 (1.53 and 1.96 with other rounding in the grid's weights: the settled
            // shape is chaotic in the last bits). The densest places are next to the roots, which cannot
            // move.
            assert!(p99 < 1.7, "the hair rests packed within 1.7 × its target almost everywhere: {p99}");
            assert!(max < 2.5, "and nowhere above 2.5 ×: {max}");
        }
        thickness.push(p90);
    }
    assert!(thickness[0] < 0.002, "without the grid the hair lies in one layer: {} m", thickness[0]);
    assert!(thickness[1] >= 0.003, "with it, a layer at least 3 mm thick: {} m", thickness[1]);
}

#[test]
fn a_combed_groom_keeps_its_shape_under_the_pressure_measured_against_its_own_packing() {
    // The groom above, settled for 2 s with the pressure on: measured against the target alone, its thin
    // layers swell and the combed style moves; against its own packing, it rests as groomed, and hair
    // pressed together beyond that still pushes back (the volume fraction at the nodes stays near the
    // groom's).
    let groom = HairGroom { strand_count: 1000, segments: 16, hair_count: 100_000, ..default() };
    let mut distances = Vec::new();
    for keep_groomed in [false, true] {
        let (mut app, head, strands) = groomed_head(groom.clone(), true, true, keep_groomed);
        let groomed: Vec<Vec<Vec3>> = strands
            .iter()
            .map(|&strand| {
                let rod = app.world().get::<SimulatedStrand>(strand).unwrap().rod();
                rod.initial_positions().iter().map(|node| node.as_vec3()).collect()
            })
            .collect();
        for _ in 0..120 {
            app.update();
        }
        let now = nodes(&app, &strands);
        let squares: Vec<f32> =
            now.iter().flatten().zip(groomed.iter().flatten()).map(|(a, b)| a.distance_squared(*b)).collect();
        let rms = (squares.iter().sum::<f32>() / squares.len() as f32).sqrt();
        let fraction = |shape: &[Vec<Vec3>]| {
            let grids = app.world().resource::<HairVolumeGrids>();
            quantile(
                shape
                    .iter()
                    .flat_map(|strand| &strand[2..])
                    .map(|&node| grids.volume_fraction_at(Some(head), node))
                    .collect(),
                0.99,
            )
        };
        println!(
            "groomed packing at rest {keep_groomed}: {:.2} mm RMS from the groom after 2 s; volume fraction at free nodes, 99th percentile {:.2}; faults {}",
            1e3 * rms,
            fraction(&now),
            app.world().resource::<HairStatistics>().faults
        );
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
        distances.push(rms);
    }
    assert!(distances[0] > 0.002, "against the target alone the groom swells: {} m RMS", distances[0]);
    assert!(distances[1] < 0.002, "against its own packing it rests within 2 mm RMS: {} m", distances[1]);
}

/// Pairs of each strand with its 3 nearest strands (by root), and how many of their nodes (past the root
/// edge) changed sides of each other between `before` and `after`.
fn crossings(before: &[Vec<Vec3>], after: &[Vec<Vec3>]) -> (usize, usize) {
    let (mut crossed, mut pairs) = (0, 0);
    for a in 0..before.len() {
        let mut nearest: Vec<usize> = (0..before.len()).filter(|&b| b != a).collect();
        nearest.sort_by(|&b, &c| before[a][0].distance(before[b][0]).total_cmp(&before[a][0].distance(before[c][0])));
        for &b in &nearest[..3] {
            for node in 2..before[a].len() {
                pairs += 1;
                let was = before[a][node] - before[b][node];
                let is = after[a][node] - after[b][node];
                crossed += usize::from(was.dot(is) < 0.0);
            }
        }
    }
    (crossed, pairs)
}

#[test]
fn long_hair_swinging_past_itself_keeps_its_layers() {
    // 400 long strands (100 000 hairs) settle for 1 s; the head turns 90° in 0.5 s and back, then rests 1 s.
    let groom = HairGroom { strand_count: 400, segments: 16, style: HairStyle::Long, hair_count: 100_000, ..default() };
    let mut counts = Vec::new();
    for (grid, pressure) in [(false, false), (true, false), (true, true)] {
        let (mut app, head, strands) = groomed_head(groom.clone(), grid, pressure, true);
        for _ in 0..60 {
            app.update();
        }
        let before = nodes(&app, &strands);
        for step in 0..60 {
            let turn = std::f32::consts::FRAC_PI_2 * (std::f32::consts::PI * (step + 1) as f32 / 60.0).sin();
            app.world_mut().get_mut::<Transform>(head).unwrap().rotation = Quat::from_rotation_y(turn);
            app.update();
        }
        for _ in 0..60 {
            app.update();
        }
        let (crossed, pairs) = crossings(&before, &nodes(&app, &strands));
        println!("grid {grid}, pressure {pressure}: {crossed} of {pairs} neighbouring node pairs changed sides");
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
        counts.push(crossed);
    }
    // Measured 448, 366 and 314: the smoothing keeps more of the layers, the pressure (against the groom's
    // own packing) a few more; against the target alone it was 1 572, rearranging the groom's thin layers
    // into volume and moving strands past their neighbours.
    assert!(counts[1] < counts[0], "the velocity smoothing keeps more of the layers: {counts:?}");
}

#[test]
fn invalid_volume_settings_are_reported_and_hold_the_hair() {
    let groom = HairGroom { strand_count: 50, segments: 8, ..default() };
    let (mut app, _, strands) = groomed_head(groom, true, true, true);
    app.world_mut().resource_mut::<HairSettings>().volume.cell_size = f32::NAN;
    let before = nodes(&app, &strands);
    for _ in 0..5 {
        app.update();
    }
    let error = app.world().resource::<HairStatistics>().settings_error.clone();
    assert!(error.as_deref().is_some_and(|error| error.contains("volume.cell_size")), "{error:?}");
    // Held: drawn carried with its (still) head, through its head's frame, so equal to single-precision
    // rounding at 1.6 m (a few 1e-7 m).
    let moved = nodes(&app, &strands)
        .iter()
        .flatten()
        .zip(before.iter().flatten())
        .map(|(now, then)| now.distance(*then))
        .fold(0.0, f32::max);
    assert!(moved < 1e-6, "the hair waits for valid settings: a node moved {moved} m");
    app.world_mut().resource_mut::<HairSettings>().volume.cell_size = 0.005;
    app.update();
    assert_eq!(app.world().resource::<HairStatistics>().settings_error, None);
    assert!(nodes(&app, &strands).iter().flatten().all(|node| node.is_finite()));
}
