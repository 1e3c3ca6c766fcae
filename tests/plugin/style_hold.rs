//! Holding hair in its groomed style (`HairSettings::style_hold`): the mechanics core's anchors (springs
//! inside the implicit step) against their analytic step and rest, the plugin's hold against the core
//! stepped with the documented springs, and held hair on a moving head against the same hair unheld.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::Integrator;
use bevy_hair_sim::simulation::SimulatedStrand;
use hair_sim_support::headless::{DT, hair_app};

/// A head standing at 1.6 m with one hair of 20 cm in 16 edges held out along +X from it, held at `rate`
/// 1/s over `reach` of its length; the app and the hair.
fn held_hair(integrator: Integrator, rate: f32, reach: f32, material: RodMaterial) -> (App, Entity, Entity) {
    let mut app = hair_app();
    {
        let mut settings = app.world_mut().resource_mut::<HairSettings>();
        settings.integrator = integrator;
        settings.style_hold = HairStyleHold { rate, reach };
    }
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let hair = HairStrand::straight(Vec3::new(0.1, 0.0, 0.0), Vec3::X, 0.2, 16).with_material(material);
    let strand = app.world_mut().spawn((hair, StrandOf(head))).id();
    (app, head, strand)
}

#[test]
fn the_hold_ties_each_node_by_a_spring_fading_from_the_root() {
    use bevy_hair_sim::rod::{Anchor, Contacts, RodWorkspace, StepLoads};
    // A soft hair (E = G = 100 Pa: its own stiffness holds nothing) held out from its head at 60/s over
    // its whole length, stepped by the plugin and, from the same state, by the mechanics core with the
    // springs the documentation gives: node i at a fraction s of the length drawn to its groomed place
    // (still: the head does not move) with ω = rate (1 − smoothstep(s)), k = ω², c = 2ω.
    let (rate, steps) = (60.0, 90);
    let soft = RodMaterial { youngs_modulus: 100.0, shear_modulus: 100.0, ..RodMaterial::human_hair() };
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        let (mut app, _, strand) = held_hair(integrator, rate, 1.0, soft);
        app.update();
        let mut rod = app.world().get::<SimulatedStrand>(strand).unwrap().rod().clone();
        // The fixed step as Bevy's clock keeps it (in whole nanoseconds).
        let dt = app.world().resource::<Time<Fixed>>().timestep().as_secs_f64();
        let params = app.world().resource::<HairSettings>().step_params(dt);
        let length: f64 = rod.rest_lengths().iter().sum();
        let mut along = 0.0;
        let anchors: Vec<Anchor> = (0..rod.node_count())
            .map(|node| {
                if node > 0 {
                    along += rod.rest_lengths()[node - 1] / length;
                }
                let fade = 1.0 - along * along * (3.0 - 2.0 * along);
                let frequency = if rod.is_node_prescribed(node) { 0.0 } else { f64::from(rate) * fade };
                let target = rod.initial_positions()[node];
                Anchor { target, stiffness: frequency * frequency, damping: 2.0 * frequency, ..Anchor::default() }
            })
            .collect();
        let mut workspace = RodWorkspace::default();
        let loads = StepLoads { anchors: Some(&anchors), ..StepLoads::default() };
        for _ in 0..steps {
            app.update();
            rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
        }
        let plugin = app.world().get::<SimulatedStrand>(strand).unwrap().rod().positions();
        let worst = plugin.iter().zip(rod.positions()).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
        let sag = 1.6 - plugin[8].y;
        println!("{integrator:?}: plugin and core {worst:e} m apart after {steps} steps; the middle {sag:.4} m down");
        assert!(worst == 0.0, "{integrator:?}: the plugin's hold is not the documented springs ({worst:e} m)");
        // Halfway along, k = (rate/2)²: alone the node would rest g/k down; the hanging tail pulls it lower.
        let alone = 9.81 / (0.5 * f64::from(rate)).powi(2);
        assert!(sag > alone && sag < 0.03, "{integrator:?}: the held middle is {sag} m down (alone {alone} m)");
    }
}

#[test]
fn a_node_held_alone_rests_where_its_spring_carries_its_weight() {
    use bevy::math::DVec3;
    use bevy_hair_sim::rod::{Anchor, Contacts, Rod, RodWorkspace, StepLoads, StepParams};
    // A soft 20 cm hair clamped at its root and held out horizontally, every free node tied to its place
    // by the same spring k: nothing pulls along it, so each node rests where its spring carries its
    // weight, g/k below its place (a static balance, the same for both integrators).
    let nodes: Vec<DVec3> = (0..=16).map(|i| DVec3::new(0.0125 * i as f64, 1.6, 0.0)).collect();
    let soft = RodMaterial { youngs_modulus: 100.0, shear_modulus: 100.0, ..RodMaterial::human_hair() };
    let stiffness = 3600.0;
    let anchors: Vec<Anchor> = nodes.iter().map(|&target| Anchor { target, stiffness, ..Anchor::default() }).collect();
    let alone = 9.81 / stiffness;
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        let params = StepParams { integrator, ..StepParams::default() };
        let mut rod = Rod::new(&nodes, DVec3::Z, soft).unwrap();
        rod.clamp_root_in_place();
        let mut workspace = RodWorkspace::default();
        let loads = StepLoads { anchors: Some(&anchors), ..StepLoads::default() };
        for _ in 0..180 {
            rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
        }
        // Beyond the clamped root edge's reach (it lifts the first nodes: 0.82 and 0.98 of g/k at nodes
        // 2 and 3, decaying along the hair).
        for node in 6..=16 {
            let sag = 1.6 - rod.positions()[node].y;
            assert!((sag / alone - 1.0).abs() < 1e-4, "{integrator:?} node {node}: {sag:e} m, alone {alone:e} m");
        }
        println!(
            "{integrator:?}: the tip rests {:.4e} m down, a node alone {alone:.4e} m",
            1.6 - rod.positions()[16].y
        );
    }
}

#[test]
fn a_held_hair_follows_its_head_and_its_tip_still_trails() {
    // The head moves sideways (along Z) at 0.6 m/s for half a second, without gravity: unheld, the hair
    // trails behind its root; held over half its length, its held half moves with the head.
    let offsets = |rate: f32| {
        let (mut app, head, strand) = held_hair(Integrator::Bdf2, rate, 0.5, RodMaterial::human_hair());
        app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
        for step in 1..=30 {
            app.world_mut().get_mut::<Transform>(head).unwrap().translation.z = 0.01 * step as f32;
            app.update();
        }
        let nodes = &app.world().get::<StrandNodes>(strand).unwrap().positions;
        // Behind the head's 0.3 m, a quarter of the way along (held at half the root's share) and at the tip.
        (0.3 - nodes[4].z, 0.3 - nodes[16].z)
    };
    let (free_middle, free_tip) = offsets(0.0);
    let (held_middle, held_tip) = offsets(200.0);
    println!(
        "behind the head: unheld {free_middle:.4} m a quarter along, {free_tip:.4} m at the tip; held {held_middle:.4}, {held_tip:.4}"
    );
    assert!(free_middle > 0.01, "the unheld hair trails: {free_middle} m");
    assert!(held_middle < 0.4 * free_middle, "held {held_middle} m behind, unheld {free_middle} m");
    assert!(
        held_tip > 0.05 * free_tip && held_tip > 0.0,
        "the held tip does not trail: {held_tip} m (unheld {free_tip} m)"
    );
}

#[test]
fn a_hold_out_of_range_is_refused() {
    for hold in [
        HairStyleHold { rate: -1.0, reach: 0.5 },
        HairStyleHold { rate: 10.0, reach: 1.5 },
        HairStyleHold { rate: f32::NAN, reach: 0.5 },
    ] {
        let error = HairSettings { style_hold: hold, ..default() }.validated(DT).unwrap_err();
        assert!(error.to_string().contains("style_hold"), "{error}");
    }
    assert!(HairSettings { style_hold: HairStyleHold { rate: 20.0, reach: 0.5 }, ..default() }.validated(DT).is_ok());
}

/// The head turned about the vertical as `benchmark coverage` shakes it (±0.7 rad at 1.8 Hz) at `step`.
fn shaken(step: usize) -> Transform {
    let t = step as f32 / 60.0;
    let angle = 0.7 * (std::f32::consts::TAU * 1.8 * t).sin();
    Transform::from_xyz(0.0, 1.6, 0.0).with_rotation(Quat::from_rotation_y(angle))
}

/// A combed groom of 64 guides × 16 edges lying on its skull, shaken for 2 s with the style held as
/// `hold`. Returns the RMS distance from their groomed places (carried with the head) of the nodes an
/// eighth to three eighths of the way along, and of the tips, m.
fn shaken_groom(hold: HairStyleHold) -> (f32, f32) {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().style_hold = hold;
    let groom = HairGroom { strand_count: 64, segments: 16, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, shaken(0))).id();
    let skull =
        (HairCollider::ellipsoid(Scalp::default().semi_axes), Transform::from_translation(Scalp::default().centre));
    app.world_mut().spawn((skull, HairColliderOf(head), ChildOf(head)));
    app.update();
    let strands = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    let to_head = shaken(0).to_matrix().inverse();
    let groomed: Vec<Vec<Vec3>> = strands
        .iter()
        .map(|&strand| {
            let rod = app.world().get::<SimulatedStrand>(strand).unwrap().rod();
            rod.initial_positions().iter().map(|p| to_head.transform_point3(p.as_vec3())).collect()
        })
        .collect();
    let (mut near, mut tips, mut samples) = (0.0_f32, 0.0_f32, 0);
    for step in 1..=120 {
        *app.world_mut().get_mut::<Transform>(head).unwrap() = shaken(step);
        app.update();
        let pose = shaken(step).to_matrix();
        for (strand, groomed) in strands.iter().zip(&groomed) {
            let nodes = &app.world().get::<StrandNodes>(*strand).unwrap().positions;
            let offset = |node: usize| nodes[node].distance_squared(pose.transform_point3(groomed[node]));
            near += (2..=6).map(offset).sum::<f32>() / 5.0;
            tips += offset(16);
        }
        samples += strands.len();
    }
    ((near / samples as f32).sqrt(), (tips / samples as f32).sqrt())
}

#[test]
fn a_held_groom_keeps_its_style_on_a_shaken_head_and_its_tips_swing() {
    let (free_near, free_tips) = shaken_groom(HairStyleHold::default());
    let (held_near, held_tips) = shaken_groom(HairStyleHold { rate: 200.0, ..default() });
    let half = shaken_groom(HairStyleHold { rate: 200.0, reach: 0.5 });
    println!(
        "from the groomed places, near the roots / at the tips: unheld {free_near:.4} / {free_tips:.4} m, held at 200/s {held_near:.4} / {held_tips:.4} m, held over half the length {:.4} / {:.4} m",
        half.0, half.1
    );
    assert!(held_near < 0.25 * free_near, "held {held_near} m from the style, unheld {free_near} m");
    assert!(held_tips > 0.2 * free_tips, "the held tips hardly swing: {held_tips} m, unheld {free_tips} m");
}

#[test]
fn an_anchor_is_a_spring_taken_implicitly_with_the_step() {
    use bevy::math::DVec3;
    use bevy_hair_sim::rod::{Anchor, Contacts, Rod, RodWorkspace, StepLoads, StepParams};
    // A free, straight 10 cm hair at rest in weightless still air, every node anchored a millimetre and a
    // half away, the place still: a uniform pull is a rigid translation, and one implicit step of
    // `m (x − x̂)/h² = −m k (x − x̄) − m c (x − x̂)/h` moves each node by `k / (1/h² + c/h + k)` of the way
    // (h = dt for backward Euler, ⅔ dt for BDF2 after a step at rest). With the place moving at `v̄` and no
    // spring, the damper alone moves it by `c v̄ / (1/h² + c/h)` (as far as `h v̄` for a stiff damper).
    let nodes: Vec<DVec3> = (0..=10).map(|i| DVec3::new(0.01 * i as f64, 0.0, 0.0)).collect();
    let (pull, velocity) = (DVec3::new(0.001, -0.0005, 0.0002), DVec3::new(0.02, 0.01, -0.03));
    let cases = [(2500.0, 0.0, DVec3::ZERO), (2500.0, 100.0, DVec3::ZERO), (0.0, 100.0, velocity)];
    for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
        for (stiffness, damping, target_velocity) in cases {
            let params = StepParams { gravity: DVec3::ZERO, air_damping: 0.0, integrator, ..StepParams::default() };
            let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
            let mut workspace = RodWorkspace::default();
            rod.step(&params, None, &mut workspace).unwrap();
            let anchors: Vec<Anchor> =
                nodes.iter().map(|&node| Anchor { target: node + pull, target_velocity, stiffness, damping }).collect();
            let loads = StepLoads { anchors: Some(&anchors), ..StepLoads::default() };
            rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap();
            let h = if integrator == Integrator::Bdf2 { 2.0 / 3.0 * params.dt } else { params.dt };
            let expected = (stiffness * pull + damping * target_velocity) / (1.0 / (h * h) + damping / h + stiffness);
            for (node, (&after, &start)) in rod.positions().iter().zip(&nodes).enumerate() {
                let moved = after - start;
                assert!(
                    (moved - expected).length() < 1e-12,
                    "{integrator:?} k {stiffness} c {damping}: node {node} moved {moved}, expected {expected}"
                );
            }
        }
    }
    let anchors: Vec<Anchor> =
        nodes.iter().map(|&node| Anchor { target: node + pull, stiffness: 2500.0, ..Anchor::default() }).collect();
    // An anchor that is not finite, or pulls with a negative stiffness, or a list of the wrong length, is
    // refused and changes nothing.
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    let mut workspace = RodWorkspace::default();
    let params = StepParams::default();
    let snapshot = rod.snapshot();
    let mut not_finite = anchors.clone();
    not_finite[3].target.y = f64::NAN;
    let mut negative = anchors.clone();
    negative[5].stiffness = -1.0;
    for (bad, expected) in
        [(&not_finite[..], "anchor at node 3"), (&negative[..], "anchor at node 5"), (&anchors[1..], "")]
    {
        let loads = StepLoads { anchors: Some(bad), ..StepLoads::default() };
        let error = rod.step_with_loads(&params, &loads, &Contacts::NONE, &mut workspace).unwrap_err();
        assert!(error.to_string().contains(expected), "{error}");
        assert_eq!(rod.snapshot(), snapshot);
    }
}
