//! What bevy_hair_sim's tests, examples and benchmarks share (a crate of the workspace, never published):
//!
//! - rods and meshes for the mechanics tests (this module),
//! - [`headless`] apps stepped one fixed step per update, and the [`logs`] they write,
//! - [`renderer`]: tests that start Bevy's renderer take turns,
//! - [`example_scene`]: the example's head and body, [`bench_scene`]: the benchmark's heads,
//! - [`counting_allocator`]: the system allocator, counting, for the allocation checks and the benchmark.

use bevy::math::DVec3;
use bevy_hair_sim::rod::{Rod, RodMaterial, RodWorkspace, StepParams};

/// `edges + 1` evenly spaced nodes from the origin along `direction`, `length` m long.
pub fn straight_nodes(length: f64, edges: usize, direction: DVec3) -> Vec<DVec3> {
    (0..=edges).map(|i| direction * (length * i as f64 / edges as f64)).collect()
}

/// The thick stiff test rod: r = 1 mm, E = 10 GPa, ρ = 1000 kg/m³, ν = 0.5.
pub fn stiff_rod_material() -> RodMaterial {
    RodMaterial::round(1e-3, 1e10, 0.5, 1000.0)
}

/// Steps `rod` `steps` times, panicking with the step's error if one fails.
pub fn run(rod: &mut Rod, params: &StepParams, steps: usize, workspace: &mut RodWorkspace) {
    for step in 0..steps {
        if let Err(error) = rod.step(params, None, workspace) {
            panic!("step {step} failed: {error}");
        }
    }
}

/// A 20 cm human hair in 16 edges hanging from a clamped root.
pub fn hanging_hair() -> Rod {
    let mut rod = Rod::new(&straight_nodes(0.2, 16, DVec3::NEG_Y), DVec3::X, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    rod
}

/// Largest node speed, m/s.
pub fn max_speed(rod: &Rod) -> f64 {
    rod.velocities().iter().map(|v| v.length()).fold(0.0, f64::max)
}

pub mod bench_scene;
pub mod counting_allocator;
pub mod example_scene;
pub mod headless;
pub mod logs;
pub mod renderer;

/// The top 100° of a sphere of `radius` m about `centre` as a triangle list: `rings + 1` rings of
/// `segments` vertices from the crown down (vertex `ring · segments + segment`), each quad between them two
/// triangles anticlockwise seen from outside.
pub fn sphere_cap(centre: bevy::math::Vec3, radius: f32, rings: u32, segments: u32) -> bevy::prelude::Mesh {
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::{Indices, PrimitiveTopology};
    let mut positions = Vec::new();
    for ring in 0..=rings {
        let polar = 100f32.to_radians() * ring as f32 / rings as f32;
        for segment in 0..segments {
            let azimuth = std::f32::consts::TAU * segment as f32 / segments as f32;
            let direction =
                bevy::math::Vec3::new(polar.sin() * azimuth.cos(), polar.cos(), polar.sin() * azimuth.sin());
            positions.push(centre + radius * direction);
        }
    }
    let at = |ring: u32, segment: u32| ring * segments + segment % segments;
    let mut indices = Vec::new();
    for ring in 0..rings {
        for segment in 0..segments {
            let (a, b, c, d) =
                (at(ring, segment), at(ring, segment + 1), at(ring + 1, segment), at(ring + 1, segment + 1));
            indices.extend([a, b, d, a, d, c]);
        }
    }
    bevy::prelude::Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
        .with_inserted_attribute(bevy::prelude::Mesh::ATTRIBUTE_POSITION, positions)
        .with_inserted_indices(Indices::U32(indices))
}

/// A closed mesh star-shaped around the origin: a UV sphere of `rings` rings and `2 rings` segments whose
/// vertex in direction `d` lies `radius(d)` m out, as positions and triangles (anticlockwise seen from
/// outside), the poles on ±Y.
pub fn star_shaped(radius: impl Fn(DVec3) -> f64, rings: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let segments = 2 * rings;
    let mut positions = vec![DVec3::Y * radius(DVec3::Y)];
    for ring in 1..rings {
        let polar = std::f64::consts::PI * f64::from(ring) / f64::from(rings);
        for segment in 0..segments {
            let azimuth = std::f64::consts::TAU * f64::from(segment) / f64::from(segments);
            let direction = DVec3::new(polar.sin() * azimuth.cos(), polar.cos(), polar.sin() * azimuth.sin());
            positions.push(direction * radius(direction));
        }
    }
    positions.push(DVec3::NEG_Y * radius(DVec3::NEG_Y));
    let bottom = positions.len() as u32 - 1;
    let at = |ring: u32, segment: u32| 1 + (ring - 1) * segments + segment % segments;
    let mut triangles = Vec::new();
    for segment in 0..segments {
        triangles.push([0, at(1, segment + 1), at(1, segment)]);
        triangles.push([bottom, at(rings - 1, segment), at(rings - 1, segment + 1)]);
        for ring in 1..rings - 1 {
            let (a, b, c, d) =
                (at(ring, segment), at(ring, segment + 1), at(ring + 1, segment), at(ring + 1, segment + 1));
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    (positions, triangles)
}
