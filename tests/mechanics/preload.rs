//! Gravity preloading in the mechanics core: a groomed strand keeps its shape under gravity, half a
//! preload sags half-way, and the hair still responds physically when gravity turns.

use bevy::math::DVec3;
use bevy_hair_sim::rod::{
    ColliderShape, Contacts, MovingCollider, RigidPose, Rod, RodMaterial, RodWorkspace, StepParams,
};
use hair_sim_support::run;

/// A 12 cm human hair in 16 edges, clamped at the root: leaving the root sideways (+x), then curving
/// down and forwards along a quarter circle of radius 8 cm.
fn groomed_hair() -> Rod {
    let nodes: Vec<DVec3> = (0..=16)
        .map(|node| {
            let angle = std::f64::consts::FRAC_PI_2 * node as f64 / 16.0;
            DVec3::new(0.08 * angle.sin(), 0.08 * (angle.cos() - 1.0), 0.02 * angle)
        })
        .collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    rod
}

/// Largest distance of a node from where it was groomed after `seconds` under `params`, m.
fn drift(rod: &mut Rod, params: &StepParams, seconds: f64) -> f64 {
    let groomed = rod.positions().to_vec();
    let mut workspace = RodWorkspace::default();
    run(rod, params, (seconds / params.dt).round() as usize, &mut workspace);
    rod.positions().iter().zip(&groomed).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max)
}

#[test]
fn a_preloaded_strand_keeps_its_groomed_shape_and_half_a_preload_sags_half_way() {
    let params = StepParams { dt: 1.0 / 60.0, ..StepParams::default() };
    let supported = vec![None; 17];
    let sag = drift(&mut groomed_hair(), &params, 3.0);

    let mut half = groomed_hair();
    half.preload_for_gravity(params.gravity, &supported, 0.5).unwrap();
    let half_sag = drift(&mut half, &params, 3.0);

    let mut full = groomed_hair();
    let report = full.preload_for_gravity(params.gravity, &supported, 1.0).unwrap();
    let full_sag = drift(&mut full, &params, 3.0);
    println!(
        "largest drift after 3 s: {sag:.4} m without preload, {half_sag:.4} m at 0.5, {full_sag:.2e} m at 1 ({report:?})"
    );

    assert!(sag > 0.02, "without preload the hair sags: {sag} m");
    assert!(full_sag < 1e-4, "preloaded, it holds its shape within 0.1 mm: {full_sag} m");
    assert!(half_sag > 0.2 * sag && half_sag < 0.8 * sag, "half a preload sags part of the way: {half_sag} m");
    assert_eq!(report.bounded_vertices, 0);
}

#[test]
fn a_preloaded_strand_falls_when_gravity_turns_upside_down() {
    let params = StepParams { dt: 1.0 / 60.0, ..StepParams::default() };
    let mut rod = groomed_hair();
    rod.preload_for_gravity(params.gravity, &vec![None; 17], 1.0).unwrap();
    let upside_down = StepParams { gravity: -params.gravity, ..params };
    let moved = drift(&mut rod, &upside_down, 2.0);
    println!("with gravity reversed the preloaded hair moves {moved:.3} m");
    assert!(moved > 0.02, "the rest shape holds the groom only against the gravity it was made for: {moved} m");
}

#[test]
fn a_strand_held_out_too_far_is_bounded_and_sags() {
    // 40 cm held straight out sideways: the root would need rest curls tighter than its edges.
    let nodes: Vec<DVec3> = (0..=16).map(|node| DVec3::new(0.025 * node as f64, 0.0, 0.0)).collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    let params = StepParams { dt: 1.0 / 60.0, ..StepParams::default() };
    let report = rod.preload_for_gravity(params.gravity, &vec![None; 17], 1.0).unwrap();
    println!("{report:?}");
    assert!(report.bounded_vertices > 0);
    let limit = 2.0 * (0.5 * bevy_hair_sim::rod::MAX_PRELOAD_TURN).tan();
    assert!(rod.rest_curvatures().iter().all(|k| k.length() <= limit + 1e-12));
    let sag = drift(&mut rod, &params, 3.0);
    assert!(sag > 0.01 && sag.is_finite(), "it sags to where the bounded rest shape holds it: {sag} m");
}

/// A human hair of `edges` edges, `length` m long, clamped at the root: a root edge of a twentieth of the
/// length along `root_direction`, then the rest along `direction`.
fn hair_leaving(root_direction: DVec3, direction: DVec3, length: f64, edges: usize) -> Rod {
    let edge = length / edges as f64;
    let mut nodes = vec![DVec3::ZERO, root_direction.normalize() * edge];
    for _ in 1..edges {
        let last = *nodes.last().unwrap();
        nodes.push(last + direction.normalize() * edge);
    }
    let mut rod = Rod::new(&nodes, direction.any_orthonormal_vector(), RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    rod
}

/// RMS distance of the rod's nodes from `shape`, m.
fn rms_distance(rod: &Rod, shape: &[DVec3]) -> f64 {
    let squares: f64 = rod.positions().iter().zip(shape).map(|(a, b)| a.distance_squared(*b)).sum();
    (squares / shape.len() as f64).sqrt()
}

/// RMS distance of the nodes from where they start over `seconds` of stepping, checked every tenth of a
/// second: the largest, m.
fn largest_rms_drift(rod: &mut Rod, params: &StepParams, seconds: f64) -> f64 {
    let shape = rod.positions().to_vec();
    let mut workspace = RodWorkspace::default();
    let mut largest = 0.0_f64;
    for _ in 0..(seconds * 10.0).round() as usize {
        run(rod, params, (0.1 / params.dt).round() as usize, &mut workspace);
        largest = largest.max(rms_distance(rod, &shape));
    }
    largest
}

#[test]
fn the_stiffening_to_hold_is_greenhills_number_for_what_does_not_hang_and_more_for_what_is_held_out() {
    let gravity = StepParams::default().gravity;
    let material = RodMaterial::human_hair();
    let bending = material.youngs_modulus * std::f64::consts::PI * material.semi_axis_1.powi(4) / 4.0;
    let weight = material.density * std::f64::consts::PI * material.semi_axis_1.powi(2) * gravity.length();
    let tilted = DVec3::new(0.2, 1.0, 0.0);
    for (direction, label) in
        [(DVec3::Y, "up"), (tilted, "tilted"), (DVec3::X, "sideways"), (DVec3::new(1.0, -0.5, 0.0), "down at 27°")]
    {
        for length in [0.05, 0.2, 0.4] {
            let rod = hair_leaving(direction, direction, length, 20);
            // Past the root edge; Greenhill's 7.837 with a factor of two to spare.
            let free = length * 19.0 / 20.0;
            let expected = (2.0 * weight * free.powi(3) / bending / 7.837).max(1.0);
            let factor = rod.stiffening_to_hold(gravity, &[]);
            assert!((factor / expected - 1.0).abs() < 1e-9, "{label}, {length} m: {factor} against {expected}");
        }
    }
    // 9.5 cm is where human hair buckles upright under its own weight; 5 cm needs nothing.
    assert_eq!(hair_leaving(DVec3::Y, DVec3::Y, 0.05, 20).stiffening_to_hold(gravity, &[]), 1.0);
    // Hanging straight down from a sideways root edge, at any length: held by its tension.
    for length in [0.2, 0.5] {
        assert_eq!(hair_leaving(DVec3::X, DVec3::NEG_Y, length, 20).stiffening_to_hold(gravity, &[]), 1.0);
    }
    // Hanging within 60° of straight down but held out there by its bend at the root, 50 cm: the preload
    // bends the root's rest curl the other way, and unstiffened the strand falls (the next test).
    for direction in [DVec3::new(1.0, -1.0, 0.3), DVec3::new(1.6, -1.0, 0.0)] {
        assert!(hair_leaving(DVec3::X, direction, 0.5, 20).stiffening_to_hold(gravity, &[]) > 4.0, "{direction}");
    }
    // Out past 60° from straight down, it is not hanging.
    assert!(hair_leaving(DVec3::X, DVec3::new(1.8, -1.0, 0.0), 0.5, 20).stiffening_to_hold(gravity, &[]) > 1.0);
    // No gravity: nothing to hold.
    assert_eq!(hair_leaving(DVec3::Y, DVec3::Y, 0.4, 20).stiffening_to_hold(DVec3::ZERO, &[]), 1.0);
}

#[test]
fn a_preloaded_strand_past_the_buckling_length_falls_unless_stiffened_to_hold() {
    let params = StepParams::default();
    // Up and leaning, straight out sideways, and up then curving out: 20 cm of human hair (Greenhill's
    // length is 9.5 cm), 24 edges.
    let shapes = [
        ("leaning up", hair_leaving(DVec3::Y, DVec3::new(0.3, 1.0, 0.1), 0.2, 24)),
        ("sideways", hair_leaving(DVec3::X, DVec3::new(1.0, 0.0, 0.2), 0.2, 24)),
        ("up then out", {
            let nodes: Vec<DVec3> = (0..=24)
                .map(|node| {
                    let angle = std::f64::consts::FRAC_PI_2 * node as f64 / 24.0;
                    DVec3::new(0.127 * (1.0 - angle.cos()), 0.127 * angle.sin(), 0.01 * angle)
                })
                .collect();
            let mut rod = Rod::new(&nodes, DVec3::Z, RodMaterial::human_hair()).unwrap();
            rod.clamp_root_in_place();
            rod
        }),
    ];
    for (label, rod) in shapes {
        let factor = rod.stiffening_to_hold(params.gravity, &[]);
        assert!(factor > 4.0, "{label}: {factor}");
        let mut alone = rod.clone();
        alone.preload_for_gravity(params.gravity, &vec![None; rod.node_count()], 1.0).unwrap();
        let fallen = largest_rms_drift(&mut alone, &params, 4.0);
        let mut stiffened = rod.clone();
        stiffened.set_material(stiffened.material().stiffened(factor)).unwrap();
        stiffened.preload_for_gravity(params.gravity, &vec![None; rod.node_count()], 1.0).unwrap();
        let shape = stiffened.positions().to_vec();
        let held = largest_rms_drift(&mut stiffened, &params, 10.0);
        // Pushed sideways by half its weight for a quarter of a second, then let go: a stable equilibrium
        // takes it back.
        let push = 0.5 * stiffened.stiffness().linear_density * params.gravity.length() * 0.2 / 24.0;
        let forces = vec![DVec3::Z * push; rod.node_count()];
        let mut workspace = RodWorkspace::default();
        for _ in 0..15 {
            stiffened.step(&params, Some(&forces), &mut workspace).unwrap();
        }
        let pushed = rms_distance(&stiffened, &shape);
        run(&mut stiffened, &params, 480, &mut workspace);
        let back = rms_distance(&stiffened, &shape);
        println!(
            "{label}: stiffened ×{factor:.1}; RMS drift preloaded only {:.1} mm in 4 s, stiffened too {:.4} mm in 10 s; pushed {:.1} mm, 8 s later {:.3} mm",
            1e3 * fallen,
            1e3 * held,
            1e3 * pushed,
            1e3 * back
        );
        // An equilibrium that is not stable: the round-off of the first steps grows until the strand falls.
        assert!(fallen > 0.01, "{label}: preloaded only, it stayed within {fallen} m");
        assert!(held < 1e-3, "{label}: stiffened to hold, it moved {held} m RMS");
        assert!(pushed > 2e-3, "{label}: the push moved it {pushed} m RMS");
        assert!(back < 0.1 * pushed && back < 1e-3, "{label}: pushed {pushed} m RMS, {back} m 8 s later");
    }
}

#[test]
fn a_preloaded_strand_held_out_by_its_root_bend_falls_unless_stiffened_to_hold() {
    // Hanging within 60° of the vertical, but held out 58° from it by its bend at the root, 50 cm: the
    // preload bends the root's rest curl the other way, and the strand turns over and falls.
    let params = StepParams::default();
    let rod = hair_leaving(DVec3::X, DVec3::new(1.6, -1.0, 0.0), 0.5, 24);
    let supports = vec![None; rod.node_count()];
    let factor = rod.stiffening_to_hold(params.gravity, &supports);
    let mut alone = rod.clone();
    alone.preload_for_gravity(params.gravity, &supports, 1.0).unwrap();
    let fallen = largest_rms_drift(&mut alone, &params, 4.0);
    let mut stiffened = rod.clone();
    stiffened.set_material(stiffened.material().stiffened(factor)).unwrap();
    stiffened.preload_for_gravity(params.gravity, &supports, 1.0).unwrap();
    let held = largest_rms_drift(&mut stiffened, &params, 10.0);
    println!(
        "held out: stiffened ×{factor:.1}; RMS drift preloaded only {:.1} mm in 4 s, stiffened {:.4} mm in 10 s",
        1e3 * fallen,
        1e3 * held
    );
    assert!(fallen > 0.01, "preloaded only, it stayed within {fallen} m");
    assert!(held < 1e-3, "stiffened to hold, it moved {held} m RMS");
}

#[test]
fn long_hair_lying_over_a_skull_is_held_there_by_its_tension_not_by_rest_curls() {
    // 35 cm of human hair combed from the crown of a 9 cm ball down its side and hanging 21 cm below:
    // frictionless, the ball pushes the hair out and the hanging weight pulls it onto the ball, as a rope
    // over a pulley. The preload leaves that to the support and changes the rest shape little.
    let (radius, thickness, edge) = (0.09, 1e-4, 0.01);
    let lying = radius + thickness;
    let on_ball = (std::f64::consts::FRAC_PI_2 * lying / edge).round() as usize;
    let mut nodes: Vec<DVec3> = (0..=on_ball)
        .map(|node| {
            let angle = std::f64::consts::FRAC_PI_2 * node as f64 / on_ball as f64;
            lying * DVec3::new(angle.sin(), angle.cos(), 0.0)
        })
        .collect();
    let supports: Vec<Option<DVec3>> =
        nodes.iter().enumerate().map(|(node, at)| (node > 0).then(|| at.normalize())).chain(vec![None; 21]).collect();
    for _ in 0..21 {
        nodes.push(*nodes.last().unwrap() - DVec3::Y * edge);
    }
    let mut rod = Rod::new(&nodes, DVec3::Z, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    let params = StepParams::default();
    let present: Vec<f64> = (0..rod.node_count()).map(|vertex| rod.rest_curvatures()[vertex].length()).collect();
    let mut unsupported = rod.clone();
    unsupported.preload_for_gravity(params.gravity, &vec![None; rod.node_count()], 1.0).unwrap();
    let largest_unsupported = unsupported.rest_curvatures().iter().map(|k| k.length()).fold(0.0, f64::max);
    let report = rod.preload_for_gravity(params.gravity, &supports, 1.0).unwrap();
    let largest_rest = rod.rest_curvatures().iter().map(|k| k.length()).fold(0.0, f64::max);
    let largest_present = present.iter().copied().fold(0.0, f64::max);

    let ball = [MovingCollider::fixed(ColliderShape::sphere(radius), 0.0, RigidPose::default())];
    let contacts = Contacts { colliders: &ball, thickness };
    let groomed = rod.positions().to_vec();
    run_with(&mut rod, &params, &contacts, 180, &mut RodWorkspace::default());
    let moved = rod.positions().iter().zip(&groomed).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
    println!(
        "{on_ball} edges on the ball: largest rest curvature {largest_rest:.3} against {largest_present:.3} groomed \
         (integrated; {largest_unsupported:.3} preloaded as if the ball were not there), {report:?}; after 3 s on a \
         frictionless ball the largest move is {:.3} mm",
        1e3 * moved
    );
    assert_eq!(report.bounded_vertices, 0);
    assert!(largest_rest < 1.5 * largest_present, "rest curvature {largest_rest} against {largest_present}");
    assert!(largest_unsupported > 3.0 * largest_present, "unsupported, curls hold it: {largest_unsupported}");
    assert!(moved < 1e-3, "held within 1 mm: moved {moved} m");
}

/// Steps `rod` `steps` times against `contacts`.
fn run_with(rod: &mut Rod, params: &StepParams, contacts: &Contacts, steps: usize, workspace: &mut RodWorkspace) {
    for _ in 0..steps {
        rod.step_with_contacts(params, None, contacts, workspace).unwrap();
    }
}
