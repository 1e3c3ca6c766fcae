//! A strand's simulated data as components, in single precision: its nodes ([`StrandNodes`]), its edges'
//! frames ([`StrandFrames`]) and its rest shape ([`StrandRestShape`]), which can be edited.
//!
//! The simulation itself runs in double precision on [`SimulatedStrand`](super::SimulatedStrand)'s rod;
//! these components are written from it by every step ([`crate::schedule::HairSystems::Step`]), and edits
//! of the rest shape are read back into it before the next one ([`crate::schedule::HairSystems::Prepare`]).

use bevy::math::{DVec2, Vec2, Vec3};
use bevy::prelude::*;

use crate::rod::{Rod, RodFrames, RodState};

/// A strand's nodes after the last step, world space, single precision: what is drawn, and what a game
/// reads to attach things to hair. Written by the plugin after every step; to move nodes, write the rod
/// ([`SimulatedStrand::rod_mut`](super::SimulatedStrand::rod_mut)) instead (changes made here are overwritten).
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct StrandNodes {
    /// Node positions `x_0 … x_n`, m (node 0 is the root).
    pub positions: Vec<Vec3>,
    /// Node velocities, m/s.
    pub velocities: Vec<Vec3>,
    /// Node positions after the step before, m: with `positions`, what is drawn between two steps.
    pub previous_positions: Vec<Vec3>,
}

impl StrandNodes {
    /// Node positions a fraction `alpha` (0 to 1) of the way from the step before to the last step, m.
    pub fn interpolated(&self, alpha: f32) -> impl Iterator<Item = Vec3> + '_ {
        self.previous_positions
            .iter()
            .zip(&self.positions)
            .map(move |(previous, current)| previous.lerp(*current, alpha))
    }

    /// Copies `state` in; the previous positions jump there too when `snap` (the strand was spawned,
    /// reset or teleported) or the node count changed.
    pub(crate) fn update(&mut self, state: &RodState, snap: bool) {
        std::mem::swap(&mut self.previous_positions, &mut self.positions);
        copy_converted(&mut self.positions, &state.positions, |position| position.as_vec3());
        copy_converted(&mut self.velocities, &state.velocities, |velocity| velocity.as_vec3());
        snap_previous(&mut self.previous_positions, &self.positions, snap);
    }
}

/// Makes the previous positions of a step the current ones when `snap` (nothing to interpolate from:
/// spawned, reset, teleported) or when they do not match in number.
pub(crate) fn snap_previous(previous: &mut Vec<Vec3>, current: &[Vec3], snap: bool) {
    if snap || previous.len() != current.len() {
        previous.clear();
        previous.extend_from_slice(current);
    }
}

/// The orthonormal material frame of one edge, single precision.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub struct EdgeFrame {
    /// Unit tangent `t` of the edge.
    pub tangent: Vec3,
    /// First material director `m1`: the direction of the cross-section's `semi_axis_1`.
    pub m1: Vec3,
    /// Second material director `m2 = t × m1`.
    pub m2: Vec3,
}

/// A strand's edge frames after the last step, world space, single precision (Bergou et al. 2008,
/// §4.2): each edge's reference frame, carried from step to step by time-parallel transport, and the twist
/// angle that turns it into the edge's material frame ([`StrandFrames::material_frame`]). Written by the
/// plugin after every step.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct StrandFrames {
    /// Unit tangent `t^i` of each edge.
    pub tangents: Vec<Vec3>,
    /// Reference director `u^i` of each edge: unit, perpendicular to the tangent.
    pub reference_directors: Vec<Vec3>,
    /// Twist angle `θ^i` of each edge's material frame from its reference frame, rad.
    pub twist: Vec<f32>,
    /// Reference twist at each vertex (integrated, rad; the two ends unused).
    pub reference_twist: Vec<f32>,
}

impl StrandFrames {
    /// The material frame of `edge`: `m1 = cos θ u + sin θ (t × u)`, `m2 = t × m1`; `None` past the last
    /// edge.
    pub fn material_frame(&self, edge: usize) -> Option<EdgeFrame> {
        let (tangent, reference, twist) =
            (*self.tangents.get(edge)?, *self.reference_directors.get(edge)?, *self.twist.get(edge)?);
        let (sin, cos) = twist.sin_cos();
        let reference_2 = tangent.cross(reference);
        Some(EdgeFrame { tangent, m1: cos * reference + sin * reference_2, m2: cos * reference_2 - sin * reference })
    }

    /// The material frames of all edges, root first.
    pub fn material_frames(&self) -> impl Iterator<Item = EdgeFrame> + '_ {
        (0..self.tangents.len()).filter_map(|edge| self.material_frame(edge))
    }

    pub(crate) fn update(&mut self, frames: &RodFrames, twist: &[f64]) {
        copy_converted(&mut self.tangents, &frames.tangents, |tangent| tangent.as_vec3());
        copy_converted(&mut self.reference_directors, &frames.reference_directors, |director| director.as_vec3());
        copy_converted(&mut self.twist, twist, |angle| angle as f32);
        copy_converted(&mut self.reference_twist, &frames.reference_twist, |angle| angle as f32);
    }
}

/// A strand's rest shape, single precision: the shape it has no elastic energy in (Bergou et al. 2008,
/// §4.1–4.2). Written when the strand is built from its [`HairStrand`](super::HairStrand); **edit it** to
/// restyle a strand in place (grow it, curl it, straighten it): the change is picked up before the next
/// step. Entries left as they were keep their full precision. A new length of the root edge moves the
/// second node's anchor on the head along the edge.
///
/// An edit the simulation cannot take (see [`Rod::set_rest_shape`]: a non-finite value, an edge of (almost)
/// zero length, a turn sharper than [`crate::rod::MAX_TURNING_ANGLE`], arrays resized) is rejected as a
/// whole: logged as an error naming the strand and the reason, and the component is put back to the rest
/// shape in use.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct StrandRestShape {
    /// Rest length `|ē^i|` of each edge, m.
    pub lengths: Vec<f32>,
    /// Rest material curvature `(κ̄₁, κ̄₂)` of each vertex, integrated: `2 tan(φ/2)` for a turn of `φ`
    /// between the two edges, along `m2` and `−m1`; dimensionless, the two ends unused.
    pub curvatures: Vec<Vec2>,
    /// Rest twist `τ̄` of each vertex (integrated, rad; the two ends unused).
    pub twists: Vec<f32>,
}

impl StrandRestShape {
    /// Copies the rod's rest shape in.
    pub(crate) fn update(&mut self, rod: &Rod) {
        let rest = rod.rest_shape();
        copy_converted(&mut self.lengths, &rest.lengths, |length| length as f32);
        copy_converted(&mut self.curvatures, &rest.curvatures, |curvature| curvature.as_vec2());
        copy_converted(&mut self.twists, &rest.twists, |twist| twist as f32);
    }

    /// Whether this differs from the rod's rest shape in single precision.
    pub(crate) fn differs_from(&self, rod: &Rod) -> bool {
        let rest = rod.rest_shape();
        !(self.lengths.iter().copied().eq(rest.lengths.iter().map(|&length| length as f32))
            && self.curvatures.iter().copied().eq(rest.curvatures.iter().map(|curvature| curvature.as_vec2()))
            && self.twists.iter().copied().eq(rest.twists.iter().map(|&twist| twist as f32)))
    }

    /// This rest shape in double precision, into `scratch`: the entries that differ from the rod's in
    /// single precision are taken from here, the others keep the rod's double-precision values.
    pub(crate) fn merge_into(&self, rod: &Rod, scratch: &mut RestShapeScratch) {
        let rest = rod.rest_shape();
        merge_edits(&self.lengths, &rest.lengths, |length| length as f32, f64::from, &mut scratch.lengths);
        merge_edits(&self.curvatures, &rest.curvatures, DVec2::as_vec2, Vec2::as_dvec2, &mut scratch.curvatures);
        merge_edits(&self.twists, &rest.twists, |twist| twist as f32, f64::from, &mut scratch.twists);
    }
}

/// `edited` in double precision, into `out`: each entry that `narrow` of the `current` one (single
/// precision) equals keeps the current value, the others are `widen`ed from `edited` (as are entries
/// past the end of `current`).
fn merge_edits<S: Copy + PartialEq, D: Copy>(
    edited: &[S],
    current: &[D],
    narrow: impl Fn(D) -> S,
    widen: impl Fn(S) -> D,
    out: &mut Vec<D>,
) {
    out.clear();
    out.extend(edited.iter().enumerate().map(|(index, &ours)| match current.get(index) {
        Some(&theirs) if narrow(theirs) == ours => theirs,
        _ => widen(ours),
    }));
}

/// Memory reused from edit to edit of rest shapes.
#[derive(Default)]
pub(crate) struct RestShapeScratch {
    pub(crate) lengths: Vec<f64>,
    pub(crate) curvatures: Vec<DVec2>,
    pub(crate) twists: Vec<f64>,
}

/// `destination` made the converted copy of `source`, reusing its memory.
pub(crate) fn copy_converted<S: Copy, T>(destination: &mut Vec<T>, source: &[S], convert: impl Fn(S) -> T) {
    destination.clear();
    destination.extend(source.iter().map(|&value| convert(value)));
}
