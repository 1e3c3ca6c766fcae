//! Finite-difference checks of every analytic derivative on random strands.

use bevy::math::DVec2;

use super::*;
use crate::rod::test_support::{Lcg, random_strand};

const POSITION_STEP: f64 = 1e-7;
const TWIST_STEP: f64 = 1e-6;
const TOLERANCE: f64 = 1e-5;

/// The rod with unknown `dof` moved by `delta`, reference frames carried along by time-parallel transport.
fn perturbed(rod: &Rod, dof: usize, delta: f64) -> Rod {
    let mut moved = rod.clone();
    if dof % 4 == 3 {
        moved.state.twist[dof / 4] += delta;
    } else {
        moved.state.positions[dof / 4][dof % 4] += delta;
    }
    moved.refresh_frames();
    moved
}

fn step_for(dof: usize) -> f64 {
    if dof % 4 == 3 { TWIST_STEP } else { POSITION_STEP }
}

/// Central difference of `f` along unknown `dof`.
fn central_difference(rod: &Rod, dof: usize, f: impl Fn(&Rod) -> f64) -> f64 {
    let h = step_for(dof);
    (f(&perturbed(rod, dof, h)) - f(&perturbed(rod, dof, -h))) / (2.0 * h)
}

fn analytic_gradient(rod: &Rod) -> Vec<f64> {
    let mut edges = Vec::new();
    edge_geometry(rod, &mut edges);
    let mut gradient = vec![0.0; dof_count(rod.node_count())];
    add_elastic_derivatives(rod, &edges, &mut gradient, None);
    gradient
}

/// The Hessian approximation the integrator assembles for `rod`.
fn assembled_hessian(rod: &Rod) -> RodMatrix {
    let size = dof_count(rod.node_count());
    let mut edges = Vec::new();
    edge_geometry(rod, &mut edges);
    let mut hessian = RodMatrix::default();
    hessian.reset(size);
    add_elastic_derivatives(rod, &edges, &mut vec![0.0; size], Some((&mut hessian, 1.0)));
    hessian
}

/// `‖a − b‖∞ / ‖b‖∞`.
fn relative_error(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// Keeps only one energy mode by zeroing the other stiffnesses.
fn only(mut rod: Rod, mode: &str) -> Rod {
    let stiffness = &mut rod.stiffness;
    if mode != "stretching" {
        stiffness.stretching = 0.0;
    }
    if mode != "bending" {
        stiffness.bending_1 = 0.0;
        stiffness.bending_2 = 0.0;
    }
    if mode != "twisting" {
        stiffness.twisting = 0.0;
    }
    rod
}

#[test]
fn gradient_of_each_energy_matches_finite_differences() {
    let mut random = Lcg(11);
    for trial in 0..4 {
        let base = random_strand(&mut random, 6 + trial);
        for mode in ["stretching", "bending", "twisting"] {
            let rod = only(base.clone(), mode);
            let analytic = analytic_gradient(&rod);
            let numeric: Vec<f64> =
                (0..analytic.len()).map(|dof| central_difference(&rod, dof, |r| r.elastic_energy().total())).collect();
            let error = relative_error(&analytic, &numeric);
            assert!(error < TOLERANCE, "{mode} gradient, trial {trial}: relative error {error:e}");
            assert!(numeric.iter().any(|g| g.abs() > 1e-12), "{mode}: the check is not vacuous");
        }
    }
}

#[test]
fn curvature_and_twist_jacobians_match_finite_differences() {
    let mut random = Lcg(5);
    let rod = random_strand(&mut random, 5);
    let mut edges = Vec::new();
    edge_geometry(&rod, &mut edges);
    for vertex in 1..rod.edge_count() {
        let strain = vertex_strain(&edges[vertex - 1], &edges[vertex], vertex_twist(&rod, vertex));
        let (kappa, tau) = rod.vertex_curvature_and_twist(vertex);
        assert!((DVec2::from(strain.kappa) - kappa).length() < 1e-14 && (strain.twist - tau).abs() < 1e-14);
        let offset = node_dof(vertex - 1);
        type Pick = fn(DVec2, f64) -> f64;
        let quantities: [(&[f64; STENCIL], Pick); 3] =
            [(&strain.grad_kappa_1, |k, _| k.x), (&strain.grad_kappa_2, |k, _| k.y), (&strain.grad_twist, |_, t| t)];
        for (analytic, pick) in quantities {
            let numeric: Vec<f64> = (0..STENCIL)
                .map(|local| {
                    central_difference(&rod, offset + local, |r| {
                        let (k, t) = r.vertex_curvature_and_twist(vertex);
                        pick(k, t)
                    })
                })
                .collect();
            let error = relative_error(analytic, &numeric);
            assert!(error < TOLERANCE, "vertex {vertex}: Jacobian relative error {error:e}");
        }
    }
}

#[test]
fn stretching_hessian_matches_finite_differences_of_the_gradient() {
    let mut random = Lcg(23);
    let mut rod = only(random_strand(&mut random, 5), "stretching");
    // Stretch every edge by 30 %, so the transverse part is not clipped and the Hessian is exact.
    let edges_before: Vec<DVec3> = rod.state.positions.windows(2).map(|pair| pair[1] - pair[0]).collect();
    for (edge, e) in edges_before.iter().enumerate() {
        let rest = rod.rest.lengths[edge];
        rod.state.positions[edge + 1] = rod.state.positions[edge] + 1.3 * rest * e.normalize();
    }
    rod.refresh_frames();
    let size = dof_count(rod.node_count());
    let hessian = assembled_hessian(&rod);
    let mut analytic = vec![0.0; size * size];
    let mut numeric = vec![0.0; size * size];
    for column in 0..size {
        let h = step_for(column);
        let plus = analytic_gradient(&perturbed(&rod, column, h));
        let minus = analytic_gradient(&perturbed(&rod, column, -h));
        for row in 0..size {
            numeric[row * size + column] = (plus[row] - minus[row]) / (2.0 * h);
            if row.abs_diff(column) <= BANDWIDTH {
                analytic[row * size + column] = hessian.get(row.max(column), row.min(column));
            }
        }
    }
    let error = relative_error(&analytic, &numeric);
    assert!(error < TOLERANCE, "stretching Hessian relative error {error:e}");
}

#[test]
fn gauss_newton_hessian_is_the_jacobian_product() {
    // H_GN = Σ ∇κᵀ B ∇κ / l: its quadratic form along a random direction equals Σ B (∇κ·d)² / l,
    // with ∇κ·d measured by finite differences of κ.
    let mut random = Lcg(41);
    let rod = only(random_strand(&mut random, 6), "bending");
    let size = dof_count(rod.node_count());
    let mut hessian = assembled_hessian(&rod);
    let direction: Vec<f64> = (0..size).map(|_| random.next()).collect();
    let mut product = vec![0.0; size];
    hessian.multiply(&direction, &mut product);
    let analytic: f64 = product.iter().zip(&direction).map(|(p, d)| p * d).sum();
    let h = 1e-7;
    let moved = |sign: f64| {
        let mut moved = rod.clone();
        for (dof, d) in direction.iter().enumerate() {
            if dof % 4 == 3 {
                moved.state.twist[dof / 4] += sign * h * d;
            } else {
                moved.state.positions[dof / 4][dof % 4] += sign * h * d;
            }
        }
        moved.refresh_frames();
        moved
    };
    let (plus, minus) = (moved(1.0), moved(-1.0));
    let stiffness = rod.stiffness();
    let numeric: f64 = (1..rod.edge_count())
        .map(|vertex| {
            let rate =
                (plus.vertex_curvature_and_twist(vertex).0 - minus.vertex_curvature_and_twist(vertex).0) / (2.0 * h);
            (stiffness.bending_1 * rate.x * rate.x + stiffness.bending_2 * rate.y * rate.y)
                / rod.rest.voronoi_lengths[vertex]
        })
        .sum();
    assert!((analytic - numeric).abs() < TOLERANCE * numeric.abs(), "{analytic} vs {numeric}");
}
