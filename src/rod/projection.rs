//! Inextensibility by fast projection (Goldenthal et al. 2007), with a Gauss–Seidel fallback.

use bevy::math::DVec3;

use super::copy_into;
use super::curve::Rod;
use super::params::StepParams;

/// Relative weight added to each constraint's own stiffness, dimensionless: consecutive edges folded
/// onto one line make the projection's system singular, and this keeps it definite.
const FOLD_REGULARISATION: f64 = 1e-6;

/// Share of an edge's free mobility, dimensionless, below which the edge counts as held (both ends
/// fixed, or both free to move only across it) and is left as it is.
const HELD_EDGE: f64 = 1e-9;

/// Scratch for the projection's tridiagonal solve.
#[derive(Debug, Clone, Default)]
pub(crate) struct ProjectionScratch {
    pub(crate) diagonal: Vec<f64>,
    pub(crate) upper: Vec<f64>,
    pub(crate) multipliers: Vec<f64>,
    pub(crate) start: Vec<DVec3>,
    pub(crate) target_lengths: Vec<f64>,
    /// `1 / m` of each node, 1/kg, as the projection sees it: zero for prescribed nodes.
    pub(crate) inverse_masses: Vec<f64>,
    /// Outward normal of the collider each node touches, or zero: a touching node moves only along
    /// its collider's tangent plane (which keeps it outside a convex collider).
    pub(crate) contact_normals: Vec<DVec3>,
}

impl ProjectionScratch {
    /// Takes the rod's own inverse masses (zero where a node is prescribed), with no node touching.
    pub(crate) fn use_rod_masses(&mut self, rod: &Rod) {
        self.inverse_masses.clear();
        self.inverse_masses.extend((0..rod.node_count()).map(|node| rod.inverse_mass(node)));
        self.contact_normals.clear();
        self.contact_normals.resize(rod.node_count(), DVec3::ZERO);
    }
}

/// The inverse mass matrix of a node applied to `v`: `w v`, or `w (I − n nᵀ) v` for a node touching a
/// collider with normal `n`.
fn mobility(inverse_mass: f64, contact_normal: DVec3, v: DVec3) -> DVec3 {
    inverse_mass * (v - contact_normal.dot(v) * contact_normal)
}

/// The largest relative difference between an edge's length and its target length.
pub(crate) fn length_error(rod: &Rod, target_lengths: &[f64]) -> f64 {
    rod.state
        .positions
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
    let ProjectionScratch {
        diagonal, upper, multipliers, start, target_lengths, inverse_masses, contact_normals, ..
    } = scratch;
    let moved = |node: usize, v: DVec3| mobility(inverse_masses[node], contact_normals[node], v);
    let mut strain = length_error(rod, target_lengths);
    for iteration in 0..params.max_projection_iterations {
        if strain <= params.strain_tolerance {
            return iteration;
        }
        diagonal.clear();
        upper.clear();
        multipliers.clear();
        for edge in 0..edge_count {
            let e = rod.state.positions[edge + 1] - rod.state.positions[edge];
            let target = target_lengths[edge];
            let stiffness = 4.0 * e.dot(moved(edge, e) + moved(edge + 1, e)) / (target * target);
            let free_stiffness =
                4.0 * e.length_squared() / (target * target) * (inverse_masses[edge] + inverse_masses[edge + 1]);
            // Zero when both ends are held, or when the edge could only lengthen along both normals: such
            // an edge is left as it is, uncoupled from its neighbours.
            if stiffness > HELD_EDGE * free_stiffness {
                // The slight excess keeps the system definite when two edges fold onto one line.
                diagonal.push(stiffness * (1.0 + FOLD_REGULARISATION));
                multipliers.push(e.length_squared() / target - target);
            } else {
                diagonal.push(0.0);
                multipliers.push(0.0);
            }
            if edge + 1 < edge_count {
                let next = rod.state.positions[edge + 2] - rod.state.positions[edge + 1];
                upper.push(-4.0 * e.dot(moved(edge + 1, next)) / (target * target_lengths[edge + 1]));
            }
        }
        for edge in 0..edge_count {
            if diagonal[edge] == 0.0 {
                diagonal[edge] = 1.0;
                if edge > 0 {
                    upper[edge - 1] = 0.0;
                }
                if edge + 1 < edge_count {
                    upper[edge] = 0.0;
                }
            }
        }
        solve_tridiagonal(diagonal, upper, multipliers);

        copy_into(start, &rod.state.positions);
        let mut fraction = 1.0;
        loop {
            for edge in 0..edge_count {
                let e = start[edge + 1] - start[edge];
                let impulse = 2.0 * fraction * multipliers[edge] / target_lengths[edge] * e;
                rod.state.positions[edge] += moved(edge, impulse);
                rod.state.positions[edge + 1] -= moved(edge + 1, impulse);
            }
            let projected = length_error(rod, target_lengths);
            if projected < strain {
                strain = projected;
                break;
            }
            rod.state.positions.copy_from_slice(start);
            if fraction < 0.1 {
                // Too far from the constraints for Newton: exact per-edge projections cannot overshoot.
                gauss_seidel_sweep(rod, target_lengths, inverse_masses, contact_normals);
                strain = length_error(rod, target_lengths);
                break;
            }
            fraction *= 0.5;
        }
    }
    params.max_projection_iterations
}

/// One symmetric Gauss–Seidel sweep (root to tip, then back) of mass-weighted projections of each
/// edge onto its target length (exact for free nodes; to first order along a touching node's tangent
/// plane). Slower than Newton near the constraints but robust far from them.
fn gauss_seidel_sweep(rod: &mut Rod, target_lengths: &[f64], inverse_masses: &[f64], contact_normals: &[DVec3]) {
    let edge_count = rod.edge_count();
    for edge in (0..edge_count).chain((0..edge_count).rev()) {
        let e = rod.state.positions[edge + 1] - rod.state.positions[edge];
        let length = e.length();
        if length == 0.0 {
            continue;
        }
        let direction = e / length;
        let start_move = mobility(inverse_masses[edge], contact_normals[edge], direction);
        let end_move = mobility(inverse_masses[edge + 1], contact_normals[edge + 1], direction);
        let total = direction.dot(start_move + end_move);
        if total <= HELD_EDGE * (inverse_masses[edge] + inverse_masses[edge + 1]) {
            continue;
        }
        let excess = (length - target_lengths[edge]) / total;
        rod.state.positions[edge] += excess * start_move;
        rod.state.positions[edge + 1] -= excess * end_move;
    }
}

/// Solves a symmetric positive-definite tridiagonal system in place (Thomas algorithm): `diagonal`
/// becomes the reciprocals of the eliminated pivots (one division per row, none in the back
/// substitution), `rhs` the solution.
fn solve_tridiagonal(diagonal: &mut [f64], upper: &[f64], rhs: &mut [f64]) {
    let n = diagonal.len();
    diagonal[0] = 1.0 / diagonal[0];
    for row in 1..n {
        let factor = upper[row - 1] * diagonal[row - 1];
        diagonal[row] = 1.0 / (diagonal[row] - factor * upper[row - 1]);
        rhs[row] -= factor * rhs[row - 1];
    }
    rhs[n - 1] *= diagonal[n - 1];
    for row in (0..n - 1).rev() {
        rhs[row] = (rhs[row] - upper[row] * rhs[row + 1]) * diagonal[row];
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
