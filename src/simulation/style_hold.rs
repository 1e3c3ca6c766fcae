//! Holding hair in its groomed style ([`HairStyleHold`]): springs inside the step that draw each rooted
//! strand's nodes towards their groomed places carried with the head, strongest at the root.

use bevy::prelude::*;

use crate::rod::Anchor;

use super::{CheckedSettings, HairSettings, HairStyleHold, SimulatedStrand, SteppedElsewhere, StrandForces};

/// Ties each held node to its groomed place `x̄_i` with a spring of stiffness `m_i k_i` (see
/// [`HairStyleHold`]) in its strand's [`StrandForces`], in parallel. Strands stepped elsewhere, quarantined, without a head or not
/// stepped at this fixed step are left alone.
pub(crate) fn hold_style(
    settings: Res<HairSettings>,
    checked: Res<CheckedSettings>,
    mut strands: Query<(&SimulatedStrand, &mut StrandForces), Without<SteppedElsewhere>>,
) {
    let hold = settings.style_hold;
    // Invalid settings are reported once, by `check_settings`, and hold the hair until they are fixed.
    if hold.stiffness(0.0) <= 0.0 || checked.params.is_none() {
        return;
    }
    strands.par_iter_mut().for_each(|(strand, mut forces)| {
        if strand.is_quarantined() || !strand.steps_now() {
            return;
        }
        let Some((rotation, translation)) = strand.groomed_pose_motion() else { return };
        hold_strand(&hold, strand, (rotation, translation), &mut forces);
    });
}

/// One strand's springs, its groomed pose carried by `motion`.
fn hold_strand(
    hold: &HairStyleHold,
    strand: &SimulatedStrand,
    (rotation, translation): (bevy::math::DQuat, bevy::math::DVec3),
    forces: &mut StrandForces,
) {
    let rod = strand.rod();
    let length = rod.rest_length();
    let groomed = rod.initial_positions();
    // Arc length from the root to each node, as a fraction of the strand's length.
    let mut along = 0.0;
    let lengths = rod.rest_lengths();
    forces.set_anchors(|node| {
        if node > 0 {
            along += lengths[node - 1] / length;
        }
        let stiffness = hold.stiffness(along);
        if stiffness <= 0.0 || rod.is_node_prescribed(node) {
            return Anchor::default();
        }
        Anchor { target: rotation * groomed[node] + translation, stiffness }
    });
}
