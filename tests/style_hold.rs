//! Holding hair in its groomed style (`HairSettings::style_hold`): the held hair's rest under its weight
//! against the relaxation's own balance, for both integrators, and a hair on a moving head against the
//! same hair unheld.

mod common;

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::Integrator;
use common::headless::{DT, hair_app};

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

/// How far each node of a soft hair (E = G = 100 Pa: its own stiffness holds nothing) held at `rate` over
/// its whole length rests below its groomed place after 3 s, m.
fn held_sags(integrator: Integrator, rate: f32) -> Vec<f32> {
    let soft = RodMaterial { youngs_modulus: 100.0, shear_modulus: 100.0, ..RodMaterial::human_hair() };
    let (mut app, _, strand) = held_hair(integrator, rate, 1.0, soft);
    for _ in 0..180 {
        app.update();
    }
    app.world().get::<StrandNodes>(strand).unwrap().positions.iter().map(|p| 1.6 - p.y).collect()
}

#[test]
fn a_held_hair_rests_where_the_hold_balances_its_weight() {
    let (g, rate) = (9.81_f64, 200.0);
    let share_at_root = 1.0 - (-f64::from(rate) * DT).exp();
    let euler = held_sags(Integrator::BackwardEuler, rate);
    let bdf2 = held_sags(Integrator::Bdf2, rate);
    // Alone, a node held with `Δv = a ((x̄ − x)/Δt − v)` rests where the change balances what its weight
    // adds in a step: `g Δt² / a` below its place (with either integrator: the change moves BDF2's history
    // with it). Near the clamped root the tilted first edges lift the nodes; towards the tip, where the
    // hold fades, the hanging rest pulls them down; in between each node rests as if alone.
    for node in 4..=7 {
        let along = node as f64 / 16.0;
        let share = share_at_root * (1.0 - along * along * (3.0 - 2.0 * along));
        let alone = g * DT * DT / share;
        let (e, b) = (f64::from(euler[node]), f64::from(bdf2[node]));
        println!("node {node}: backward Euler {e:.3e} m, BDF2 {b:.3e} m, a node alone {alone:.3e} m");
        assert!((e / alone - 1.0).abs() < 0.05, "node {node}: {e} m, alone {alone} m");
        assert!((b / e - 1.0).abs() < 0.02, "node {node}: BDF2 {b} m, backward Euler {e} m");
    }
    // Unheld, the same hair hangs.
    let unheld = held_sags(Integrator::Bdf2, 0.0);
    assert!(unheld[16] > 0.15, "the unheld tip is {} m down", unheld[16]);
    assert!(bdf2[8] < 0.02, "the held middle is {} m down", bdf2[8]);
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
