//! Errors of the mechanics core: invalid input is rejected with a value that says what is wrong.

use bevy::math::DVec3;
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
    /// Two consecutive edges fold back onto each other, where curvature is undefined.
    #[error("edges {edge} and {} fold back onto each other (turning angle of 180°)", edge + 1)]
    FoldedEdges {
        /// Index of the first of the two edges.
        edge: usize,
    },
    /// A material parameter is zero, negative, NaN or infinite.
    #[error("material parameter `{parameter}` must be positive and finite, got {value}")]
    InvalidMaterial {
        /// Name of the parameter.
        parameter: &'static str,
        /// The value that was given.
        value: f64,
    },
    /// A vector that must be finite and not parallel to an edge is not.
    #[error("the material direction {direction} is not finite or is parallel to edge {edge}")]
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

/// Why a time step failed. The rod is restored to its state before the step, at rest.
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
    /// The step produced NaN or infinite values.
    #[error("the step produced a non-finite value at node {node}")]
    NonFinite {
        /// First node with a non-finite position, velocity or twist.
        node: usize,
    },
    /// An edge ended the step stretched or compressed beyond the allowed strain.
    #[error("edge {edge} is strained by {strain:e}, more than the allowed {limit:e}")]
    OverStrained {
        /// The most strained edge.
        edge: usize,
        /// Its strain `|e|/|ē| − 1`.
        strain: f64,
        /// The divergence threshold, [`crate::rod::StepParams::divergence_strain`].
        limit: f64,
    },
}
