//! [`StrandSnapshot`]: save a strand and resume it later exactly.

use bevy::ecs::query::QueryData;
use bevy::prelude::*;

use super::data::{StrandFrames, StrandNodes, StrandRestShape};
use super::strand::SimulatedStrand;

/// Everything a strand's future depends on, copied out: restoring it (inserting it back on the strand,
/// `commands.entity(strand).insert(snapshot)`) makes the strand repeat, bit for bit, the steps that
/// followed the copy, given the same head motion, forces and settings. Take one with
/// [`StrandSnapshot::of`] from a query for [`StrandSnapshotData`].
///
/// A snapshot belongs to the strand it was taken of (its nodes, its head anchor); restoring it into another
/// strand replaces that strand's state with this one.
#[derive(Bundle, Debug, Clone)]
pub struct StrandSnapshot {
    /// The simulated rod and its head anchor, double precision, with the strand's fault record.
    pub strand: SimulatedStrand,
    /// The nodes as drawn.
    pub nodes: StrandNodes,
    /// The frames as read.
    pub frames: StrandFrames,
    /// The rest shape, edits included.
    pub rest_shape: StrandRestShape,
}

/// What [`StrandSnapshot::of`] reads: `Query<StrandSnapshotData>`.
#[derive(QueryData)]
pub struct StrandSnapshotData {
    strand: &'static SimulatedStrand,
    nodes: &'static StrandNodes,
    frames: &'static StrandFrames,
    rest_shape: &'static StrandRestShape,
}

impl StrandSnapshot {
    /// Copies a strand's data out of a `Query<StrandSnapshotData>` item.
    pub fn of(data: StrandSnapshotDataItem) -> Self {
        Self {
            strand: data.strand.clone(),
            nodes: data.nodes.clone(),
            frames: data.frames.clone(),
            rest_shape: data.rest_shape.clone(),
        }
    }
}
