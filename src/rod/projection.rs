//! Inextensibility by fast projection (Goldenthal et al. 2007), with a Gauss–Seidel fallback.

use bevy::math::DVec3;

use super::curve::Rod;
use super::lanes::{LANES, LaneMask, Points, Real, Vector, lanes_in};
use super::params::StepParams;

/// Relative weight added to each constraint's own stiffness, dimensionless: consecutive edges folded
/// onto one line make the projection's system singular, and this keeps it definite.
const FOLD_REGULARISATION: f64 = 1e-6;

/// Share of an edge's free mobility, dimensionless, below which the edge counts as held (both ends
/// fixed, or both free to move only across it) and is left as it is.
const HELD_EDGE: f64 = 1e-9;

/// Scratch for the projection's tridiagonal solve, for one strand (`f64`) or a lockstep batch.
#[derive(Debug, Clone, Default)]
pub(crate) struct TridiagonalScratch<T> {
    diagonal: Vec<T>,
    upper: Vec<T>,
    multipliers: Vec<T>,
    start: Vec<Vector<T>>,
}

/// Scratch for the projection, and what it projects with.
#[derive(Debug, Clone, Default)]
pub(crate) struct ProjectionScratch {
    pub(crate) tridiagonal: TridiagonalScratch<f64>,
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

/// What the projection holds the edges to, for one strand (`f64`) or a lockstep batch's strands.
pub(crate) struct LengthConstraints<'a, T, N: ?Sized> {
    /// The target length of each edge, m.
    pub target_lengths: &'a [T],
    /// `1 / m` of each node, 1/kg (zero: prescribed).
    pub inverse_masses: &'a [T],
    /// The outward normal of the collider each node touches, or zero.
    pub contact_normals: &'a N,
}

impl<T: Real, N: Points<T> + ?Sized> LengthConstraints<'_, T, N> {
    /// The inverse mass matrix of a node applied to `v`: `w v`, or `w (I − n nᵀ) v` for a node touching
    /// a collider with normal `n`.
    #[inline(always)]
    fn mobility(&self, node: usize, v: Vector<T>) -> Vector<T> {
        let normal = self.contact_normals.point(node);
        (v - normal.scale(normal.dot(v))).scale(self.inverse_masses[node])
    }
}

/// The largest relative difference between an edge's length and its target length.
pub(crate) fn length_error(rod: &Rod, target_lengths: &[f64]) -> f64 {
    largest_length_error(&rod.state.positions[..], target_lengths)
}

/// [`length_error`] for one strand's or a batch's points.
#[inline(always)]
fn largest_length_error<T: Real>(points: &(impl Points<T> + ?Sized), target_lengths: &[T]) -> T {
    let one = T::splat(1.0);
    let mut error = T::splat(0.0);
    for (edge, &target) in target_lengths.iter().enumerate() {
        let length = (points.point(edge + 1) - points.point(edge)).length();
        error = error.max((length / target - one).abs());
    }
    error
}

/// Fast projection onto the length constraints `C_j = e_j·e_j / L_j − L_j = 0`, `L_j` the target lengths
/// (Goldenthal et al. 2007): repeats `x ← x − M⁻¹ ∇Cᵀ λ` with `(∇C M⁻¹ ∇Cᵀ) λ = C`, a tridiagonal
/// system, until every edge is within `strain_tolerance` of its target, with the masses of
/// [`ProjectionScratch::inverse_masses`] (prescribed nodes have infinite mass). Far from the constraints
/// a Newton step can overshoot: it is halved until the largest error drops, and after four halvings
/// replaced by a Gauss–Seidel sweep of exact per-edge projections.
/// Returns the iterations taken.
pub(crate) fn project_edge_lengths(rod: &mut Rod, params: &StepParams, scratch: &mut ProjectionScratch) -> u32 {
    let ProjectionScratch { tridiagonal, target_lengths, inverse_masses, contact_normals } = scratch;
    let constraints = LengthConstraints { target_lengths, inverse_masses, contact_normals: &contact_normals[..] };
    project_points(&mut rod.state.positions[..], &constraints, params, tridiagonal, 1)[0]
}

/// [`project_edge_lengths`] for one strand's points or for the lanes `lanes` of a batch's, each lane
/// with the same operations in the same order as the strand alone (a lane that is done is left as it
/// is). Returns the iterations each lane took.
#[inline(always)]
pub(crate) fn project_points<T: Real, N: Points<T> + ?Sized>(
    points: &mut (impl Points<T> + ?Sized),
    constraints: &LengthConstraints<T, N>,
    params: &StepParams,
    scratch: &mut TridiagonalScratch<T>,
    lanes: LaneMask,
) -> [u32; LANES] {
    let edge_count = constraints.target_lengths.len();
    let targets = constraints.target_lengths;
    let TridiagonalScratch { diagonal, upper, multipliers, start } = scratch;
    let (zero, one, two, four) = (T::splat(0.0), T::splat(1.0), T::splat(2.0), T::splat(4.0));
    let moved = |node: usize, v: Vector<T>| constraints.mobility(node, v);
    let mut strain = largest_length_error(points, targets);
    let mut iterations = [params.max_projection_iterations; LANES];
    let mut going = lanes;
    for iteration in 0..params.max_projection_iterations {
        let done = strain.le(T::splat(params.strain_tolerance)) & going;
        for lane in lanes_in(done) {
            iterations[lane] = iteration;
        }
        going &= !done;
        if going == 0 {
            break;
        }
        diagonal.clear();
        upper.clear();
        multipliers.clear();
        for edge in 0..edge_count {
            let e = points.point(edge + 1) - points.point(edge);
            let target = targets[edge];
            let stiffness = four * e.dot(moved(edge, e) + moved(edge + 1, e)) / (target * target);
            let free_stiffness = four * e.dot(e) / (target * target)
                * (constraints.inverse_masses[edge] + constraints.inverse_masses[edge + 1]);
            // Zero when both ends are held, or when the edge could only lengthen along both normals: such
            // an edge is left as it is, uncoupled from its neighbours.
            let coupled = stiffness.gt(T::splat(HELD_EDGE) * free_stiffness);
            // The slight excess keeps the system definite when two edges fold onto one line.
            diagonal.push(T::select(coupled, stiffness * T::splat(1.0 + FOLD_REGULARISATION), zero));
            multipliers.push(T::select(coupled, e.dot(e) / target - target, zero));
            if edge + 1 < edge_count {
                let next = points.point(edge + 2) - points.point(edge + 1);
                upper.push(-four * e.dot(moved(edge + 1, next)) / (target * targets[edge + 1]));
            }
        }
        for edge in 0..edge_count {
            let held = diagonal[edge].eq(zero);
            diagonal[edge] = T::select(held, one, diagonal[edge]);
            if edge > 0 {
                upper[edge - 1] = T::select(held, zero, upper[edge - 1]);
            }
            if edge + 1 < edge_count {
                upper[edge] = T::select(held, zero, upper[edge]);
            }
        }
        solve_tridiagonal(diagonal, upper, multipliers);

        start.clear();
        start.extend((0..=edge_count).map(|node| points.point(node)));
        let mut fraction = one;
        let mut searching = going;
        loop {
            for edge in 0..edge_count {
                let e = start[edge + 1] - start[edge];
                let impulse = e.scale(two * fraction * multipliers[edge] / targets[edge]);
                let (first, second) = (points.point(edge), points.point(edge + 1));
                points.set_point(edge, Vector::select(searching, first + moved(edge, impulse), first));
                points.set_point(edge + 1, Vector::select(searching, second - moved(edge + 1, impulse), second));
            }
            let projected = largest_length_error(points, targets);
            let accepted = projected.lt(strain) & searching;
            strain = T::select(accepted, projected, strain);
            searching &= !accepted;
            if searching == 0 {
                break;
            }
            for (node, &started) in start.iter().enumerate() {
                points.set_point(node, Vector::select(searching, started, points.point(node)));
            }
            // Too far from the constraints for Newton: exact per-edge projections cannot overshoot.
            let stuck = fraction.lt(T::splat(0.1)) & searching;
            if stuck != 0 {
                gauss_seidel_sweep(points, constraints, stuck);
                strain = T::select(stuck, largest_length_error(points, targets), strain);
                searching &= !stuck;
                if searching == 0 {
                    break;
                }
            }
            fraction = T::select(searching, fraction * T::splat(0.5), fraction);
        }
    }
    iterations
}

/// One symmetric Gauss–Seidel sweep (root to tip, then back) of mass-weighted projections of each
/// edge onto its target length (exact for free nodes; to first order along a touching node's tangent
/// plane), in the lanes of `lanes`. Slower than Newton near the constraints but robust far from them.
#[inline(always)]
fn gauss_seidel_sweep<T: Real, N: Points<T> + ?Sized>(
    points: &mut (impl Points<T> + ?Sized),
    constraints: &LengthConstraints<T, N>,
    lanes: LaneMask,
) {
    let edge_count = constraints.target_lengths.len();
    let masses = constraints.inverse_masses;
    for edge in (0..edge_count).chain((0..edge_count).rev()) {
        let (first, second) = (points.point(edge), points.point(edge + 1));
        let e = second - first;
        let length = e.length();
        let direction = e.divide(length);
        let start_move = constraints.mobility(edge, direction);
        let end_move = constraints.mobility(edge + 1, direction);
        let total = direction.dot(start_move + end_move);
        // Left as it is: an edge of no length, or one held at both ends.
        let moving =
            lanes & !length.eq(T::splat(0.0)) & !total.le(T::splat(HELD_EDGE) * (masses[edge] + masses[edge + 1]));
        let excess = (length - constraints.target_lengths[edge]) / total;
        points.set_point(edge, Vector::select(moving, first + start_move.scale(excess), first));
        points.set_point(edge + 1, Vector::select(moving, second - end_move.scale(excess), second));
    }
}

/// Solves a symmetric positive-definite tridiagonal system in place (Thomas algorithm): `diagonal`
/// becomes the reciprocals of the eliminated pivots (one division per row, none in the back
/// substitution), `rhs` the solution.
#[inline(always)]
fn solve_tridiagonal<T: Real>(diagonal: &mut [T], upper: &[T], rhs: &mut [T]) {
    let n = diagonal.len();
    let one = T::splat(1.0);
    diagonal[0] = one / diagonal[0];
    for row in 1..n {
        let factor = upper[row - 1] * diagonal[row - 1];
        diagonal[row] = one / (diagonal[row] - factor * upper[row - 1]);
        let previous = rhs[row - 1];
        rhs[row] -= factor * previous;
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
