//! The discrete framed curve: nodes, edges, reference and material frames, twist, rest state and
//! boundary conditions of one rod.

use bevy::math::{DQuat, DVec2, DVec3};
use bevy::reflect::Reflect;

use super::copy_into;
use super::error::RodError;
use super::frames::{
    carry_reference_frames, material_directors, parallel_transport, perpendicular_unit, signed_angle, wrap_angle,
};
use super::material::{RodMaterial, Stiffness};
use super::state::{RestShape, RodConstraints, RodFrames, RodInertia, RodSnapshot, RodState, StepHistory};

/// Edges shorter than this fraction of the rod's mean edge length are rejected as degenerate.
const MIN_RELATIVE_EDGE_LENGTH: f64 = 1e-6;

/// The largest turning angle between two consecutive edges that a rod is created with or given as rest
/// curvature, rad (170°, an integrated curvature `2 tan(φ/2)` of 22.9): tighter is a kink, not a
/// curl. The curvature and its derivatives grow as `1/(π − φ)` and faster towards a fold, and the step
/// keeps its system solvable there (see [`crate::rod::Rod::step_with_contacts`]), and only a state
/// folded to within 1e-6 rad of π cannot be stepped at all: this leaves room for a rod created at the
/// limit to be bent further by its motion.
pub const MAX_TURNING_ANGLE: f64 = 170.0 * std::f64::consts::PI / 180.0;

/// How close to π a turning angle may come before the state cannot be stepped, rad: the curvature
/// binormal `2 t × t' / (1 + t·t')` then overflows the step's arithmetic.
const FOLDED_STATE_GAP: f64 = 1e-6;

/// The largest rest twist `|τ̄|` of a vertex, rad (a hundred turns between two edges): far beyond any
/// rod's, and far from where the twisting energy would overflow.
pub const MAX_REST_TWIST: f64 = 200.0 * std::f64::consts::PI;

/// The smallest angle between a material direction and its edge, rad: closer to the edge, the director
/// `m1` made perpendicular to it would come from rounding rather than from the direction given.
pub const MIN_MATERIAL_DIRECTION_ANGLE: f64 = 1e-3;

/// How far a rotation's quaternion may be from unit length, dimensionless, before it is rejected as not a
/// rotation (within it, it is normalised).
const ROTATION_LENGTH_TOLERANCE: f64 = 1e-3;

/// The integrated curvature `2 tan(φ/2)` of the largest turning angle [`MAX_TURNING_ANGLE`].
fn max_integrated_curvature() -> f64 {
    2.0 * (0.5 * MAX_TURNING_ANGLE).tan()
}

/// Rejects a rest curvature of `vertex` that is not finite, or whose magnitude `2 tan(φ/2)` asks the
/// edges to turn by more than [`MAX_TURNING_ANGLE`].
fn check_rest_curvature(vertex: usize, curvature: DVec2) -> Result<(), RodError> {
    if !curvature.is_finite() {
        return Err(RodError::NonFiniteRestShape { what: "curvature", vertex });
    }
    if curvature.length() > max_integrated_curvature() {
        return Err(RodError::RestCurvatureTooLarge {
            vertex,
            turning_degrees: (2.0 * (0.5 * curvature.length()).atan()).to_degrees(),
            limit_degrees: MAX_TURNING_ANGLE.to_degrees(),
        });
    }
    Ok(())
}

/// Rejects a rest twist of `vertex` that is not finite or beyond [`MAX_REST_TWIST`].
fn check_rest_twist(vertex: usize, twist: f64) -> Result<(), RodError> {
    if !twist.is_finite() {
        return Err(RodError::NonFiniteRestShape { what: "twist", vertex });
    }
    if twist.abs() > MAX_REST_TWIST {
        return Err(RodError::RestTwistTooLarge { vertex, twist, limit: MAX_REST_TWIST });
    }
    Ok(())
}

/// `direction` made perpendicular to the unit `tangent` and normalised, if it is finite, not zero, and at
/// least [`MIN_MATERIAL_DIRECTION_ANGLE`] away from the tangent's line. The direction is first scaled by
/// its largest component, so that a tiny (even subnormal) direction is judged by its direction alone, and
/// a zero one, which has none, is rejected.
fn material_director(direction: DVec3, tangent: DVec3) -> Option<DVec3> {
    let scaled = scaled_direction(direction)?;
    let perpendicular = scaled - scaled.dot(tangent) * tangent;
    if perpendicular.length() < MIN_MATERIAL_DIRECTION_ANGLE.sin() * scaled.length() {
        return None;
    }
    // From the direction as given when squaring it neither underflows nor overflows (the same bits as
    // ever), else from the scaled one.
    let source = if squares_safely(direction) { direction } else { scaled };
    Some((source - source.dot(tangent) * tangent).normalize())
}

/// `direction` divided by its largest component's magnitude (from 1 to √3 long: no underflow, whatever
/// its scale), if it is finite and not zero.
fn scaled_direction(direction: DVec3) -> Option<DVec3> {
    let largest = direction.abs().max_element();
    (largest.is_finite() && largest > 0.0).then(|| direction / largest)
}

/// Whether `direction`'s squared length is a normal, finite number: its length and projections are then
/// exact to rounding.
fn squares_safely(direction: DVec3) -> bool {
    let squared = direction.length_squared();
    squared.is_finite() && squared >= f64::MIN_POSITIVE
}

/// The first pair of consecutive edges (vectors of any non-zero length) that turn by more than
/// `max_angle` (rad), by the index of the first edge: `a·b < cos(max_angle) |a| |b|`, with no division.
fn first_fold(edges: impl Iterator<Item = DVec3>, max_angle: f64) -> Option<usize> {
    let limit = max_angle.cos();
    let mut previous: Option<(DVec3, f64)> = None;
    for (edge, e) in edges.enumerate() {
        let squared = e.length_squared();
        if previous.is_some_and(|(a, a_squared)| a.dot(e) < limit * (a_squared * squared).sqrt()) {
            return Some(edge - 1);
        }
        previous = Some((e, squared));
    }
    None
}

/// The orthonormal material frame `(t, m1, m2)` of one edge.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub struct MaterialFrame {
    /// Unit tangent of the edge.
    pub tangent: DVec3,
    /// First material director: the direction of the cross-section's `semi_axis_1`.
    pub m1: DVec3,
    /// Second material director, `t × m1`.
    pub m2: DVec3,
}

/// One elastic rod (a hair strand) in the Discrete Elastic Rods model (Bergou et al. 2008).
///
/// Nodes `x_0 … x_n` joined by edges `e^i = x_{i+1} − x_i`. Each edge carries a reference frame, kept
/// adapted by parallel transport in space (at creation) and time (every step), and a twist angle `θ^i`
/// giving its material frame. The shape the rod is created with is its rest shape: rest lengths,
/// rest material curvatures and rest twists are measured from it, so it feels no elastic force there.
///
/// Positions are in m, velocities in m/s, angles in radians. Interior vertices `1 … n−1` carry
/// curvature and twist; arrays indexed by vertex have one entry per node, the two ends unused.
#[derive(Debug, Clone, Reflect)]
pub struct Rod {
    pub(crate) state: RodState,
    pub(crate) frames: RodFrames,
    pub(crate) rest: RestShape,
    pub(crate) inertia: RodInertia,
    pub(crate) constraints: RodConstraints,
    material: RodMaterial,
    pub(crate) stiffness: Stiffness,
    /// The state and frames the rod was created with, for [`Rod::reset`].
    initial: RodSnapshot,
}

impl Rod {
    /// Creates a rod through `positions` (m) whose first edge has its first material director `m1` along
    /// `material_direction` (projected perpendicular to the edge). The given shape is the rest shape.
    ///
    /// Rejects fewer than 3 nodes, non-finite nodes, (nearly) zero-length edges, consecutive edges that
    /// turn by more than [`MAX_TURNING_ANGLE`], a material direction that is zero, not finite, or within
    /// [`MIN_MATERIAL_DIRECTION_ANGLE`] of the first edge, and invalid material parameters.
    pub fn new(positions: &[DVec3], material_direction: DVec3, material: RodMaterial) -> Result<Self, RodError> {
        material.validate()?;
        if positions.len() < 3 {
            return Err(RodError::TooFewNodes { nodes: positions.len() });
        }
        if let Some((node, &position)) = positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
            return Err(RodError::NonFiniteNode { node, position });
        }
        let node_count = positions.len();
        let edge_count = node_count - 1;
        let rest_lengths: Vec<f64> = positions.windows(2).map(|pair| (pair[1] - pair[0]).length()).collect();
        let minimum = MIN_RELATIVE_EDGE_LENGTH * rest_lengths.iter().sum::<f64>() / edge_count as f64;
        if let Some((edge, &length)) = rest_lengths.iter().enumerate().find(|(_, l)| **l <= minimum) {
            return Err(RodError::DegenerateEdge { edge, length, minimum });
        }
        let tangents: Vec<DVec3> = positions.windows(2).map(|pair| (pair[1] - pair[0]).normalize()).collect();
        if let Some(edge) = first_fold(tangents.iter().copied(), MAX_TURNING_ANGLE) {
            return Err(RodError::FoldedEdges { edge });
        }
        let first_director = material_director(material_direction, tangents[0])
            .ok_or(RodError::InvalidMaterialDirection { edge: 0, direction: material_direction })?;

        // Space-parallel transport of the first director along the curve.
        let mut reference_directors = Vec::with_capacity(edge_count);
        reference_directors.push(first_director);
        for edge in 1..edge_count {
            let carried = parallel_transport(reference_directors[edge - 1], tangents[edge - 1], tangents[edge]);
            reference_directors.push(perpendicular_unit(carried, tangents[edge]).unwrap_or(carried));
        }

        let stiffness = material.stiffness();
        let mut voronoi_lengths = vec![0.0; node_count];
        for (edge, &length) in rest_lengths.iter().enumerate() {
            voronoi_lengths[edge] += 0.5 * length;
            voronoi_lengths[edge + 1] += 0.5 * length;
        }
        let state = RodState {
            positions: positions.to_vec(),
            velocities: vec![DVec3::ZERO; node_count],
            twist: vec![0.0; edge_count],
            twist_rates: vec![0.0; edge_count],
            contact_normal_forces: vec![0.0; node_count],
            history: StepHistory::empty(node_count),
        };
        let frames = RodFrames { reference_directors, tangents, reference_twist: vec![0.0; node_count] };
        let mut rod = Self {
            initial: RodSnapshot { state: state.clone(), frames: frames.clone() },
            state,
            frames,
            inertia: RodInertia {
                masses: voronoi_lengths.iter().map(|l| stiffness.linear_density * l).collect(),
                twist_inertias: rest_lengths.iter().map(|l| stiffness.twist_inertia_density * l).collect(),
            },
            rest: RestShape {
                lengths: rest_lengths,
                voronoi_lengths,
                curvatures: vec![DVec2::ZERO; node_count],
                twists: vec![0.0; node_count],
            },
            constraints: RodConstraints { node_targets: vec![None; node_count], twist_targets: vec![None; edge_count] },
            material,
            stiffness,
        };
        rod.refresh_frames();
        for vertex in 1..edge_count {
            let (kappa, twist) = rod.vertex_curvature_and_twist(vertex);
            rod.rest.curvatures[vertex] = kappa;
            rod.rest.twists[vertex] = twist;
        }
        Ok(rod)
    }

    /// Number of nodes `n + 1`.
    pub fn node_count(&self) -> usize {
        self.state.positions.len()
    }

    /// Number of edges `n`.
    pub fn edge_count(&self) -> usize {
        self.state.positions.len() - 1
    }

    /// Node positions, m.
    pub fn positions(&self) -> &[DVec3] {
        &self.state.positions
    }

    /// Node positions, m, for moving nodes directly (an editor, a scripted pose). The frames follow the
    /// nodes at the next step; velocities are left as they are. A state the next step cannot start from
    /// (a non-finite position, two nodes on top of each other, two edges folded onto each other) is not
    /// kept: that step puts the rod back in its rest pose and reports
    /// [`crate::rod::StepError::UnusableState`].
    pub fn positions_mut(&mut self) -> &mut [DVec3] {
        // The two-step integrator's memory no longer describes how the rod got here.
        self.state.history.dt = 0.0;
        &mut self.state.positions
    }

    /// Node velocities, m/s.
    pub fn velocities(&self) -> &[DVec3] {
        &self.state.velocities
    }

    /// Per-edge twist angles `θ^i` of the material frames relative to the reference frames, rad.
    pub fn twist_angles(&self) -> &[f64] {
        &self.state.twist
    }

    /// Rest lengths `|ē^i|` of the edges, m.
    pub fn rest_lengths(&self) -> &[f64] {
        &self.rest.lengths
    }

    /// Total rest length of the rod, m.
    pub fn rest_length(&self) -> f64 {
        self.rest.lengths.iter().sum()
    }

    /// Rest length of the longest edge, m.
    pub fn longest_rest_edge(&self) -> f64 {
        self.rest.lengths.iter().copied().fold(0.0, f64::max)
    }

    /// Lumped node masses `ρ A l_i` (Voronoi lengths), kg.
    pub fn masses(&self) -> &[f64] {
        &self.inertia.masses
    }

    /// The material the rod was made of.
    pub fn material(&self) -> &RodMaterial {
        &self.material
    }

    /// The stiffnesses derived from the material.
    pub fn stiffness(&self) -> &Stiffness {
        &self.stiffness
    }

    /// Rest material curvatures `(κ̄₁, κ̄₂)` per vertex (integrated, dimensionless; ends unused).
    pub fn rest_curvatures(&self) -> &[DVec2] {
        &self.rest.curvatures
    }

    /// Rest twists `τ̄` per vertex (integrated, rad; ends unused).
    pub fn rest_twists(&self) -> &[f64] {
        &self.rest.twists
    }

    /// The material frame of `edge`.
    pub fn material_frame(&self, edge: usize) -> MaterialFrame {
        let tangent = self.frames.tangents[edge];
        let (m1, m2) = material_directors(self.frames.reference_directors[edge], tangent, self.state.twist[edge]);
        MaterialFrame { tangent, m1, m2 }
    }

    /// The current material curvatures `(κ₁, κ₂)` and twist `τ` at interior `vertex` (integrated,
    /// dimensionless and rad): `κ₁ = ½ κb·(m2^{i−1} + m2^i)`, `κ₂ = −½ κb·(m1^{i−1} + m1^i)`,
    /// `τ = θ^i − θ^{i−1} + refTwist_i`.
    pub fn vertex_curvature_and_twist(&self, vertex: usize) -> (DVec2, f64) {
        let (previous, next) = (self.material_frame(vertex - 1), self.material_frame(vertex));
        let binormal = super::frames::curvature_binormal(previous.tangent, next.tangent);
        let kappa = DVec2::new(0.5 * binormal.dot(previous.m2 + next.m2), -0.5 * binormal.dot(previous.m1 + next.m1));
        let twist = self.state.twist[vertex] - self.state.twist[vertex - 1] + self.frames.reference_twist[vertex];
        (kappa, twist)
    }

    /// The largest edge strain `|e|/|ē| − 1` in absolute value, with the edge it occurs on.
    pub fn max_strain(&self) -> (usize, f64) {
        self.state
            .positions
            .windows(2)
            .zip(&self.rest.lengths)
            .map(|(pair, rest)| ((pair[1] - pair[0]).length() / rest - 1.0).abs())
            .enumerate()
            .fold(
                (0, 0.0),
                |best, (edge, strain)| {
                    if strain > best.1 || strain.is_nan() { (edge, strain) } else { best }
                },
            )
    }

    /// The sharpest turn between two consecutive edges, rad (0 straight, π folded back onto itself), with
    /// its vertex (0 for a single edge).
    pub fn sharpest_turn(&self) -> (usize, f64) {
        let tangents: Vec<DVec3> =
            self.state.positions.windows(2).map(|pair| (pair[1] - pair[0]).normalize_or_zero()).collect();
        tangents
            .windows(2)
            .map(|pair| pair[0].angle_between(pair[1]))
            .enumerate()
            .fold((0, 0.0), |best, (edge, angle)| if angle > best.1 { (edge + 1, angle) } else { best })
    }

    /// Kinetic energy of the nodes and of the edges' spin about their axes, J.
    pub fn kinetic_energy(&self) -> f64 {
        let translational: f64 =
            self.inertia.masses.iter().zip(&self.state.velocities).map(|(m, v)| 0.5 * m * v.length_squared()).sum();
        let spin: f64 =
            self.inertia.twist_inertias.iter().zip(&self.state.twist_rates).map(|(i, w)| 0.5 * i * w * w).sum();
        translational + spin
    }

    /// Sets the rest material curvature `(κ̄₁, κ̄₂)` of interior `vertex` (integrated, dimensionless).
    /// Rejects a non-finite curvature, and one whose magnitude `2 tan(φ/2)` asks the edges to turn by
    /// more than [`MAX_TURNING_ANGLE`]; the rod is then unchanged.
    pub fn set_rest_curvature(&mut self, vertex: usize, curvature: DVec2) -> Result<(), RodError> {
        self.check_vertex(vertex)?;
        check_rest_curvature(vertex, curvature)?;
        self.rest.curvatures[vertex] = curvature;
        Ok(())
    }

    /// Sets the rest twist `τ̄` of interior `vertex` (integrated, rad). Rejects a non-finite twist and one
    /// beyond [`MAX_REST_TWIST`]; the rod is then unchanged.
    pub fn set_rest_twist(&mut self, vertex: usize, twist: f64) -> Result<(), RodError> {
        self.check_vertex(vertex)?;
        check_rest_twist(vertex, twist)?;
        self.rest.twists[vertex] = twist;
        Ok(())
    }

    /// Replaces the whole rest shape at once: rest edge lengths (m), rest curvatures and rest twists per
    /// vertex (integrated; the two ends are ignored). Voronoi lengths, masses and spin inertias follow the
    /// new lengths. All or nothing: rejects arrays of the wrong length, a non-finite entry, an edge shorter
    /// than a millionth of the mean, a curvature or twist [`Rod::set_rest_curvature`] or
    /// [`Rod::set_rest_twist`] would reject; the rod is then unchanged.
    pub fn set_rest_shape(&mut self, lengths: &[f64], curvatures: &[DVec2], twists: &[f64]) -> Result<(), RodError> {
        let (nodes, edges) = (self.node_count(), self.edge_count());
        for (expected, actual) in [(edges, lengths.len()), (nodes, curvatures.len()), (nodes, twists.len())] {
            if expected != actual {
                return Err(RodError::WrongLength { expected, actual });
            }
        }
        if let Some(edge) = lengths.iter().position(|length| !length.is_finite()) {
            return Err(RodError::NonFiniteRestShape { what: "length", vertex: edge });
        }
        let minimum = MIN_RELATIVE_EDGE_LENGTH * lengths.iter().sum::<f64>() / edges as f64;
        if let Some((edge, &length)) = lengths.iter().enumerate().find(|(_, length)| **length <= minimum) {
            return Err(RodError::DegenerateEdge { edge, length, minimum });
        }
        for vertex in 1..edges {
            check_rest_curvature(vertex, curvatures[vertex])?;
            check_rest_twist(vertex, twists[vertex])?;
        }
        self.rest.lengths.copy_from_slice(lengths);
        self.rest.curvatures[1..edges].copy_from_slice(&curvatures[1..edges]);
        self.rest.twists[1..edges].copy_from_slice(&twists[1..edges]);
        self.rest.voronoi_lengths.fill(0.0);
        for (edge, &length) in lengths.iter().enumerate() {
            self.rest.voronoi_lengths[edge] += 0.5 * length;
            self.rest.voronoi_lengths[edge + 1] += 0.5 * length;
        }
        self.update_inertia();
        Ok(())
    }

    /// Masses and spin inertias from the rest lengths and the material's stiffness (densities).
    fn update_inertia(&mut self) {
        let stiffness = &self.stiffness;
        for (mass, length) in self.inertia.masses.iter_mut().zip(&self.rest.voronoi_lengths) {
            *mass = stiffness.linear_density * length;
        }
        for (inertia, length) in self.inertia.twist_inertias.iter_mut().zip(&self.rest.lengths) {
            *inertia = stiffness.twist_inertia_density * length;
        }
    }

    /// Gives the whole rod a uniform natural curvature `(k₁, k₂)` in 1/m, in its material frame:
    /// free of load it curls into a circular arc (a helix when twisted) of curvature `|k|`.
    ///
    /// The discrete rest curvature at vertex i is `2 tan(|k| l_i / 2) k/|k|`: the turning angle between
    /// edge midpoints a Voronoi length `l_i` apart on a circle of curvature `|k|`. Rejects a non-finite
    /// curvature, and one that turns some vertex by more than [`MAX_TURNING_ANGLE`] (`|k| l_i` beyond
    /// it: curls tighter than the rod's edges can draw); the rod is then unchanged.
    pub fn set_natural_curvature(&mut self, curvature_per_metre: DVec2) -> Result<(), RodError> {
        if !curvature_per_metre.is_finite() {
            return Err(RodError::NonFiniteRestShape { what: "natural curvature", vertex: 0 });
        }
        let magnitude = curvature_per_metre.length();
        if let Some(vertex) =
            (1..self.edge_count()).find(|&vertex| magnitude * self.rest.voronoi_lengths[vertex] > MAX_TURNING_ANGLE)
        {
            return Err(RodError::RestCurvatureTooLarge {
                vertex,
                turning_degrees: (magnitude * self.rest.voronoi_lengths[vertex]).to_degrees(),
                limit_degrees: MAX_TURNING_ANGLE.to_degrees(),
            });
        }
        for vertex in 1..self.edge_count() {
            self.rest.curvatures[vertex] = if magnitude > 0.0 {
                curvature_per_metre / magnitude * 2.0 * (0.5 * magnitude * self.rest.voronoi_lengths[vertex]).tan()
            } else {
                DVec2::ZERO
            };
        }
        Ok(())
    }

    /// Replaces the material: stiffnesses, masses and spin inertias are recomputed, the rest shape and
    /// the current state stay. Rejects an invalid material and leaves the rod unchanged.
    pub fn set_material(&mut self, material: RodMaterial) -> Result<(), RodError> {
        material.validate()?;
        self.stiffness = material.stiffness();
        self.update_inertia();
        self.material = material;
        Ok(())
    }

    /// Moves the whole rod rigidly, `x ↦ R x + t`: positions, velocities, frames and boundary targets
    /// turn with it, twists and reference twists are unchanged, so its elastic state is the same.
    ///
    /// `rotation` is normalised first; one that is not finite, or whose length is off 1 by more than
    /// 1e-3 (not a rotation: it would scale the rod), is rejected, as is a non-finite `translation`, and
    /// the rod is then unchanged.
    pub fn transform_rigidly(&mut self, rotation: DQuat, translation: DVec3) -> Result<(), RodError> {
        let length = rotation.length();
        if !(rotation.is_finite() && (length - 1.0).abs() <= ROTATION_LENGTH_TOLERANCE) {
            return Err(RodError::InvalidRotation { rotation, length });
        }
        if !translation.is_finite() {
            return Err(RodError::NonFiniteTarget { node: 0, target: translation });
        }
        let rotation = rotation / length;
        for position in &mut self.state.positions {
            *position = rotation * *position + translation;
        }
        for target in self.constraints.node_targets.iter_mut().flatten() {
            *target = rotation * *target + translation;
        }
        // The step before moves with the rod, so that a two-step integrator carries its momentum along.
        for position in &mut self.state.history.positions {
            *position = rotation * *position + translation;
        }
        let turned = self
            .state
            .velocities
            .iter_mut()
            .chain(&mut self.state.history.velocities)
            .chain(&mut self.frames.reference_directors)
            .chain(&mut self.frames.tangents);
        for vector in turned.chain(self.constraints.twist_targets.iter_mut().flatten()) {
            *vector = rotation * *vector;
        }
        Ok(())
    }

    /// Clamps `edge`: its two nodes are held at `start` and `end` (m) and its first material director
    /// points along `material_direction`. Call again each step to move the clamp (a hair root following a
    /// head); the step moves the nodes there and turns the edge's twist, continuing from its last value.
    /// Rejects non-finite or coincident targets and a material direction that is zero, not finite, or
    /// within [`MIN_MATERIAL_DIRECTION_ANGLE`] of the edge.
    pub fn clamp_edge(
        &mut self,
        edge: usize,
        start: DVec3,
        end: DVec3,
        material_direction: DVec3,
    ) -> Result<(), RodError> {
        if edge >= self.edge_count() {
            return Err(RodError::OutOfRange { what: "edge", index: edge, count: self.edge_count() });
        }
        for (node, target) in [(edge, start), (edge + 1, end)] {
            if !target.is_finite() {
                return Err(RodError::NonFiniteTarget { node, target });
            }
        }
        let tangent = (end - start).normalize_or_zero();
        if tangent == DVec3::ZERO || material_director(material_direction, tangent).is_none() {
            return Err(RodError::InvalidMaterialDirection { edge, direction: material_direction });
        }
        self.constraints.node_targets[edge] = Some(start);
        self.constraints.node_targets[edge + 1] = Some(end);
        // A direction too small or too large to square is kept scaled, so that it stays usable where it is
        // projected; any other is kept as given.
        self.constraints.twist_targets[edge] = if squares_safely(material_direction) {
            Some(material_direction)
        } else {
            scaled_direction(material_direction)
        };
        Ok(())
    }

    /// Clamps the root (edge 0) where it is now, with its current material frame.
    pub fn clamp_root_in_place(&mut self) {
        let frame = self.material_frame(0);
        self.constraints.node_targets[0] = Some(self.state.positions[0]);
        self.constraints.node_targets[1] = Some(self.state.positions[1]);
        self.constraints.twist_targets[0] = Some(frame.m1);
    }

    /// Pins `node` to `position` (m), leaving its edges free to turn: a hair tie, a rope end.
    pub fn pin_node(&mut self, node: usize, position: DVec3) -> Result<(), RodError> {
        self.check_node(node)?;
        if !position.is_finite() {
            return Err(RodError::NonFiniteTarget { node, target: position });
        }
        self.constraints.node_targets[node] = Some(position);
        Ok(())
    }

    /// Frees `node` from any pin or clamp.
    pub fn release_node(&mut self, node: usize) -> Result<(), RodError> {
        self.check_node(node)?;
        self.constraints.node_targets[node] = None;
        Ok(())
    }

    /// Frees `edge`'s twist from its clamp (its nodes stay pinned until released).
    pub fn release_edge_twist(&mut self, edge: usize) -> Result<(), RodError> {
        if edge >= self.edge_count() {
            return Err(RodError::OutOfRange { what: "edge", index: edge, count: self.edge_count() });
        }
        self.constraints.twist_targets[edge] = None;
        Ok(())
    }

    /// `1 / m` of `node`, 1/kg; zero when its position is prescribed (it cannot be pushed).
    pub(crate) fn inverse_mass(&self, node: usize) -> f64 {
        if self.constraints.node_targets[node].is_some() { 0.0 } else { 1.0 / self.inertia.masses[node] }
    }

    /// Whether `node`'s position is prescribed by a pin or a clamp.
    pub fn is_node_prescribed(&self, node: usize) -> bool {
        self.constraints.node_targets.get(node).is_some_and(Option::is_some)
    }

    /// The node positions the rod was created with, m: the pose [`Rod::reset`] puts it back in.
    pub fn initial_positions(&self) -> &[DVec3] {
        &self.initial.state.positions
    }

    /// Puts the rod back in the shape and frames it was created with, at rest. Boundary conditions stay.
    pub fn reset(&mut self) {
        self.state.copy_from(&self.initial.state);
        self.frames.copy_from(&self.initial.frames);
        self.refresh_frames();
    }

    /// Why the rod's current positions cannot start a step, if they cannot: the first node with a
    /// non-finite position, that (nearly) coincides with the next one, or whose two edges fold onto each
    /// other (within [`FOLDED_STATE_GAP`] of π). (Positions can be written from outside, [`Rod::positions_mut`].)
    pub(crate) fn unusable_state(&self) -> Option<(usize, &'static str)> {
        if let Some(node) = self.state.positions.iter().position(|p| !p.is_finite()) {
            return Some((node, "not finite"));
        }
        if let Some(node) = self.state.twist.iter().position(|t| !t.is_finite()) {
            return Some((node, "twist not finite"));
        }
        let positions = &self.state.positions;
        let coincident = |edge: usize| {
            let minimum = MIN_RELATIVE_EDGE_LENGTH * self.rest.lengths[edge];
            (positions[edge + 1] - positions[edge]).length_squared() <= minimum * minimum
        };
        if let Some(edge) = (0..self.edge_count()).find(|&edge| coincident(edge)) {
            return Some((edge, "on top of the next node"));
        }
        let edges = positions.windows(2).map(|pair| pair[1] - pair[0]);
        first_fold(edges, std::f64::consts::PI - FOLDED_STATE_GAP)
            .map(|edge| (edge + 1, "edges folded onto each other"))
    }

    /// Time-parallel transport: carries each edge's reference director from the tangent it was adapted
    /// to onto the edge's current tangent, then updates the reference twists, continuing each from its
    /// previous value so that they do not wrap at ±π.
    pub(crate) fn refresh_frames(&mut self) {
        let edge_count = self.edge_count();
        let RodFrames { tangents, reference_directors, reference_twist, .. } = &mut self.frames;
        carry_reference_frames(
            &self.state.positions[..],
            &mut tangents[..],
            &mut reference_directors[..],
            reference_twist,
            edge_count,
        );
    }

    /// The change of `θ^edge` that turns the edge's `m1` onto its clamp's material direction once the
    /// edge lies along its prescribed nodes (the reference director carried there by parallel transport),
    /// continuing from the current twist so that turning a clamp by 3π is three half turns, not one.
    /// `None` when the edge's twist is free.
    pub(crate) fn twist_target_offset(&self, edge: usize) -> Option<f64> {
        let direction = self.constraints.twist_targets[edge]?;
        let tangent = match (self.constraints.node_targets[edge], self.constraints.node_targets[edge + 1]) {
            (Some(start), Some(end)) => (end - start).normalize_or(self.frames.tangents[edge]),
            _ => self.frames.tangents[edge],
        };
        let reference = parallel_transport(self.frames.reference_directors[edge], self.frames.tangents[edge], tangent);
        let target = perpendicular_unit(direction, tangent)?;
        let angle = signed_angle(reference, target, tangent);
        Some(wrap_angle(angle - self.state.twist[edge]))
    }

    fn check_node(&self, node: usize) -> Result<(), RodError> {
        if node < self.node_count() {
            Ok(())
        } else {
            Err(RodError::OutOfRange { what: "node", index: node, count: self.node_count() })
        }
    }

    fn check_vertex(&self, vertex: usize) -> Result<(), RodError> {
        if (1..self.edge_count()).contains(&vertex) {
            Ok(())
        } else {
            Err(RodError::OutOfRange { what: "interior vertex", index: vertex, count: self.edge_count() - 1 })
        }
    }
}

/// The rod's data by group, and snapshots of what a step starts from.
impl Rod {
    /// The rod's motion: positions, velocities, twists.
    pub fn state(&self) -> &RodState {
        &self.state
    }

    /// The edges' reference frames and the reference twists.
    pub fn frames(&self) -> &RodFrames {
        &self.frames
    }

    /// The rest shape: rest lengths, curvatures and twists.
    pub fn rest_shape(&self) -> &RestShape {
        &self.rest
    }

    /// The lumped masses and spin inertias.
    pub fn inertia(&self) -> &RodInertia {
        &self.inertia
    }

    /// The boundary conditions.
    pub fn constraints(&self) -> &RodConstraints {
        &self.constraints
    }

    /// A copy of what the next step starts from (see [`RodSnapshot`]).
    pub fn snapshot(&self) -> RodSnapshot {
        RodSnapshot { state: self.state.clone(), frames: self.frames.clone() }
    }

    /// Puts `snapshot` back: the following steps repeat those that followed it, bit for bit. Rejects a
    /// snapshot of a rod with another number of nodes (the rod is then unchanged); a snapshot with
    /// non-finite values is accepted here and reported by the next step as
    /// [`crate::rod::StepError::UnusableState`].
    pub fn restore(&mut self, snapshot: &RodSnapshot) -> Result<(), RodError> {
        if !snapshot.fits(self.node_count()) {
            return Err(RodError::SnapshotMismatch { nodes: self.node_count(), snapshot_nodes: snapshot.node_count() });
        }
        self.state.copy_from(&snapshot.state);
        self.frames.copy_from(&snapshot.frames);
        Ok(())
    }

    /// Copies the state and frames into `snapshot`, reusing its memory.
    /// (Not the history: the step reads it from the rod, which keeps it until the step ends.)
    pub(crate) fn save_into(&self, snapshot: &mut RodSnapshot) {
        snapshot.state.copy_motion_from(&self.state);
        snapshot.frames.copy_from(&self.frames);
    }

    /// Puts the configuration of `snapshot` back (positions, twists, frames), at rest: the step's own
    /// roll-back after a failure. `snapshot` was saved from this rod.
    pub(crate) fn restore_at_rest(&mut self, snapshot: &RodSnapshot) {
        copy_into(&mut self.state.positions, &snapshot.state.positions);
        copy_into(&mut self.state.twist, &snapshot.state.twist);
        self.frames.copy_from(&snapshot.frames);
        self.state.velocities.fill(DVec3::ZERO);
        self.state.twist_rates.fill(0.0);
        self.state.contact_normal_forces.fill(0.0);
        self.state.history.dt = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(nodes: usize) -> Vec<DVec3> {
        (0..nodes).map(|i| DVec3::new(0.01 * i as f64, 0.0, 0.0)).collect()
    }

    #[test]
    fn invalid_input_is_rejected_with_a_reason() {
        let hair = RodMaterial::human_hair();
        assert_eq!(Rod::new(&straight(2), DVec3::Y, hair).unwrap_err(), RodError::TooFewNodes { nodes: 2 });
        let mut nodes = straight(5);
        nodes[3].y = f64::NAN;
        assert!(matches!(Rod::new(&nodes, DVec3::Y, hair), Err(RodError::NonFiniteNode { node: 3, .. })));
        let mut nodes = straight(5);
        nodes[2] = nodes[1];
        assert!(matches!(Rod::new(&nodes, DVec3::Y, hair), Err(RodError::DegenerateEdge { edge: 1, .. })));
        let mut nodes = straight(4);
        nodes[3] = nodes[1];
        assert!(matches!(Rod::new(&nodes, DVec3::Y, hair), Err(RodError::FoldedEdges { edge: 1 })));
        assert!(matches!(Rod::new(&straight(4), DVec3::X, hair), Err(RodError::InvalidMaterialDirection { .. })));
        let bad = RodMaterial { youngs_modulus: 0.0, ..hair };
        assert!(matches!(Rod::new(&straight(4), DVec3::Y, bad), Err(RodError::InvalidMaterial { .. })));
        let mut rod = Rod::new(&straight(4), DVec3::Y, hair).unwrap();
        assert!(rod.pin_node(9, DVec3::ZERO).is_err());
        assert!(rod.pin_node(1, DVec3::NAN).is_err());
        assert!(rod.clamp_edge(0, DVec3::ZERO, DVec3::X, DVec3::X).is_err());
        assert!(rod.set_rest_curvature(0, DVec2::ONE).is_err());
        let message = Rod::new(&straight(2), DVec3::Y, hair).unwrap_err().to_string();
        assert!(message.contains("at least 3 nodes"), "{message}");
    }

    #[test]
    fn spawned_shape_is_its_own_rest_shape() {
        let helix: Vec<DVec3> = (0..20)
            .map(|i| {
                let s = i as f64 * 0.4;
                DVec3::new(0.01 * s.cos(), 0.01 * s.sin(), 0.003 * s)
            })
            .collect();
        let rod = Rod::new(&helix, DVec3::Z, RodMaterial::human_hair()).unwrap();
        for vertex in 1..rod.edge_count() {
            let (kappa, twist) = rod.vertex_curvature_and_twist(vertex);
            assert!((kappa - rod.rest.curvatures[vertex]).length() < 1e-15);
            assert!((twist - rod.rest.twists[vertex]).abs() < 1e-15);
            assert!(kappa.length() > 0.01, "a helix is curved");
        }
        let total_mass: f64 = rod.masses().iter().sum();
        let expected = rod.stiffness().linear_density * rod.rest_length();
        assert!((total_mass - expected).abs() < 1e-12 * expected);
    }

    #[test]
    fn frames_stay_orthonormal_and_adapted_after_transport() {
        let mut rod = Rod::new(&straight(6), DVec3::Y, RodMaterial::human_hair()).unwrap();
        for (i, p) in rod.state.positions.iter_mut().enumerate() {
            p.y += 0.003 * (i as f64).powi(2);
            p.z -= 0.002 * i as f64;
        }
        rod.refresh_frames();
        for edge in 0..rod.edge_count() {
            let frame = rod.material_frame(edge);
            let tangent = (rod.state.positions[edge + 1] - rod.state.positions[edge]).normalize();
            assert!((frame.tangent - tangent).length() < 1e-14);
            assert!(frame.m1.dot(tangent).abs() < 1e-14 && frame.m2.dot(tangent).abs() < 1e-14);
            assert!((frame.m1.length() - 1.0).abs() < 1e-14 && frame.m1.dot(frame.m2).abs() < 1e-14);
        }
    }

    #[test]
    fn a_rigid_motion_keeps_the_elastic_state() {
        let mut rod = Rod::new(&straight(8), DVec3::Y, RodMaterial::human_hair()).unwrap();
        for (i, p) in rod.state.positions.iter_mut().enumerate() {
            p.y += 0.002 * (i as f64).powi(2);
            p.z += 0.001 * (i as f64).sin();
        }
        rod.state.twist[3] = 0.4;
        rod.state.velocities[5] = DVec3::new(0.1, -0.2, 0.3);
        rod.refresh_frames();
        let before = rod.clone();
        let rotation = DQuat::from_euler(bevy::math::EulerRot::YXZ, 0.7, -1.2, 2.9);
        let translation = DVec3::new(3.0, -1.0, 100.0);
        rod.transform_rigidly(rotation, translation).unwrap();
        rod.refresh_frames();
        for node in 0..rod.node_count() {
            let expected = rotation * before.state.positions[node] + translation;
            assert!((rod.state.positions[node] - expected).length() < 1e-12);
            assert!((rod.state.velocities[node] - rotation * before.state.velocities[node]).length() < 1e-14);
        }
        for vertex in 1..rod.edge_count() {
            let (kappa, twist) = rod.vertex_curvature_and_twist(vertex);
            let (kappa_before, twist_before) = before.vertex_curvature_and_twist(vertex);
            assert!((kappa - kappa_before).length() < 1e-12, "curvature at {vertex}");
            assert!((twist - twist_before).abs() < 1e-12, "twist at {vertex}");
        }
        let (energy, energy_before) = (rod.elastic_energy(), before.elastic_energy());
        assert!((energy.bending - energy_before.bending).abs() <= 1e-10 * energy_before.bending);
        assert!((energy.twisting - energy_before.twisting).abs() <= 1e-10 * energy_before.twisting);
    }

    #[test]
    fn a_new_material_changes_masses_and_stiffness_but_not_the_shape() {
        let mut rod = Rod::new(&straight(6), DVec3::Y, RodMaterial::human_hair()).unwrap();
        let positions = rod.state.positions.clone();
        let dense = RodMaterial { density: 2600.0, ..RodMaterial::human_hair() };
        rod.set_material(dense).unwrap();
        let total: f64 = rod.masses().iter().sum();
        assert!((total - dense.stiffness().linear_density * rod.rest_length()).abs() < 1e-12 * total);
        assert_eq!(rod.stiffness(), &dense.stiffness());
        assert_eq!(rod.state.positions, positions);
        let invalid = RodMaterial { youngs_modulus: f64::NAN, ..dense };
        assert!(matches!(
            rod.set_material(invalid),
            Err(RodError::InvalidMaterial { parameter: "youngs_modulus", .. })
        ));
        assert_eq!(rod.material(), &dense, "a rejected material changes nothing");
    }
}
