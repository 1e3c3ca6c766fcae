//! Several strands stepped in lockstep, one per SIMD lane ([`LockstepWorkspace::step`]).
//!
//! A strand's step is a chain of short dependent operations: the banded `L D Lᵀ` eliminates one pivot
//! after another, each waiting on the last. One core runs such a chain far below its arithmetic peak.
//! Strands are independent, so [`LANES`] of them with the same node count go through the chain side by
//! side: entry `(i, j)` of the batch's matrix holds entry `(i, j)` of every strand's matrix
//! ([`Lanes`]), and one SIMD instruction does for all of them what a scalar one does for one.
//!
//! The instruction set is chosen when the program runs (`multiversion`): AVX2 with FMA where the CPU
//! has it, AVX elsewhere on x86-64, and plain `f64` code on any other CPU, from the same source and
//! with no `RUSTFLAGS`. Every lane does exactly the scalar step's operations in the same order (no fused
//! multiply-adds are formed), so a strand stepped in a batch ends bit for bit where [`Rod::step_with_loads`]
//! would put it, whatever strands share its batch. A strand that fails rolls back and reports alone;
//! one whose iterations end early is left out of its batch's later iterations.
//!
//! What runs in lanes: the elastic terms (assembled straight into the batch's matrix, from one source
//! shared with the one-strand step), the inertia, drag, anchor and applied-force terms, internal
//! damping's product and residual, the edges' geometry, the factorisation, the substitutions, the
//! Newton update with its trust region, the projection onto the edge lengths and the reference frames
//! (their `atan2` and the material directors' `sin_cos` lane by lane: std's functions, so that the bits
//! match), and the prescribed unknowns where the batch's strands share them (as the strands of a head,
//! each clamped at its root, do). Each strand's contact and Levenberg–Marquardt shift are written into
//! its own lane, and its contacts are looked at strand by strand. The plugin steps its strands this way;
//! `benchmark lockstep` compares the two paths (`docs/performance.md`).

use super::banded::{BandedMatrix, MatrixLane, factorize_best, solve_best};
use super::contact::Contacts;
use super::curve::Rod;
use super::energy::{
    BANDWIDTH, EdgeFrame, EdgeGeometry, ElasticSource, Moduli, add_elastic_terms, dof_count, edge_frame, vertex_twist,
};
use super::error::StepError;
use super::frames::carry_reference_frames;
use super::inertia::{InertiaSource, NodeAnchor, add_inertia_terms};
use super::lanes::{LaneMask, Lanes, Real, Vector, lanes_in};
use super::params::StepParams;
use super::projection::{LengthConstraints, ProjectionScratch, TridiagonalScratch, project_points};
use super::solver::{
    MovingUnknowns, NewtonProgress, RodWorkspace, StepLoads, StepReport, damped_scale, first_non_finite_update,
    newton_update, next_regularisation,
};

pub use super::lanes::LANES;

/// The banded matrix of a batch's Newton systems, one strand per lane.
type BatchMatrix = BandedMatrix<BANDWIDTH, Lanes>;

/// One strand of a lockstep batch: its rod, what acts on it from outside, its colliders.
#[derive(Debug)]
pub struct LockstepStrand<'r, 'l> {
    /// The strand.
    pub rod: &'r mut Rod,
    /// Forces, wind and velocity changes on it during the step (see [`StepLoads`]).
    pub loads: StepLoads<'l>,
    /// The colliders it meets and its collision thickness.
    pub contacts: Contacts<'l>,
}

/// Scratch memory for stepping strands [`LANES`] at a time: one [`RodWorkspace`] per lane and the
/// batch's matrix. Grows to the largest strands, then never allocates; one per thread.
#[derive(Debug, Clone, Default)]
pub struct LockstepWorkspace {
    lanes: [RodWorkspace; LANES],
    matrix: BatchMatrix,
    /// The elastic gradient, then the right-hand side and the solution.
    solution: Vec<Lanes>,
    elastic: BatchElastic,
    inertia: BatchInertia,
    projection: BatchProjection,
    frames: BatchFrames,
    /// Scratch for products on one lane of the matrix.
    product_scratch: [Vec<f64>; 2],
    /// The lanes' deformations since their first guess, and the elastic terms' matrix times them
    /// (internal damping).
    displacement: Vec<Lanes>,
    elastic_product: Vec<Lanes>,
    /// The damped lanes' internal damping forces.
    damping_force: Vec<Lanes>,
    /// The displacements left to the lanes' prescribed unknowns, and the matrix times them.
    prescribed: Vec<Lanes>,
    prescribed_coupling: Vec<Lanes>,
    /// The lanes in which each edge is free (not both its nodes held) this step.
    free_edges: Vec<LaneMask>,
}

/// What the elastic terms read of a batch's strands, lane by lane ([`ElasticSource`]): the rest shape
/// and moduli, gathered once a step, and the frames and twists, gathered at each assembly, from which
/// the edges' geometry is computed in lanes ([`batch_edge_frames`]).
#[derive(Debug, Clone, Default)]
struct BatchElastic {
    moduli: Moduli<Lanes>,
    rest_lengths: Vec<Lanes>,
    voronoi_lengths: Vec<Lanes>,
    rest_curvatures: Vec<[Lanes; 2]>,
    rest_twists: Vec<Lanes>,
    tangents: Vec<Vector<Lanes>>,
    directors: Vec<Vector<Lanes>>,
    edge_twists: Vec<Lanes>,
    edges: Vec<EdgeFrame<Lanes>>,
    /// The twist of each interior vertex.
    twists: Vec<Lanes>,
}

impl BatchElastic {
    /// Sizes everything for strands of `edge_count` edges (allocating only when it grows).
    fn resize(&mut self, edge_count: usize) {
        self.rest_lengths.resize(edge_count, Lanes::default());
        self.voronoi_lengths.resize(edge_count, Lanes::default());
        self.rest_curvatures.resize(edge_count, Default::default());
        self.rest_twists.resize(edge_count, Lanes::default());
        self.tangents.resize(edge_count, Vector::default());
        self.directors.resize(edge_count, Vector::default());
        self.edge_twists.resize(edge_count, Lanes::default());
        self.edges.resize(edge_count, EdgeFrame::default());
        self.twists.resize(edge_count, Lanes::default());
    }

    /// Takes `rod`'s rest shape and moduli into `lane`.
    fn gather_rest(&mut self, lane: usize, rod: &Rod) {
        let stiffness = rod.stiffness();
        self.moduli.stretching.0[lane] = stiffness.stretching;
        self.moduli.bending_1.0[lane] = stiffness.bending_1;
        self.moduli.bending_2.0[lane] = stiffness.bending_2;
        self.moduli.twisting.0[lane] = stiffness.twisting;
        let rest = &rod.rest;
        for (entry, &length) in self.rest_lengths.iter_mut().zip(&rest.lengths) {
            entry.0[lane] = length;
        }
        // Interior vertices only: `1 ..< edge_count`.
        let vertices = 1..rod.edge_count();
        for vertex in vertices {
            self.voronoi_lengths[vertex].0[lane] = rest.voronoi_lengths[vertex];
            self.rest_curvatures[vertex][0].0[lane] = rest.curvatures[vertex].x;
            self.rest_curvatures[vertex][1].0[lane] = rest.curvatures[vertex].y;
            self.rest_twists[vertex].0[lane] = rest.twists[vertex];
        }
    }

    /// Takes `rod`'s current frames and twists into `lane`.
    fn gather_state(&mut self, lane: usize, rod: &Rod) {
        let frames = &rod.frames;
        for (edge, &tangent) in frames.tangents.iter().enumerate() {
            self.tangents[edge].set_lane(lane, tangent);
            self.directors[edge].set_lane(lane, frames.reference_directors[edge]);
            self.edge_twists[edge].0[lane] = rod.state.twist[edge];
        }
        for vertex in 1..rod.edge_count() {
            self.twists[vertex].0[lane] = vertex_twist(rod, vertex);
        }
    }

    /// Writes `lane`'s edges' geometry into `edges` (a strand's workspace).
    fn scatter_edges(&self, lane: usize, edges: &mut Vec<EdgeGeometry>) {
        edges.clear();
        edges.extend(self.edges.iter().map(|edge| EdgeGeometry {
            tangent: edge.tangent.lane(lane),
            length: edge.length.0[lane],
            inverse_length: edge.inverse_length.0[lane],
            m1: edge.m1.lane(lane),
            m2: edge.m2.lane(lane),
        }));
    }
}

/// The edges' geometry of a batch from its nodes' `positions` and its gathered frames and twists
/// (`energy::edge_geometry` in lanes), compiled for the best instruction set the CPU has (see
/// [`factorize_best`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn batch_edge_frames(elastic: &mut BatchElastic, positions: &[Vector<Lanes>]) {
    let BatchElastic { tangents, directors, edge_twists, edges, .. } = elastic;
    for (edge, frame) in edges.iter_mut().enumerate() {
        *frame = edge_frame(positions[edge], positions[edge + 1], tangents[edge], directors[edge], edge_twists[edge]);
    }
}

impl ElasticSource<Lanes> for BatchElastic {
    #[inline(always)]
    fn edge_count(&self) -> usize {
        self.edges.len()
    }

    #[inline(always)]
    fn moduli(&self) -> Moduli<Lanes> {
        self.moduli
    }

    #[inline(always)]
    fn edge(&self, edge: usize) -> EdgeFrame<Lanes> {
        self.edges[edge]
    }

    #[inline(always)]
    fn rest_length(&self, edge: usize) -> Lanes {
        self.rest_lengths[edge]
    }

    #[inline(always)]
    fn twist(&self, vertex: usize) -> Lanes {
        self.twists[vertex]
    }

    #[inline(always)]
    fn voronoi_length(&self, vertex: usize) -> Lanes {
        self.voronoi_lengths[vertex]
    }

    #[inline(always)]
    fn rest_curvature(&self, vertex: usize) -> [Lanes; 2] {
        self.rest_curvatures[vertex]
    }

    #[inline(always)]
    fn rest_twist(&self, vertex: usize) -> Lanes {
        self.rest_twists[vertex]
    }
}

/// What the inertia terms read of a batch's strands, lane by lane ([`InertiaSource`]): the scheme, the
/// step's start and the loads, gathered once a step (a load is zero in the lanes of strands without
/// it), and the iterate, gathered at each assembly.
#[derive(Debug, Clone, Default)]
struct BatchInertia {
    scheme_step: Lanes,
    masses: Vec<Lanes>,
    positions: Vec<Vector<Lanes>>,
    predicted_positions: Vec<Vector<Lanes>>,
    predicted_velocities: Vec<Vector<Lanes>>,
    start_tangents: Vec<Vector<Lanes>>,
    forces: BatchLoad<Vector<Lanes>>,
    air_velocities: BatchLoad<Vector<Lanes>>,
    anchors: BatchLoad<NodeAnchor<Lanes>>,
    twist_inertias: Vec<Lanes>,
    twist_changes: Vec<Lanes>,
    start_twist_rates: Vec<Lanes>,
}

/// A load of a batch's nodes (forces, wind, anchors), if any of its strands has it: zero in the lanes
/// of the strands without it.
#[derive(Debug, Clone, Default)]
struct BatchLoad<V> {
    values: Vec<V>,
    present: bool,
}

impl<V: Copy + Default> BatchLoad<V> {
    /// Puts a strand's load (`value` of each of the `nodes` nodes, if it has the load) into its lane
    /// (`set`): the first strand with the load clears the batch's values to zero in every lane.
    fn gather<W>(&mut self, nodes: usize, value: impl Fn(usize) -> Option<W>, mut set: impl FnMut(&mut V, W)) {
        if value(0).is_none() {
            return;
        }
        if !self.present {
            self.values.clear();
            self.values.resize(nodes, V::default());
            self.present = true;
        }
        for (node, entry) in self.values.iter_mut().enumerate() {
            if let Some(value) = value(node) {
                set(entry, value);
            }
        }
    }

    /// The load of node `node`, if the batch has it.
    #[inline(always)]
    fn get(&self, node: usize) -> Option<V> {
        self.present.then(|| self.values[node])
    }
}

impl BatchInertia {
    /// Sizes everything for strands of `nodes` nodes, with no load yet (allocating only when it grows).
    fn begin(&mut self, nodes: usize) {
        self.masses.resize(nodes, Lanes::default());
        self.positions.resize(nodes, Vector::default());
        self.predicted_positions.resize(nodes, Vector::default());
        self.predicted_velocities.resize(nodes, Vector::default());
        self.start_tangents.resize(nodes - 1, Vector::default());
        self.twist_inertias.resize(nodes - 1, Lanes::default());
        self.twist_changes.resize(nodes - 1, Lanes::default());
        self.start_twist_rates.resize(nodes - 1, Lanes::default());
        self.forces.present = false;
        self.air_velocities.present = false;
        self.anchors.present = false;
    }

    /// Takes what the step of `strand` starts from into `lane`.
    fn gather_step(&mut self, lane: usize, strand: &impl InertiaSource<f64>) {
        *self.scheme_step.lane_mut(lane) = strand.scheme_step();
        for (node, mass) in self.masses.iter_mut().enumerate() {
            *mass.lane_mut(lane) = strand.mass(node);
            self.predicted_positions[node].set_lane(lane, strand.predicted_position(node).lane(0));
            self.predicted_velocities[node].set_lane(lane, strand.predicted_velocity(node).lane(0));
        }
        for (edge, tangent) in self.start_tangents.iter_mut().enumerate() {
            tangent.set_lane(lane, strand.start_tangent(edge).lane(0));
            *self.twist_inertias[edge].lane_mut(lane) = strand.twist_inertia(edge);
            *self.start_twist_rates[edge].lane_mut(lane) = strand.start_twist_rate(edge);
        }
        let nodes = self.masses.len();
        self.forces.gather(nodes, |node| strand.force(node), |entry, value| entry.set_lane(lane, value.lane(0)));
        let air = |node| strand.air_velocity(node);
        self.air_velocities.gather(nodes, air, |entry, value| entry.set_lane(lane, value.lane(0)));
        self.anchors.gather(
            nodes,
            |node| strand.anchor(node),
            |entry, value| {
                entry.target.set_lane(lane, value.target.lane(0));
                entry.target_velocity.set_lane(lane, value.target_velocity.lane(0));
                *entry.stiffness.lane_mut(lane) = value.stiffness;
                *entry.damping.lane_mut(lane) = value.damping;
            },
        );
    }

    /// Takes `strand`'s current iterate into `lane`.
    fn gather_iterate(&mut self, lane: usize, strand: &impl InertiaSource<f64>) {
        for (node, position) in self.positions.iter_mut().enumerate() {
            position.set_lane(lane, strand.position(node).lane(0));
        }
        for (edge, change) in self.twist_changes.iter_mut().enumerate() {
            *change.lane_mut(lane) = strand.twist_change(edge);
        }
    }
}

impl InertiaSource<Lanes> for BatchInertia {
    #[inline(always)]
    fn node_count(&self) -> usize {
        self.masses.len()
    }

    #[inline(always)]
    fn scheme_step(&self) -> Lanes {
        self.scheme_step
    }

    #[inline(always)]
    fn mass(&self, node: usize) -> Lanes {
        self.masses[node]
    }

    #[inline(always)]
    fn position(&self, node: usize) -> Vector<Lanes> {
        self.positions[node]
    }

    #[inline(always)]
    fn predicted_position(&self, node: usize) -> Vector<Lanes> {
        self.predicted_positions[node]
    }

    #[inline(always)]
    fn predicted_velocity(&self, node: usize) -> Vector<Lanes> {
        self.predicted_velocities[node]
    }

    #[inline(always)]
    fn start_tangent(&self, edge: usize) -> Vector<Lanes> {
        self.start_tangents[edge]
    }

    #[inline(always)]
    fn force(&self, node: usize) -> Option<Vector<Lanes>> {
        self.forces.get(node)
    }

    #[inline(always)]
    fn air_velocity(&self, node: usize) -> Option<Vector<Lanes>> {
        self.air_velocities.get(node)
    }

    #[inline(always)]
    fn anchor(&self, node: usize) -> Option<NodeAnchor<Lanes>> {
        self.anchors.get(node)
    }

    #[inline(always)]
    fn twist_inertia(&self, edge: usize) -> Lanes {
        self.twist_inertias[edge]
    }

    #[inline(always)]
    fn twist_change(&self, edge: usize) -> Lanes {
        self.twist_changes[edge]
    }

    #[inline(always)]
    fn start_twist_rate(&self, edge: usize) -> Lanes {
        self.start_twist_rates[edge]
    }
}

/// What the projection onto the edge lengths works on for a batch's strands, lane by lane.
#[derive(Debug, Clone, Default)]
struct BatchProjection {
    points: Vec<Vector<Lanes>>,
    target_lengths: Vec<Lanes>,
    inverse_masses: Vec<Lanes>,
    contact_normals: Vec<Vector<Lanes>>,
    scratch: TridiagonalScratch<Lanes>,
}

impl BatchProjection {
    /// Sizes everything for strands of `nodes` nodes (allocating only when it grows).
    fn resize(&mut self, nodes: usize) {
        self.points.resize(nodes, Vector::default());
        self.target_lengths.resize(nodes - 1, Lanes::default());
        self.inverse_masses.resize(nodes, Lanes::default());
        self.contact_normals.resize(nodes, Vector::default());
    }

    /// Takes `rod`'s positions and what its projection holds it to into `lane` (but the target
    /// lengths, which [`batch_newton_update`] wrote).
    fn gather(&mut self, lane: usize, rod: &Rod, projection: &ProjectionScratch) {
        for (point, &position) in self.points.iter_mut().zip(rod.positions()) {
            point.set_lane(lane, position);
        }
        for (entry, &mass) in self.inverse_masses.iter_mut().zip(&projection.inverse_masses) {
            entry.0[lane] = mass;
        }
        for (entry, &normal) in self.contact_normals.iter_mut().zip(&projection.contact_normals) {
            entry.set_lane(lane, normal);
        }
    }

    /// Puts `lane`'s projected positions back into `rod`.
    fn scatter(&self, lane: usize, rod: &mut Rod) {
        for (position, point) in rod.state.positions.iter_mut().zip(&self.points) {
            *position = point.lane(lane);
        }
    }
}

/// The projection of a batch's `lanes` onto their edge lengths, compiled for the best instruction set
/// the CPU has (see [`factorize_best`]). Returns each lane's iterations.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn project_batch(batch: &mut BatchProjection, params: &StepParams, lanes: LaneMask) -> [u32; LANES] {
    let BatchProjection { points, target_lengths, inverse_masses, contact_normals, scratch } = batch;
    let constraints = LengthConstraints { target_lengths, inverse_masses, contact_normals: &contact_normals[..] };
    project_points(&mut points[..], &constraints, params, scratch, lanes)
}

/// `out = A x` for a batch's matrix, compiled for the best instruction set the CPU has (see
/// [`factorize_best`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn multiply_batch(matrix: &mut BatchMatrix, x: &[Lanes], out: &mut [Lanes]) {
    matrix.multiply(x, out);
}

/// The reference frames of a batch's strands, lane by lane, refreshed together.
#[derive(Debug, Clone, Default)]
struct BatchFrames {
    positions: Vec<Vector<Lanes>>,
    tangents: Vec<Vector<Lanes>>,
    directors: Vec<Vector<Lanes>>,
    reference_twist: Vec<Lanes>,
}

impl BatchFrames {
    /// Sizes everything for strands of `nodes` nodes (allocating only when it grows).
    fn resize(&mut self, nodes: usize) {
        self.positions.resize(nodes, Vector::default());
        self.tangents.resize(nodes - 1, Vector::default());
        self.directors.resize(nodes - 1, Vector::default());
        self.reference_twist.resize(nodes - 1, Lanes::default());
    }

    /// Takes `rod`'s positions and frames into `lane`.
    fn gather(&mut self, lane: usize, rod: &Rod) {
        for (entry, &position) in self.positions.iter_mut().zip(rod.positions()) {
            entry.set_lane(lane, position);
        }
        let frames = &rod.frames;
        for (entry, &tangent) in self.tangents.iter_mut().zip(&frames.tangents) {
            entry.set_lane(lane, tangent);
        }
        for (entry, &director) in self.directors.iter_mut().zip(&frames.reference_directors) {
            entry.set_lane(lane, director);
        }
        for (entry, &twist) in self.reference_twist.iter_mut().zip(&frames.reference_twist) {
            entry.0[lane] = twist;
        }
    }

    /// Puts `lane`'s refreshed frames back into `rod`.
    fn scatter(&self, lane: usize, rod: &mut Rod) {
        let frames = &mut rod.frames;
        for (tangent, entry) in frames.tangents.iter_mut().zip(&self.tangents) {
            *tangent = entry.lane(lane);
        }
        for (director, entry) in frames.reference_directors.iter_mut().zip(&self.directors) {
            *director = entry.lane(lane);
        }
        for (twist, entry) in frames.reference_twist.iter_mut().zip(&self.reference_twist) {
            *twist = entry.0[lane];
        }
    }
}

/// `Rod::refresh_frames` for every lane of a batch, compiled for the best instruction set the CPU has
/// (see [`factorize_best`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn refresh_batch_frames(frames: &mut BatchFrames) {
    let BatchFrames { positions, tangents, directors, reference_twist } = frames;
    let edge_count = tangents.len();
    carry_reference_frames(&positions[..], &mut tangents[..], &mut directors[..], reference_twist, edge_count);
}

/// Writes `lane`'s updated iterate (`positions`, `twists`) into its rod and its edges' target lengths
/// into its workspace, after [`batch_newton_update`].
fn scatter_update(
    lane: usize,
    (positions, twists, target_lengths): (&[Vector<Lanes>], &[Lanes], &[Lanes]),
    rod: &mut Rod,
    workspace: &mut RodWorkspace,
) {
    for (position, point) in rod.state.positions.iter_mut().zip(positions) {
        *position = point.lane(lane);
    }
    for (twist, entry) in rod.state.twist.iter_mut().zip(twists) {
        *twist = entry.0[lane];
    }
    let targets = &mut workspace.projection_mut().target_lengths;
    targets.clear();
    targets.extend(target_lengths.iter().map(|length| length.0[lane]));
}

/// `solver::newton_update` for a batch's lanes, compiled for the best instruction set the CPU has
/// (see [`factorize_best`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn batch_newton_update(
    positions: &mut [Vector<Lanes>],
    twist: &mut [Lanes],
    update: &[Lanes],
    rest_lengths: &[Lanes],
    free_edges: &[LaneMask],
    params: &StepParams,
    target_lengths: &mut Vec<Lanes>,
) -> (Lanes, LaneMask) {
    newton_update(positions, twist, update, rest_lengths, |edge| free_edges[edge], params, target_lengths)
}

/// The inertia terms of a batch, compiled for the best instruction set the CPU has (see
/// [`factorize_best`]).
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn add_batch_inertia_terms(
    source: &BatchInertia,
    params: &StepParams,
    residual: &mut [Lanes],
    matrix: &mut BatchMatrix,
) {
    add_inertia_terms(source, params, residual, matrix);
}

/// The elastic terms of a batch, compiled for the best instruction set the CPU has (see
/// [`factorize_best`]): the same bits on every one.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn add_batch_elastic_terms(source: &BatchElastic, gradient: &mut [Lanes], matrix: &mut BatchMatrix, scale: Lanes) {
    add_elastic_terms(source, gradient, Some((matrix, scale)));
}

/// The result of each strand of a batch, in the batch's order (`None` past its end).
pub type LockstepResults = [Option<Result<StepReport, StepError>>; LANES];

impl LockstepWorkspace {
    /// Advances up to [`LANES`] strands by `params.dt` together, each exactly as
    /// [`Rod::step_with_loads`] would (same result, bit for bit; the same roll-back on failure), and
    /// returns their results in order. Strands whose node count differs from the first's are stepped
    /// alone.
    ///
    /// # Panics
    /// With more than [`LANES`] strands.
    pub fn step(&mut self, params: &StepParams, strands: &mut [LockstepStrand]) -> LockstepResults {
        assert!(strands.len() <= LANES, "{} strands in a lockstep batch of {LANES}", strands.len());
        let mut results = LockstepResults::default();
        let Some(first) = strands.first() else {
            return results;
        };
        let nodes = first.rod.node_count();
        self.elastic.resize(nodes - 1);
        self.projection.resize(nodes);
        self.frames.resize(nodes);
        self.inertia.begin(nodes);
        self.free_edges.clear();
        self.free_edges.resize(nodes - 1, 0);
        let mut active: LaneMask = 0;
        for (lane, (strand, workspace)) in strands.iter_mut().zip(&mut self.lanes).enumerate() {
            let LockstepStrand { rod, loads, contacts } = strand;
            if rod.node_count() != nodes {
                results[lane] = Some(rod.step_with_loads(params, loads, contacts, workspace));
                continue;
            }
            if let Err(error) = rod.check_step_input(params, loads, contacts) {
                results[lane] = Some(Err(error));
                continue;
            }
            rod.begin_step(workspace);
            rod.begin_integration(params, contacts, workspace);
            self.elastic.gather_rest(lane, rod);
            self.inertia.gather_step(lane, &rod.inertia_source(workspace, loads));
            for (edge, free) in self.free_edges.iter_mut().enumerate() {
                *free |= LaneMask::from(rod.constraints.is_edge_free(edge)) << lane;
            }
            active |= 1 << lane;
        }
        let size = dof_count(nodes);
        let mut progress = [NewtonProgress::default(); LANES];
        while active != 0 {
            active = self.assemble_and_factorize(params, strands, active, size, &mut results);
            if active == 0 {
                break;
            }
            self.solve(active, size);
            // Each lane's contacts on its update, then the updates in lanes, written back to the rods.
            let mut contacts_changed = [false; LANES];
            for lane in lanes_in(active) {
                contacts_changed[lane] = strands[lane].rod.update_contacts_with(params, &mut self.lanes[lane]);
            }
            let (fractions, finite) = batch_newton_update(
                &mut self.inertia.positions,
                &mut self.elastic.edge_twists,
                &self.solution,
                &self.elastic.rest_lengths,
                &self.free_edges,
                params,
                &mut self.projection.target_lengths,
            );
            let mut last = [false; LANES];
            let mut projecting: LaneMask = 0;
            for lane in lanes_in(active) {
                let (rod, workspace) = (&mut *strands[lane].rod, &mut self.lanes[lane]);
                if finite & (1 << lane) == 0 {
                    let error = StepError::NonFinite { node: first_non_finite_update(&self.solution, lane) };
                    results[lane] = Some(rod.end_step(Err(error), workspace));
                    active &= !(1 << lane);
                    continue;
                }
                let updated =
                    (&self.inertia.positions[..], &self.elastic.edge_twists[..], &self.projection.target_lengths[..]);
                scatter_update(lane, updated, rod, workspace);
                let update = (fractions.0[lane], contacts_changed[lane]);
                last[lane] = rod.begin_projection(update, params, &mut progress[lane], workspace);
                self.projection.gather(lane, rod, workspace.projection());
                projecting |= 1 << lane;
            }
            let iterations = project_batch(&mut self.projection, params, projecting);
            // Each lane's frames are refreshed next, in lanes: after the projection, or, on its last
            // iteration, after its contacts and strain bound.
            let mut endings = [None; LANES];
            for lane in lanes_in(projecting) {
                let strand = &mut strands[lane];
                let (rod, workspace) = (&mut *strand.rod, &mut self.lanes[lane]);
                self.projection.scatter(lane, rod);
                rod.end_projection(iterations[lane], &mut progress[lane], workspace);
                if last[lane] {
                    endings[lane] = Some(rod.end_iterations(params, &strand.contacts, progress[lane], workspace));
                }
                self.frames.gather(lane, rod);
            }
            refresh_batch_frames(&mut self.frames);
            for lane in lanes_in(projecting) {
                let (rod, workspace) = (&mut *strands[lane].rod, &mut self.lanes[lane]);
                self.frames.scatter(lane, rod);
                if let Some(ending) = endings[lane] {
                    let result = rod.end_integration(params, ending, workspace);
                    results[lane] = Some(rod.end_step(result, workspace));
                    active &= !(1 << lane);
                }
            }
        }
        results
    }

    /// Assembles the Newton system of each `active` lane's strand and factorises them together, each
    /// lane with its own Levenberg–Marquardt shift (see [`Rod::step_with_loads`]). The elastic terms
    /// are assembled in lanes, straight into the batch's matrix; the others lane by lane. Returns the
    /// lanes still going: a lane whose system does not factorise even with the largest shift ends with
    /// its error in `results`.
    fn assemble_and_factorize(
        &mut self,
        params: &StepParams,
        strands: &mut [LockstepStrand],
        mut active: LaneMask,
        size: usize,
        results: &mut LockstepResults,
    ) -> LaneMask {
        let mut regularisation = [0.0; LANES];
        for lane in lanes_in(active) {
            let (rod, workspace) = (&*strands[lane].rod, &mut self.lanes[lane]);
            rod.clear_residual(workspace);
            self.elastic.gather_state(lane, rod);
            self.inertia.gather_iterate(lane, &rod.inertia_source(workspace, &strands[lane].loads));
        }
        batch_edge_frames(&mut self.elastic, &self.inertia.positions);
        loop {
            // Every going lane again: the factorisation wrote over the last attempt.
            self.matrix.reset(size);
            self.solution.clear();
            self.solution.resize(size, Lanes::default());
            let scale = Lanes::splat(damped_scale(params));
            add_batch_elastic_terms(&self.elastic, &mut self.solution, &mut self.matrix, scale);
            // Internal damping's product with the elastic terms' matrix, for every lane at once.
            self.displacement.clear();
            self.displacement.resize(size, Lanes::default());
            let mut damped: LaneMask = 0;
            for lane in lanes_in(active) {
                let workspace = &mut self.lanes[lane];
                if strands[lane].rod.damped_displacement(params, workspace) {
                    for (entry, &value) in self.displacement.iter_mut().zip(workspace.displacement()) {
                        entry.0[lane] = value;
                    }
                    damped |= 1 << lane;
                }
            }
            self.elastic_product.resize(size, Lanes::default());
            if damped != 0 {
                multiply_batch(&mut self.matrix, &self.displacement, &mut self.elastic_product);
                self.add_damping_forces(params, strands, damped);
            }
            add_batch_inertia_terms(&self.inertia, params, &mut self.solution, &mut self.matrix);
            for lane in lanes_in(active) {
                let workspace = &mut self.lanes[lane];
                for (residual, gradient) in workspace.residual_mut().iter_mut().zip(&self.solution) {
                    *residual = gradient.0[lane];
                }
                let mut matrix = MatrixLane {
                    matrix: &mut self.matrix,
                    lane,
                    scratch: &mut self.product_scratch,
                    elastic_product: &self.elastic_product,
                };
                strands[lane].rod.add_contact_terms(params, workspace, &mut matrix, regularisation[lane]);
            }
            self.add_prescribed_unknowns(strands, active, size);
            let mut rows = [0; LANES];
            let failed = factorize_best(&mut self.matrix, &mut rows) & active;
            if failed == 0 {
                return active;
            }
            for lane in lanes_in(failed) {
                match next_regularisation(regularisation[lane], rows[lane]) {
                    Ok(shift) => regularisation[lane] = shift,
                    Err(error) => {
                        results[lane] = Some(strands[lane].rod.end_step(Err(error), &mut self.lanes[lane]));
                        active &= !(1 << lane);
                    }
                }
            }
            if active == 0 {
                return 0;
            }
        }
    }

    /// Each `active` lane's prescribed unknowns ([`Rod::add_prescribed_unknowns`]). Where the lanes
    /// prescribe the same unknowns and the same span of them still moves (the strands of a head, each
    /// clamped at its root, do), the product that takes the displacements to the right-hand side and the
    /// identity rows are written for the whole batch, each lane with the operations it would do alone;
    /// otherwise lane by lane.
    fn add_prescribed_unknowns(&mut self, strands: &[LockstepStrand], active: LaneMask, size: usize) {
        self.prescribed.clear();
        self.prescribed.resize(size, Lanes::default());
        let mut shared: Option<(u128, MovingUnknowns)> = None;
        let mut alike = true;
        for lane in lanes_in(active) {
            let rod = &*strands[lane].rod;
            let (prescribed, mut moving) = (&mut self.prescribed, MovingUnknowns::default());
            rod.prescribed_displacements(|dof, offset| {
                prescribed[dof].0[lane] = offset;
                moving.include(dof, offset);
            });
            alike &= prescribed_set(rod).is_some_and(|set| *shared.get_or_insert((set, moving)) == (set, moving));
        }
        let Some((set, moving)) = shared.filter(|_| alike) else {
            for lane in lanes_in(active) {
                let mut matrix = MatrixLane {
                    matrix: &mut self.matrix,
                    lane,
                    scratch: &mut self.product_scratch,
                    elastic_product: &self.elastic_product,
                };
                strands[lane].rod.add_prescribed_unknowns(&mut self.lanes[lane], &mut matrix);
            }
            return;
        };
        if let Some(columns) = moving.columns() {
            self.prescribed_coupling.resize(size, Lanes::default());
            self.matrix.multiply_columns(columns, &self.prescribed, &mut self.prescribed_coupling);
            for lane in lanes_in(active) {
                let residual = self.lanes[lane].residual_mut().iter_mut();
                for (r, coupling) in residual.zip(&self.prescribed_coupling) {
                    *r += coupling.0[lane];
                }
            }
        }
        let mut rest = set;
        while rest != 0 {
            let dof = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            self.matrix.set_identity_row_in_every_lane(dof);
            for lane in lanes_in(active) {
                self.lanes[lane].residual_mut()[dof] = -self.prescribed[dof].0[lane];
            }
        }
    }

    /// Internal damping of the `damped` lanes (on the displacements and the elastic product in the
    /// workspace), added to the batch's residual in lanes.
    fn add_damping_forces(&mut self, params: &StepParams, strands: &[LockstepStrand], damped: LaneMask) {
        self.damping_force.clear();
        self.damping_force.resize(self.solution.len(), Lanes::default());
        let mut factor = 0.0;
        for lane in lanes_in(damped) {
            let workspace = &mut self.lanes[lane];
            self.elastic.scatter_edges(lane, workspace.edges_mut());
            let mut matrix = MatrixLane {
                matrix: &mut self.matrix,
                lane,
                scratch: &mut self.product_scratch,
                elastic_product: &self.elastic_product,
            };
            factor = strands[lane].rod.internal_damping_force(params, workspace, &mut matrix);
            for (entry, &force) in self.damping_force.iter_mut().zip(workspace.damping_force()) {
                entry.0[lane] = force;
            }
        }
        let factor = Lanes::splat(factor);
        for (residual, &force) in self.solution.iter_mut().zip(&self.damping_force) {
            *residual = Lanes::select(damped, *residual + factor * force, *residual);
        }
    }

    /// Solves each `active` lane's factorised system for its Newton update: in the batch's solution, and
    /// in each lane's workspace (where its contacts look at it, `Rod::update_contacts_with`).
    fn solve(&mut self, active: LaneMask, size: usize) {
        self.solution.clear();
        self.solution.resize(size, Lanes::default());
        for lane in lanes_in(active) {
            for (entry, residual) in self.solution.iter_mut().zip(self.lanes[lane].residual()) {
                entry.0[lane] = -residual;
            }
        }
        solve_best(&mut self.matrix, &mut self.solution);
        for lane in lanes_in(active) {
            for (residual, entry) in self.lanes[lane].residual_mut().iter_mut().zip(&self.solution) {
                *residual = entry.0[lane];
            }
        }
    }
}

/// `rod`'s prescribed unknowns as a set (bit `k` for unknown `k`), if all are among the first 128.
fn prescribed_set(rod: &Rod) -> Option<u128> {
    rod.prescribed_unknowns().try_fold(0_u128, |set, dof| (dof < 128).then(|| set | 1 << dof))
}

#[cfg(test)]
mod tests {
    use bevy::math::{DQuat, DVec3};

    use super::*;
    use crate::rod::test_support::Lcg;
    use crate::rod::{Anchor, ColliderShape, MovingCollider, RigidPose, RodMaterial};

    /// A 20 cm hair of `edges` edges leaving its root at `angle` from the horizontal, root clamped.
    fn hair(edges: usize, angle: f64) -> Rod {
        let direction = DVec3::new(angle.cos(), angle.sin(), 0.0);
        let nodes: Vec<DVec3> = (0..=edges).map(|i| 0.2 * i as f64 / edges as f64 * direction).collect();
        let mut rod = Rod::new(&nodes, DVec3::Z, RodMaterial::human_hair()).unwrap();
        rod.clamp_root_in_place();
        rod
    }

    /// Moves a root clamp by a shake and a turn at time `t` (s), as a head would.
    fn shake(rod: &mut Rod, root: [DVec3; 2], t: f64) {
        let turn = DQuat::from_rotation_y(3.0 * (7.0 * t).sin());
        let shift = DVec3::new(0.05 * (25.0 * t).sin(), 0.03 * (11.0 * t).cos(), 0.0);
        rod.clamp_edge(0, turn * root[0] + shift, turn * root[1] + shift, turn * DVec3::Z).unwrap();
    }

    /// Everything a step changes, for comparing two rods bit for bit.
    fn same_state(a: &Rod, b: &Rod) -> bool {
        a.state == b.state && a.frames == b.frames
    }

    #[test]
    fn a_batch_steps_each_strand_exactly_as_alone() {
        // Five hairs in a batch of four and one: different shapes, one with another node count (stepped
        // alone), a ball under two of them, wind on one, anchors on one, forces on one (not finite at
        // one step), and for a while a pin on one (so that its batch's prescribed unknowns differ).
        let angles = [0.0, 0.4, -0.7, 1.2, -0.2];
        let edge_counts = [24, 24, 24, 16, 24];
        let make = || -> Vec<Rod> { angles.iter().zip(edge_counts).map(|(&a, e)| hair(e, a)).collect() };
        let (mut alone, mut batched) = (make(), make());
        let roots: Vec<[DVec3; 2]> = alone.iter().map(|rod| [rod.positions()[0], rod.positions()[1]]).collect();
        let ball = MovingCollider::fixed(
            ColliderShape::sphere(0.08),
            0.3,
            RigidPose::new(DQuat::IDENTITY, DVec3::new(0.1, -0.1, 0.0)),
        );
        let colliders = [ball];
        let contacts = |strand: usize| Contacts {
            colliders: if strand.is_multiple_of(2) { &colliders } else { &[] },
            thickness: 1e-4,
        };
        let mut random = Lcg(3);
        let wind: Vec<DVec3> = (0..=24).map(|_| 3.0 * random.vector()).collect();
        let bad_forces = vec![DVec3::new(f64::NAN, 0.0, 0.0); 25];
        let forces: Vec<DVec3> = (0..=24).map(|_| 1e-6 * random.vector()).collect();
        let anchors: Vec<Anchor> = (0..=24)
            .map(|node| Anchor {
                target: DVec3::new(0.008 * node as f64, -0.002 * node as f64, 0.0),
                target_velocity: 0.1 * random.vector(),
                stiffness: 50.0,
                damping: 5.0,
            })
            .collect();
        let loads = |strand: usize, step: usize| StepLoads {
            air_velocities: (strand == 1).then_some(&wind[..]),
            forces: (strand == 2).then_some(if step == 7 { &bad_forces[..] } else { &forces[..] }),
            anchors: (strand == 0).then_some(&anchors[..]),
            ..StepLoads::default()
        };
        let params = StepParams::default();
        let (mut scalar, mut lockstep) = (RodWorkspace::default(), LockstepWorkspace::default());
        let (mut failures, mut iterations) = (0, 0);
        for step in 0..90 {
            let t = step as f64 * params.dt;
            for (index, rod) in alone.iter_mut().chain(batched.iter_mut()).enumerate() {
                shake(rod, roots[index % angles.len()], t);
                if index % angles.len() == 1 && step == 30 {
                    rod.pin_node(12, rod.positions()[12] + DVec3::new(0.0, 0.01, 0.0)).unwrap();
                } else if index % angles.len() == 1 && step == 60 {
                    rod.release_node(12).unwrap();
                }
            }
            let expected: Vec<_> = alone
                .iter_mut()
                .enumerate()
                .map(|(strand, rod)| rod.step_with_loads(&params, &loads(strand, step), &contacts(strand), &mut scalar))
                .collect();
            let mut results = Vec::new();
            for (chunk, rods) in batched.chunks_mut(LANES).enumerate() {
                let mut strands: Vec<LockstepStrand> = rods
                    .iter_mut()
                    .enumerate()
                    .map(|(lane, rod)| {
                        let strand = chunk * LANES + lane;
                        LockstepStrand { rod, loads: loads(strand, step), contacts: contacts(strand) }
                    })
                    .collect();
                let stepped = lockstep.step(&params, &mut strands);
                results.extend(stepped.into_iter().take(strands.len()).map(Option::unwrap));
            }
            // Compared as printed: the reported force that is not finite is NaN, which is not equal to itself.
            assert_eq!(format!("{results:?}"), format!("{expected:?}"), "step {step}");
            for (strand, (a, b)) in alone.iter().zip(&batched).enumerate() {
                assert!(same_state(a, b), "strand {strand} differs after step {step}");
            }
            failures += expected.iter().filter(|result| result.is_err()).count();
            iterations += expected.iter().filter_map(|r| r.as_ref().ok()).map(|r| r.newton_iterations).sum::<u32>();
        }
        assert_eq!(failures, 1, "the one step with a force that is not finite fails, alone");
        // The shaking makes strands take different numbers of Newton iterations, so that lanes end apart.
        assert!(iterations > 90 * 5, "{iterations} Newton iterations in 90 steps of 5 strands");
    }
}
