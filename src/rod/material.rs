//! Material parameters of a rod (SI units) and the stiffnesses derived from them.

use bevy::reflect::{Reflect, std_traits::ReflectDefault};

use super::error::RodError;

/// Elastic and inertial properties of a rod with an elliptical cross-section.
///
/// The cross-section's semi-axis `semi_axis_1` lies along the first material direction `m1`,
/// `semi_axis_2` along `m2`. A round fibre has both equal to its radius.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Debug, Clone, PartialEq, Default)]
pub struct RodMaterial {
    /// Semi-axis of the cross-section along the first material direction `m1`, m.
    pub semi_axis_1: f64,
    /// Semi-axis of the cross-section along the second material direction `m2`, m.
    pub semi_axis_2: f64,
    /// Young's modulus `E`, Pa: resistance to stretching and bending.
    pub youngs_modulus: f64,
    /// Shear modulus `G`, Pa: resistance to twisting.
    pub shear_modulus: f64,
    /// Mass density `ρ`, kg/m³.
    pub density: f64,
}

/// The rod's stiffnesses and inertias per unit length, derived from a [`RodMaterial`].
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub struct Stiffness {
    /// Stretching stiffness `EA`, N.
    pub stretching: f64,
    /// Bending stiffness `EI₁` for curvature `κ₁` (bending towards `m1`), N·m².
    pub bending_1: f64,
    /// Bending stiffness `EI₂` for curvature `κ₂` (bending towards `m2`), N·m².
    pub bending_2: f64,
    /// Twisting stiffness `GJ`, N·m².
    pub twisting: f64,
    /// Mass per unit length `ρA`, kg/m.
    pub linear_density: f64,
    /// Moment of inertia about the axis per unit length `ρ I_p`, kg·m.
    pub twist_inertia_density: f64,
}

/// The range each material parameter must lie in, with its unit: wide enough for anything from a
/// 0.1 µm fibre of jelly to a metre-thick cable ten times stiffer than diamond, narrow enough to keep the
/// step's arithmetic (stiffness over inertia, squared in the factorisation) far from overflow.
pub const MATERIAL_RANGES: [(&str, f64, f64, &str); 5] = [
    ("semi_axis_1", 1e-7, 1.0, "m"),
    ("semi_axis_2", 1e-7, 1.0, "m"),
    ("youngs_modulus", 1e2, 1e13, "Pa"),
    ("shear_modulus", 1e2, 1e13, "Pa"),
    ("density", 1.0, 1e5, "kg/m³"),
];

impl RodMaterial {
    /// A round fibre of `radius` (m), Young's modulus (Pa), Poisson ratio (dimensionless) and density (kg/m³).
    /// The shear modulus is `G = E / (2 (1 + ν))`.
    pub fn round(radius: f64, youngs_modulus: f64, poisson_ratio: f64, density: f64) -> Self {
        Self {
            semi_axis_1: radius,
            semi_axis_2: radius,
            youngs_modulus,
            shear_modulus: youngs_modulus / (2.0 * (1.0 + poisson_ratio)),
            density,
        }
    }

    /// Typical human scalp hair: radius 40 µm, E = 3.5 GPa, Poisson ratio 0.4 (G = 1.25 GPa), ρ = 1300 kg/m³.
    pub fn human_hair() -> Self {
        Self::round(40e-6, 3.5e9, 0.4, 1300.0)
    }

    /// This material with its Young's and shear moduli `factor` times as large (so its bending, twisting
    /// and stretching stiffness), at most to the top of [`MATERIAL_RANGES`]: hair held in a style by a
    /// styling product or bonded into a clump bends as a stiffer fibre of the same weight would.
    pub fn stiffened(&self, factor: f64) -> Self {
        let (youngs_max, shear_max) = (MATERIAL_RANGES[2].2, MATERIAL_RANGES[3].2);
        Self {
            youngs_modulus: (self.youngs_modulus * factor).min(youngs_max),
            shear_modulus: (self.shear_modulus * factor).min(shear_max),
            ..*self
        }
    }

    /// Checks that every parameter is positive and finite.
    pub fn validate(&self) -> Result<(), RodError> {
        let parameters = [
            ("semi_axis_1", self.semi_axis_1),
            ("semi_axis_2", self.semi_axis_2),
            ("youngs_modulus", self.youngs_modulus),
            ("shear_modulus", self.shear_modulus),
            ("density", self.density),
        ];
        for ((parameter, value), (_, low, high, unit)) in parameters.into_iter().zip(MATERIAL_RANGES) {
            if !(low..=high).contains(&value) {
                return Err(RodError::InvalidMaterial { parameter, value, low, high, unit });
            }
        }
        Ok(())
    }

    /// Cross-section area `A = π a b`, m².
    pub fn area(&self) -> f64 {
        std::f64::consts::PI * self.semi_axis_1 * self.semi_axis_2
    }

    /// Stiffnesses of an elliptical section: `EA`, `EI₁ = Eπa³b/4`, `EI₂ = Eπab³/4`,
    /// `GJ = Gπa³b³/(a²+b²)` (Saint-Venant torsion of an ellipse; `Gπr⁴/2` when round).
    pub fn stiffness(&self) -> Stiffness {
        let pi = std::f64::consts::PI;
        let (a, b) = (self.semi_axis_1, self.semi_axis_2);
        let area = self.area();
        Stiffness {
            stretching: self.youngs_modulus * area,
            bending_1: self.youngs_modulus * pi * a.powi(3) * b / 4.0,
            bending_2: self.youngs_modulus * pi * a * b.powi(3) / 4.0,
            twisting: self.shear_modulus * pi * a.powi(3) * b.powi(3) / (a * a + b * b),
            linear_density: self.density * area,
            twist_inertia_density: self.density * pi * a * b * (a * a + b * b) / 4.0,
        }
    }
}

impl Default for RodMaterial {
    /// Human hair, see [`RodMaterial::human_hair`].
    fn default() -> Self {
        Self::human_hair()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_section_matches_textbook_formulas() {
        let material = RodMaterial::round(1e-3, 1e10, 0.5, 1000.0);
        let k = material.stiffness();
        let pi = std::f64::consts::PI;
        let second_moment = pi * 1e-12 / 4.0;
        assert!((k.bending_1 - 1e10 * second_moment).abs() < 1e-12 * k.bending_1);
        assert_eq!(k.bending_1, k.bending_2);
        let shear = 1e10 / 3.0;
        assert!((k.twisting - shear * pi * 1e-12 / 2.0).abs() < 1e-12 * k.twisting);
        assert!((k.linear_density - 1000.0 * pi * 1e-6).abs() < 1e-15);
    }

    #[test]
    fn elliptical_section_is_stiffer_along_its_long_axis() {
        let material = RodMaterial { semi_axis_1: 2e-3, semi_axis_2: 1e-3, ..RodMaterial::round(1e-3, 1e10, 0.3, 1e3) };
        let k = material.stiffness();
        assert!((k.bending_1 / k.bending_2 - 4.0).abs() < 1e-12);
    }

    #[test]
    fn invalid_parameters_are_named() {
        let mut material = RodMaterial::human_hair();
        material.density = -1.0;
        assert_eq!(
            material.validate(),
            Err(RodError::InvalidMaterial { parameter: "density", value: -1.0, low: 1.0, high: 1e5, unit: "kg/m³" })
        );
        material.density = 1300.0;
        material.semi_axis_2 = f64::NAN;
        assert!(matches!(material.validate(), Err(RodError::InvalidMaterial { parameter: "semi_axis_2", .. })));
    }
}
