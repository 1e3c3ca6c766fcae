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
//! (the groom spreads them evenly between guide roots). Each follower's own clumping and scatter
//! ([`HairFollowers::clumping_variation`], [`HairFollowers::scatter`]) are drawn from its root when it is
//! bound and kept in its rest offsets, so the GPU's placement needs nothing more and a wisp's hairs do not
//! move as one rigid lock.
//!
//! **Out of the head.** After placement, follower nodes inside one of their head's colliders (grown by
//! the guide's collision thickness) are moved out to its surface: radially from a sphere's or an
//! ellipsoid's centre, from a capsule's axis, up from a plane. That is not the nearest surface point of
//! an elongated ellipsoid, but it is cheap and lands outside. Eight nodes are pushed out together, one
//! per SIMD lane (AVX2 or AVX chosen when the program runs), and a bounding ball per collider skips the
//! eight when all lie far from it.
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

use std::f64::consts::{PI, TAU};

use bevy::math::{DVec3, Vec3};
use bevy::platform::time::Instant;
use bevy::prelude::*;

use bevy::ecs::schedule::InternedScheduleLabel;

use crate::parallel::uneven_batches;
use crate::rod::{ColliderShape, MovingCollider, Rod, RodMaterial};
use crate::schedule::{HairPrepareSystems, HairStepSystems};
use crate::simulation::{
    CheckedSettings, HairSettings, HairStatistics, HairStrand, SimulatedStrand, StrandColliders, StrandFrames,
    StrandNodes, StrandOf, snap_previous,
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
    /// How much each follower's clumping differs from [`HairFollowers::clumping`], 0 to 1: follower `k`
    /// gathers by `clumping · (1 + clumping_variation · (2 u_k − 1))` (at most 1), with `u_k` drawn
    /// uniformly from 0 to 1 per follower, so that a wisp's hairs do not all end on one cone. 0 (the
    /// default): every follower gathers alike.
    pub clumping_variation: f32,
    /// How far a follower strays from its place around the guide towards its tip, m: each follower is
    /// moved across its guide by `a_k s² (cos φ_k(s) m1 + sin φ_k(s) m2)` in the guide's rest material
    /// frame, with `s` from 0 at the root to 1 at the tip, an amplitude `a_k` drawn uniformly from 0 to
    /// `scatter` per follower, and a direction `φ_k(s) = φ_k + ψ_k s` that turns by up to half a turn
    /// from root to tip (`φ_k` and `ψ_k ∈ [−π, π]` drawn per follower). The roots stay where they are.
    /// Production grooms call it noise: it breaks a wisp's hairs out of one rigid lock. 0 (the default):
    /// none. Finite, not negative.
    pub scatter: f32,
}

/// Per follower, what [`HairFollowers::clumping_variation`] and [`HairFollowers::scatter`] draw: four
/// numbers uniform on `[0, 1)`, seeded by its root's bits, so that a follower draws the same every time it
/// is bound, however the curves are ordered.
fn follower_draws(root: Vec3) -> [f32; 4] {
    let [x, y, z] = root.to_array().map(|coordinate| u64::from(coordinate.to_bits()));
    let mut random = fastrand::Rng::with_seed((x << 32 | y) ^ (z << 16));
    std::array::from_fn(|_| random.f32())
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
    /// The guide's nodes and the material frame `(t, m1, m2)` at each this step (scratch, reused).
    #[reflect(ignore)]
    node_frames: Vec<[Vec3; 4]>,
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
    /// frame there `(t, m1, m2)`, m: follower after follower, as bound (clumping and scatter included).
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

    /// Binds `followers` to the guide `spec` at rest, on a head of scale `head_scale`: each node's offset in
    /// the guide's rest material frames, gathered towards the tip by its clumping and moved across the
    /// guide by its scatter. The follower's root offset from the guide's is scaled with the head, as the
    /// roots are (a [`HairStrand`]'s root is head-local, its shape from the root in metres).
    fn bind(
        &mut self,
        spec: &HairStrand,
        followers: &HairFollowers,
        default: &RodMaterial,
        head_scale: DVec3,
    ) -> Result<(), String> {
        let HairFollowers { curves, clumping, clumping_variation, scatter } = followers;
        let (clumping, variation, scatter) = (f64::from(*clumping), f64::from(*clumping_variation), *scatter);
        if !(0.0..=1.0).contains(&clumping) {
            return Err(format!("the clumping {clumping} is not between 0 and 1"));
        }
        if !(0.0..=1.0).contains(&variation) {
            return Err(format!("the clumping variation {variation} is not between 0 and 1"));
        }
        if !(scatter.is_finite() && scatter >= 0.0) {
            return Err(format!("the scatter {scatter} m is not a finite length of 0 or more"));
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
            let [clump_draw, amplitude_draw, angle_draw, turn_draw] = follower_draws(curve[0]).map(f64::from);
            let clumping = (clumping * (1.0 + variation * (2.0 * clump_draw - 1.0))).min(1.0);
            let amplitude = f64::from(scatter) * amplitude_draw;
            let (angle, turn) = (TAU * angle_draw, PI * (2.0 * turn_draw - 1.0));
            // The roots' head-local offset taken to metres: `(s − 1)(f_0 − g_0)` more (exactly nothing at a
            // scale of 1).
            let roots_scaled = (curve[0].as_dvec3() - local[0]) * (head_scale - DVec3::ONE);
            for (node, point) in curve.iter().enumerate() {
                let frame = rod.material_frame(node.saturating_sub(1));
                let s = node as f64 / (nodes - 1) as f64;
                let offset = (1.0 - clumping * s) * (point.as_dvec3() - local[node] + roots_scaled);
                let (sin, cos) = (angle + turn * s).sin_cos();
                let strayed = amplitude * s * s;
                self.offsets.push(
                    DVec3::new(
                        offset.dot(frame.tangent),
                        offset.dot(frame.m1) + strayed * cos,
                        offset.dot(frame.m2) + strayed * sin,
                    )
                    .as_vec3(),
                );
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
        // Each node and the material frame of the edge arriving at it (the root edge's at the root; none
        // before the first step: the followers then sit on the guide).
        self.node_frames.clear();
        self.node_frames.extend((0..per).map(|node| {
            let frame = frames.material_frame(node.saturating_sub(1));
            let [tangent, m1, m2] = frame.map_or([Vec3::ZERO; 3], |frame| [frame.tangent, frame.m1, frame.m2]);
            [nodes.positions[node], tangent, m1, m2]
        }));
        self.colliders.clear();
        self.colliders.extend(colliders.iter().map(|collider| GrownCollider::new(collider, thickness)));
        self.positions.resize(self.offsets.len(), Vec3::ZERO);
        for (follower, offsets) in self.positions.chunks_exact_mut(per).zip(self.offsets.chunks_exact(per)) {
            for ((position, offset), &[base, tangent, m1, m2]) in
                follower.iter_mut().zip(offsets).zip(&self.node_frames)
            {
                *position = base + offset.x * tangent + offset.y * m1 + offset.z * m2;
            }
        }
        push_out(&mut self.positions, per, &self.colliders);
        snap_previous(&mut self.previous_positions, &self.positions, snap);
    }
}

/// A collider grown by a strand's thickness, in single precision: followers are placed, not simulated, so
/// their push-out is a cheap projection rather than the step's exact contact.
#[derive(Debug, Clone, PartialEq)]
struct GrownCollider {
    shape: ColliderShape,
    centre: Vec3,
    /// The collider's local axes in world space (the columns of its rotation).
    axes: [Vec3; 3],
    reach_squared: f32,
}

/// Follower nodes pushed out of the colliders together, one per SIMD lane (eight `f32`s: an AVX register).
const PUSH_LANES: usize = 8;
/// One coordinate of [`PUSH_LANES`] follower nodes.
type PushLanes = [f32; PUSH_LANES];

impl GrownCollider {
    fn new(collider: &MovingCollider, thickness: f32) -> Self {
        let reach = collider.shape.bounding_radius() as f32 + thickness;
        let rotation = collider.end.rotation.as_quat();
        Self {
            shape: collider.shape.inflated(f64::from(thickness)),
            centre: collider.end.translation.as_vec3(),
            axes: [rotation * Vec3::X, rotation * Vec3::Y, rotation * Vec3::Z],
            reach_squared: reach * reach,
        }
    }

    /// `offset` (world, from the centre) in the collider's frame.
    #[inline(always)]
    fn to_local(&self, offset: Vec3) -> Vec3 {
        Vec3::new(offset.dot(self.axes[0]), offset.dot(self.axes[1]), offset.dot(self.axes[2]))
    }

    /// The lanes of `(x, y, z)` that lie inside moved out to the surface: radially from the centre (a
    /// sphere, an ellipsoid), from the axis (a capsule), straight up (a plane), through the nearest face or
    /// from the nearest point of the box (a cuboid, a mesh: lane by lane). Each lane's arithmetic is
    /// branch-free, so the loops compile to SIMD instructions.
    #[inline(always)]
    fn push_out(&self, x: &mut PushLanes, y: &mut PushLanes, z: &mut PushLanes) {
        let c = self.centre;
        let (ox, oy, oz): (PushLanes, PushLanes, PushLanes) =
            (lanes(|k| x[k] - c.x), lanes(|k| y[k] - c.y), lanes(|k| z[k] - c.z));
        let offset = |k: usize| Vec3::new(ox[k], oy[k], oz[k]);
        let squared = lanes(|k| ox[k] * ox[k] + oy[k] * oy[k] + oz[k] * oz[k]);
        if squared.iter().fold(true, |far, &squared| far & (squared > self.reach_squared)) {
            return;
        }
        let [axis_x, axis_y, axis_z] = self.axes;
        let moved = [x, y, z];
        let offsets = [ox, oy, oz];
        match self.shape {
            // Radially: `c + o r/|o|` (a node at the very centre goes out along the collider's `y` axis).
            ColliderShape::Sphere { radius } => {
                let radius = radius as f32;
                let centred = squared.map(|squared| squared == 0.0);
                let scale = lanes(|k| if centred[k] { 0.0 } else { radius / squared[k].sqrt() });
                let shift = std::array::from_fn(|k| axis_y * if centred[k] { radius } else { 0.0 });
                move_lanes(moved, c, offsets, squared.map(|squared| squared < radius * radius), scale, shift);
            }
            // From the axis: `c + a ŷ + (o − a ŷ) r/|o − a ŷ|`, `a` the offset along the axis clamped to the
            // segment, written as `o s + a (1 − s) ŷ` (a node on the axis goes out along the `x` axis).
            ColliderShape::Capsule { radius, half_length } => {
                let (radius, half_length) = (radius as f32, half_length as f32);
                let along = lanes(|k| offset(k).dot(axis_y).clamp(-half_length, half_length));
                let away = lanes(|k| (offset(k) - along[k] * axis_y).length_squared());
                let on_axis = away.map(|away| away == 0.0);
                let scale = lanes(|k| if on_axis[k] { 0.0 } else { radius / away[k].sqrt() });
                let shift = std::array::from_fn(|k| {
                    axis_y * (along[k] * (1.0 - scale[k])) + if on_axis[k] { axis_x * radius } else { Vec3::ZERO }
                });
                move_lanes(moved, c, offsets, away.map(|away| away < radius * radius), scale, shift);
            }
            // Radially, to where the ray from the centre leaves the ellipsoid: `c + o/|R⁻¹o ⊘ a|`.
            ColliderShape::Ellipsoid { semi_axes } => {
                let semi_axes = semi_axes.as_vec3();
                let scaled = lanes(|k| (self.to_local(offset(k)) / semi_axes).length());
                let centred = scaled.map(|scaled| scaled == 0.0);
                let scale = lanes(|k| if centred[k] { 0.0 } else { 1.0 / scaled[k] });
                let shift = std::array::from_fn(|k| axis_y * if centred[k] { semi_axes.y } else { 0.0 });
                move_lanes(moved, c, offsets, scaled.map(|scaled| scaled < 1.0), scale, shift);
            }
            // Straight up its normal: `x − (o·n) n` where `o·n < 0`.
            ColliderShape::Plane => {
                let height = lanes(|k| offset(k).dot(axis_y));
                let (inside, shift) = (height.map(|height| height < 0.0), height.map(|height| axis_y * -height));
                move_lanes(moved, c, offsets, inside, [1.0; PUSH_LANES], shift);
            }
            ColliderShape::Cuboid { .. } | ColliderShape::Mesh { .. } => {
                let [x, y, z] = moved;
                for k in 0..PUSH_LANES {
                    let local = self.to_local(offset(k)).as_dvec3();
                    if self.shape.contains(local) {
                        let surface = self.shape.closest_surface_point(local).point.as_vec3();
                        let world = c + axis_x * surface.x + axis_y * surface.y + axis_z * surface.z;
                        (x[k], y[k], z[k]) = (world.x, world.y, world.z);
                    }
                }
            }
        }
    }
}

/// Moves lane `k` of `(x, y, z)` to `centre + offset · scale[k] + shift[k]` where `inside[k]`. Kept out of
/// line: measured, the loop over the nodes is faster with the move as a call than inlined into it
/// (`docs/performance.md`).
#[inline(never)]
fn move_lanes(
    [x, y, z]: [&mut PushLanes; 3],
    centre: Vec3,
    [ox, oy, oz]: [PushLanes; 3],
    inside: [bool; PUSH_LANES],
    scale: PushLanes,
    shift: [Vec3; PUSH_LANES],
) {
    if !inside.iter().fold(false, |any, &inside| any | inside) {
        return;
    }
    for k in 0..PUSH_LANES {
        let world = centre + Vec3::new(ox[k], oy[k], oz[k]) * scale[k] + shift[k];
        x[k] = if inside[k] { world.x } else { x[k] };
        y[k] = if inside[k] { world.y } else { y[k] };
        z[k] = if inside[k] { world.z } else { z[k] };
    }
}

/// One value per lane, from `value(lane)`.
#[inline(always)]
fn lanes(value: impl FnMut(usize) -> f32) -> PushLanes {
    std::array::from_fn(value)
}

/// Every node of `positions` (followers of `per` nodes each, one after another) from the third of its
/// follower on moved out of each of `colliders` it lies in, [`PUSH_LANES`] nodes at a time. Compiled for
/// AVX2 with FMA and for AVX besides the baseline, chosen when the program runs.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn push_out(positions: &mut [Vec3], per: usize, colliders: &[GrownCollider]) {
    if colliders.is_empty() {
        return;
    }
    for (chunk, nodes) in positions.chunks_mut(PUSH_LANES).enumerate() {
        // The last chunk's missing lanes repeat its first node and are not written back.
        let lane = |k: usize| nodes[if k < nodes.len() { k } else { 0 }];
        let (mut x, mut y, mut z) = (lanes(|k| lane(k).x), lanes(|k| lane(k).y), lanes(|k| lane(k).z));
        for collider in colliders {
            collider.push_out(&mut x, &mut y, &mut z);
        }
        for (k, node) in nodes.iter_mut().enumerate() {
            // The root and the node after it stay on the guide's.
            if (chunk * PUSH_LANES + k) % per >= 2 {
                *node = Vec3::new(x[k], y[k], z[k]);
            }
        }
    }
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
        if let Err(reason) = nodes.bind(&spec, &followers, &settings.default_material, strand.spawn_scale()) {
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
        guides.par_iter_mut().batching_strategy(uneven_batches(PLACE_BATCHES_PER_THREAD)).for_each(
            |(strand, nodes, frames, mut followers, strand_of, marked)| {
                if followers.offsets.is_empty() {
                    return;
                }
                if !asked(marked, strand_of) {
                    unplaced(&mut followers);
                    return;
                }
                let thickness = strand.contact_thickness(margin) as f32;
                followers.place(nodes, frames, colliders.of(strand_of), thickness);
            },
        );
        count = guides.iter().map(|(_, _, _, followers, ..)| followers.count()).sum();
    }
    statistics.followers = count;
    statistics.follower_seconds = started.elapsed().as_secs_f64();
}

/// Batches of guides per compute thread in [`place_followers`].
const PLACE_BATCHES_PER_THREAD: usize = 16;

/// Follower hairs (see the [module documentation](self)): binds each guide's [`HairFollowers`] in
/// [`HairPrepareSystems::Bind`] and places them after every step in [`HairStepSystems::Follow`]. Part of
/// [`crate::HairPlugins`]; without it, [`HairFollowers`] are ignored.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rod::RigidPose;
    use bevy::math::DQuat;

    /// The push-out of one node as the GPU's shader writes it (`push_out` in `render/followers.wgsl`): into
    /// the collider's frame, out to the surface there, and back.
    fn pushed_one_at_a_time(world: Vec3, collider: &GrownCollider, rotation: Quat) -> Vec3 {
        let offset = world - collider.centre;
        if offset.length_squared() > collider.reach_squared {
            return world;
        }
        let local = rotation.inverse() * offset;
        let outside = match collider.shape {
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
                (scaled < 1.0).then(|| local / scaled)
            }
            ColliderShape::Plane => (local.y < 0.0).then(|| Vec3::new(local.x, 0.0, local.z)),
            _ => {
                let local = local.as_dvec3();
                collider.shape.contains(local).then(|| collider.shape.closest_surface_point(local).point.as_vec3())
            }
        };
        outside.map_or(world, |local| collider.centre + rotation * local)
    }

    #[test]
    fn nodes_in_lanes_are_pushed_out_as_one_at_a_time_and_the_first_two_of_each_follower_stay() {
        let pose = RigidPose {
            rotation: DQuat::from_euler(EulerRot::XYZ, 0.4, -0.7, 1.1),
            translation: DVec3::new(0.02, 1.6, -0.03),
        };
        let shapes = [
            ColliderShape::sphere(0.09),
            ColliderShape::capsule(0.05, 0.06),
            ColliderShape::ellipsoid(DVec3::new(0.08, 0.1, 0.12)),
            ColliderShape::Plane,
            ColliderShape::cuboid(DVec3::new(0.06, 0.1, 0.04)),
        ];
        // 13 followers of 7 nodes (91 nodes: eleven full chunks of lanes and one of three), on a grid
        // through the colliders.
        let per = 7;
        let nodes: Vec<Vec3> = (0..13 * per)
            .map(|index| {
                let [i, j, k] = [index % 5, index / 5 % 5, index / 25];
                pose.translation.as_vec3() + 0.035 * Vec3::new(i as f32 - 2.0, j as f32 - 2.0, k as f32 - 1.5)
            })
            .collect();
        let rotation = pose.rotation.as_quat();
        for shape in shapes {
            let collider = GrownCollider::new(&MovingCollider::fixed(shape.clone(), 0.3, pose), 0.002);
            let mut lanes = nodes.clone();
            push_out(&mut lanes, per, std::slice::from_ref(&collider));
            let mut moved = 0;
            for (index, (&before, &after)) in nodes.iter().zip(&lanes).enumerate() {
                let expected =
                    if index % per >= 2 { pushed_one_at_a_time(before, &collider, rotation) } else { before };
                moved += usize::from(expected != before);
                assert!(
                    after.distance(expected) < 1e-6,
                    "{shape:?}: node {index} at {before} pushed to {after}, one at a time to {expected}"
                );
                if expected == before {
                    assert_eq!(after, before, "{shape:?}: node {index} outside moved");
                }
            }
            assert!(moved >= 3, "{shape:?}: only {moved} nodes inside: the test does not reach it");
        }
    }
}
