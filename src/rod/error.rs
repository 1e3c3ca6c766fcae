//! Errors of the mechanics core: invalid input is rejected with a value that says what is wrong.

use bevy::math::{DQuat, DVec3};
use thiserror::Error;

/// Why a rod, a material or a boundary condition was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RodError {
    /// A rod needs at least two edges (three nodes) to bend.
    #[error("a rod needs at least 3 nodes (2 edges), got {nodes} nodes")]
    TooFewNodes {
        /// Number of nodes that were given.
        nodes: usize,
    },
    /// A node position has a NaN or infinite coordinate.
    #[error("node {node} is not finite: {position}")]
    NonFiniteNode {
        /// Index of the offending node.
        node: usize,
        /// The position that was given, m.
        position: DVec3,
    },
    /// Two consecutive nodes coincide (or nearly so).
    #[error("edge {edge} has length {length:e} m; edges must be longer than {minimum:e} m")]
    DegenerateEdge {
        /// Index of the offending edge (between nodes `edge` and `edge + 1`).
        edge: usize,
        /// Its length, m.
        length: f64,
        /// The shortest accepted length, m.
        minimum: f64,
    },
    /// Two consecutive edges turn by more than [`crate::rod::MAX_TURNING_ANGLE`]: folded (nearly) back
    /// onto each other, where curvature is undefined and the implicit system cannot be solved.
    #[error("edges {edge} and {} fold back onto each other (they turn by more than the largest turning angle a rod steps, MAX_TURNING_ANGLE)", edge + 1)]
    FoldedEdges {
        /// Index of the first of the two edges.
        edge: usize,
    },
    /// A rest curvature or rest twist is NaN or infinite.
    #[error("the rest {what} at vertex {vertex} is not finite")]
    NonFiniteRestShape {
        /// "curvature", "twist" or "natural curvature".
        what: &'static str,
        /// The interior vertex it was meant for (0 for a natural curvature, which applies to all).
        vertex: usize,
    },
    /// A rest curvature that asks two edges to turn by more than [`crate::rod::MAX_TURNING_ANGLE`] (an
    /// integrated curvature `2 tan(φ/2)` above 22.9): a kink, where the edges nearly fold back.
    #[error(
        "the rest curvature at vertex {vertex} turns its edges by {turning_degrees:.1}°, more than the {limit_degrees}° a rod can bend between two edges"
    )]
    RestCurvatureTooLarge {
        /// The interior vertex (for a natural curvature: the first vertex where it is too large).
        vertex: usize,
        /// The turning angle asked for, degrees (for a natural curvature `|k| l_i`, which can exceed 180°).
        turning_degrees: f64,
        /// The largest turning angle, degrees.
        limit_degrees: f64,
    },
    /// A rest twist so large that the twisting energy `GJ (τ − τ̄)² / 2l` would overflow.
    #[error("the rest twist {twist} rad at vertex {vertex} is beyond ±{limit} rad")]
    RestTwistTooLarge {
        /// The interior vertex.
        vertex: usize,
        /// The rest twist asked for, rad.
        twist: f64,
        /// The largest rest twist in magnitude, [`crate::rod::MAX_REST_TWIST`], rad.
        limit: f64,
    },
    /// A rotation that is not a finite unit quaternion (it would scale the rod).
    #[error("the rotation {rotation} is not a finite unit quaternion (length {length})")]
    InvalidRotation {
        /// The rotation that was given.
        rotation: DQuat,
        /// Its length.
        length: f64,
    },
    /// A material parameter is NaN or outside its range ([`crate::rod::MATERIAL_RANGES`]).
    #[error("material parameter `{parameter}` must be finite, from {low:e} to {high:e} {unit}, got {value}")]
    InvalidMaterial {
        /// Name of the parameter.
        parameter: &'static str,
        /// The value that was given.
        value: f64,
        /// The smallest value allowed.
        low: f64,
        /// The largest value allowed.
        high: f64,
        /// The parameter's unit.
        unit: &'static str,
    },
    /// A material direction that is zero, not finite, or lies within
    /// [`crate::rod::MIN_MATERIAL_DIRECTION_ANGLE`] of its edge (where `m1` would come from rounding).
    #[error(
        "the material direction {direction} is zero, not finite, or within MIN_MATERIAL_DIRECTION_ANGLE (1e-3 rad) of edge {edge}"
    )]
    InvalidMaterialDirection {
        /// The edge the direction was meant for.
        edge: usize,
        /// The direction that was given.
        direction: DVec3,
    },
    /// A boundary-condition target is NaN or infinite.
    #[error("the target {target} for node {node} is not finite")]
    NonFiniteTarget {
        /// The node the target was meant for.
        node: usize,
        /// The target position that was given, m.
        target: DVec3,
    },
    /// An external force is NaN or infinite.
    #[error("the external force {force} on node {node} is not finite")]
    NonFiniteForce {
        /// The node the force acts on.
        node: usize,
        /// The force that was given, N.
        force: DVec3,
    },
    /// An air velocity (wind) is NaN or infinite.
    #[error("the air velocity {velocity} at node {node} is not finite")]
    NonFiniteAirVelocity {
        /// The node the air velocity was given for.
        node: usize,
        /// The velocity that was given, m/s.
        velocity: DVec3,
    },
    /// A velocity change (an impulse per mass, e.g. from hair–hair interaction) is NaN or infinite.
    #[error("the velocity change {change} at node {node} is not finite")]
    NonFiniteVelocityChange {
        /// The node the change was given for.
        node: usize,
        /// The change that was given, m/s.
        change: DVec3,
    },
    /// An anchor ([`crate::rod::Anchor`]) that is not finite, or has a negative stiffness or damping.
    #[error(
        "the anchor at node {node} (towards {target} moving at {target_velocity} m/s, stiffness {stiffness} 1/s², damping {damping} 1/s) needs finite values and a stiffness and damping not negative"
    )]
    InvalidAnchor {
        /// The node the anchor was given for.
        node: usize,
        /// Where it pulls, m.
        target: DVec3,
        /// How fast that place moves, m/s.
        target_velocity: DVec3,
        /// Its stiffness per unit mass, 1/s².
        stiffness: f64,
        /// Its damping per unit mass, 1/s.
        damping: f64,
    },
    /// A node or edge index past the end of the rod.
    #[error("{what} index {index} is out of range (the rod has {count})")]
    OutOfRange {
        /// "node", "edge" or "vertex".
        what: &'static str,
        /// The index that was given.
        index: usize,
        /// How many there are.
        count: usize,
    },
    /// A per-node array has the wrong length.
    #[error("expected {expected} per-node values, got {actual}")]
    WrongLength {
        /// Number of nodes of the rod.
        expected: usize,
        /// Length of the array that was given.
        actual: usize,
    },
    /// A snapshot restored into a rod it does not fit: another number of nodes, or arrays of the wrong
    /// lengths.
    #[error(
        "the snapshot does not fit this rod of {nodes} nodes (it was taken of {snapshot_nodes} nodes, or is incomplete)"
    )]
    SnapshotMismatch {
        /// Number of nodes of the rod.
        nodes: usize,
        /// Number of node positions in the snapshot.
        snapshot_nodes: usize,
    },
    /// A collider dimension, friction coefficient or pose, or a collision thickness, is invalid.
    #[error(
        "collider parameter `{parameter}` is invalid: {value} (dimensions must be positive and finite, friction and thickness zero or positive, poses finite)"
    )]
    InvalidCollider {
        /// Name of the parameter.
        parameter: &'static str,
        /// The value that was given (NaN for a pose).
        value: f64,
    },
    /// A gravity-preload parameter is out of its valid range.
    #[error("gravity preload parameter `{parameter}` is invalid: {value} ({requirement})")]
    InvalidPreload {
        /// Name of the parameter.
        parameter: &'static str,
        /// The value that was given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// A step parameter is out of its valid range.
    #[error("step parameter `{parameter}` is invalid: {value} ({requirement})")]
    InvalidStepParameter {
        /// Name of the parameter.
        parameter: &'static str,
        /// The value that was given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
}

/// Why a time step failed. The rod is restored to its state before the step, at rest (or, when that state
/// itself was unusable, to its rest pose).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StepError {
    /// The input to the step (parameters or external forces) was invalid; nothing was changed.
    #[error("invalid step input: {0}")]
    InvalidInput(#[from] RodError),
    /// The implicit system was not positive definite (the rod was folded or degenerate).
    #[error("the implicit system is not positive definite at degree of freedom {dof}")]
    NotPositiveDefinite {
        /// Index of the degree of freedom where the factorisation broke down.
        dof: usize,
    },
    /// The rod's state was unusable when the step began: a node position that is not finite, or two
    /// nodes (nearly) on top of each other, written from outside (through [`crate::rod::Rod::positions_mut`]).
    /// The rod was put back in its rest pose (carried onto its clamp, if it has one), at rest.
    #[error("the rod's state at the start of the step was unusable: {reason} at node {node}")]
    UnusableState {
        /// The first offending node.
        node: usize,
        /// What was wrong with it.
        reason: &'static str,
    },
    /// The step produced NaN or infinite values.
    #[error("the step produced a non-finite value at node {node}")]
    NonFinite {
        /// First node with a non-finite position, velocity or twist.
        node: usize,
    },
    /// An edge would end the step stretched or compressed beyond the strain bound,
    /// [`crate::rod::StepParams::strain_bound`], even after the extra projection (boundary conditions that
    /// cannot all be met, such as two pins farther apart than the rod is long).
    #[error("edge {edge} is strained by {strain:e}, more than the allowed {limit:e}")]
    OverStrained {
        /// The most strained edge.
        edge: usize,
        /// Its strain `|e|/|ē| − 1`.
        strain: f64,
        /// The strain bound, [`crate::rod::StepParams::strain_bound`].
        limit: f64,
    },
}
