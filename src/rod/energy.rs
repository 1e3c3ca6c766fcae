//! Elastic energies of a rod (stretching, bending, twisting), their analytic gradients, and the
//! positive semi-definite Hessian approximation the implicit integrator uses.
//!
//! Unknowns are ordered `x_0, θ^0, x_1, θ^1, …, θ^{n−1}, x_n` (4 per edge, 3 for the last node), so a
//! bending or twisting term touches 11 consecutive unknowns and the Hessian has half-bandwidth 10.

use bevy::math::{DVec2, DVec3};

use super::banded::BandedMatrix;
use super::curve::Rod;

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
    out.clear();
    out.extend((0..rod.edge_count()).map(|edge| {
        let frame = rod.material_frame(edge);
        let length = (rod.state.positions[edge + 1] - rod.state.positions[edge]).length();
        EdgeGeometry { tangent: frame.tangent, length, inverse_length: 1.0 / length, m1: frame.m1, m2: frame.m2 }
    }));
}

/// Material curvatures and twist at one vertex with their gradients over the vertex's 11 unknowns
/// `[x_{i−1}, θ^{i−1}, x_i, θ^i, x_{i+1}]` (reference frames carried by time-parallel transport).
#[derive(Debug, Clone, Copy)]
pub(crate) struct VertexStrain {
    pub kappa: DVec2,
    pub twist: f64,
    pub grad_kappa_1: [f64; STENCIL],
    pub grad_kappa_2: [f64; STENCIL],
    pub grad_twist: [f64; STENCIL],
}

/// Writes the node gradients of a quantity from its edge gradients (`∂/∂x_{i−1} = −∂/∂e^{i−1}`,
/// `∂/∂x_i = ∂/∂e^{i−1} − ∂/∂e^i`, `∂/∂x_{i+1} = ∂/∂e^i`) and its two twist derivatives.
fn scatter_vertex_gradient(d_previous: DVec3, d_next: DVec3, d_theta: [f64; 2]) -> [f64; STENCIL] {
    let (a, b, c) = (-d_previous, d_previous - d_next, d_next);
    [a.x, a.y, a.z, d_theta[0], b.x, b.y, b.z, d_theta[1], c.x, c.y, c.z]
}

/// Curvatures `κ₁ = ½ κb·(m2^{i−1}+m2^i)`, `κ₂ = −½ κb·(m1^{i−1}+m1^i)`, twist `τ` and their gradients
/// (Bergou et al. 2008, §7; with `χ = 1 + t^{i−1}·t^i`, `t̃ = (t^{i−1}+t^i)/χ`, `m̃ = (m^{i−1}+m^i)/χ`).
pub(crate) fn vertex_strain(previous: &EdgeGeometry, next: &EdgeGeometry, twist: f64) -> VertexStrain {
    let (t0, t1) = (previous.tangent, next.tangent);
    // One division for the vertex: `1/χ`, with `κb = 2 t^{i−1} × t^i / χ` (see `curvature_binormal`).
    let inverse_chi = 1.0 / (1.0 + t0.dot(t1));
    let binormal = 2.0 * inverse_chi * t0.cross(t1);
    let tilde_t = inverse_chi * (t0 + t1);
    let tilde_m1 = inverse_chi * (previous.m1 + next.m1);
    let tilde_m2 = inverse_chi * (previous.m2 + next.m2);
    let kappa_1 = 0.5 * binormal.dot(previous.m2 + next.m2);
    let kappa_2 = -0.5 * binormal.dot(previous.m1 + next.m1);
    let (inverse_0, inverse_1) = (previous.inverse_length, next.inverse_length);

    let grad_kappa_1 = scatter_vertex_gradient(
        (-kappa_1 * tilde_t + t1.cross(tilde_m2)) * inverse_0,
        (-kappa_1 * tilde_t - t0.cross(tilde_m2)) * inverse_1,
        [-0.5 * binormal.dot(previous.m1), -0.5 * binormal.dot(next.m1)],
    );
    let grad_kappa_2 = scatter_vertex_gradient(
        (-kappa_2 * tilde_t - t1.cross(tilde_m1)) * inverse_0,
        (-kappa_2 * tilde_t + t0.cross(tilde_m1)) * inverse_1,
        [-0.5 * binormal.dot(previous.m2), -0.5 * binormal.dot(next.m2)],
    );
    let grad_twist = scatter_vertex_gradient(0.5 * binormal * inverse_0, 0.5 * binormal * inverse_1, [-1.0, 1.0]);
    VertexStrain { kappa: DVec2::new(kappa_1, kappa_2), twist, grad_kappa_1, grad_kappa_2, grad_twist }
}

/// Adds `Σ_k scales_k · g_k g_kᵀ` (the Gauss–Newton terms of one vertex) to the Hessian, over the vertex
/// stencil whose first unknown is `offset`, writing each row's band as one contiguous run.
fn add_vertex_hessian(hessian: &mut RodMatrix, offset: usize, scales: [f64; 3], gradients: [&[f64; STENCIL]; 3]) {
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
fn add_edge_hessian(hessian: &mut RodMatrix, start: usize, block: &[[f64; 3]; 3]) {
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
    mut hessian: Option<(&mut RodMatrix, f64)>,
) {
    let stiffness = *rod.stiffness();
    for (edge, geometry) in edges.iter().enumerate() {
        let rest = rod.rest.lengths[edge];
        let force = stiffness.stretching * (geometry.length / rest - 1.0);
        let (start, end) = (node_dof(edge), node_dof(edge + 1));
        for axis in 0..3 {
            gradient[start + axis] -= force * geometry.tangent[axis];
            gradient[end + axis] += force * geometry.tangent[axis];
        }
        if let Some((hessian, scale)) = hessian.as_mut() {
            let axial = *scale * stiffness.stretching / rest;
            let transverse = axial * (1.0 - rest / geometry.length).max(0.0);
            let t = geometry.tangent.to_array();
            let block = std::array::from_fn(|a| {
                std::array::from_fn(|b| (axial - transverse) * t[a] * t[b] + if a == b { transverse } else { 0.0 })
            });
            add_edge_hessian(hessian, start, &block);
        }
    }
    for vertex in 1..rod.edge_count() {
        let twist = rod.state.twist[vertex] - rod.state.twist[vertex - 1] + rod.frames.reference_twist[vertex];
        let strain = vertex_strain(&edges[vertex - 1], &edges[vertex], twist);
        let inverse_length = 1.0 / rod.rest.voronoi_lengths[vertex];
        let bend = strain.kappa - rod.rest.curvatures[vertex];
        let turn = strain.twist - rod.rest.twists[vertex];
        let coefficients = [
            (stiffness.bending_1 * inverse_length, bend.x, &strain.grad_kappa_1),
            (stiffness.bending_2 * inverse_length, bend.y, &strain.grad_kappa_2),
            (stiffness.twisting * inverse_length, turn, &strain.grad_twist),
        ];
        let offset = node_dof(vertex - 1);
        for (modulus, deviation, grad) in coefficients {
            for (slot, value) in gradient[offset..offset + STENCIL].iter_mut().zip(grad) {
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
