//! The air around a strand at one instant, ready to evaluate at many points: a uniform wind, travelling
//! sinusoidal modes (turbulence) and round jets. What the plugin's wind (`HairWind`) and its sources blow, in
//! a form the CPU and the GPU's step evaluate alike.

use bevy::math::DVec3;

/// The air of a `HairWind` and its `HairWindSource`s at one instant, ready to evaluate at many points:
/// what the GPU's step samples at every node (`GpuStrandSolver::set_air`), and what
/// [`AirSnapshot::velocity_at`] gives on the CPU. Built by `HairWind::snapshot_into`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AirSnapshot {
    /// The mean wind with its gust at that instant, m/s: the same everywhere.
    pub uniform: DVec3,
    /// The turbulence's modes, each `a cos(k·x + φ)` at that instant (none in still air).
    pub modes: Vec<AirMode>,
    /// The wind sources' jets.
    pub jets: Vec<AirJet>,
}

/// One mode of `HairWind`'s turbulence at one instant: the air's velocity `a cos(k·x + φ)` at `x`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AirMode {
    /// The wave vector `k`, rad/m.
    pub wave_vector: DVec3,
    /// The amplitude `a` (across `k`), m/s.
    pub amplitude: DVec3,
    /// The phase `φ` at that instant, rad, in `[0, 2π)`: the mode's own phase and frequency, and the mean
    /// wind's carrying, `φ₀ + ω t − k·U t`.
    pub phase: f64,
}

/// A `HairWindSource` where it is: a round jet from `origin` along `axis` (see `HairWindSource`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AirJet {
    /// Where the jet starts, m.
    pub origin: DVec3,
    /// The unit direction it blows along.
    pub axis: DVec3,
    /// `HairWindSource::speed`, m/s.
    pub speed: f64,
    /// `HairWindSource::radius`, m.
    pub radius: f64,
    /// `HairWindSource::range`, m.
    pub range: f64,
}

impl AirJet {
    /// The jet's air velocity at `position`, m/s (`HairWindSource::velocity_at`).
    pub fn velocity_at(&self, position: DVec3) -> DVec3 {
        let offset = position - self.origin;
        let along = offset.dot(self.axis);
        if !(along >= 0.0 && along < self.range) || self.radius <= 0.0 {
            return DVec3::ZERO;
        }
        let across = (offset - along * self.axis).length();
        let width = self.radius + 0.1 * along;
        let decay = (1.0 - along / self.range).powi(2);
        self.speed * decay * (-(across / width).powi(2)).exp() * self.axis
    }
}

impl AirSnapshot {
    /// Whether no air moves anywhere.
    pub fn is_still(&self) -> bool {
        self.uniform == DVec3::ZERO && self.modes.is_empty() && self.jets.is_empty()
    }

    /// The air's velocity at `position` (m), m/s: the uniform wind, every turbulence mode and every jet.
    pub fn velocity_at(&self, position: DVec3) -> DVec3 {
        let turbulence: DVec3 =
            self.modes.iter().map(|mode| mode.amplitude * (mode.wave_vector.dot(position) + mode.phase).cos()).sum();
        let jets: DVec3 = self.jets.iter().map(|jet| jet.velocity_at(position)).sum();
        self.uniform + turbulence + jets
    }
}
