//! The parameters of a time step, with their units and valid ranges.

use bevy::math::DVec3;
use bevy::reflect::{Reflect, std_traits::ReflectDefault};

use super::error::RodError;

/// The longest time step, s: no game steps slower, and a free rod falling for much longer would leave
/// the range where its node positions keep the edges' lengths to the strain tolerance.
pub const MAX_DT: f64 = 1.0;

/// The largest gravitational acceleration, m/s² (a thousand times the Earth's).
pub const MAX_GRAVITY: f64 = 1e4;

/// How a step integrates the equations of motion in time. Both are implicit, so stable at any step for
/// stiff hair, and both damp the modes a step cannot resolve (`ω·dt ≫ 1`) within a few steps; they
/// differ in what they remove by themselves from the motions you see (numerical damping). An undamped
/// oscillation of angular frequency `ω` stepped at `dt` loses its amplitude at the rate
/// `ζ = −ln|z|/dt` (1/s), `z` the scheme's amplification factor for `y' = iωy`: about `ω²dt/2` for
/// backward Euler and `ω⁴dt³/4` for BDF2 when `ω·dt ≪ 1`. At 60 Hz:
///
/// | motion | backward Euler: amplitude lost per second | BDF2 |
/// |---|---:|---:|
/// | 0.5 Hz swing | 7.9 % | 0.01 % |
/// | 1 Hz | 28 % | 0.2 % |
/// | 2 Hz | 72 % | 2.6 % |
/// | 5 Hz | 99.9 % | 49 % |
///
/// (`tests/mechanics/integrator.rs` measures these rates on a pendulum.) The second-order scheme was chosen by
/// these numbers: a released 30 cm rod with no physical damping keeps 94 % of its energy
/// after 1 s at 60 Hz (backward Euler 27 %), and converges at second order. The trapezoidal rule and
/// Newmark-type schemes with less damping still were tried: with the inextensibility projection they
/// fall back to first order (corrections of positions enter their velocity and acceleration memory),
/// and undamped fast modes ring after every contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub enum Integrator {
    /// Backward (implicit) Euler: first order; damps a mode of frequency `ω` at the rate `ω²dt/2`
    /// (for `ω·dt ≪ 1`), so hair at 60 Hz moves as if in syrup whatever the damping parameters say.
    BackwardEuler,
    /// The second-order backward differentiation formula (BDF2) for the nodes:
    /// `v = (3xₙ₊₁ − 4xₙ + xₙ₋₁)/(2dt)`, and alike for accelerations. Second order, L-stable; damps a
    /// mode at the rate `ω⁴dt³/4`, so the damping you set is the damping you get. It needs the step
    /// before ([`crate::rod::StepHistory`]): the first step after a spawn, reset, failure, positions
    /// written from outside or a change of `dt` is a backward Euler step. The twists, which follow the
    /// centre line quasi-statically, are always stepped by backward Euler.
    #[default]
    Bdf2,
}

/// Parameters of one time step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Time step, s, at most [`MAX_DT`]. Any positive value is stable; 1/60 s is a game's fixed step.
    pub dt: f64,
    /// Gravitational acceleration, m/s², at most [`MAX_GRAVITY`] in size.
    pub gravity: DVec3,
    /// The time integrator. Default [`Integrator::Bdf2`].
    pub integrator: Integrator,
    /// Air drag across the strand `γ`, 1/s: drag per length `f = −ρA γ [P⊥ + r P∥] (v − u)` against the
    /// velocity relative to the air `u`, with `P⊥`, `P∥` the projections across and along the strand and
    /// `r` [`StepParams::axial_drag_ratio`]. A strand moving sideways through still air slows to `1/e`
    /// in `1/γ` seconds. The per-length coefficient `c⊥ = ρAγ` (N·s/m²) of the default 3/s on human hair
    /// is 2e-5 N·s/m², the order of slender-body Stokes drag in air (`4πμ / (ln(2ℓ/d) + ½)` ≈ 4e-5
    /// N·s/m² for centimetre segments); the law is linear in the relative speed, which fits hair in
    /// breezes (Reynolds numbers of a few) better than in gales.
    pub air_damping: f64,
    /// Drag along the strand as a fraction `r` of the drag across it, dimensionless, in [0, 1]: 1 is
    /// drag per mass the same in every direction; slender-body theory gives ½ for a cylinder (Cox 1970).
    pub axial_drag_ratio: f64,
    /// Internal damping `β`, s: stiffness-proportional (Rayleigh) friction `−β H v` inside the material.
    /// An elastic mode of angular frequency `ω` decays at the rate `½ β ω²`. It acts on the motion
    /// relative to the rigid motion of the root clamp, so a strand carried along by its head is not braked.
    pub internal_damping: f64,
    /// Most Newton iterations per step. A step stops after one (linearly implicit Euler) when that
    /// iteration was not limited by [`StepParams::max_rotation`] and its linearisation left no edge more
    /// than [`StepParams::newton_strain_tolerance`] longer than intended; violent motion takes more.
    pub max_newton_iterations: u32,
    /// Edge strain, dimensionless, that a Newton iteration's linearisation may leave (before projection)
    /// for the step to end there: a measure of how far edges turned, since a linear step turning an
    /// edge by `φ` stretches it by about `φ²/2`. The default 0.5 % (turns of about 0.1 rad in one
    /// iteration): at 1 % a released rod kept 90 % of its energy after 1 s with BDF2, at 0.5 % 94 %,
    /// for 3 % more Newton iterations on the benchmark's moving head.
    pub newton_strain_tolerance: f64,
    /// Largest turn of any edge in one Newton iteration, rad: larger updates are scaled down (a trust
    /// region), so a rod released far from equilibrium moves there over several iterations instead of
    /// following a linear extrapolation.
    pub max_rotation: f64,
    /// Relative accuracy, dimensionless, to which the projection restores each edge to the length the
    /// implicit solve gave it to first order. What it leaves acts as a damping of its own: at 1e-6 a
    /// 1 Hz pendulum lost amplitude 40 % faster than backward Euler alone says, and BDF2's swing ten
    /// times faster than BDF2 alone; at the default 1e-8 both are within 2 % and a factor 2.
    pub strain_tolerance: f64,
    /// Largest elastic edge strain, dimensionless, the projection lets stand: stretch from tension
    /// (`T / EA`, about 1e-6 for a hanging hair) is kept up to this, anything beyond is projected away,
    /// so edges never stretch more than this plus `strain_tolerance`.
    pub strain_allowance: f64,
    /// Most projection iterations per Newton iteration (each one converges quadratically). A step whose
    /// projections end above [`StepParams::strain_bound`] takes more (see [`crate::rod::Rod::step_with_contacts`]).
    pub max_projection_iterations: u32,
}

impl Default for StepParams {
    /// 1/60 s, BDF2, Earth gravity along −Y, air damping 3/s (half of it along the strand), internal
    /// damping 1 ms, up to 4 Newton iterations (linearisation strain 0.5 %, turns of 0.25 rad), strain
    /// tolerance 1e-8, strain allowance 5e-4, 16 projection iterations.
    fn default() -> Self {
        Self {
            dt: 1.0 / 60.0,
            integrator: Integrator::Bdf2,
            gravity: DVec3::new(0.0, -9.81, 0.0),
            air_damping: 3.0,
            axial_drag_ratio: 0.5,
            internal_damping: 1e-3,
            max_newton_iterations: 4,
            newton_strain_tolerance: 0.005,
            max_rotation: 0.25,
            strain_tolerance: 1e-8,
            strain_allowance: 5e-4,
            max_projection_iterations: 16,
        }
    }
}

impl StepParams {
    /// Checks that every parameter is in its valid range.
    pub fn validate(&self) -> Result<(), RodError> {
        let invalid =
            |parameter, value, requirement| Err(RodError::InvalidStepParameter { parameter, value, requirement });
        if !(self.dt > 0.0 && self.dt <= MAX_DT) {
            return invalid("dt", self.dt, "must be positive and at most 1 s");
        }
        if !self.gravity.is_finite() || self.gravity.length() > MAX_GRAVITY {
            return invalid("gravity", self.gravity.length(), "must be finite and at most 10 000 m/s² in size");
        }
        for (name, value) in [("air_damping", self.air_damping), ("internal_damping", self.internal_damping)] {
            if !(value.is_finite() && value >= 0.0) {
                return invalid(name, value, "must be zero or positive and finite");
            }
        }
        if !(0.0..=1.0).contains(&self.axial_drag_ratio) {
            return invalid("axial_drag_ratio", self.axial_drag_ratio, "must be between 0 and 1");
        }
        if self.max_newton_iterations == 0 {
            return invalid("max_newton_iterations", 0.0, "must be at least 1");
        }
        for (name, value) in
            [("newton_strain_tolerance", self.newton_strain_tolerance), ("max_rotation", self.max_rotation)]
        {
            if !(value.is_finite() && value > 0.0) {
                return invalid(name, value, "must be positive and finite");
            }
        }
        if !(self.strain_allowance.is_finite() && (0.0..0.5).contains(&self.strain_allowance)) {
            return invalid("strain_allowance", self.strain_allowance, "must be at least 0 and below 0.5");
        }
        if !(self.strain_tolerance.is_finite() && self.strain_tolerance > 0.0) {
            return invalid("strain_tolerance", self.strain_tolerance, "must be positive and finite");
        }
        if self.max_projection_iterations == 0 {
            return invalid("max_projection_iterations", 0.0, "must be at least 1");
        }
        Ok(())
    }

    /// The largest edge strain `| |e|/|ē| − 1 |` a successful step ends with, dimensionless:
    /// `(1 + strain_allowance)(1 + strain_tolerance) − 1`, that is `strain_allowance + strain_tolerance`
    /// and their product (5.00005e-4 by default). A step never returns `Ok` above it.
    pub fn strain_bound(&self) -> f64 {
        (1.0 + self.strain_allowance) * (1.0 + self.strain_tolerance) - 1.0
    }

    /// Whether an edge strain is within [`StepParams::strain_bound`] (NaN is not).
    pub(crate) fn within_strain_bound(&self, strain: f64) -> bool {
        strain <= self.strain_bound()
    }
}
