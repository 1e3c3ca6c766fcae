//! [`PackedStrandPose`]: a strand's pose after the last step in 32-bit words, written by the step while the
//! strand is in the core's cache, for a GPU that places and draws hairs from it (the renderer's follower
//! placement, `render::feed`). Reading one small array per strand costs a frame a fraction of reading the
//! five of [`StrandNodes`] and [`StrandFrames`], each behind a pointer of its own.
//!
//! **The frames in 24 bits a node, without trigonometry per node.** A follower node is placed in the
//! material frame of its guide's edge (Bergou et al. 2008, §4.2). The frame of the root edge is sent as
//! the angle of its director `m1` about the edge's tangent: in the basis `b1 = (t × r)/|t × r|`,
//! `b2 = t × b1`, `r` the X or the Y axis, whichever is farther from `t` (one bit), as a "diamond angle"
//! (`s / (|c| + |s|)` by quadrant) in 23 bits, within 4.8e-7 rad ([`encode_director`]). Each later edge's
//! frame follows from the one before: carried onto the edge by parallel transport along the strand, then
//! turned about it by the material twist `τ_i = θ^i − θ^{i−1} + m_i` of the vertex between them
//! (Bergou et al. 2008, §4.2.2: the twist `θ` of each frame from its reference frame, and the reference
//! frames' own twist `m_i`), sent as a fraction of a turn in 24 bits, 3.7e-7 rad a step
//! ([`encode_turn`]). The reader walks each strand from its root ([`walk_directors`]).

use bevy::math::Vec3;
use bevy::prelude::*;

use super::data::{StrandFrames, StrandNodes};

/// A pose with nothing to interpolate from: its previous positions are its current ones (spawned, reset,
/// teleported) or do not match them in number.
pub const POSE_SNAP: u32 = 1;
/// A pose whose frames cannot be used (missing, not finite, or an edge of zero length): hairs placed
/// about it go on its nodes.
pub const POSE_NO_FRAMES: u32 = 2;
/// The diamond angle's steps per quadrant.
const ANGLE_STEPS: f32 = (1 << 21) as f32;
/// The bit of a director's code that says the basis was built from the Y axis.
const FROM_Y: u32 = 1 << 23;
/// A material twist's steps per turn.
const TURN_STEPS: f32 = (1 << 24) as f32;
/// The largest material twist of one vertex (rad) whose frames are used: ten turns.
const MAX_VERTEX_TWIST: f32 = 20.0 * std::f32::consts::PI;
/// The bits of a 24-bit code.
const CODE_BITS: u32 = (1 << 24) - 1;

/// A strand's pose after the last step, packed in 32-bit words (see the [module documentation](self)): its
/// flags ([`POSE_SNAP`], [`POSE_NO_FRAMES`]), its contact thickness, its node positions (world space,
/// single precision) and one 24-bit frame code per node, three bytes each. Add it to a strand to have
/// the step write it; the renderer adds it to the guides whose followers the GPU places.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct PackedStrandPose {
    /// Flags, thickness (m, `f32` bits), node count; `x y z` per node (`f32` bits); the frame codes, three
    /// bytes each (little-endian), padded with zeros to a whole word.
    words: Vec<u32>,
}

/// Words before the positions: flags, thickness, node count.
const HEADER_WORDS: usize = 3;

impl PackedStrandPose {
    /// An empty pose with room for a strand of `nodes` nodes: poses made one after the other for the
    /// strands in the order they are read lie one after the other in memory (the step never has to move
    /// them), so that reading them is one pass through memory instead of a jump per strand.
    pub fn with_capacity(nodes: usize) -> Self {
        Self { words: Vec::with_capacity(HEADER_WORDS + 4 * nodes) }
    }

    /// Packs `nodes` and `frames` (as the step wrote them) with the strand's contact thickness (m);
    /// `snapped` says the pose jumped there (spawned, reset or teleported), as whoever wrote `nodes` knows
    /// ([`PackedStrandPose::write_from_components`] judges it from the nodes). A pose whose previous
    /// positions do not match its nodes in number snaps too.
    pub fn write(&mut self, nodes: &StrandNodes, frames: &StrandFrames, thickness: f32, snapped: bool) {
        let count = nodes.positions.len();
        self.words.clear();
        self.words.extend([0, thickness.to_bits(), count as u32]);
        self.words.extend_from_slice(bytemuck::cast_slice(&nodes.positions));
        // A word per code first, then each moved down to three bytes (to a lower address than it is read
        // from, so that none is overwritten before it is moved).
        let codes_at = self.words.len();
        self.words.resize(codes_at + count, 0);
        let usable = frame_codes(&nodes.positions, frames, &mut self.words[codes_at..]);
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut self.words[codes_at..]);
        for node in 0..count {
            let code = [bytes[4 * node], bytes[4 * node + 1], bytes[4 * node + 2]];
            bytes[3 * node..3 * node + 3].copy_from_slice(&code);
        }
        let code_words = (3 * count).div_ceil(4);
        bytes[3 * count..4 * code_words].fill(0);
        self.words.truncate(codes_at + code_words);
        let snap = snapped || nodes.previous_positions.len() != count;
        self.words[0] = if snap { POSE_SNAP } else { 0 } | if usable { 0 } else { POSE_NO_FRAMES };
    }

    /// Packs as [`PackedStrandPose::write`] does, for a caller that did not write `nodes` itself: the pose
    /// snapped where its previous positions are its current ones.
    pub fn write_from_components(&mut self, nodes: &StrandNodes, frames: &StrandFrames, thickness: f32) {
        self.write(nodes, frames, thickness, nodes.previous_positions == nodes.positions);
    }

    /// The whole array, to ask for it ahead of reading it.
    pub(crate) fn words(&self) -> &[u32] {
        &self.words
    }

    /// Number of nodes (0 before the first write).
    pub fn node_count(&self) -> usize {
        self.words.get(2).map_or(0, |&count| count as usize)
    }

    /// [`POSE_SNAP`] and [`POSE_NO_FRAMES`].
    pub fn flags(&self) -> u32 {
        self.words.first().copied().unwrap_or(POSE_SNAP | POSE_NO_FRAMES)
    }

    /// The strand's contact thickness, m.
    pub fn thickness(&self) -> f32 {
        self.words.get(1).map_or(0.0, |&bits| f32::from_bits(bits))
    }

    /// Node positions, `x y z` per node as `f32` bits, m.
    pub fn positions(&self) -> &[u32] {
        self.words.get(HEADER_WORDS..HEADER_WORDS + 3 * self.node_count()).unwrap_or_default()
    }

    /// The frame codes, three bytes each (little-endian), as the GPU reads them: the root edge's director
    /// ([`encode_director`]) at the root and the next node, then at node `i + 1` the material twist of
    /// vertex `i` ([`encode_turn`]).
    pub fn frame_code_bytes(&self) -> &[u8] {
        let count = self.node_count();
        let codes = self.words.get(HEADER_WORDS + 3 * count..).unwrap_or_default();
        bytemuck::cast_slice(codes).get(..3 * count).unwrap_or_default()
    }

    /// The frame code of `node` (see [`PackedStrandPose::frame_code_bytes`]); 0 past the last.
    pub fn frame_code(&self, node: usize) -> u32 {
        let bytes = self.frame_code_bytes().get(3 * node..3 * node + 3).unwrap_or(&[0; 3]);
        u32::from_le_bytes([bytes[0], bytes[1], bytes[2], 0])
    }
}

/// Writes the frame codes of a strand with nodes `positions` and `frames`, a word each (see
/// [`PackedStrandPose::frame_code_bytes`]); says whether they are usable.
fn frame_codes(positions: &[Vec3], frames: &StrandFrames, codes: &mut [u32]) -> bool {
    let edges = positions.len().saturating_sub(1);
    let (twist, reference_twist) = (&frames.twist, &frames.reference_twist);
    if edges == 0 || frames.tangents.len() != edges || twist.len() != edges || reference_twist.len() != edges + 1 {
        return false;
    }
    // Whoever reads the codes divides by each edge's length. The checks are and-ed without a branch (a
    // comparison with NaN is false): a running minimum would chain each edge to the one before.
    let mut usable = true;
    for ends in positions.windows(2) {
        usable &= (ends[1] - ends[0]).length_squared() >= f32::MIN_POSITIVE;
    }
    let Some(root) = frames.material_frame(0) else { return false };
    codes[0] = encode_director(root.tangent, root.m1);
    codes[1] = codes[0];
    usable &= root.m1.is_finite() && root.tangent.is_finite();
    // Past `MAX_VERTEX_TWIST` a vertex's twist is no frame at all.
    for vertex in 1..edges {
        let tau = twist[vertex] - twist[vertex - 1] + reference_twist[vertex];
        usable &= tau.abs() <= MAX_VERTEX_TWIST;
        codes[vertex + 1] = encode_turn(tau);
    }
    usable
}

/// The 24-bit code of the director `m1` about the unit `tangent` (see the [module documentation](self)).
pub fn encode_director(tangent: Vec3, m1: Vec3) -> u32 {
    let from_y = tangent.x.abs() > tangent.y.abs();
    let (b1, b2) = director_basis(tangent, from_y);
    diamond_steps(m1.dot(b1), m1.dot(b2)) | if from_y { FROM_Y } else { 0 }
}

/// The director `m1` a code stands for about the unit `tangent`, as the GPU decodes it.
pub fn decode_director(tangent: Vec3, code: u32) -> Vec3 {
    let (b1, b2) = director_basis(tangent, code & FROM_Y != 0);
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

/// The basis `(b1, b2)` across `tangent` built from the X axis, or from the Y axis when `from_y`.
fn director_basis(tangent: Vec3, from_y: bool) -> (Vec3, Vec3) {
    let axis = if from_y { Vec3::Y } else { Vec3::X };
    let b1 = tangent.cross(axis).normalize();
    (b1, tangent.cross(b1))
}

/// The diamond angle of `(c, s)` (0 to 4 round the circle: `1 − c / (|c| + |s|)` for `s ≥ 0`,
/// `3 + c / (|c| + |s|)` below) in steps of 1/2²¹, rounded, 4 wrapping to 0; a zero vector has angle 1.
/// Without a branch: the side of `s` is a factor, and adding 2²³ rounds the steps into the low bits.
fn diamond_steps(c: f32, s: f32) -> u32 {
    const INTEGER: f32 = 8_388_608.0;
    let ratio = c / (c.abs() + s.abs()).max(f32::MIN_POSITIVE);
    let below = if s < 0.0 { 1.0 } else { 0.0 };
    let diamond = 1.0 + 2.0 * below + ratio * (2.0 * below - 1.0);
    (diamond * ANGLE_STEPS + INTEGER).to_bits() & (FROM_Y - 1)
}

/// The 24-bit code of a turn by `angle` (rad): the nearest of 2²⁴ steps per turn, two's complement,
/// wrapping round the circle (to half a step for `|angle|` up to 2²⁷ rad). Rounded in f64 without a
/// branch or a call into libm: adding `1.5 · 2⁵²` leaves the nearest integer in the low bits of the sum
/// (`f32::round` is a call into libm without SSE4.1, as much as the rest of a strand's packing).
pub fn encode_turn(angle: f32) -> u32 {
    const ROUNDING: f64 = 6_755_399_441_055_744.0;
    const STEPS_PER_RADIAN: f64 = (1 << 24) as f64 / std::f64::consts::TAU;
    ((f64::from(angle) * STEPS_PER_RADIAN + ROUNDING).to_bits() as u32) & CODE_BITS
}

/// `(sin, cos)` of the turn a code stands for, as the GPU computes them: the quarter turns taken exactly
/// from the code's top bits, the rest (under an eighth of a turn) through Cephes' minimax polynomials of
/// `sinf` and `cosf` (relative error under 1e-7), so that no hardware `sin` or `cos` (whose accuracy
/// WGSL leaves loose) is needed.
pub fn turn_sin_cos(code: u32) -> (f32, f32) {
    // The nearest quarter turn and the rest, in steps: `code = q · 2²² + rest`, `|rest| ≤ 2²¹`.
    let quarter = ((code + (1 << 21)) >> 22) & 3;
    let rest = ((code & CODE_BITS) as i32 - (quarter << 22) as i32) << 8 >> 8;
    let r = rest as f32 * (std::f32::consts::TAU / TURN_STEPS);
    let r2 = r * r;
    let sin = r + r * r2 * (-1.666_665_5e-1 + r2 * (8.332_161e-3 + r2 * -1.951_529_6e-4));
    let cos = 1.0 - 0.5 * r2 + r2 * r2 * (4.166_664_6e-2 + r2 * (-1.388_731_6e-3 + r2 * 2.443_315_7e-5));
    match quarter {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// `v` carried from the unit tangent `from` to the unit tangent `to` by the rotation about `from × to`
/// that takes one to the other (parallel transport between adjacent edges, Bergou et al. 2008, §4.2.1):
/// `v cos φ + (b × v) + b (b · v)/(1 + cos φ)` with `b = from × to`. Tangents turned back on themselves
/// (`cos φ ≤ −0.999`) leave `v` as it is, to be made perpendicular to `to` by the caller.
pub fn transport(from: Vec3, to: Vec3, v: Vec3) -> Vec3 {
    let axis = from.cross(to);
    let cos = from.dot(to);
    if cos <= -0.999 {
        return v;
    }
    v * cos + axis.cross(v) + axis * (axis.dot(v) / (1.0 + cos))
}

/// `v` made perpendicular to the unit `t` and unit; where nothing of it is left across `t` (an edge turned
/// back on the one before), the basis direction `b1` across `t`.
fn perpendicular_unit(v: Vec3, t: Vec3) -> Vec3 {
    let across = v - v.dot(t) * t;
    if across.length_squared() > 1e-12 { across.normalize() } else { director_basis(t, t.x.abs() > t.y.abs()).0 }
}

/// The director `m1` of each node's edge (the root edge's at the root) of `pose`, walked from the root as
/// the GPU walks it (`followers.wgsl`, `frames`): the root's from its code about the root edge, each next
/// edge's carried onto it and turned by its vertex's material twist; tangents from the pose's positions.
pub fn walk_directors(pose: &PackedStrandPose, directors: &mut Vec<Vec3>) {
    directors.clear();
    let positions: &[Vec3] = bytemuck::cast_slice(pose.positions());
    if positions.len() < 2 {
        return;
    }
    let mut tangent = (positions[1] - positions[0]).normalize();
    let mut m1 = decode_director(tangent, pose.frame_code(0));
    directors.extend([m1, m1]);
    for (node, ends) in positions[1..].windows(2).enumerate() {
        let next = (ends[1] - ends[0]).normalize();
        let carried = transport(tangent, next, m1);
        let (sin, cos) = turn_sin_cos(pose.frame_code(node + 2));
        let turned = cos * carried + sin * next.cross(carried);
        m1 = perpendicular_unit(turned, next);
        directors.push(m1);
        tangent = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turns_keep_their_angle_within_a_step() {
        let step = std::f32::consts::TAU / TURN_STEPS;
        let mut worst = 0.0_f64;
        for index in -200_000..=200_000 {
            // Up to three turns either way, and the quarter turns themselves.
            let angle = if index % 1000 == 0 {
                ((index / 1000) % 12) as f32 * std::f32::consts::FRAC_PI_2
            } else {
                index as f32 * 9.4e-5
            };
            let (sin, cos) = turn_sin_cos(encode_turn(angle));
            let (expected_sin, expected_cos) = f64::from(angle).sin_cos();
            let error = (f64::from(sin) - expected_sin).abs().max((f64::from(cos) - expected_cos).abs());
            worst = worst.max(error);
        }
        // Half a step of rounding; the f32 rounding of `angle · 2²⁴/2π` (and of that factor) at up to three
        // turns, 3 steps (1.1e-6 rad); the polynomials' 1e-7 and the f32 rounding of the result.
        assert!(worst < 0.5 * f64::from(step) + 1.1e-6 + 2e-7, "{worst}");
    }

    #[test]
    fn directors_keep_their_angle_within_their_resolution() {
        let mut worst = 0.0_f32;
        let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, Vec3::new(1.0, 1.0, 0.0).normalize()];
        let mut rng = fastrand::Rng::with_seed(7);
        for index in 0..20_000 {
            let tangent = axes
                .get(index)
                .copied()
                .unwrap_or_else(|| Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5).normalize_or(Vec3::Z));
            let m1 = tangent.any_orthonormal_vector();
            let (sin, cos) = (index as f32 * 0.377).sin_cos();
            let m1 = cos * m1 + sin * tangent.cross(m1);
            let decoded = decode_director(tangent, encode_director(tangent, m1));
            assert!((decoded.length() - 1.0).abs() < 1e-5 && decoded.dot(tangent).abs() < 1e-5);
            worst = worst.max(decoded.cross(m1).length().asin());
        }
        // A step of 2⁻²¹ of a quadrant turns the director by at most 2 · 2⁻²¹ rad, half of it by rounding;
        // plus the f32 rounding of the basis and of this measurement.
        assert!(worst <= 1.0 / 2_097_152.0 + 1e-6, "{worst} rad");
    }
}
