//! Wind: the air's velocity around the hair, against which the air drag of
//! [`HairSettings::air_damping`](crate::simulation::HairSettings::air_damping) acts. A global [`HairWind`] (a mean wind with gusts and turbulence) and
//! local [`HairWindSource`]s (a fan, a hair dryer) add up; [`HairWindPlugin`] writes their sum at every
//! node of every strand into [`StrandForces`] in [`HairSystems::ExternalForces`], where your own air
//! fields can add theirs.
//!
//! Everything is a smooth, deterministic function of position and simulated time: the same seed gives
//! the same wind, bit for bit, and with no wind (the default) nothing is computed at all.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! fn breeze(mut commands: Commands) {
//!     // 2 m/s from the left, gusting by up to ±1 m/s every 3 s, with 0.5 m/s eddies of 30 cm.
//!     commands.insert_resource(HairWind {
//!         velocity: Vec3::new(2.0, 0.0, 0.0),
//!         gusts: 1.0,
//!         turbulence: 0.5,
//!         ..default()
//!     });
//!     // A hair dryer 40 cm in front of the face, blowing towards it (along its local −Z).
//!     commands.spawn((
//!         HairWindSource { speed: 6.0, radius: 0.04, range: 1.0 },
//!         Transform::from_xyz(0.0, 1.6, 0.4).looking_at(Vec3::new(0.0, 1.6, 0.0), Vec3::Y),
//!     ));
//! }
//! # let mut app = App::new();
//! # app.add_systems(Startup, breeze);
//! ```
//!
//! Reading the wind field directly:
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! let mut app = App::new();
//! app.add_plugins((MinimalPlugins, HairPlugins::default()))
//!     // 3 m/s from −X, gusting by ±1 m/s, with 0.5 m/s eddies of 30 cm.
//!     .insert_resource(HairWind { velocity: Vec3::new(3.0, 0.0, 0.0), gusts: 1.0, turbulence: 0.5, ..default() });
//! let wind = app.world().resource::<HairWind>();
//! assert!(wind.velocity_at(Vec3::new(0.0, 1.6, 0.0), 2.0).x > 1.0);
//! ```

use std::f64::consts::TAU;

use bevy::ecs::entity::EntityHashMap;
use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::math::DVec3;
use bevy::prelude::*;

use crate::rod::{AirJet, AirMode, AirSnapshot};
use crate::schedule::HairSystems;
use crate::simulation::{SimulatedStrand, SteppedElsewhere, StrandForces, StrandNodes};

/// Sinusoidal modes summed for the turbulence (Kraichnan 1970): enough for a field without visible
/// repetition, few enough to stay cheap.
pub const TURBULENCE_MODES: usize = 8;

/// Along a strand the turbulence is evaluated at nodes this fraction of [`HairWind::turbulence_scale`]
/// apart (and at the tip), and interpolated linearly between: eddies are tens of centimetres, edges
/// about one, and a sinusoid sampled four times per wavelength is interpolated within 15 % of its
/// amplitude (still smooth in time, where it matters for the motion).
pub const TURBULENCE_SAMPLE_SPACING: f32 = 0.25;

/// The fastest air a wind or wind source may blow, m/s (three times a record gust): beyond it the air is
/// not wind, and sums of such speeds would overflow the drag.
pub const MAX_WIND_SPEED: f32 = 1000.0;

/// The global wind, the same for every head (a resource; insert it, or edit it at run time).
///
/// The air's velocity at point `x` and time `t` is `u = (|U| + g(t)) Û + u'(x − U t, t)`:
/// - `U` = [`HairWind::velocity`], the mean wind;
/// - `g(t)`, gusts: smooth noise in `[−gusts, gusts]` (m/s) along the mean wind's direction, changing on
///   the scale of [`HairWind::gust_period`] (no gusts without a mean wind);
/// - `u'`, turbulence: a divergence-free sum of [`TURBULENCE_MODES`] random Fourier modes (Kraichnan
///   1970) with eddies of about [`HairWind::turbulence_scale`], RMS [`HairWind::turbulence`] per
///   component (on average over directions: a few modes are not quite isotropic), evolving over [`HairWind::turbulence_period`] and carried along by the
///   mean wind (frozen turbulence).
///
/// Random choices come from [`HairWind::seed`]: the same seed gives the same wind, bit for bit.
#[derive(Resource, Reflect, Debug, Clone, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairWind {
    /// Mean wind velocity `U`, m/s: direction and speed. Default zero (still air).
    pub velocity: Vec3,
    /// Gust amplitude, m/s: the mean wind's speed varies smoothly within `±gusts`. Default 0.
    pub gusts: f32,
    /// Time scale of the gusts, s: about how long one gust lasts. Default 3.
    pub gust_period: f32,
    /// Turbulence, m/s: the RMS of the eddies' velocity per component (their RMS speed is √3 times it).
    /// Default 0.
    pub turbulence: f32,
    /// Size of the eddies, m (their wavelength). Default 0.3.
    pub turbulence_scale: f32,
    /// Time scale over which the eddies change as they are carried along, s. Default 2.
    pub turbulence_period: f32,
    /// Seed of the gusts' and eddies' random choices. Default 0.
    pub seed: u64,
}

impl Default for HairWind {
    fn default() -> Self {
        Self {
            velocity: Vec3::ZERO,
            gusts: 0.0,
            gust_period: 3.0,
            turbulence: 0.0,
            turbulence_scale: 0.3,
            turbulence_period: 2.0,
            seed: 0,
        }
    }
}

impl HairWind {
    /// Whether this wind moves any air (a zero wind adds nothing, not even zeros).
    pub fn is_calm(&self) -> bool {
        self.velocity == Vec3::ZERO && self.turbulence == 0.0
    }

    /// Checks that every parameter is finite and in its range (speeds and amplitudes from 0 to
    /// [`MAX_WIND_SPEED`], scales and periods positive); says which is not.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.velocity.is_finite() && self.velocity.length() <= MAX_WIND_SPEED) {
            return Err(format!(
                "HairWind::velocity {} is not finite or faster than {MAX_WIND_SPEED} m/s",
                self.velocity
            ));
        }
        for (name, value) in [("gusts", self.gusts), ("turbulence", self.turbulence)] {
            if !(0.0..=MAX_WIND_SPEED).contains(&value) {
                return Err(format!("HairWind::{name} {value} must be from 0 to {MAX_WIND_SPEED} m/s"));
            }
        }
        for (name, value) in [
            ("gust_period", self.gust_period),
            ("turbulence_scale", self.turbulence_scale),
            ("turbulence_period", self.turbulence_period),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("HairWind::{name} {value} must be finite and positive"));
            }
        }
        Ok(())
    }

    /// The air's velocity at `position` (m) and simulated time `time` (s), m/s (see [`HairWind`]).
    pub fn velocity_at(&self, position: Vec3, time: f64) -> Vec3 {
        self.field().velocity_at(position.as_dvec3(), time).as_vec3()
    }

    /// This wind and `sources` (each with its transform) at simulated time `time` (s), into `snapshot`
    /// (its lists reused): what [`AirSnapshot::velocity_at`] evaluates, equal to
    /// [`HairWind::velocity_at`] plus each source's [`HairWindSource::velocity_at`]. Invalid sources are
    /// the caller's to leave out.
    pub fn snapshot_into<'a>(
        &self,
        time: f64,
        sources: impl IntoIterator<Item = (&'a HairWindSource, &'a GlobalTransform)>,
        snapshot: &mut AirSnapshot,
    ) {
        let field = self.field();
        snapshot.uniform = field.uniform_at(time);
        snapshot.modes.clear();
        if field.turbulent {
            snapshot.modes.extend(field.modes.iter().map(|mode| AirMode {
                wave_vector: mode.wave_vector,
                amplitude: mode.amplitude,
                phase: (mode.phase + mode.frequency * time - mode.wave_vector.dot(field.mean) * time).rem_euclid(TAU),
            }));
        }
        snapshot.jets.clear();
        snapshot.jets.extend(
            sources
                .into_iter()
                .filter(|(source, _)| source.speed != 0.0)
                .map(|(source, transform)| source.jet(transform)),
        );
    }

    /// The wind at one time, ready to evaluate at many points.
    fn field(&self) -> WindField {
        let mean = self.velocity.as_dvec3();
        let mut random = SplitMix64(self.seed);
        let mut modes = [TurbulenceMode::default(); TURBULENCE_MODES];
        if self.turbulence > 0.0 {
            // Each mode's amplitude is a unit vector across its wave vector: the mean square speed over
            // space and time is then N/2, so this factor makes it 3 turbulence².
            let amplitude = f64::from(self.turbulence) * (6.0 / TURBULENCE_MODES as f64).sqrt();
            let wavenumber = TAU / f64::from(self.turbulence_scale);
            let frequency = TAU / f64::from(self.turbulence_period);
            for mode in &mut modes {
                let direction = random.unit_vector();
                let across = direction.any_orthonormal_pair();
                let angle = TAU * random.unit();
                mode.wave_vector = direction * wavenumber * (0.5 + random.unit());
                mode.amplitude = amplitude * (across.0 * angle.cos() + across.1 * angle.sin());
                mode.frequency = frequency * (0.5 + random.unit());
                mode.phase = TAU * random.unit();
            }
        }
        WindField {
            mean,
            gusts: f64::from(self.gusts),
            gust_period: f64::from(self.gust_period),
            gust_seed: random.next(),
            modes,
            turbulent: self.turbulence > 0.0,
        }
    }
}

/// A local wind source, such as a fan or a hair dryer: a round jet blowing along the entity's forward
/// direction (local −Z) from its position. At distance `d` along the axis and `r` from it the air moves
/// along the axis at `speed · (1 − d/range)² · exp(−(r/w)²)`, with the jet's width `w = radius + d/10`
/// (a free jet spreads by about a tenth of the distance); zero behind the source and beyond `range`.
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Component, Debug, Clone, PartialEq)]
#[require(Transform)]
pub struct HairWindSource {
    /// Air speed at the source's mouth, m/s.
    pub speed: f32,
    /// Radius of the mouth, m.
    pub radius: f32,
    /// Distance along the axis where the jet has died down, m.
    pub range: f32,
}

impl HairWindSource {
    /// Checks that the speed is at most [`MAX_WIND_SPEED`] either way and the radius and range positive
    /// and finite; says which is not.
    pub fn validate(&self) -> Result<(), String> {
        if !(-MAX_WIND_SPEED..=MAX_WIND_SPEED).contains(&self.speed) {
            return Err(format!("its speed {} m/s is not finite or beyond ±{MAX_WIND_SPEED} m/s", self.speed));
        }
        for (name, value) in [("radius", self.radius), ("range", self.range)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("its {name} {value} m must be positive and finite"));
            }
        }
        Ok(())
    }

    /// This source's jet where `transform` puts it: from its position along its forward direction (local
    /// −Z).
    pub fn jet(&self, transform: &GlobalTransform) -> AirJet {
        AirJet {
            origin: transform.translation().as_dvec3(),
            axis: transform.forward().as_vec3().as_dvec3(),
            speed: f64::from(self.speed),
            radius: f64::from(self.radius),
            range: f64::from(self.range),
        }
    }

    /// The air's velocity at `position` (m) from this source placed at `transform`, m/s.
    pub fn velocity_at(&self, transform: &GlobalTransform, position: Vec3) -> Vec3 {
        self.jet(transform).velocity_at(position.as_dvec3()).as_vec3()
    }
}

/// One random Fourier mode of the turbulence: `a cos(k·x + ω t + φ)` with `a ⟂ k`.
#[derive(Debug, Clone, Copy, Default)]
struct TurbulenceMode {
    wave_vector: DVec3,
    amplitude: DVec3,
    frequency: f64,
    phase: f64,
}

/// [`HairWind`] prepared for evaluation.
#[derive(Debug, Clone)]
struct WindField {
    mean: DVec3,
    gusts: f64,
    gust_period: f64,
    gust_seed: u64,
    modes: [TurbulenceMode; TURBULENCE_MODES],
    turbulent: bool,
}

impl WindField {
    /// The mean wind with its gust at `time`, m/s: the same everywhere.
    fn uniform_at(&self, time: f64) -> DVec3 {
        if self.gusts == 0.0 || self.mean == DVec3::ZERO {
            return self.mean;
        }
        let speed = self.mean.length() + self.gusts * smooth_noise(self.gust_seed, time / self.gust_period);
        speed * self.mean.normalize()
    }

    /// The turbulence at `position` and `time`, m/s, carried along by the mean wind.
    fn turbulence_at(&self, position: DVec3, time: f64) -> DVec3 {
        if !self.turbulent {
            return DVec3::ZERO;
        }
        let carried = position - self.mean * time;
        self.modes
            .iter()
            .map(|mode| mode.amplitude * (mode.wave_vector.dot(carried) + mode.frequency * time + mode.phase).cos())
            .sum()
    }

    fn velocity_at(&self, position: DVec3, time: f64) -> DVec3 {
        self.uniform_at(time) + self.turbulence_at(position, time)
    }
}

/// Smooth noise in [−1, 1] of `x`: random values at the integers (from `seed`), joined by quintic
/// smoothstep (continuous slope and curvature).
fn smooth_noise(seed: u64, x: f64) -> f64 {
    let cell = x.floor();
    let value = |i: f64| 2.0 * SplitMix64(seed ^ (i as i64 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)).unit() - 1.0;
    let t = x - cell;
    let blend = t * t * t * (t * (6.0 * t - 15.0) + 10.0);
    value(cell) + blend * (value(cell + 1.0) - value(cell))
}

/// SplitMix64 (Steele, Lea, Flood 2014): a tiny, well-mixed generator, enough for picking the wind's
/// modes deterministically from a seed.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on the unit sphere.
    fn unit_vector(&mut self) -> DVec3 {
        let z = 2.0 * self.unit() - 1.0;
        let angle = TAU * self.unit();
        let ring = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(ring * angle.cos(), ring * angle.sin(), z)
    }
}

/// Adds the wind of [`HairWind`] and every [`HairWindSource`] to the air's velocity at every strand's
/// nodes (in [`StrandForces`]), at their positions at the start of the step and the step's simulated
/// time; in parallel over strands. A calm wind and no sources add nothing. An invalid [`HairWind`], or
/// an invalid [`HairWindSource`] (or one whose transform is not finite), is reported once, by name, and
/// blows no air until it is fixed. Strands [`SteppedElsewhere`] are left out: the GPU samples the air
/// itself (`GpuStrandSolver::set_air`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn add_wind(
    time: Res<Time>,
    wind: Res<HairWind>,
    sources: Query<(Entity, &HairWindSource, &GlobalTransform)>,
    mut strands: Query<(&SimulatedStrand, &StrandNodes, &mut StrandForces), Without<SteppedElsewhere>>,
    mut reported: Local<Option<String>>,
    mut reported_sources: Local<EntityHashMap<String>>,
    mut active_sources: Local<Vec<(HairWindSource, GlobalTransform)>>,
) {
    if let Err(error) = wind.validate() {
        if reported.as_ref() != Some(&error) {
            error!("{error}: the wind is off until it is fixed");
            *reported = Some(error);
        }
        return;
    }
    *reported = None;
    // Reused from step to step, so that no step allocates.
    active_sources.clear();
    for (entity, source, transform) in &sources {
        let affine = transform.affine();
        let checked = source.validate().and_then(|()| {
            let finite = affine.matrix3.is_finite() && affine.translation.is_finite();
            finite.then_some(()).ok_or_else(|| "its transform is not finite".to_string())
        });
        match checked {
            Ok(()) => {
                reported_sources.remove(&entity);
                if source.speed != 0.0 {
                    active_sources.push((*source, *transform));
                }
            }
            Err(reason) if reported_sources.get(&entity) != Some(&reason) => {
                error!("hair wind source {entity} blows no air until it is fixed: {reason}");
                reported_sources.insert(entity, reason);
            }
            Err(_) => {}
        }
    }
    // Sources despawned while reported.
    reported_sources.retain(|entity, _| sources.contains(*entity));
    let sources = &*active_sources;
    if wind.is_calm() && sources.is_empty() {
        return;
    }
    let field = wind.field();
    // The air moves over the step: take it at the step's middle.
    let now = time.elapsed_secs_f64() - 0.5 * time.delta_secs_f64();
    let uniform = field.uniform_at(now);
    strands.par_iter_mut().for_each(|(strand, nodes, mut forces)| {
        let positions = &nodes.positions;
        // A strand not stepped now (a coarser level of detail) would have its forces cleared unused.
        if positions.is_empty() || !strand.steps_now() {
            return;
        }
        let last = positions.len() - 1;
        let edge = positions.get(1).map_or(1.0, |next| next.distance(positions[0]));
        let stride = ((TURBULENCE_SAMPLE_SPACING * wind.turbulence_scale / edge) as usize).clamp(1, last.max(1));
        let turbulence_at = |node: usize| field.turbulence_at(positions[node].as_dvec3(), now);
        let (mut before, mut before_value) = (0, turbulence_at(0));
        let (mut after, mut after_value) = (0, before_value);
        forces.add_air_velocities(|node| {
            let mut velocity = uniform;
            if field.turbulent {
                // Sampled every `stride` nodes and at the tip, interpolated between.
                if node > after {
                    (before, before_value) = (after, after_value);
                    after = (after + stride).min(last);
                    after_value = turbulence_at(after);
                }
                velocity += if after == before {
                    before_value
                } else {
                    before_value.lerp(after_value, (node - before) as f64 / (after - before) as f64)
                };
            }
            for (source, transform) in sources {
                velocity += source.velocity_at(transform, positions[node]).as_dvec3();
            }
            velocity
        });
    });
}

/// Wind for the hair simulation: [`HairWind`] and [`HairWindSource`]s, added to every strand in
/// [`HairSystems::ExternalForces`]. Part of [`crate::HairPlugins`].
#[derive(Debug, Clone)]
pub struct HairWindPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: InternedScheduleLabel,
}

impl Plugin for HairWindPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairWind>()
            .register_type::<HairWindSource>()
            .init_resource::<HairWind>()
            .add_systems(self.schedule, add_wind.in_set(HairSystems::ExternalForces));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_snapshot_blows_what_the_wind_and_its_sources_blow() {
        let wind = HairWind {
            velocity: Vec3::new(2.0, 0.0, -1.0),
            gusts: 1.0,
            turbulence: 0.6,
            turbulence_scale: 0.4,
            seed: 5,
            ..default()
        };
        let fan = HairWindSource { speed: 5.0, radius: 0.05, range: 1.0 };
        let transform =
            GlobalTransform::from(Transform::from_xyz(0.1, 1.6, 0.6).looking_at(Vec3::new(0.0, 1.6, 0.0), Vec3::Y));
        let mut snapshot = AirSnapshot::default();
        // Late in a game (an hour), where the phases would lose digits if they were not wrapped.
        for time in [0.0, 12.34, 3600.5] {
            wind.snapshot_into(time, [(&fan, &transform)], &mut snapshot);
            assert_eq!(snapshot.modes.len(), TURBULENCE_MODES);
            for point in [Vec3::new(0.0, 1.6, 0.0), Vec3::new(0.05, 1.5, 0.3), Vec3::new(-0.2, 1.8, 0.1)] {
                let expected =
                    wind.field().velocity_at(point.as_dvec3(), time) + fan.velocity_at(&transform, point).as_dvec3();
                let got = snapshot.velocity_at(point.as_dvec3());
                // `HairWindSource::velocity_at` rounds the fan's air to `f32`; the modes' phases are
                // wrapped to [0, 2π), exact to `f64` rounding of `ω t` (1e-12 rad an hour in).
                assert!(got.distance(expected) < 1e-6, "at {point}, t = {time}: {got} against {expected}");
            }
        }
        // A still wind and no source: nothing moves.
        HairWind::default().snapshot_into(1.0, [], &mut snapshot);
        assert!(snapshot.is_still() && snapshot.velocity_at(DVec3::ONE) == DVec3::ZERO);
    }

    #[test]
    fn calm_wind_is_zero_everywhere() {
        let wind = HairWind::default();
        assert!(wind.is_calm());
        assert_eq!(wind.velocity_at(Vec3::new(0.3, 1.2, -0.4), 12.5), Vec3::ZERO);
    }

    #[test]
    fn turbulence_has_the_asked_rms_and_no_divergence() {
        let wind = HairWind { turbulence: 0.8, turbulence_scale: 0.5, seed: 7, ..default() };
        let field = wind.field();
        // RMS over a large cube of space and a stretch of time: √3 × 0.8 in all.
        let mut squares = 0.0;
        let samples = 20_000;
        let mut random = SplitMix64(99);
        for _ in 0..samples {
            let point = DVec3::new(random.unit(), random.unit(), random.unit()) * 20.0;
            squares += field.turbulence_at(point, 50.0 * random.unit()).length_squared();
        }
        let rms = (squares / samples as f64 / 3.0).sqrt();
        assert!((rms / 0.8 - 1.0).abs() < 0.05, "RMS per component {rms} (asked 0.8)");
        // Divergence by central differences: each mode is transverse, so it vanishes.
        let (point, step) = (DVec3::new(0.1, 1.5, -0.2), 1e-5);
        let derivative = |axis: DVec3| {
            (field.turbulence_at(point + step * axis, 3.0) - field.turbulence_at(point - step * axis, 3.0))
                / (2.0 * step)
        };
        let divergence = derivative(DVec3::X).x + derivative(DVec3::Y).y + derivative(DVec3::Z).z;
        let gradient_scale = derivative(DVec3::X).length() + derivative(DVec3::Y).length();
        assert!(divergence.abs() < 1e-6 * gradient_scale, "∇·u = {divergence} (gradients {gradient_scale})");
    }

    #[test]
    fn gusts_stay_within_their_amplitude_along_the_wind() {
        let wind = HairWind { velocity: Vec3::new(0.0, 0.0, -3.0), gusts: 1.5, gust_period: 2.0, seed: 3, ..default() };
        let speeds: Vec<f32> = (0..600).map(|i| wind.velocity_at(Vec3::ZERO, 0.05 * i as f64).length()).collect();
        let (low, high) = speeds.iter().fold((f32::MAX, f32::MIN), |(l, h), &s| (l.min(s), h.max(s)));
        assert!(low >= 1.5 - 1e-4 && high <= 4.5 + 1e-4, "speeds {low}..{high}");
        assert!(high - low > 1.0, "gusts vary the speed: {low}..{high}");
        // Smooth: no jump between samples 50 ms apart bigger than the amplitude's share of the period.
        let largest_jump = speeds.windows(2).map(|pair| (pair[1] - pair[0]).abs()).fold(0.0, f32::max);
        assert!(largest_jump < 0.15, "largest change in 50 ms: {largest_jump} m/s");
        let direction = wind.velocity_at(Vec3::ZERO, 1.234).normalize();
        assert!(direction.distance(Vec3::NEG_Z) < 1e-6, "along the mean wind: {direction}");
    }

    #[test]
    fn a_fan_blows_along_its_axis_and_dies_down() {
        let fan = HairWindSource { speed: 5.0, radius: 0.05, range: 1.0 };
        let transform = GlobalTransform::from(Transform::from_xyz(0.0, 0.0, 1.0).looking_at(Vec3::ZERO, Vec3::Y));
        let at_mouth = fan.velocity_at(&transform, Vec3::new(0.0, 0.0, 0.999));
        assert!((at_mouth - Vec3::new(0.0, 0.0, -5.0)).length() < 0.05, "{at_mouth}");
        let halfway = fan.velocity_at(&transform, Vec3::new(0.0, 0.0, 0.5));
        assert!((halfway.z + 5.0 * 0.25).abs() < 1e-5, "(1 − ½)² of the speed: {halfway}");
        assert_eq!(fan.velocity_at(&transform, Vec3::new(0.0, 0.0, 1.5)), Vec3::ZERO, "behind the fan");
        assert_eq!(fan.velocity_at(&transform, Vec3::new(0.0, 0.0, -0.1)), Vec3::ZERO, "beyond its range");
        // Half a metre out the jet is 0.05 + 0.05 m wide: 10 cm off its axis the speed is e⁻¹ of the axis'.
        let aside = fan.velocity_at(&transform, Vec3::new(0.1, 0.0, 0.5)).length();
        assert!((aside / halfway.length() - (-1.0f32).exp()).abs() < 1e-5, "off the axis: {aside}");
    }
}
