//! Gravity preloading (sag-free rest shapes): rest curvatures and twists that make a rod's current shape
//! its static equilibrium under gravity, so that a groomed strand keeps its groomed shape instead of
//! sagging as soon as it is simulated (the inverse statics of Derouet-Jourdan et al. 2010, here on the
//! discrete rod of Bergou et al. 2008).
//!
//! **Method.** The root edge is held (nodes 0 and 1, twist 0). Equilibrium at every other unknown is
//! `Σ_v s_v · ∇(κ₁, κ₂, τ)_v + Σ_j T_j ∇|e^j| = m g` (at nodes; zero at twists), with the bending and
//! twisting stresses `s_v = (EI₁ (κ₁ − κ̄₁), EI₂ (κ₂ − κ̄₂), GJ (τ − τ̄)) / l_v` and the edge tensions `T_j`.
//! A vertex's terms touch the nodes `v − 1 … v + 1`, so the system is triangular from the tip: node
//! `v + 1`'s three force equations and edge `v`'s twist equation give `s_v` and `T_v` by one 4 × 4 solve,
//! once the vertices beyond are known. The rest curvature and twist follow from `s_v`; the tension is
//! the inextensible rod's own (a strain of `T/EA`, around 1e-9 for hair).
//!
//! A node resting on a collider (`supports`: the outward normal of the surface under it) passes to it the
//! part of its load that pushes into the surface, as a frictionless support would: hair lying on the top
//! of a skull needs no preload there, hair lying on its steep sides is held by its bending stiffness and
//! its tension from the root against the part of its weight along the surface. Friction, which the
//! simulation has, only adds to what holds it.
//!
//! **Safeguards.** Where no sensible rest shape exists (a long strand held out sideways needs rest curls
//! tighter than its edges), each vertex's rest curvature is bounded at [`MAX_PRELOAD_TURN`] and its rest
//! twist at [`MAX_REST_TWIST`]: such a strand sags to where the bounded rest shape holds it, and the
//! report counts the vertices that were bounded. Gravity is baked into the rest shape, not applied as a
//! force: turned upside down or under another gravity, the hair responds physically.

use bevy::math::{DMat4, DVec2, DVec3, DVec4};

use super::curve::{MAX_REST_TWIST, MAX_TURNING_ANGLE, Rod};
use super::energy::{EdgeGeometry, edge_geometry, vertex_strain, vertex_twist};
use super::error::RodError;

/// The largest turn between two edges a preloaded rest shape asks for, rad (150°): short of
/// [`MAX_TURNING_ANGLE`], so that a strand preloaded to the bound can still bend further under load.
pub const MAX_PRELOAD_TURN: f64 = 150.0 * std::f64::consts::PI / 180.0;

/// Greenhill's self-weight buckling number: a straight uniform column clamped upright at its foot and
/// free at its top buckles under its own weight once `ρ A g L³ / EI` exceeds 7.837 (Greenhill 1881;
/// Timoshenko & Gere, *Theory of Elastic Stability*, 1961, §2.13). For human hair (r = 40 µm,
/// E = 3.5 GPa) that is at `L` = 9.5 cm.
pub const SELF_WEIGHT_BUCKLING: f64 = 7.837;

/// The load a stiffened rod can hold upright, in multiples of its own weight ([`Rod::stiffening_to_hold`]):
/// at exactly Greenhill's number the upright column has no stiffness left against buckling, and the
/// smallest push would move it far.
const HOLDING_MARGIN: f64 = 2.0;

/// How far the preload's rest curvature may point against the current curvature at a vertex
/// ([`Rod::stiffening_to_hold`]): `κ · κ̄ ≥ −FLIP_MARGIN · GJ / EI` (integrated curvatures). Measured on
/// 40 cm hair combed round a 9 cm skull that is not there (24 edges): strands fell from `−0.43 GJ / EI`
/// and held from `−0.17 GJ / EI`; 0.1 leaves a margin of about two.
pub const FLIP_MARGIN: f64 = 0.1;

/// The largest twisting moment a preloaded rod may carry, as `M_t L / GJ` ([`Rod::stiffening_to_hold`]):
/// Greenhill's twisted shaft buckles at `2π EI / GJ` (8.6 for human hair); the same strands fell from
/// 12.3 and held up to 14.2 alongside little bending; 7.5 leaves a margin.
pub const TWIST_HOLDING: f64 = 7.5;

/// How far from straight down every edge of a rod (past its root edge) may point and the rod still hang
/// in [`Rod::stiffening_to_hold`], as the cosine of the angle: 60°.
const HANGING_COSINE: f64 = 0.5;

/// What [`Rod::preload_for_gravity`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PreloadReport {
    /// Interior vertices whose rest curvature or twist had to be bounded (the strand will sag there).
    pub bounded_vertices: usize,
    /// Largest change of rest curvature, integrated (dimensionless).
    pub max_curvature_change: f64,
    /// Nodes resting on a collider.
    pub supported_nodes: usize,
}

impl Rod {
    /// Gives the rod rest curvatures and twists in which its current shape is in static equilibrium
    /// under `gravity` (m/s²), with the root edge held and each node for which `supports` gives the
    /// outward unit normal of a surface resting on it (one entry per node, `None` for a free node);
    /// `factor` (0 to 1) blends from the current rest shape (0) to the sag-free one (1). Rest lengths are
    /// kept. The derivation is in the module documentation of `src/rod/preload.rs`.
    ///
    /// Rejects a non-finite `gravity`, a `factor` outside 0 to 1, `supports` of the wrong length or with
    /// a normal that is not finite, and leaves the rod unchanged.
    pub fn preload_for_gravity(
        &mut self,
        gravity: DVec3,
        supports: &[Option<DVec3>],
        factor: f64,
    ) -> Result<PreloadReport, RodError> {
        if !gravity.is_finite() {
            return Err(RodError::InvalidPreload {
                parameter: "gravity",
                value: gravity.length(),
                requirement: "must be finite",
            });
        }
        if !(0.0..=1.0).contains(&factor) {
            return Err(RodError::InvalidPreload {
                parameter: "factor",
                value: factor,
                requirement: "must lie in 0 to 1",
            });
        }
        if supports.len() != self.node_count() {
            return Err(RodError::WrongLength { expected: self.node_count(), actual: supports.len() });
        }
        if let Some(normal) = supports.iter().flatten().find(|normal| !normal.is_finite()) {
            return Err(RodError::InvalidPreload {
                parameter: "support normal",
                value: normal.length(),
                requirement: "must be finite",
            });
        }
        let changes = self.sag_free_changes(gravity, supports);
        let mut report =
            PreloadReport { supported_nodes: supports.iter().flatten().count(), ..PreloadReport::default() };
        let largest = 2.0 * (0.5 * MAX_PRELOAD_TURN).tan();
        for (vertex, change) in changes.iter().enumerate() {
            let Some((bend, turn)) = *change else {
                continue;
            };
            let (kappa, twist) = self.vertex_curvature_and_twist(vertex);
            let sag_free = kappa - bend;
            let old = self.rest.curvatures[vertex];
            let mut curvature = old + factor * (sag_free - old);
            if curvature.length() > largest {
                curvature *= largest / curvature.length();
                report.bounded_vertices += 1;
            }
            report.max_curvature_change = report.max_curvature_change.max((curvature - old).length());
            let sag_free_twist = twist - turn;
            let old_twist = self.rest.twists[vertex];
            let rest_twist = old_twist + factor * (sag_free_twist - old_twist);
            if rest_twist.abs() > MAX_REST_TWIST {
                report.bounded_vertices += 1;
            }
            self.rest.curvatures[vertex] = curvature;
            self.rest.twists[vertex] = rest_twist.clamp(-MAX_REST_TWIST, MAX_REST_TWIST);
        }
        debug_assert!(largest < 2.0 * (0.5 * MAX_TURNING_ANGLE).tan());
        Ok(report)
    }

    /// By how much the rod's bending and twisting stiffness must grow (a factor, at least 1) for its
    /// current shape, once preloaded ([`Rod::preload_for_gravity`], with the same `supports`), to be a
    /// stable equilibrium under `gravity` (m/s²): the largest of three factors.
    ///
    /// - **Held up or out** (Greenhill): a rod whose edges past the root edge all point within 60° of
    ///   straight down hangs, held by its tension: 1. Any other must be short enough to hold up twice its
    ///   weight: twice its self-weight number `ρ A |g| L³ / EI` (`L` its length past the root edge, `EI`
    ///   the smaller bending stiffness) over Greenhill's [`SELF_WEIGHT_BUCKLING`] (human hair leaving the
    ///   scalp upwards or sideways is stiffened past 7.5 cm).
    /// - **Bent against its rest curl**: where the preload's rest curvature `κ̄` points against the
    ///   current curvature `κ` (integrated, `κ · κ̄ < 0`), turning the cross-section over releases
    ///   bending energy `EI κ · κ̄ / l` faster than twisting it costs (about `GJ / l`), and the strand
    ///   flips over and falls: hair combed round a skull that is not there. Stiffening by `k` leaves
    ///   `κ̄ = κ − Δκ / k`; `k` is the least that keeps `κ · κ̄ ≥ −`[`FLIP_MARGIN`]` · GJ / EI` at every
    ///   vertex.
    /// - **Twisted**: a twisting moment `M_t` buckles a rod of length `L` once `M_t L / GJ` passes a few
    ///   (Greenhill's twisted shaft: `2π EI / GJ`); `k` keeps it at most [`TWIST_HOLDING`].
    ///
    /// Preloading alone makes any shape an equilibrium, but not a stable one: a strand standing up, held
    /// out sideways, or combed round a head it does not lie on, buckles at the smallest disturbance and
    /// falls. (Takahashi & Batty, "Rest Shape Optimization for Sag-Free Discrete Elastic Rods", 2024, box
    /// the rest shape for the same reason; stiffening until the needed rest shape fits the box keeps the
    /// groom's shape, which bounding it would not.) `supports` as for the preload; one of the wrong
    /// length counts no support.
    pub fn stiffening_to_hold(&self, gravity: DVec3, supports: &[Option<DVec3>]) -> f64 {
        let weight = gravity.length();
        if !(weight > 0.0 && weight.is_finite()) {
            return 1.0;
        }
        let down = gravity / weight;
        let positions = self.positions();
        let hangs = positions
            .get(1..)
            .unwrap_or_default()
            .windows(2)
            .all(|ends| (ends[1] - ends[0]).normalize_or_zero().dot(down) >= HANGING_COSINE);
        let length: f64 = self.rest_lengths().iter().skip(1).sum();
        let stiffness = *self.stiffness();
        let bending = stiffness.bending_1.min(stiffness.bending_2);
        let held = if hangs {
            1.0
        } else {
            let number = stiffness.linear_density * weight * length.powi(3) / bending;
            HOLDING_MARGIN * number / SELF_WEIGHT_BUCKLING
        };
        let unsupported;
        let supports = if supports.len() == self.node_count() {
            supports
        } else {
            unsupported = vec![None; self.node_count()];
            &unsupported
        };
        let flip_margin = FLIP_MARGIN * stiffness.twisting / bending;
        let mut needed = held.max(1.0);
        for (vertex, change) in self.sag_free_changes(gravity, supports).iter().enumerate() {
            let Some((bend, turn)) = *change else {
                continue;
            };
            let (kappa, _) = self.vertex_curvature_and_twist(vertex);
            // κ · (κ − Δκ / k) ≥ −m  ⇔  k ≥ κ · Δκ / (|κ|² + m).
            let against = kappa.dot(bend);
            if against > 0.0 {
                needed = needed.max(against / (kappa.length_squared() + flip_margin));
            }
            // The twisting moment M_t = GJ Δτ / l.
            let twisting_number = turn.abs() * length / self.rest.voronoi_lengths[vertex];
            needed = needed.max(twisting_number / TWIST_HOLDING);
        }
        if needed.is_finite() { needed } else { 1.0 }
    }

    /// Per interior vertex, how far the rest curvature and twist must move from the current ones
    /// (integrated: `Δκ = s l / EI`, `Δτ = s_τ l / GJ`) for the current shape to hold under `gravity` with
    /// `supports`; `None` at the ends and where the shape is singular.
    fn sag_free_changes(&self, gravity: DVec3, supports: &[Option<DVec3>]) -> Vec<Option<(DVec2, f64)>> {
        let mut edges: Vec<EdgeGeometry> = Vec::with_capacity(self.edge_count());
        edge_geometry(self, &mut edges);
        let stiffness = *self.stiffness();
        let stresses = self.equilibrium_stresses(&edges, gravity, supports);
        stresses
            .iter()
            .enumerate()
            .map(|(vertex, stress)| {
                let stress = (*stress)?;
                let length = self.rest.voronoi_lengths[vertex];
                let bend = DVec2::new(stress.x * length / stiffness.bending_1, stress.y * length / stiffness.bending_2);
                Some((bend, stress.z * length / stiffness.twisting))
            })
            .collect()
    }

    /// The bending and twisting stresses `s_v` (N·m) that hold the rod's current shape against `gravity`,
    /// per interior vertex (`None` at the ends and where the shape is singular), solved from the tip
    /// towards the root.
    fn equilibrium_stresses(
        &self,
        edges: &[EdgeGeometry],
        gravity: DVec3,
        supports: &[Option<DVec3>],
    ) -> Vec<Option<DVec3>> {
        let (nodes, edge_count) = (self.node_count(), self.edge_count());
        // Force and twisting moment on every unknown from what is already known (gravity, the vertices
        // and edges solved so far), as gradient components: equilibrium makes each total zero.
        let mut node_force: Vec<DVec3> = (0..nodes).map(|node| -self.inertia.masses[node] * gravity).collect();
        let mut edge_torque = vec![0.0; edge_count];
        let mut stresses = vec![None; nodes];
        for vertex in (1..edge_count).rev() {
            let strain = vertex_strain(&edges[vertex - 1], &edges[vertex], vertex_twist(self, vertex));
            let gradients = [&strain.grad_kappa_1, &strain.grad_kappa_2, &strain.grad_twist];
            // Columns: each stress's force on node v + 1 (stencil 8..11) and torque on edge v (7); the
            // tension's force on node v + 1 is along the edge.
            let column = |g: &[f64; 11]| DVec4::new(g[8], g[9], g[10], g[7]);
            let tangent = edges[vertex].tangent;
            let matrix = DMat4::from_cols(
                column(gradients[0]),
                column(gradients[1]),
                column(gradients[2]),
                DVec4::new(tangent.x, tangent.y, tangent.z, 0.0),
            );
            // A surface under the node takes the part of its load that pushes into it.
            let mut load = node_force[vertex + 1];
            if let Some(normal) = supports[vertex + 1] {
                load -= load.dot(normal).max(0.0) * normal;
            }
            let rhs = -DVec4::new(load.x, load.y, load.z, edge_torque[vertex]);
            let determinant = matrix.determinant();
            if !(determinant.is_finite() && determinant.abs() > f64::MIN_POSITIVE) {
                continue;
            }
            let solution = matrix.inverse() * rhs;
            let (stress, tension) = (solution.truncate(), solution.w);
            if !stress.is_finite() || !tension.is_finite() {
                continue;
            }
            stresses[vertex] = Some(stress);
            // Spread this vertex's stress and this edge's tension over the unknowns they touch.
            for (s, gradient) in stress.to_array().into_iter().zip(gradients) {
                for node in 0..3 {
                    let slot = &mut node_force[vertex - 1 + node];
                    *slot += s * DVec3::new(gradient[4 * node], gradient[4 * node + 1], gradient[4 * node + 2]);
                }
                edge_torque[vertex - 1] += s * gradient[3];
                edge_torque[vertex] += s * gradient[7];
            }
            node_force[vertex] -= tension * edges[vertex].tangent;
            node_force[vertex + 1] += tension * edges[vertex].tangent;
        }
        stresses
    }
}

#[cfg(test)]
mod tests {
    use bevy::math::DVec3;

    use super::super::RodError;
    use super::super::energy::{add_elastic_derivatives, dof_count, edge_geometry, node_dof, twist_dof};
    use super::super::test_support::{Lcg, random_strand};
    use super::*;

    /// The largest force (N) and twisting moment (N·m) left unbalanced at the free unknowns of `rod`
    /// under `gravity`, once each free edge carries the tension that balances its tip-side node along it.
    fn unbalanced(rod: &Rod, gravity: DVec3) -> (f64, f64) {
        let mut edges = Vec::new();
        edge_geometry(rod, &mut edges);
        let mut gradient = vec![0.0; dof_count(rod.node_count())];
        add_elastic_derivatives(rod, &edges, &mut gradient, None);
        let residual = |node: usize| {
            let d = node_dof(node);
            DVec3::new(gradient[d], gradient[d + 1], gradient[d + 2]) - rod.masses()[node] * gravity
        };
        let (mut force, mut tension) = (0.0_f64, 0.0);
        for node in (2..rod.node_count()).rev() {
            let beyond = if node + 1 < rod.node_count() { -tension * edges[node].tangent } else { DVec3::ZERO };
            let load = residual(node) + beyond;
            tension = -load.dot(edges[node - 1].tangent);
            force = force.max((load + tension * edges[node - 1].tangent).length());
        }
        let torque = (1..rod.edge_count()).map(|edge| gradient[twist_dof(edge)].abs()).fold(0.0, f64::max);
        (force, torque)
    }

    #[test]
    fn preloaded_rest_shapes_balance_gravity_at_every_free_unknown() {
        let mut random = Lcg(7);
        let gravity = DVec3::new(0.3, -9.81, 0.2);
        for _ in 0..20 {
            let mut rod = random_strand(&mut random, 12);
            // The stretch of the random strand is its rest length: no stretching force at this shape.
            let lengths: Vec<f64> = rod.state.positions.windows(2).map(|p| p[0].distance(p[1])).collect();
            let (curvatures, twists) = (rod.rest.curvatures.clone(), rod.rest.twists.clone());
            rod.set_rest_shape(&lengths, &curvatures, &twists).unwrap();
            let weight = rod.masses()[5] * gravity.length();
            let before = unbalanced(&rod, gravity);
            let report = rod.preload_for_gravity(gravity, &vec![None; rod.node_count()], 1.0).unwrap();
            let (force, torque) = unbalanced(&rod, gravity);
            assert_eq!(report.bounded_vertices, 0);
            assert!(before.0 > 10.0 * weight, "unbalanced before: {} N against a node weight of {weight} N", before.0);
            assert!(force < 1e-9 * before.0 && torque < 1e-9 * before.1.max(weight * 0.01), "{force} N, {torque} N·m");
        }
    }

    #[test]
    fn invalid_preload_parameters_are_rejected_without_change() {
        let mut rod = random_strand(&mut Lcg(3), 6);
        let before = rod.rest_shape().clone();
        let supported = vec![None; 7];
        assert!(matches!(
            rod.preload_for_gravity(DVec3::NAN, &supported, 1.0),
            Err(RodError::InvalidPreload { parameter: "gravity", .. })
        ));
        assert!(rod.preload_for_gravity(DVec3::NEG_Y, &supported, 1.5).is_err());
        assert!(rod.preload_for_gravity(DVec3::NEG_Y, &supported[..3], 1.0).is_err());
        assert_eq!(rod.rest_shape(), &before);
    }
}
