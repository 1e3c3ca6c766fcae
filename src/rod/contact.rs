//! Contact with colliders inside a step: nodes (and edges dipping between them) are kept outside every
//! collider, grown by the strand's thickness, with Coulomb friction.
//!
//! Two parts, both in each collider's own frame (where a moving collider is still):
//! - **Contact inside the implicit solve.** Every Newton iteration finds the nodes that touch a collider
//!   (at the collider's end pose) and adds, for each, a stiff one-sided spring along the surface normal
//!   (a penalty: a node pressed by its weight sinks `g dt² / 10⁴`, 0.3 µm at 60 Hz) and Coulomb friction
//!   against its slip over the step relative to the collider, smoothed as in IPC (Li et al. 2020):
//!   `f = −μ f_n u / max(|u|, ε)`, with the normal force `f_n` lagged by one iteration. Below the
//!   friction limit a node creeps by at most `ε` per step ([`STICKING_SLIP_SPEED`]); above it, it slides
//!   against `μ f_n`. A sliding node whose slip a Newton update reverses (friction strong enough to stop
//!   it, as on landing) has its friction linearised as a spring towards zero slip for the rest of the
//!   step, so that the iterations do not swing it from side to side. The iterations go on until the set
//!   of touching nodes holds, so the solve knows what supports the strand, and nodes that would be
//!   pulled off are let go.
//! - **What the solve could not see, after it.** A node that ended inside a collider is moved to the
//!   closest surface point; a node whose path over the step crossed the collider (a fast collider, a thin
//!   one) is moved to where the path entered, so nothing tunnels; friction then acts on positions
//!   (Macklin et al. 2014). Edges that dip between their nodes are pushed out at their deepest point. The
//!   length projection and the push-out then alternate, the projection moving touching nodes only along
//!   their colliders' tangent planes (which keeps them outside a convex collider), and the lengths are
//!   restored last.
//!
//! Cost: per step, strand and collider, two ball tests per node (before the solve and after it), which
//! keep the range of nodes that can come near it; then, per Newton iteration, one cheap distance bound
//! per node in that range and exact tests only for what can touch. A node that lands on a collider or
//! starts sliding on it costs one more Newton iteration of its strand.

use std::ops::Range;

use bevy::math::{DMat3, DVec3};

use super::banded::StrandMatrix;
use super::collider::{ColliderShape, MovingCollider, RigidPose, SurfacePoint};
use super::copy_into;
use super::curve::Rod;
use super::energy::node_dof;
use super::error::RodError;
use super::params::StepParams;
use super::projection::{ProjectionScratch, length_error, project_edge_lengths};

/// Rounds of "project lengths, push out again" after the first push-out, at most: they stop as soon as a
/// push-out moves nothing. In a concave corner (an ear against the skull) each push-out and projection
/// moves the node a little less; 4 rounds left nodes up to 3.4 mm inside the `character` example's ear,
/// 8 up to 2.9 mm, 16 none (`tests/gpu/character.rs`).
const CONTACT_ROUNDS: u32 = 16;

/// A push smaller than this, m, does not count as moving a node (rounding on the surface).
const MOVE_TOLERANCE: f64 = 1e-7;

/// A node closer than this to a collider's surface, m, touches it (the spring is in the solve, with no
/// force until the node sinks in).
const CONTACT_GAP: f64 = 1e-6;

/// A touching node that the solve left deeper than this inside a collider, m, is pushed out after it
/// (shallower ones are the spring's own give, which the next step's spring answers).
const PUSH_DEPTH: f64 = 1e-5;

/// Stiffness of the contact spring relative to the node's inertia `m (1/dt² + γ/dt)`: a node pressed by
/// its weight sinks `g dt² / 10⁴` (0.3 µm at 60 Hz) into the collider.
const CONTACT_STIFFNESS_RATIO: f64 = 1e4;

/// A free node closer along the strand to a prescribed node inside a collider than this many times that
/// node's depth (m, from the collider's surface grown by the thickness) is left free of that collider:
/// it could not be outside without stretching the strand (a root inside a hat, a hand or a ceiling plane),
/// so the strand is not torn trying. Hair growing out of a scalp collider has its roots a thickness deep,
/// so only nodes within two thicknesses of the root are let in.
const HELD_REACH: f64 = 2.0;

/// How far along the strand a prescribed node at `local` inside the (grown) collider `shape` holds the
/// strand inside it, m: [`HELD_REACH`] times its depth; `None` when it is not inside.
pub(crate) fn held_reach(shape: &ColliderShape, local: DVec3) -> Option<f64> {
    if !shape.contains(local) {
        return None;
    }
    let surface = shape.closest_surface_point(local);
    Some(HELD_REACH * (surface.point - local).dot(surface.normal).max(0.0))
}

/// Speed, m/s, below which friction acts as a stiff spring on the slip rather than as a constant force
/// (the smoothing of IPC's friction): a node held below its friction limit creeps at most this fast.
pub const STICKING_SLIP_SPEED: f64 = 1e-5;

/// The colliders a rod meets during a step and its collision thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contacts<'a> {
    /// The colliders, with their poses at the start and end of the step.
    pub colliders: &'a [MovingCollider],
    /// Distance from the rod's centre line that must stay outside every collider, m: the strand's
    /// radius plus a margin.
    pub thickness: f64,
}

impl Contacts<'_> {
    /// No colliders.
    pub const NONE: Contacts<'static> = Contacts { colliders: &[], thickness: 0.0 };

    /// Checks the thickness (zero or positive) and every collider.
    pub fn validate(&self) -> Result<(), RodError> {
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return Err(RodError::InvalidCollider { parameter: "thickness", value: self.thickness });
        }
        self.colliders.iter().try_for_each(MovingCollider::validate)
    }
}

/// A node touching a collider at the current Newton iterate.
#[derive(Debug, Clone, Copy, PartialEq)]
struct NodeContact {
    node: usize,
    /// Index of the collider among the nearby ones.
    collider: usize,
    /// Signed distance of the node from the surface, m (negative inside).
    distance: f64,
    /// Outward surface normal at the closest surface point (world).
    normal: DVec3,
    /// Slip over the step along the surface, relative to the collider (world), m.
    slip: DVec3,
    friction: f64,
    /// Whether the contact is new and has not been through a Newton solve yet (its friction had no
    /// normal force).
    first_solve: bool,
    /// Whether a Newton update of this step reversed its slip: its sliding friction is then linearised
    /// as a spring towards zero slip for the rest of the step (see [`Rod::add_contact_forces`]).
    reversed: bool,
}

/// Where a slip `u`, m, lies on the smoothed friction law: sticking (`|u| < ε`) or sliding.
fn is_sticking(slip: DVec3, sticking_slip: f64) -> bool {
    slip.length_squared() < sticking_slip * sticking_slip
}

/// A collider near the rod, ready for per-node tests: its shape grown by the thickness, and the maps
/// between its frame and the world at the start and end of the step.
#[derive(Debug, Clone)]
struct NearbyCollider {
    /// The nodes that can come near it this step (from the first to the last); the others are not tested.
    nodes: Range<usize>,
    /// The nodes held inside it by prescribed nodes there (see [`HELD_REACH`]), which it does not push.
    held: Range<usize>,
    shape: ColliderShape,
    /// Edges longer than this, m, can dip into the collider deeper than the thickness between two nodes
    /// that touch it (the sagitta `l² / 8ρ` of a chord on a surface of curvature radius `ρ`), so they are
    /// tested too.
    edge_test_length: f64,
    friction: f64,
    /// For an ellipsoid, the reciprocals of its semi-axes and of the least of them (1/m), for
    /// [`NearbyCollider::certainly_beyond`].
    ellipsoid_reciprocals: Option<(DVec3, f64)>,
    start_inverse: DMat3,
    start_translation: DVec3,
    end_rotation: DMat3,
    end_inverse: DMat3,
    end_translation: DVec3,
}

impl NearbyCollider {
    fn new(collider: &MovingCollider, thickness: f64, nodes: Range<usize>) -> Self {
        let end_rotation = DMat3::from_quat(collider.end.rotation);
        // A plane grows by moving it out along its normal.
        let lift = |pose: &RigidPose| match collider.shape {
            ColliderShape::Plane => pose.translation + pose.rotation * DVec3::new(0.0, thickness, 0.0),
            _ => pose.translation,
        };
        let shape = collider.shape.inflated(thickness);
        let ellipsoid_reciprocals = match shape {
            ColliderShape::Ellipsoid { semi_axes } => Some((semi_axes.recip(), semi_axes.min_element().recip())),
            _ => None,
        };
        Self {
            nodes,
            held: 0..0,
            shape,
            ellipsoid_reciprocals,
            edge_test_length: (8.0 * collider.shape.smallest_curvature_radius() * thickness).sqrt(),
            friction: collider.friction,
            start_inverse: DMat3::from_quat(collider.start.rotation.inverse()),
            start_translation: lift(&collider.start),
            end_rotation,
            end_inverse: end_rotation.transpose(),
            end_translation: lift(&collider.end),
        }
    }

    /// The nodes that prescribed nodes inside this collider hold there: those within [`HELD_REACH`]
    /// times a prescribed node's depth of it along the strand, the prescribed nodes included, from the
    /// first to the last (empty if none is inside).
    fn held_nodes(&self, rod: &Rod) -> Range<usize> {
        let mut held = 0..0;
        for (node, target) in rod.constraints.node_targets.iter().enumerate() {
            let Some(local) = target.map(|target| self.local_at_end(target)) else {
                continue;
            };
            let Some(reach) = held_reach(&self.shape, local) else {
                continue;
            };
            let (mut first, mut last, mut arc) = (node, node, 0.0);
            while first > 0 && arc + rod.rest.lengths[first - 1] < reach {
                arc += rod.rest.lengths[first - 1];
                first -= 1;
            }
            arc = 0.0;
            while last < rod.edge_count() && arc + rod.rest.lengths[last] < reach {
                arc += rod.rest.lengths[last];
                last += 1;
            }
            held = if held.is_empty() { first..last + 1 } else { held.start.min(first)..held.end.max(last + 1) };
        }
        held
    }

    /// Whether this collider can push `node`: neither prescribed nor held inside it.
    fn pushes(&self, rod: &Rod, node: usize) -> bool {
        !self.held.contains(&node) && !rod.is_node_prescribed(node)
    }

    /// The nodes near this collider that it can push.
    fn free_nodes<'a>(&'a self, rod: &'a Rod) -> impl Iterator<Item = usize> + 'a {
        self.nodes.clone().filter(move |&node| self.pushes(rod, node))
    }

    /// Whether `local` (in this collider's frame) is certainly more than `gap` ≥ 0 m from its surface: the
    /// shape's [`ColliderShape::distance_bound`] above `gap`. An ellipsoid's is taken without its divisions
    /// and square root, `|p / a|² > (1 + gap / a_min)²`, with a margin (a relative 1e-12) wider than
    /// their rounding, so that it never rules out a point the bound does not: the contact tests give the
    /// same results, for fewer cycles (most nodes of a head's hair are tested against its skull).
    fn certainly_beyond(&self, local: DVec3, gap: f64) -> bool {
        match self.ellipsoid_reciprocals {
            Some((inverse_axes, inverse_least)) => {
                let threshold = 1.0 + gap * inverse_least;
                (local * inverse_axes).length_squared() > threshold * threshold * (1.0 + 1e-12)
            }
            None => self.shape.distance_bound(local) > gap,
        }
    }

    fn local_at_start(&self, world: DVec3) -> DVec3 {
        self.start_inverse * (world - self.start_translation)
    }

    fn local_at_end(&self, world: DVec3) -> DVec3 {
        self.end_inverse * (world - self.end_translation)
    }

    fn world_at_end(&self, local: DVec3) -> DVec3 {
        self.end_translation + self.end_rotation * local
    }

    /// Where a node that moved from `local_start` (in the collider's frame) to `end` (world, collider at
    /// its end pose) must go, with the surface normal there (world): the contact point, with friction
    /// applied if `friction`, or `None` if it does not touch.
    fn resolve_node(&self, local_start: DVec3, end: DVec3, friction: bool) -> Option<(DVec3, DVec3)> {
        let local_end = self.local_at_end(end);
        if self.certainly_beyond(local_end, local_end.distance(local_start)) {
            return None;
        }
        let started_inside = self.shape.contains(local_start);
        let entry = || (!started_inside).then(|| self.shape.entry(local_start, local_end)).flatten();
        let hit: SurfacePoint = if self.shape.contains(local_end) {
            let closest = self.shape.closest_surface_point(local_end);
            // A path that came in from the far side went past the middle: back to where it entered.
            match entry() {
                Some(entered) if entered.normal.dot(closest.normal) < 0.0 => entered,
                _ => closest,
            }
        } else {
            entry()?
        };
        let mut point = hit.point;
        if friction && self.friction > 0.0 {
            // Only the motion along the surface counts: measured from where the node was, put on the surface.
            let anchor = if started_inside { local_start } else { self.shape.closest_surface_point(local_start).point };
            let depth = (hit.point - local_end).dot(hit.normal).max(0.0);
            let moved = hit.point - anchor;
            let tangential = moved - moved.dot(hit.normal) * hit.normal;
            let limit = self.friction * depth;
            let length = tangential.length();
            point -= if length <= limit { tangential } else { limit / length * tangential };
        }
        Some((self.world_at_end(point), self.end_rotation * hit.normal))
    }

    /// The contact geometry of `node` at `position` (world, collider at its end pose), for this collider
    /// (`index` among the nearby ones); `start` is where the node was at the start of the step.
    fn contact(&self, index: usize, node: usize, position: DVec3, start: DVec3) -> NodeContact {
        let local = self.local_at_end(position);
        let surface = self.shape.closest_surface_point(local);
        let normal = self.end_rotation * surface.normal;
        let moved = position - self.world_at_end(self.local_at_start(start));
        NodeContact {
            node,
            collider: index,
            distance: (local - surface.point).dot(surface.normal),
            normal,
            slip: moved - moved.dot(normal) * normal,
            friction: self.friction,
            first_solve: true,
            reversed: false,
        }
    }

    /// A contact of `node` at `position` (world, collider at its end pose) if it lies within `gap` m of
    /// the surface and started the step (at `start`) outside the tangent plane there, in the collider's
    /// frame. A node that started behind that plane was swept past by the collider: its closest point is
    /// on the wrong side, and the push-out after the solve finds where its path entered instead.
    fn new_contact(&self, index: usize, node: usize, position: DVec3, start: DVec3, gap: f64) -> Option<NodeContact> {
        if self.certainly_beyond(self.local_at_end(position), gap) {
            return None;
        }
        let contact = self.contact(index, node, position, start);
        let normal = self.end_inverse * contact.normal;
        let surface_point = self.local_at_end(position) - contact.distance * normal;
        let approached_from_outside = normal.dot(self.local_at_start(start) - surface_point) >= -PUSH_DEPTH;
        (contact.distance <= gap && approached_from_outside).then_some(contact)
    }

    /// The closest surface point (world) and the normal there, if `world` (collider at its end pose) is
    /// more than `depth` m inside.
    fn closest_if_deeper(&self, world: DVec3, depth: f64) -> Option<(DVec3, DVec3)> {
        let local = self.local_at_end(world);
        if !self.shape.contains(local) {
            return None;
        }
        let surface = self.shape.closest_surface_point(local);
        ((surface.point - local).dot(surface.normal) > depth)
            .then(|| (self.world_at_end(surface.point), self.end_rotation * surface.normal))
    }

    /// The push, in world space, that moves the point of the edge `start`–`end` deepest inside the shape
    /// out to the surface, with that point's fraction along the edge.
    fn edge_push(&self, start: DVec3, end: DVec3) -> Option<(f64, DVec3)> {
        let (local_start, local_end) = (self.local_at_end(start), self.local_at_end(end));
        if self.certainly_beyond(local_start, local_start.distance(local_end)) {
            return None;
        }
        let (fraction, surface) = self.shape.segment_contact(local_start, local_end)?;
        let deepest = local_start.lerp(local_end, fraction);
        Some((fraction, self.end_rotation * (surface.point - deepest)))
    }
}

/// The matrix `v vᵀ`.
pub(crate) fn outer_product(v: DVec3) -> DMat3 {
    DMat3::from_cols(v.x * v, v.y * v, v.z * v)
}

/// Where each node came from in a push-out pass.
#[derive(Debug, Clone, Copy)]
enum NodePaths<'a> {
    /// The positions at the start of the step, with each collider at its start pose; friction applies.
    Step(&'a [DVec3]),
    /// The positions before a length projection moved the nodes, with each collider at its end pose: a
    /// node the projection dragged through a collider is caught too.
    Round(&'a [DVec3]),
}

/// Scratch memory of the contact handling, kept with the rod's workspace.
#[derive(Debug, Clone, Default)]
pub(crate) struct ContactScratch {
    nearby: Vec<NearbyCollider>,
    /// Every contact made during the step, refreshed at each Newton iterate (those the iterate has
    /// left have no force).
    touching: Vec<NodeContact>,
    /// Normal force on each node from the last Newton update, N: friction's lagged `f_n`. During a step
    /// this holds the rod's own [`Rod::contact_normal_forces`] (swapped in and out by the solver), so
    /// that one workspace serves many rods.
    pub(crate) normal_forces: Vec<f64>,
    /// Per node: listed in `touching` (during the Newton iterations), then in contact (after them).
    touched: Vec<bool>,
    /// Positions before the last length projection of the contact rounds.
    before_projection: Vec<DVec3>,
}

impl ContactScratch {
    /// Keeps the colliders of `contacts` whose swept bounds come within `margin` of a node of `rod`, at
    /// `start_positions` or where it is now, or of an edge between them, with the range of nodes that do
    /// and the range held inside.
    fn find_nearby(&mut self, rod: &Rod, contacts: &Contacts, start_positions: &[DVec3], margin: f64) {
        let (positions, longest_edge) = (&rod.state.positions, rod.longest_rest_edge());
        self.nearby.clear();
        // The box around every node, at the start and now: a collider whose bounds miss it has no node
        // near (the margin keeps rounding from missing one the test below would find).
        let (low, high) = positions
            .iter()
            .chain(start_positions)
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), &p| (low.min(p), high.max(p)));
        for collider in contacts.colliders {
            // A point of an edge within the bounds puts one of its ends within half an edge of them.
            let (centre, radius) = collider.swept_bounds(contacts.thickness + margin + 0.5 * longest_edge);
            let reach = radius * (1.0 + 1e-9) + 1e-12;
            if centre.clamp(low, high).distance_squared(centre) > reach * reach {
                continue;
            }
            let near = |node: &usize| {
                let nearest =
                    start_positions[*node].distance_squared(centre).min(positions[*node].distance_squared(centre));
                nearest <= radius * radius
            };
            let Some(first) = (0..positions.len()).find(near) else {
                continue;
            };
            let last = (first..positions.len()).rev().find(near).unwrap_or(first);
            let mut nearby = NearbyCollider::new(collider, contacts.thickness, first..last + 1);
            nearby.held = nearby.held_nodes(rod);
            self.nearby.push(nearby);
        }
    }
}

impl Rod {
    /// Prepares the contact handling of a step: finds the colliders that can come near the rod, moving
    /// from `start_positions` at its start velocities and under gravity for a step (with room to spare).
    pub(crate) fn begin_contacts(
        &self,
        contacts: &Contacts,
        params: &StepParams,
        start_positions: &[DVec3],
        scratch: &mut ContactScratch,
    ) {
        scratch.touching.clear();
        scratch.touched.clear();
        scratch.touched.resize(self.node_count(), false);
        if contacts.colliders.is_empty() {
            scratch.nearby.clear();
            scratch.normal_forces.fill(0.0);
            return;
        }
        let fastest = self.state.velocities.iter().map(|v| v.length()).fold(0.0, f64::max);
        let reach = 2.0 * (fastest * params.dt + params.gravity.length() * params.dt * params.dt);
        scratch.find_nearby(self, contacts, start_positions, reach);
        // Room for every node touching every nearby collider, so that no later iterate allocates.
        scratch.touching.reserve(self.node_count() * scratch.nearby.len());
    }

    /// The contact spring's stiffness for `node`, N/m: [`CONTACT_STIFFNESS_RATIO`] times its inertia
    /// `m (1/h² + γ/h)` (`inertia_scale` the bracket, `h` the integrator's step).
    fn contact_stiffness(&self, node: usize, inertia_scale: f64) -> f64 {
        CONTACT_STIFFNESS_RATIO * self.inertia.masses[node] * inertia_scale
    }

    /// The normal force, N, that stops `node` found `distance` m from a collider's surface (negative
    /// inside) within the step: `m (1/h² + γ/h) (−d)`, what the contact spring settles to when the
    /// node's inertia carried it that deep (`inertia_scale` the bracket); zero outside.
    fn stopping_force(&self, node: usize, inertia_scale: f64, distance: f64) -> f64 {
        self.inertia.masses[node] * inertia_scale * (-distance).max(0.0)
    }

    /// Adds contact to the Newton system at the current iterate (see the module documentation): for each
    /// node touching a collider, the one-sided normal spring `½ k d²` (`d` the signed distance, `k` from
    /// the node's inertia) and the smoothed, lagged Coulomb friction `μ f_n φ(|u|)` on its slip `u`, with
    /// Hessian `μ f_n / ε P` while `|u| < ε` and `μ f_n / |u| (P − ûûᵀ)` beyond (`P` the tangent
    /// projector; both positive semi-definite).
    pub(crate) fn add_contact_forces(
        &self,
        scratch: &mut ContactScratch,
        start_positions: &[DVec3],
        params: &StepParams,
        inertia_scale: f64,
        residual: &mut [f64],
        hessian: &mut impl StrandMatrix,
    ) {
        let ContactScratch { nearby, touching, normal_forces, touched, .. } = scratch;
        for contact in touching.iter_mut() {
            let (node, first_solve, reversed) = (contact.node, contact.first_solve, contact.reversed);
            *contact = nearby[contact.collider].contact(
                contact.collider,
                node,
                self.state.positions[node],
                start_positions[node],
            );
            (contact.first_solve, contact.reversed) = (first_solve, reversed);
        }
        for (index, collider) in nearby.iter().enumerate() {
            for node in collider.free_nodes(self) {
                let known = || touching.iter().any(|contact| contact.node == node && contact.collider == index);
                if touched[node] && known() {
                    continue;
                }
                if let Some(mut contact) =
                    collider.new_contact(index, node, self.state.positions[node], start_positions[node], CONTACT_GAP)
                {
                    // A node resting since the last step has its normal force from then, one found inside
                    // the force that stops it there.
                    normal_forces[node] =
                        normal_forces[node].max(self.stopping_force(node, inertia_scale, contact.distance));
                    contact.first_solve = normal_forces[node] == 0.0;
                    touching.push(contact);
                    touched[node] = true;
                }
            }
        }
        let sticking_slip = STICKING_SLIP_SPEED * params.dt;
        // A contact the iterate has left stays listed (so that it is not counted as new if it comes
        // back), with no force.
        for contact in touching.iter().filter(|contact| contact.distance <= CONTACT_GAP) {
            let dof = node_dof(contact.node);
            let stiffness = self.contact_stiffness(contact.node, inertia_scale);
            let n = contact.normal;
            let tangent_projector = DMat3::IDENTITY - outer_product(n);
            let mut force = stiffness * contact.distance.min(0.0) * n;
            let mut block = stiffness * outer_product(n);
            let limit = contact.friction * normal_forces[contact.node];
            if is_sticking(contact.slip, sticking_slip) {
                force += limit / sticking_slip * contact.slip;
                block += limit / sticking_slip * tangent_projector;
            } else {
                let slip = contact.slip.length();
                let direction = contact.slip / slip;
                force += limit * direction;
                // Sliding friction is constant along the slip, so its exact Hessian has nothing there.
                // Where a linear step with it carried the node back past zero slip (friction strong
                // enough to stop the slip, as on landing), the iterations would swing from side to
                // side: from then on it is linearised as a spring towards zero slip with the same force
                // (a Picard step), which does not overshoot.
                let along = if contact.reversed { DMat3::ZERO } else { outer_product(direction) };
                block += limit / slip * (tangent_projector - along);
            }
            for row in 0..3 {
                residual[dof + row] += force[row];
                for column in 0..=row {
                    hessian.add(dof + row, dof + column, block.col(column)[row]);
                }
            }
        }
    }

    /// After a Newton solve: records each touching node's normal force where the update `node_update`
    /// puts it (the spring's force, linearised), for the next iterate's friction; for a free node that
    /// would sink into a collider, the force that stops it there (so its new contact has friction from
    /// its first solve); zero for the other nodes. Returns whether the update leaves the law it was
    /// linearised with: a touching node that would pass from sticking to sliding, a sliding node whose
    /// slip the update reverses (or, once linearised as a spring, changes by more than a tenth), a new
    /// contact whose friction had no normal force yet, or a free node that would sink into a collider;
    /// the Newton iterations then go on. (A node that lifts off stays listed for the rest of the step, without
    /// force, so that the touching set only grows and the iterations end.)
    pub(crate) fn update_contacts(
        &self,
        scratch: &mut ContactScratch,
        start_positions: &[DVec3],
        params: &StepParams,
        inertia_scale: f64,
        node_update: impl Fn(usize) -> DVec3,
    ) -> bool {
        let sticking_slip = STICKING_SLIP_SPEED * params.dt;
        let ContactScratch { nearby, touching, normal_forces, touched, .. } = scratch;
        normal_forces.fill(0.0);
        let mut changed = false;
        for contact in touching.iter_mut().filter(|contact| contact.distance <= CONTACT_GAP) {
            let stiffness = self.contact_stiffness(contact.node, inertia_scale);
            let update = node_update(contact.node);
            let distance = contact.distance + contact.normal.dot(update);
            normal_forces[contact.node] += stiffness * (-distance).max(0.0);
            let slip = contact.slip + update - contact.normal.dot(update) * contact.normal;
            // Sticking past the smoothing width: the friction force would be its limit, not the spring.
            // A new contact's friction had no normal force yet: once more with the one it now has.
            // A sliding node whose slip the update reverses takes the spring linearisation from now on;
            // one that has it is checked: the spring's force was right only if the slip kept its
            // size (within a tenth).
            let sliding = !is_sticking(contact.slip, sticking_slip) && !is_sticking(slip, sticking_slip);
            let reverses = sliding && !contact.reversed && slip.dot(contact.slip) < 0.0;
            let spring_missed =
                sliding && contact.reversed && (slip - contact.slip).length() > 0.1 * contact.slip.length();
            contact.reversed |= reverses;
            changed |= is_sticking(contact.slip, sticking_slip) && !is_sticking(slip, sticking_slip)
                || (contact.first_solve && contact.friction > 0.0)
                || reverses
                || spring_missed;
            contact.first_solve = false;
        }
        for (index, collider) in nearby.iter().enumerate() {
            for node in collider.free_nodes(self).filter(|&node| !touched[node]) {
                let position = self.state.positions[node] + node_update(node);
                if let Some(contact) = collider.new_contact(index, node, position, start_positions[node], 0.0) {
                    normal_forces[node] =
                        normal_forces[node].max(self.stopping_force(node, inertia_scale, contact.distance));
                    changed = true;
                }
            }
        }
        changed
    }

    /// Keeps the rod outside `contacts`' colliders after the implicit solve (see the module
    /// documentation); `start_positions` are the positions at the start of the step. Returns the number
    /// of nodes in contact and the projection iterations used.
    pub(crate) fn resolve_contacts(
        &mut self,
        contacts: &Contacts,
        start_positions: &[DVec3],
        params: &StepParams,
        projection: &mut ProjectionScratch,
        scratch: &mut ContactScratch,
    ) -> (u32, u32) {
        scratch.find_nearby(self, contacts, start_positions, 0.0);
        let ContactScratch { nearby, touching, touched, before_projection, .. } = scratch;
        touched.clear();
        touched.resize(self.node_count(), false);
        projection.use_rod_masses(self);
        for contact in touching.iter().filter(|contact| contact.distance <= CONTACT_GAP) {
            touched[contact.node] = true;
            projection.contact_normals[contact.node] = contact.normal;
        }
        let mut moved = self.push_out(nearby, touched, projection, NodePaths::Step(start_positions));
        let mut projection_iterations = 0;
        for _ in 0..CONTACT_ROUNDS {
            if !moved {
                break;
            }
            projection_iterations += self.project_along_surfaces(params, projection, before_projection);
            moved = self.push_out(nearby, touched, projection, NodePaths::Round(before_projection));
        }
        if moved {
            // Lengths come last: a stretched edge would spring back with thousands of times the hair's
            // weight next step, while touching nodes only slide along their (convex) colliders.
            projection_iterations += self.project_along_surfaces(params, projection, before_projection);
        }
        let in_contact = touched.iter().filter(|touched| **touched).count();
        (in_contact as u32, projection_iterations)
    }

    /// The length projection with touching nodes moving only along their colliders' tangent planes; when
    /// the lengths cannot be met that way (a collider pushing the strand ahead of it), it starts again
    /// with touching nodes free, and the next push-out puts them back. `before_projection` keeps the
    /// positions it started from. Returns the projection iterations.
    fn project_along_surfaces(
        &mut self,
        params: &StepParams,
        projection: &mut ProjectionScratch,
        before_projection: &mut Vec<DVec3>,
    ) -> u32 {
        copy_into(before_projection, &self.state.positions);
        let mut iterations = project_edge_lengths(self, params, projection);
        let error = length_error(self, &projection.target_lengths);
        if error.is_nan() || error > params.strain_tolerance {
            self.state.positions.copy_from_slice(before_projection);
            projection.contact_normals.fill(DVec3::ZERO);
            iterations += project_edge_lengths(self, params, projection);
        }
        iterations
    }

    /// One pass over every collider: free nodes that ended inside or whose path entered are moved to the
    /// surface, then edges dipping in are pushed out at their deepest point; what was pushed is marked in
    /// `touched`, with its surface normal in the projection's contact normals. Returns whether anything
    /// moved.
    fn push_out(
        &mut self,
        nearby: &[NearbyCollider],
        touched: &mut [bool],
        projection: &mut ProjectionScratch,
        paths: NodePaths,
    ) -> bool {
        let ProjectionScratch { inverse_masses, contact_normals, .. } = projection;
        let mut moved = false;
        for collider in nearby {
            for node in collider.nodes.clone() {
                if !collider.pushes(self, node) {
                    continue;
                }
                let end = self.state.positions[node];
                let resolved = match paths {
                    // Touching nodes moved along the surface on purpose, held by their springs.
                    _ if touched[node] => collider.closest_if_deeper(end, PUSH_DEPTH),
                    NodePaths::Step(starts) => collider.resolve_node(collider.local_at_start(starts[node]), end, true),
                    NodePaths::Round(starts) => collider.resolve_node(collider.local_at_end(starts[node]), end, false),
                };
                if let Some((position, normal)) = resolved {
                    moved |= position.distance_squared(end) > MOVE_TOLERANCE * MOVE_TOLERANCE;
                    self.state.positions[node] = position;
                    touched[node] = true;
                    contact_normals[node] = normal;
                }
            }
            // Edges at a prescribed or held node (a root inside its head) are left to their free node's test.
            for edge in collider.nodes.start.saturating_sub(1)..collider.nodes.end.min(self.edge_count()) {
                if !(collider.pushes(self, edge) && collider.pushes(self, edge + 1)) {
                    continue;
                }
                let (start, end) = (self.state.positions[edge], self.state.positions[edge + 1]);
                if start.distance_squared(end) <= collider.edge_test_length * collider.edge_test_length {
                    continue;
                }
                let Some((fraction, push)) = collider.edge_push(start, end) else {
                    continue;
                };
                let (start_weight, end_weight) = (inverse_masses[edge], inverse_masses[edge + 1]);
                let (start_share, end_share) = ((1.0 - fraction) * start_weight, fraction * end_weight);
                let scale = (1.0 - fraction) * start_share + fraction * end_share;
                if scale <= 0.0 {
                    continue;
                }
                self.state.positions[edge] += start_share / scale * push;
                self.state.positions[edge + 1] += end_share / scale * push;
                moved |= push.length_squared() > MOVE_TOLERANCE * MOVE_TOLERANCE;
                let normal = push.normalize_or_zero();
                for node in [edge, edge + 1] {
                    touched[node] = true;
                    contact_normals[node] = normal;
                }
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quick ellipsoid test behind the contact tests rules out a point only where the shape's distance
    /// bound does (so the contacts found are the same), and every point the bound puts clearly beyond.
    #[test]
    fn the_quick_ellipsoid_test_rules_out_what_the_distance_bound_rules_out() {
        let collider = MovingCollider {
            shape: ColliderShape::ellipsoid(DVec3::new(0.078, 0.095, 0.1)),
            friction: 0.3,
            start: RigidPose::default(),
            end: RigidPose::default(),
        };
        let nearby = NearbyCollider::new(&collider, 1.04e-3, 0..1);
        let ColliderShape::Ellipsoid { semi_axes } = nearby.shape else { unreachable!("an ellipsoid stays one") };
        let mut random = fastrand::Rng::with_seed(7);
        let mut within_a_nanometre = 0;
        for sample in 0..400_000 {
            let direction = DVec3::new(random.f64() - 0.5, random.f64() - 0.5, random.f64() - 0.5);
            let Some(direction) = direction.try_normalize() else { continue };
            let gap = [0.0, CONTACT_GAP, 0.01 * random.f64()][sample % 3];
            let on_surface = direction / (direction / semi_axes).length();
            // Half the points within a nanometre of where the bound equals the gap, half anywhere from
            // 8 cm inside to 2 cm out.
            let offset =
                if sample % 2 == 0 { gap + 1e-9 * (2.0 * random.f64() - 1.0) } else { 0.1 * random.f64() - 0.08 };
            let point = on_surface * (1.0 + offset / semi_axes.min_element());
            let bound = nearby.shape.distance_bound(point);
            within_a_nanometre += usize::from((bound - gap).abs() < 1e-9);
            let quick = nearby.certainly_beyond(point, gap);
            assert!(!quick || bound > gap, "{point} ruled out {gap} m away, its bound {bound} m");
            assert!(quick || bound <= gap + 1e-12, "{point} kept {gap} m away, its bound {bound} m");
        }
        assert!(within_a_nanometre > 100_000, "only {within_a_nanometre} points near the threshold");
    }

    /// `find_nearby` keeps every collider a node is near, at the start or now, with the nodes from the
    /// first near one to the last: checked node by node against colliders placed at random, half of them
    /// within a micrometre of the reach of a node that moved.
    #[test]
    fn the_colliders_found_nearby_are_those_a_node_is_near() {
        use crate::rod::RodMaterial;
        let arc = |t: f64| DVec3::new(0.1 * t.sin(), -0.2 * t, 0.05 * (1.0 - t.cos()));
        let positions: Vec<DVec3> = (0..=24).map(|i| arc(i as f64 / 24.0)).collect();
        let mut rod = Rod::new(&positions, DVec3::X, RodMaterial::human_hair()).unwrap();
        // The step moved the hair: its start lies 3 cm to the side and 1 cm up, twisted a little.
        let start_positions: Vec<DVec3> =
            positions.iter().enumerate().map(|(i, p)| *p + DVec3::new(0.03, 0.01, 0.001 * i as f64)).collect();
        rod.state.positions[..].copy_from_slice(&positions);
        let mut random = fastrand::Rng::with_seed(11);
        let (thickness, margin) = (1e-3, 2e-3);
        let mut unit = || DVec3::new(random.f64() - 0.5, random.f64() - 0.5, random.f64() - 0.5).normalize();
        let mut colliders = Vec::new();
        let mut placing = fastrand::Rng::with_seed(12);
        for index in 0..400 {
            let radius = 0.005 + 0.02 * placing.f64();
            let travel = 0.01 * unit();
            let probe = MovingCollider {
                shape: ColliderShape::sphere(radius),
                friction: 0.0,
                start: RigidPose::default(),
                end: RigidPose::new(Default::default(), travel),
            };
            let reach = probe.swept_bounds(thickness + margin + 0.5 * rod.longest_rest_edge()).1;
            let distance =
                if index % 2 == 0 { reach + 1e-6 * (2.0 * placing.f64() - 1.0) } else { 0.5 * placing.f64() };
            // A quarter straight out from the node farthest along an axis: there the box around the nodes
            // is as near the collider as that node is.
            let centre = if index % 4 == 0 {
                let axis =
                    [DVec3::X, DVec3::Y, DVec3::Z, DVec3::NEG_X, DVec3::NEG_Y, DVec3::NEG_Z][placing.usize(0..6)];
                let all = positions.iter().chain(&start_positions);
                let farthest = all.max_by(|a, b| a.dot(axis).total_cmp(&b.dot(axis))).unwrap();
                *farthest + distance * axis
            } else {
                let node = placing.usize(0..positions.len());
                let from = if placing.bool() { start_positions[node] } else { positions[node] };
                from + distance * unit()
            };
            let pose = |offset: DVec3| RigidPose::new(Default::default(), centre - 0.5 * travel + offset);
            colliders.push(MovingCollider { start: pose(DVec3::ZERO), end: pose(travel), ..probe });
        }
        let contacts = Contacts { colliders: &colliders, thickness };
        let mut scratch = ContactScratch::default();
        scratch.find_nearby(&rod, &contacts, &start_positions, margin);
        let mut found = scratch.nearby.iter();
        let mut kept = 0;
        for collider in &colliders {
            let (centre, reach) = collider.swept_bounds(thickness + margin + 0.5 * rod.longest_rest_edge());
            let near: Vec<usize> = (0..positions.len())
                .filter(|&node| {
                    start_positions[node].distance_squared(centre).min(positions[node].distance_squared(centre))
                        <= reach * reach
                })
                .collect();
            if let (Some(&first), Some(&last)) = (near.first(), near.last()) {
                let nearby = found.next().expect("a collider a node is near is found");
                assert_eq!(nearby.nodes, first..last + 1, "the collider at {centre} ({reach} m)");
                kept += 1;
            }
        }
        assert!(found.next().is_none(), "no collider is found that no node is near");
        assert!((100..300).contains(&kept), "{kept} of 400 colliders near: the test sees both kinds");
    }
}
