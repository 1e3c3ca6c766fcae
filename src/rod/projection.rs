//! Inextensibility by fast projection (Goldenthal et al. 2007), with a Gauss–Seidel fallback.

use bevy::math::DVec3;

use super::curve::Rod;
use super::solver::{StepParams, copy_into};

/// Scratch for the projection's tridiagonal solve.
#[derive(Debug, Clone, Default)]
pub(crate) struct ProjectionScratch {
    pub(crate) diagonal: Vec<f64>,
    pub(crate) upper: Vec<f64>,
    pub(crate) multipliers: Vec<f64>,
    pub(crate) start: Vec<DVec3>,
    pub(crate) target_lengths: Vec<f64>,
    /// `1 / m` of each node, 1/kg, as the projection sees it: zero for prescribed nodes, and for nodes
    /// held by static friction while contacts are resolved.
    pub(crate) inverse_masses: Vec<f64>,
}

impl ProjectionScratch {
    /// Takes the rod's own inverse masses (zero where a node is prescribed).
    pub(crate) fn use_rod_masses(&mut self, rod: &Rod) {
        self.inverse_masses.clear();
        self.inverse_masses.extend((0..rod.node_count()).map(|node| rod.inverse_mass(node)));
    }
}

/// The largest relative difference between an edge's length and its target length.
pub(crate) fn length_error(rod: &Rod, target_lengths: &[f64]) -> f64 {
    rod.positions
        .windows(2)
        .zip(target_lengths)
        .map(|(pair, target)| ((pair[1] - pair[0]).length() / target - 1.0).abs())
        .fold(0.0, f64::max)
}

/// Fast projection onto the length constraints `C_j = e_j·e_j / L_j − L_j = 0`, `L_j` the target lengths
/// (Goldenthal et al. 2007): repeats `x ← x − M⁻¹ ∇Cᵀ λ` with `(∇C M⁻¹ ∇Cᵀ) λ = C`, a tridiagonal
/// system, until every edge is within `strain_tolerance` of its target, with the masses of
/// [`ProjectionScratch::inverse_masses`] (prescribed nodes have infinite mass). Far from the constraints
/// a Newton step can overshoot: it is halved until the largest error drops, and after four halvings
/// replaced by a Gauss–Seidel sweep of exact per-edge projections.
/// Returns the iterations taken.
pub(crate) fn project_edge_lengths(rod: &mut Rod, params: &StepParams, scratch: &mut ProjectionScratch) -> u32 {
    let edge_count = rod.edge_count();
    let ProjectionScratch { diagonal, upper, multipliers, start, target_lengths, inverse_masses } = scratch;
    let mut strain = length_error(rod, target_lengths);
    for iteration in 0..params.max_projection_iterations {
        if strain <= params.strain_tolerance {
            return iteration;
        }
        diagonal.clear();
        upper.clear();
        multipliers.clear();
        for edge in 0..edge_count {
            let e = rod.positions[edge + 1] - rod.positions[edge];
            let target = target_lengths[edge];
            let weight = inverse_masses[edge] + inverse_masses[edge + 1];
            let stiffness = 4.0 * e.length_squared() / (target * target) * weight;
            let constraint = e.length_squared() / target - target;
            if stiffness > 0.0 {
                diagonal.push(stiffness);
                multipliers.push(constraint);
            } else {
                diagonal.push(1.0);
                multipliers.push(0.0);
            }
            if edge + 1 < edge_count {
                let next = rod.positions[edge + 2] - rod.positions[edge + 1];
                let shared = inverse_masses[edge + 1];
                upper.push(-4.0 * shared * e.dot(next) / (target * target_lengths[edge + 1]));
            }
        }
        solve_tridiagonal(diagonal, upper, multipliers);
        copy_into(start, &rod.positions);
        let mut fraction = 1.0;
        loop {
            for edge in 0..edge_count {
                let e = start[edge + 1] - start[edge];
                let impulse = 2.0 * fraction * multipliers[edge] / target_lengths[edge] * e;
                let (start_weight, end_weight) = (inverse_masses[edge], inverse_masses[edge + 1]);
                rod.positions[edge] += start_weight * impulse;
                rod.positions[edge + 1] -= end_weight * impulse;
            }
            let projected = length_error(rod, target_lengths);
            if projected < strain {
                strain = projected;
                break;
            }
            rod.positions.copy_from_slice(start);
            if fraction < 0.1 {
                // Too far from the constraints for Newton: exact per-edge projections cannot overshoot.
                gauss_seidel_sweep(rod, target_lengths, inverse_masses);
                strain = length_error(rod, target_lengths);
                break;
            }
            fraction *= 0.5;
        }
    }
    params.max_projection_iterations
}

/// One symmetric Gauss–Seidel sweep (root to tip, then back) of exact, mass-weighted projections of
/// each edge onto its target length. Slower than Newton near the constraints but robust far from them.
fn gauss_seidel_sweep(rod: &mut Rod, target_lengths: &[f64], inverse_masses: &[f64]) {
    let edge_count = rod.edge_count();
    for edge in (0..edge_count).chain((0..edge_count).rev()) {
        let (start_weight, end_weight) = (inverse_masses[edge], inverse_masses[edge + 1]);
        let total = start_weight + end_weight;
        let e = rod.positions[edge + 1] - rod.positions[edge];
        let length = e.length();
        if total == 0.0 || length == 0.0 {
            continue;
        }
        let correction = (length - target_lengths[edge]) / (length * total) * e;
        rod.positions[edge] += start_weight * correction;
        rod.positions[edge + 1] -= end_weight * correction;
    }
}

/// Solves a symmetric positive-definite tridiagonal system in place (Thomas algorithm): `diagonal` and
/// `upper` are overwritten, `rhs` becomes the solution.
fn solve_tridiagonal(diagonal: &mut [f64], upper: &[f64], rhs: &mut [f64]) {
    let n = diagonal.len();
    for row in 1..n {
        let factor = upper[row - 1] / diagonal[row - 1];
        diagonal[row] -= factor * upper[row - 1];
        rhs[row] -= factor * rhs[row - 1];
    }
    rhs[n - 1] /= diagonal[n - 1];
    for row in (0..n - 1).rev() {
        rhs[row] = (rhs[row] - upper[row] * rhs[row + 1]) / diagonal[row];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tridiagonal_solve_matches_multiplication() {
        let diagonal = [4.0, 5.0, 6.0, 3.0];
        let upper = [1.0, -2.0, 0.5];
        let expected = [1.0, -2.0, 3.0, 0.25];
        let mut rhs: Vec<f64> = (0..4)
            .map(|i| {
                let mut value = diagonal[i] * expected[i];
                if i > 0 {
                    value += upper[i - 1] * expected[i - 1];
                }
                if i < 3 {
                    value += upper[i] * expected[i + 1];
                }
                value
            })
            .collect();
        let mut diagonal = diagonal;
        solve_tridiagonal(&mut diagonal, &upper, &mut rhs);
        for (x, e) in rhs.iter().zip(expected) {
            assert!((x - e).abs() < 1e-14);
        }
    }
}
