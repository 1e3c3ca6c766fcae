//! A CPU time budget for the hair: [`HairCpuBudget`] says how many milliseconds of each fixed step the hair
//! may take on the CPU, and the [`HairDetailPlugin`](super::HairDetailPlugin) keeps it by stepping the hair
//! less often (see [`keep_cpu_budget`]).

use bevy::platform::time::Instant;
use bevy::prelude::*;

use super::{MAX_STEP_INTERVAL, valid_or_reported_once};
use crate::rod::RodError;
use crate::simulation::{HairDetailLevel, HairStatistics};

/// How much CPU time the hair may take per fixed step (per frame, when the game draws one frame per fixed
/// step), and how coarse it may go to keep it. Off by default: every head at the level of detail its
/// distance gives ([`crate::detail`]), the reference behaviour.
///
/// The budget counts the wall-clock time of the hair's systems in the fixed step, from growing grooms and
/// building strands to the placed followers (a groom growing once moves no choice), with every compute thread
/// working ([`HairStatistics::update_seconds`]). It is kept by the lever that changes the look least per
/// millisecond saved, measured on the example's scene (`docs/performance.md`): every head's strands are stepped
/// every `n`-th fixed step, with a step `n` times as long, each strand on its own turn so that every fixed step
/// costs about the same, and drawn interpolated between its steps, carried with its head (a level of detail,
/// [`HairDetailLevel::Stepped`]), the hair–hair grid sampled by the strands stepped at each fixed step. `n` is
/// chosen from what the updates cost: coarser as soon as more than two of the last 16 updates are over the
/// budget, finer once the cost predicted there leaves a margin. Heads with a
/// [`HairDetail::fixed`](super::HairDetail::fixed) level keep it. [`HairStatistics::budget_step_interval`] says
/// which `n` is in use.
///
/// ```
/// use bevy::prelude::*;
/// use bevy_hair_sim::prelude::*;
///
/// fn hair_in_two_milliseconds(mut commands: Commands) {
///     // At most 2 ms of each fixed step on the CPU; the hair may be stepped as rarely as every 8th fixed
///     // step (7.5 Hz at 60 Hz) to keep it.
///     commands.insert_resource(HairCpuBudget { milliseconds: Some(2.0), max_step_interval: 8 });
/// }
/// assert!(HairCpuBudget::milliseconds(4.0).validate().is_ok());
/// assert!(HairCpuBudget::milliseconds(-1.0).validate().is_err());
/// ```
#[derive(Resource, Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Resource, Debug, Default, Clone, PartialEq)]
pub struct HairCpuBudget {
    /// Milliseconds of each fixed step the hair may take on the CPU, positive and finite; `None` (the
    /// default): no budget.
    pub milliseconds: Option<f32>,
    /// The coarsest step interval the budget may use to keep it, fixed steps (1 to 16). Default 6 (at 60 Hz,
    /// hair stepped at 10 Hz at the coarsest). Past it the budget is exceeded rather than the hair made
    /// coarser; [`HairStatistics::update_seconds`] then says by how much.
    pub max_step_interval: u32,
}

impl Default for HairCpuBudget {
    fn default() -> Self {
        Self { milliseconds: None, max_step_interval: 6 }
    }
}

impl HairCpuBudget {
    /// A budget of `milliseconds` per fixed step, at most [`HairCpuBudget::max_step_interval`]'s default.
    pub fn milliseconds(milliseconds: f32) -> Self {
        Self { milliseconds: Some(milliseconds), ..default() }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), RodError> {
        let invalid = |parameter: &'static str, value: f64, requirement: &'static str| {
            Err(RodError::InvalidStepParameter { parameter, value, requirement })
        };
        if let Some(milliseconds) = self.milliseconds
            && !(milliseconds.is_finite() && milliseconds > 0.0)
        {
            return invalid("milliseconds", milliseconds.into(), "positive and finite, or None for no budget");
        }
        if !(1..=MAX_STEP_INTERVAL).contains(&self.max_step_interval) {
            return invalid("max_step_interval", self.max_step_interval.into(), "from 1 to 16");
        }
        Ok(())
    }
}

/// The last fixed steps whose costs are judged.
const SAMPLES: usize = 16;
/// Which of the last [`SAMPLES`] updates, from the cheapest, stands for what an interval costs: the
/// largest but two (the 14th of 16), so that the budget holds for most updates, not only half of them,
/// while a one-off spike (a groom growing, a strand preloaded) moves no choice.
const JUDGED_SAMPLE: usize = SAMPLES - 3;
/// Fixed steps at an interval before a finer one is tried (2 s at 60 Hz).
const STEPS_BEFORE_FINER: u32 = 120;
/// Fixed steps after the budget was exceeded during which no interval as fine as the exceeded one is
/// tried again (10 s at 60 Hz): the motion that made it too costly may still be going on.
const STEPS_BEFORE_RETRYING: u32 = 600;
/// The share of the budget a coarser interval is chosen to fill, by its predicted cost: room for the
/// prediction's error and the updates that cost more than the judged one.
const COARSER_AIM: f64 = 0.85;
/// The share of the budget a finer interval must be predicted to fill at most before it is tried.
const FINER_AIM: f64 = 0.7;
/// How much more the strands' part of an update is predicted to cost at full detail than stepped in
/// turns at the same rate: a step of one fixed step takes as many Newton iterations as it needs (1.1 on
/// the example's head at rest, 2.5 shaken), a longer step one.
const FULL_DETAIL_FACTOR: f64 = 2.0;

/// What [`keep_cpu_budget`] keeps from one fixed step to the next: the clock of this update, the
/// interval in use and what the last updates at it cost.
#[derive(Resource, Debug)]
pub(crate) struct BudgetKeeper {
    /// When this fixed step's hair systems started.
    started: Option<Instant>,
    /// The step interval every head is stepped at at least, fixed steps (1: the budget coarsens nothing).
    pub(crate) step_interval: u32,
    /// Fixed steps still to pass before the interval's costs are measured: the drawn clocks are still
    /// moving to the new interval's lag, and strands falling behind are stepped every fixed step.
    settling: u32,
    /// Fixed steps measured at this interval.
    measured: u32,
    /// The last [`SAMPLES`] updates at this interval, s: the whole, and its part that scales with the
    /// strands stepped (their step and the grid), oldest overwritten first.
    samples: [(f64, f64); SAMPLES],
    /// The judged sample ([`JUDGED_SAMPLE`]) of `samples`, whole and scaling part, once they are all of
    /// this interval, s.
    whole: f64,
    scaling: f64,
    /// Fixed steps before an interval at least as fine as `refused` may be tried again.
    retry_in: u32,
    /// The finest interval found over the budget, while `retry_in` runs.
    refused: u32,
    /// The last invalid budget reported.
    reported: Option<String>,
}

impl Default for BudgetKeeper {
    fn default() -> Self {
        Self {
            started: None,
            step_interval: 1,
            settling: 0,
            measured: 0,
            samples: [(0.0, 0.0); SAMPLES],
            whole: 0.0,
            scaling: 0.0,
            retry_in: 0,
            refused: 0,
            reported: None,
        }
    }
}

impl BudgetKeeper {
    /// `level` made at least as coarse as the budget's interval (a carried head stays carried).
    pub(crate) fn coarsen(&self, level: HairDetailLevel) -> HairDetailLevel {
        match level {
            HairDetailLevel::Stepped(interval) => HairDetailLevel::Stepped(interval.max(self.step_interval)),
            HairDetailLevel::Carried => HairDetailLevel::Carried,
        }
    }

    /// Moves to `interval`, to be measured once the drawn clocks have their new lag (they move a quarter
    /// of a fixed step per fixed step towards it; see [`crate::detail`]).
    fn move_to(&mut self, interval: u32) {
        let change = interval.abs_diff(self.step_interval);
        self.settling = 4 * change + 2 * interval;
        self.step_interval = interval;
        self.measured = 0;
    }

    /// Records one more update of `whole` seconds, `scaling` of them in the strands' step and the grid, and
    /// the judged sample of the last [`SAMPLES`] of each.
    fn record(&mut self, whole: f64, scaling: f64) {
        self.samples[self.measured as usize % SAMPLES] = (whole, scaling);
        self.measured += 1;
        let judged = |part: fn(&(f64, f64)) -> f64| {
            let mut values = self.samples.map(|sample| part(&sample));
            values.sort_unstable_by(f64::total_cmp);
            values[JUDGED_SAMPLE]
        };
        (self.whole, self.scaling) = (judged(|sample| sample.0), judged(|sample| sample.1));
    }

    /// What an update is predicted to cost at `interval`, s, from the judged costs at the interval in use:
    /// the strands' part scales with the share of them stepped at each fixed step, the rest stays.
    fn predicted(&self, interval: u32) -> f64 {
        let fixed = (self.whole - self.scaling).max(0.0);
        let strands = self.scaling * f64::from(self.step_interval) / f64::from(interval);
        fixed + if interval == 1 { FULL_DETAIL_FACTOR * strands } else { strands }
    }

    /// The interval to use next for a budget of `budget` s and intervals up to `coarsest`.
    fn choose(&mut self, budget: f64, coarsest: u32) -> u32 {
        let current = self.step_interval;
        if current > coarsest {
            return coarsest;
        }
        if (self.measured as usize) < SAMPLES {
            return current;
        }
        if self.whole > budget {
            if current < coarsest {
                (self.retry_in, self.refused) = (STEPS_BEFORE_RETRYING, current);
            }
            let fits = (current + 1..=coarsest).find(|&interval| self.predicted(interval) <= COARSER_AIM * budget);
            return fits.unwrap_or(coarsest);
        }
        let finest_allowed = if self.retry_in > 0 { self.refused + 1 } else { 1 };
        if self.measured >= STEPS_BEFORE_FINER && finest_allowed < current {
            let fits = (finest_allowed..current).find(|&interval| self.predicted(interval) <= FINER_AIM * budget);
            if let Some(interval) = fits {
                return interval;
            }
        }
        current
    }
}

/// Starts the clock of the hair's systems in this fixed step.
pub(crate) fn start_update_clock(mut keeper: ResMut<BudgetKeeper>) {
    keeper.started = Some(Instant::now());
}

/// Measures what the hair's systems took in this fixed step ([`HairStatistics::update_seconds`]) and,
/// with a [`HairCpuBudget`], chooses the step interval of the next fixed steps: every head's hair is stepped
/// at least that rarely ([`BudgetKeeper::coarsen`], applied by the level of detail's choice).
///
/// **The choice.** Of the last 16 updates, the largest but two, whole and of its part that scales with the
/// strands stepped (the step and the grid), predict what another interval would cost: the scaling part in
/// proportion to the strands stepped per fixed step, twice that again at full detail (more Newton
/// iterations), the rest unchanged. After 16 measured fixed steps at an interval (once the drawn clocks
/// have the interval's lag), a cost over the budget moves to the finest coarser interval predicted within
/// 85 % of it, and keeps the intervals as fine as the exceeded one untried for 600 fixed steps; after 120
/// fixed steps within the budget, the finest finer interval predicted within 70 % of it is tried.
pub(crate) fn keep_cpu_budget(
    budget: Res<HairCpuBudget>,
    mut keeper: ResMut<BudgetKeeper>,
    mut statistics: ResMut<HairStatistics>,
) {
    let Some(started) = keeper.started.take() else { return };
    let whole = started.elapsed().as_secs_f64();
    statistics.update_seconds = whole;
    keeper.retry_in = keeper.retry_in.saturating_sub(1);
    let consequence = "HairCpuBudget rejected, the hair runs without a budget until it is fixed";
    let valid = valid_or_reported_once(budget.validate(), &mut keeper.reported, consequence);
    let Some(milliseconds) = budget.milliseconds.filter(|_| valid) else {
        if keeper.step_interval != 1 {
            keeper.move_to(1);
        }
        statistics.budget_step_interval = 1;
        return;
    };
    if keeper.settling > 0 {
        keeper.settling -= 1;
    } else {
        keeper.record(whole, statistics.step_seconds + statistics.volume_seconds);
        let next = keeper.choose(f64::from(milliseconds) * 1e-3, budget.max_step_interval);
        if next != keeper.step_interval {
            keeper.move_to(next);
        }
    }
    statistics.budget_step_interval = keeper.step_interval;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A keeper at `interval` after [`SAMPLES`] updates of `whole` s, `scaling` of them in the strands.
    fn measured(interval: u32, whole: f64, scaling: f64) -> BudgetKeeper {
        let mut keeper = BudgetKeeper { step_interval: interval, ..default() };
        for _ in 0..SAMPLES {
            keeper.record(whole, scaling);
        }
        keeper
    }

    #[test]
    fn the_keeper_goes_as_coarse_as_the_budget_needs_and_back_only_with_room() {
        // 10 ms at full detail, 8 of them in the strands, against 4 ms: at `n` the update is predicted at
        // 2 + 8/n ms; 85 % of 4 ms is first reached at n = 6 (3.33 ms).
        let mut keeper = measured(1, 0.010, 0.008);
        assert_eq!(keeper.choose(0.004, 16), 6);
        assert_eq!(keeper.choose(0.004, 4), 4, "no coarser than allowed, even over the budget");
        // At 6, within the budget: it stays, and does not go back to the exceeded full detail for 600 steps.
        keeper = BudgetKeeper { retry_in: keeper.retry_in, refused: keeper.refused, ..measured(6, 0.0033, 0.0013) };
        keeper.measured = STEPS_BEFORE_FINER;
        assert_eq!(keeper.choose(0.004, 16), 6);
        // With a budget twice as large, room enough for every third step (2 + 2 × 1.3 = 4.6 ms against
        // 70 % of 8), but not for every second (2 + 3 × 1.3 = 5.9 ms) nor, while the wait runs, full detail.
        assert_eq!(keeper.choose(0.008, 16), 3);
        keeper.retry_in = 0;
        assert_eq!(keeper.choose(0.008, 16), 3, "full detail is predicted twice as costly per strand");
        assert_eq!(keeper.choose(0.020, 16), 2, "full detail predicted at 17.6 ms, over 70 % of 20");
        assert_eq!(keeper.choose(0.030, 16), 1);
        // Too few updates measured at an interval: no judgement yet.
        keeper.measured = 3;
        assert_eq!(keeper.choose(0.001, 16), 6);
    }

    #[test]
    fn one_spike_moves_no_choice() {
        let mut keeper = measured(2, 0.002, 0.0015);
        keeper.record(0.5, 0.0015);
        assert_eq!(keeper.choose(0.003, 16), 2);
    }
}
