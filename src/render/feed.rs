//! What the GPU is sent to place a head's followers and draw its hair itself (`followers.wgsl`): once per
//! layout, each drawn node's rest offset from its guide and where each guide starts; once per step, the
//! guides' nodes, a 24-bit frame code per guide node, a word or two per guide and the head's colliders.
//! Everything else (every follower node, the guides' material frames, the interpolation between steps) is
//! made on the GPU.
//!
//! **What the CPU does per step** is copying: the step packs each guide's pose into one small array while
//! the strand is in its core's cache ([`PackedStrandPose`]: positions, and the frames as the root edge's
//! director and each vertex's material twist, no trigonometry per node), and [`GuideUpload::pack`] copies
//! those arrays, one per guide, into the upload, checking on the way that each guide is still as laid out
//! (its node count, its followers and their binding, its drawn radius), so that no other pass over the
//! guides is needed to see a change ([`LayoutChanged`]). The GPU walks each guide from its root to make the
//! frames (`frames` in the shader, [`walk_directors`] on the CPU); a follower node is then
//! `x_g + o_t t + o_1 m1 + o_2 m2` in the material frame of its guide's edge ([`crate::followers`]).
//!
//! Bytes per step: 15 per guide node and 8 per guide, against 12 per drawn node when the CPU writes every
//! node (a guide with ten followers: 11 × 12 = 132 bytes per node before, 15 after).
//!
//! [`walk_directors`]: crate::simulation::packed::walk_directors

use bevy::math::Vec3;
use bevy::prelude::Entity;

use super::{GuideLayout, bounds_of, take_front};
use crate::followers::FollowerNodes;
use crate::parallel::prefetch;
use crate::rod::{ColliderShape, MovingCollider};
use crate::simulation::PackedStrandPose;
use crate::simulation::packed::{POSE_NO_FRAMES, POSE_SNAP};

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
pub const GUIDE_SNAP: u32 = POSE_SNAP;
/// A guide without usable frames this step: its followers are drawn on its nodes.
pub const GUIDE_NO_FRAMES: u32 = POSE_NO_FRAMES;
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
    /// plane `(0, 0, 0, 3)`, cuboid `(half extents, 4)` (its rounding is `centre.w` less the half
    /// extents' length), m.
    pub shape: [f32; 4],
}

impl GpuCollider {
    /// The collider at the end of its step's motion, as the CPU placement takes it; `None` for a mesh,
    /// which the GPU placement does not push followers out of (the guides still meet it).
    pub fn new(collider: &MovingCollider) -> Option<Self> {
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
            // The rounding is the bounding radius less the half extents' length.
            ColliderShape::Cuboid { half_extents, .. } => {
                let half = half_extents.as_vec3();
                [half.x, half.y, half.z, 4.0]
            }
            ColliderShape::Mesh { .. } => return None,
        };
        Some(Self {
            centre: [centre.x, centre.y, centre.z, collider.shape.bounding_radius() as f32],
            rotation: rotation.to_array(),
            shape,
        })
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
    /// The guides as laid out, in layout order.
    laid_out: Vec<GuideLayout>,
    /// First guide node of each guide, and one past the last.
    guide_first: Vec<usize>,
    /// The longest rest offset, m.
    max_offset: f32,
    /// This step's guide node positions, `x y z` per node, world space, m.
    pub positions: Vec<f32>,
    /// This step's frame code per guide node ([`PackedStrandPose::frame_code_bytes`]), three bytes each
    /// (little-endian), padded to whole words.
    pub frames: Vec<u8>,
    /// Per guide: its contact thickness (m, `f32` bits) and flags ([`GUIDE_SNAP`], [`GUIDE_NO_FRAMES`]).
    pub guides: Vec<[u32; 2]>,
    /// The head's colliders this step.
    pub colliders: Vec<GpuCollider>,
    /// What each piece of the work of [`GuideUpload::pack`] leaves (reused).
    pieces: Vec<PackedPiece>,
}

impl GuideUpload {
    /// Lays out the drawn nodes of `guides` (each guide's layout and its followers as bound, in drawing
    /// order), as [`super::HairStrips::set_layout`] lays them out.
    pub fn set_layout<'a>(&mut self, guides: impl IntoIterator<Item = (GuideLayout, Option<&'a FollowerNodes>)>) {
        self.laid_out.clear();
        self.drawn_nodes.clear();
        self.guide_of_node.clear();
        self.guide_first.clear();
        self.max_offset = 0.0;
        let mut guide_node = 0_usize;
        for (index, (guide, followers)) in guides.into_iter().enumerate() {
            let nodes = guide.nodes as usize;
            self.laid_out.push(guide);
            self.guide_first.push(guide_node);
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

    /// The guides as laid out, in drawing order.
    pub fn guides(&self) -> &[GuideLayout] {
        &self.laid_out
    }

    /// Per guide: its first guide node; and one past the last guide node.
    pub fn guide_starts(&self) -> Vec<u32> {
        self.guide_first.iter().map(|&first| first as u32).collect()
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

    /// Writes this step's guide data in parallel on up to `threads` threads, with `colliders`, checking on
    /// the way that each guide is as laid out: `guide_of` gives a guide's layout as it is now and the pose
    /// the step packed for it, if any; where there is none (just laid out, or the strand changed since),
    /// `unpacked` packs one into the array it is given from the guide's components (saying whether the
    /// guide was found). `snap_all` draws every guide where it is now (when more than one step passed
    /// since the last upload, the GPU has no previous step to interpolate from).
    ///
    /// Returns the bounds of what will be drawn (the guides' nodes widened by twice the longest offset: a
    /// follower node pushed out of a collider stays that close), `None` when nothing is there; or
    /// [`LayoutChanged`] when a guide is gone or no longer as laid out (then lay out again and pack
    /// again). A guide whose pose cannot be had either way keeps its last data and is drawn still.
    pub fn pack<'a>(
        &mut self,
        threads: usize,
        colliders: &[MovingCollider],
        snap_all: bool,
        guide_of: impl Fn(Entity) -> Option<(GuideLayout, Option<&'a PackedStrandPose>)> + Sync,
        unpacked: impl Fn(Entity, &mut PackedStrandPose) -> bool + Sync,
    ) -> Result<Option<(Vec3, Vec3)>, LayoutChanged> {
        self.colliders.clear();
        self.colliders.extend(colliders.iter().filter_map(GpuCollider::new));
        let (laid_out, first_nodes) = (&self.laid_out, &self.guide_first);
        let ranges = super::piece_ranges(laid_out.len(), threads);
        self.pieces.resize_with(ranges.len(), PackedPiece::default);
        let (mut positions, mut frames): (&mut [f32], &mut [u8]) = (&mut self.positions, &mut self.frames);
        let (mut guides, mut pieces) = (&mut self.guides[..], &mut self.pieces[..]);
        let work = ranges.map(|range| {
            let nodes = first_nodes[range.end] - first_nodes[range.start];
            let guide_count = range.len();
            let piece_positions = take_front(&mut positions, 3 * nodes);
            let piece_frames = take_front(&mut frames, FRAME_CODE_BYTES * nodes);
            let piece_guides = take_front(&mut guides, guide_count);
            (range, piece_positions, piece_frames, piece_guides, &mut take_front(&mut pieces, 1)[0])
        });
        let (guide_of, unpacked) = (&guide_of, &unpacked);
        crate::parallel::run_in_parallel(threads, work, |(range, positions, frames, guides, piece)| {
            piece.layout_changed = false;
            let base = first_nodes[range.start];
            // Each guide is looked up `AHEAD` guides early and its pose asked for then.
            let end_of_piece = range.end;
            let look = |index: usize| {
                let found = if index < end_of_piece { guide_of(laid_out[index].entity) } else { None };
                found.inspect(|(_, pose)| {
                    if let Some(pose) = pose {
                        prefetch(pose.words());
                    }
                })
            };
            let mut found: [Option<(GuideLayout, Option<&PackedStrandPose>)>; AHEAD] = [None; AHEAD];
            for index in range.start..range.start + AHEAD {
                found[index % AHEAD] = look(index);
            }
            for (guide, index) in guides.iter_mut().zip(range) {
                let this = std::mem::replace(&mut found[index % AHEAD], look(index + AHEAD));
                let Some((layout, pose)) = this.filter(|(layout, _)| *layout == laid_out[index]) else {
                    piece.layout_changed = true;
                    return;
                };
                let (start, end) = (first_nodes[index] - base, first_nodes[index + 1] - base);
                let scratch = &mut piece.pose;
                let pose = match pose {
                    Some(pose) if pose.node_count() == end - start => pose,
                    _ if unpacked(layout.entity, scratch) && scratch.node_count() == end - start => &*scratch,
                    _ => {
                        guide[1] |= GUIDE_SNAP;
                        continue;
                    }
                };
                positions[3 * start..3 * end].copy_from_slice(bytemuck::cast_slice(pose.positions()));
                frames[FRAME_CODE_BYTES * start..FRAME_CODE_BYTES * end].copy_from_slice(pose.frame_code_bytes());
                let flags = pose.flags() | if snap_all { GUIDE_SNAP } else { 0 };
                *guide = [pose.thickness().to_bits(), flags];
            }
            // What is drawn: a guide not found this step is drawn where it was.
            piece.bounds = bounds_of(positions);
        });
        if self.pieces.iter().any(|piece| piece.layout_changed) {
            return Err(LayoutChanged);
        }
        let empty = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (low, high) = self.pieces.iter().fold(empty, |(low, high), piece| {
            let (a, b) = piece.bounds;
            (low.min(a), high.max(b))
        });
        let reach = Vec3::splat(2.0 * self.max_offset);
        Ok((low.cmple(high).all()).then_some((low - reach, high + reach)))
    }
}

/// What [`GuideUpload::pack`] finds when a guide is gone or no longer as laid out (its node count, its
/// followers, their binding or its drawn radius changed): the hair must be laid out again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LayoutChanged;

/// What one piece of [`GuideUpload::pack`]'s work leaves (reused from step to step).
#[derive(Debug, Clone, Default)]
struct PackedPiece {
    /// Bounds of the piece's guide nodes.
    bounds: (Vec3, Vec3),
    /// Whether one of its guides is gone or no longer as laid out.
    layout_changed: bool,
    /// A pose packed here for a guide the step packed none for.
    pose: PackedStrandPose,
}

/// A drawn node's word without flags but the root's: its guide node, and [`DRAWN_ROOT`] at a root.
fn node_word(guide_node: usize, node: usize) -> u32 {
    (guide_node as u32 & DRAWN_GUIDE_NODE) | if node == 0 { DRAWN_ROOT } else { 0 }
}

/// How many guides ahead [`GuideUpload::pack`] looks guides up and asks for their poses.
const AHEAD: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulation::{StrandFrames, StrandNodes};

    /// A wavy strand of `edges` edges with consistent frames (reference directors carried along by
    /// parallel transport, so that the reference twists are zero) and twist angles from `twist`.
    fn strand(edges: usize, shift: f32, twist: impl Fn(usize) -> f32) -> (StrandNodes, StrandFrames) {
        let mut nodes = StrandNodes { positions: vec![Vec3::new(shift, 1.5, -0.2)], ..Default::default() };
        let mut frames = StrandFrames::default();
        let mut reference = Vec3::ZERO;
        for edge in 0..edges {
            let phase = edge as f32 * 0.7;
            let tangent = Vec3::new(0.8 * phase.sin(), -1.0, 0.6 * (1.3 * phase).cos()).normalize();
            reference = if edge == 0 {
                tangent.any_orthonormal_vector()
            } else {
                crate::simulation::packed::transport(frames.tangents[edge - 1], tangent, reference).normalize()
            };
            let next = nodes.positions[edge] + 0.01 * tangent;
            nodes.positions.push(next);
            frames.tangents.push(tangent);
            frames.reference_directors.push(reference);
            frames.twist.push(twist(edge));
        }
        nodes.previous_positions = nodes.positions.iter().map(|p| *p - Vec3::X * 1e-3).collect();
        frames.reference_twist = vec![0.0; edges + 1];
        (nodes, frames)
    }

    #[test]
    fn poses_packed_by_the_step_and_poses_packed_here_upload_the_same() {
        let guides: Vec<(StrandNodes, StrandFrames)> =
            (0..9).map(|index| strand(8 + index, index as f32 * 0.01, |edge| (edge * index) as f32 * 0.1)).collect();
        let entities: Vec<Entity> = (0..guides.len() as u32).map(Entity::from_raw_u32).map(Option::unwrap).collect();
        let packed: Vec<PackedStrandPose> = guides
            .iter()
            .map(|(nodes, frames)| {
                let mut pose = PackedStrandPose::default();
                pose.write(nodes, frames, 2e-4, false);
                pose
            })
            .collect();
        let index_of = |entity: Entity| entities.iter().position(|&e| e == entity);
        let layout_of = |index: usize| GuideLayout {
            entity: entities[index],
            nodes: guides[index].0.positions.len() as u32,
            followers: 0,
            binding: 0,
            radius: 4e-5,
        };
        let layout = || (0..guides.len()).map(|index| (layout_of(index), None));
        let (mut by_step, mut here) = (GuideUpload::default(), GuideUpload::default());
        by_step.set_layout(layout());
        here.set_layout(layout());
        // Two threads' pieces on one side, one on the other.
        let packed_by_step = |entity| index_of(entity).map(|i| (layout_of(i), Some(&packed[i])));
        let bounds = by_step.pack(2, &[], false, packed_by_step, |_, _| false);
        let unpacked = |entity: Entity, pose: &mut PackedStrandPose| {
            let Some(i) = index_of(entity) else { return false };
            pose.write(&guides[i].0, &guides[i].1, 2e-4, false);
            true
        };
        let none_packed = |entity| index_of(entity).map(|i| (layout_of(i), None));
        assert_eq!(here.pack(1, &[], false, none_packed, unpacked), bounds);
        assert!(bounds.is_ok_and(|bounds| bounds.is_some()));
        assert_eq!(
            (&by_step.positions, &by_step.frames, &by_step.guides),
            (&here.positions, &here.frames, &here.guides)
        );
        let expected: Vec<f32> =
            guides.iter().flat_map(|(nodes, _)| nodes.positions.iter().flat_map(|p| p.to_array())).collect();
        assert_eq!(by_step.positions, expected);
        assert!(by_step.guides.iter().all(|&[thickness, flags]| f32::from_bits(thickness) == 2e-4 && flags == 0));
        // A guide found neither way keeps its data and is drawn still.
        assert!(here.pack(1, &[], false, none_packed, |_, _| false).is_ok());
        assert_eq!(here.positions, expected);
        assert!(here.guides.iter().all(|&[_, flags]| flags & GUIDE_SNAP != 0));
    }

    #[test]
    fn a_guide_gone_or_changed_since_the_layout_is_found_while_packing() {
        let guides: Vec<(StrandNodes, StrandFrames)> =
            (0..12).map(|index| strand(6, index as f32 * 0.01, |_| 0.0)).collect();
        let entities: Vec<Entity> = (0..guides.len() as u32).map(Entity::from_raw_u32).map(Option::unwrap).collect();
        let layout_of =
            |index: usize| GuideLayout { entity: entities[index], nodes: 7, followers: 0, binding: 0, radius: 4e-5 };
        let mut upload = GuideUpload::default();
        upload.set_layout((0..guides.len()).map(|index| (layout_of(index), None)));
        let index_of = |entity: Entity| entities.iter().position(|&e| e == entity);
        let unpacked = |entity: Entity, pose: &mut PackedStrandPose| {
            let Some(i) = index_of(entity) else { return false };
            pose.write(&guides[i].0, &guides[i].1, 2e-4, false);
            true
        };
        let as_laid_out = |entity| index_of(entity).map(|i| (layout_of(i), None));
        assert!(upload.pack(2, &[], false, as_laid_out, unpacked).is_ok());
        for threads in [1, 2, 3] {
            // The last guide gone; the ninth's followers bound again; the fourth drawn wider.
            let gone = |entity| index_of(entity).filter(|&i| i != 11).map(|i| (layout_of(i), None));
            assert_eq!(upload.pack(threads, &[], false, gone, unpacked), Err(LayoutChanged));
            let rebound =
                |entity| index_of(entity).map(|i| (GuideLayout { binding: u64::from(i == 8), ..layout_of(i) }, None));
            assert_eq!(upload.pack(threads, &[], false, rebound, unpacked), Err(LayoutChanged));
            let wider = |entity| {
                index_of(entity)
                    .map(|i| (GuideLayout { radius: if i == 3 { 8e-5 } else { 4e-5 }, ..layout_of(i) }, None))
            };
            assert_eq!(upload.pack(threads, &[], false, wider, unpacked), Err(LayoutChanged));
        }
        assert!(upload.pack(2, &[], false, as_laid_out, unpacked).is_ok_and(|bounds| bounds.is_some()));
    }
}
