//! The frame a groom grows in on a head: the head's own axes (which way its face and crown point in a
//! rig's joint space) and its scale taken out, so that a groom's lengths are metres on any rig.

use std::sync::Arc;

use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;

use super::procedural::GroomError;
use super::surface::{GroomSurface, ScalpSurface};
use crate::followers::HairFollowers;
use crate::simulation::HairStrand;

/// Which way a head's face and crown point in its local space. A [`HairGroom`](super::HairGroom) is
/// designed facing `−Z` with its crown up `+Y` (Bevy's convention, and the default here); a rig's head
/// joint often has axes of its own (a glTF exported from Blender points a head bone's `+Y` along the
/// neck, and animals' rigs point an axis down the snout). Give the joint's axes and the groom turns
/// onto them: the parting, the brow and the nape land where the face is.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct HeadAxes {
    /// The direction the face looks, in the head's local space (need not be unit length).
    pub forward: Vec3,
    /// The direction from the chin to the crown, in the head's local space; only its part across
    /// `forward` counts.
    pub up: Vec3,
}

impl Default for HeadAxes {
    fn default() -> Self {
        Self { forward: Vec3::NEG_Z, up: Vec3::Y }
    }
}

impl HeadAxes {
    /// A head facing `forward` with its crown towards `up`, both in its local space.
    pub fn new(forward: Vec3, up: Vec3) -> Self {
        Self { forward, up }
    }

    /// The rotation that turns a groom's design axes (face `−Z`, crown `+Y`) onto these; fails if either
    /// direction is zero or not finite, or they are parallel.
    pub fn rotation(&self) -> Result<Quat, GroomError> {
        let invalid = || GroomError::HeadAxes { forward: self.forward, up: self.up };
        let up = self.up.try_normalize().ok_or_else(invalid)?;
        let forward = self.forward.try_normalize().ok_or_else(invalid)?;
        let back = -(forward - forward.dot(up) * up).try_normalize().ok_or_else(invalid)?;
        // The design's x (the head's left-to-right) is y × z.
        Ok(Quat::from_mat3(&Mat3::from_cols(up.cross(back), up, back)).normalize())
    }
}

/// Where a groom grows on a head: in the head's local space turned onto [`HeadAxes`] and with the head's
/// (uniform) scale taken out, so in metres. Strands grown there are given to the head as
/// [`HairStrand`]s are: the root in the head's local space (the head's scale moves it), the shape from it
/// in metres, turned with the head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GroomFrame {
    /// From the groom's design axes to the head's local axes.
    pub rotation: Quat,
    /// The head's scale: head-local units per metre are `1 / scale`.
    pub scale: f32,
}

/// How far a head's scale may differ between its axes (relative) and still be taken as uniform.
const UNIFORM_SCALE_TOLERANCE: f32 = 1e-3;

impl GroomFrame {
    /// The frame of `head` as it is placed now: its scale taken out ([`GroomFrame::head_scale`]), its axes
    /// left to the groom ([`HeadAxes`]). A scale that differs between the head's axes cannot be honoured
    /// (hair would stretch as the head turns): it is reported, and the hair grown at the mean scale.
    pub fn of_head(head: Entity, transforms: &TransformHelper) -> Self {
        let (scale, uneven) = Self::head_scale(head, transforms);
        if let Some(uneven) = uneven {
            error!(
                "hair of head {head}: its scale {uneven} differs between its axes; hair keeps its shape as a head turns, so it is grown at the mean scale {scale}"
            );
        }
        Self { rotation: Quat::IDENTITY, scale }
    }

    /// `head`'s scale as it is placed now, as one number: the mean of its axes' scales, with the scale
    /// itself when they differ by more than [`UNIFORM_SCALE_TOLERANCE`]. 1 for a head with no usable
    /// transform yet (its strands wait for it).
    pub fn head_scale(head: Entity, transforms: &TransformHelper) -> (f32, Option<Vec3>) {
        let scale = transforms
            .compute_global_transform(head)
            .ok()
            .map(|transform| transform.to_scale_rotation_translation().0)
            .filter(|scale| scale.is_finite() && scale.min_element() > 0.0);
        let Some(scale) = scale else { return (1.0, None) };
        let mean = scale.element_sum() / 3.0;
        let uneven = scale.max_element() - scale.min_element() > UNIFORM_SCALE_TOLERANCE * mean;
        (mean, uneven.then_some(scale))
    }

    /// Whether this is the head's own space (nothing to turn or scale).
    pub fn is_identity(&self) -> bool {
        self.rotation == Quat::IDENTITY && self.scale == 1.0
    }

    /// The head-local point `local` in this frame, m.
    pub fn point_in_frame(self, local: Vec3) -> Vec3 {
        self.rotation.inverse() * (self.scale * local)
    }

    /// A head's `surface` (head-local), if it has one, in this frame.
    pub fn surface_of(&self, surface: Option<&GroomSurface>) -> Result<Option<GroomSurface>, GroomError> {
        Ok(match surface {
            Some(GroomSurface::Ready(shape)) if !self.is_identity() => {
                Some(GroomSurface::Ready(Arc::new(shape.mapped(|position| self.point_in_frame(position))?)))
            }
            _ => surface.cloned(),
        })
    }

    /// `nodes` grown in this frame (m), given to the head as a [`HairStrand`]'s are: the root in the head's
    /// local space, the shape from it turned onto the head's axes, in metres.
    pub fn nodes_to_head(&self, nodes: &mut [Vec3]) {
        if self.is_identity() {
            return;
        }
        let Some(&root) = nodes.first() else { return };
        let turned_root = self.rotation * root;
        let head_root = turned_root / self.scale;
        for node in nodes {
            *node = head_root + (self.rotation * *node - turned_root);
        }
    }

    /// Hair grown in this frame given to the head: every strand's and follower's nodes
    /// ([`GroomFrame::nodes_to_head`]) and material direction.
    pub fn grown_to_head(&self, grown: &mut [(HairStrand, HairFollowers)]) {
        if self.is_identity() {
            return;
        }
        for (strand, followers) in grown {
            self.nodes_to_head(&mut strand.nodes);
            strand.material_direction = self.rotation * strand.material_direction;
            followers.curves.iter_mut().for_each(|curve| self.nodes_to_head(curve));
        }
    }
}

impl ScalpSurface {
    /// This surface with every vertex moved by `map` (a rotation and a uniform scale keep its triangles and
    /// density).
    pub(crate) fn mapped(&self, map: impl Fn(Vec3) -> Vec3) -> Result<Self, GroomError> {
        let (positions, triangles, density) = self.parts();
        Self::new(positions.iter().map(|&position| map(position)).collect(), triangles.to_vec())?
            .with_density(density.to_vec())
    }
}
