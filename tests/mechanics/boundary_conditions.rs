//! Pinned nodes and anisotropic cross-sections against analytic results.

use bevy::math::DVec3;
use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};
use hair_sim_support::{max_speed, run, straight_nodes};

/// Catenary parameter `a` of a chain of length `length` hanging between supports `span` apart at the
/// same height: the root of `2 a sinh(span / 2a) = length`, by bisection.
fn catenary_parameter(span: f64, length: f64) -> f64 {
    let (mut low, mut high) = (1e-3, 1e3);
    for _ in 0..200 {
        let middle = 0.5 * (low + high);
        if 2.0 * middle * (span / (2.0 * middle)).sinh() > length { low = middle } else { high = middle }
    }
    0.5 * (low + high)
}

#[test]
fn rope_pinned_at_both_ends_hangs_as_a_catenary() {
    let (length, span, edges) = (1.2, 1.0, 40);
    let start = DVec3::new(-0.5 * length, 0.0, 0.0);
    let nodes: Vec<DVec3> = straight_nodes(length, edges, DVec3::X).into_iter().map(|p| p + start).collect();
    // A soft fibre, so bending stiffness is negligible against the weight: a rope.
    let material = RodMaterial::round(40e-6, 3.5e7, 0.4, 1300.0);
    let mut rope = Rod::new(&nodes, DVec3::Y, material).unwrap();
    let params = StepParams::default();
    let mut workspace = RodWorkspace::default();
    // Bring the two ends together over one second, as two hands would, then let it settle.
    let inward = 0.5 * (length - span);
    for step in 1..=60 {
        let shift = inward * step as f64 / 60.0;
        rope.pin_node(0, nodes[0] + DVec3::X * shift).unwrap();
        rope.pin_node(edges, nodes[edges] - DVec3::X * shift).unwrap();
        run(&mut rope, &params, 1, &mut workspace);
    }
    run(&mut rope, &params, 600, &mut workspace);
    assert!(max_speed(&rope) < 1e-4, "settled: {} m/s", max_speed(&rope));
    assert!((rope.positions()[0] - DVec3::new(-0.5 * span, 0.0, 0.0)).length() < 1e-12, "pins hold exactly");
    assert!((rope.positions()[edges] - DVec3::new(0.5 * span, 0.0, 0.0)).length() < 1e-12);

    let a = catenary_parameter(span, length);
    let expected_sag = a * ((span / (2.0 * a)).cosh() - 1.0);
    let sag = -rope.positions()[edges / 2].y;
    let error = sag / expected_sag - 1.0;
    println!("catenary sag {expected_sag:.5} m, rope sags {sag:.5} m ({:+.3} %)", 100.0 * error);
    assert!(error.abs() < 0.01, "sag off the catenary by {:.3} %", 100.0 * error);
    // Every node lies on the catenary y = a cosh(x/a) − a cosh(span/2a).
    for p in rope.positions() {
        let on_curve = a * (p.x / a).cosh() - a * (span / (2.0 * a)).cosh();
        assert!((p.y - on_curve).abs() < 0.01 * expected_sag, "node {p} off the catenary by {:e} m", p.y - on_curve);
    }
}

/// Static tip deflection (vector) of a horizontal elliptical cantilever whose first material direction
/// on the root edge is `m1`.
fn elliptical_cantilever_tip(m1: DVec3) -> DVec3 {
    let edges = 20;
    let material = RodMaterial { semi_axis_1: 2e-3, semi_axis_2: 1e-3, ..RodMaterial::round(1e-3, 1e10, 0.5, 1000.0) };
    let nodes = straight_nodes(0.2, edges, DVec3::X);
    let mut rod = Rod::new(&nodes, m1, material).unwrap();
    rod.clamp_root_in_place();
    let params = StepParams { air_damping: 5.0, ..Default::default() };
    let mut workspace = RodWorkspace::default();
    run(&mut rod, &params, 600, &mut workspace);
    assert!(max_speed(&rod) < 1e-7);
    rod.positions()[edges] - nodes[edges]
}

#[test]
fn elliptical_section_bends_less_across_its_long_axis() {
    // m1 vertical: gravity bends it towards m1, resisted by EI₁ = Eπa³b/4.
    let stiff_way = elliptical_cantilever_tip(DVec3::Y);
    // m1 horizontal: gravity bends it towards m2, resisted by EI₂ = Eπab³/4, four times less.
    let soft_way = elliptical_cantilever_tip(DVec3::Z);
    let ratio = soft_way.y / stiff_way.y;
    println!("deflections {:.4e} m and {:.4e} m, ratio {ratio:.5} (EI₁/EI₂ = 4)", stiff_way.y, soft_way.y);
    assert!((ratio - 4.0).abs() < 0.02, "deflection ratio {ratio}, expected EI₁/EI₂ = 4");
    assert!(soft_way.z.abs() < 1e-9 && stiff_way.z.abs() < 1e-9, "bending stays in the vertical plane");
}
