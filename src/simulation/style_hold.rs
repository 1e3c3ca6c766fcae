//! Holding hair in its groomed style ([`HairStyleHold`]): velocity changes that draw each rooted strand's
//! nodes towards their groomed places carried with the head, strongest at the root.

use bevy::prelude::*;

use super::{CheckedSettings, HairSettings, HairStyleHold, SimulatedStrand, SteppedElsewhere, StrandForces};

/// Adds each held node's velocity change `a_i ((x̄_i − x_i)/Δt − v_i)` (see [`HairStyleHold`]) to its
/// strand's [`StrandForces`], in parallel. Strands stepped elsewhere, quarantined, without a head or not
/// stepped at this fixed step are left alone.
pub(crate) fn hold_style(
    time: Res<Time>,
    settings: Res<HairSettings>,
    checked: Res<CheckedSettings>,
    mut strands: Query<(&SimulatedStrand, &mut StrandForces), Without<SteppedElsewhere>>,
) {
    let hold = settings.style_hold;
    let dt = time.delta_secs_f64();
    // Invalid settings are reported once, by `check_settings`, and hold the hair until they are fixed.
    if hold.share(dt, 0.0) <= 0.0 || checked.params.is_none() {
        return;
    }
    strands.par_iter_mut().for_each(|(strand, mut forces)| {
        if strand.is_quarantined() || !strand.steps_now() {
            return;
        }
        let Some((rotation, translation)) = strand.groomed_pose_motion() else { return };
        hold_strand(&hold, dt, strand, (rotation, translation), &mut forces);
    });
}

/// One strand's velocity changes, its groomed pose carried by `motion`.
fn hold_strand(
    hold: &HairStyleHold,
    dt: f64,
    strand: &SimulatedStrand,
    (rotation, translation): (bevy::math::DQuat, bevy::math::DVec3),
    forces: &mut StrandForces,
) {
    let rod = strand.rod();
    let length = rod.rest_length();
    let (groomed, positions, velocities) = (rod.initial_positions(), rod.positions(), rod.velocities());
    // Arc length from the root to each node, as a fraction of the strand's length.
    let mut along = 0.0;
    let lengths = rod.rest_lengths();
    forces.add_velocity_changes_and_forces(false, |node| {
        if node > 0 {
            along += lengths[node - 1] / length;
        }
        let share = hold.share(dt, along);
        if share <= 0.0 || rod.is_node_prescribed(node) {
            return Default::default();
        }
        let target = rotation * groomed[node] + translation;
        (share * ((target - positions[node]) / dt - velocities[node]), Default::default())
    });
}
