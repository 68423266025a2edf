//! Classification-based optimisation: sequential RACOS ([`Sracos`], Hu, Qian & Yu 2017,
//! "Sequential classification-based optimization for direct policy search", Algorithm 2,
//! AAAI 2017) and its batch-mode baseline RACOS ([`Racos`],
//! Algorithm 1), as the authors' package ZOOpt 0.4.2 implements them (`zoopt/algos/
//! opt_algorithms/racos/`: `sracos.py`, `racos.py`, `racos_common.py`,
//! `racos_classification.py`; value suppression in `noise_handling/ssracos.py`).
//!
//! The model is a set of k *positive* samples (the best seen) and m *negative* samples. To
//! propose a candidate, a classifier learns an axis-parallel box around one positive that
//! holds no negative (see `sracos/classifier.rs`), and the candidate is that positive with a
//! few "uncertain" coordinates redrawn inside the box; with probability 1 − λ (ZOOpt's
//! `exploration_rate`, 0.01) the candidate is drawn uniformly from the whole search box
//! instead. RACOS keeps the model fixed for a batch of m candidates; SRACOS updates it after
//! every evaluation, which is what an episode-by-episode robot needs.
//!
//! # As in ZOOpt (continuous search space)
//! * **Start:** r = k + m distinct uniform samples; the best k are positive, the rest
//!   negative.
//! * **Classifier** (`mixed_classification`): shrink the box against randomly chosen
//!   negatives along randomly chosen coordinates until no negative is inside.
//! * **Sampling** (`rand_sample`): copy the positive, redraw `uncertain_bits` distinct random
//!   coordinates inside the box: ZOOpt's rule gives 1 for n ≤ 100, 2 for n ≤ 1000, 3 above
//!   ([`zoopt_uncertain_bits`]). With probability `exploration_rate` sample uniformly.
//! * **Distinct candidates:** a candidate equal to a stored sample is redrawn from the same
//!   box, up to 100 times.
//! * **SRACOS update** (`replace`): sorted insertion into the positive set by ZOOpt's
//!   `binary_search`: a cost equal to the best goes before it (so on a plateau of equal costs
//!   every newcomer enters and the search walks on), a cost equal to the worst (and above the
//!   best) after it, that is, out; ties in between go before. The r initial samples are
//!   sorted stably (ZOOpt's `selection`). The displaced worst positive (or the new sample
//!   itself, if no better than it) goes
//!   to the negative set by the [`Replacement`] strategy: WR replaces the worst negative if
//!   the newcomer is better (else drops the newcomer), RR a random negative, LM the negative
//!   farthest from the best sample.
//! * **RACOS update** (`selection`): after each batch of m evaluations, the best k of all
//!   stored and new samples become positive and the next best m negative.
//! * **Set sizes** from the budget ([`zoopt_set_sizes`], ZOOpt's `auto_set`): budget ≤ 50:
//!   (k, m) = (1, 3); ≤ 100: (1, 5); ≤ 1000: (2, 10); above: (2, 20). They are the type
//!   parameters `K` and `M` here, defaulting to (2, 10), ZOOpt's choice for 101–1000
//!   evaluations, the range of an episode budget on a robot.
//! * **Value suppression** (noise handling, [`Suppression`], off by default; ZOOpt's SSRACOS):
//!   after `non_update_allowed` consecutive samples that do not enter the positive set, every
//!   positive not re-evaluated before is evaluated `resample_times` more times and its value
//!   becomes `(1 − balance_rate)·value + balance_rate·mean`; the positives are re-sorted and
//!   the sample that triggered it is inserted last. The re-evaluations count against the
//!   budget. Under zero-mean noise one lucky episode then cannot hold a positive slot for
//!   ever; against rare one-sided flattering outliers it measured worse than no suppression
//!   (`experiments/findings/sracos.md`).
//!
//! # Documented deviations
//! * **Distinct-candidate fallback.** After 100 duplicate draws from the box ZOOpt starts a
//!   new iteration (new coin, new classifier) and ends the run after 100 such failures; here
//!   the candidate is then drawn uniformly from the whole search box (up to 100 times), and if
//!   even that finds only stored points the search reports [`Status::Converged`](super::Status::Converged) (ZOOpt's
//!   "sample space has been fully explored"). It takes a search box a few f32 steps wide.
//! * **LM** measures the margin from the best sample seen (the positive set's best), as the
//!   paper says; ZOOpt measures it from the best *negative*.
//! * **RR** draws its random slot in `ask` (the RNG comes in there; `tell` has none).
//! * **Budget.** `max_evaluations` is exact. ZOOpt's RACOS runs ⌊budget/m⌋ batches after the
//!   r initial samples, r evaluations over the budget. The paper's Algorithm 1 keeps only the
//!   positive set between batches (line 5); ZOOpt's `selection` (followed) keeps the best r.
//! * **Classifier cap**: learning stops after 4·m + 32 cuts (ZOOpt loops until done; see
//!   `sracos/classifier.rs`), and at most [`MAX_UNCERTAIN_BITS`] coordinates are redrawn.
//! * **Value suppression**: [`Optimizer::best`] stays the best cost *told* (the contract);
//!   the suppressed values are in [`Sracos::positives`], whose first entry is the candidate to
//!   trust under noise. ZOOpt's final answer re-evaluates the positives once more and picks the
//!   best re-evaluated one; that last step is left to the caller.
//! * Numbers are `f32`; random integers in `0..n` come from one `u32` by multiply-shift
//!   (bias below n/2³², invisible at these sizes).

use rand_core::RngCore;

use super::{Best, Bounds, Error, Ledger, Optimizer, Vector, unit_f32};
use super::{check_stopping, default_is_const, ledger_accessors, require};

mod classifier;

use classifier::Region;

/// The most coordinates one candidate may redraw (`uncertain_bits`); ZOOpt's automatic rule
/// uses at most 3 for continuous spaces.
pub const MAX_UNCERTAIN_BITS: usize = 16;

/// Draws from one learned box (and then uniformly) before a duplicate is given up on; ZOOpt's
/// limit.
const MAX_DRAWS: u32 = 100;

/// ZOOpt's budget-based set sizes `(k, m)`: k positive and m negative samples (training size
/// r = k + m), from its `Parameter.auto_set`. Pick the optimizer's `K` and `M` with it.
///
/// ```
/// use ctrl_adapt::optimizer::sracos::zoopt_set_sizes;
/// assert_eq!(zoopt_set_sizes(50), (1, 3));
/// assert_eq!(zoopt_set_sizes(100), (1, 5));
/// assert_eq!(zoopt_set_sizes(200), (2, 10)); // the default `Sracos<N>`
/// assert_eq!(zoopt_set_sizes(2000), (2, 20));
/// ```
pub const fn zoopt_set_sizes(budget: u32) -> (usize, usize) {
    match budget {
        0..=50 => (1, 3),
        51..=100 => (1, 5),
        101..=1000 => (2, 10),
        _ => (2, 20),
    }
}

/// ZOOpt's number of uncertain coordinates for a continuous space of dimension `n`
/// (`choose_ub`): 1 for n ≤ 100, 2 for n ≤ 1000, 3 above.
///
/// ```
/// use ctrl_adapt::optimizer::sracos::zoopt_uncertain_bits;
/// assert_eq!(zoopt_uncertain_bits(18), 1);
/// assert_eq!(zoopt_uncertain_bits(1000), 2);
/// assert_eq!(zoopt_uncertain_bits(1001), 3);
/// ```
pub const fn zoopt_uncertain_bits(n: usize) -> usize {
    if n <= 100 {
        1
    } else if n <= 1000 {
        2
    } else {
        3
    }
}

/// Whether `a == b`, testing the coordinates `first` before the rest. A classifier
/// candidate differs from its positive only in the uncertain coordinates, and the stored
/// samples are mostly such near-copies of each other, so a plain scan would run deep into
/// nearly every vector; testing the uncertain coordinates first usually settles it at once.
fn same<const N: usize>(a: &Vector<N>, b: &Vector<N>, first: &[usize]) -> bool {
    first.iter().all(|&i| a.get(i) == b.get(i)) && a.iter().zip(b.iter()).all(|(x, y)| x == y)
}

/// A uniform integer in `0..n` (`n ≥ 1`) by multiply-shift on one `u32`.
fn below<R: RngCore + ?Sized>(rng: &mut R, n: usize) -> usize {
    // The result is < n already; the `min` tells the compiler, so indexing with it needs no
    // bounds check (no panic path). n = 0 gives 0, as before.
    (((u64::from(rng.next_u32()) * n as u64) >> 32) as usize).min(n.saturating_sub(1))
}

/// How SRACOS puts the sample displaced from the positive set into the negative set
/// (the paper's `strategy_N`; the positive set always drops its worst).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Replacement {
    /// WR: replace the worst negative if the newcomer is better, else drop the newcomer
    /// (the paper's and ZOOpt's default).
    Worst,
    /// RR: replace a uniformly random negative.
    Random,
    /// LM: replace the negative farthest (Euclidean) from the best sample seen.
    LargestMargin,
}

/// Value suppression, ZOOpt's noise handling for SRACOS (SSRACOS); see the
/// [module docs](self).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Suppression {
    /// Consecutive samples that do not enter the positive set before the positives are
    /// re-evaluated (≥ 1).
    pub non_update_allowed: u32,
    /// Extra evaluations of each positive (≥ 1); they count against the budget.
    pub resample_times: u32,
    /// Weight of the re-evaluated mean in the new value, in [0, 1].
    pub balance_rate: f32,
}

impl Suppression {
    /// ZOOpt's defaults (500, 100, 0.5), meant for cheap simulated objectives. On a robot
    /// scale them to the episode budget: for 300 episodes, say, (30, 5, 0.5).
    pub const ZOOPT: Self = Self {
        non_update_allowed: 500,
        resample_times: 100,
        balance_rate: 0.5,
    };

    /// `Ok` when every field is in its range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        require(self.non_update_allowed != 0, "non_update_allowed")?;
        require(self.resample_times != 0, "resample_times")?;
        require((0.0..=1.0).contains(&self.balance_rate), "balance_rate")?;
        Ok(())
    }
}

/// The number of uncertain coordinates for dimension `n`, or an error if the configured one
/// exceeds `n`.
fn resolve_uncertain_bits(configured: Option<u8>, n: usize) -> Result<usize, Error> {
    match configured {
        None => Ok(zoopt_uncertain_bits(n).min(n)),
        Some(ub) if usize::from(ub) <= n => Ok(usize::from(ub)),
        Some(_) => Err(Error::InvalidParameter("uncertain_bits")),
    }
}

/// Parameters of [`Sracos`] and [`Racos`]; checked by [`SracosConfig::validate`] and the
/// constructors. RACOS uses the exploration rate, the uncertain bits and the budget; it has
/// no replacement strategy nor value suppression and refuses a configuration that asks for
/// either (`replacement` other than [`Replacement::Worst`], or a `suppression`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SracosConfig {
    /// 1 − λ ∈ [0, 1]: the probability of a uniform candidate from the whole box.
    pub exploration_rate: f32,
    /// Coordinates redrawn per candidate, 1..=[`MAX_UNCERTAIN_BITS`] and ≤ N;
    /// `None` for ZOOpt's rule [`zoopt_uncertain_bits`].
    pub uncertain_bits: Option<u8>,
    /// How the negative set takes the displaced sample.
    pub replacement: Replacement,
    /// Value suppression for noisy costs; `None` (off) by default.
    pub suppression: Option<Suppression>,
    /// Evaluations (episodes) allowed, ≥ 1, the r initial samples included.
    pub max_evaluations: u32,
}

impl SracosConfig {
    /// ZOOpt's defaults: exploration 0.01, automatic uncertain bits, WR, no suppression, and
    /// no budget limit.
    pub const DEFAULT: Self = Self {
        exploration_rate: 0.01,
        uncertain_bits: None,
        replacement: Replacement::Worst,
        suppression: None,
        max_evaluations: u32::MAX,
    };

    /// `Ok` when every parameter is in its range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        require(
            (0.0..=1.0).contains(&self.exploration_rate),
            "exploration_rate",
        )?;
        require(
            self.uncertain_bits
                .is_none_or(|ub| ub != 0 && usize::from(ub) <= MAX_UNCERTAIN_BITS),
            "uncertain_bits",
        )?;
        check_stopping(None, self.max_evaluations)?;
        match self.suppression {
            Some(s) => s.validate(),
            None => Ok(()),
        }
    }
}

default_is_const!(SracosConfig);

/// The configuration [`Racos`] used to take; RACOS now takes [`SracosConfig`], whose extra
/// fields it refuses away from their defaults. `RacosConfig::DEFAULT` and struct updates
/// from it still compile.
#[deprecated(since = "0.2.0", note = "RACOS takes `SracosConfig`")]
pub type RacosConfig = SracosConfig;

/// The accessors SRACOS and RACOS share: the configuration, the uncertain coordinates and
/// the classifier's two sets (documented per algorithm).
macro_rules! model_accessors {
    ($positives:literal, $negatives:literal) => {
        /// The configuration in use.
        pub fn config(&self) -> &SracosConfig {
            &self.model.config
        }

        /// The number of coordinates each classifier candidate redraws.
        pub fn uncertain_bits(&self) -> usize {
            self.model.uncertain_bits
        }

        #[doc = $positives]
        pub fn positives(&self) -> &[Best<N>] {
            self.model.archive.positives()
        }

        #[doc = $negatives]
        pub fn negatives(&self) -> &[Best<N>] {
            self.model.archive.negatives()
        }
    };
}

/// The positive and negative sets, filled by the r initial samples and then of fixed size.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Archive<const N: usize, const K: usize, const M: usize> {
    /// Sorted by cost (ties as in [`Archive::insert`]); the first `len.min(K)` are filled.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    positive: [Best<N>; K],
    /// Whether value suppression has re-evaluated `positive[i]` (moves with it).
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    resampled: [bool; K],
    /// Unordered; the first `len − K` are filled (once `len > K`).
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    negative: [Best<N>; M],
    /// Samples stored, ≤ K + M.
    len: usize,
}

impl<const N: usize, const K: usize, const M: usize> Archive<N, K, M> {
    /// The empty archive: a constant, copied straight into place (built at run time, its
    /// arrays would be assembled on the stack and then copied, 0.9 KB at N = 18).
    const EMPTY: Self = {
        let empty = Best {
            theta: crate::vector::zero::<N>(),
            cost: f32::INFINITY,
        };
        Self {
            positive: [empty; K],
            resampled: [false; K],
            negative: [empty; M],
            len: 0,
        }
    };

    fn is_full(&self) -> bool {
        self.len >= K + M
    }

    fn positives(&self) -> &[Best<N>] {
        &self.positive[..self.len.min(K)]
    }

    fn negatives(&self) -> &[Best<N>] {
        // len ≤ K + M, so the `min` changes nothing; it spares a bounds check (panic path).
        &self.negative[..self.len.saturating_sub(K).min(M)]
    }

    /// Whether `theta` equals a stored sample (exact f32 equality, as ZOOpt's 1e-17);
    /// see [`same`] for `first`.
    fn contains(&self, theta: &Vector<N>, first: &[usize]) -> bool {
        self.positives()
            .iter()
            .chain(self.negatives())
            .any(|e| same(&e.theta, theta, first))
    }

    /// The SRACOS update: sorted insertion into the positive set, then the displaced sample
    /// into the negative set by `replacement` (`slot` is RR's pre-drawn index). While the
    /// sets are filling, the displaced sample is simply appended.
    fn insert(&mut self, entry: Best<N>, replacement: Replacement, slot: usize) {
        self.insert_with(entry, replacement, slot, false);
    }

    /// [`Archive::insert`] as a stable sort (ties after equal costs, in arrival order): the
    /// r initial samples, and RACOS's `selection` over stored ∪ batch (inserted one by one
    /// with WR).
    fn insert_stable(&mut self, entry: Best<N>) {
        self.insert_with(entry, Replacement::Worst, 0, true);
    }

    fn insert_with(&mut self, entry: Best<N>, replacement: Replacement, slot: usize, stable: bool) {
        let filled = self.len.min(K);
        let costs = |i: usize| self.positive.get(i).map_or(f32::INFINITY, |p| p.cost);
        let at = if filled < K || stable {
            // A stable sort (ZOOpt's `selection`), ties in arrival order.
            self.positive[..filled].partition_point(|p| p.cost <= entry.cost)
        } else if entry.cost <= costs(0) {
            // ZOOpt's `binary_search`: a tie with the best goes *before* it, so on a plateau
            // of equal costs the newcomer joins the positive set and the search keeps moving
            // instead of stalling on its first positives.
            0
        } else if entry.cost >= costs(K - 1) {
            K
        } else {
            self.positive[..K].partition_point(|p| p.cost < entry.cost)
        };
        let displaced = if filled < K {
            self.shift_in(at, filled, entry);
            self.len += 1;
            return;
        } else if at >= K {
            entry
        } else {
            let worst = self.positive[K - 1];
            self.shift_in(at, K - 1, entry);
            worst
        };
        let stored = self.len - K;
        if stored < M {
            self.negative[stored] = displaced;
            self.len += 1;
            return;
        }
        match replacement {
            // The first worst (farthest) negative, its value carried along with its index
            // and the slot written through `get_mut`: no bounds check, no panic path.
            Replacement::Worst => {
                let mut worst = 0;
                let mut worst_cost = self.negative.first().map_or(f32::INFINITY, |e| e.cost);
                for (i, e) in self.negative.iter().enumerate() {
                    if e.cost > worst_cost {
                        (worst, worst_cost) = (i, e.cost);
                    }
                }
                if worst_cost > displaced.cost
                    && let Some(e) = self.negative.get_mut(worst)
                {
                    *e = displaced;
                }
            }
            Replacement::Random => self.negative[slot % M] = displaced,
            Replacement::LargestMargin => {
                let best = self.positive[0].theta;
                let mut farthest = 0;
                let mut distance = 0.0;
                for (i, e) in self.negative.iter().enumerate() {
                    let d = (e.theta - best).norm_squared();
                    if d > distance {
                        (farthest, distance) = (i, d);
                    }
                }
                if let Some(e) = self.negative.get_mut(farthest) {
                    *e = displaced;
                }
            }
        }
    }

    /// Moves `positive[at..end]` one place up (dropping `positive[end]`) and puts `entry`
    /// at `at`, with the re-evaluation flags alongside.
    fn shift_in(&mut self, at: usize, end: usize, entry: Best<N>) {
        // Callers pass at ≤ end < K; the test only spares `copy_within`'s assertions and
        // the bounds checks (panic paths).
        if at <= end && end < K {
            // `copy_within(at..end, at + 1)`, written out: its assertions are panic paths.
            let mut i = end;
            while i > at {
                self.positive[i] = self.positive[i - 1];
                self.resampled[i] = self.resampled[i - 1];
                i -= 1;
            }
            self.positive[at] = entry;
            self.resampled[at] = false;
        }
    }

    /// Re-sorts the (full) positive set after value suppression changed costs; stable.
    fn sort_positives(&mut self) {
        for i in 1..K {
            let mut j = i;
            while j > 0 && self.positive[j - 1].cost > self.positive[j].cost {
                self.positive.swap(j - 1, j);
                self.resampled.swap(j - 1, j);
                j -= 1;
            }
        }
    }

    /// The first positive at or after `from` not yet re-evaluated.
    fn next_unresampled(&self, from: usize) -> Option<usize> {
        (from..K).find(|&i| !self.resampled[i])
    }

    /// A new candidate: r distinct uniform samples first, then from the classifier with
    /// probability 1 − `exploration_rate`, else uniform; `is_new(x, first)` rejects
    /// duplicates (`first`: the coordinates to compare first, see [`same`]).
    /// `None` when no new point was found (see the module docs).
    // Never inlined: its region and candidate temporaries then live only while it runs,
    // not in the frame of every caller (a firmware loop that also tells).
    #[inline(never)]
    fn propose<R: RngCore + ?Sized>(
        &self,
        bounds: &Bounds<N>,
        exploration_rate: f32,
        uncertain_bits: usize,
        rng: &mut R,
        is_new: impl Fn(&Vector<N>, &[usize]) -> bool,
    ) -> Option<Vector<N>> {
        if self.is_full() && unit_f32(rng) < 1.0 - exploration_rate {
            let positive = self.positive[below(rng, K)].theta;
            let region = Region::learn(bounds, &positive, &self.negative, uncertain_bits, rng);
            for _ in 0..MAX_DRAWS {
                let x = region.sample(&positive, rng);
                if is_new(&x, region.dims()) {
                    return Some(x);
                }
            }
        }
        (0..MAX_DRAWS)
            .map(|_| bounds.sample_uniform(rng))
            .find(|x| is_new(x, &[]))
    }
}

/// What SRACOS is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
enum Phase<const N: usize> {
    /// Sampling new candidates (the r initial ones first).
    Search,
    /// Value suppression: re-evaluating `positive[slot]`, `told` of `resample_times` done
    /// with costs summing to `sum`; `held` is the sample that triggered it.
    Resample {
        slot: usize,
        told: u32,
        sum: f64,
        held: Best<N>,
    },
}

/// The classification model SRACOS and RACOS share: the box, the configuration, the number
/// of coordinates a classifier candidate redraws, and the positive and negative sets.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Model<const N: usize, const K: usize, const M: usize> {
    bounds: Bounds<N>,
    config: SracosConfig,
    uncertain_bits: usize,
    archive: Archive<N, K, M>,
}

impl<const N: usize, const K: usize, const M: usize> Model<N, K, M> {
    /// An empty model of `bounds` after checking `config`.
    fn try_new(bounds: Bounds<N>, config: SracosConfig) -> Result<Self, Error> {
        const {
            assert!(
                K >= 1 && M >= 1,
                "the model needs a positive and a negative sample"
            )
        };
        config.validate()?;
        Ok(Self {
            bounds,
            config,
            uncertain_bits: resolve_uncertain_bits(config.uncertain_bits, N)?,
            archive: Archive::EMPTY,
        })
    }

    /// A new candidate from the sets (see [`Archive::propose`]).
    fn propose<R: RngCore + ?Sized>(
        &self,
        rng: &mut R,
        is_new: impl Fn(&Vector<N>, &[usize]) -> bool,
    ) -> Option<Vector<N>> {
        let rate = self.config.exploration_rate;
        self.archive
            .propose(&self.bounds, rate, self.uncertain_bits, rng, is_new)
    }
}

#[cfg(feature = "serde")]
impl<const N: usize, const K: usize, const M: usize> Model<N, K, M> {
    /// The checks of a decoded model: the constructor's (box, configuration, the uncertain
    /// bits it resolves to) and the archive's: at most K + M samples, each stored sample
    /// finite, inside the box and of finite cost.
    fn check_decoded(&self) -> Result<(), Error> {
        self.bounds.check_decoded()?;
        self.config.validate()?;
        require(
            resolve_uncertain_bits(self.config.uncertain_bits, N)? == self.uncertain_bits,
            "uncertain_bits",
        )?;
        require(self.archive.len <= K + M, "len")?;
        check_samples(&self.bounds, self.archive.positives(), "positive")?;
        check_samples(&self.bounds, self.archive.negatives(), "negative")
    }
}

/// Every sample of `samples` finite, inside `bounds` and of finite cost, else an error
/// naming `field`.
#[cfg(feature = "serde")]
fn check_samples<const N: usize>(
    bounds: &Bounds<N>,
    samples: &[Best<N>],
    field: &'static str,
) -> Result<(), Error> {
    for sample in samples {
        bounds.check(&sample.theta, field)?;
        crate::error::require_finite([&sample.cost], field)?;
    }
    Ok(())
}

/// Sequential RACOS: classification-based optimisation that updates its model after every
/// evaluation, with `K` positive and `M` negative samples stored in place
/// ((K + M)·(4·N + 4) bytes plus a few hundred; 1.3 kB for N = 18 with the defaults).
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, Optimizer, Sracos, SracosConfig, Status};
/// use rand_core::SeedableRng;
///
/// let bounds = Bounds::<10>::uniform(-1.0, 1.0)?;
/// let config = SracosConfig { max_evaluations: 400, ..SracosConfig::DEFAULT };
/// // (K, M) = (2, 10): ZOOpt's set sizes for 101..=1000 evaluations, the default.
/// let mut search: Sracos<10> = Sracos::try_new(bounds, config)?;
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(7);
/// while search.status() == Status::Running {
///     let theta = search.ask(&mut rng)?;
///     let cost: f32 = theta.iter().map(|t| (t - 0.2) * (t - 0.2)).sum();
///     search.tell(cost)?;
/// }
/// assert_eq!(search.status(), Status::BudgetSpent);
/// // Uniform samples of this box cost 13.7 on average.
/// assert!(search.best().unwrap().cost < 0.5);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
///
/// One candidate at a time under [`InFlight`](super::InFlight) too (its
/// [`Generation`](super::Generation) room is 1): each candidate is drawn from the model the
/// cost before it updated.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Sracos<const N: usize, const K: usize = 2, const M: usize = 10> {
    model: Model<N, K, M>,
    /// RR's negative slot for the pending candidate, drawn in `ask`.
    slot: usize,
    /// Consecutive samples that did not enter the positive set (value suppression).
    non_update: u32,
    phase: Phase<N>,
    ledger: Ledger<N>,
}

impl<const N: usize, const K: usize, const M: usize> Sracos<N, K, M> {
    /// A search over `bounds` with `config`.
    pub fn try_new(bounds: Bounds<N>, config: SracosConfig) -> Result<Self, Error> {
        Ok(Self {
            model: Model::try_new(bounds, config)?,
            slot: 0,
            non_update: 0,
            phase: Phase::Search,
            ledger: Ledger::new(config.max_evaluations),
        })
    }

    /// As [`Self::try_new`], with `start` (finite, inside `bounds`, else
    /// [`Error::NonFinite`] / [`Error::OutOfBounds`] naming `"start"`) the first sample
    /// instead of a uniform draw: it is made the pending candidate, so the first `ask`
    /// returns it (and a record saved at once holds it, in the same format as any pending
    /// candidate), and it enters the sets like any sample.
    pub fn try_with_start(
        bounds: Bounds<N>,
        config: SracosConfig,
        start: Vector<N>,
    ) -> Result<Self, Error> {
        bounds.check(&start, "start")?;
        let mut search = Self::try_new(bounds, config)?;
        search.ledger.hand_out(start, &bounds);
        Ok(search)
    }

    model_accessors!(
        "The positive set, best first (fewer than `K` during the first samples). Under value \
         suppression the costs of re-evaluated entries are the suppressed ones, so the first \
         entry is the parameter vector to trust on a noisy plant.",
        "The negative set, unordered (empty until `K` samples are stored)."
    );

    /// Whether value suppression is re-evaluating the positives.
    pub fn is_resampling(&self) -> bool {
        matches!(self.phase, Phase::Resample { .. })
    }

    /// Value suppression's bookkeeping for a new sample; `Some(slot)` when the positives
    /// must be re-evaluated now, starting with `positive[slot]`.
    fn suppression_due(&mut self, cost: f32) -> Option<usize> {
        let s = self.model.config.suppression?;
        if !self.model.archive.is_full() {
            return None;
        }
        if cost < self.model.archive.positive[K - 1].cost {
            self.non_update = 0;
            return None;
        }
        self.non_update = self.non_update.saturating_add(1);
        if self.non_update < s.non_update_allowed {
            return None;
        }
        self.non_update = 0;
        self.model.archive.next_unresampled(0)
    }

    /// One more re-evaluation of `positive[slot]` told: blends once `resample_times` are in,
    /// then moves to the next positive or ends the round.
    fn resample(&mut self, slot: usize, told: u32, sum: f64, held: Best<N>) {
        let Some(s) = self.model.config.suppression else {
            return;
        };
        if told < s.resample_times {
            self.phase = Phase::Resample {
                slot,
                told,
                sum,
                held,
            };
            return;
        }
        if let Some(p) = self.model.archive.positive.get_mut(slot) {
            // In f64: the mean of finite f32 costs is finite, and the blend is convex.
            let mean = sum / f64::from(told);
            let b = f64::from(s.balance_rate);
            let blended = (1.0 - b) * f64::from(p.cost) + b * mean;
            p.cost = blended.clamp(f64::from(f32::MIN), f64::from(f32::MAX)) as f32;
            self.model.archive.resampled[slot] = true;
        }
        match self.model.archive.next_unresampled(slot + 1) {
            Some(next) => {
                self.phase = Phase::Resample {
                    slot: next,
                    told: 0,
                    sum: 0.0,
                    held,
                }
            }
            None => {
                self.model.archive.sort_positives();
                self.model
                    .archive
                    .insert(held, self.model.config.replacement, self.slot);
                self.phase = Phase::Search;
            }
        }
    }
}

#[cfg(feature = "serde")]
impl<const N: usize, const K: usize, const M: usize> Sracos<N, K, M> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the model's (see `Model::check_decoded`), RR's slot below M, value suppression's
    /// counter below its threshold, and a re-evaluation round only under suppression, on a
    /// full archive, at a positive below K, with fewer than `resample_times` costs told and
    /// a finite sum, and a held sample inside the box.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        self.model.check_decoded()?;
        require(self.slot < M, "slot")?;
        let suppression = self.model.config.suppression;
        require(
            suppression.is_none_or(|s| self.non_update < s.non_update_allowed),
            "non_update",
        )?;
        if let Phase::Resample {
            slot,
            told,
            sum,
            held,
        } = self.phase
        {
            let valid = suppression.is_some_and(|s| told < s.resample_times)
                && self.model.archive.is_full()
                && slot < K
                && sum.is_finite();
            require(valid, "phase")?;
            check_samples(&self.model.bounds, &[held], "held")?;
        }
        self.ledger.check_decoded(&self.model.bounds)
    }
}

impl<const N: usize, const K: usize, const M: usize> Optimizer<N> for Sracos<N, K, M> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        let theta = match self.phase {
            Phase::Resample { slot, .. } => self.model.archive.positive.get(slot).map(|p| p.theta),
            Phase::Search => {
                if self.model.config.replacement == Replacement::Random {
                    self.slot = below(rng, M);
                }
                let model = &self.model;
                model.propose(rng, |x, first| !model.archive.contains(x, first))
            }
        };
        self.ledger.hand_out_or_stop(theta, &self.model.bounds)
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        let theta = self.ledger.accept(cost)?;
        let entry = Best { theta, cost };
        match self.phase {
            Phase::Resample {
                slot,
                told,
                sum,
                held,
            } => self.resample(slot, told + 1, sum + f64::from(cost), held),
            Phase::Search => match self.suppression_due(cost) {
                Some(slot) => {
                    self.phase = Phase::Resample {
                        slot,
                        told: 0,
                        sum: 0.0,
                        held: entry,
                    }
                }
                None => self
                    .model
                    .archive
                    .insert(entry, self.model.config.replacement, self.slot),
            },
        }
        self.ledger.settle();
        Ok(())
    }

    ledger_accessors!(model.bounds);
}

/// Batch-mode RACOS (the paper's Algorithm 1 as ZOOpt runs it): the model is fixed while a
/// batch of `M` candidates is evaluated, then the best `K` of everything become positive and
/// the next `M` negative. One candidate per `ask` all the same; the batch is stored in place,
/// so the state is (K + 2M) samples.
///
/// One candidate at a time under [`InFlight`](super::InFlight) too: a candidate equal to one
/// told in the batch is refused, so the batch's candidates depend on the told costs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Racos<const N: usize, const K: usize = 2, const M: usize = 10> {
    model: Model<N, K, M>,
    /// This batch's evaluated samples, the first `batch_len`.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    batch: [Best<N>; M],
    batch_len: usize,
    ledger: Ledger<N>,
}

impl<const N: usize, const K: usize, const M: usize> Racos<N, K, M> {
    /// A search over `bounds` with `config`.
    pub fn try_new(bounds: Bounds<N>, config: SracosConfig) -> Result<Self, Error> {
        require(config.replacement == Replacement::Worst, "replacement")?;
        require(config.suppression.is_none(), "suppression")?;
        Ok(Self {
            model: Model::try_new(bounds, config)?,
            batch: Archive::<N, K, M>::EMPTY.negative,
            batch_len: 0,
            ledger: Ledger::new(config.max_evaluations),
        })
    }

    model_accessors!(
        "The positive set of the current batch's model, best first.",
        "The negative set of the current batch's model, unordered."
    );
}

#[cfg(feature = "serde")]
impl<const N: usize, const K: usize, const M: usize> Racos<N, K, M> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (WR, no suppression), the model's (see `Model::check_decoded`), and
    /// the batch's: fewer than M samples, only once the archive is full, each inside the
    /// box and of finite cost.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        let config = &self.model.config;
        require(config.replacement == Replacement::Worst, "replacement")?;
        require(config.suppression.is_none(), "suppression")?;
        self.model.check_decoded()?;
        require(
            self.batch_len < M && (self.batch_len == 0 || self.model.archive.is_full()),
            "batch_len",
        )?;
        let batch = self.batch.get(..self.batch_len).unwrap_or(&[]);
        check_samples(&self.model.bounds, batch, "batch")?;
        self.ledger.check_decoded(&self.model.bounds)
    }
}

impl<const N: usize, const K: usize, const M: usize> Optimizer<N> for Racos<N, K, M> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        // batch_len ≤ M: `get` always succeeds and spares a bounds check (panic path).
        let batch = self.batch.get(..self.batch_len).unwrap_or(&[]);
        let archive = &self.model.archive;
        let theta = self.model.propose(rng, |x, first| {
            !archive.contains(x, first) && !batch.iter().any(|e| same(&e.theta, x, first))
        });
        self.ledger.hand_out_or_stop(theta, &self.model.bounds)
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        let theta = self.ledger.accept(cost)?;
        let entry = Best { theta, cost };
        if !self.model.archive.is_full() {
            self.model.archive.insert_stable(entry);
        } else if let Some(slot) = self.batch.get_mut(self.batch_len) {
            *slot = entry;
            self.batch_len += 1;
            if self.batch_len >= M {
                // Inserting one by one with WR keeps the best K positive and the next best
                // M negative: ZOOpt's `selection` over stored ∪ batch.
                for e in self.batch {
                    self.model.archive.insert_stable(e);
                }
                self.batch_len = 0;
            }
        }
        self.ledger.settle();
        Ok(())
    }

    ledger_accessors!(model.bounds);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::Status;
    use crate::testing::{any_bounds, check_any_costs, check_rejected_configs, rng};
    use proptest::prelude::*;

    fn sracos<const N: usize, const K: usize, const M: usize>(
        config: SracosConfig,
    ) -> Sracos<N, K, M> {
        Sracos::try_new(Bounds::uniform(-1.0, 1.0).unwrap(), config).unwrap()
    }

    fn sphere<const N: usize>(t: &Vector<N>) -> f32 {
        t.iter().map(|v| (v - 0.2) * (v - 0.2)).sum()
    }

    /// Costs of a set, sorted.
    fn sorted_costs(set: &[Best<3>]) -> Vec<f32> {
        let mut c: Vec<f32> = set.iter().map(|e| e.cost).collect();
        c.sort_by(f32::total_cmp);
        c
    }

    /// Checks: the first r = K + M candidates are distinct and inside the box; once they are
    /// told, the positive set is the best K (sorted) and the negative set the other M.
    #[test]
    fn initial_samples_split_into_best_k_and_the_rest() {
        let mut s = sracos::<3, 2, 4>(SracosConfig::DEFAULT);
        let mut r = rng(1);
        let costs = [5.0, 1.0, 4.0, 0.5, 3.0, 2.0];
        let mut seen = Vec::new();
        for c in costs {
            let t = s.ask(&mut r).unwrap();
            assert!(s.bounds().contains(&t));
            assert!(!seen.contains(&t));
            seen.push(t);
            s.tell(c).unwrap();
        }
        let pos: Vec<f32> = s.positives().iter().map(|e| e.cost).collect();
        assert_eq!(pos, [0.5, 1.0]);
        assert_eq!(sorted_costs(s.negatives()), [2.0, 3.0, 4.0, 5.0]);
        assert_eq!(s.positives()[0].theta, seen[3]);
    }

    /// Checks ZOOpt's tie rule on a plateau: once both positives cost the same, a newcomer
    /// of that cost enters the positive set first and the older second positive moves to
    /// the negative set (without it the search stalls on a plateau of equal costs); a
    /// newcomer tying only the worst positive stays out.
    #[test]
    fn a_tie_with_the_best_enters_the_positive_set_first() {
        let mut s = sracos::<3, 2, 3>(SracosConfig::DEFAULT);
        let mut r = rng(4);
        let mut told = Vec::new();
        for c in [1.0, 1.0, 3.0, 4.0, 5.0] {
            told.push(s.ask(&mut r).unwrap());
            s.tell(c).unwrap();
        }
        assert_eq!(s.positives()[1].theta, told[1]);
        let tie = s.ask(&mut r).unwrap();
        s.tell(1.0).unwrap();
        assert_eq!(s.positives()[0].theta, tie);
        assert_eq!(s.positives()[1].theta, told[0]);
        assert!(s.negatives().iter().any(|e| e.theta == told[1]));
        assert_eq!(sorted_costs(s.negatives()), [1.0, 3.0, 4.0]);

        // Positives now cost 1 and 1; make the worst one 2 by a better newcomer, then tie it.
        s.ask(&mut r).unwrap();
        s.tell(0.5).unwrap();
        let before = s.positives().to_vec();
        let worst_tie = s.ask(&mut r).unwrap();
        s.tell(1.0).unwrap();
        assert_eq!(s.positives(), before.as_slice());
        // Out of the positive set, it replaced the worst negative (3) by WR.
        assert!(s.negatives().iter().any(|e| e.theta == worst_tie));
        assert_eq!(sorted_costs(s.negatives()), [1.0, 1.0, 1.0]);
    }

    /// Checks: with exploration off, every candidate after the start is a stored positive
    /// with at most `uncertain_bits` coordinates changed.
    #[test]
    fn classifier_candidates_redraw_only_uncertain_coordinates() {
        let config = SracosConfig {
            exploration_rate: 0.0,
            uncertain_bits: Some(2),
            ..SracosConfig::DEFAULT
        };
        let mut s = sracos::<8, 2, 10>(config);
        let mut r = rng(2);
        for i in 0..400 {
            let positives: Vec<Vector<8>> = s.positives().iter().map(|e| e.theta).collect();
            let t = s.ask(&mut r).unwrap();
            if i >= 12 {
                let changed = |p: &Vector<8>| (0..8).filter(|&d| t[d] != p[d]).count();
                assert!(positives.iter().any(|p| changed(p) <= 2), "candidate {i}");
            }
            s.tell(sphere(&t)).unwrap();
        }
    }

    /// Checks the coin: with the default exploration rate 0.01, about 1% of candidates are
    /// uniform draws (far from every positive in many coordinates): between 0.3% and 2%
    /// of 3000.
    #[test]
    fn about_one_percent_of_candidates_are_uniform() {
        let mut s = sracos::<20, 2, 10>(SracosConfig::DEFAULT);
        let mut r = rng(3);
        let mut uniform = 0;
        for i in 0..3012 {
            let positives: Vec<Vector<20>> = s.positives().iter().map(|e| e.theta).collect();
            let t = s.ask(&mut r).unwrap();
            let changed = |p: &Vector<20>| (0..20).filter(|&d| t[d] != p[d]).count();
            if i >= 12 && positives.iter().all(|p| changed(p) > 1) {
                uniform += 1;
            }
            s.tell(sphere(&t)).unwrap();
        }
        assert!((9..=60).contains(&uniform), "{uniform} uniform candidates");
    }

    /// Drives `s` through the start and returns it with fixed costs 1..=r.
    fn filled<const K: usize, const M: usize>(replacement: Replacement) -> Sracos<3, K, M> {
        let mut s = sracos::<3, K, M>(SracosConfig {
            replacement,
            ..SracosConfig::DEFAULT
        });
        let mut r = rng(4);
        for c in 1..=K + M {
            s.ask(&mut r).unwrap();
            s.tell(c as f32).unwrap();
        }
        s
    }

    /// Checks WR: a sample worse than every negative is dropped; one that displaces a
    /// positive sends that positive to replace the worst negative.
    #[test]
    fn wr_replaces_the_worst_negative_only_by_a_better_sample() {
        let mut s = filled::<2, 3>(Replacement::Worst);
        let mut r = rng(5);
        let before = *s.negatives().first().unwrap();
        s.ask(&mut r).unwrap();
        s.tell(9.0).unwrap();
        assert_eq!(sorted_costs(s.negatives()), [3.0, 4.0, 5.0]);
        assert!(s.negatives().contains(&before));
        let t = s.ask(&mut r).unwrap();
        s.tell(0.5).unwrap();
        assert_eq!(
            s.positives()[0],
            Best {
                theta: t,
                cost: 0.5
            }
        );
        assert_eq!(sorted_costs(s.positives()), [0.5, 1.0]);
        assert_eq!(sorted_costs(s.negatives()), [2.0, 3.0, 4.0]);
    }

    /// Checks RR: the displaced sample replaces the negative in the slot drawn at `ask`,
    /// even when it is worse than that negative.
    #[test]
    fn rr_replaces_the_slot_drawn_at_ask() {
        let mut s = filled::<1, 4>(Replacement::Random);
        let mut r = rng(6);
        for _ in 0..20 {
            let negatives = s.negatives().to_vec();
            let t = s.ask(&mut r).unwrap();
            let slot = s.slot;
            s.tell(100.0).unwrap();
            for (i, (a, b)) in negatives.iter().zip(s.negatives()).enumerate() {
                if i == slot {
                    assert_eq!(
                        *b,
                        Best {
                            theta: t,
                            cost: 100.0
                        }
                    );
                } else {
                    assert_eq!(a, b);
                }
            }
        }
    }

    /// Checks LM: the displaced sample replaces the negative farthest from the best sample.
    #[test]
    fn lm_replaces_the_negative_farthest_from_the_best() {
        let mut s = filled::<2, 4>(Replacement::LargestMargin);
        let mut r = rng(7);
        for _ in 0..20 {
            let best = s.positives()[0].theta;
            let negatives = s.negatives().to_vec();
            let far = (0..4)
                .max_by(|&a, &b| {
                    let d = |i: usize| (negatives[i].theta - best).norm_squared();
                    d(a).total_cmp(&d(b))
                })
                .unwrap();
            let t = s.ask(&mut r).unwrap();
            s.tell(100.0).unwrap();
            assert_eq!(
                s.negatives()[far],
                Best {
                    theta: t,
                    cost: 100.0
                }
            );
        }
    }

    /// Checks RACOS: after the start, the model stays fixed for M − 1 tells and is replaced,
    /// at the M-th, by the best K (positive) and next best M (negative) of everything.
    #[test]
    fn racos_keeps_its_model_for_a_batch() {
        let mut s: Racos<3, 2, 4> =
            Racos::try_new(Bounds::uniform(-1.0, 1.0).unwrap(), SracosConfig::DEFAULT).unwrap();
        let mut r = rng(8);
        let mut all = Vec::new();
        for i in 0..6 + 4 * 5 {
            let model = (s.positives().to_vec(), s.negatives().to_vec());
            let t = s.ask(&mut r).unwrap();
            let cost = ((i * 37) % 23) as f32;
            s.tell(cost).unwrap();
            all.push(Best { theta: t, cost });
            if i >= 6 && (i - 6) % 4 != 3 {
                assert_eq!((s.positives().to_vec(), s.negatives().to_vec()), model);
            } else if i >= 5 {
                let mut costs: Vec<f32> = all.iter().map(|e| e.cost).collect();
                costs.sort_by(f32::total_cmp);
                assert_eq!(sorted_costs(s.positives()), costs[..2]);
                assert_eq!(sorted_costs(s.negatives()), costs[2..6]);
            }
        }
    }

    /// Checks value suppression step by step: after `non_update_allowed` samples that do not
    /// enter the positive set, each positive is asked again `resample_times` times, its cost
    /// becomes the blend, the positives are re-sorted, the held sample goes in last, and
    /// re-evaluated positives are not re-evaluated at the next trigger.
    #[test]
    fn value_suppression_reevaluates_and_blends() {
        let config = SracosConfig {
            suppression: Some(Suppression {
                non_update_allowed: 2,
                resample_times: 2,
                balance_rate: 0.5,
            }),
            ..SracosConfig::DEFAULT
        };
        let mut s = sracos::<3, 2, 3>(config);
        let mut r = rng(9);
        for c in [1.0, 2.0, 3.0, 4.0, 5.0] {
            s.ask(&mut r).unwrap();
            s.tell(c).unwrap();
        }
        let (p0, p1) = (s.positives()[0].theta, s.positives()[1].theta);
        s.ask(&mut r).unwrap();
        s.tell(2.0).unwrap(); // ties the worst positive: no update
        assert!(!s.is_resampling());
        let held = s.ask(&mut r).unwrap();
        s.tell(3.5).unwrap();
        assert!(s.is_resampling());
        // p0 (cost 1) re-evaluated at 6 and 8: 0.5·1 + 0.5·7 = 4; p1 (cost 2) at 2 and 2: 2.
        for (expect, cost) in [(p0, 6.0), (p0, 8.0), (p1, 2.0), (p1, 2.0)] {
            assert_eq!(s.ask(&mut r).unwrap(), expect);
            s.tell(cost).unwrap();
        }
        assert!(!s.is_resampling());
        assert_eq!(
            s.positives(),
            [
                Best {
                    theta: p1,
                    cost: 2.0
                },
                Best {
                    theta: held,
                    cost: 3.5
                }
            ]
        );
        assert_eq!(sorted_costs(s.negatives()), [2.0, 3.0, 4.0]);
        assert_eq!(s.evaluations(), 11);
        // The best told cost is still the raw 1.0 (the contract); p0 now carries 4.
        assert_eq!(s.best().unwrap().cost, 1.0);
        // Next trigger: p1 is done, only the held sample (new at slot 1) is re-evaluated.
        for _ in 0..2 {
            s.ask(&mut r).unwrap();
            s.tell(50.0).unwrap();
        }
        assert!(s.is_resampling());
        assert_eq!(s.ask(&mut r).unwrap(), held);
    }

    /// Checks the duplicate fallback: in a box holding only two f32 values per coordinate
    /// (1-D), once both are stored no new candidate exists and the search reports Converged
    /// instead of repeating a point; RACOS alike.
    #[test]
    fn a_box_without_new_points_converges() {
        let bounds = Bounds::<1>::try_new([1.0].into(), [1.0 + f32::EPSILON].into()).unwrap();
        let mut s: Sracos<1, 1, 1> = Sracos::try_new(bounds, SracosConfig::DEFAULT).unwrap();
        let mut q: Racos<1, 1, 1> = Racos::try_new(bounds, SracosConfig::DEFAULT).unwrap();
        let mut r = rng(10);
        let a = s.ask(&mut r).unwrap();
        s.tell(1.0).unwrap();
        let b = s.ask(&mut r).unwrap();
        s.tell(2.0).unwrap();
        assert_ne!(a, b);
        assert_eq!(s.ask(&mut r), Err(Error::Stopped));
        assert_eq!(s.status(), Status::Converged);
        for c in [1.0, 2.0] {
            q.ask(&mut r).unwrap();
            q.tell(c).unwrap();
        }
        assert_eq!(q.ask(&mut r), Err(Error::Stopped));
        assert_eq!(q.status(), Status::Converged);
    }

    /// Checks: tell before ask, repeated ask, budget exhaustion and ask after the stop.
    #[test]
    fn call_order_errors_and_idempotent_ask() {
        let mut s = sracos::<2, 1, 3>(SracosConfig {
            max_evaluations: 6,
            ..SracosConfig::DEFAULT
        });
        let mut r = rng(11);
        assert_eq!(s.tell(1.0), Err(Error::NoPendingAsk));
        for i in 0..6 {
            let t = s.ask(&mut r).unwrap();
            assert_eq!(s.ask(&mut r).unwrap(), t);
            assert_eq!(s.pending(), Some(&t));
            s.tell(i as f32).unwrap();
            assert_eq!(s.tell(1.0), Err(Error::NoPendingAsk));
        }
        assert_eq!(s.status(), Status::BudgetSpent);
        assert_eq!(s.ask(&mut r), Err(Error::Stopped));
        assert_eq!(s.best().unwrap().cost, 0.0);
    }

    /// Checks: the same seed gives the same candidates for each strategy and RACOS, another
    /// seed different ones.
    #[test]
    fn identical_seeds_give_identical_runs() {
        fn trace<O: Optimizer<4>>(mut o: O, seed: u64) -> Vec<Vector<4>> {
            let mut r = rng(seed);
            (0..200)
                .map(|_| {
                    let t = o.ask(&mut r).unwrap();
                    o.tell(sphere(&t)).unwrap();
                    t
                })
                .collect()
        }
        for replacement in [
            Replacement::Worst,
            Replacement::Random,
            Replacement::LargestMargin,
        ] {
            let s = sracos::<4, 2, 5>(SracosConfig {
                replacement,
                ..SracosConfig::DEFAULT
            });
            assert_eq!(trace(s, 1), trace(s, 1));
            assert_ne!(trace(s, 1), trace(s, 2));
        }
        let q: Racos<4> =
            Racos::try_new(Bounds::uniform(-1.0, 1.0).unwrap(), SracosConfig::DEFAULT).unwrap();
        assert_eq!(trace(q, 1), trace(q, 1));
        assert_ne!(trace(q, 1), trace(q, 2));
    }

    /// Checks that each invalid parameter is rejected by name, by SRACOS and by RACOS (which
    /// also refuses a replacement strategy or value suppression).
    #[test]
    fn constructors_name_the_bad_parameter() {
        let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        check_rejected_configs(
            SracosConfig::DEFAULT,
            |c| Sracos::<3>::try_new(b, c),
            &[
                (|c| c.exploration_rate = -0.1, "exploration_rate"),
                (|c| c.exploration_rate = 1.1, "exploration_rate"),
                (|c| c.exploration_rate = f32::NAN, "exploration_rate"),
                (|c| c.uncertain_bits = Some(0), "uncertain_bits"),
                (|c| c.uncertain_bits = Some(17), "uncertain_bits"),
                (|c| c.uncertain_bits = Some(4), "uncertain_bits"),
                (|c| c.max_evaluations = 0, "max_evaluations"),
            ],
        );
        let e = Error::InvalidParameter;
        let with = |s: Suppression| {
            let c = SracosConfig {
                suppression: Some(s),
                ..SracosConfig::DEFAULT
            };
            Sracos::<3>::try_new(b, c).unwrap_err()
        };
        let z = Suppression::ZOOPT;
        assert_eq!(
            with(Suppression {
                non_update_allowed: 0,
                ..z
            }),
            e("non_update_allowed")
        );
        assert_eq!(
            with(Suppression {
                resample_times: 0,
                ..z
            }),
            e("resample_times")
        );
        assert_eq!(
            with(Suppression {
                balance_rate: 1.5,
                ..z
            }),
            e("balance_rate")
        );
        // RACOS checks the same fields and refuses the two it has no use for.
        check_rejected_configs(
            SracosConfig::DEFAULT,
            |c| Racos::<3>::try_new(b, c),
            &[
                (|c| c.uncertain_bits = Some(4), "uncertain_bits"),
                (|c| c.exploration_rate = 1.1, "exploration_rate"),
                (|c| c.replacement = Replacement::Random, "replacement"),
                (|c| c.suppression = Some(Suppression::ZOOPT), "suppression"),
            ],
        );
        assert_eq!(
            Sracos::<3>::try_new(b, SracosConfig::DEFAULT)
                .unwrap()
                .uncertain_bits(),
            1
        );
    }

    fn any_replacement() -> impl Strategy<Value = Replacement> {
        prop_oneof![
            Just(Replacement::Worst),
            Just(Replacement::Random),
            Just(Replacement::LargestMargin)
        ]
    }

    proptest! {
        /// Checks, for random boxes, strategies, seeds and cost sequences (any f32): every
        /// candidate is inside the box; the positive set always holds the K best costs told
        /// (with WR the negative set the next M); a non-finite cost is rejected and leaves
        /// the whole optimizer unchanged; the best cost never increases.
        #[test]
        fn sracos_invariants(
            bounds in any_bounds::<3>(1e-2),
            replacement in any_replacement(),
            seed in any::<u64>(),
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..200),
        ) {
            let config = SracosConfig { replacement, ..SracosConfig::DEFAULT };
            let mut s: Sracos<3, 2, 4> = Sracos::try_new(bounds, config).unwrap();
            let mut told = Vec::new();
            check_any_costs(&mut s, &bounds, &costs, seed, |s, cost| {
                if cost.is_finite() {
                    told.push(cost);
                }
                let mut sorted = told.clone();
                sorted.sort_by(f32::total_cmp);
                let k = sorted.len().min(2);
                prop_assert_eq!(sorted_costs(s.positives()), &sorted[..k]);
                if replacement == Replacement::Worst {
                    let m = sorted.len().min(6);
                    prop_assert_eq!(sorted_costs(s.negatives()), &sorted[k..m]);
                }
                prop_assert_eq!(s.best().map(|b| b.cost), sorted.first().copied());
                Ok(())
            })?;
        }

        /// Checks the same for RACOS, with the positive set checked after each batch.
        #[test]
        fn racos_invariants(
            bounds in any_bounds::<3>(1e-2),
            seed in any::<u64>(),
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..200),
        ) {
            let mut s: Racos<3, 2, 4> = Racos::try_new(bounds, SracosConfig::DEFAULT).unwrap();
            let mut told = Vec::new();
            check_any_costs(&mut s, &bounds, &costs, seed, |s, cost| {
                if cost.is_finite() {
                    told.push(cost);
                }
                if s.batch_len == 0 {
                    let mut sorted = told.clone();
                    sorted.sort_by(f32::total_cmp);
                    let k = sorted.len().min(2);
                    prop_assert_eq!(sorted_costs(s.positives()), &sorted[..k]);
                    prop_assert_eq!(sorted_costs(s.negatives()), &sorted[k..sorted.len().min(6)]);
                }
                Ok(())
            })?;
        }

        /// Checks, with value suppression on (small thresholds so it triggers): candidates
        /// stay inside the box, bad costs change nothing, and the positive set stays sorted.
        #[test]
        fn suppression_keeps_the_contract(
            seed in any::<u64>(),
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..300),
        ) {
            let config = SracosConfig {
                suppression: Some(Suppression {
                    non_update_allowed: 3,
                    resample_times: 2,
                    balance_rate: 0.7,
                }),
                ..SracosConfig::DEFAULT
            };
            let mut s: Sracos<3, 2, 4> = sracos(config);
            let bounds = *s.bounds();
            check_any_costs(&mut s, &bounds, &costs, seed, |s, _| {
                prop_assert!(s.positives().windows(2).all(|w| w[0].cost <= w[1].cost)
                    || s.is_resampling());
                prop_assert!(s.positives().iter().all(|p| p.cost.is_finite()));
                Ok(())
            })?;
        }
    }
}
