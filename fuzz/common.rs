//! What every fuzz target checks of a groom file the parser accepted.

use bevy::math::DVec3;
use bevy_hair_sim::groom::{GroomFile, GroomPlacement, UpAxis};
use bevy_hair_sim::rod::{Rod, RodMaterial};

/// The parsed groom is consistent, finite where it must be, no larger than its file justifies, and every
/// strand placed from it is either a rod with a finite state or rejected with an error.
pub fn check_groom(groom: &GroomFile, file_length: usize) {
    let points = groom.points.len();
    assert!(groom.points.iter().all(|point| point.is_finite()), "a non-finite point was accepted");
    assert_eq!(groom.strand_starts.first().copied().unwrap_or(0), 0);
    assert_eq!(groom.strand_starts.last().copied().unwrap_or(0), points);
    assert!(groom.strand_starts.windows(2).all(|pair| pair[0] < pair[1]), "a strand without points");
    for (name, length) in [
        ("thickness", groom.thickness.as_ref().map(Vec::len)),
        ("transparency", groom.transparency.as_ref().map(Vec::len)),
        ("colours", groom.colors.as_ref().map(Vec::len)),
        ("point UVs", groom.point_uvs.as_ref().map(Vec::len)),
    ] {
        assert!(length.is_none_or(|length| length == points), "{name}: {length:?} for {points} points");
    }
    assert!(groom.strand_uvs.as_ref().is_none_or(|uvs| uvs.len() == groom.strand_count()));
    // Memory: every point and strand came from at least 12 bytes of the file (a `.hair` point; a `.tfx`
    // point takes 16), and each point holds at most 12 + 4 + 4 + 12 + 8 bytes of data in memory.
    assert!(points <= file_length / 12 && groom.strand_count() <= file_length / 12 + 1);

    for placement in [
        GroomPlacement { max_strands: 32, ..Default::default() },
        GroomPlacement { metres_per_unit: 0.01, up: UpAxis::Z, segments: 5, max_strands: 32, ..Default::default() },
    ] {
        let placed = groom.placed_strands(&placement, &RodMaterial::human_hair());
        assert!(placed.skipped <= groom.strand_count() && placed.guides.len() <= placement.max_strands);
        assert!(placed.drawn_strands() + placed.skipped == groom.strand_count());
        for (strand, _) in placed.guides {
            assert_eq!(strand.nodes.len(), placement.segments + 1);
            let nodes: Vec<DVec3> = strand.nodes.iter().map(|node| node.as_dvec3()).collect();
            let material = strand.material.unwrap_or_else(RodMaterial::human_hair);
            if let Ok(rod) = Rod::new(&nodes, strand.material_direction.as_dvec3(), material) {
                let frame = rod.material_frame(0);
                assert!(frame.m1.is_finite() && frame.m2.is_finite(), "a rod built with a non-finite frame");
                assert!(rod.positions().iter().all(|p| p.is_finite()));
            }
        }
    }
}
