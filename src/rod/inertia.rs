//! The Newton system's inertia, air drag, anchors and applied forces, for one strand (`f64`) or a
//! lockstep batch's strands (`Lanes`), from one source: what [`add_inertia_terms`] reads comes through
//! [`InertiaSource`], and every lane does the scalar path's operations in the same order.

use super::banded::BandedMatrix;
use super::energy::{BANDWIDTH, node_dof, twist_dof};
use super::lanes::{Real, Vector, matrix3};
use super::params::StepParams;

/// A node's [`Anchor`](super::Anchor) as the inertia terms read it.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct NodeAnchor<T> {
    pub target: Vector<T>,
    pub target_velocity: Vector<T>,
    pub stiffness: T,
    pub damping: T,
}

/// What the inertia terms read of a strand, or of every strand of a lockstep batch lane by lane: the
/// step's scheme (see `Scheme` in the solver), the state at the step's start, the iterate, the loads.
/// A batch answers `Some` for a load when any of its strands has it (zero in the others).
pub(crate) trait InertiaSource<T: Real> {
    /// Number of nodes.
    fn node_count(&self) -> usize;
    /// The scheme's step `h`, s.
    fn scheme_step(&self) -> T;
    /// A node's mass, kg.
    fn mass(&self, node: usize) -> T;
    /// A node's position in the current iterate, m.
    fn position(&self, node: usize) -> Vector<T>;
    /// The scheme's `x̂` of a node, m.
    fn predicted_position(&self, node: usize) -> Vector<T>;
    /// The scheme's `v̂` of a node, m/s.
    fn predicted_velocity(&self, node: usize) -> Vector<T>;
    /// An edge's unit tangent at the step's start.
    fn start_tangent(&self, edge: usize) -> Vector<T>;
    /// The applied force on a node, N, if any.
    fn force(&self, node: usize) -> Option<Vector<T>>;
    /// The air's velocity at a node, m/s, if not still.
    fn air_velocity(&self, node: usize) -> Option<Vector<T>>;
    /// A node's anchor, if any.
    fn anchor(&self, node: usize) -> Option<NodeAnchor<T>>;
    /// An edge's spin inertia `J`, kg·m².
    fn twist_inertia(&self, edge: usize) -> T;
    /// An edge's twist in the current iterate less its twist at the step's start, rad.
    fn twist_change(&self, edge: usize) -> T;
    /// An edge's twist rate at the step's start, rad/s.
    fn start_twist_rate(&self, edge: usize) -> T;
}

/// Inertia `M (q − x̂ − h v̂)/h²` of the nodes and of the edges' spin (see `Scheme` in the solver), the
/// air drag `D (v − u)` with `v = (q − x̂)/h` (see [`StepParams::air_damping`]: `D = m γ [I − (1 − r) t tᵀ]`
/// per node, `t` its tangent at the start of the step, `u` the air's velocity), spin drag `γ J θ̇`, the
/// anchors' springs and dampers `m k (x − x̄) + m c (v − v̄)`, with Hessian `M/h² + D/h + M (K + C/h)`,
/// and the forces: gravity `M g` and the applied ones. Added to `residual` and `matrix`.
#[inline(always)]
pub(crate) fn add_inertia_terms<T: Real>(
    source: &impl InertiaSource<T>,
    params: &StepParams,
    residual: &mut [T],
    matrix: &mut BandedMatrix<BANDWIDTH, T>,
) {
    let (h, gamma) = (source.scheme_step(), T::splat(params.air_damping));
    let (zero, one) = (T::splat(0.0), T::splat(1.0));
    let across = T::splat(1.0 - params.axial_drag_ratio);
    let gravity =
        Vector { x: T::splat(params.gravity.x), y: T::splat(params.gravity.y), z: T::splat(params.gravity.z) };
    let last = source.node_count() - 1;
    for node in 0..=last {
        let mass = source.mass(node);
        let mut force = gravity.scale(mass);
        if let Some(applied) = source.force(node) {
            force = force + applied;
        }
        let offset = source.position(node) - source.predicted_position(node);
        let mut relative_velocity = offset.divide(h);
        if let Some(air) = source.air_velocity(node) {
            relative_velocity = relative_velocity - air;
        }
        // The drag tensor m γ [I − (1 − r) t tᵀ] with the node's tangent, the mean of its edges'
        // (glam's `normalize_or`).
        let tangent = match node {
            0 => source.start_tangent(0),
            n if n == last => source.start_tangent(n - 1),
            n => {
                let (sum, fallback) = (source.start_tangent(n - 1) + source.start_tangent(n), source.start_tangent(n));
                let reciprocal = one / sum.length();
                Vector::select(!reciprocal.not_positive_finite(), sum.scale(reciprocal), fallback)
            }
        };
        let t = tangent.to_array();
        let drag_scale = mass * gamma;
        let drag = matrix3(|row, column| {
            let identity = if row == column { one } else { zero };
            drag_scale * (identity - across * (t[column] * t[row]))
        });
        let v = relative_velocity.to_array();
        let dragged = |row: usize| drag[row][0] * v[0] + drag[row][1] * v[1] + drag[row][2] * v[2];
        let inertia = mass / (h * h);
        let inertial = (offset - source.predicted_velocity(node).scale(h)).scale(inertia);
        let mut residual_node = Vector {
            x: inertial.x + dragged(0) - force.x,
            y: inertial.y + dragged(1) - force.y,
            z: inertial.z + dragged(2) - force.z,
        };
        let mut diagonal = inertia;
        if let Some(anchor) = source.anchor(node) {
            let spring = (source.position(node) - anchor.target).scale(mass * anchor.stiffness);
            let damper = (offset.divide(h) - anchor.target_velocity).scale(mass * anchor.damping);
            residual_node = residual_node + (spring + damper);
            diagonal += mass * (anchor.stiffness + anchor.damping / h);
        }
        let residual_node = residual_node.to_array();
        for row in 0..3 {
            let dof = node_dof(node) + row;
            residual[dof] += residual_node[row];
            for (column, &drag) in drag[row].iter().enumerate().take(row + 1) {
                let diagonal = if row == column { diagonal } else { zero };
                matrix.add_entry(dof, node_dof(node) + column, diagonal + drag / h);
            }
        }
    }
    // The twists by backward Euler (see `Scheme` in the solver).
    let dt = T::splat(params.dt);
    let twist_scale = T::splat(1.0 / (params.dt * params.dt) + params.air_damping / params.dt);
    for edge in 0..last {
        let inertia = source.twist_inertia(edge);
        let change = source.twist_change(edge);
        let dof = twist_dof(edge);
        residual[dof] +=
            inertia / (dt * dt) * (change - dt * source.start_twist_rate(edge)) + gamma * inertia / dt * change;
        matrix.add_entry(dof, dof, inertia * twist_scale);
    }
}
