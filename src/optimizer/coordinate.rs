//! Coordinate search with line-search expansions (Lucidi & Sciandrone), the local phase of
//! Leonetti, Kormushev and Sagratella, "Combining local and global direct derivative-free
//! optimization for reinforcement learning" (Cybernetics and Information Technologies,
//! 2012), section 4.2.1.
//!
//! The algorithm, as the paper gives it (minimisation, directions d_1..d_2n = ±e_i, one
//! tentative step α̃_j per direction):
//!
//! * **Step 1** — if max_j α̃_j ≤ ε, stop; otherwise start an iteration at y_1 = x = θ^k.
//! * **Step 2** — for direction d_j, evaluate J(y_j + α̃_j d_j). If
//!   J(y_j + α̃_j d_j) ≤ J(y_j) − γ α̃_j² *and* J(y_j + α̃_j d_j) < J(x), accept (α_j = α̃_j,
//!   x = y_j + α_j d_j) and *expand*: while J(y_j + δα_j d_j) passes the same two tests,
//!   α_j ← δα_j and x moves there; then α̃_j ← α_j. Otherwise α_j = 0 and α̃_j ← σα̃_j.
//! * **Step 3–5** — y_{j+1} = y_j + α_j d_j; after the 2n directions θ^{k+1} = x.
//!
//! Here each evaluation is an episode, so the loops above are unrolled into a state machine
//! driven by [`Optimizer::ask`]/[`Optimizer::tell`]: `tell` records the cost, runs the
//! decisions of Step 2 and prepares the next candidate at once, so [`Optimizer::status`] is
//! current as soon as the last cost is told.
//!
//! # Choices the paper leaves open (documented deviations)
//! * **Direction order.** d_j = +e_j for j ≤ n and −e_{j−n} for j > n (the set
//!   D = {e_1..e_n, −e_1..−e_n} of Lucidi & Sciandrone).
//! * **Bounds.** The paper is unconstrained. As in the box-constrained line search of
//!   Lucidi, Liuzzi and co-authors (DFL's `linesearchbox`), a step is truncated to the largest
//!   feasible step along its direction, α = min(α̃, α_max), and the sufficient-decrease test
//!   uses the truncated α actually taken. After a success α̃ ← max(α, α̃), the paper's rule
//!   wherever no truncation happened (there α ≥ α̃), so that steps shrink only on failure. An expansion that would not move further (the point
//!   is already on the face) ends the line search without an evaluation. A direction with
//!   α_max = 0 (the point is on that face) counts as a failure without an evaluation, so its
//!   α̃ contracts by σ: no episode is spent on a candidate equal to the current point.
//! * **Step floor.** A failed direction's step contracts to max(σα̃, ε) rather than σα̃.
//!   The paper's stopping test (every α̃ ≤ ε) is unchanged; what changes is that a direction
//!   that keeps failing while *other* directions keep the iteration going (on Rosenbrock,
//!   θ_{i+1} has to wait until θ_i moves) no longer shrinks its step towards 0. In exact
//!   arithmetic such a step recovers by expansions, but in f32 a step below the resolution
//!   of θ_i never moves θ_i again and the direction is dead for good: without the floor the
//!   search stalls on the 10-D Rosenbrock function at cost 5.1 with its largest step 0.5.
//!   With it, a revived direction regrows by δ per expansion, log_δ(α/ε) evaluations.
//! * **f32 resolution.** A step too small to change the f32 coordinate is treated like a
//!   zero feasible step. If a whole iteration evaluates nothing, no later iteration can
//!   either (steps only shrink), so the search reports [`Status::Converged`] at once rather
//!   than spinning down to ε.
//! * **Budget.** `max_evaluations` stops the search with [`Status::BudgetSpent`]; on a robot
//!   the episode budget (150 episodes in the paper's AUV experiment) is the real limit.
//!
//! # Defaults and their source
//! γ = 1e-6 (sufficient decrease), σ = 0.5 (contraction) and δ = 2 (expansion, 1/0.5) are
//! the values of Liuzzi & Lucidi's public DFL line-search codes. The paper gives no values;
//! the initial step (0.1) and tolerance (1e-4) are ours and are meant to be set per problem:
//! α̃⁰ is the first step on every parameter, so it should be a fraction (say a tenth) of each
//! parameter's useful range, and ε the finest change that still matters on the robot.

use rand_core::RngCore;

use super::{Bounds, Error, Ledger, Optimizer, Status, Vector};
use super::{check_stopping, default_is_const, ledger_accessors, require};

/// Parameters of [`CoordinateSearch`]. Plain fields, checked by [`CoordinateConfig::validate`]
/// (and by the optimizer's constructors).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CoordinateConfig {
    /// α̃⁰: the first tentative step in every direction (> 0, finite), in parameter units.
    pub initial_step: f32,
    /// σ ∈ (0, 1): a failed direction's step is multiplied by σ.
    pub contraction: f32,
    /// δ > 1: a successful step is tried again δ times longer.
    pub expansion: f32,
    /// γ ∈ (0, 1): the sufficient-decrease constant of J(y + αd) ≤ J(y) − γα².
    pub sufficient_decrease: f32,
    /// ε > 0: the search has converged when every tentative step is ≤ ε.
    pub tolerance: f32,
    /// Evaluations (episodes) allowed, ≥ 1.
    pub max_evaluations: u32,
}

impl CoordinateConfig {
    /// The defaults described in the [module docs](self).
    pub const DEFAULT: Self = Self {
        initial_step: 0.1,
        contraction: 0.5,
        expansion: 2.0,
        sufficient_decrease: 1e-6,
        tolerance: 1e-4,
        max_evaluations: u32::MAX,
    };

    /// `Ok` when every parameter is in its range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        let in_open_unit = |v: f32| v > 0.0 && v < 1.0;
        require(
            self.initial_step.is_finite() && self.initial_step > 0.0,
            "initial_step",
        )?;
        require(in_open_unit(self.contraction), "contraction")?;
        require(
            self.expansion.is_finite() && self.expansion > 1.0,
            "expansion",
        )?;
        require(
            in_open_unit(self.sufficient_decrease),
            "sufficient_decrease",
        )?;
        require(
            self.tolerance.is_finite() && self.tolerance > 0.0,
            "tolerance",
        )?;
        check_stopping(None, self.max_evaluations)
    }
}

default_is_const!(CoordinateConfig);

/// Where the state machine stands; the next candidate follows from it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
enum Phase {
    /// θ⁰ itself has to be evaluated first (J(y_1) is needed by every test).
    Start,
    /// First trial along the current direction, with step `step` (α̃ truncated to the box).
    Probe { step: f32 },
    /// Expansion along the current direction: `accepted` is α_j so far, `step` the trial δα_j
    /// (truncated to the box).
    Expand { accepted: f32, step: f32 },
    /// Stopped; see [`CoordinateSearch::status`].
    Done,
}

/// Coordinate search with line-search expansions over a box, as a resumable ask/tell state
/// machine: deterministic, no RNG use, `O(N)` work per call and `~20·N` bytes of state.
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Status};
/// use rand_core::SeedableRng;
///
/// let bounds = Bounds::<2>::uniform(-2.0, 2.0)?;
/// let config = CoordinateConfig { initial_step: 0.5, tolerance: 1e-3, ..Default::default() };
/// let mut search = CoordinateSearch::try_new(bounds, [1.5, -1.0].into(), config)?;
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(0); // unused by this algorithm
/// while search.status() == Status::Running {
///     let theta = search.ask(&mut rng)?;
///     let cost = (theta[0] - 0.3).powi(2) + 2.0 * (theta[1] + 0.2).powi(2);
///     search.tell(cost)?;
/// }
/// let best = search.best().unwrap();
/// assert!((best.theta[0] - 0.3).abs() < 1e-2 && (best.theta[1] + 0.2).abs() < 1e-2);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
///
/// One candidate at a time under [`InFlight`](super::InFlight) too (its
/// [`Generation`](super::Generation) room is 1): each trial point follows the cost of the one
/// before.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CoordinateSearch<const N: usize> {
    bounds: Bounds<N>,
    config: CoordinateConfig,
    /// α̃_j for d_j = +e_j.
    steps_up: Vector<N>,
    /// α̃_j for d_j = −e_j.
    steps_down: Vector<N>,
    /// y_j, the origin of the current line search, and J(y_j).
    origin: Vector<N>,
    origin_cost: f32,
    /// x^k, the best point of the current iteration, and J(x^k).
    current: Vector<N>,
    current_cost: f32,
    /// j − 1 ∈ 0..2N.
    direction: usize,
    /// Candidates evaluated since the iteration began (see "f32 resolution").
    evaluated_this_iteration: u32,
    iterations: u32,
    phase: Phase,
    ledger: Ledger<N>,
}

impl<const N: usize> CoordinateSearch<N> {
    /// A search starting from `start` (θ⁰, which must be finite and inside `bounds`) with
    /// the same initial step `config.initial_step` in every direction.
    pub fn try_new(
        bounds: Bounds<N>,
        start: Vector<N>,
        config: CoordinateConfig,
    ) -> Result<Self, Error> {
        Self::try_with_steps(bounds, start, Vector::repeat(config.initial_step), config)
    }

    /// As [`CoordinateSearch::try_new`] with one initial step per coordinate (used for both
    /// ±e_i), for parameters of different scales; `config.initial_step` is ignored.
    pub fn try_with_steps(
        bounds: Bounds<N>,
        start: Vector<N>,
        steps: Vector<N>,
        config: CoordinateConfig,
    ) -> Result<Self, Error> {
        config.validate()?;
        require(
            steps.iter().all(|s| s.is_finite() && *s > 0.0),
            "initial_step",
        )?;
        bounds.check(&start, "start")?;
        Ok(Self {
            bounds,
            config,
            steps_up: steps,
            steps_down: steps,
            origin: start,
            origin_cost: f32::INFINITY,
            current: start,
            current_cost: f32::INFINITY,
            direction: 0,
            evaluated_this_iteration: 0,
            iterations: 0,
            phase: Phase::Start,
            ledger: Ledger::new(config.max_evaluations),
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &CoordinateConfig {
        &self.config
    }

    /// The tentative steps α̃ for the directions +e_i and −e_i.
    pub fn steps(&self) -> (&Vector<N>, &Vector<N>) {
        (&self.steps_up, &self.steps_down)
    }

    /// Completed iterations k (sweeps over all 2N directions).
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    /// The tentative step α̃_j of direction `j` (0-based over the 2N directions).
    fn tentative(&self, j: usize) -> f32 {
        // `j < 2N` always (`direction` wraps at 2N), but the compiler cannot see that, so
        // plain indexing would keep a panic path in the firmware (`scripts/panic-check`);
        // the unreachable fallback is the smallest step.
        let steps = if j < N {
            &self.steps_up
        } else {
            &self.steps_down
        };
        steps.get(j % N).copied().unwrap_or(self.config.tolerance)
    }

    /// α̃_j ← σα̃_j, floored at ε (see "Step floor" in the module docs).
    fn contract(&mut self, j: usize) {
        let step = (self.tentative(j) * self.config.contraction).max(self.config.tolerance);
        self.set_tentative(j, step);
    }

    /// α̃_j ← α_j after a successful line search. In the interior α_j ≥ α̃_j, so this is
    /// the paper's rule; a step truncated by the box keeps the longer α̃_j, so that steps
    /// shrink only on failure.
    fn succeed(&mut self, j: usize, accepted: f32) {
        self.set_tentative(j, accepted.max(self.tentative(j)));
    }

    fn set_tentative(&mut self, j: usize, step: f32) {
        // `.get_mut` for the reason given in `tentative`.
        let steps = if j < N {
            &mut self.steps_up
        } else {
            &mut self.steps_down
        };
        if let Some(s) = steps.get_mut(j % N) {
            *s = step;
        }
    }

    /// The point `from + step·d_j`, kept inside the box (truncation plus a final clamp
    /// against rounding), and whether it differs from `from` in f32.
    fn along(&self, from: &Vector<N>, j: usize, step: f32) -> (Vector<N>, bool) {
        let i = j % N;
        let mut p = *from;
        let moved = if j < N {
            from[i] + step
        } else {
            from[i] - step
        };
        // max/min rather than `f32::clamp`, whose `min <= max` assertion (true for valid
        // bounds, but not provable by the compiler) is a panic path.
        p[i] = moved
            .max(self.bounds.lower()[i])
            .min(self.bounds.upper()[i]);
        let differs = p[i] != from[i];
        (p, differs)
    }

    /// α_max: the longest step along d_j from the line-search origin that stays in the box.
    fn max_step(&self, j: usize) -> f32 {
        let i = j % N;
        if j < N {
            self.bounds.upper()[i] - self.origin[i]
        } else {
            self.origin[i] - self.bounds.lower()[i]
        }
    }

    /// Steps 3–5 and 1: closes the line search along the current direction and moves to the
    /// next one, closing the iteration (and testing for convergence) after direction 2N.
    fn next_direction(&mut self) {
        // Step 3: y_{j+1} = y_j + α_j d_j, which is x^k (x only ever moves along d_j from y_j).
        self.origin = self.current;
        self.origin_cost = self.current_cost;
        self.direction += 1;
        if self.direction < 2 * N {
            return;
        }
        // Step 5 then Step 1.
        self.direction = 0;
        self.iterations = self.iterations.saturating_add(1);
        let largest = self.steps_up.max().max(self.steps_down.max());
        if largest <= self.config.tolerance || self.evaluated_this_iteration == 0 {
            self.ledger.stop(Status::Converged);
            self.phase = Phase::Done;
        }
        self.evaluated_this_iteration = 0;
    }

    /// Walks the state machine forward to the next candidate that needs an evaluation,
    /// resolving without episodes the directions that cannot move.
    fn prepare_next(&mut self) {
        // Each pass either returns or advances `direction`; a full iteration with no
        // evaluation sets Done, so at most 2·2N passes happen.
        loop {
            if self.ledger.status() != Status::Running {
                self.phase = Phase::Done;
                return;
            }
            if self.ledger.budget_spent() {
                self.ledger.stop(Status::BudgetSpent);
                self.phase = Phase::Done;
                return;
            }
            let j = self.direction;
            match self.phase {
                Phase::Start | Phase::Done => return,
                Phase::Probe { .. } => {
                    let step = self.tentative(j).min(self.max_step(j));
                    if self.along(&self.origin, j, step).1 {
                        self.phase = Phase::Probe { step };
                        return;
                    }
                    // Nothing to try in this direction: a failure without an episode.
                    self.contract(j);
                }
                Phase::Expand { accepted, .. } => {
                    let step = (self.config.expansion * accepted).min(self.max_step(j));
                    let (trial, _) = self.along(&self.origin, j, step);
                    if step > accepted && trial != self.current {
                        self.phase = Phase::Expand { accepted, step };
                        return;
                    }
                    // On the face of the box: the expansion ends where it is.
                    self.succeed(j, accepted);
                }
            }
            self.phase = Phase::Probe { step: 0.0 };
            self.next_direction();
        }
    }

    /// The candidate of the current phase.
    fn candidate(&self) -> Vector<N> {
        match self.phase {
            Phase::Start | Phase::Done => self.origin,
            Phase::Probe { step } | Phase::Expand { step, .. } => {
                self.along(&self.origin, self.direction, step).0
            }
        }
    }

    /// Step 2's acceptance test for a trial at distance `step` with cost `cost`.
    fn sufficient(&self, step: f32, cost: f32) -> bool {
        cost <= self.origin_cost - self.config.sufficient_decrease * step * step
            && cost < self.current_cost
    }
}

#[cfg(feature = "serde")]
impl<const N: usize> CoordinateSearch<N> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (box, configuration, finite positive steps) and the state
    /// machine's: the line-search origin and the incumbent finite and inside the box, their
    /// costs finite once θ⁰ has been told, a direction index below 2N, finite non-negative
    /// trial steps, and `Done` exactly when the search has stopped.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::require_finite;
        self.bounds.check_decoded()?;
        self.config.validate()?;
        require_finite(&self.steps_up, "steps_up")?;
        require(self.steps_up.iter().all(|s| *s > 0.0), "steps_up")?;
        require_finite(&self.steps_down, "steps_down")?;
        require(self.steps_down.iter().all(|s| *s > 0.0), "steps_down")?;
        self.bounds.check(&self.origin, "origin")?;
        self.bounds.check(&self.current, "current")?;
        if self.phase != Phase::Start {
            require_finite([&self.origin_cost, &self.current_cost], "current_cost")?;
        }
        require(self.direction < 2 * N, "direction")?;
        let step_ok = |s: f32| s.is_finite() && s >= 0.0;
        let phase_ok = match self.phase {
            Phase::Start | Phase::Done => true,
            Phase::Probe { step } => step_ok(step),
            Phase::Expand { accepted, step } => step_ok(accepted) && step_ok(step),
        };
        require(phase_ok, "phase")?;
        require(
            (self.phase == Phase::Done) == (self.ledger.status() != Status::Running),
            "phase",
        )?;
        self.ledger.check_decoded(&self.bounds)
    }
}

impl<const N: usize> Optimizer<N> for CoordinateSearch<N> {
    fn ask<R: RngCore + ?Sized>(&mut self, _rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        Ok(self.ledger.hand_out(self.candidate(), &self.bounds))
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        let theta = self.ledger.accept(cost)?;
        self.evaluated_this_iteration = self.evaluated_this_iteration.saturating_add(1);
        let j = self.direction;
        match self.phase {
            Phase::Start => {
                self.origin_cost = cost;
                self.current_cost = cost;
                self.phase = Phase::Probe { step: 0.0 };
                // Step 1 at k = 0: initial steps may already be below the tolerance.
                let largest = self.steps_up.max().max(self.steps_down.max());
                if largest <= self.config.tolerance {
                    self.ledger.stop(Status::Converged);
                }
            }
            // A sufficient decrease is accepted, and the line search expands along it.
            Phase::Probe { step } | Phase::Expand { step, .. } if self.sufficient(step, cost) => {
                self.current = theta;
                self.current_cost = cost;
                self.phase = Phase::Expand {
                    accepted: step,
                    step,
                };
            }
            // A failed probe contracts the direction's step.
            Phase::Probe { .. } => {
                self.contract(j);
                self.phase = Phase::Probe { step: 0.0 };
                self.next_direction();
            }
            // A failed expansion keeps the last accepted step and the direction succeeds.
            Phase::Expand { accepted, .. } => {
                self.succeed(j, accepted);
                self.phase = Phase::Probe { step: 0.0 };
                self.next_direction();
            }
            // `accept` succeeded, so a candidate was pending, so the phase was not Done.
            Phase::Done => {}
        }
        self.prepare_next();
        Ok(())
    }

    ledger_accessors!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::Best;
    use crate::testing::{
        any_bounds, check_any_costs, check_call_order, check_rejected_configs,
        check_rejected_starts, check_seeded, rng, with_start,
    };
    use proptest::prelude::*;

    /// Runs the search to its stop (or `budget` evaluations) and returns the best.
    fn minimise<const N: usize>(
        search: &mut CoordinateSearch<N>,
        budget: u32,
        f: impl Fn(&Vector<N>) -> f32,
    ) -> Best<N> {
        let mut r = rng(0);
        for _ in 0..budget {
            let Ok(theta) = search.ask(&mut r) else { break };
            search.tell(f(&theta)).unwrap();
        }
        search.best().unwrap()
    }

    /// Σ 10^(3i/(N−1)) (θ_i − c_i)², condition number 1e3, minimiser c_i = 0.5 − i/(2N).
    fn ellipsoid<const N: usize>(t: &Vector<N>) -> f32 {
        (0..N)
            .map(|i| {
                let c = 0.5 - i as f64 / (2 * N) as f64;
                10f64.powf(3.0 * i as f64 / (N - 1) as f64) * (f64::from(t[i]) - c).powi(2)
            })
            .sum::<f64>() as f32
    }

    fn rosenbrock<const N: usize>(t: &Vector<N>) -> f32 {
        (0..N - 1)
            .map(|i| {
                let (a, b) = (f64::from(t[i]), f64::from(t[i + 1]));
                100.0 * (b - a * a).powi(2) + (1.0 - a).powi(2)
            })
            .sum::<f64>() as f32
    }

    fn config(initial_step: f32, tolerance: f32) -> CoordinateConfig {
        CoordinateConfig {
            initial_step,
            tolerance,
            ..CoordinateConfig::DEFAULT
        }
    }

    /// Checks: from three starts, the search stops by its own test (not the budget) with
    /// cost < 1e-6 and every coordinate within 2e-3 of the minimiser (tolerance ε = 1e-6).
    fn converges<const N: usize>(f: fn(&Vector<N>) -> f32, minimiser: impl Fn(usize) -> f32) {
        let bounds = Bounds::<N>::uniform(-5.0, 5.0).unwrap();
        for start in [-1.2, 0.0, 2.0] {
            let mut s = CoordinateSearch::try_new(bounds, Vector::repeat(start), config(0.5, 1e-6))
                .unwrap();
            let best = minimise(&mut s, 1_000_000, f);
            assert_eq!(s.status(), Status::Converged, "N={N} start={start}");
            assert!(best.cost < 1e-6, "N={N} start={start}: cost {}", best.cost);
            for i in 0..N {
                let err = (best.theta[i] - minimiser(i)).abs();
                assert!(err < 2e-3, "N={N} start={start}: θ[{i}] off by {err}");
            }
        }
    }

    #[test]
    fn converges_on_ill_conditioned_quadratic_in_2_to_10_dims() {
        converges::<2>(ellipsoid::<2>, |i| 0.5 - i as f32 / 4.0);
        converges::<5>(ellipsoid::<5>, |i| 0.5 - i as f32 / 10.0);
        converges::<10>(ellipsoid::<10>, |i| 0.5 - i as f32 / 20.0);
    }

    #[test]
    fn converges_on_rosenbrock_in_2_to_10_dims() {
        converges::<2>(rosenbrock::<2>, |_| 1.0);
        converges::<5>(rosenbrock::<5>, |_| 1.0);
        converges::<10>(rosenbrock::<10>, |_| 1.0);
    }

    #[test]
    fn steps_shrink_only_on_a_failed_probe() {
        // Interior optimum, so no direction is ever blocked by the box: every contraction
        // must come from a told cost that failed the sufficient-decrease test.
        let bounds = Bounds::<4>::uniform(-5.0, 5.0).unwrap();
        let mut s = CoordinateSearch::try_new(bounds, Vector::zeros(), config(0.3, 1e-5)).unwrap();
        let mut r = rng(0);
        let (mut contractions, mut expansions) = (0, 0);
        while let Ok(theta) = s.ask(&mut r) {
            let before = s;
            let cost = ellipsoid(&theta);
            s.tell(cost).unwrap();
            for j in 0..8 {
                let (old, new) = (before.tentative(j), s.tentative(j));
                if new < old {
                    contractions += 1;
                    let Phase::Probe { step } = before.phase else {
                        panic!("step {j} shrank outside a probe");
                    };
                    assert_eq!(j, before.direction, "only the probed direction shrinks");
                    assert!(
                        !before.sufficient(step, cost),
                        "step {j} shrank on a success"
                    );
                    assert_eq!(new, (old * 0.5).max(1e-5));
                } else if new > old {
                    expansions += 1;
                }
            }
        }
        assert_eq!(s.status(), Status::Converged);
        assert!(contractions > 0 && expansions > 0);
    }

    #[test]
    fn expansion_doubles_the_step_while_decrease_holds() {
        // Linear descent along +e_0 inside [0, 100]: from 0 with α̃ = 1 the accepted points
        // are 1, 2, 4, 8, ... until the face at 100 truncates the step.
        let bounds = Bounds::<1>::uniform(0.0, 100.0).unwrap();
        let mut s = CoordinateSearch::try_new(bounds, [0.0].into(), config(1.0, 1e-3)).unwrap();
        let mut r = rng(0);
        let mut asked = [0.0f32; 9];
        for a in &mut asked {
            let t = s.ask(&mut r).unwrap();
            *a = t[0];
            s.tell(-t[0]).unwrap();
        }
        assert_eq!(asked, [0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 100.0]);
        assert_eq!(s.best().unwrap().theta[0], 100.0);
    }

    #[test]
    fn identical_seeds_give_identical_runs() {
        // A noisy objective draws its noise from the caller's RNG: the same seed must give
        // the same sequence of candidates and costs, another seed a different one.
        let bounds = Bounds::<3>::uniform(-2.0, 2.0).unwrap();
        let s = CoordinateSearch::try_new(bounds, Vector::zeros(), config(0.5, 1e-4)).unwrap();
        assert!(check_seeded(&s, 0.01, ellipsoid) > 20);
    }

    #[test]
    fn constructors_name_the_bad_parameter() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let z = Vector::<2>::zeros();
        check_rejected_configs(
            CoordinateConfig::DEFAULT,
            |c| CoordinateSearch::try_new(b, z, c),
            &[
                (|c| c.initial_step = 0.0, "initial_step"),
                (|c| c.initial_step = f32::NAN, "initial_step"),
                (|c| c.contraction = 1.0, "contraction"),
                (|c| c.expansion = 1.0, "expansion"),
                (|c| c.sufficient_decrease = 0.0, "sufficient_decrease"),
                (|c| c.tolerance = -1.0, "tolerance"),
                (|c| c.max_evaluations = 0, "max_evaluations"),
            ],
        );
        let c = CoordinateConfig::DEFAULT;
        check_rejected_starts("start", |s| CoordinateSearch::try_new(b, s, c));
        assert_eq!(
            CoordinateSearch::try_with_steps(b, z, [0.1, -0.1].into(), c),
            Err(Error::InvalidParameter("initial_step"))
        );
    }

    #[test]
    fn call_order_errors_and_idempotent_ask() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let c = CoordinateConfig {
            max_evaluations: 3,
            ..CoordinateConfig::DEFAULT
        };
        let mut s = CoordinateSearch::try_new(b, Vector::zeros(), c).unwrap();
        check_call_order(&mut s);
    }

    #[test]
    fn minimiser_outside_the_box_ends_on_its_face() {
        // The unconstrained minimiser (3, −3) lies outside [−1, 1]²: the search must stop at
        // the nearest corner without ever asking outside.
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let mut s = CoordinateSearch::try_new(b, Vector::zeros(), config(0.3, 1e-5)).unwrap();
        let best = minimise(&mut s, 10_000, |t| {
            (t[0] - 3.0).powi(2) + (t[1] + 3.0).powi(2)
        });
        assert_eq!(s.status(), Status::Converged);
        assert_eq!(best.theta, Vector::from([1.0, -1.0]));
    }

    #[test]
    fn initial_steps_at_tolerance_stop_after_the_start() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let mut s = CoordinateSearch::try_new(b, Vector::zeros(), config(1e-4, 1e-4)).unwrap();
        let mut r = rng(0);
        s.ask(&mut r).unwrap();
        s.tell(0.5).unwrap();
        assert_eq!(s.status(), Status::Converged);
        assert_eq!(s.ask(&mut r), Err(Error::Stopped));
    }

    proptest! {
        /// Checks, for random boxes, starts, configs and cost sequences (any f32, NaN and
        /// infinities included): every candidate is inside the box, a non-finite cost is an
        /// error that leaves the whole state unchanged, and the best cost never increases.
        #[test]
        fn candidates_in_bounds_and_bad_costs_change_nothing(
            (bounds, start) in with_start(any_bounds::<4>(1e-3)),
            step in 1e-3f32..1e3,
            contraction in 0.05f32..0.95,
            expansion in 1.05f32..4.0,
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..300),
        ) {
            let cfg = CoordinateConfig {
                initial_step: step, contraction, expansion, tolerance: 1e-4,
                ..CoordinateConfig::DEFAULT
            };
            let mut s = CoordinateSearch::try_new(bounds, start, cfg).unwrap();
            check_any_costs(&mut s, &bounds, &costs, 1, |_, _| Ok(()))?;
        }
    }
}
