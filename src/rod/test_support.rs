//! Helpers shared by the core's unit tests: a seeded generator and random strands.

use bevy::math::{DVec2, DVec3};

use super::{Rod, RodMaterial};

/// A small seeded generator (PCG-style LCG), so tests are reproducible without a dependency.
pub struct Lcg(pub u64);

impl Lcg {
    /// Uniform in `[-0.5, 0.5)`.
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    /// Uniform vector in the cube `[-0.5, 0.5)³`.
    pub fn vector(&mut self) -> DVec3 {
        DVec3::new(self.next(), self.next(), self.next())
    }
}

/// A random, elliptical, curved strand with random rest curvature, rest twist, twist angles and
/// stretch, so that every energy term and every derivative is exercised away from rest.
pub fn random_strand(random: &mut Lcg, edges: usize) -> Rod {
    let mut nodes = vec![DVec3::ZERO];
    let mut direction = DVec3::X;
    for _ in 0..edges {
        direction = (direction + 0.8 * random.vector()).normalize();
        let length = 0.01 * (1.0 + 0.5 * random.next());
        nodes.push(*nodes.last().unwrap() + length * direction);
    }
    let material = RodMaterial {
        semi_axis_1: 1e-3,
        semi_axis_2: 0.6e-3,
        youngs_modulus: 1e7,
        shear_modulus: 4e6,
        density: 1000.0,
    };
    let mut rod = Rod::new(&nodes, random.vector().cross(direction), material).unwrap();
    for vertex in 1..edges {
        let rest = DVec2::new(random.next(), random.next()) * 0.6;
        rod.set_rest_curvature(vertex, rest).unwrap();
        rod.set_rest_twist(vertex, random.next()).unwrap();
    }
    for edge in 0..edges {
        rod.state.twist[edge] = 2.0 * random.next();
    }
    for node in 0..=edges {
        rod.state.positions[node] += 0.002 * random.vector();
    }
    rod.refresh_frames();
    rod
}
