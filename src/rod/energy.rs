//! Elastic energies of a rod (stretching, bending, twisting), their analytic gradients, and the
//! positive semi-definite Hessian approximation the implicit integrator uses.
//!
//! Unknowns are ordered `x_0, θ^0, x_1, θ^1, …, θ^{n−1}, x_n` (4 per edge, 3 for the last node), so a
//! bending or twisting term touches 11 consecutive unknowns and the Hessian has half-bandwidth 10.

use bevy::math::DVec3;

use super::banded::BandedMatrix;
use super::curve::Rod;
use super::frames::directors_turned_by;
use super::lanes::{Real, Vector, matrix3};

/// Half-bandwidth of a rod's Hessian in the interleaved ordering.
pub(crate) const BANDWIDTH: usize = 10;
/// The banded matrix of a rod's implicit system.
pub(crate) type RodMatrix = BandedMatrix<BANDWIDTH>;
/// Number of unknowns a vertex's bending and twisting terms touch.
const STENCIL: usize = 11;

/// Index of the first coordinate of node `node` in the interleaved ordering.
#[inline]
pub(crate) fn node_dof(node: usize) -> usize {
    4 * node
}

/// Index of edge `edge`'s twist angle in the interleaved ordering.
#[inline]
pub(crate) fn twist_dof(edge: usize) -> usize {
    4 * edge + 3
}

/// Number of unknowns of a rod with `node_count` nodes.
#[inline]
pub(crate) fn dof_count(node_count: usize) -> usize {
    4 * node_count - 1
}

/// Elastic energy of a rod split by mode, J.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ElasticEnergy {
    /// `Σ ½ EA (|e|/|ē| − 1)² |ē|`.
    pub stretching: f64,
    /// `Σ [EI₁ (κ₁ − κ̄₁)² + EI₂ (κ₂ − κ̄₂)²] / (2 l_i)`.
    pub bending: f64,
    /// `Σ GJ (τ − τ̄)² / (2 l_i)`.
    pub twisting: f64,
}

impl ElasticEnergy {
    /// Sum of the three modes, J.
    pub fn total(&self) -> f64 {
        self.stretching + self.bending + self.twisting
    }
}

/// Current geometry of one edge: unit tangent, length and material directors.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct EdgeGeometry {
    pub tangent: DVec3,
    pub length: f64,
    pub inverse_length: f64,
    pub m1: DVec3,
    pub m2: DVec3,
}

/// Fills `out` with each edge's geometry (frames must be fresh: see `Rod::refresh_frames`).
pub(crate) fn edge_geometry(rod: &Rod, out: &mut Vec<EdgeGeometry>) {
    let (positions, frames, twist) = (&rod.state.positions, &rod.frames, &rod.state.twist);
    out.clear();
    out.extend((0..rod.edge_count()).map(|edge| {
        let frame = edge_frame::<f64>(
            positions[edge].into(),
            positions[edge + 1].into(),
            frames.tangents[edge].into(),
            frames.reference_directors[edge].into(),
            twist[edge],
        );
        EdgeGeometry::from(&frame)
    }));
}

/// An edge's geometry from its end points, its unit tangent and reference director (fresh) and its
/// twist `θ`, for one strand or a lockstep batch: `|e|`, `1/|e|` and the material directors
/// ([`super::frames::material_directors`]).
#[inline(always)]
pub(crate) fn edge_frame<T: Real>(
    start: Vector<T>,
    end: Vector<T>,
    tangent: Vector<T>,
    reference: Vector<T>,
    twist: T,
) -> EdgeFrame<T> {
    let length = (end - start).length();
    let (m1, m2) = directors_turned_by(reference, tangent, twist);
    EdgeFrame { tangent, length, inverse_length: T::splat(1.0) / length, m1, m2 }
}

impl From<&EdgeFrame<f64>> for EdgeGeometry {
    #[inline(always)]
    fn from(frame: &EdgeFrame<f64>) -> Self {
        Self {
            tangent: frame.tangent.lane(0),
            length: frame.length,
            inverse_length: frame.inverse_length,
            m1: frame.m1.lane(0),
            m2: frame.m2.lane(0),
        }
    }
}

/// An edge's geometry as the elastic terms read it: [`EdgeGeometry`] for one strand (`f64`), or the
/// same of every strand of a lockstep batch ([`Lanes`](super::lanes::Lanes)).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct EdgeFrame<T> {
    pub tangent: Vector<T>,
    pub length: T,
    pub inverse_length: T,
    pub m1: Vector<T>,
    pub m2: Vector<T>,
}

impl From<&EdgeGeometry> for EdgeFrame<f64> {
    #[inline(always)]
    fn from(edge: &EdgeGeometry) -> Self {
        Self {
            tangent: edge.tangent.into(),
            length: edge.length,
            inverse_length: edge.inverse_length,
            m1: edge.m1.into(),
            m2: edge.m2.into(),
        }
    }
}

/// The elastic moduli the terms weigh their strains with (see [`Stiffness`]), N and N·m².
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Moduli<T> {
    pub stretching: T,
    pub bending_1: T,
    pub bending_2: T,
    pub twisting: T,
}

/// What the elastic terms read of a strand: one strand's own data (`T = f64`), or that of every strand
/// of a lockstep batch, lane by lane.
pub(crate) trait ElasticSource<T: Real> {
    /// Number of edges.
    fn edge_count(&self) -> usize;
    /// The moduli.
    fn moduli(&self) -> Moduli<T>;
    /// The current geometry of an edge.
    fn edge(&self, edge: usize) -> EdgeFrame<T>;
    /// The rest length `|ē|` of an edge, m.
    fn rest_length(&self, edge: usize) -> T;
    /// The twist `θ^i − θ^{i−1} + m_ref,i` at an interior vertex, rad.
    fn twist(&self, vertex: usize) -> T;
    /// The Voronoi length `l_i` of an interior vertex, m.
    fn voronoi_length(&self, vertex: usize) -> T;
    /// The rest curvatures `(κ̄₁, κ̄₂)` of an interior vertex.
    fn rest_curvature(&self, vertex: usize) -> [T; 2];
    /// The rest twist `τ̄` of an interior vertex, rad.
    fn rest_twist(&self, vertex: usize) -> T;
}

/// One strand's elastic data: the rod and its edges' geometry (from [`edge_geometry`]).
pub(crate) struct StrandElastic<'a> {
    pub rod: &'a Rod,
    pub edges: &'a [EdgeGeometry],
}

impl ElasticSource<f64> for StrandElastic<'_> {
    #[inline(always)]
    fn edge_count(&self) -> usize {
        self.rod.edge_count()
    }

    #[inline(always)]
    fn moduli(&self) -> Moduli<f64> {
        let stiffness = self.rod.stiffness();
        Moduli {
            stretching: stiffness.stretching,
            bending_1: stiffness.bending_1,
            bending_2: stiffness.bending_2,
            twisting: stiffness.twisting,
        }
    }

    #[inline(always)]
    fn edge(&self, edge: usize) -> EdgeFrame<f64> {
        (&self.edges[edge]).into()
    }

    #[inline(always)]
    fn rest_length(&self, edge: usize) -> f64 {
        self.rod.rest.lengths[edge]
    }

    #[inline(always)]
    fn twist(&self, vertex: usize) -> f64 {
        vertex_twist(self.rod, vertex)
    }

    #[inline(always)]
    fn voronoi_length(&self, vertex: usize) -> f64 {
        self.rod.rest.voronoi_lengths[vertex]
    }

    #[inline(always)]
    fn rest_curvature(&self, vertex: usize) -> [f64; 2] {
        self.rod.rest.curvatures[vertex].to_array()
    }

    #[inline(always)]
    fn rest_twist(&self, vertex: usize) -> f64 {
        self.rod.rest.twists[vertex]
    }
}

/// The twist `θ^i − θ^{i−1} + m_ref,i` at interior vertex `vertex` of a rod, rad.
#[inline(always)]
pub(crate) fn vertex_twist(rod: &Rod, vertex: usize) -> f64 {
    rod.state.twist[vertex] - rod.state.twist[vertex - 1] + rod.frames.reference_twist[vertex]
}

/// Material curvatures and twist at one vertex with their gradients over the vertex's 11 unknowns
/// `[x_{i−1}, θ^{i−1}, x_i, θ^i, x_{i+1}]` (reference frames carried by time-parallel transport).
#[derive(Debug, Clone, Copy)]
pub(crate) struct VertexStrain<T = f64> {
    pub kappa: [T; 2],
    pub twist: T,
    pub grad_kappa_1: [T; STENCIL],
    pub grad_kappa_2: [T; STENCIL],
    pub grad_twist: [T; STENCIL],
}

/// Writes the node gradients of a quantity from its edge gradients (`∂/∂x_{i−1} = −∂/∂e^{i−1}`,
/// `∂/∂x_i = ∂/∂e^{i−1} − ∂/∂e^i`, `∂/∂x_{i+1} = ∂/∂e^i`) and its two twist derivatives.
#[inline(always)]
fn scatter_vertex_gradient<T: Real>(d_previous: Vector<T>, d_next: Vector<T>, d_theta: [T; 2]) -> [T; STENCIL] {
    let (a, b, c) = (-d_previous, d_previous - d_next, d_next);
    [a.x, a.y, a.z, d_theta[0], b.x, b.y, b.z, d_theta[1], c.x, c.y, c.z]
}

/// Curvatures `κ₁ = ½ κb·(m2^{i−1}+m2^i)`, `κ₂ = −½ κb·(m1^{i−1}+m1^i)`, twist `τ` and their gradients
/// (Bergou et al. 2008, §7; with `χ = 1 + t^{i−1}·t^i`, `t̃ = (t^{i−1}+t^i)/χ`, `m̃ = (m^{i−1}+m^i)/χ`).
pub(crate) fn vertex_strain(previous: &EdgeGeometry, next: &EdgeGeometry, twist: f64) -> VertexStrain {
    strain_at(&previous.into(), &next.into(), twist)
}

/// [`vertex_strain`] for one strand or a batch's lanes.
#[inline(always)]
fn strain_at<T: Real>(previous: &EdgeFrame<T>, next: &EdgeFrame<T>, twist: T) -> VertexStrain<T> {
    let (t0, t1) = (previous.tangent, next.tangent);
    let (one, half) = (T::splat(1.0), T::splat(0.5));
    // One division for the vertex: `1/χ`, with `κb = 2 t^{i−1} × t^i / χ` (see `curvature_binormal`).
    let inverse_chi = one / (one + t0.dot(t1));
    let binormal = t0.cross(t1).scale(T::splat(2.0) * inverse_chi);
    let tilde_t = (t0 + t1).scale(inverse_chi);
    let tilde_m1 = (previous.m1 + next.m1).scale(inverse_chi);
    let tilde_m2 = (previous.m2 + next.m2).scale(inverse_chi);
    let kappa_1 = half * binormal.dot(previous.m2 + next.m2);
    let kappa_2 = -half * binormal.dot(previous.m1 + next.m1);
    let (inverse_0, inverse_1) = (previous.inverse_length, next.inverse_length);

    let grad_kappa_1 = scatter_vertex_gradient(
        (tilde_t.scale(-kappa_1) + t1.cross(tilde_m2)).scale(inverse_0),
        (tilde_t.scale(-kappa_1) - t0.cross(tilde_m2)).scale(inverse_1),
        [-half * binormal.dot(previous.m1), -half * binormal.dot(next.m1)],
    );
    let grad_kappa_2 = scatter_vertex_gradient(
        (tilde_t.scale(-kappa_2) - t1.cross(tilde_m1)).scale(inverse_0),
        (tilde_t.scale(-kappa_2) + t0.cross(tilde_m1)).scale(inverse_1),
        [-half * binormal.dot(previous.m2), -half * binormal.dot(next.m2)],
    );
    let grad_twist = scatter_vertex_gradient(
        binormal.scale(half).scale(inverse_0),
        binormal.scale(half).scale(inverse_1),
        [-one, one],
    );
    VertexStrain { kappa: [kappa_1, kappa_2], twist, grad_kappa_1, grad_kappa_2, grad_twist }
}

/// Adds `Σ_k scales_k · g_k g_kᵀ` (the Gauss–Newton terms of one vertex) to the Hessian, over the vertex
/// stencil whose first unknown is `offset`, writing each row's band as one contiguous run.
#[inline(always)]
fn add_vertex_hessian<T: Real>(
    hessian: &mut BandedMatrix<BANDWIDTH, T>,
    offset: usize,
    scales: [T; 3],
    gradients: [&[T; STENCIL]; 3],
) {
    const WIDTH: usize = BANDWIDTH + 1;
    let rows = hessian.band_rows_mut(offset..offset + STENCIL);
    let [g0, g1, g2] = gradients;
    for (a, band) in rows.chunks_exact_mut(WIDTH).enumerate() {
        let [w0, w1, w2] = [scales[0] * g0[a], scales[1] * g1[a], scales[2] * g2[a]];
        // Columns `offset ..= offset + a` sit at positions `BANDWIDTH − a ..= BANDWIDTH`.
        for (b, entry) in band[BANDWIDTH - a..].iter_mut().enumerate() {
            *entry += w0 * g0[b] + w1 * g1[b] + w2 * g2[b];
        }
    }
}

/// Adds the stretching Hessian block `K` of the edge whose first unknown is `start` (its nodes at
/// `start` and `start + 4`): `K` on both diagonal blocks and `−K` between them.
#[inline(always)]
fn add_edge_hessian<T: Real>(hessian: &mut BandedMatrix<BANDWIDTH, T>, start: usize, block: &[[T; 3]; 3]) {
    const WIDTH: usize = BANDWIDTH + 1;
    let (first_node, second_node) = hessian.band_rows_mut(start..start + 7).split_at_mut(4 * WIDTH);
    for a in 0..3 {
        let first_row = &mut first_node[a * WIDTH..(a + 1) * WIDTH];
        let second_row = &mut second_node[a * WIDTH..(a + 1) * WIDTH];
        for b in 0..3 {
            // In row `start + 4 + a`, column `start + b` sits at `BANDWIDTH − 4 − a + b` and column
            // `start + 4 + b` at `BANDWIDTH − a + b`.
            second_row[BANDWIDTH - 4 - a + b] -= block[a][b];
            if b <= a {
                first_row[BANDWIDTH - a + b] += block[a][b];
                second_row[BANDWIDTH - a + b] += block[a][b];
            }
        }
    }
}

impl Rod {
    /// The rod's elastic energy by mode at its current configuration, J.
    pub fn elastic_energy(&self) -> ElasticEnergy {
        let stiffness = self.stiffness();
        let mut energy = ElasticEnergy::default();
        for (pair, &rest) in self.state.positions.windows(2).zip(&self.rest.lengths) {
            let strain = (pair[1] - pair[0]).length() / rest - 1.0;
            energy.stretching += 0.5 * stiffness.stretching * strain * strain * rest;
        }
        for vertex in 1..self.edge_count() {
            let (kappa, twist) = self.vertex_curvature_and_twist(vertex);
            let (bend, turn) = (kappa - self.rest.curvatures[vertex], twist - self.rest.twists[vertex]);
            let length = self.rest.voronoi_lengths[vertex];
            energy.bending +=
                (stiffness.bending_1 * bend.x * bend.x + stiffness.bending_2 * bend.y * bend.y) / (2.0 * length);
            energy.twisting += stiffness.twisting * turn * turn / (2.0 * length);
        }
        energy
    }
}

/// Adds the elastic energy's gradient (N for positions, N·m for twists) to `gradient`, and, when given
/// `(hessian, scale)`, its Hessian approximation times `scale` to `hessian`: the exact stretching
/// Hessian with its transverse part clipped at zero under compression, and the Gauss–Newton bending
/// and twisting terms `Σ ∇κᵀ B ∇κ / l` — all positive semi-definite, so the implicit system stays
/// positive definite.
pub(crate) fn add_elastic_derivatives(
    rod: &Rod,
    edges: &[EdgeGeometry],
    gradient: &mut [f64],
    hessian: Option<(&mut RodMatrix, f64)>,
) {
    add_elastic_terms(&StrandElastic { rod, edges }, gradient, hessian);
}

/// [`add_elastic_derivatives`] for one strand, or for every strand of a lockstep batch at once (the
/// same operations in the same order in every lane).
#[inline(always)]
pub(crate) fn add_elastic_terms<T: Real>(
    source: &impl ElasticSource<T>,
    gradient: &mut [T],
    mut hessian: Option<(&mut BandedMatrix<BANDWIDTH, T>, T)>,
) {
    let moduli = source.moduli();
    let (zero, one) = (T::splat(0.0), T::splat(1.0));
    for edge in 0..source.edge_count() {
        let geometry = source.edge(edge);
        let rest = source.rest_length(edge);
        let force = moduli.stretching * (geometry.length / rest - one);
        let (start, end) = (node_dof(edge), node_dof(edge + 1));
        let t = geometry.tangent.to_array();
        for axis in 0..3 {
            gradient[start + axis] -= force * t[axis];
            gradient[end + axis] += force * t[axis];
        }
        if let Some((hessian, scale)) = hessian.as_mut() {
            let axial = *scale * moduli.stretching / rest;
            let transverse = axial * (one - rest / geometry.length).max(zero);
            let block = matrix3(|a, b| (axial - transverse) * t[a] * t[b] + if a == b { transverse } else { zero });
            add_edge_hessian(hessian, start, &block);
        }
    }
    for vertex in 1..source.edge_count() {
        let strain = strain_at(&source.edge(vertex - 1), &source.edge(vertex), source.twist(vertex));
        let inverse_length = one / source.voronoi_length(vertex);
        let rest_curvature = source.rest_curvature(vertex);
        let bend = [strain.kappa[0] - rest_curvature[0], strain.kappa[1] - rest_curvature[1]];
        let turn = strain.twist - source.rest_twist(vertex);
        let coefficients = [
            (moduli.bending_1 * inverse_length, bend[0], &strain.grad_kappa_1),
            (moduli.bending_2 * inverse_length, bend[1], &strain.grad_kappa_2),
            (moduli.twisting * inverse_length, turn, &strain.grad_twist),
        ];
        let offset = node_dof(vertex - 1);
        for (modulus, deviation, grad) in coefficients {
            for (slot, &value) in gradient[offset..offset + STENCIL].iter_mut().zip(grad) {
                *slot += modulus * deviation * value;
            }
        }
        if let Some((hessian, scale)) = hessian.as_mut() {
            add_vertex_hessian(
                hessian,
                offset,
                coefficients.map(|(modulus, ..)| *scale * modulus),
                coefficients.map(|(.., grad)| grad),
            );
        }
    }
}

#[cfg(test)]
mod tests;
