//! What the GPU is sent to place a head's followers and draw its hair itself (`followers.wgsl`): once per
//! layout, each drawn node's rest offset from its guide; once per step, the guides' nodes, their material
//! frames packed to 24 bits a node, a word or two per guide and the head's colliders. Everything else
//! (every follower node, the interpolation between steps) is made on the GPU.
//!
//! **A frame in 24 bits.** A follower node is `x_g + o_t t + o_1 m1 + o_2 m2` in the material frame of the
//! guide's edge arriving at the node ([`crate::followers`]). The GPU takes `t` from the guide's drawn
//! nodes (the edge's direction, which is the frame's tangent), so only `m1`'s angle about `t` is sent: in
//! the basis `b1 = (t × r)/|t × r|`, `b2 = t × b1` with `r` the X or the Y axis, whichever is farther from
//! `t` (one bit), as a "diamond angle" (`s / (|c| + |s|)` by quadrant, no trigonometry) in 23 bits:
//! within 4.8e-7 rad, under 0.1 µm at 10 cm from the guide. (In 16 bits it would be 1.2e-4 rad: 12 µm
//! at 10 cm, more than f32 rounding.)
//!
//! Bytes per step: 15 per guide node and 8 per guide, against 12 per drawn node when the CPU writes every
//! node (a guide with ten followers: 11 × 12 = 132 bytes per node before, 15 after).

use bevy::math::Vec3;
use bevy::prelude::Entity;

use super::{bounds_of, take_front};
use crate::followers::FollowerNodes;
use crate::parallel::prefetch;
use crate::rod::{ColliderShape, MovingCollider};
use crate::simulation::{StrandFrames, StrandNodes};

/// A drawn node that is its guide's own node (drawn where the guide is), in [`GuideUpload::drawn_nodes`].
pub const DRAWN_GUIDE: u32 = 1 << 31;
/// A drawn follower node that is pushed out of the colliders (the third node on).
pub const DRAWN_PUSHED: u32 = 1 << 30;
/// A drawn node at a root: its frame is the root edge's, whose tangent runs to the next node.
pub const DRAWN_ROOT: u32 = 1 << 29;
/// The bits of a drawn node's word that hold its guide node.
pub const DRAWN_GUIDE_NODE: u32 = DRAWN_ROOT - 1;
/// A guide whose previous positions are its current ones (spawned, reset, teleported): nothing to
/// interpolate from, in [`GuideUpload::guides`].
pub const GUIDE_SNAP: u32 = 1;
/// A guide without usable frames this step: its followers are drawn on its nodes.
pub const GUIDE_NO_FRAMES: u32 = 2;
/// The diamond angle's steps per quadrant.
const ANGLE_STEPS: f32 = (1 << 21) as f32;
/// The bit of a frame code that says the basis was built from the Y axis.
const FROM_Y: u32 = 1 << 23;
/// Bytes of a frame code.
pub const FRAME_CODE_BYTES: usize = 3;

/// A collider as `followers.wgsl` reads it: three `vec4<f32>`.
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct GpuCollider {
    /// Centre (m) and the shape's bounding radius (m, infinite for a plane).
    pub centre: [f32; 4],
    /// Orientation, a unit quaternion `x y z w`.
    pub rotation: [f32; 4],
    /// Sphere `(radius, 0, 0, 0)`, capsule `(radius, half length, 0, 1)`, ellipsoid `(semi-axes, 2)`,
    /// plane `(0, 0, 0, 3)`, m.
    pub shape: [f32; 4],
}

impl GpuCollider {
    /// The collider at the end of its step's motion, as the CPU placement takes it.
    pub fn new(collider: &MovingCollider) -> Self {
        let centre = collider.end.translation.as_vec3();
        let rotation = collider.end.rotation.as_quat();
        let shape = match collider.shape {
            ColliderShape::Sphere { radius } => [radius as f32, 0.0, 0.0, 0.0],
            ColliderShape::Capsule { radius, half_length } => [radius as f32, half_length as f32, 0.0, 1.0],
            ColliderShape::Ellipsoid { semi_axes } => {
                let axes = semi_axes.as_vec3();
                [axes.x, axes.y, axes.z, 2.0]
            }
            ColliderShape::Plane => [0.0, 0.0, 0.0, 3.0],
        };
        Self {
            centre: [centre.x, centre.y, centre.z, collider.shape.bounding_radius() as f32],
            rotation: rotation.to_array(),
            shape,
        }
    }
}

/// One head's data for the GPU's follower placement (see the [module documentation](self)). The layout
/// part follows [`super::HairStrips`]' layout: the guides in order, each followed by its followers.
#[derive(Debug, Clone, Default)]
pub struct GuideUpload {
    /// Per drawn node: the rest offset in the guide's frame (three `f32` as bits, zero for a guide's own
    /// node) and a word: its guide node | [`DRAWN_GUIDE`] | [`DRAWN_PUSHED`] | [`DRAWN_ROOT`].
    pub drawn_nodes: Vec<[u32; 4]>,
    /// Per guide node: its guide's index.
    pub guide_of_node: Vec<u32>,
    /// The guides, in layout order.
    entities: Vec<Entity>,
    /// First guide node of each guide, and one past the last.
    guide_first: Vec<usize>,
    /// Each guide's follower binding when laid out, to see a rebinding.
    bindings: Vec<u64>,
    /// The longest rest offset, m.
    max_offset: f32,
    /// This step's guide node positions, `x y z` per node, world space, m.
    pub positions: Vec<f32>,
    /// This step's frame code per guide node (see the [module documentation](self)), three bytes each
    /// (little-endian), padded to whole words.
    pub frames: Vec<u8>,
    /// Per guide: its contact thickness (m, `f32` bits) and flags ([`GUIDE_SNAP`], [`GUIDE_NO_FRAMES`]).
    pub guides: Vec<[u32; 2]>,
    /// The head's colliders this step.
    pub colliders: Vec<GpuCollider>,
    /// Bounds of each piece's guide nodes (reused).
    piece_bounds: Vec<(Vec3, Vec3)>,
}

/// What [`GuideUpload::pack`] reads of one guide: its nodes, frames and contact thickness (m).
pub type PackedGuide<'a> = (&'a StrandNodes, &'a StrandFrames, f32);

impl GuideUpload {
    /// Lays out the drawn nodes of `guides` (entity, node count, followers as bound; in drawing order), as
    /// [`super::HairStrips::set_layout`] lays them out.
    pub fn set_layout<'a>(&mut self, guides: impl IntoIterator<Item = (Entity, u32, Option<&'a FollowerNodes>)>) {
        self.entities.clear();
        self.drawn_nodes.clear();
        self.guide_of_node.clear();
        self.guide_first.clear();
        self.bindings.clear();
        self.max_offset = 0.0;
        let mut guide_node = 0_usize;
        for (index, (entity, nodes, followers)) in guides.into_iter().enumerate() {
            let nodes = nodes as usize;
            self.entities.push(entity);
            self.guide_first.push(guide_node);
            self.bindings.push(followers.map_or(0, FollowerNodes::binding));
            for node in 0..nodes {
                self.drawn_nodes.push([0, 0, 0, DRAWN_GUIDE | node_word(guide_node + node, node)]);
                self.guide_of_node.push(index as u32);
            }
            let offsets = followers.filter(|f| f.nodes_per_follower() == nodes).map_or(&[][..], |f| f.rest_offsets());
            for follower in offsets.chunks_exact(nodes.max(1)) {
                for (node, offset) in follower.iter().enumerate() {
                    self.max_offset = self.max_offset.max(offset.length());
                    let word = node_word(guide_node + node, node) | if node >= 2 { DRAWN_PUSHED } else { 0 };
                    self.drawn_nodes.push([offset.x.to_bits(), offset.y.to_bits(), offset.z.to_bits(), word]);
                }
            }
            guide_node += nodes;
        }
        self.guide_first.push(guide_node);
        self.positions.clear();
        self.positions.resize(3 * guide_node, 0.0);
        self.frames.clear();
        self.frames.resize((FRAME_CODE_BYTES * guide_node).next_multiple_of(4), 0);
        self.guides.clear();
        self.guides.resize(self.guide_first.len() - 1, [0, GUIDE_SNAP]);
    }

    /// Whether any guide's followers were bound again since the layout (their offsets changed).
    pub fn rebound<'a>(&self, followers: impl IntoIterator<Item = Option<&'a FollowerNodes>>) -> bool {
        let mut count = 0;
        for (index, followers) in followers.into_iter().enumerate() {
            if self.bindings.get(index) != Some(&followers.map_or(0, FollowerNodes::binding)) {
                return true;
            }
            count += 1;
        }
        count != self.bindings.len()
    }

    /// Number of drawn nodes.
    pub fn drawn_node_count(&self) -> usize {
        self.drawn_nodes.len()
    }

    /// Number of guide nodes.
    pub fn guide_node_count(&self) -> usize {
        self.guide_of_node.len()
    }

    /// Bytes sent per step: positions, frames, guides and colliders.
    pub fn step_bytes(&self) -> usize {
        4 * self.positions.len()
            + self.frames.len()
            + 8 * self.guides.len()
            + std::mem::size_of::<GpuCollider>() * self.colliders.len()
    }

    /// Writes this step's guide data (`lookup` gives each guide's nodes, frames and contact thickness) in
    /// parallel on up to `threads` threads, with `colliders`;
    /// `snap_all` draws every guide where it is now (when more than one step passed since the last upload,
    /// the GPU has no previous step to interpolate from). Returns the bounds of what will be drawn (the
    /// guides' nodes widened by twice the longest offset: a follower node pushed out of a collider stays
    /// that close), `None` when nothing is there. A guide `lookup` does not find, or whose node count no
    /// longer matches, keeps its last data and is drawn still.
    pub fn pack<'a>(
        &mut self,
        threads: usize,
        colliders: &[MovingCollider],
        snap_all: bool,
        lookup: impl Fn(Entity) -> Option<PackedGuide<'a>> + Sync,
    ) -> Option<(Vec3, Vec3)> {
        self.colliders.clear();
        self.colliders.extend(colliders.iter().map(GpuCollider::new));
        let empty = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (entities, first_nodes) = (&self.entities, &self.guide_first);
        let ranges = super::piece_ranges(entities.len(), threads);
        self.piece_bounds.clear();
        self.piece_bounds.resize(ranges.len(), empty);
        let (mut positions, mut frames): (&mut [f32], &mut [u8]) = (&mut self.positions, &mut self.frames);
        let (mut guides, mut bounds) = (&mut self.guides[..], &mut self.piece_bounds[..]);
        let work = ranges.map(|range| {
            let nodes = first_nodes[range.end] - first_nodes[range.start];
            let guide_count = range.len();
            let piece_positions = take_front(&mut positions, 3 * nodes);
            let piece_frames = take_front(&mut frames, FRAME_CODE_BYTES * nodes);
            (
                range,
                piece_positions,
                piece_frames,
                take_front(&mut guides, guide_count),
                &mut take_front(&mut bounds, 1)[0],
            )
        });
        let lookup = &lookup;
        crate::parallel::run_in_parallel(threads, work, |(range, positions, frames, guides, bounds)| {
            let base = first_nodes[range.start];
            // Each guide is looked up `AHEAD` guides early and its arrays asked for then.
            let end_of_piece = range.end;
            let look = |index: usize| {
                let found = if index < end_of_piece { lookup(entities[index]) } else { None };
                found.inspect(|&guide| prefetch_guide(guide))
            };
            let mut found: [Option<PackedGuide<'a>>; AHEAD] = [None; AHEAD];
            for index in range.start..range.start + AHEAD {
                found[index % AHEAD] = look(index);
            }
            for (guide, index) in guides.iter_mut().zip(range) {
                let this = std::mem::replace(&mut found[index % AHEAD], look(index + AHEAD));
                let (start, end) = (first_nodes[index] - base, first_nodes[index + 1] - base);
                let Some((nodes, strand_frames, thickness)) = this else {
                    guide[1] |= GUIDE_SNAP;
                    continue;
                };
                if nodes.positions.len() != end - start {
                    guide[1] |= GUIDE_SNAP;
                    continue;
                }
                // As the CPU placement and drawing see it: nothing to interpolate from.
                let snap = snap_all
                    || nodes.previous_positions == nodes.positions
                    || nodes.previous_positions.len() != nodes.positions.len();
                let codes = &mut frames[FRAME_CODE_BYTES * start..FRAME_CODE_BYTES * end];
                let usable = pack_guide(&nodes.positions, strand_frames, &mut positions[3 * start..3 * end], codes);
                let flags = if snap { GUIDE_SNAP } else { 0 } | if usable { 0 } else { GUIDE_NO_FRAMES };
                *guide = [thickness.to_bits(), flags];
            }
            // What is drawn: a guide not found this step is drawn where it was.
            *bounds = bounds_of(positions);
        });
        let (low, high) = self.piece_bounds.iter().fold(empty, |(low, high), (a, b)| (low.min(*a), high.max(*b)));
        let reach = Vec3::splat(2.0 * self.max_offset);
        (low.cmple(high).all()).then_some((low - reach, high + reach))
    }
}

/// A drawn node's word without flags but the root's: its guide node, and [`DRAWN_ROOT`] at a root.
fn node_word(guide_node: usize, node: usize) -> u32 {
    (guide_node as u32 & DRAWN_GUIDE_NODE) | if node == 0 { DRAWN_ROOT } else { 0 }
}

/// Edges coded side by side by [`frame_codes`]: its loops run over them without a branch, so that the
/// compiler vectorises them (four lanes at a time with the baseline SSE2).
const LANES: usize = 8;

/// The largest twist (rad) that [`frame_codes`] reduces in single precision: a batch with a larger one
/// (or one that is not finite) takes [`sin_cos`]'s double-precision reduction instead.
const SINGLE_PRECISION_TWIST: f32 = 8192.0;

/// How many guides ahead [`GuideUpload::pack`] looks guides up and asks for their arrays.
const AHEAD: usize = 4;

/// Asks for what [`pack_guide`] and the snapping check read of `guide` (see [`prefetch`]).
fn prefetch_guide((nodes, frames, _): PackedGuide) {
    prefetch(&nodes.positions);
    prefetch(&nodes.previous_positions[..nodes.previous_positions.len().min(1)]);
    prefetch(&frames.tangents);
    prefetch(&frames.reference_directors);
    prefetch(&frames.twist);
}

/// Writes one guide's node positions (`x y z` per node, for the GPU) and the frame code of each node (the
/// frame of the edge arriving at the node; the root edge's at the root); says whether the frames were
/// usable (one per edge, no edge of zero length). Compiled for AVX2 and FMA too, used where the CPU has them
/// (the eight lanes of [`frame_codes`] fill one register then).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn pack_guide(nodes: &[Vec3], frames: &StrandFrames, positions: &mut [f32], codes: &mut [u8]) -> bool {
    positions.copy_from_slice(bytemuck::cast_slice(nodes));
    let edges = nodes.len().saturating_sub(1);
    let (tangents, directors, twists) = (&frames.tangents, &frames.reference_directors, &frames.twist);
    if edges == 0 || tangents.len() != edges || directors.len() != edges || twists.len() != edges {
        return false;
    }
    // The GPU divides by each edge's length: one of zero length makes the frames unusable.
    if nodes.windows(2).any(|ends| (ends[1] - ends[0]).length_squared() < f32::MIN_POSITIVE) {
        return false;
    }
    let (whole_tangents, last_tangents) = tangents.as_chunks::<LANES>();
    let (whole_directors, last_directors) = directors.as_chunks::<LANES>();
    let (whole_twists, last_twists) = twists.as_chunks::<LANES>();
    let mut edge_codes = codes[FRAME_CODE_BYTES..].chunks_exact_mut(FRAME_CODE_BYTES * LANES);
    let whole = whole_tangents.iter().zip(whole_directors).zip(whole_twists);
    for (((t, u), twist), out) in whole.zip(&mut edge_codes) {
        write_codes(out, frame_codes(t, u, twist));
    }
    if !last_twists.is_empty() {
        // The last, short batch: its lanes padded with a frame that codes without trouble (and not written).
        let (mut t, mut u, mut twist) = ([Vec3::Z; LANES], [Vec3::X; LANES], [0.0; LANES]);
        t[..last_tangents.len()].copy_from_slice(last_tangents);
        u[..last_directors.len()].copy_from_slice(last_directors);
        twist[..last_twists.len()].copy_from_slice(last_twists);
        write_codes(edge_codes.into_remainder(), frame_codes(&t, &u, &twist));
    }
    // The root is drawn in the root edge's frame.
    codes.copy_within(FRAME_CODE_BYTES..2 * FRAME_CODE_BYTES, 0);
    true
}

/// Writes the first `out.len() / 3` of `codes`, three bytes each (little-endian).
#[inline(always)]
fn write_codes(out: &mut [u8], codes: [u32; LANES]) {
    for (out, code) in out.chunks_exact_mut(FRAME_CODE_BYTES).zip(codes) {
        out.copy_from_slice(&code.to_le_bytes()[..FRAME_CODE_BYTES]);
    }
}

/// The frame codes (see the [module documentation](self)) of [`LANES`] edges, each the material
/// director `m1 = cos θ u + sin θ v`, `v = t × u`, of the edge with unit tangent `t`, reference director
/// `u` and twist `θ`.
///
/// Made without making `m1` or the basis: with `r` the axis the basis is built from, `b1 = t × r` and
/// `b2 = t × b1`, the director's coordinates are `m1 · b1 = −m2 · r` and `m1 · b2 = −m1 · r` (`m1 ⟂ t`),
/// with `m1 · r = cos θ u_r + sin θ v_r` and `m2 · r = cos θ v_r − sin θ u_r`: one component of `u` and
/// of `v`. The basis is left unnormalised (the diamond angle is a ratio); `t` is the frame's (the GPU takes
/// the edge's, the same to f32 rounding). The twist is reduced to `θ = q π/2 + ρ`, `|ρ| ≤ π/4`: the
/// director is coded at `ρ` and turned by `q` quarter turns after, which adds `q` to its diamond angle.
/// The lanes are whole arrays, so that the compiler keeps them in SIMD registers (a slice of variable
/// length made it go through the stack, a store and a reload per lane).
#[inline(always)]
fn frame_codes(tangents: &[Vec3; LANES], directors: &[Vec3; LANES], twist: &[f32; LANES]) -> [u32; LANES] {
    let t = [tangents.map(|t| t.x), tangents.map(|t| t.y), tangents.map(|t| t.z)];
    let u = [directors.map(|u| u.x), directors.map(|u| u.y), directors.map(|u| u.z)];
    let (mut sin, mut cos, mut turns) = ([0.0_f32; LANES], [0.0_f32; LANES], [0_u32; LANES]);
    if twist.iter().all(|angle| angle.abs() <= SINGLE_PRECISION_TWIST) {
        for lane in 0..LANES {
            (sin[lane], cos[lane], turns[lane]) = reduced_sin_cos(twist[lane]);
        }
    } else {
        for lane in 0..LANES {
            (sin[lane], cos[lane]) = sin_cos(twist[lane]);
        }
    }
    let mut codes = [0_u32; LANES];
    for lane in 0..LANES {
        let (tx, ty, tz) = (t[0][lane], t[1][lane], t[2][lane]);
        let (ux, uy, uz) = (u[0][lane], u[1][lane], u[2][lane]);
        let from_y = tx.abs() > ty.abs();
        let u_r = if from_y { uy } else { ux };
        let v_r = if from_y { tz * ux - tx * uz } else { ty * uz - tz * uy };
        let (m1_r, m2_r) = (cos[lane] * u_r + sin[lane] * v_r, cos[lane] * v_r - sin[lane] * u_r);
        let steps = diamond_steps(-m2_r, -m1_r).wrapping_add(turns[lane] << 21) & (FROM_Y - 1);
        codes[lane] = steps | if from_y { FROM_Y } else { 0 };
    }
    codes
}

/// `(sin ρ, cos ρ, q mod 4)` with `x = q π/2 + ρ`, `|ρ| ≤ π/4`, for `|x| ≤` [`SINGLE_PRECISION_TWIST`], to
/// about 1e-7, in single precision and without a branch: Cody–Waite reduction by `π/2` split in two (the
/// first with 11 bits, so that its product with `q` is exact), and minimax polynomials of the 7th and 8th
/// degrees on `|ρ| ≤ π/4` (Cephes' `sinf` and `cosf`, relative error under 1e-7).
#[inline(always)]
fn reduced_sin_cos(x: f32) -> (f32, f32, u32) {
    // Adding 1.5 · 2²³ rounds to the nearest integer, which then sits in the low bits of the sum.
    const ROUNDING: f32 = 12_582_912.0;
    const HALF_PI: [f32; 2] = [1.570_312_5, 4.838_268e-4];
    let shifted = x * std::f32::consts::FRAC_2_PI + ROUNDING;
    let quadrant = shifted - ROUNDING;
    let r = (x - quadrant * HALF_PI[0]) - quadrant * HALF_PI[1];
    // Below 1e-8 the terms past `r` and `1` vanish in f32; dropping them keeps their products out of the
    // subnormal range, where each operation costs a hundred cycles (a twist within 1e-13 of a multiple of
    // π/2 would otherwise make them subnormal).
    let r_odd = if r.abs() < 1e-8 { 0.0 } else { r };
    let r2 = r_odd * r_odd;
    let sin = r + r_odd * r2 * (-1.666_665_5e-1 + r2 * (8.332_161e-3 + r2 * -1.951_529_6e-4));
    let cos = 1.0 - 0.5 * r2 + r2 * r2 * (4.166_664_6e-2 + r2 * (-1.388_731_6e-3 + r2 * 2.443_315_7e-5));
    (sin, cos, shifted.to_bits() & 3)
}

/// `(sin x, cos x)` to about 1e-9 for `|x|` up to 1e6 rad, without a call into libm: Cody–Waite reduction
/// to `|r| ≤ π/4` in f64 and Taylor series to the 10th order there.
fn sin_cos(angle: f32) -> (f32, f32) {
    // Adding and taking away 1.5 · 2⁵² rounds to the nearest integer in f64 arithmetic.
    const ROUNDING: f64 = 6_755_399_441_055_744.0;
    let x = f64::from(angle);
    let quadrant = (x * std::f64::consts::FRAC_2_PI + ROUNDING) - ROUNDING;
    let r = x - quadrant * std::f64::consts::FRAC_PI_2;
    let r2 = r * r;
    // Horner's scheme on the Taylor coefficients `(−1)^k / (2k + 1)!` and `(−1)^k / (2k)!`.
    let sin = r * (1.0 + r2 * (-1.0 / 6.0 + r2 * (1.0 / 120.0 + r2 * (-1.0 / 5_040.0 + r2 * (1.0 / 362_880.0)))));
    let cos =
        1.0 + r2 * (-0.5 + r2 * (1.0 / 24.0 + r2 * (-1.0 / 720.0 + r2 * (1.0 / 40_320.0 + r2 * (-1.0 / 3_628_800.0)))));
    let (sin, cos) = (sin as f32, cos as f32);
    // Quadrant q turns by q · π/2: an odd one swaps the two (cos → sin, −sin → cos), q = 2, 3 negate both.
    match (quadrant as i64).rem_euclid(4) {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// The diamond angle of `(c, s)` (0 to 4 round the circle: `1 − c / (|c| + |s|)` for `s ≥ 0`,
/// `3 + c / (|c| + |s|)` below) in steps of 1/[`ANGLE_STEPS`], rounded, 4 wrapping to 0; a zero vector has
/// angle 1. Without a branch: the side of `s` is a factor, and adding 2²³ rounds the steps (under 2²³)
/// into the low bits of the sum.
#[inline(always)]
fn diamond_steps(c: f32, s: f32) -> u32 {
    const INTEGER: f32 = 8_388_608.0;
    let ratio = c / (c.abs() + s.abs()).max(f32::MIN_POSITIVE);
    let below = if s < 0.0 { 1.0 } else { 0.0 };
    let diamond = 1.0 + 2.0 * below + ratio * (2.0 * below - 1.0);
    (diamond * ANGLE_STEPS + INTEGER).to_bits() & (FROM_Y - 1)
}

/// The basis `(b1, b2)` across `tangent` built from the X axis, or from the Y axis when `from_y`.
pub fn frame_basis(tangent: Vec3, from_y: bool) -> (Vec3, Vec3) {
    let axis = if from_y { Vec3::Y } else { Vec3::X };
    let b1 = tangent.cross(axis).normalize();
    (b1, tangent.cross(b1))
}

/// The 24-bit code of the director `m1` about the unit `tangent` (see the [module documentation](self)).
pub fn encode_frame(tangent: Vec3, m1: Vec3) -> u32 {
    let from_y = tangent.x.abs() > tangent.y.abs();
    let (b1, b2) = frame_basis(tangent, from_y);
    diamond_steps(m1.dot(b1), m1.dot(b2)) | if from_y { FROM_Y } else { 0 }
}

/// The director `m1` a code stands for about the unit `tangent`, as `followers.wgsl` decodes it.
pub fn decode_frame(tangent: Vec3, code: u32) -> Vec3 {
    let (b1, b2) = frame_basis(tangent, code & FROM_Y != 0);
    let d = (code & (FROM_Y - 1)) as f32 / ANGLE_STEPS;
    let (c, s) = if d < 1.0 {
        (1.0 - d, d)
    } else if d < 2.0 {
        (1.0 - d, 2.0 - d)
    } else if d < 3.0 {
        (d - 3.0, 2.0 - d)
    } else {
        (d - 3.0, d - 4.0)
    };
    (c * b1 + s * b2).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_matches_the_standard_library() {
        let mut worst = 0.0_f64;
        for index in -200_000..=200_000 {
            let angle = index as f32 * 1.7e-3 + (index % 7) as f32 * 1e3;
            let (sin, cos) = sin_cos(angle);
            let (expected_sin, expected_cos) = f64::from(angle).sin_cos();
            worst = worst.max((f64::from(sin) - expected_sin).abs()).max((f64::from(cos) - expected_cos).abs());
        }
        // f32 rounding of the result (6e-8) and the series' 2e-9.
        assert!(worst < 1e-7, "{worst}");
    }

    #[test]
    fn the_single_precision_reduction_matches_the_standard_library() {
        let mut worst = 0.0_f64;
        for index in -400_000..=400_000 {
            // Steps that are not a fraction of π/2, up to the bound of the single-precision path.
            let angle = index as f32 * 0.020_479_3;
            assert!(angle.abs() <= SINGLE_PRECISION_TWIST);
            let (sin, cos, quadrant) = reduced_sin_cos(angle);
            let (sin, cos) = match quadrant {
                0 => (sin, cos),
                1 => (cos, -sin),
                2 => (-sin, -cos),
                _ => (-cos, sin),
            };
            let (expected_sin, expected_cos) = f64::from(angle).sin_cos();
            worst = worst.max((f64::from(sin) - expected_sin).abs()).max((f64::from(cos) - expected_cos).abs());
        }
        // The polynomials' 1e-7 relative error, the f32 rounding of `ρ` (3e-8) and of the result (6e-8).
        assert!(worst < 2e-7, "{worst}");
    }

    /// Frames of `edges` edges along a wavy strand with twists from `twist`, and its nodes.
    fn strand(edges: usize, twist: impl Fn(usize) -> f32) -> (Vec<Vec3>, StrandFrames) {
        let mut nodes = vec![Vec3::new(0.1, 1.5, -0.2)];
        let mut frames = StrandFrames::default();
        for edge in 0..edges {
            let phase = edge as f32 * 0.7;
            // Tangents on both sides of |x| = |y|, so that both bases are used.
            let tangent = Vec3::new(1.3 * phase.sin(), -1.0, 0.6 * (1.3 * phase).cos()).normalize();
            let reference = tangent.cross(Vec3::new(0.2, 0.3, 1.0)).normalize();
            nodes.push(nodes[edge] + 0.01 * tangent);
            frames.tangents.push(tangent);
            frames.reference_directors.push(reference);
            frames.twist.push(twist(edge));
        }
        frames.reference_twist = vec![0.0; edges + 1];
        (nodes, frames)
    }

    #[test]
    fn a_director_coded_from_the_reference_and_twist_is_the_director_coded_directly() {
        // Twists in the single-precision path, and batches that take the double-precision one: past its
        // bound, and not finite.
        type TwistOfEdge = fn(usize) -> f32;
        let twists: [(&str, TwistOfEdge); 4] = [
            ("small", |edge| edge as f32 * 0.37 - 6.0),
            ("large", |edge| ((edge % 17) as f32 * 997.3 - 8000.0) * if edge % 2 == 0 { 1.0 } else { -1.0 }),
            ("beyond the single-precision bound", |edge| 8192.0 + edge as f32 * 12_345.6),
            ("one batch not finite", |edge| if edge == 9 { f32::NAN } else { edge as f32 }),
        ];
        let mut froms = [0, 0];
        for (name, twist) in twists {
            let edges = 21;
            let (nodes, frames) = strand(edges, twist);
            let mut positions = vec![0.0; 3 * nodes.len()];
            let mut codes = vec![0_u8; FRAME_CODE_BYTES * nodes.len()];
            assert!(pack_guide(&nodes, &frames, &mut positions, &mut codes), "{name}");
            assert_eq!(positions, nodes.iter().flat_map(|node| node.to_array()).collect::<Vec<_>>(), "{name}");
            let low = nodes.iter().fold(Vec3::INFINITY, |low, node| low.min(*node));
            let high = nodes.iter().fold(Vec3::NEG_INFINITY, |high, node| high.max(*node));
            assert_eq!(bounds_of(&positions), (low, high), "{name}");
            let code = |node: usize| {
                let bytes = &codes[FRAME_CODE_BYTES * node..FRAME_CODE_BYTES * (node + 1)];
                u32::from_le_bytes([bytes[0], bytes[1], bytes[2], 0])
            };
            assert_eq!(code(0), code(1), "{name}: the root takes the root edge's frame");
            for edge in 0..edges {
                let (packed, tangent) = (code(edge + 1), frames.tangents[edge]);
                if !frames.twist[edge].is_finite() {
                    continue;
                }
                let direct = encode_frame(tangent, frames.material_frame(edge).unwrap().m1);
                // The same angle, to a step of the code (the two round differently in f32).
                let difference = (packed & (FROM_Y - 1)).abs_diff(direct & (FROM_Y - 1));
                assert!(
                    packed & FROM_Y == direct & FROM_Y && (difference <= 2 || difference >= FROM_Y - 3),
                    "{name}, edge {edge}: {packed} {direct}"
                );
                froms[usize::from(packed & FROM_Y != 0)] += 1;
            }
        }
        assert!(froms[0] > 10 && froms[1] > 10, "both bases are used: {froms:?}");
    }

    #[test]
    fn frames_with_an_edge_of_zero_length_are_not_usable() {
        let (mut nodes, frames) = strand(10, |edge| edge as f32);
        nodes[4] = nodes[3];
        let mut positions = vec![0.0; 3 * nodes.len()];
        let mut codes = vec![0_u8; FRAME_CODE_BYTES * nodes.len()];
        assert!(!pack_guide(&nodes, &frames, &mut positions, &mut codes));
        let (nodes, mut frames) = strand(10, |edge| edge as f32);
        frames.twist.pop();
        assert!(!pack_guide(&nodes, &frames, &mut positions, &mut codes), "a frame missing");
    }
}
