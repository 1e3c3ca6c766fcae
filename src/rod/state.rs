//! The groups of data a [`crate::rod::Rod`] is made of: its motion ([`RodState`]), its reference frames
//! ([`RodFrames`]), its rest shape ([`RestShape`]), its mass ([`RodInertia`]) and its boundary conditions
//! ([`RodConstraints`]). A step reads the rest shape, inertia and constraints and advances the state and
//! the frames; [`RodSnapshot`] is those two, which is all a step starts from.

use bevy::math::{DVec2, DVec3};
use bevy::reflect::{Reflect, std_traits::ReflectDefault};

use super::copy_into;

/// What a step advances, besides the frames: node positions and velocities, edge twists and their rates.
/// Indexed by node (`n + 1` entries) or by edge (`n`).
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct RodState {
    /// Node positions `x_i`, m.
    pub positions: Vec<DVec3>,
    /// Node velocities, m/s.
    pub velocities: Vec<DVec3>,
    /// Twist angle `θ^i` of each edge's material frame from its reference frame, rad.
    pub twist: Vec<f64>,
    /// `dθ^i/dt` of each edge, rad/s.
    pub twist_rates: Vec<f64>,
    /// Normal force on each node from its colliders at the end of the last step, N: friction's lagged
    /// normal force, so that a node resting since then has friction from its first Newton iteration.
    pub contact_normal_forces: Vec<f64>,
    /// The state the last step started from: the two-step integrator's memory ([`StepHistory`]).
    pub history: StepHistory,
}

/// The nodes' state one step back, `(x, v)ₙ₋₁`, which the two-step integrator
/// ([`crate::rod::Integrator::Bdf2`]) needs besides the current one (the twists are stepped by backward
/// Euler). Its arrays are sized with the rod (indexed by node) and only valid while
/// [`StepHistory::dt`] is positive.
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct StepHistory {
    /// Length of the step that led from this state to the current one, s; 0 when there is none (a new
    /// rod, a reset, a failed step's roll-back, positions written from outside): the next step is then
    /// a one-step (backward Euler) start.
    pub dt: f64,
    /// Node positions, m.
    pub positions: Vec<DVec3>,
    /// Node velocities, m/s.
    pub velocities: Vec<DVec3>,
}

impl StepHistory {
    /// An empty history for a rod of `nodes` nodes, its arrays sized (so that steps never allocate).
    pub(crate) fn empty(nodes: usize) -> Self {
        Self { dt: 0.0, positions: vec![DVec3::ZERO; nodes], velocities: vec![DVec3::ZERO; nodes] }
    }

    /// Records `state`'s positions and velocities as those a step of `dt` s started from.
    pub(crate) fn record(&mut self, state: &RodState, dt: f64) {
        copy_into(&mut self.positions, &state.positions);
        copy_into(&mut self.velocities, &state.velocities);
        self.dt = dt;
    }

    /// Copies `source` into `self`, reusing its memory.
    pub fn copy_from(&mut self, source: &Self) {
        copy_into(&mut self.positions, &source.positions);
        copy_into(&mut self.velocities, &source.velocities);
        self.dt = source.dt;
    }
}

/// Each edge's reference frame, kept adapted to the edge by time-parallel transport (Bergou et al. 2008,
/// §4.2), and the reference twist between consecutive frames. History matters here: the frames a step
/// ends with depend on those it started from.
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct RodFrames {
    /// Unit tangent `t^i` of each edge.
    pub tangents: Vec<DVec3>,
    /// Reference director `u^i` of each edge: unit, perpendicular to its tangent.
    pub reference_directors: Vec<DVec3>,
    /// Reference twist `m_i` at each vertex (integrated, rad; ends unused): the angle between `u^{i−1}`
    /// carried onto edge `i` and `u^i`, continued from step to step so that it does not wrap at ±π.
    pub reference_twist: Vec<f64>,
}

/// The shape a rod has no elastic energy in: rest edge lengths, and the rest curvature and twist of each
/// interior vertex (Bergou et al. 2008, §4.1–4.2). Arrays indexed by vertex have one entry per node, the
/// two ends unused.
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct RestShape {
    /// Rest length `|ē^i|` of each edge, m.
    pub lengths: Vec<f64>,
    /// Voronoi length `l_i = (|ē^{i−1}| + |ē^i|)/2` of each node (half an edge at the ends), m.
    pub voronoi_lengths: Vec<f64>,
    /// Rest material curvature `(κ̄₁, κ̄₂)` of each vertex (integrated, dimensionless).
    pub curvatures: Vec<DVec2>,
    /// Rest twist `τ̄` of each vertex (integrated, rad).
    pub twists: Vec<f64>,
}

/// The rod's lumped mass: what its material's density gives its Voronoi lengths and edges.
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct RodInertia {
    /// Node masses `ρ A l_i`, kg.
    pub masses: Vec<f64>,
    /// Each edge's moment of inertia about its own axis, `ρ J |ē^i|`, kg·m².
    pub twist_inertias: Vec<f64>,
}

/// The rod's boundary conditions: prescribed node positions and clamped edge twists.
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct RodConstraints {
    /// Where each node is held, m; `None` where it is free.
    pub node_targets: Vec<Option<DVec3>>,
    /// The direction each clamped edge's `m1` is turned to; `None` where the twist is free.
    pub twist_targets: Vec<Option<DVec3>>,
}

impl RodConstraints {
    /// Whether edge `edge` moves in a Newton update: not both its nodes held.
    #[inline(always)]
    pub(crate) fn is_edge_free(&self, edge: usize) -> bool {
        self.node_targets[edge].is_none() || self.node_targets[edge + 1].is_none()
    }

    /// The edges whose twist is held (clamped).
    pub(crate) fn clamped_edges(&self) -> impl Iterator<Item = usize> + '_ {
        self.twist_targets.iter().enumerate().filter(|(_, target)| target.is_some()).map(|(edge, _)| edge)
    }
}

/// Everything a step starts from that it changes: the state and the frames. Restoring a snapshot taken
/// after step `k` makes the following steps repeat steps `k + 1, …` bit for bit (with the same inputs).
#[derive(Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct RodSnapshot {
    /// Positions, velocities, twists.
    pub state: RodState,
    /// Reference frames and twists.
    pub frames: RodFrames,
}

impl RodState {
    /// Copies `source` into `self`, reusing its memory (a derived `clone_from` would allocate).
    pub fn copy_from(&mut self, source: &Self) {
        self.copy_motion_from(source);
        self.history.copy_from(&source.history);
    }

    /// Copies everything but the history (what a step's roll-back needs), reusing the memory.
    pub(crate) fn copy_motion_from(&mut self, source: &Self) {
        copy_into(&mut self.positions, &source.positions);
        copy_into(&mut self.velocities, &source.velocities);
        copy_into(&mut self.twist, &source.twist);
        copy_into(&mut self.twist_rates, &source.twist_rates);
        copy_into(&mut self.contact_normal_forces, &source.contact_normal_forces);
    }
}

impl RodFrames {
    /// Copies `source` into `self`, reusing its memory.
    pub fn copy_from(&mut self, source: &Self) {
        copy_into(&mut self.tangents, &source.tangents);
        copy_into(&mut self.reference_directors, &source.reference_directors);
        copy_into(&mut self.reference_twist, &source.reference_twist);
    }
}

impl RodSnapshot {
    /// Number of nodes the snapshot was taken of.
    pub fn node_count(&self) -> usize {
        self.state.positions.len()
    }

    /// Whether every array has the length a rod of `nodes` nodes needs.
    pub(crate) fn fits(&self, nodes: usize) -> bool {
        let (state, frames) = (&self.state, &self.frames);
        let edges = nodes.saturating_sub(1);
        let history = &state.history;
        [
            state.positions.len(),
            state.velocities.len(),
            state.contact_normal_forces.len(),
            frames.reference_twist.len(),
            history.positions.len(),
            history.velocities.len(),
        ]
        .iter()
        .all(|&len| len == nodes)
            && [state.twist.len(), state.twist_rates.len(), frames.tangents.len(), frames.reference_directors.len()]
                .iter()
                .all(|&len| len == edges)
    }
}
