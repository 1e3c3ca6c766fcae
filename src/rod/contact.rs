//! Contact with colliders inside a step: nodes (and edges dipping between them) are kept outside every
//! collider, grown by the strand's thickness, with Coulomb friction.
//!
//! Two parts, both in each collider's own frame (where a moving collider is still):
//! - **Resting contact, inside the implicit solve.** A node that starts the step on a collider is held
//!   there by a stiff spring `k` in the Newton system: in all directions while static friction holds it
//!   (it stays where it was on the collider), along the normal only once it slides, with the kinetic
//!   friction force `μ f_n` against its motion. After each solve the spring's force gives the contact
//!   force: a pulling normal force lets go, a tangential force above `μ f_n` starts sliding, and the
//!   Newton iterations go on until the contact set holds, so the solve knows what supports the strand.
//!   (Not yet enough: a free strand draped over a sphere still slides off; see issue 5.)
//! - **New contact, after the solve.** A node the solve put inside a collider is moved to the closest
//!   surface point; a node whose path over the step crossed the collider (a fast collider, a thin one)
//!   is moved to where the path entered, so nothing tunnels. Friction is applied on positions (Macklin
//!   et al. 2014): the normal push `d` is the normal impulse times `dt/m`, so the tangential displacement
//!   relative to the surface is removed when at most `μ d`, shortened by `μ d` otherwise. Edges that dip
//!   between their nodes are pushed out at their deepest point. As pushes stretch edges, the length
//!   projection and the push-out then alternate for a few rounds.
//!
//! Cost: per step and strand, one bounding-box test per collider; then, per collider near the strand,
//! one cheap distance bound per node and per edge, and exact tests only for what can touch it.

use bevy::math::{DMat3, DVec3};

use super::banded::BandedMatrix;
use super::collider::{ColliderShape, MovingCollider, RigidPose, SurfacePoint};
use super::curve::Rod;
use super::energy::node_dof;
use super::error::RodError;
use super::projection::{ProjectionScratch, length_error, project_edge_lengths};
use super::solver::{StepParams, copy_into};

/// Rounds of "project lengths, push out again" after the first push-out.
const CONTACT_ROUNDS: u32 = 4;

/// A push smaller than this, m, does not count as moving a node (rounding on the surface).
const MOVE_TOLERANCE: f64 = 1e-7;

/// A node that starts a step within this distance of a collider's surface, m, rests on it, and so does
/// one within half the distance gravity moves it in a step (it lands during the step).
const RESTING_DISTANCE: f64 = 1e-5;

/// Slip, m per step, below which a sliding node's friction keeps the direction it broke free in (so that
/// the linearisation stays regular near zero slip).
const SMALLEST_SLIP: f64 = 1e-9;

/// Stiffness of the resting-contact spring relative to the node's inertia `m (1/dt² + γ/dt)`: a node
/// pressed by its weight sinks `g dt² / 10⁴` (0.3 µm at 60 Hz) into the collider.
const CONTACT_STIFFNESS_RATIO: f64 = 1e4;

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

/// A node resting on a collider at the start of the step, held in the implicit solve by a spring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RestingContact {
    node: usize,
    /// The node's place on the collider at the start of the step, carried to the collider's pose at the
    /// end of the step (world, m): where static friction keeps it.
    anchor: DVec3,
    /// Outward surface normal at the anchor (world).
    normal: DVec3,
    friction: f64,
    /// Spring stiffness, N/m, set by the Newton iteration from the node's inertia.
    stiffness: f64,
    /// Whether the node slides (the spring holds only the normal) rather than sticks.
    sliding: bool,
    /// Direction of the slip once sliding: that of the slip the spring resisted when the node broke free,
    /// then that of the current slip.
    slip_direction: DVec3,
    /// Normal force of the last Newton update, N.
    normal_force: f64,
}

/// A collider near the rod, ready for per-node tests: its shape grown by the thickness, and the maps
/// between its frame and the world at the start and end of the step.
#[derive(Debug, Clone, Copy)]
struct NearbyCollider {
    shape: ColliderShape,
    /// Edges longer than this, m, can dip into the collider deeper than the thickness between two nodes
    /// that touch it (the sagitta `l² / 8ρ` of a chord on a surface of curvature radius `ρ`), so they are
    /// tested too.
    edge_test_length: f64,
    friction: f64,
    start_inverse: DMat3,
    start_translation: DVec3,
    end_rotation: DMat3,
    end_inverse: DMat3,
    end_translation: DVec3,
}

impl NearbyCollider {
    fn new(collider: &MovingCollider, thickness: f64) -> Self {
        let end_rotation = DMat3::from_quat(collider.end.rotation);
        // A plane grows by moving it out along its normal.
        let lift = |pose: &RigidPose| match collider.shape {
            ColliderShape::Plane => pose.translation + pose.rotation * DVec3::new(0.0, thickness, 0.0),
            _ => pose.translation,
        };
        Self {
            shape: collider.shape.inflated(thickness),
            edge_test_length: (8.0 * collider.shape.smallest_curvature_radius() * thickness).sqrt(),
            friction: collider.friction,
            start_inverse: DMat3::from_quat(collider.start.rotation.inverse()),
            start_translation: lift(&collider.start),
            end_rotation,
            end_inverse: end_rotation.transpose(),
            end_translation: lift(&collider.end),
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
    /// its end pose) must go: the contact point, with friction applied if `friction`, or `None` if it does
    /// not touch.
    fn resolve_node(&self, local_start: DVec3, end: DVec3, friction: bool) -> Option<DVec3> {
        let local_end = self.local_at_end(end);
        if self.shape.distance_bound(local_end) > local_end.distance(local_start) {
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
        Some(self.world_at_end(point))
    }

    /// The push, in world space, that moves the point of the edge `start`–`end` deepest inside the shape
    /// out to the surface, with that point's fraction along the edge.
    fn edge_push(&self, start: DVec3, end: DVec3) -> Option<(f64, DVec3)> {
        let (local_start, local_end) = (self.local_at_end(start), self.local_at_end(end));
        if self.shape.distance_bound(local_start) > local_start.distance(local_end) {
            return None;
        }
        let (fraction, surface) = self.shape.segment_contact(local_start, local_end)?;
        let deepest = local_start.lerp(local_end, fraction);
        Some((fraction, self.end_rotation * (surface.point - deepest)))
    }
}

/// The matrix `v vᵀ`.
fn outer_product(v: DVec3) -> DMat3 {
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

/// Scratch memory of the contact handling.
#[derive(Debug, Clone, Default)]
pub(crate) struct ContactScratch {
    nearby: Vec<NearbyCollider>,
    pub(crate) resting: Vec<RestingContact>,
    touched: Vec<bool>,
    stuck: Vec<bool>,
    before_projection: Vec<DVec3>,
}

impl ContactScratch {
    /// Keeps the colliders of `contacts` whose swept bounds meet the box around `positions`.
    fn find_nearby<'a>(&mut self, contacts: &Contacts, positions: impl Iterator<Item = &'a DVec3>) {
        let (low, high) = positions
            .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(low, high), position| {
                (low.min(*position), high.max(*position))
            });
        self.nearby.clear();
        self.nearby.extend(
            contacts
                .colliders
                .iter()
                .filter(|collider| {
                    let (centre, radius) = collider.swept_bounds(contacts.thickness);
                    centre.clamp(low, high).distance_squared(centre) <= radius * radius
                })
                .map(|collider| NearbyCollider::new(collider, contacts.thickness)),
        );
    }
}

impl Rod {
    /// Finds the nodes that rest on a collider at the start of the step (`start_positions`): their
    /// springs hold them in the coming Newton iterations (one that would rather lift off is let go).
    pub(crate) fn find_resting_contacts(
        &self,
        contacts: &Contacts,
        params: &StepParams,
        start_positions: &[DVec3],
        scratch: &mut ContactScratch,
    ) {
        scratch.resting.clear();
        if contacts.colliders.is_empty() {
            return;
        }
        let band = RESTING_DISTANCE + 0.5 * params.gravity.length() * params.dt * params.dt;
        scratch.find_nearby(contacts, start_positions.iter().chain(&self.positions));
        for collider in &scratch.nearby {
            for (node, start) in start_positions.iter().enumerate() {
                let local = collider.local_at_start(*start);
                if self.is_node_prescribed(node) || collider.shape.distance_bound(local) > band {
                    continue;
                }
                let surface = collider.shape.closest_surface_point(local);
                let height = (local - surface.point).dot(surface.normal);
                if (-RESTING_DISTANCE..=band).contains(&height) {
                    scratch.resting.push(RestingContact {
                        node,
                        anchor: collider.world_at_end(surface.point),
                        normal: collider.end_rotation * surface.normal,
                        friction: collider.friction,
                        stiffness: 0.0,
                        sliding: false,
                        slip_direction: DVec3::ZERO,
                        normal_force: 0.0,
                    });
                }
            }
        }
    }

    /// Adds the resting contacts to the Newton system. The normal is held by the stiff spring
    /// `½ k (n·(x − a))²`. Along the surface, a sticking node is held by the same spring; a sliding one
    /// feels the kinetic friction force `−μ f_n ŝ` against its slip `s` (the tangential part of `x − a`),
    /// with `f_n` from the previous Newton update (lagged, as in IPC, Li et al. 2020), linearised into the
    /// Hessian as `μ f_n / |s| (P − ŝŝᵀ)` (`P` the tangent projector), which is positive semi-definite.
    pub(crate) fn add_contact_springs(
        &self,
        resting: &mut [RestingContact],
        inertia_scale: f64,
        residual: &mut [f64],
        hessian: &mut BandedMatrix,
    ) {
        for contact in resting {
            let dof = node_dof(contact.node);
            contact.stiffness = CONTACT_STIFFNESS_RATIO * self.masses[contact.node] * inertia_scale;
            let (k, n) = (contact.stiffness, contact.normal);
            let offset = self.positions[contact.node] - contact.anchor;
            let slip = offset - n.dot(offset) * n;
            let mut force = k * n.dot(offset) * n;
            let mut block = k * outer_product(n);
            let tangent_projector = DMat3::IDENTITY - outer_product(n);
            if !contact.sliding {
                force += k * slip;
                block += k * tangent_projector;
            } else {
                let limit = contact.friction * contact.normal_force;
                let length = slip.length();
                if length > SMALLEST_SLIP {
                    contact.slip_direction = slip / length;
                }
                let direction = contact.slip_direction;
                force += limit * direction;
                block += limit / length.max(SMALLEST_SLIP) * (tangent_projector - outer_product(direction));
            }
            for row in 0..3 {
                residual[dof + row] += force[row];
                for column in 0..=row {
                    hessian.add(dof + row, dof + column, block.col(column)[row]);
                }
            }
        }
    }

    /// Reads each resting contact's normal force from its spring for the Newton update `node_update`
    /// (the full update, before any trust-region scaling): a contact that pulls lets go, and a sticking one
    /// held along the surface harder than `μ f_n` starts sliding. Returns whether the contact set changed
    /// (the Newton iterations must then go on).
    pub(crate) fn update_resting_contacts(
        &self,
        resting: &mut Vec<RestingContact>,
        node_update: impl Fn(usize) -> DVec3,
    ) -> bool {
        let mut changed = false;
        resting.retain_mut(|contact| {
            let offset = self.positions[contact.node] + node_update(contact.node) - contact.anchor;
            contact.normal_force = -contact.stiffness * contact.normal.dot(offset);
            if contact.normal_force < 0.0 {
                changed = true;
                return false;
            }
            let slip = offset - contact.normal.dot(offset) * contact.normal;
            if !contact.sliding && contact.stiffness * slip.length() > contact.friction * contact.normal_force {
                contact.sliding = true;
                contact.slip_direction = slip.normalize_or_zero();
                changed = true;
            }
            true
        });
        changed
    }

    /// Puts the nodes static friction holds exactly on their anchors, and marks them in `stuck`.
    fn hold_stuck_nodes(&mut self, resting: &[RestingContact], stuck: &mut [bool]) {
        for contact in resting.iter().filter(|contact| !contact.sliding) {
            self.positions[contact.node] = contact.anchor;
            stuck[contact.node] = true;
        }
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
        scratch.find_nearby(contacts, start_positions.iter().chain(&self.positions));
        let ContactScratch { nearby, resting, touched, stuck, before_projection } = scratch;
        for flags in [&mut *touched, &mut *stuck] {
            flags.clear();
            flags.resize(self.node_count(), false);
        }
        for contact in resting.iter() {
            touched[contact.node] = true;
        }
        self.hold_stuck_nodes(resting, stuck);
        projection.use_rod_masses(self);
        let mut moved = self.push_out(nearby, touched, &projection.inverse_masses, NodePaths::Step(start_positions));
        let mut projection_iterations = 0;
        for _ in 0..CONTACT_ROUNDS {
            if !moved {
                break;
            }
            copy_into(before_projection, &self.positions);
            projection_iterations += self.project_holding_stuck_nodes(stuck, params, projection);
            moved = self.push_out(nearby, touched, &projection.inverse_masses, NodePaths::Round(before_projection));
        }
        let in_contact = touched.iter().filter(|touched| **touched).count();
        (in_contact as u32, projection_iterations)
    }

    /// The inextensibility projection with the nodes held by static friction (`stuck`) fixed. When the
    /// lengths cannot be met that way (the strand pulls harder than friction holds), they are let go
    /// and the projection runs again. Returns the projection iterations.
    fn project_holding_stuck_nodes(
        &mut self,
        stuck: &mut [bool],
        params: &StepParams,
        projection: &mut ProjectionScratch,
    ) -> u32 {
        let mut holding = false;
        for (node, _) in stuck.iter().enumerate().filter(|(_, stuck)| **stuck) {
            projection.inverse_masses[node] = 0.0;
            holding = true;
        }
        // An edge held at both ends keeps the length it has (both ends kept their places on the collider).
        for edge in 0..self.edge_count() {
            if projection.inverse_masses[edge] == 0.0 && projection.inverse_masses[edge + 1] == 0.0 {
                projection.target_lengths[edge] = self.positions[edge].distance(self.positions[edge + 1]);
            }
        }
        let mut iterations = project_edge_lengths(self, params, projection);
        if holding && length_error(self, &projection.target_lengths) > params.strain_tolerance {
            stuck.fill(false);
            projection.use_rod_masses(self);
            iterations += project_edge_lengths(self, params, projection);
        }
        iterations
    }

    /// One pass over every collider: free nodes that ended inside or whose path entered are moved to the
    /// surface, then edges dipping in are pushed out at their deepest point; what was pushed is marked in
    /// `touched`. Returns whether anything moved.
    fn push_out(
        &mut self,
        nearby: &[NearbyCollider],
        touched: &mut [bool],
        inverse_masses: &[f64],
        paths: NodePaths,
    ) -> bool {
        let mut moved = false;
        for collider in nearby {
            for node in 0..self.node_count() {
                if self.is_node_prescribed(node) {
                    continue;
                }
                let end = self.positions[node];
                let resolved = match paths {
                    // Resting nodes moved along the surface on purpose: only a new contact follows its path.
                    NodePaths::Step(starts) if !touched[node] => {
                        collider.resolve_node(collider.local_at_start(starts[node]), end, true)
                    }
                    NodePaths::Step(_) => {
                        let local = collider.local_at_end(end);
                        let inside = collider.shape.distance_bound(local) <= 0.0 && collider.shape.contains(local);
                        inside.then(|| collider.world_at_end(collider.shape.closest_surface_point(local).point))
                    }
                    NodePaths::Round(starts) => collider.resolve_node(collider.local_at_end(starts[node]), end, false),
                };
                if let Some(position) = resolved {
                    moved |= position.distance_squared(end) > MOVE_TOLERANCE * MOVE_TOLERANCE;
                    self.positions[node] = position;
                    touched[node] = true;
                }
            }
            // Edges at a prescribed node (a root inside its head) are left to their free node's test.
            for edge in 0..self.edge_count() {
                if self.is_node_prescribed(edge) || self.is_node_prescribed(edge + 1) {
                    continue;
                }
                let (start, end) = (self.positions[edge], self.positions[edge + 1]);
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
                self.positions[edge] += start_share / scale * push;
                self.positions[edge + 1] += end_share / scale * push;
                moved |= push.length_squared() > MOVE_TOLERANCE * MOVE_TOLERANCE;
                touched[edge] = true;
                touched[edge + 1] = true;
            }
        }
        moved
    }
}
