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
