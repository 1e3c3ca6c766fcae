//! Levels of detail: crowds of heads at a game's budget. Each head's hair is stepped at a rate chosen from
//! its distance to the nearest camera and whether any camera sees it; hair far away is stepped every
//! second or fourth step, hair out of sight or very far is carried with its head without being simulated.
//!
//! **Scheme.**
//! - A head at level [`HairDetailLevel::Stepped`]`(n)` has its strands stepped on every `n`-th fixed step,
//!   with a step of `n · dt`: the same implicit scheme, stable at any step, at `1/n` of the cost. Its
//!   strands take their turns on different fixed steps (a quarter of them on each, at every fourth step),
//!   so every fixed step costs about the same: no spike every `n`-th step.
//! - Between two of its steps the hair is **drawn from its head's frame**: the nodes are kept in the
//!   head's (rigid) local space and carried with the head every fixed step, so the roots stay on the
//!   head however fast it moves. The drawn shape is interpolated between the shapes of the strand's last
//!   steps (keyframes), at a drawn clock that runs `n − 1` fixed steps behind: never extrapolated, and
//!   smooth relative to the head.
//! - At [`HairDetailLevel::Carried`] a head's hair is not simulated at all: it keeps its shape in its head's
//!   frame and follows the head rigidly. When the head comes back, its strands are carried rigidly to
//!   where the head is and simulated from there.
//! - **No pops.** When the level changes, the drawn clock runs at most [`DRAWN_CLOCK_RATE_CHANGE`] (25 %)
//!   faster or slower than the fixed steps until it has its new lag, so the drawn hair never moves more
//!   than 25 % faster than the hair itself; the simulation never jumps either (a longer or shorter step
//!   starts from where the hair is).
//! - **The hair–hair grid** ([`crate::volume`]) is sampled by the strands stepped at each fixed step, each
//!   standing for the hairs of the `n` fixed steps its step spans, and smoothed over as long: the head's
//!   hair is as dense on the grid as at full detail, at `1/n` of the splat's cost.
//! - **What is lost at a coarser level:** motion faster than the longer step resolves (the implicit step
//!   damps it, as at a lower frame rate; a longer step also takes one Newton iteration and projects the
//!   edge lengths to 1e-6 instead of 1e-8, which damps a little more), the grid's detail (a quarter of the
//!   strands at a time at every fourth step), and up to `n − 1` fixed
//!   steps of delay in the hair's motion relative to its head. Going coarser, the hair's motion relative
//!   to its head slows by a quarter for `4 (n − 1)` fixed steps while the drawn clock falls behind, the
//!   strand meanwhile stepped every fixed step (so that its drawn shape always has a keyframe ahead).
//! - **Coming back from being carried** the hair starts with its head's motion (each node the velocity
//!   of the head's rigid motion over the last fixed step), not with the velocities it had when it was
//!   set aside.
//!
//! **Choice.** [`HairDetailSettings`] say at which distances the levels change (with a margin against
//! flickering between two levels); a head's [`HairDetail`] shows the level in use and can fix one.
//! Distances are to the nearest active [`Camera`]; a head is out of sight when no active camera's
//! [`Frustum`] reaches a ball around it as large as its hair. Without any camera (a server, a test),
//! every head is at full detail.
//!
//! **A CPU budget.** [`HairCpuBudget`] (off by default) says how many milliseconds of each fixed step the
//! hair may take on the CPU; the plugin measures every update ([`HairStatistics::update_seconds`]) and
//! steps every head at least every `n`-th fixed step, `n` chosen to keep it
//! ([`HairStatistics::budget_step_interval`]). What it costs and what it changes on the example's head is
//! in `docs/performance.md`.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! fn crowd_settings(mut commands: Commands, extras: Query<Entity, (With<HairHead>, Without<Camera>)>) {
//!     // Full detail within 5 m, every second step to 10 m, every fourth beyond, carried past 40 m or
//!     // out of sight.
//!     commands.insert_resource(HairDetailSettings {
//!         full_detail_distance: 5.0,
//!         carried_distance: 40.0,
//!         ..default()
//!     });
//!     // Background characters: always at every fourth step, whatever the camera does.
//!     for head in &extras {
//!         commands.entity(head).insert(HairDetail::fixed(HairDetailLevel::Stepped(4)));
//!     }
//! }
//! // A game whose hair may take 4 ms of each fixed step on the CPU.
//! # let mut app = App::new();
//! app.insert_resource(HairCpuBudget::milliseconds(4.0));
//! assert_eq!(HairDetailSettings::default().level_at(7.0, true), HairDetailLevel::Stepped(4));
//! assert_eq!(HairDetailSettings::default().level_at(1.0, false), HairDetailLevel::Carried);
//! ```

mod budget;

use bevy::camera::primitives::{Frustum, Sphere};
use bevy::prelude::*;

pub use budget::HairCpuBudget;
use budget::{BudgetKeeper, keep_cpu_budget, start_update_clock};

use crate::rod::RodError;
use crate::schedule::{HairPinSystems, HairPrepareSystems, HairStepSystems, HairSystems};
pub use crate::simulation::{DRAWN_CLOCK_RATE_CHANGE, HairDetailLevel, HeadsByDetail, LONGER_STEP_STRAIN_TOLERANCE};
use crate::simulation::{HairHead, HairStatistics, HeadMotion, HeadStrands, SimulatedStrand, StrandOf};

/// Put on every [`HairHead`] by the [`HairDetailPlugin`]: the level of detail its hair is
/// simulated at, and what it was chosen from. Set [`HairDetail::fixed`] to choose the level yourself.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct HairDetail {
    /// A level to keep whatever the distance (`None`, the default: chosen from [`HairDetailSettings`]).
    pub fixed: Option<HairDetailLevel>,
    level: HairDetailLevel,
    distance: f32,
    on_screen: bool,
    reach: f32,
}

impl HairDetail {
    /// A head whose hair is always simulated at `level`.
    pub fn fixed(level: HairDetailLevel) -> Self {
        Self { fixed: Some(level), ..default() }
    }

    /// The level in use at the last fixed step.
    pub fn level(&self) -> HairDetailLevel {
        self.level
    }

    /// Distance from the head's origin to the nearest active camera at the last fixed step, m (infinite
    /// without one).
    pub fn distance(&self) -> f32 {
        self.distance
    }

    /// Whether an active camera's frustum reached the head's hair at the last fixed step (true without
    /// cameras, or with cameras that have no [`Frustum`]).
    pub fn on_screen(&self) -> bool {
        self.on_screen
    }

    /// Radius of a ball around the head's origin that holds its hair, m: what the sight test uses
    /// (measured every 16 fixed steps).
    pub fn reach(&self) -> f32 {
        self.reach
    }
}

/// When hair is simulated at a coarser level of detail (see the [module documentation](self)). Read at
/// every fixed step; invalid values are reported once and every head is simulated at full detail until
/// they are fixed.
#[derive(Resource, Reflect, Debug, Clone, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairDetailSettings {
    /// Whether levels are chosen from distance and sight. Off: every head at full detail, except those
    /// with a [`HairDetail::fixed`] level. Default on.
    pub enabled: bool,
    /// Heads within this distance of a camera are stepped every fixed step, m. Beyond, the step interval
    /// doubles with each doubling of the distance (every second step up to twice this distance, every
    /// fourth up to four times, …), up to [`HairDetailSettings::max_step_interval`]. Default 3.
    pub full_detail_distance: f32,
    /// The longest step interval, fixed steps (1 to 16). Default 4 (at 60 Hz, hair stepped at 15 Hz).
    pub max_step_interval: u32,
    /// Heads farther than this from every camera are carried, not simulated, m (infinite: never).
    /// Default 30.
    pub carried_distance: f32,
    /// The level of heads no camera sees. Default [`HairDetailLevel::Carried`]: hair out of sight costs
    /// nothing; a shadow cast by it keeps its last shape.
    pub off_screen: HairDetailLevel,
    /// Relative margin against flickering between two levels, 0 to 0.5: a head moves to a coarser level
    /// only once it is this much farther than the level's distance, and back only once it is this much
    /// nearer. Default 0.1.
    pub hysteresis: f32,
}

impl Default for HairDetailSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            full_detail_distance: 3.0,
            max_step_interval: 4,
            carried_distance: 30.0,
            off_screen: HairDetailLevel::Carried,
            hysteresis: 0.1,
        }
    }
}

/// The longest step interval [`HairDetailSettings::max_step_interval`] may ask for.
pub const MAX_STEP_INTERVAL: u32 = 16;

impl HairDetailSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), RodError> {
        let invalid = |parameter: &'static str, value: f64, requirement: &'static str| {
            Err(RodError::InvalidStepParameter { parameter, value, requirement })
        };
        let interval_ok = |interval: u32| (1..=MAX_STEP_INTERVAL).contains(&interval);
        if !(self.full_detail_distance.is_finite() && self.full_detail_distance > 0.0) {
            return invalid("full_detail_distance", self.full_detail_distance.into(), "positive and finite");
        }
        if !interval_ok(self.max_step_interval) {
            return invalid("max_step_interval", self.max_step_interval.into(), "from 1 to 16");
        }
        if self.carried_distance.is_nan() || self.carried_distance <= 0.0 {
            return invalid("carried_distance", self.carried_distance.into(), "positive (infinite: never)");
        }
        if let HairDetailLevel::Stepped(interval) = self.off_screen
            && !interval_ok(interval)
        {
            return invalid("off_screen", interval.into(), "a step interval from 1 to 16");
        }
        if !(0.0..=0.5).contains(&self.hysteresis) {
            return invalid("hysteresis", self.hysteresis.into(), "from 0 to 0.5");
        }
        Ok(())
    }

    /// The level for a head `distance` m from the nearest camera, seen or not, with no hysteresis.
    pub fn level_at(&self, distance: f32, on_screen: bool) -> HairDetailLevel {
        if !on_screen {
            return self.off_screen;
        }
        if distance > self.carried_distance {
            return HairDetailLevel::Carried;
        }
        let mut interval = 1;
        while interval < self.max_step_interval && distance > self.full_detail_distance * interval as f32 {
            interval *= 2;
        }
        HairDetailLevel::Stepped(interval.min(self.max_step_interval))
    }

    /// The level for a head at `distance`, seen or not, that is at `current`: the level of the distance,
    /// unless the head is within [`HairDetailSettings::hysteresis`] of the distance where it would change.
    pub fn next_level(&self, current: HairDetailLevel, distance: f32, on_screen: bool) -> HairDetailLevel {
        let coarser = self.level_at(distance * (1.0 - self.hysteresis), on_screen);
        if coarser.coarseness() > current.coarseness() {
            return coarser;
        }
        let finer = self.level_at(distance * (1.0 + self.hysteresis), on_screen);
        if finer.coarseness() < current.coarseness() {
            return finer;
        }
        current
    }
}

/// Levels of detail for crowds (see the [module documentation](self)); part of [`crate::HairPlugins`].
/// Without it every head is simulated at full detail.
#[derive(Debug, Clone)]
pub struct HairDetailPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: bevy::ecs::schedule::InternedScheduleLabel,
}

impl Plugin for HairDetailPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairDetail>()
            .register_type::<HairDetailSettings>()
            .register_type::<HairCpuBudget>()
            .init_resource::<HairDetailSettings>()
            .init_resource::<HairCpuBudget>()
            .init_resource::<BudgetKeeper>()
            .register_required_components::<HairHead, HairDetail>()
            .add_systems(
                self.schedule,
                (
                    start_update_clock.in_set(HairSystems::Prepare).before(HairPrepareSystems::Grow),
                    choose_hair_detail.in_set(HairPinSystems::ChooseDetail),
                    keep_cpu_budget.in_set(HairSystems::Step).after(HairStepSystems::Follow),
                ),
            );
    }
}

/// Fixed steps between two measurements of a head's reach ([`HairDetail::reach`]).
const REACH_PERIOD: u64 = 16;

/// What [`choose_hair_detail`] keeps from step to step: the fixed steps counted, the last error
/// reported, and scratch lists reused so that no step allocates.
#[derive(Default)]
pub(crate) struct DetailMemory {
    fixed_step: u64,
    reported: Option<String>,
    viewers: Vec<Viewer>,
}

/// What one camera says about distance and sight.
pub(crate) struct Viewer {
    position: Vec3,
    frustum: Option<Frustum>,
}

/// Chooses every head's level for this fixed step, and tells each of its strands whether it is stepped
/// in this one.
pub(crate) fn choose_hair_detail(
    settings: Res<HairDetailSettings>,
    cameras: Query<(&Camera, &GlobalTransform, Option<&Frustum>)>,
    mut heads: Query<HeadItem>,
    mut strands: Query<(Entity, &mut SimulatedStrand, &StrandOf)>,
    mut statistics: ResMut<HairStatistics>,
    budget: Res<BudgetKeeper>,
    mut memory: Local<DetailMemory>,
) {
    let DetailMemory { fixed_step, reported, viewers } = &mut *memory;
    *fixed_step += 1;
    let valid = valid_or_reported_once(
        settings.validate(),
        reported,
        "HairDetailSettings rejected, every head is at full detail until they are fixed",
    );
    viewers.clear();
    let active = cameras.iter().filter(|(camera, ..)| camera.is_active);
    viewers.extend(
        active.map(|(_, transform, frustum)| Viewer { position: transform.translation(), frustum: frustum.copied() }),
    );
    let mut heads_by_detail = HeadsByDetail::default();
    for (_, motion, head_strands, mut detail) in &mut heads {
        let centre = motion.translation();
        // A ball around the head that holds its hair: the farthest root plus that strand's length
        // (measured again every `REACH_PERIOD` fixed steps: it changes only with the hair's rest shape).
        let reach = if detail.reach > 0.0 && !(*fixed_step).is_multiple_of(REACH_PERIOD) {
            detail.reach
        } else {
            let reach_of = |(_, strand, _): (Entity, &SimulatedStrand, &StrandOf)| {
                let rod = strand.rod();
                rod.positions()[0].as_vec3().distance(centre) + rod.rest_lengths().iter().sum::<f64>() as f32
            };
            head_strands
                .strands()
                .iter()
                .filter_map(|&entity| strands.get(entity).ok())
                .map(reach_of)
                .fold(0.0, f32::max)
        };
        let distance = viewers.iter().map(|viewer| viewer.position.distance(centre)).fold(f32::INFINITY, f32::min);
        let ball = Sphere { center: centre.into(), radius: reach };
        let on_screen = viewers.is_empty()
            || viewers.iter().any(|viewer| viewer.frustum.is_none_or(|frustum| frustum.intersects_sphere(&ball, true)));
        let level = match detail.fixed {
            Some(level) => level,
            None if !valid || !settings.enabled || viewers.is_empty() => budget.coarsen(HairDetailLevel::FULL),
            None => budget.coarsen(settings.next_level(detail.level, distance, on_screen)),
        };
        let new = HairDetail { level, distance, on_screen, reach, ..*detail };
        detail.set_if_neq(new);
        heads_by_detail.add(level);
    }
    statistics.heads_by_detail = heads_by_detail;
    let heads = heads.as_readonly();
    let step = *fixed_step;
    strands.par_iter_mut().for_each(|(entity, mut strand, &StrandOf(head))| {
        let level = heads.get(head).map_or(HairDetailLevel::FULL, |(.., detail)| detail.level);
        // Each strand takes its own turn (by entity): a head's strands are spread evenly over the fixed
        // steps of its interval, so that every fixed step costs about as much.
        let due = level
            .step_interval()
            .is_some_and(|interval| step.wrapping_add(entity.to_bits()).is_multiple_of(u64::from(interval)));
        let due = due || strand.detail.falling_behind(level);
        strand.set_detail(level, due);
    });
}

/// Whether settings checked as `checked` can be used; an error is logged as `consequence: error` once, when
/// it differs from the last one logged (`reported`), and forgotten once the settings are valid again.
fn valid_or_reported_once(checked: Result<(), RodError>, reported: &mut Option<String>, consequence: &str) -> bool {
    let Err(error) = checked else {
        *reported = None;
        return true;
    };
    let message = error.to_string();
    if reported.as_ref() != Some(&message) {
        error!("{consequence}: {message}");
        *reported = Some(message);
    }
    false
}

/// What [`choose_hair_detail`] reads and writes of a head.
type HeadItem = (Entity, &'static HeadMotion, &'static HeadStrands, &'static mut HairDetail);
