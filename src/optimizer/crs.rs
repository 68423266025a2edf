//! Controlled Random Search with a weighted centroid and a weighted reflection: the global
//! phase of Leonetti et al. 2012, section 4.1.1 (Price's CRS as improved by Brachetti et al.),
//! in "Combining local and global direct derivative-free optimization for reinforcement
//! learning" (2012).
//!
//! * **Step 0** — m ≥ n + 1 points drawn uniformly in the box D and evaluated: the set S.
//! * **Step 1** — J_max, J_min over S; stop when J_max − J_min ≤ ε.
//! * **Step 2** — draw n + 1 distinct points of S at random, θ_{i₀} the worst of them; the
//!   weighted centroid c = Σ_j w_j θ_{i_j} with w_j = η_j / Σ_r η_r,
//!   η_j = 1 / (J(θ_{i_j}) − J_min + φ); the trial θ̄ = c − α(θ_{i₀} − c) with
//!   α = 1 − (J(θ_{i₀}) − Σ_j w_j J(θ_{i_j})) / (J_max − J_min + φ) and
//!   φ = n (J_max − J_min)² / (J_max⁰ − J_min⁰). If θ̄ ∉ D, go back to Step 2.
//! * **Steps 3–4** — if J(θ̄) < J_max, θ̄ replaces the worst point of S; otherwise S stays.
//!
//! Each evaluation is an episode, so Step 0 is m asks and every later ask is one trial.
//!
//! # Documented deviations
//! * **Step 2 must terminate.** The paper redraws until θ̄ lies in D, which may never happen
//!   (a set pressed against a face of the box reflects outwards again and again). Here at
//!   most `max_redraws` draws are made; if none lands inside D, the last trial is projected
//!   onto D (coordinate-wise clamp): the nearest feasible point along the same reflection.
//! * **Degenerate initial spread.** If the m initial costs are all equal, φ would divide by
//!   zero; Step 1 already stops there (J_max − J_min = 0 ≤ ε), so the search reports
//!   [`Status::Converged`] after Step 0 and the division never happens.
//! * **Random subsets** are drawn by a partial Fisher–Yates shuffle of a permutation kept
//!   in the optimizer (2·m bytes), so a draw costs O(n) and needs no stack buffer.

use rand_core::RngCore;

use super::{Bounds, Draw, Error, Generation, Ledger, Optimizer, Status, Vector, random_index};
use super::{check_stopping, default_is_const, ledger_accessors, require};
use crate::vector::unrolled;

/// Parameters of [`ControlledRandomSearch`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CrsConfig {
    /// ε ≥ 0: stop when J_max − J_min ≤ ε over the set.
    pub tolerance: f32,
    /// Evaluations (episodes) allowed, ≥ 1; the m initial points count.
    pub max_evaluations: u32,
    /// Trials drawn per ask before projecting onto the box (≥ 1).
    pub max_redraws: u32,
}

impl CrsConfig {
    /// ε = 1e-6, no evaluation limit, 64 redraws.
    pub const DEFAULT: Self = Self {
        tolerance: 1e-6,
        max_evaluations: u32::MAX,
        max_redraws: 64,
    };

    /// `Ok` when every parameter is in its range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        check_stopping(Some(self.tolerance), self.max_evaluations)?;
        require(self.max_redraws != 0, "max_redraws")?;
        Ok(())
    }
}

default_is_const!(CrsConfig);

/// Controlled Random Search over a box with a set of `M` points in R^N (M ≥ N + 1; Price
/// suggests M ≈ 10(N + 1)). State: (4N + 4)·M bytes plus the bounds.
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, ControlledRandomSearch, CrsConfig, Optimizer, Status};
/// use rand_core::SeedableRng;
///
/// let bounds = Bounds::<2>::uniform(-2.0, 2.0)?;
/// let mut crs = ControlledRandomSearch::<2, 30>::try_new(bounds, CrsConfig::DEFAULT)?;
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(3);
/// while crs.status() == Status::Running && crs.evaluations() < 3000 {
///     let t = crs.ask(&mut rng)?;
///     crs.tell((t[0] - 1.0).powi(2) + (t[1] + 0.5).powi(2))?;
/// }
/// assert!(crs.best().unwrap().cost < 1e-4);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
///
/// Under [`InFlight`](super::InFlight) the M points of Step 0 can be in flight together
/// (uniform draws); after it, one trial point at a time.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ControlledRandomSearch<const N: usize, const M: usize> {
    bounds: Bounds<N>,
    config: CrsConfig,
    /// The set S (Step 0 fills it up to M points); the costs alongside.
    points: heapless::Vec<Vector<N>, M>,
    costs: heapless::Vec<f32, M>,
    /// (J_max⁰ − J_min⁰)/2, halved so that it is finite for any finite costs.
    initial_spread: f32,
    /// (index of the worst point, J_max, J_min) of the full set, kept up to date by `tell`
    /// so that neither `ask` nor the stopping test scans the set again.
    extremes: (usize, f32, f32),
    /// A permutation of 0..M, partially reshuffled for each subset draw.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    order: [u16; M],
    ledger: Ledger<N>,
}

impl<const N: usize, const M: usize> ControlledRandomSearch<N, M> {
    /// A search over `bounds`; sizes are checked at compile time.
    pub fn try_new(bounds: Bounds<N>, config: CrsConfig) -> Result<Self, Error> {
        const { assert!(M > N, "CRS needs m ≥ n + 1 points") };
        const { assert!(M <= u16::MAX as usize, "at most 65535 points") };
        config.validate()?;
        Ok(Self {
            bounds,
            config,
            points: heapless::Vec::new(),
            costs: heapless::Vec::new(),
            initial_spread: 0.0,
            extremes: (0, 0.0, 0.0),
            order: core::array::from_fn(|i| i as u16),
            ledger: Ledger::new(config.max_evaluations),
        })
    }

    /// As [`Self::try_new`], with `start` (finite, inside `bounds`, else
    /// [`Error::NonFinite`] / [`Error::OutOfBounds`] naming `"start"`) the first point of
    /// Step 0 instead of a uniform draw: it is made the pending candidate, so the first `ask`
    /// returns it (and a record saved at once holds it, in the same format as any pending
    /// candidate), and its cost is the set's first.
    pub fn try_with_start(
        bounds: Bounds<N>,
        config: CrsConfig,
        start: Vector<N>,
    ) -> Result<Self, Error> {
        bounds.check(&start, "start")?;
        let mut search = Self::try_new(bounds, config)?;
        search.ledger.hand_out(start, &bounds);
        Ok(search)
    }

    /// The configuration.
    pub fn config(&self) -> &CrsConfig {
        &self.config
    }

    /// The current set S with its costs (only the first [`Self::len`] entries are filled
    /// during Step 0).
    pub fn set(&self) -> (&[Vector<N>], &[f32]) {
        (&self.points, &self.costs)
    }

    /// Points in S so far.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether S is still empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index of the worst point of the (full) set and the worst and best costs,
    /// (worst, J_max, J_min); the first worst in index order.
    fn scan_extremes(&self) -> (usize, f32, f32) {
        // Values carried along with the index: no indexing, so no bounds check to prove.
        let first = self.costs.first().copied().unwrap_or(0.0);
        let (mut worst, mut j_max, mut j_min) = (0, first, first);
        for (i, &c) in self.costs.iter().enumerate() {
            if c > j_max {
                (worst, j_max) = (i, c);
            }
            if c < j_min {
                j_min = c;
            }
        }
        (worst, j_max, j_min)
    }

    /// Index of the worst point of the (full) set and J_max, the first worst in index
    /// order: [`Self::scan_extremes`] without J_min, four costs per loop turn (at opt-level
    /// "s" the loop's own bookkeeping would cost as much as the comparisons).
    fn scan_worst(&self) -> (usize, f32) {
        let mut worst = (0, self.costs.first().copied().unwrap_or(0.0));
        let chunks = self.costs.chunks_exact(4);
        let rest = chunks.remainder();
        for (k, chunk) in chunks.enumerate() {
            unrolled::<4>(|j| {
                if let Some(&c) = chunk.get(j)
                    && c > worst.1
                {
                    worst = (4 * k + j, c);
                }
            });
        }
        for (j, &c) in rest.iter().enumerate() {
            if c > worst.1 {
                worst = (M - rest.len() + j, c);
            }
        }
        worst
    }

    /// One trial of Step 2 (may lie outside the box).
    fn trial<R: RngCore + ?Sized>(&mut self, rng: &mut R, j_max: f32, j_min: f32) -> Vector<N> {
        // Partial Fisher–Yates: order[..=N] becomes a uniform random (N+1)-subset.
        for k in 0..=N {
            let pick = k + random_index(rng, M - k);
            // Always true (random_index < M − k); the test spares a bounds check.
            if pick < M {
                self.order.swap(k, pick);
            }
        }
        // `order` is a permutation of 0..M, so every `get` below succeeds; `get` rather
        // than indexing because the compiler cannot know it (no panic path).
        let subset = self.order.get(..=N).unwrap_or(&[]);
        let point = |i: u16| {
            let i = usize::from(i);
            self.points.get(i).zip(self.costs.get(i))
        };
        // Costs enter as halves (c/2 − j_min/2): the differences of costs near ±f32::MAX
        // would overflow, and every term below is a ratio of cost differences, so a common
        // factor ½ changes nothing else (bit for bit: scaling by a power of two commutes with
        // rounding). `initial_spread` is stored halved as well.
        let spread = 0.5 * j_max - 0.5 * j_min;
        let phi = N as f32 * spread * spread / self.initial_spread;
        let first = subset.first().copied().and_then(point);
        let Some((mut worst_point, mut worst_cost)) = first.map(|(p, &c)| (p, c)) else {
            return Vector::zeros();
        };
        let mut eta_sum = 0.0;
        for (p, &c) in subset.iter().filter_map(|&i| point(i)) {
            if c > worst_cost {
                (worst_point, worst_cost) = (p, c);
            }
            eta_sum += 1.0 / (0.5 * c - 0.5 * j_min + phi);
        }
        let mut centroid = Vector::<N>::zeros();
        let mut weighted_cost = 0.0;
        for (p, &c) in subset.iter().filter_map(|&i| point(i)) {
            let w = 1.0 / (0.5 * c - 0.5 * j_min + phi) / eta_sum;
            // centroid += w·p, element by element (nalgebra's `p * w` builds and copies a
            // temporary vector; at opt-level "s" that was half of an ask).
            unrolled::<N>(|k| centroid[k] += p[k] * w);
            weighted_cost += w * (0.5 * c);
        }
        let alpha = 1.0 - (0.5 * worst_cost - weighted_cost) / (spread + phi);
        unrolled::<N>(|k| centroid[k] -= (worst_point[k] - centroid[k]) * alpha);
        centroid
    }

    /// Step 1's stopping test on the full set.
    fn check_stop(&mut self) {
        if !self.points.is_full() {
            return;
        }
        let (_, j_max, j_min) = self.extremes;
        if j_max - j_min <= self.config.tolerance {
            self.ledger.stop(Status::Converged);
        }
    }
}

#[cfg(feature = "serde")]
impl<const N: usize, const M: usize> ControlledRandomSearch<N, M> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (box, configuration) and the set's: as many costs as points, every
    /// point finite and inside the box, every cost finite, the halved initial spread finite
    /// and ≥ 0, the extremes of a full set a worst index within it with J_max its cost and
    /// J_min ≤ J_max, and `order` a permutation of 0..M.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::require_finite;
        self.bounds.check_decoded()?;
        self.config.validate()?;
        require(self.points.len() == self.costs.len(), "costs")?;
        for p in &self.points {
            self.bounds.check(p, "points")?;
        }
        require_finite(&self.costs, "costs")?;
        require_finite([&self.initial_spread], "initial_spread")?;
        require(self.initial_spread >= 0.0, "initial_spread")?;
        if self.points.is_full() {
            let (worst, j_max, j_min) = self.extremes;
            require(self.costs.get(worst) == Some(&j_max), "extremes")?;
            require(j_min.is_finite() && j_min <= j_max, "extremes")?;
        }
        let mut seen = [false; M];
        for &i in &self.order {
            match seen.get_mut(usize::from(i)) {
                Some(s) if !*s => *s = true,
                _ => return Err(Error::InvalidParameter("order")),
            }
        }
        self.ledger.check_decoded(&self.bounds)
    }
}

/// Step 0 samples the box uniformly whatever the costs, so the points that fill the set
/// can be in flight together; after it each trial point follows the set the last cost
/// changed (one at a time).
impl<const N: usize, const M: usize> Generation<N> for ControlledRandomSearch<N, M> {
    fn room(&self) -> usize {
        let rest = M.saturating_sub(self.points.len());
        // Full: one trial point at a time.
        self.ledger.room(rest.max(1))
    }

    fn most(&self) -> usize {
        M
    }

    fn draws_ahead(&self) -> bool {
        !self.points.is_full()
    }

    fn adopts_pending(&self) -> bool {
        // A draw is its candidate alone (`resume` hands θ out again).
        true
    }

    fn draw<R: RngCore + ?Sized>(&mut self, _ahead: usize, rng: &mut R) -> Result<Draw<N>, Error> {
        if self.points.is_full() {
            return self.ask(rng).map(Draw::of);
        }
        Ok(Draw::of(
            self.bounds.clamp(&self.bounds.sample_uniform(rng)),
        ))
    }

    fn resume(&mut self, draw: &Draw<N>) {
        // After an `ask`-made draw the same θ is pending already; this changes nothing.
        self.ledger.hand_out(draw.theta, &self.bounds);
    }
}

impl<const N: usize, const M: usize> Optimizer<N> for ControlledRandomSearch<N, M> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        if !self.points.is_full() {
            return Ok(self
                .ledger
                .hand_out(self.bounds.sample_uniform(rng), &self.bounds));
        }
        let (_, j_max, j_min) = self.extremes;
        let mut candidate = self.trial(rng, j_max, j_min);
        let mut redraws = 1;
        while !self.bounds.contains(&candidate) && redraws < self.config.max_redraws {
            if candidate.iter().any(|v| !v.is_finite()) {
                // Degenerate weights (a set of equal costs whose spread then grew from
                // zero): no redraw can help; sample the box instead of clamping NaN.
                return Ok(self
                    .ledger
                    .hand_out(self.bounds.sample_uniform(rng), &self.bounds));
            }
            candidate = self.trial(rng, j_max, j_min);
            redraws += 1;
        }
        // Still outside after the redraws: the ledger projects it onto the box.
        Ok(self.ledger.hand_out(candidate, &self.bounds))
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        let theta = self.ledger.accept(cost)?;
        if !self.points.is_full() {
            // Step 0: filling the set. Both pushes succeed (points and costs grow together,
            // and neither is full); their results are ignored rather than unwrapped.
            let _ = self.points.push(theta);
            let _ = self.costs.push(cost);
            if self.points.is_full() {
                self.extremes = self.scan_extremes();
                let (_, j_max, j_min) = self.extremes;
                self.initial_spread = 0.5 * j_max - 0.5 * j_min;
            }
        } else {
            let (worst, j_max, _) = self.extremes;
            if cost < j_max
                && let (Some(p), Some(c)) = (self.points.get_mut(worst), self.costs.get_mut(worst))
            {
                (*p, *c) = (theta, cost);
                // The worst point left; J_min can only have fallen, to this cost.
                let (worst, j_max) = self.scan_worst();
                let j_min = if cost < self.extremes.2 {
                    cost
                } else {
                    self.extremes.2
                };
                self.extremes = (worst, j_max, j_min);
            }
        }
        self.check_stop();
        self.ledger.settle();
        Ok(())
    }

    ledger_accessors!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::Best;
    use proptest::prelude::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    /// Six-hump camel on [−3, 3] × [−2, 2]: six local minima, the global ones
    /// f = −1.031628 at (0.0898, −0.7126) and (−0.0898, 0.7126).
    fn camel(t: &Vector<2>) -> f32 {
        let (x, y) = (f64::from(t[0]), f64::from(t[1]));
        ((4.0 - 2.1 * x * x + x.powi(4) / 3.0) * x * x + x * y + (-4.0 + 4.0 * y * y) * y * y)
            as f32
    }

    /// Branin on [−5, 10] × [0, 15]: three global minima with f = 0.397887.
    fn branin(t: &Vector<2>) -> f32 {
        use core::f64::consts::PI;
        let (x, y) = (f64::from(t[0]), f64::from(t[1]));
        let b = 5.1 / (4.0 * PI * PI);
        let c = 5.0 / PI;
        ((y - b * x * x + c * x - 6.0).powi(2) + 10.0 * (1.0 - 1.0 / (8.0 * PI)) * x.cos() + 10.0)
            as f32
    }

    fn solve(bounds: Bounds<2>, f: fn(&Vector<2>) -> f32, seed: u64) -> (Best<2>, Status, u32) {
        let config = CrsConfig {
            tolerance: 1e-5,
            max_evaluations: 5000,
            ..CrsConfig::DEFAULT
        };
        let mut crs = ControlledRandomSearch::<2, 30>::try_new(bounds, config).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
        while let Ok(t) = crs.ask(&mut rng) {
            assert!(bounds.contains(&t));
            crs.tell(f(&t)).unwrap();
        }
        (crs.best().unwrap(), crs.status(), crs.evaluations())
    }

    /// Checks: costs near ±f32::MAX (their spread overflows f32) still give reflected trials,
    /// not NaN clamped to the lower corner: of 50 candidates after the set is full, none is
    /// the corner and all are inside the box.
    #[test]
    fn costs_near_f32_max_do_not_collapse_the_trials_to_a_corner() {
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let mut crs = ControlledRandomSearch::<2, 4>::try_new(bounds, CrsConfig::DEFAULT).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(3);
        for cost in [f32::MAX, -f32::MAX, 1.0, 2.0] {
            crs.ask(&mut rng).unwrap();
            crs.tell(cost).unwrap();
        }
        for k in 0..50 {
            let t = crs.ask(&mut rng).unwrap();
            assert!(bounds.contains(&t));
            assert_ne!(t, *bounds.lower(), "candidate {k}");
            crs.tell(f32::MAX * 0.5).unwrap();
        }
    }

    /// Checks: from 20 seeds (random initial sets), CRS with m = 30 stops by its own test
    /// (spread ≤ 1e-5) on the six-hump camel with the global value to 1e-4 and at one of the
    /// two global minimisers to 1e-2.
    #[test]
    fn finds_the_global_minimum_of_the_six_hump_camel() {
        let bounds = Bounds::try_new([-3.0, -2.0].into(), [3.0, 2.0].into()).unwrap();
        for seed in 0..20 {
            let (best, status, evals) = solve(bounds, camel, seed);
            assert_eq!(status, Status::Converged, "seed {seed} after {evals}");
            assert!(
                (best.cost + 1.031_628).abs() < 1e-4,
                "seed {seed}: {}",
                best.cost
            );
            let at = |x: f32, y: f32| {
                (best.theta[0] - x).abs() < 1e-2 && (best.theta[1] - y).abs() < 1e-2
            };
            assert!(
                at(0.0898, -0.7126) || at(-0.0898, 0.7126),
                "seed {seed}: {:?}",
                best.theta
            );
        }
    }

    /// Checks: the same on Branin (three global minima), value to 1e-4.
    #[test]
    fn finds_the_global_minimum_of_branin() {
        let bounds = Bounds::try_new([-5.0, 0.0].into(), [10.0, 15.0].into()).unwrap();
        for seed in 0..20 {
            let (best, status, _) = solve(bounds, branin, seed);
            assert_eq!(status, Status::Converged);
            assert!(
                (best.cost - 0.397_887).abs() < 1e-4,
                "seed {seed}: {}",
                best.cost
            );
        }
    }

    #[test]
    fn equal_initial_costs_stop_after_step_zero() {
        let b = Bounds::<2>::uniform(0.0, 1.0).unwrap();
        let mut crs = ControlledRandomSearch::<2, 3>::try_new(b, CrsConfig::DEFAULT).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(0);
        for _ in 0..3 {
            crs.ask(&mut rng).unwrap();
            crs.tell(7.0).unwrap();
        }
        assert_eq!(crs.status(), Status::Converged);
        assert_eq!(crs.ask(&mut rng), Err(Error::Stopped));
    }

    #[test]
    fn config_is_validated() {
        let b = Bounds::<2>::uniform(0.0, 1.0).unwrap();
        let bad = |c: CrsConfig| ControlledRandomSearch::<2, 3>::try_new(b, c).unwrap_err();
        let d = CrsConfig::DEFAULT;
        assert_eq!(
            bad(CrsConfig {
                tolerance: -1.0,
                ..d
            }),
            Error::InvalidParameter("tolerance")
        );
        assert_eq!(
            bad(CrsConfig {
                max_redraws: 0,
                ..d
            }),
            Error::InvalidParameter("max_redraws")
        );
        assert_eq!(
            bad(CrsConfig {
                max_evaluations: 0,
                ..d
            }),
            Error::InvalidParameter("max_evaluations")
        );
    }

    proptest! {
        /// Checks, for any sequence of costs (NaN and infinities included) on a set pressed
        /// against the faces: every candidate is inside the box (the redraw bound and the
        /// projection hold), non-finite costs are rejected with the state unchanged, the
        /// best never worsens, and the set always holds the best cost told.
        #[test]
        fn candidates_in_bounds_and_bad_costs_change_nothing(
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..400),
            seed in any::<u64>(),
        ) {
            let b = Bounds::<3>::try_new([0.0, -1.0, 5.0].into(), [1e-3, 1.0, 6.0].into()).unwrap();
            let config = CrsConfig { max_redraws: 2, ..CrsConfig::DEFAULT };
            let mut crs = ControlledRandomSearch::<3, 5>::try_new(b, config).unwrap();
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            let mut best = f32::INFINITY;
            for cost in costs {
                let Ok(t) = crs.ask(&mut rng) else { break };
                prop_assert!(b.contains(&t));
                let before = crs.clone();
                if cost.is_finite() {
                    prop_assert!(crs.tell(cost).is_ok());
                } else {
                    prop_assert_eq!(crs.tell(cost), Err(Error::NonFinite("cost")));
                    prop_assert_eq!(&crs, &before);
                }
                let now = crs.best().map_or(f32::INFINITY, |b| b.cost);
                prop_assert!(now <= best);
                best = now;
                if !crs.is_empty() {
                    let set_min = crs.set().1.iter().copied().fold(f32::INFINITY, f32::min);
                    prop_assert_eq!(set_min, best);
                }
            }
        }
    }
}
