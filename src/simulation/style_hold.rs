//! Holding hair in its groomed style ([`HairStyleHold`]): springs inside the step that draw each rooted
//! strand's nodes towards their groomed places carried with the head, strongest at the root. The step
//! writes them per strand just before it steps the strand ([`style_anchors`]), into its thread's scratch,
//! while the strand's memory is in that core's cache.

use crate::rod::Anchor;

use super::{HairStyleHold, SimulatedStrand};

/// Ties each node of `strand` to its groomed place `x̄_i` with a critically damped spring (see
/// [`HairStyleHold`]) for its coming step of `dt` seconds, its groomed pose carried by the head's motion
/// over the step: one [`Anchor`] per node in `anchors`. False, with `anchors` left as they were, for a
/// strand the hold does not reach (no head, or a hold that holds nothing).
pub(crate) fn style_anchors(
    hold: &HairStyleHold,
    strand: &SimulatedStrand,
    dt: f64,
    anchors: &mut Vec<Anchor>,
) -> bool {
    if hold.angular_frequency(0.0) <= 0.0 {
        return false;
    }
    let (Some((start_rotation, start_translation)), Some((rotation, translation))) =
        (strand.groomed_pose_motion_at_start(), strand.groomed_pose_motion())
    else {
        return false;
    };
    let rod = strand.rod();
    let length = rod.rest_length();
    let (groomed, lengths) = (rod.initial_positions(), rod.rest_lengths());
    // Arc length from the root to each node, as a fraction of the strand's length.
    let mut along = 0.0;
    anchors.clear();
    anchors.extend(groomed.iter().enumerate().map(|(node, &place)| {
        if node > 0 {
            along += lengths[node - 1] / length;
        }
        let frequency = hold.angular_frequency(along);
        if frequency <= 0.0 || rod.is_node_prescribed(node) || dt <= 0.0 {
            return Anchor::default();
        }
        let target = rotation * place + translation;
        let start = start_rotation * place + start_translation;
        Anchor {
            target,
            target_velocity: (target - start) / dt,
            stiffness: frequency * frequency,
            damping: 2.0 * frequency,
        }
    }));
    true
}
