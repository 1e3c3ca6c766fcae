//! Follower hairs: dense hair at a game's budget. A few thousand *guide* strands are simulated; each
//! carries *followers*, hairs that are not simulated but placed every step from their guide's motion.
//!
//! **Scheme.** Each follower node keeps its rest offset from the guide's node of the same index, in the
//! guide's material frame there (`t, m1, m2` of the edge arriving at the node; of the root edge at the
//! root): `x_f = x_g + o_t t + o_1 m1 + o_2 m2`. Bending, turning or twisting a guide bends, turns and
//! twists its followers with it, and a follower keeps its own rest shape (its curls, its length within
//! the guide's node count) relative to its guide. This is the single-guide scheme of TressFX's follow
//! hairs, expressed in DER's material frames rather than in a frame built from the tangent alone, so
//! that twist is carried; blending two or three guides (Unity's hair, Jolt) spreads followers more
//! smoothly between guides that move apart, but averages away the twist and costs a multiple. Here the
//! followers of one guide are its clump; how far they spread is how far their roots lie from the guide's
//! (the groom spreads them evenly between guide roots).
//!
//! **Out of the head.** After placement, follower nodes inside one of their head's colliders (grown by
//! the guide's collision thickness) are moved out to its surface: radially from a sphere's or an
//! ellipsoid's centre, from a capsule's axis, up from a plane. That is not the nearest surface point of
//! an elongated ellipsoid, but it is cheap and lands outside; a bounding ball per collider skips the
//! nodes far from it.
//!
//! **Data.** A guide's followers live on the guide's entity, contiguous ([`FollowerNodes`]): one
//! allocation per guide, written by the thread that steps the guide's neighbours, and read by the
//! renderer and the gizmos (interpolated between steps like [`crate::simulation::StrandNodes`]).
//!
//! **Where they are placed** ([`FollowerPlacement`]). Without the renderer, every step on the CPU, as
//! above. With the renderer (the `render` feature's `HairRenderPlugin`), on the GPU where they are
//! drawn, by the same scheme from the guides' nodes and frames, and [`FollowerNodes`] stays unplaced
//! (its [`FollowerNodes::positions`] empty) except for the heads or guides marked
//! [`PlaceFollowersOnCpu`]: mark those whose followers the game reads.

use bevy::math::{DVec3, Vec3};
use bevy::platform::time::Instant;
use bevy::prelude::*;

use bevy::ecs::schedule::InternedScheduleLabel;

use crate::rod::{ColliderShape, MovingCollider, Rod, RodMaterial};
use crate::schedule::{HairPrepareSystems, HairStepSystems};
use crate::simulation::{
    CheckedSettings, EdgeFrame, HairSettings, HairStatistics, HairStrand, SimulatedStrand, StrandColliders,
    StrandFrames, StrandNodes, StrandOf, snap_previous,
};

/// The followers of a guide strand, as spawned: each a curve of as many nodes as the guide's
/// [`HairStrand`], in the same space (the head's local space for a strand with a head), root first. Put
/// it beside a `HairStrand`; the plugin places the followers from the guide's motion every step
/// ([`FollowerNodes`]). Changing it rebinds them.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
#[require(FollowerNodes)]
pub struct HairFollowers {
    /// Node positions of each follower at rest, m.
    pub curves: Vec<Vec<Vec3>>,
    /// How much the followers gather onto their guide towards the tip, 0 to 1: each follower node's
    /// offset from the guide is scaled by `1 − clumping · s`, with `s` from 0 at the root to 1 at the
    /// tip. 0 (the default) keeps every follower's own rest shape; 1 brings the tips onto the guide's.
    pub clumping: f32,
}

/// Where a guide's followers are, world space, single precision: written every step after the guides'
/// step when they are placed on the CPU ([`FollowerPlacement`]; otherwise the positions stay empty and
/// the rest offsets are what the GPU places them from; see the [module documentation](self)).
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct FollowerNodes {
    /// Nodes per follower (the guide's node count).
    nodes_per_follower: usize,
    /// Each follower node's rest offset from the guide's node, in the guide's material frame `(t, m1, m2)`.
    offsets: Vec<Vec3>,
    /// Follower node positions after the last step, m: follower after follower.
    pub positions: Vec<Vec3>,
    /// Follower node positions after the step before, m.
    pub previous_positions: Vec<Vec3>,
    /// The guide's material frame at each node this step (scratch, reused).
    #[reflect(ignore)]
    node_frames: Vec<Option<EdgeFrame>>,
    /// The head's colliders grown by the guide's thickness this step (scratch, reused).
    #[reflect(ignore)]
    colliders: Vec<GrownCollider>,
    /// Why the followers were rejected when last bound, if they were.
    rejection: Option<String>,
    /// Which binding the offsets come from: unique per [`FollowerNodes::bind`] in the process, 0 unbound.
    binding: u64,
}

/// The last binding made (see [`FollowerNodes::binding`]).
static LAST_BINDING: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

impl FollowerNodes {
    /// Number of followers bound (placed or not).
    pub fn count(&self) -> usize {
        self.offsets.len().checked_div(self.nodes_per_follower).unwrap_or(0)
    }

    /// Whether the last step placed the followers on the CPU ([`FollowerNodes::positions`] holds them).
    pub fn is_placed(&self) -> bool {
        self.count() > 0 && self.positions.len() == self.offsets.len()
    }

    /// Which binding of the followers the rest offsets come from: a number unique in the process to each
    /// time they are bound (0 when they are not), so that a renderer sees when to take them again.
    pub fn binding(&self) -> u64 {
        self.binding
    }

    /// Each follower node's rest offset from the guide's node of the same index, in the guide's material
    /// frame there `(t, m1, m2)`, m: follower after follower, as bound (clumping included).
    pub fn rest_offsets(&self) -> &[Vec3] {
        &self.offsets
    }

    /// Nodes of each follower.
    pub fn nodes_per_follower(&self) -> usize {
        self.nodes_per_follower
    }

    /// Why the guide's [`HairFollowers`] were rejected when last bound (logged once), if they were: none
    /// of them is placed until they are changed.
    pub fn rejection(&self) -> Option<&str> {
        self.rejection.as_deref()
    }

    /// Follower `index`'s nodes after the last step, m (none when not placed on the CPU).
    pub fn follower(&self, index: usize) -> &[Vec3] {
        let range = index * self.nodes_per_follower..(index + 1) * self.nodes_per_follower;
        self.positions.get(range).unwrap_or(&[])
    }

    /// Follower `index`'s nodes a fraction `alpha` (0 to 1) of the way from the step before to the last
    /// (none when not placed on the CPU).
    pub fn interpolated(&self, index: usize, alpha: f32) -> impl Iterator<Item = Vec3> + '_ {
        let current = self.follower(index);
        let range = index * self.nodes_per_follower..(index + 1) * self.nodes_per_follower;
        let previous = self.previous_positions.get(range).unwrap_or(current);
        previous.iter().zip(current).map(move |(a, b)| a.lerp(*b, alpha))
    }

    /// Binds `followers` to the guide `spec` at rest: each node's offset in the guide's rest material
    /// frames, gathered towards the tip by the clumping.
    fn bind(&mut self, spec: &HairStrand, followers: &HairFollowers, default: &RodMaterial) -> Result<(), String> {
        let (curves, clumping) = (&followers.curves, followers.clumping);
        if !(0.0..=1.0).contains(&clumping) {
            return Err(format!("the clumping {clumping} is not between 0 and 1"));
        }
        let nodes = spec.nodes.len();
        if let Some((index, curve)) = curves.iter().enumerate().find(|(_, curve)| curve.len() != nodes) {
            return Err(format!("follower {index} has {} nodes, its guide {nodes}", curve.len()));
        }
        if let Some(index) = curves.iter().position(|curve| !curve.iter().all(|node| node.is_finite())) {
            return Err(format!("follower {index} has a non-finite node"));
        }
        let local: Vec<DVec3> = spec.nodes.iter().map(|node| node.as_dvec3()).collect();
        let material = spec.material.unwrap_or(*default);
        let rod = Rod::new(&local, spec.material_direction.as_dvec3(), material).map_err(|error| error.to_string())?;
        self.nodes_per_follower = nodes;
        self.offsets.clear();
        for curve in curves {
            for (node, point) in curve.iter().enumerate() {
                let frame = rod.material_frame(node.saturating_sub(1));
                let gathered = 1.0 - f64::from(clumping) * node as f64 / (nodes - 1) as f64;
                let offset = gathered * (point.as_dvec3() - local[node]);
                self.offsets
                    .push(DVec3::new(offset.dot(frame.tangent), offset.dot(frame.m1), offset.dot(frame.m2)).as_vec3());
            }
        }
        self.positions.clear();
        self.previous_positions.clear();
        self.binding = LAST_BINDING.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        Ok(())
    }

    /// Places the followers on the guide's `nodes` and `frames`, out of `colliders` by `thickness` (m);
    /// `snap` makes the previous positions jump there too.
    fn place(&mut self, nodes: &StrandNodes, frames: &StrandFrames, colliders: &[MovingCollider], thickness: f32) {
        let per = self.nodes_per_follower;
        if per == 0 || nodes.positions.len() != per {
            return;
        }
        // Snap with the guide (spawned, reset or teleported: nothing to interpolate from).
        let snap = nodes.previous_positions == nodes.positions;
        std::mem::swap(&mut self.previous_positions, &mut self.positions);
        self.positions.clear();
        // The material frame of the edge arriving at each node (the root edge's at the root).
        self.node_frames.clear();
        self.node_frames.extend((0..per).map(|node| frames.material_frame(node.saturating_sub(1))));
        self.colliders.clear();
        self.colliders.extend(colliders.iter().map(|collider| GrownCollider::new(collider, thickness)));
        for follower in self.offsets.chunks_exact(per) {
            for (node, offset) in follower.iter().enumerate() {
                let base = nodes.positions[node];
                let position = match self.node_frames[node] {
                    Some(frame) => base + offset.x * frame.tangent + offset.y * frame.m1 + offset.z * frame.m2,
                    None => base,
                };
                let position = if node >= 2 { push_out(position, &self.colliders) } else { position };
                self.positions.push(position);
            }
        }
        snap_previous(&mut self.previous_positions, &self.positions, snap);
    }
}

/// A collider grown by a strand's thickness, in single precision: followers are placed, not simulated, so
/// their push-out is a cheap projection rather than the step's exact contact.
#[derive(Debug, Clone, PartialEq)]
struct GrownCollider {
    shape: ColliderShape,
    centre: Vec3,
    rotation: Quat,
    reach_squared: f32,
}

impl GrownCollider {
    fn new(collider: &MovingCollider, thickness: f32) -> Self {
        let reach = collider.shape.bounding_radius() as f32 + thickness;
        Self {
            shape: collider.shape.inflated(f64::from(thickness)),
            centre: collider.end.translation.as_vec3(),
            rotation: collider.end.rotation.as_quat(),
            reach_squared: reach * reach,
        }
    }

    /// `world` moved out to the surface if it lies inside: radially from the centre (a sphere, an
    /// ellipsoid), from the axis (a capsule), straight up (a plane), through the nearest face or from the
    /// nearest point of the box (a cuboid).
    fn push_out(&self, world: Vec3) -> Vec3 {
        let offset = world - self.centre;
        if offset.length_squared() > self.reach_squared {
            return world;
        }
        let local = self.rotation.inverse() * offset;
        let outside = match self.shape {
            ColliderShape::Sphere { radius } => {
                let radius = radius as f32;
                (local.length_squared() < radius * radius).then(|| local.normalize_or(Vec3::Y) * radius)
            }
            ColliderShape::Capsule { radius, half_length } => {
                let (radius, half_length) = (radius as f32, half_length as f32);
                let axis = Vec3::new(0.0, local.y.clamp(-half_length, half_length), 0.0);
                let away = local - axis;
                (away.length_squared() < radius * radius).then(|| axis + away.normalize_or(Vec3::X) * radius)
            }
            ColliderShape::Ellipsoid { semi_axes } => {
                let scaled = (local / semi_axes.as_vec3()).length();
                (scaled < 1.0).then(|| if scaled > 0.0 { local / scaled } else { Vec3::Y * semi_axes.y as f32 })
            }
            ColliderShape::Plane => (local.y < 0.0).then(|| Vec3::new(local.x, 0.0, local.z)),
            ColliderShape::Cuboid { .. } | ColliderShape::Mesh { .. } => {
                let local = local.as_dvec3();
                self.shape.contains(local).then(|| self.shape.closest_surface_point(local).point.as_vec3())
            }
        };
        outside.map_or(world, |local| self.centre + self.rotation * local)
    }
}

/// `position` moved out of each of `colliders` it lies in.
fn push_out(position: Vec3, colliders: &[GrownCollider]) -> Vec3 {
    colliders.iter().fold(position, |position, collider| collider.push_out(position))
}

/// What [`bind_followers`] reads and writes of a guide.
type GuideToBind = (
    Entity,
    Ref<'static, HairStrand>,
    Ref<'static, HairFollowers>,
    Ref<'static, SimulatedStrand>,
    &'static mut FollowerNodes,
);

/// Binds the followers of new or rebuilt guides (a changed [`HairStrand`] is rebuilt) and of changed
/// [`HairFollowers`], and, when the settings change, of guides whose followers are not bound. A guide that
/// follows the default material while it is invalid waits, silently: the invalid settings are reported
/// once, as invalid settings.
fn bind_followers(settings: Res<HairSettings>, mut guides: Query<GuideToBind>) {
    let default_valid = settings.default_material.validate().is_ok();
    for (entity, spec, followers, strand, mut nodes) in &mut guides {
        let unbound = nodes.offsets.is_empty() && !followers.curves.is_empty();
        let rebuilt = strand.is_added() || spec.is_changed();
        if !(followers.is_changed() || rebuilt || settings.is_changed() && unbound) {
            continue;
        }
        if spec.material.is_none() && !default_valid {
            *nodes = FollowerNodes::default();
            continue;
        }
        let rejection = nodes.rejection.take();
        if let Err(reason) = nodes.bind(&spec, &followers, &settings.default_material) {
            // Tried again when the guide or the settings change; the same reason is not news.
            if followers.is_changed() || rejection.as_ref() != Some(&reason) {
                error!("hair strand {entity}: its followers were rejected: {reason}");
            }
            *nodes = FollowerNodes { rejection: Some(reason), ..default() };
        }
    }
}

/// Where follower hairs are placed each step. Without it (headless apps), [`FollowerPlacement::Cpu`];
/// the renderer (`HairRenderPlugin`) inserts [`FollowerPlacement::Gpu`] unless the app has inserted one
/// before adding the plugins. It can be changed at any time.
#[derive(Resource, Reflect, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub enum FollowerPlacement {
    /// Every guide's followers are placed on the CPU, into [`FollowerNodes`], and drawn from there.
    #[default]
    Cpu,
    /// The renderer places and draws the followers on the GPU; on the CPU only those of the heads and
    /// guides marked [`PlaceFollowersOnCpu`] are placed (for a game that reads their [`FollowerNodes`]).
    Gpu,
}

/// Marks a [`crate::simulation::HairHead`] (all its guides) or one guide strand whose followers are placed
/// on the CPU into [`FollowerNodes`] every step even when the GPU draws them ([`FollowerPlacement::Gpu`]):
/// what a game that reads follower positions asks for.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct PlaceFollowersOnCpu;

/// What [`place_followers`] reads and writes of a guide.
type GuideToPlace = (
    &'static SimulatedStrand,
    &'static StrandNodes,
    &'static StrandFrames,
    &'static mut FollowerNodes,
    Option<&'static StrandOf>,
    Has<PlaceFollowersOnCpu>,
);

/// Places the followers of every guide that is placed on the CPU ([`FollowerPlacement`]) from its new
/// state, in parallel, kept out of its head's colliders by the collision margin of the last valid settings
/// (invalid ones hold the guides, which are drawn carried with their heads, and their followers with
/// them). The followers of the others are left unplaced.
fn place_followers(
    checked: Res<CheckedSettings>,
    placement: Option<Res<FollowerPlacement>>,
    mut statistics: ResMut<HairStatistics>,
    mut guides: Query<GuideToPlace>,
    marked_heads: Query<(), With<PlaceFollowersOnCpu>>,
    colliders: StrandColliders,
) {
    let started = Instant::now();
    let margin = checked.collision_margin;
    let all = placement.is_none_or(|placement| *placement == FollowerPlacement::Cpu);
    let asked = |marked: bool, strand_of: Option<&StrandOf>| {
        all || marked || strand_of.is_some_and(|head| marked_heads.contains(head.0))
    };
    let unplaced = |followers: &mut Mut<FollowerNodes>| {
        if !followers.positions.is_empty() {
            followers.positions.clear();
            followers.previous_positions.clear();
        }
    };
    // One pass on this thread finds whether any guide is to be placed here, counts the followers and
    // clears what the others placed before (cheaper than spreading it when the GPU places them all).
    let mut any_asked = all;
    let mut count = 0;
    if !all {
        for (.., mut followers, strand_of, marked) in &mut guides {
            count += followers.count();
            if followers.offsets.is_empty() {
                continue;
            }
            if asked(marked, strand_of) {
                any_asked = true;
                break;
            }
            unplaced(&mut followers);
        }
    }
    if any_asked {
        guides.par_iter_mut().for_each(|(strand, nodes, frames, mut followers, strand_of, marked)| {
            if followers.offsets.is_empty() {
                return;
            }
            if !asked(marked, strand_of) {
                unplaced(&mut followers);
                return;
            }
            let thickness = strand.contact_thickness(margin) as f32;
            followers.place(nodes, frames, colliders.of(strand_of), thickness);
        });
        count = guides.iter().map(|(_, _, _, followers, ..)| followers.count()).sum();
    }
    statistics.followers = count;
    statistics.follower_seconds = started.elapsed().as_secs_f64();
}

/// Follower hairs (see the [module documentation](self)): binds each guide's [`HairFollowers`] in
/// [`HairPrepareSystems::Bind`] and places them after every step in [`HairStepSystems::Follow`]. Part of
/// [`crate::HairPlugin`]; without it, [`HairFollowers`] are ignored.
#[derive(Debug, Clone)]
pub struct HairFollowersPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: InternedScheduleLabel,
}

impl Plugin for HairFollowersPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairFollowers>()
            .register_type::<FollowerNodes>()
            .register_type::<FollowerPlacement>()
            .register_type::<PlaceFollowersOnCpu>()
            .add_systems(
                self.schedule,
                (bind_followers.in_set(HairPrepareSystems::Bind), place_followers.in_set(HairStepSystems::Follow)),
            );
    }
}
