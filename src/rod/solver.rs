//! Time integration of one rod: implicit BDF2 (or backward Euler) on positions, backward Euler on
//! twists, with inextensibility.
//!
//! Why these schemes: real hair is so stiff that explicit steps would need `dt < l √(ρ/E)` (about 7 µs
//! for stretching, tens of µs for bending) while a game steps at 1/60 s. Implicit schemes are stable at
//! any step and damp the unresolvable fast modes; BDF2 does so without damping the motions a step
//! resolves (backward Euler removes 28 % of a 1 Hz swing's amplitude per second at 60 Hz; BDF2 0.2 %:
//! see [`Integrator`]). Written with the scheme's step `h` and prediction `x̂`, `v̂` ([`Scheme`];
//! backward Euler `h = dt`, `x̂ = xₙ`, `v̂ = vₙ`), each Newton iteration solves
//!
//! `(M/h² + D/h + M (K + C/h) + (1 + β/dt) H) Δq = −[M (q − x̂ − h v̂)/h² + D ((q − x̂)/h − u) + M K (q − x̄) + M C ((q − x̂)/h − v̄) + ∇E + β/dt H (q − q̃) − f]`
//!
//! over the unknowns `q = (x_0, θ^0, …, x_n)` (the twists with backward Euler's weights), where `H` is
//! the positive semi-definite Hessian approximation of [`super::energy`], `D` the air drag relative to
//! the air's velocity `u` ([`StepParams::air_damping`]), `K` and `C` the anchors' stiffnesses and damping
//! per unit mass pulling towards `x̄` moving at `v̄` ([`Anchor`]) and `β` the internal (stiffness-proportional)
//! damping measured from the configuration `q̃` below. Prescribed unknowns (pins, clamps) enter as known
//! displacements. The matrix is banded (half-bandwidth 10), so each solve costs `O(n)`.
//!
//! - **First guess** (`q̃`): the rod carried rigidly with its first clamped edge (a root following its
//!   head). The iterations then only resolve the hair's motion relative to its root.
//! - **Trust region**: an update that would turn an edge by more than [`StepParams::max_rotation`] is
//!   scaled down, so a rod far from equilibrium moves there over several iterations, never following a
//!   wild linear extrapolation.
//! - **Inextensibility**: the stiff stretching term keeps the linear solve from stretching edges to first
//!   order; a projection ([`super::projection`]) then removes the second-order stretch a linearised
//!   rotation leaves, without the rotation locking a stiff spring alone would cause.
//! - **Adaptive iterations**: calm steps stop after one iteration (linearly implicit); violent ones take
//!   up to [`StepParams::max_newton_iterations`].
//!
//! Velocities are the scheme's: `v = (x − x̂)/h` from the projected positions.

use bevy::math::{DMat3, DVec3};
use bevy::reflect::Reflect;

use super::banded::{StrandMatrix, factorize_best, solve_best};
use super::contact::{ContactScratch, Contacts};
use super::copy_into;
use super::curve::Rod;
use super::energy::{EdgeGeometry, RodMatrix, add_elastic_derivatives, dof_count, edge_geometry, node_dof, twist_dof};
use super::error::{RodError, StepError};
use super::frames::perpendicular_unit;
use super::inertia::{InertiaSource, NodeAnchor, add_inertia_terms};
use super::lanes::{LaneMask, Points, Real, Vector};
use super::params::Integrator;
use super::params::StepParams;
use super::projection::{ProjectionScratch, length_error, project_edge_lengths};
use super::state::{RodSnapshot, RodState, StepHistory};
use super::timing::{Part, StepTimings, Stopwatch};

/// Projection iterations a step may add, on the whole strand, when its own left an edge beyond
/// [`StepParams::strain_bound`] (see [`Rod::step_with_contacts`]).
pub const EXTRA_PROJECTION_ITERATIONS: u32 = 64;

/// The first Levenberg–Marquardt shift λ tried when a Newton system does not factorise (see
/// [`Rod::assemble_and_factorize`]), dimensionless.
const FIRST_REGULARISATION: f64 = 1e-8;

/// The largest Levenberg–Marquardt shift λ tried, dimensionless: the diagonal doubled.
const MAX_REGULARISATION: f64 = 1.0;

/// Adding this to a step's length (relative) still counts as the same length for the two-step integrator.
const SAME_DT: f64 = 1e-9;

/// How the step turns positions into velocities and velocities into accelerations, per node:
/// `v = (x − x̂)/h` and `a = (v − v̂)/h`, with `h` the scheme's step and `x̂`, `v̂` what the known states
/// give. Backward Euler: `h = dt`, `x̂ = xₙ`, `v̂ = vₙ`. BDF2: `h = ⅔ dt`, `x̂ = (4xₙ − xₙ₋₁)/3`,
/// `v̂ = (4vₙ − vₙ₋₁)/3`. Either way the step solves `M (x − x̂ − h v̂)/h² = F(x, (x − x̂)/h)`.
///
/// The twists always take backward Euler: they follow the centre line quasi-statically (hair's
/// torsional modes are far above any step's frequency), and the one motion of theirs without
/// stiffness, a free end's spin about its axis, gains nothing from a two-step extrapolation.
#[derive(Debug, Clone, Default)]
struct Scheme {
    /// The scheme's step `h` for the nodes, s.
    h: f64,
    /// `x̂` of every node, m.
    positions: Vec<DVec3>,
    /// `v̂` of every node, m/s.
    velocities: Vec<DVec3>,
}

impl Scheme {
    /// The weights of a step of `params.dt` from `state` (positions and velocities at the step's start)
    /// and `history` (the step before): BDF2 when asked for and there is a history of a step of the same
    /// length, backward Euler otherwise.
    fn prepare(&mut self, params: &StepParams, state: &RodState, history: &StepHistory) {
        let dt = params.dt;
        let two_step =
            params.integrator == Integrator::Bdf2 && history.dt > 0.0 && (history.dt - dt).abs() <= SAME_DT * dt;
        if two_step {
            self.h = 2.0 / 3.0 * dt;
            let positions = state.positions.iter().zip(&history.positions);
            self.positions.clear();
            self.positions.extend(positions.map(|(&now, &before)| bdf2_extrapolation(now, before)));
            let velocities = state.velocities.iter().zip(&history.velocities);
            self.velocities.clear();
            self.velocities.extend(velocities.map(|(&now, &before)| bdf2_extrapolation(now, before)));
        } else {
            self.h = dt;
            copy_into(&mut self.positions, &state.positions);
            copy_into(&mut self.velocities, &state.velocities);
        }
    }

    /// The nodes' inertia factor `1/h² + γ/h`, 1/s² (`γ` the air drag across the strand): a node's
    /// block of the Newton matrix is about `m` times it, and contact springs are scaled by it.
    fn inertia_scale(&self, params: &StepParams) -> f64 {
        1.0 / (self.h * self.h) + params.air_damping / self.h
    }
}

/// `(4 now − before)/3`, BDF2's extrapolation from the last two states.
fn bdf2_extrapolation<T>(now: T, before: T) -> T
where
    T: Copy + std::ops::Mul<f64, Output = T> + std::ops::Sub<Output = T>,
{
    (now * 4.0 - before) * (1.0 / 3.0)
}

/// The Levenberg–Marquardt shift to assemble with after a factorisation with `regularisation` met a
/// non-positive pivot at `row` (see [`Rod::assemble_and_factorize`]), or the error when the largest
/// has been tried.
pub(super) fn next_regularisation(regularisation: f64, row: usize) -> Result<f64, StepError> {
    if regularisation < MAX_REGULARISATION {
        Ok((100.0 * regularisation).max(FIRST_REGULARISATION))
    } else {
        Err(StepError::NotPositiveDefinite { dof: row })
    }
}

/// How far a step's Newton iterations have gone.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct NewtonProgress {
    newton_iterations: u32,
    projection_iterations: u32,
}

/// What a step's Newton iterations ended with ([`Rod::end_iterations`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct IterationsEnd {
    newton_iterations: u32,
    projection_iterations: u32,
    contact_count: u32,
    /// The most strained edge and its strain.
    strain: (usize, f64),
}

/// The elastic Hessian's factor `1 + β/dt` with internal damping.
pub(super) fn damped_scale(params: &StepParams) -> f64 {
    1.0 + params.internal_damping / params.dt
}

/// What acts on a rod from outside during a step, besides gravity ([`StepParams::gravity`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct StepLoads<'a> {
    /// Force on each node, N (one per node), or none.
    pub forces: Option<&'a [DVec3]>,
    /// The air's velocity at each node, m/s (one per node): the drag of [`StepParams::air_damping`]
    /// acts on the velocity relative to it (wind). `None` is still air.
    pub air_velocities: Option<&'a [DVec3]>,
    /// A change of each node's velocity at the start of the step, m/s (one per node), or none: an impulse
    /// per mass, such as the velocity smoothing of hair–hair interaction ([`crate::volume`]). Prescribed
    /// nodes ignore it. With BDF2 the velocity one step back changes too, so that both integrators'
    /// predicted velocity `v̂` moves by exactly the change.
    pub velocity_changes: Option<&'a [DVec3]>,
    /// A zero-length spring on each node towards a place, inside the implicit solve (one per node), or
    /// none: see [`Anchor`]. Prescribed nodes ignore theirs.
    pub anchors: Option<&'a [Anchor]>,
}

/// A node drawn towards a moving place by a zero-length spring and a damper, `−m k (x − x̄) − m c (v − v̄)`
/// (`m` the node's mass, `x̄` the place at the end of the step, `v̄` its velocity), taken implicitly with
/// the rest of the step, so that the elastic forces and inertia of the strand beyond it pull against it
/// in the same solve (the plugin's style hold ties hair to its groomed shape with them). On a free node
/// alone it is an oscillator of angular frequency `√k`, critically damped at `c = 2√k`; against a steady
/// force `F` it gives way by `F/(m k)`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Anchor {
    /// Where the spring pulls the node at the end of the step, m.
    pub target: DVec3,
    /// The place's velocity, m/s: the damper acts on the node's velocity relative to it.
    pub target_velocity: DVec3,
    /// Stiffness per unit of the node's mass `k`, 1/s² (finite, not negative; 0: no spring).
    pub stiffness: f64,
    /// Damping per unit of the node's mass `c`, 1/s (finite, not negative; 0: no damper).
    pub damping: f64,
}

impl Anchor {
    /// Whether it can be stepped: finite, with a stiffness and damping not negative.
    fn is_usable(&self) -> bool {
        self.target.is_finite()
            && self.target_velocity.is_finite()
            && self.stiffness.is_finite()
            && self.stiffness >= 0.0
            && self.damping.is_finite()
            && self.damping >= 0.0
    }
}

/// One strand's [`InertiaSource`]: its rod at the current iterate, its step's scheme and start, its loads.
pub(super) struct StrandInertia<'a> {
    rod: &'a Rod,
    workspace: &'a RodWorkspace,
    loads: &'a StepLoads<'a>,
}

impl InertiaSource<f64> for StrandInertia<'_> {
    #[inline(always)]
    fn node_count(&self) -> usize {
        self.rod.node_count()
    }

    #[inline(always)]
    fn scheme_step(&self) -> f64 {
        self.workspace.scheme.h
    }

    #[inline(always)]
    fn mass(&self, node: usize) -> f64 {
        self.rod.inertia.masses[node]
    }

    #[inline(always)]
    fn position(&self, node: usize) -> Vector<f64> {
        self.rod.state.positions[node].into()
    }

    #[inline(always)]
    fn predicted_position(&self, node: usize) -> Vector<f64> {
        self.workspace.scheme.positions[node].into()
    }

    #[inline(always)]
    fn predicted_velocity(&self, node: usize) -> Vector<f64> {
        self.workspace.scheme.velocities[node].into()
    }

    #[inline(always)]
    fn start_tangent(&self, edge: usize) -> Vector<f64> {
        self.workspace.saved.frames.tangents[edge].into()
    }

    #[inline(always)]
    fn force(&self, node: usize) -> Option<Vector<f64>> {
        self.loads.forces.map(|forces| forces[node].into())
    }

    #[inline(always)]
    fn air_velocity(&self, node: usize) -> Option<Vector<f64>> {
        self.loads.air_velocities.map(|air| air[node].into())
    }

    #[inline(always)]
    fn anchor(&self, node: usize) -> Option<NodeAnchor<f64>> {
        self.loads.anchors.map(|anchors| {
            let Anchor { target, target_velocity, stiffness, damping } = anchors[node];
            NodeAnchor { target: target.into(), target_velocity: target_velocity.into(), stiffness, damping }
        })
    }

    #[inline(always)]
    fn twist_inertia(&self, edge: usize) -> f64 {
        self.rod.inertia.twist_inertias[edge]
    }

    #[inline(always)]
    fn twist_change(&self, edge: usize) -> f64 {
        self.rod.state.twist[edge] - self.workspace.saved.state.twist[edge]
    }

    #[inline(always)]
    fn start_twist_rate(&self, edge: usize) -> f64 {
        self.workspace.saved.state.twist_rates[edge]
    }
}

/// What a successful step measured.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub struct StepReport {
    /// Largest edge strain after the step, dimensionless.
    pub max_strain: f64,
    /// Newton iterations the step took.
    pub newton_iterations: u32,
    /// Projection iterations the step needed, over all its Newton iterations and contact rounds.
    pub projection_iterations: u32,
    /// Nodes in contact with a collider at the end of the step.
    pub contacts: u32,
}

/// Scratch memory for stepping rods. One workspace serves any number of rods (one at a time: a rod's
/// state is all in the rod); it grows to the largest rod and then never allocates again. One per
/// thread keeps it in the core's cache.
#[derive(Debug, Clone, Default)]
pub struct RodWorkspace {
    hessian: RodMatrix,
    residual: Vec<f64>,
    displacement: Vec<f64>,
    damping_force: Vec<f64>,
    prescribed: Vec<f64>,
    edges: Vec<EdgeGeometry>,
    saved: RodSnapshot,
    scheme: Scheme,
    /// Positions and twists after the first guess (the strand carried with its root): internal
    /// damping acts on the deformation from there.
    carried_positions: Vec<DVec3>,
    carried_twist: Vec<f64>,
    projection: ProjectionScratch,
    contacts: ContactScratch,
    stopwatch: Stopwatch,
}

impl RodWorkspace {
    /// Starts (or stops) timing the parts of every step taken with this workspace, from zero: see
    /// [`RodWorkspace::part_timings`]. Off by default.
    pub fn time_parts(&mut self, enabled: bool) {
        self.stopwatch.set_enabled(enabled);
    }

    /// What the projection of the last Newton iteration holds the strand to.
    pub(super) fn projection(&self) -> &ProjectionScratch {
        &self.projection
    }

    /// [`RodWorkspace::projection`], to write.
    pub(super) fn projection_mut(&mut self) -> &mut ProjectionScratch {
        &mut self.projection
    }

    /// The displacement [`Rod::damped_displacement`] wrote.
    pub(super) fn displacement(&self) -> &[f64] {
        &self.displacement
    }

    /// The force [`Rod::internal_damping_force`] wrote.
    pub(super) fn damping_force(&self) -> &[f64] {
        &self.damping_force
    }

    /// The edges' geometry at the last assembly, to write (internal damping reads it).
    pub(super) fn edges_mut(&mut self) -> &mut Vec<EdgeGeometry> {
        &mut self.edges
    }

    /// The residual of the last Newton system assembled (its right-hand side negated), or its
    /// solution once solved.
    pub(super) fn residual(&self) -> &[f64] {
        &self.residual
    }

    /// See [`RodWorkspace::residual`].
    pub(super) fn residual_mut(&mut self) -> &mut [f64] {
        &mut self.residual
    }

    /// The time spent in each part of the steps since [`RodWorkspace::time_parts`] turned timing on.
    pub fn part_timings(&self) -> Option<&StepTimings> {
        self.stopwatch.timings()
    }
}

impl Rod {
    /// Advances the rod by `params.dt` under gravity, optional per-node `external_forces` (N) and its
    /// boundary conditions (prescribed nodes move to their targets over the step), with no colliders:
    /// [`Rod::step_with_contacts`] with [`Contacts::NONE`].
    pub fn step(
        &mut self,
        params: &StepParams,
        external_forces: Option<&[DVec3]>,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        self.step_with_contacts(params, external_forces, &Contacts::NONE, workspace)
    }

    /// Advances the rod by `params.dt` under gravity, optional per-node `external_forces` (N) and its
    /// boundary conditions (prescribed nodes move to their targets over the step), kept outside the
    /// colliders of `contacts` with friction (see [`Contacts`]), in still air:
    /// [`Rod::step_with_loads`] with only forces.
    pub fn step_with_contacts(
        &mut self,
        params: &StepParams,
        external_forces: Option<&[DVec3]>,
        contacts: &Contacts,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        let loads = StepLoads { forces: external_forces, ..StepLoads::default() };
        self.step_with_loads(params, &loads, contacts, workspace)
    }

    /// Advances the rod by `params.dt` under gravity, the `loads` from outside (per-node forces, the
    /// air's velocity for the drag, velocity changes at the start) and its boundary conditions (prescribed nodes move to their targets
    /// over the step), kept outside the colliders of `contacts` with friction (see [`Contacts`]).
    ///
    /// No `Ok` step ends with an edge strained beyond [`StepParams::strain_bound`]: when the projections
    /// of the Newton iterations leave more (they ran out of iterations, or contact pushed the strand),
    /// up to [`EXTRA_PROJECTION_ITERATIONS`] more run on the whole strand, and if even that is not enough,
    /// every free node is put at its edge's length from its neighbour towards the nearest prescribed
    /// node (follow the leader, Müller et al. 2012). That reaches every node outside the prescribed ones;
    /// the nodes between two prescribed nodes are the projection's alone, so a rope pinned at both ends
    /// and pulled (nearly) straight between its pins, or pins farther apart than the rod allows, can end
    /// above the bound: the step is then reported as [`StepError::OverStrained`].
    ///
    /// On failure (non-finite values, a non-positive-definite system, strain above the bound) the rod is
    /// put back where it was before the step, at rest, and the error says what happened; invalid input
    /// changes nothing. A rod whose state cannot start a step (written from outside: a non-finite or
    /// folded position) is put back in its rest pose, carried onto its clamp, with
    /// [`StepError::UnusableState`].
    pub fn step_with_loads(
        &mut self,
        params: &StepParams,
        loads: &StepLoads,
        contacts: &Contacts,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        self.check_step_input(params, loads, contacts)?;
        self.begin_step(workspace);
        let result = self.integrate(params, loads, contacts, workspace);
        self.end_step(result, workspace)
    }

    /// Checks what a step is given (and the rod's own state, which may have been written from outside),
    /// and applies the loads' velocity changes: nothing else changes on an error (a state that cannot
    /// start a step is put back in its rest pose, carried onto its clamp).
    pub(super) fn check_step_input(
        &mut self,
        params: &StepParams,
        loads: &StepLoads,
        contacts: &Contacts,
    ) -> Result<(), StepError> {
        if let Some((node, reason)) = self.unusable_state() {
            self.reset();
            self.carry_with_first_clamp();
            return Err(StepError::UnusableState { node, reason });
        }
        params.validate()?;
        contacts.validate()?;
        if let Some(forces) = loads.forces {
            if forces.len() != self.node_count() {
                return Err(RodError::WrongLength { expected: self.node_count(), actual: forces.len() }.into());
            }
            if let Some((node, &force)) = forces.iter().enumerate().find(|(_, f)| !f.is_finite()) {
                return Err(RodError::NonFiniteForce { node, force }.into());
            }
        }
        if let Some(air) = loads.air_velocities {
            if air.len() != self.node_count() {
                return Err(RodError::WrongLength { expected: self.node_count(), actual: air.len() }.into());
            }
            if let Some((node, &velocity)) = air.iter().enumerate().find(|(_, u)| !u.is_finite()) {
                return Err(RodError::NonFiniteAirVelocity { node, velocity }.into());
            }
        }
        if let Some(changes) = loads.velocity_changes {
            if changes.len() != self.node_count() {
                return Err(RodError::WrongLength { expected: self.node_count(), actual: changes.len() }.into());
            }
            if let Some((node, &change)) = changes.iter().enumerate().find(|(_, dv)| !dv.is_finite()) {
                return Err(RodError::NonFiniteVelocityChange { node, change }.into());
            }
            self.change_velocities(changes);
        }
        if let Some(anchors) = loads.anchors {
            if anchors.len() != self.node_count() {
                return Err(RodError::WrongLength { expected: self.node_count(), actual: anchors.len() }.into());
            }
            if let Some((node, anchor)) = anchors.iter().enumerate().find(|(_, anchor)| !anchor.is_usable()) {
                return Err(RodError::InvalidAnchor {
                    node,
                    target: anchor.target,
                    target_velocity: anchor.target_velocity,
                    stiffness: anchor.stiffness,
                    damping: anchor.damping,
                }
                .into());
            }
        }
        Ok(())
    }

    /// Saves what a step starts from, for a roll-back, once its input is known to be valid.
    pub(super) fn begin_step(&mut self, workspace: &mut RodWorkspace) {
        workspace.stopwatch.start_step();
        self.save_into(&mut workspace.saved);
        // The rod's lagged normal forces stand in the contact scratch for the step (a swap of buffers).
        std::mem::swap(&mut self.state.contact_normal_forces, &mut workspace.contacts.normal_forces);
    }

    /// Ends a step begun with [`Rod::begin_step`]: puts the rod back where it was, at rest, if it failed.
    pub(super) fn end_step(
        &mut self,
        result: Result<StepReport, StepError>,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        std::mem::swap(&mut self.state.contact_normal_forces, &mut workspace.contacts.normal_forces);
        if result.is_err() {
            self.restore_at_rest(&workspace.saved);
        }
        result
    }

    /// Adds `changes` to the free nodes' velocities, and to the velocities one step back when the
    /// two-step integrator has them: `v̂ = (4vₙ − vₙ₋₁)/3` then moves by exactly the change.
    fn change_velocities(&mut self, changes: &[DVec3]) {
        let history = self.state.history.dt > 0.0;
        for (node, &change) in changes.iter().enumerate() {
            if self.is_node_prescribed(node) {
                continue;
            }
            self.state.velocities[node] += change;
            if history {
                self.state.history.velocities[node] += change;
            }
        }
    }

    fn integrate(
        &mut self,
        params: &StepParams,
        loads: &StepLoads,
        contacts: &Contacts,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        self.begin_integration(params, contacts, workspace);
        let mut progress = NewtonProgress::default();
        loop {
            self.assemble_and_factorize(params, loads, workspace)?;
            let RodWorkspace { hessian, residual, .. } = workspace;
            residual.iter_mut().for_each(|r| *r = -*r);
            solve_best(hessian, residual);
            let update = self.apply_newton_update(params, workspace)?;
            if self.end_newton_iteration(update, params, &mut progress, workspace) {
                break;
            }
        }
        self.finish_integration(params, contacts, progress, workspace)
    }

    /// What a step does before its Newton iterations: the first guess (the rod carried with its
    /// root), the scheme's prediction, the projection's masses, the colliders near the strand.
    pub(super) fn begin_integration(&mut self, params: &StepParams, contacts: &Contacts, workspace: &mut RodWorkspace) {
        self.carry_with_first_clamp();
        workspace.stopwatch.lap(Part::Frames);
        copy_into(&mut workspace.carried_positions, &self.state.positions);
        copy_into(&mut workspace.carried_twist, &self.state.twist);
        workspace.scheme.prepare(params, &workspace.saved.state, &self.state.history);
        workspace.projection.use_rod_masses(self);
        workspace.stopwatch.lap(Part::Forces);
        self.begin_contacts(contacts, params, &workspace.saved.state.positions, &mut workspace.contacts);
        workspace.stopwatch.lap(Part::Collisions);
    }

    /// After a Newton update that applied `fraction` of itself and changed the contacts or not
    /// (`update`): counts the iteration, projects onto the edge lengths and refreshes the frames.
    /// Returns whether the iterations are over (converged, or out of iterations).
    pub(super) fn end_newton_iteration(
        &mut self,
        update: (f64, bool),
        params: &StepParams,
        progress: &mut NewtonProgress,
        workspace: &mut RodWorkspace,
    ) -> bool {
        let last = self.begin_projection(update, params, progress, workspace);
        let iterations = project_edge_lengths(self, params, &mut workspace.projection);
        self.end_projection(iterations, progress, workspace);
        if !last {
            self.refresh_frames();
            workspace.stopwatch.lap(Part::Frames);
        }
        last
    }

    /// [`Rod::end_newton_iteration`] up to the projection: counts the iteration, and, when it is the
    /// last, puts the prescribed unknowns on their targets. Returns whether it is the last.
    pub(super) fn begin_projection(
        &mut self,
        (fraction, contacts_changed): (f64, bool),
        params: &StepParams,
        progress: &mut NewtonProgress,
        workspace: &RodWorkspace,
    ) -> bool {
        progress.newton_iterations += 1;
        let linearisation_error = length_error(self, &workspace.projection.target_lengths);
        let converged = fraction == 1.0 && linearisation_error <= params.newton_strain_tolerance && !contacts_changed;
        let last = converged || progress.newton_iterations == params.max_newton_iterations;
        if last {
            self.snap_to_targets();
        }
        last
    }

    /// [`Rod::end_newton_iteration`] after the projection, which took `iterations` (the frames are
    /// refreshed next, unless the iteration was the last).
    pub(super) fn end_projection(&self, iterations: u32, progress: &mut NewtonProgress, workspace: &mut RodWorkspace) {
        progress.projection_iterations += iterations;
        workspace.stopwatch.lap(Part::Constraints);
    }

    /// What a step does after its Newton iterations: contacts resolved, the strain bound kept, frames,
    /// velocities, and the checks that the result is finite and within the bound.
    pub(super) fn finish_integration(
        &mut self,
        params: &StepParams,
        contacts: &Contacts,
        progress: NewtonProgress,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        let ending = self.end_iterations(params, contacts, progress, workspace);
        self.refresh_frames();
        workspace.stopwatch.lap(Part::Frames);
        self.end_integration(params, ending, workspace)
    }

    /// [`Rod::finish_integration`] up to the frames: contacts resolved and the strain bound kept.
    pub(super) fn end_iterations(
        &mut self,
        params: &StepParams,
        contacts: &Contacts,
        progress: NewtonProgress,
        workspace: &mut RodWorkspace,
    ) -> IterationsEnd {
        let NewtonProgress { newton_iterations, mut projection_iterations } = progress;
        let mut contact_count = 0;
        if !contacts.colliders.is_empty() {
            let (in_contact, iterations) = self.resolve_contacts(
                contacts,
                &workspace.saved.state.positions,
                params,
                &mut workspace.projection,
                &mut workspace.contacts,
            );
            contact_count = in_contact;
            projection_iterations += iterations;
            workspace.stopwatch.lap(Part::Collisions);
        }
        let mut strain = self.max_strain();
        if !params.within_strain_bound(strain.1) {
            projection_iterations += self.enforce_strain_bound(params, &mut workspace.projection);
            strain = self.max_strain();
            workspace.stopwatch.lap(Part::Constraints);
        }
        IterationsEnd { newton_iterations, projection_iterations, contact_count, strain }
    }

    /// [`Rod::finish_integration`] after the frames: velocities, and the checks that the result is
    /// finite and within the bound.
    pub(super) fn end_integration(
        &mut self,
        params: &StepParams,
        ending: IterationsEnd,
        workspace: &mut RodWorkspace,
    ) -> Result<StepReport, StepError> {
        let IterationsEnd { newton_iterations, projection_iterations, contact_count, strain } = ending;
        self.update_velocities(params, workspace);
        let finite = |node: usize| {
            self.state.positions[node].is_finite()
                && self.state.velocities[node].is_finite()
                && (node == self.edge_count() || self.state.twist[node].is_finite())
        };
        if let Some(node) = (0..self.node_count()).find(|&node| !finite(node)) {
            return Err(StepError::NonFinite { node });
        }
        let (edge, max_strain) = strain;
        if !params.within_strain_bound(max_strain) {
            return Err(StepError::OverStrained { edge, strain: max_strain, limit: params.strain_bound() });
        }
        workspace.stopwatch.lap(Part::Forces);
        Ok(StepReport { max_strain, newton_iterations, projection_iterations, contacts: contact_count })
    }

    /// The velocities the step ends with, from its positions by the scheme ([`Scheme`]), and the
    /// history the next step needs.
    fn update_velocities(&mut self, params: &StepParams, workspace: &RodWorkspace) {
        let RodWorkspace { saved, scheme, .. } = workspace;
        for (velocity, (position, predicted)) in
            self.state.velocities.iter_mut().zip(self.state.positions.iter().zip(&scheme.positions))
        {
            *velocity = (*position - *predicted) / scheme.h;
        }
        let twists = self.state.twist.iter().zip(&saved.state.twist);
        for (rate, (twist, start)) in self.state.twist_rates.iter_mut().zip(twists) {
            *rate = (twist - start) / params.dt;
        }
        self.state.history.record(&saved.state, params.dt);
    }

    /// The first guess of a step: the rod carried rigidly with the motion of its first clamped edge
    /// (position, tangent and material frame) from where it is to its targets. Only the starting point
    /// of the Newton iterations changes, not the equations they solve; starting here, the iterations
    /// need only resolve the hair's motion relative to its root, which is what their linearisation and
    /// trust region handle well, even when a head moves centimetres per step.
    fn carry_with_first_clamp(&mut self) {
        let first_clamp = (0..self.edge_count()).find_map(|edge| {
            Some((
                edge,
                self.constraints.node_targets[edge]?,
                self.constraints.node_targets[edge + 1]?,
                self.constraints.twist_targets[edge]?,
            ))
        });
        let Some((edge, start, end, direction)) = first_clamp else {
            return;
        };
        let old = self.material_frame(edge);
        let tangent = (end - start).normalize_or(old.tangent);
        let Some(m1) = perpendicular_unit(direction, tangent) else {
            return;
        };
        let rotation = DMat3::from_cols(tangent, m1, tangent.cross(m1))
            * DMat3::from_cols(old.tangent, old.m1, old.m2).transpose();
        let pivot = self.state.positions[edge];
        for position in &mut self.state.positions {
            *position = start + rotation * (*position - pivot);
        }
        (self.state.positions[edge], self.state.positions[edge + 1]) = (start, end);
        // The frames turn with the strand: reference twist and twists are unchanged by a rigid motion.
        for (tangent, director) in self.frames.tangents.iter_mut().zip(&mut self.frames.reference_directors) {
            (*tangent, *director) = (rotation * *tangent, rotation * *director);
        }
    }

    /// Brings every edge within [`StepParams::strain_bound`] of its rest length after a step whose
    /// projections left more (see [`Rod::step_with_contacts`]): up to [`EXTRA_PROJECTION_ITERATIONS`] of
    /// the projection with no contact constraint, then, if need be, follow the leader from the
    /// prescribed nodes outwards. Returns the projection iterations.
    fn enforce_strain_bound(&mut self, params: &StepParams, projection: &mut ProjectionScratch) -> u32 {
        projection.contact_normals.fill(DVec3::ZERO);
        let extended = StepParams { max_projection_iterations: EXTRA_PROJECTION_ITERATIONS, ..*params };
        let iterations = project_edge_lengths(self, &extended, projection);
        if !params.within_strain_bound(self.max_strain().1) {
            self.follow_the_leader(&projection.target_lengths);
        }
        iterations
    }

    /// Puts each free node at its edge's target length (m) from its neighbour on the side of the nearest
    /// prescribed node, along the edge as it is: past the last prescribed node towards the tip, before
    /// the first towards the root, from the root for a free rod. Exact lengths in one pass, at the price
    /// of moving the nodes more than a mass-weighted projection would (Müller et al. 2012, "Fast
    /// Simulation of Inextensible Hair and Fur"); nodes between two prescribed ones are left.
    fn follow_the_leader(&mut self, target_lengths: &[f64]) {
        let node_count = self.node_count();
        let first = (0..node_count).find(|&node| self.is_node_prescribed(node)).unwrap_or(0);
        let last = (0..node_count).rfind(|&node| self.is_node_prescribed(node)).unwrap_or(0);
        let place = |rod: &mut Rod, from: usize, to: usize, edge: usize| {
            let direction = (rod.state.positions[to] - rod.state.positions[from]).normalize_or_zero();
            let direction = if direction == DVec3::ZERO {
                if to > from { rod.frames.tangents[edge] } else { -rod.frames.tangents[edge] }
            } else {
                direction
            };
            rod.state.positions[to] = rod.state.positions[from] + target_lengths[edge] * direction;
        };
        for node in last + 1..node_count {
            place(self, node - 1, node, node - 1);
        }
        for node in (0..first).rev() {
            place(self, node + 1, node, node);
        }
    }

    /// Puts prescribed nodes exactly on their targets and clamped edges exactly at their twist, in
    /// case a Newton update was scaled down before getting there. (The twist targets are measured from
    /// the frames as they are, carried to the target tangents, so the frames need no refresh first.)
    fn snap_to_targets(&mut self) {
        for (position, target) in self.state.positions.iter_mut().zip(&self.constraints.node_targets) {
            if let Some(target) = target {
                *position = *target;
            }
        }
        for edge in self.constraints.clamped_edges() {
            if let Some(offset) = self.twist_target_offset(edge) {
                self.state.twist[edge] += offset;
            }
        }
    }

    /// Assembles the Newton system of the current iterate (see the module documentation) and
    /// factorises its matrix.
    ///
    /// The matrix is positive definite in exact arithmetic, but a rod folded nearly back on itself, or
    /// with edges much shorter than its thickness, has bending terms so much larger than its inertia
    /// that rounding can break the factorisation. It is then assembled again with its diagonal scaled
    /// by `1 + λ` (Levenberg–Marquardt), λ from [`FIRST_REGULARISATION`] up a hundredfold at a time to
    /// [`MAX_REGULARISATION`]: a shorter step in a descent direction instead of a failure.
    fn assemble_and_factorize(
        &mut self,
        params: &StepParams,
        loads: &StepLoads,
        workspace: &mut RodWorkspace,
    ) -> Result<(), StepError> {
        let mut regularisation = 0.0;
        loop {
            self.assemble_newton_system(params, loads, workspace, regularisation);
            let mut row = [0];
            match factorize_best(&mut workspace.hessian, &mut row) {
                0 => return Ok(()),
                _ => regularisation = next_regularisation(regularisation, row[0])?,
            }
        }
    }

    /// Assembles the Newton system at the current iterate into the workspace's matrix and residual, one
    /// term at a time (see the module documentation): elastic forces, internal damping, inertia with
    /// gravity and external forces, contact, the diagonal scaled by `1 + regularisation`, prescribed
    /// unknowns.
    pub(super) fn assemble_newton_system(
        &mut self,
        params: &StepParams,
        loads: &StepLoads,
        workspace: &mut RodWorkspace,
        regularisation: f64,
    ) {
        self.begin_assembly(workspace);
        let RodWorkspace { hessian, residual, edges, .. } = workspace;
        hessian.reset(residual.len());
        add_elastic_derivatives(self, edges, residual, Some((hessian, damped_scale(params))));
        let damped = self.damped_displacement(params, workspace);
        // Taken out for the other terms, which see the workspace whole (an exchange of pointers).
        let mut hessian = std::mem::take(&mut workspace.hessian);
        if damped {
            self.add_internal_damping(params, workspace, &mut hessian);
        }
        let mut residual = std::mem::take(&mut workspace.residual);
        add_inertia_terms(&self.inertia_source(workspace, loads), params, &mut residual, &mut hessian);
        workspace.residual = residual;
        workspace.stopwatch.lap(Part::Forces);
        self.add_contact_and_prescribed_terms(params, workspace, &mut hessian, regularisation);
        workspace.hessian = hessian;
    }

    /// The start of an assembly: the edges' geometry, and the residual at zero.
    pub(super) fn begin_assembly(&self, workspace: &mut RodWorkspace) {
        edge_geometry(self, &mut workspace.edges);
        self.clear_residual(workspace);
    }

    /// The workspace's residual at zero, sized for this strand.
    pub(super) fn clear_residual(&self, workspace: &mut RodWorkspace) {
        workspace.residual.clear();
        workspace.residual.resize(dof_count(self.node_count()), 0.0);
    }

    /// What the inertia terms read of this strand at its current iterate ([`add_inertia_terms`]).
    pub(super) fn inertia_source<'a>(&'a self, workspace: &'a RodWorkspace, loads: &'a StepLoads) -> StrandInertia<'a> {
        StrandInertia { rod: self, workspace, loads }
    }

    /// The Newton system's terms after the elastic ones, internal damping and inertia (in `matrix`, the
    /// residual in the workspace): contact, the diagonal scaled by `1 + regularisation`, prescribed
    /// unknowns.
    fn add_contact_and_prescribed_terms(
        &self,
        params: &StepParams,
        workspace: &mut RodWorkspace,
        matrix: &mut impl StrandMatrix,
        regularisation: f64,
    ) {
        self.add_contact_terms(params, workspace, matrix, regularisation);
        self.add_prescribed_unknowns(workspace, matrix);
    }

    /// [`Rod::add_contact_and_prescribed_terms`] up to the prescribed unknowns: contact, and the
    /// diagonal scaled by `1 + regularisation`.
    pub(super) fn add_contact_terms(
        &self,
        params: &StepParams,
        workspace: &mut RodWorkspace,
        matrix: &mut impl StrandMatrix,
        regularisation: f64,
    ) {
        let RodWorkspace { residual, saved, contacts, stopwatch, scheme, .. } = workspace;
        self.add_contact_forces(
            contacts,
            &saved.state.positions,
            params,
            scheme.inertia_scale(params),
            residual,
            matrix,
        );
        stopwatch.lap(Part::Collisions);
        if regularisation > 0.0 {
            matrix.scale_diagonal(1.0 + regularisation);
        }
    }

    /// Internal (Rayleigh) friction `β/dt H (q − q̃)` on the deformation since the first guess `q̃` (the
    /// strand carried with its root), not on that rigid motion. Along each edge the stretching part
    /// damps the true change of length, since `H Δq` would count a turn by `φ` as a stretch by `φ²/2`
    /// times the huge axial stiffness.
    fn add_internal_damping(&self, params: &StepParams, workspace: &mut RodWorkspace, hessian: &mut impl StrandMatrix) {
        let factor = self.internal_damping_force(params, workspace, hessian);
        let RodWorkspace { residual, damping_force, .. } = workspace;
        for (r, f) in residual.iter_mut().zip(damping_force.iter()) {
            *r += factor * f;
        }
    }

    /// [`Rod::add_internal_damping`] up to its residual: writes `H (q − q̃)` with the stretching part
    /// corrected into the workspace's damping force, and returns the factor the residual takes it with.
    pub(super) fn internal_damping_force(
        &self,
        params: &StepParams,
        workspace: &mut RodWorkspace,
        hessian: &mut impl StrandMatrix,
    ) -> f64 {
        let RodWorkspace { displacement, damping_force, edges, carried_positions, .. } = workspace;
        hessian.multiply_elastic(displacement, damping_force);
        let damped_scale = damped_scale(params);
        let axial_stiffness = damped_scale * self.stiffness().stretching;
        for (edge, geometry) in edges.iter().enumerate() {
            let carried_length = carried_positions[edge].distance(carried_positions[edge + 1]);
            let linearised = geometry.tangent.dot(
                DVec3::from_slice(&displacement[node_dof(edge + 1)..node_dof(edge + 1) + 3])
                    - DVec3::from_slice(&displacement[node_dof(edge)..node_dof(edge) + 3]),
            );
            let correction = axial_stiffness / self.rest.lengths[edge]
                * (geometry.length - carried_length - linearised)
                * geometry.tangent;
            for axis in 0..3 {
                damping_force[node_dof(edge) + axis] -= correction[axis];
                damping_force[node_dof(edge + 1) + axis] += correction[axis];
            }
        }
        // The product was with the damped `(1 + β/dt) H`.
        params.internal_damping / params.dt / damped_scale
    }

    /// Writes the deformation since the first guess, `q − q̃`, into the workspace's displacement, and
    /// says whether internal damping acts on it (not on the first iteration, which starts at `q̃`).
    pub(super) fn damped_displacement(&self, params: &StepParams, workspace: &mut RodWorkspace) -> bool {
        let size = dof_count(self.node_count());
        let RodWorkspace { displacement, damping_force, carried_positions, carried_twist, .. } = workspace;
        // On the first iteration the iterate is where the strand was carried: nothing to damp yet.
        let damped = params.internal_damping > 0.0
            && (self.state.positions != *carried_positions || self.state.twist != *carried_twist);
        // Sized on every iteration (a no-op once grown), so that no later step allocates.
        displacement.resize(size, 0.0);
        damping_force.resize(size, 0.0);
        if damped {
            for node in 0..self.node_count() {
                let offset = self.state.positions[node] - carried_positions[node];
                displacement[node_dof(node)..node_dof(node) + 3].copy_from_slice(&offset.to_array());
            }
            for edge in 0..self.edge_count() {
                displacement[twist_dof(edge)] = self.state.twist[edge] - carried_twist[edge];
            }
        }
        damped
    }

    /// Prescribed unknowns (pins, clamps) move by their remaining displacement `d`: their rows become
    /// identity rows with right-hand side `d`, and the free rows see `−A d` on their right-hand side.
    pub(super) fn add_prescribed_unknowns(&self, workspace: &mut RodWorkspace, hessian: &mut impl StrandMatrix) {
        let size = dof_count(self.node_count());
        let RodWorkspace { residual, prescribed, damping_force: coupling, .. } = workspace;
        prescribed.clear();
        prescribed.resize(size, 0.0);
        let mut moving = MovingUnknowns::default();
        self.prescribed_displacements(|dof, offset| {
            prescribed[dof] = offset;
            moving.include(dof, offset);
        });
        // Usually only the root edge's unknowns move: multiply by the columns they span, not all.
        if let Some(columns) = moving.columns() {
            hessian.multiply_columns(columns, prescribed, coupling);
            for (r, coupling) in residual.iter_mut().zip(coupling.iter()) {
                *r += coupling;
            }
        }
        for dof in self.prescribed_unknowns() {
            hessian.set_identity_row(dof);
            residual[dof] = -prescribed[dof];
        }
    }

    /// The prescribed unknowns: the coordinates of each pinned or clamped node, then each clamped edge's
    /// twist.
    pub(super) fn prescribed_unknowns(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.node_count())
            .filter(|&node| self.constraints.node_targets[node].is_some())
            .flat_map(|node| node_dof(node)..node_dof(node) + 3)
            .chain(self.constraints.clamped_edges().map(twist_dof))
    }

    /// Calls `visit(unknown, d)` for each prescribed unknown, in the order of
    /// [`Rod::prescribed_unknowns`], with the displacement `d` that remains to its target (0 for a
    /// clamped edge whose twist has no target here).
    pub(super) fn prescribed_displacements(&self, mut visit: impl FnMut(usize, f64)) {
        for (node, target) in self.constraints.node_targets.iter().enumerate() {
            if let Some(target) = target {
                let offset = *target - self.state.positions[node];
                for (axis, offset) in offset.to_array().into_iter().enumerate() {
                    visit(node_dof(node) + axis, offset);
                }
            }
        }
        for edge in self.constraints.clamped_edges() {
            visit(twist_dof(edge), self.twist_target_offset(edge).unwrap_or(0.0));
        }
    }

    /// Applies the Newton update the workspace's residual now holds (the solution of the system)
    /// within the trust region. Returns the fraction of the update that was applied (below 1 when
    /// the trust region limited it), and whether the update changes which nodes touch a collider.
    pub(super) fn apply_newton_update(
        &mut self,
        params: &StepParams,
        workspace: &mut RodWorkspace,
    ) -> Result<(f64, bool), StepError> {
        let contacts_changed = self.update_contacts_with(params, workspace);
        let RodWorkspace { residual, projection, stopwatch, .. } = workspace;
        let Rod { state, constraints, rest, .. } = self;
        let (fraction, finite) = newton_update(
            &mut state.positions[..],
            &mut state.twist,
            residual,
            &rest.lengths,
            |edge| LaneMask::from(constraints.is_edge_free(edge)),
            params,
            &mut projection.target_lengths,
        );
        if finite == 0 {
            return Err(StepError::NonFinite { node: first_non_finite_update(residual, 0) });
        }
        // The frames are refreshed once the projection has moved the nodes (see `integrate`).
        stopwatch.lap(Part::Solve);
        Ok((fraction, contacts_changed))
    }

    /// The contacts' part of [`Rod::apply_newton_update`], on the update the workspace's residual
    /// holds: whether it changes which nodes touch a collider (see [`Rod::update_contacts`]).
    pub(super) fn update_contacts_with(&mut self, params: &StepParams, workspace: &mut RodWorkspace) -> bool {
        let RodWorkspace { residual, saved, contacts, stopwatch, scheme, .. } = workspace;
        let inertia_scale = scheme.inertia_scale(params);
        stopwatch.lap(Part::Solve);
        let node_update = |node: usize| DVec3::from_slice(&residual[node_dof(node)..node_dof(node) + 3]);
        let changed = self.update_contacts(contacts, &saved.state.positions, params, inertia_scale, node_update);
        stopwatch.lap(Part::Collisions);
        changed
    }
}

/// The first node whose update in `update` (lane `lane`) is not finite (0 if none is).
pub(super) fn first_non_finite_update<T: Real>(update: &[T], lane: usize) -> usize {
    let nodes = update.len().div_ceil(4);
    (0..nodes).find(|&node| (0..3).any(|axis| !update[node_dof(node) + axis].lane(lane).is_finite())).unwrap_or(0)
}

/// Applies a Newton `update` (the system's solution) to `positions` and `twist` within the trust
/// region, for one strand or a lockstep batch's lanes: an update that turns a free edge
/// (`free_edges(edge)`, the lanes where not both its nodes are prescribed) by more than
/// [`StepParams::max_rotation`] is scaled down. Writes each edge's length after the update to first
/// order, `|e| + t·Δe`, kept within the strain allowance (what the implicit solve with its stiff
/// stretching term meant; the projection removes only the second-order stretch a linearised rotation
/// leaves), into `target_lengths`. Returns the fraction of the update applied and the lanes whose
/// largest turn is finite (the others are left unchanged, but for their target lengths).
#[inline(always)]
pub(super) fn newton_update<T: Real>(
    positions: &mut (impl Points<T> + ?Sized),
    twist: &mut [T],
    update: &[T],
    rest_lengths: &[T],
    free_edges: impl Fn(usize) -> LaneMask,
    params: &StepParams,
    target_lengths: &mut Vec<T>,
) -> (T, LaneMask) {
    let (zero, one, half) = (T::splat(0.0), T::splat(1.0), T::splat(0.5));
    let edge_count = twist.len();
    let node_update = |node: usize| Vector {
        x: update[node_dof(node)],
        y: update[node_dof(node) + 1],
        z: update[node_dof(node) + 2],
    };
    let mut largest_turn = zero;
    for edge in 0..edge_count {
        let e = positions.point(edge + 1) - positions.point(edge);
        let change = node_update(edge + 1) - node_update(edge);
        let along = change.dot(e) / e.dot(e);
        // Turning, and shrinking towards a fold, both count as turning.
        let turn = (change - e.scale(along)).length() / e.length() + (-along - half).max(zero);
        largest_turn = largest_turn.max(T::select(free_edges(edge), turn, zero));
    }
    let finite = largest_turn.lt(T::splat(f64::INFINITY));
    let max_rotation = T::splat(params.max_rotation);
    let fraction = T::select(largest_turn.gt(max_rotation), max_rotation / largest_turn, one);
    target_lengths.clear();
    target_lengths.extend((0..edge_count).map(|edge| {
        let e = positions.point(edge + 1) - positions.point(edge);
        let change = (node_update(edge + 1) - node_update(edge)).scale(fraction);
        let rest = rest_lengths[edge];
        let allowance = T::splat(params.strain_allowance) * rest;
        let length = e.length() + change.dot(e) / e.length();
        let (low, high) = (rest - allowance, rest + allowance);
        let length = T::select(length.lt(low), low, length);
        T::select(length.gt(high), high, length)
    }));
    for node in 0..=edge_count {
        let moved = positions.point(node) + node_update(node).scale(fraction);
        positions.set_point(node, Vector::select(finite, moved, positions.point(node)));
    }
    for (edge, twist) in twist.iter_mut().enumerate() {
        *twist = T::select(finite, *twist + fraction * update[twist_dof(edge)], *twist);
    }
    (fraction, finite)
}

/// The span of the prescribed unknowns that still move (a displacement not zero), whose columns the
/// product in [`Rod::add_prescribed_unknowns`] takes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct MovingUnknowns(Option<(usize, usize)>);

impl MovingUnknowns {
    /// Takes in unknown `dof` if its displacement `offset` is not zero.
    pub(super) fn include(&mut self, dof: usize, offset: f64) {
        if offset != 0.0 {
            let (first, last) = self.0.unwrap_or((dof, dof));
            self.0 = Some((first.min(dof), last.max(dof)));
        }
    }

    /// The columns from the first moving unknown to the last, if any moves.
    pub(super) fn columns(self) -> Option<std::ops::Range<usize>> {
        self.0.map(|(first, last)| first..last + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_parameters_are_rejected_without_change() {
        let nodes: Vec<DVec3> = (0..5).map(|i| DVec3::new(0.01 * i as f64, 0.0, 0.0)).collect();
        let mut rod = Rod::new(&nodes, DVec3::Y, super::super::RodMaterial::human_hair()).unwrap();
        let mut workspace = RodWorkspace::default();
        let params = StepParams { dt: -1.0, ..Default::default() };
        assert!(matches!(
            rod.step(&params, None, &mut workspace),
            Err(StepError::InvalidInput(RodError::InvalidStepParameter { parameter: "dt", .. }))
        ));
        let forces = vec![DVec3::ZERO; 3];
        assert!(matches!(
            rod.step(&StepParams::default(), Some(&forces), &mut workspace),
            Err(StepError::InvalidInput(RodError::WrongLength { expected: 5, actual: 3 }))
        ));
        assert_eq!(rod.positions(), &nodes[..]);
    }
}
