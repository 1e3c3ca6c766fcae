//! Holding hair in its groomed style ([`HairStyleHold`]): springs inside the step that draw each rooted
//! strand's nodes towards their groomed places carried with the head, strongest at the root.

use bevy::math::{DQuat, DVec3};
use bevy::prelude::*;

use crate::rod::Anchor;

use super::{CheckedSettings, HairSettings, HairStyleHold, SimulatedStrand, SteppedElsewhere, StrandForces};

/// Ties each held node to its groomed place `x̄_i` with a critically damped spring (see
/// [`HairStyleHold`]) in its strand's [`StrandForces`], in parallel. Strands stepped elsewhere,
/// quarantined, without a head or not stepped at this fixed step are left alone.
pub(crate) fn hold_style(
    time: Res<Time>,
    settings: Res<HairSettings>,
    checked: Res<CheckedSettings>,
    mut strands: Query<(&SimulatedStrand, &mut StrandForces), Without<SteppedElsewhere>>,
) {
    let hold = settings.style_hold;
    // Invalid settings are reported once, by `check_settings`, and hold the hair until they are fixed.
    if hold.angular_frequency(0.0) <= 0.0 || checked.params.is_none() {
        return;
    }
    let dt = time.delta_secs_f64();
    strands.par_iter_mut().for_each(|(strand, mut forces)| {
        if strand.is_quarantined() || !strand.steps_now() {
            return;
        }
        let (Some(start), Some(end)) = (strand.groomed_pose_motion_at_start(), strand.groomed_pose_motion()) else {
            return;
        };
        let step = dt * f64::from(strand.fixed_steps_in_step());
        hold_strand(&hold, strand, [start, end], step, &mut forces);
    });
}

/// One strand's springs and dampers, its groomed pose carried by the `[start, end]` motions of a step of
/// `dt` seconds.
fn hold_strand(
    hold: &HairStyleHold,
    strand: &SimulatedStrand,
    [(start_rotation, start_translation), (rotation, translation)]: [(DQuat, DVec3); 2],
    dt: f64,
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
        let frequency = hold.angular_frequency(along);
        if frequency <= 0.0 || rod.is_node_prescribed(node) || dt <= 0.0 {
            return Anchor::default();
        }
        let target = rotation * groomed[node] + translation;
        let start = start_rotation * groomed[node] + start_translation;
        Anchor {
            target,
            target_velocity: (target - start) / dt,
            stiffness: frequency * frequency,
            damping: 2.0 * frequency,
        }
    });
}
