//! LineBO, Bayesian optimisation on one-dimensional subspaces, with SafeOpt on each line:
//! after J. Kirschner, M. Mutný, N. Hiller, R. Ischebeck and A. Krause, "Adaptive and Safe
//! Bayesian Optimization in High Dimensions via One-Dimensional Subspaces" (ICML 2019), and,
//! for the safe variant, Y. Sui, A. Gotovos, J. Burdick and A. Krause, "Safe Exploration for
//! Optimization with Gaussian Processes" (ICML 2015) in the form of F. Berkenkamp,
//! A. Schoellig and A. Krause, "Safe Controller Optimization for Quadrotors with Gaussian
//! Processes" (ICRA 2016) and of the authors' `safeopt` package (confidence intervals from
//! the GP alone, no Lipschitz constant). The details the papers leave open follow the
//! LineBO authors' code (`febo`, `subdomainbo`), reimplemented here, not copied.
//!
//! One global Gaussian process models the cost over the whole box (its kernel, incremental
//! Cholesky factor and eviction rule are [below](#the-gaussian-process)). The search runs a
//! sequence of lines:
//!
//! 1. θ⁰ is evaluated first; its cost is the GP's prior mean.
//! 2. A line through the current origin o (θ⁰ at first) along a direction d: the coordinate
//!    axes in turn (`CoordinateLineBO`) or a uniformly random direction in the normalised
//!    box (`RandomLineBO`), cut to the box, t ∈ [t₋, t₊].
//! 3. On the line, `evaluations_per_line` episodes, each at the grid point chosen by
//!    * **without a threshold**, GP-UCB for minimisation: the lowest lower confidence bound
//!      l(x) = μ(x) − β σ(x);
//!    * **with a threshold h**, SafeOpt on the line: the safe set S is the interval of grid
//!      points around o whose upper bound u(x) = μ(x) + β σ(x) is ≤ h (θ⁰ is safe by
//!      assumption); the minimisers M = {x ∈ S : l(x) ≤ min_S u}; the expanders G, the
//!      points of S whose optimistic observation (a fictitious cost l(x) at x) would bring
//!      the upper bound of an unsafe neighbour of S to ≤ h; the episode goes to the point of
//!      M ∪ G with the widest interval u − l.
//! 4. The next origin is the minimiser of the posterior mean μ on the line (within S with
//!    a threshold), as the authors' code does; go to 2.
//!
//! # β and what the safety guarantee covers
//! β scales the confidence intervals μ ± βσ. The theorems (Sui et al., theorem 1) hold with
//! probability 1 − δ when the cost is a sample of the GP (or has a bounded norm in its
//! RKHS), the kernel and noise are the true ones, and β grows like √log(t/δ); practice,
//! the `safeopt` package and Berkenkamp et al. use a constant β = 2 to 3 (default 2). The
//! guarantee is about the *latent* cost, the noise-free mean of an episode: a single noisy
//! episode can exceed h. It is void when the kernel is misspecified (a length scale longer
//! than the cost's, a signal variance too small, or noise larger than configured), and it
//! rests on θ⁰ being safe. Within those limits every candidate of the safe variant after θ⁰
//! has u(x) ≤ h when it is proposed, or is θ⁰ again: when a line's safe set is empty (its
//! origin, a point that passed the test on the line before, no longer does), the line is
//! abandoned, θ⁰ is proposed and the next line starts from it.
//!
//! # Hyperparameters, and a rule to choose them
//! * `length_scale` ℓ, relative to the box's width: the distance over which the cost
//!   changes by about σ_f. Default 0.25 (ours).
//! * `signal_variance` σ_f², in cost units²: the square of the typical difference between
//!   the cost at θ⁰ and across the box (for a controller, about the square of the start's
//!   cost when a bad θ can double it). Default 1.
//! * `noise_variance` σ_n², in cost units²: the variance of repeated episodes at one θ.
//!   Default 10⁻².
//! * `jitter`: added to σ_n² relative to σ_f², 10⁻⁴ by default; it bounds the Cholesky
//!   factor's conditioning in f32.
//!
//! # Choices the papers leave open, and deviations
//! * **Fixed grid.** The line subproblem is solved on `GRID` = 64 equally spaced points of
//!   the line inside the box, the point nearest o moved onto o (the authors' code uses 300
//!   grid points for the acquisition and 300 for the safe set). 64 keeps the posterior pass
//!   at 64 triangular solves per episode on a microcontroller, and resolves the line to
//!   1/64 of its length, finer than ℓ. The grid of the k-th line is shifted by frac(k/φ) of
//!   a cell, so that successive lines along one axis do not sample the same lattice and
//!   the optimum is resolved finer than a cell over several lines.
//! * **Evaluations per line.** The authors' code spends 10 to 30 evaluations per line and
//!   ends a line early when its optimum is known within 1 %; on a robot every episode
//!   counts, so here each line takes a fixed `evaluations_per_line` (default 3), and the
//!   origin is not evaluated again at the start of each line (the code's "best" step).
//! * **Safe set on the line.** As the authors' code: only the interval connected to o
//!   counts, so only the two unsafe grid points next to it can extend it, and the expander
//!   test checks those two (the `safeopt` package checks every unsafe point; on a line the
//!   farther ones cannot change the connected set). The selection is Sui et al.'s
//!   (widest interval over M ∪ G); the LineBO code instead compares the safe acquisition
//!   point with one expander in the acquisition's direction.
//! * **No contraction of the intervals.** As the `safeopt` package without a Lipschitz
//!   constant, the intervals are recomputed from the GP, not intersected with the earlier
//!   ones (the grid changes from line to line).
//! * **Capacity.** The GP remembers `M` episodes (const generic, no heap); beyond that it
//!   evicts (see [below](#the-gaussian-process)). With M ≥ the budget nothing is ever
//!   evicted.
//! * **f32** throughout: the Cortex-M4F has a single-precision FPU.
//! * **No stopping test.** Like the authors' code, the search runs until its budget
//!   (`max_evaluations`, then [`Status::BudgetSpent`](super::Status)); it never reports
//!   `Converged`.
//!
//! # The Gaussian process
//! A zero-mean GP on the cost minus a prior mean, with a squared-exponential kernel on the
//! normalised parameters, over at most `M` remembered episodes (Rasmussen & Williams,
//! "Gaussian Processes for Machine Learning", 2006, algorithm 2.1, with the factor kept up
//! to date point by point).
//!
//! * **Kernel.** k(x, x') = σ_f² exp(−‖x − x'‖² / (2ℓ²)) on x ∈ [−1, 1]ⁿ, ℓ = 2 × the
//!   configured length scale (which is relative to the box's width).
//! * **Noise and jitter.** The observations carry the variance σ_n² + jitter·σ_f²: the
//!   jitter keeps every pivot of the Cholesky factor of K + σ²I at least that large in
//!   exact arithmetic, so that f32 rounding (relative 6·10⁻⁸ per operation, a few 10⁻⁶
//!   over a 64-term sum) cannot make it indefinite.
//! * **Appending** a point costs one forward substitution, O(n²): the new row of L is
//!   L⁻¹k(X, x) and its pivot the Schur complement k(x, x) + σ² − ‖L⁻¹k‖². A pivot that
//!   rounding has pushed below half its theoretical floor σ² triggers a refactorisation
//!   from the kernel matrix, O(n³/6), in which any pivot below σ² is replaced by σ². L is
//!   stored by rows, so that the forward substitution of every posterior (one per grid
//!   point) reads contiguous memory.
//! * **Eviction.** With `M` points held, the point least correlated with the point the
//!   search is working around (the current line's origin), that is the farthest from it in
//!   the kernel's metric, is dropped: its row and column leave L, and the block below
//!   absorbs its column by a rank-one update (rotations that only raise the pivots), O(n²)
//!   instead of a refactorisation's O(n³); the factor is that of the kept points up to
//!   rounding. Near points decide the line the
//!   search works on; a far point adds almost nothing there, and in the safe variant
//!   dropping it only widens the confidence intervals around the line, which shrinks the
//!   safe set rather than grows it (up to its small pull on the mean).
//! * **Extreme costs.** A residual (cost − prior mean) is clipped to ±10⁶ σ_f in the model
//!   (the optimizer's best keeps the true cost), so any finite f32 cost keeps the weights
//!   K⁻¹y finite.
//! * **Kernel along the grid** (a numerical deviation, not a modelling one). On the evenly
//!   spaced grid t_g = t₀ + gΔ, ‖o + t_g d − x_i‖² is a quadratic in g whose g²
//!   coefficient Δ² is the same for every remembered x_i, so the kernel values along the
//!   line are e_i r_iʲ exp(−wΔ² j(j − 1)) from a block's start: two `expf` per episode
//!   every 8 grid points and a multiplication in between, instead of one `expf` per grid
//!   point and episode. Each block restarts from the kernel computed directly; the values
//!   differ from it by a relative 10⁻⁶ at most (about 2·8 + 4 roundings), those below
//!   10⁻³⁰ σ_f² over a whole block are taken as 0, and the posterior means and variances
//!   on a line then equal a refactorised model's computed point by point within 10⁻⁵ σ_f
//!   and 10⁻⁵ σ_f² (a test, on random data). The grid point moved onto the origin is
//!   computed directly.

pub(crate) mod gp;

use nalgebra::SVector;
use rand_core::RngCore;

#[cfg(test)]
use super::Status;
use super::{Bounds, Error, Ledger, Optimizer, Vector};
use super::{check_stopping, default_is_const, ledger_accessors, require};
use crate::bounds::UnitMap;
use crate::random::normal_vector_f32;
use gp::{Gp, Kernel};

/// The points of the grid on each line.
pub const GRID: usize = 64;

/// How the lines are oriented.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum LineDirections {
    /// The coordinate axes in turn, θ_1, θ_2, …, θ_n, θ_1, … (`CoordinateLineBO`).
    Coordinate,
    /// A direction drawn uniformly on the sphere of the normalised box, one per line
    /// (`RandomLineBO`), from the RNG passed to `ask`.
    Random,
}

/// Parameters of [`LineBo`], checked by [`LineBoConfig::validate`]; see the
/// [module docs](self) for their meaning and a rule to choose them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LineBoConfig {
    /// ℓ relative to the box's width, in [10⁻³, 10³].
    pub length_scale: f32,
    /// σ_f² in cost units², in [10⁻²⁰, 10²⁰].
    pub signal_variance: f32,
    /// σ_n² in cost units², in [0, 10²⁰].
    pub noise_variance: f32,
    /// Added to the noise variance, relative to σ_f², in [10⁻⁶, 1].
    pub jitter: f32,
    /// β > 0 (at most 10³): confidence intervals are μ ± βσ.
    pub beta: f32,
    /// Coordinate or random lines.
    pub directions: LineDirections,
    /// Episodes on each line, ≥ 1.
    pub evaluations_per_line: u32,
    /// h: with `Some`, only points whose upper confidence bound is ≤ h are proposed
    /// (SafeOpt); finite.
    pub threshold: Option<f32>,
    /// Evaluations (episodes) allowed, ≥ 1.
    pub max_evaluations: u32,
}

impl LineBoConfig {
    /// The defaults of the module docs: ℓ = 0.25, σ_f² = 1, σ_n² = 10⁻², jitter 10⁻⁴,
    /// β = 2, coordinate lines of 3 episodes, no threshold, no budget limit.
    pub const DEFAULT: Self = Self {
        length_scale: 0.25,
        signal_variance: 1.0,
        noise_variance: 1e-2,
        jitter: 1e-4,
        beta: 2.0,
        directions: LineDirections::Coordinate,
        evaluations_per_line: 3,
        threshold: None,
        max_evaluations: u32::MAX,
    };

    /// `Ok` when every parameter is in its range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        let within = |v: f32, lo: f32, hi: f32| v >= lo && v <= hi;
        require(within(self.length_scale, 1e-3, 1e3), "length_scale")?;
        require(within(self.signal_variance, 1e-20, 1e20), "signal_variance")?;
        require(within(self.noise_variance, 0.0, 1e20), "noise_variance")?;
        require(within(self.jitter, 1e-6, 1.0), "jitter")?;
        require(self.beta > 0.0 && self.beta <= 1e3, "beta")?;
        require(self.evaluations_per_line >= 1, "evaluations_per_line")?;
        require(self.threshold.is_none_or(f32::is_finite), "threshold")?;
        check_stopping(None, self.max_evaluations)
    }

    fn kernel(&self) -> Kernel {
        // ℓ in [−1, 1]ⁿ units is twice ℓ relative to the width.
        let width = 2.0 * self.length_scale;
        Kernel {
            signal: self.signal_variance,
            inverse_width: 1.0 / (2.0 * width * width),
            noise: self.noise_variance + self.jitter * self.signal_variance,
        }
    }
}

default_is_const!(LineBoConfig);

/// The current line: o + t d, t ∈ [lower, upper], in normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Line<const N: usize> {
    /// d, ‖d‖ = 1.
    direction: Vector<N>,
    lower: f32,
    upper: f32,
    /// Where the grid starts within its first cell, in [0, 1).
    offset: f32,
    /// Episodes told on this line.
    told: u32,
}

impl<const N: usize> Line<N> {
    /// The line through `origin` along `direction` (finite, nonzero) cut to [−1, 1]ⁿ, its
    /// grid shifted by `offset` ∈ [0, 1) of a cell; `None` when the direction has no length.
    fn through(origin: &Vector<N>, direction: Vector<N>, offset: f32) -> Option<Self> {
        let norm = direction.norm();
        if !(norm > 1e-6 && norm.is_finite()) {
            return None;
        }
        let direction = direction / norm;
        let (mut lower, mut upper) = (f32::NEG_INFINITY, f32::INFINITY);
        for i in 0..N {
            let d = direction[i];
            if d != 0.0 {
                let (a, b) = ((-1.0 - origin[i]) / d, (1.0 - origin[i]) / d);
                lower = lower.max(a.min(b));
                upper = upper.min(a.max(b));
            }
        }
        // o is inside the box, so t = 0 is feasible; rounding may say otherwise.
        let (lower, upper) = (lower.min(0.0), upper.max(0.0));
        (upper - lower > 0.0 && (upper - lower).is_finite()).then_some(Self {
            direction,
            lower,
            upper,
            offset,
            told: 0,
        })
    }

    /// The grid index moved onto t = 0: the point nearest it.
    fn origin_index(&self) -> usize {
        let step = (self.upper - self.lower) / GRID as f32;
        let index = libm::roundf(-self.lower / step - self.offset);
        if index.is_finite() && index >= 0.0 {
            (index as usize).min(GRID - 1)
        } else {
            0
        }
    }

    /// t of grid point `g`: t₋ + (g + offset)(t₊ − t₋)/GRID, or 0 at the origin's index.
    fn t(&self, g: usize) -> f32 {
        if g == self.origin_index() {
            return 0.0;
        }
        self.grid_t(g)
    }

    /// t of grid point `g` of the evenly spaced grid, before the origin's index is moved
    /// onto t = 0.
    fn grid_t(&self, g: usize) -> f32 {
        let fraction = (g as f32 + self.offset) / GRID as f32;
        self.lower + fraction * (self.upper - self.lower)
    }
}

/// The posterior on the current line's grid.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Posterior {
    mean: SVector<f32, GRID>,
    sd: SVector<f32, GRID>,
}

/// LineBO with an optional SafeOpt threshold (module docs), remembering `M` episodes in
/// its Gaussian process: about 4·M² + 4·M·n + 12·M bytes (23 536 B at n = 18 with M = 64,
/// the recommended capacity there; 27 336 B at n = 31, 17 864 B with M = 48), three
/// columns of M floats of them the working space of the posterior pass, so that the
/// stack it needs beyond the state stays within 2 KB.
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, LineBo, LineBoConfig, Optimizer};
/// use rand_core::SeedableRng;
///
/// let bounds = Bounds::<2>::uniform(-1.0, 1.0)?;
/// let cost = |t: &ctrl_adapt::Vector<2>| (t[0] - 0.4).powi(2) + (t[1] + 0.3).powi(2);
/// let start = [0.0, 0.0].into();
/// // Never propose a point whose cost may exceed the start's by more than 0.2.
/// let config = LineBoConfig {
///     signal_variance: 0.1,
///     noise_variance: 1e-4,
///     threshold: Some(cost(&start) + 0.2),
///     ..LineBoConfig::DEFAULT
/// };
/// let mut search: LineBo<2, 32> = LineBo::try_new(bounds, start, config)?;
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(0);
/// for _ in 0..30 {
///     let theta = search.ask(&mut rng)?;
///     assert!(cost(&theta) <= cost(&start) + 0.2);
///     search.tell(cost(&theta))?;
/// }
/// assert!(search.best().unwrap().cost < 0.01);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
///
/// One candidate at a time under [`InFlight`](super::InFlight) too (its
/// [`Generation`](super::Generation) room is 1): each point of a line follows the GP the cost
/// before it updated.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LineBo<const N: usize, const M: usize> {
    config: LineBoConfig,
    unit: UnitMap<N>,
    /// θ⁰.
    start: Vector<N>,
    /// The origin of the current (or next) line, normalised.
    origin: Vector<N>,
    /// Lines begun so far (the coordinate of the next coordinate line is this mod n).
    lines: u32,
    line: Option<Line<N>>,
    /// The posterior on `line`'s grid (meaningless while `line` is `None`).
    posterior: Posterior,
    gp: Gp<N, M>,
    ledger: Ledger<N>,
    /// Working columns, no state: not saved (a decoded search starts with zeros).
    #[cfg_attr(feature = "serde", serde(skip))]
    scratch: Scratch<M>,
}

/// The working columns of the posterior pass ([`LineBo::refresh`]: the sweep's two
/// per-episode arrays and the kernel column) and of the expander test (the two edges'
/// L⁻¹k and the candidate's), in the state rather than on the stack: a
/// microcontroller's RAM bounds state and stack together, and three columns of M floats
/// in the deepest frame are what took the stack past the state + 2 KB that every
/// optimizer keeps to. They carry nothing from one call to the next, so two searches that
/// differ only in them are equal, and they are neither saved nor logged.
#[derive(Debug, Clone, Copy)]
struct Scratch<const M: usize> {
    first: SVector<f32, M>,
    second: SVector<f32, M>,
    column: SVector<f32, M>,
}

impl<const M: usize> Scratch<M> {
    const ZERO: Self = Self {
        first: SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; 1])),
        second: SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; 1])),
        column: SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; 1])),
    };
}

impl<const M: usize> Default for Scratch<M> {
    fn default() -> Self {
        Self::ZERO
    }
}

impl<const M: usize> PartialEq for Scratch<M> {
    /// Always: the columns hold no state.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

#[cfg(feature = "defmt")]
impl<const M: usize> defmt::Format for Scratch<M> {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "Scratch")
    }
}

impl<const N: usize, const M: usize> LineBo<N, M> {
    /// A search from `start` (θ⁰: finite, inside `bounds`, and assumed safe when
    /// `config.threshold` is set).
    ///
    /// The object is large (about 4·M² bytes): call this where it is to stay.
    pub fn try_new(
        bounds: Bounds<N>,
        start: Vector<N>,
        config: LineBoConfig,
    ) -> Result<Self, Error> {
        const {
            assert!(M >= 2, "the GP needs room for at least two episodes");
        }
        config.validate()?;
        bounds.check(&start, "start")?;
        let unit = UnitMap::new(bounds);
        Ok(Self {
            config,
            unit,
            start,
            origin: unit.unit_in_box(&start),
            lines: 0,
            line: None,
            posterior: Posterior {
                mean: SVector::zeros(),
                sd: SVector::zeros(),
            },
            gp: Gp::EMPTY,
            ledger: Ledger::new(config.max_evaluations),
            scratch: Scratch::ZERO,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &LineBoConfig {
        &self.config
    }

    /// The origin of the current (or next) line in parameter units: θ⁰ until the first
    /// line ends, then the posterior mean's minimiser on the last line ended (the policy
    /// to deploy).
    pub fn origin(&self) -> Vector<N> {
        self.unit.theta_of(&self.origin)
    }

    /// Episodes the GP holds (at most `M`).
    pub fn remembered(&self) -> usize {
        self.gp.len()
    }

    /// Starts the next line through `origin`, drawing its direction from `rng` if random.
    fn begin_line<R: RngCore + ?Sized>(&mut self, rng: &mut R) {
        let axis = (self.lines as usize) % N;
        let coordinate = Vector::from_fn(|i, _| if i == axis { 1.0 } else { 0.0 });
        let direction = match self.config.directions {
            LineDirections::Coordinate => coordinate,
            LineDirections::Random => normal_vector_f32::<N, R>(rng),
        };
        // The grid of line k is shifted by frac(k/φ) of a cell (a low-discrepancy sequence,
        // in 32-bit fixed point, kept to the 24 bits an f32 below 1 holds): a fixed grid
        // would put every line along one axis on the same points, and the search could not
        // resolve the optimum finer than a cell.
        let offset = (self.lines.wrapping_mul(0x9E37_79B9) >> 8) as f32 / 16_777_216.0;
        self.lines = self.lines.wrapping_add(1);
        // A random draw of (numerically) zero length falls back to the axis, which always
        // spans the box.
        self.line = Line::through(&self.origin, direction, offset)
            .or_else(|| Line::through(&self.origin, coordinate, offset));
        self.refresh(true);
    }

    /// Recomputes the posterior on the line's grid: the means, and with `variance` the
    /// standard deviations (one triangular solve per grid point, most of the work). Out of
    /// line, as [`Self::choose`].
    #[inline(never)]
    fn refresh(&mut self, variance: bool) {
        let Some(line) = self.line else { return };
        let kernel = self.config.kernel();
        let Scratch {
            first,
            second,
            column: k,
        } = &mut self.scratch;
        let step = (line.upper - line.lower) / GRID as f32;
        let mut sweep = gp::Sweep::new(step, &kernel, first, second);
        let at_origin = line.origin_index();
        for g in 0..GRID {
            let (o, d) = (&self.origin, &line.direction);
            self.gp
                .sweep_column((o, d), line.grid_t(g), g, &kernel, &mut sweep, k);
            if g == at_origin {
                // The grid point moved onto the origin: its column from the points.
                self.gp.column_on_line(o, d, 0.0, &kernel, k);
            }
            let (mean, sd) = if variance {
                let (mean, variance) = self.gp.posterior(k, &kernel);
                (mean, Some(libm::sqrtf(variance)))
            } else {
                (self.gp.mean(k), None)
            };
            if let Some(m) = self.posterior.mean.get_mut(g) {
                *m = mean;
            }
            if let (Some(sd), Some(s)) = (sd, self.posterior.sd.get_mut(g)) {
                *s = sd;
            }
        }
    }

    /// l and u at grid point `g` (NaN off the grid).
    fn bounds_at(&self, g: usize) -> (f32, f32) {
        bounds_at(&self.posterior, self.config.beta, g)
    }

    /// u − l at `g`, NaN counted as 0.
    fn width(&self, g: usize) -> f32 {
        let (l, u) = self.bounds_at(g);
        let w = u - l;
        if w.is_nan() { 0.0 } else { w }
    }

    /// The safe set on the line: the grid interval [lo, hi] around the origin whose upper
    /// bounds are ≤ h. θ⁰ is safe by assumption; any other origin must pass the test like
    /// every point (once an episode there has raised its bound above h, it is no longer
    /// safe), and `None` means that it does not.
    fn safe_interval(&self, line: &Line<N>, threshold: f32) -> Option<(usize, usize)> {
        let o = line.origin_index();
        let safe = |g: usize| self.bounds_at(g).1 <= threshold;
        if !(safe(o) || self.origin == self.unit.unit_in_box(&self.start)) {
            return None;
        }
        let mut lo = o;
        while lo > 0 && safe(lo - 1) {
            lo -= 1;
        }
        let mut hi = o;
        while hi + 1 < GRID && safe(hi + 1) {
            hi += 1;
        }
        Some((lo, hi))
    }

    /// The grid point of the next episode on the line (module docs, step 3); `None` when
    /// the safe set is empty. Out of line, so that its vectors (the edges' L⁻¹k) and those
    /// of the posterior pass in [`Self::refresh`] never share one stack frame.
    #[inline(never)]
    fn choose(&mut self, line: &Line<N>) -> Option<usize> {
        let Some(h) = self.config.threshold else {
            return Some(argmin(0..GRID, |g| self.bounds_at(g).0));
        };
        let (lo, hi) = self.safe_interval(line, h)?;
        let best_upper = (lo..=hi)
            .map(|g| self.bounds_at(g).1)
            .fold(f32::INFINITY, f32::min);
        let view = &*self;
        let minimisers = || (lo..=hi).filter(move |&g| view.bounds_at(g).0 <= best_upper);
        let widest = argmin(minimisers(), |g| -self.width(g));
        let widest = if minimisers().any(|g| g == widest) {
            widest
        } else {
            // No minimiser (NaN bounds): the origin.
            line.origin_index()
        };
        let floor = self.width(widest);
        // Expanders: only a point wider than the widest minimiser can be chosen, so test
        // those, widest first, and stop at the first expander (as `safeopt` does).
        let mut order = [0u8; GRID];
        let mut count = 0;
        for g in lo..=hi {
            if self.width(g) > floor
                && self.bounds_at(g).0 > best_upper
                && let Some(slot) = order.get_mut(count)
            {
                *slot = g as u8;
                count += 1;
            }
        }
        // Widest first, ties in grid order: an insertion sort, which (unlike the standard
        // library's sorts, whose check of the comparison's consistency is a panic path)
        // cannot panic; at most 64 entries.
        let wider = |a: u8, b: u8| self.width(usize::from(a)) > self.width(usize::from(b));
        for i in 1..count {
            let mut j = i;
            while j > 0 {
                match order.get_mut(j - 1..=j) {
                    Some([a, b]) if wider(*b, *a) => core::mem::swap(a, b),
                    _ => break,
                }
                j -= 1;
            }
        }
        if count == 0 {
            return Some(widest);
        }
        // The edges' L⁻¹k in the scratch's first two columns, the candidate's in the third.
        let kernel = self.config.kernel();
        let Scratch {
            first,
            second,
            column,
        } = &mut self.scratch;
        let edges = [
            lo.checked_sub(1)
                .map(|e| edge(&self.gp, &kernel, &self.origin, line, e, first)),
            (hi + 1 < GRID).then(|| edge(&self.gp, &kernel, &self.origin, line, hi + 1, second)),
        ];
        let whites = [&*first, &*second];
        for &g in order.iter().take(count) {
            let g = usize::from(g);
            let (lower, _) = bounds_at(&self.posterior, self.config.beta, g);
            let test = Expansion {
                gp: &self.gp,
                kernel: &kernel,
                beta: self.config.beta,
                origin: &self.origin,
                line,
            };
            if test.expands(g, lower, &edges, whites, column, h) {
                return Some(g);
            }
        }
        Some(widest)
    }

    /// Ends the line: the next origin is the posterior mean's minimiser on it (within the
    /// safe set with a threshold).
    fn end_line(&mut self, line: &Line<N>) {
        let (lo, hi) = match self.config.threshold {
            Some(h) => match self.safe_interval(line, h) {
                Some(interval) => interval,
                None => return self.fall_back(),
            },
            None => (0, GRID - 1),
        };
        let o = line.origin_index();
        let g = argmin(lo..=hi, |g| {
            // Ties (a flat mean) stay at the origin.
            let m = self.posterior.mean.get(g).copied().unwrap_or(f32::NAN);
            if g == o {
                m
            } else {
                m + f32::EPSILON * m.abs()
            }
        });
        self.origin = self.point(line, g);
        self.line = None;
    }

    /// Abandons the line when its safe set is empty: the next line starts from θ⁰, the one
    /// point safe by assumption.
    fn fall_back(&mut self) {
        self.origin = self.unit.unit_in_box(&self.start);
        self.line = None;
    }

    /// Grid point `g` of `line`, normalised, inside [−1, 1]ⁿ.
    fn point(&self, line: &Line<N>, g: usize) -> Vector<N> {
        let x = self.origin + line.direction * line.t(g);
        x.map(|v| v.clamp(-1.0, 1.0))
    }

    /// The upper confidence bound u(θ) = μ(θ) + βσ(θ) of the latent cost at θ under the
    /// current GP: with a threshold h, every candidate the search proposes after θ⁰ has
    /// u ≤ h when it is proposed (up to rounding), or is θ⁰ itself. For diagnostics and
    /// tests; O(M²) work.
    pub fn upper_bound(&self, theta: &Vector<N>) -> f32 {
        let kernel = self.config.kernel();
        let mut k = self.gp.kernel_column(&self.unit.unit_of(theta), &kernel);
        let (mean, var) = self.gp.posterior(&mut k, &kernel);
        mean + self.config.beta * libm::sqrtf(var)
    }
}

/// l and u at grid point `g` of `posterior` (NaN off the grid).
fn bounds_at(posterior: &Posterior, beta: f32, g: usize) -> (f32, f32) {
    let mean = posterior.mean.get(g).copied().unwrap_or(f32::NAN);
    let sd = posterior.sd.get(g).copied().unwrap_or(f32::NAN);
    let half = beta * sd;
    (mean - half, mean + half)
}

/// An unsafe grid point next to the safe set: its t, posterior mean and variance (its
/// L⁻¹k is in the scratch, shared by the expander tests).
struct Edge {
    t: f32,
    mean: f32,
    variance: f32,
}

/// The posterior at the unsafe grid point `e` next to the safe set, for
/// [`Expansion::expands`], its L⁻¹k written to `white`.
fn edge<const N: usize, const M: usize>(
    gp: &Gp<N, M>,
    kernel: &Kernel,
    origin: &Vector<N>,
    line: &Line<N>,
    e: usize,
    white: &mut SVector<f32, M>,
) -> Edge {
    let t = line.t(e);
    gp.column_on_line(origin, &line.direction, t, kernel, white);
    let (mean, variance) = gp.posterior(white, kernel);
    Edge { t, mean, variance }
}

/// What the expander test reads of the search (borrowed apart from its scratch).
struct Expansion<'a, const N: usize, const M: usize> {
    gp: &'a Gp<N, M>,
    kernel: &'a Kernel,
    beta: f32,
    origin: &'a Vector<N>,
    line: &'a Line<N>,
}

impl<const N: usize, const M: usize> Expansion<'_, N, M> {
    /// Whether a fictitious observation of l(x_g) = `lower` at grid point `g` would bring
    /// the upper bound of one of the unsafe `edges` (their L⁻¹k in `whites`) to ≤ h;
    /// `column` is the candidate's working column.
    fn expands(
        &self,
        g: usize,
        lower: f32,
        edges: &[Option<Edge>; 2],
        whites: [&SVector<f32, M>; 2],
        column: &mut SVector<f32, M>,
        h: f32,
    ) -> bool {
        if edges.iter().all(Option::is_none) {
            return false;
        }
        let (kernel, tg) = (self.kernel, self.line.t(g));
        self.gp
            .column_on_line(self.origin, &self.line.direction, tg, kernel, column);
        let (mean_g, var_g) = self.gp.posterior(column, kernel);
        edges.iter().zip(whites).any(|(e, white)| {
            let Some(e) = e else { return false };
            let dt = tg - e.t;
            let cov = self.gp.covariance(kernel.at(dt * dt), column, white);
            let gain = cov / (var_g + kernel.noise);
            let mean = e.mean + gain * (lower - mean_g);
            let var = (e.variance - gain * cov).max(0.0);
            mean + self.beta * libm::sqrtf(var) <= h
        })
    }
}

/// The index of `values` where `key` is lowest (NaN never wins; the first on ties), or 0.
fn argmin(indices: impl Iterator<Item = usize>, key: impl Fn(usize) -> f32) -> usize {
    let mut best = (0, f32::INFINITY);
    let mut any = false;
    for i in indices {
        let k = key(i);
        if !any || k < best.1 {
            if !any || !k.is_nan() {
                best = (i, k);
            }
            any = true;
        }
    }
    best.0
}

#[cfg(feature = "serde")]
impl<const N: usize, const M: usize> LineBo<N, M> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (box, configuration, start), the map to the unit box recomputed
    /// from the box, the origin inside [−1, 1]ⁿ, a line (if any) with a unit direction and
    /// t range around 0 and fewer episodes told than a line takes, a finite posterior with
    /// standard deviations ≥ 0, the GP's checks and the ledger's.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::require_finite;
        self.unit.bounds.check_decoded()?;
        require(UnitMap::new(self.unit.bounds) == self.unit, "bounds")?;
        self.config.validate()?;
        self.unit.bounds.check(&self.start, "start")?;
        require_finite(self.origin.iter(), "origin")?;
        // θ⁰ maps to [−1, 1]ⁿ up to rounding.
        require(self.origin.iter().all(|v| v.abs() <= 1.0 + 1e-3), "origin")?;
        if let Some(line) = &self.line {
            require_finite(line.direction.iter(), "line")?;
            require((line.direction.norm() - 1.0).abs() < 1e-3, "line")?;
            let range = line.upper - line.lower;
            require(
                line.lower <= 0.0 && line.upper >= 0.0 && range > 0.0 && range.is_finite(),
                "line",
            )?;
            require(line.told < self.config.evaluations_per_line, "line")?;
            require((0.0..1.0).contains(&line.offset), "line")?;
        }
        require_finite(self.posterior.mean.iter(), "posterior")?;
        require_finite(self.posterior.sd.iter(), "posterior")?;
        require(self.posterior.sd.iter().all(|s| *s >= 0.0), "posterior")?;
        self.gp.check_decoded()?;
        require(
            self.gp.len() == (self.ledger.evaluations() as usize).min(M),
            "evaluations",
        )?;
        self.ledger.check_decoded(&self.unit.bounds)
    }
}

impl<const N: usize, const M: usize> Optimizer<N> for LineBo<N, M> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        if self.ledger.evaluations() == 0 {
            return Ok(self.ledger.hand_out(self.start, &self.unit.bounds));
        }
        if self.line.is_none() {
            self.begin_line(rng);
        }
        let chosen = match self.line {
            Some(line) => self.choose(&line).map(|g| self.point(&line, g)),
            None => None,
        };
        let theta = match chosen {
            Some(x) => self.unit.theta_of(&x),
            None => {
                // No safe point on the line: θ⁰ is (module docs, "β and what the safety
                // guarantee covers").
                self.fall_back();
                self.start
            }
        };
        Ok(self.ledger.hand_out(theta, &self.unit.bounds))
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        let theta = self.ledger.accept(cost)?;
        let x = self.unit.unit_in_box(&theta);
        self.gp
            .append(&x, cost, &self.config.kernel(), &self.origin);
        if let Some(mut line) = self.line {
            line.told += 1;
            self.line = Some(line);
            // The end of a line needs only the means, unless the safe set is to be known.
            let ends = line.told >= self.config.evaluations_per_line;
            self.refresh(!ends || self.config.threshold.is_some());
            if ends {
                self.end_line(&line);
            }
        }
        self.ledger.settle();
        Ok(())
    }

    ledger_accessors!(unit.bounds);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{
        any_bounds, check_any_costs, check_call_order, check_rejected_calls_change_nothing,
        check_rejected_configs, check_rejected_starts, check_seeded, evaluations_to_target, rng,
        with_start,
    };
    use proptest::prelude::*;

    /// A shifted, scaled quadratic with its minimum 0 at (0.4, −0.3, 0.2, −0.1).
    fn quadratic(t: &Vector<4>) -> f32 {
        let c = Vector::<4>::from([0.4, -0.3, 0.2, -0.1]);
        (0..4)
            .map(|i| (i as f32 + 1.0) * (t[i] - c[i]).powi(2))
            .sum()
    }

    /// σ_f² = 4 (the quadratic spans 0 to about 10 over the box); a small noise and jitter,
    /// since the cost is exact, so that the GP can resolve costs of 10⁻².
    fn config(threshold: Option<f32>, directions: LineDirections) -> LineBoConfig {
        LineBoConfig {
            signal_variance: 4.0,
            noise_variance: 1e-4,
            jitter: 1e-6,
            threshold,
            directions,
            ..LineBoConfig::DEFAULT
        }
    }

    #[test]
    fn constructors_name_the_bad_parameter() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let z = Vector::<2>::zeros();
        check_rejected_configs(
            LineBoConfig::DEFAULT,
            |c| LineBo::<2, 8>::try_new(b, z, c),
            &[
                (|c| c.length_scale = 0.0, "length_scale"),
                (|c| c.length_scale = f32::NAN, "length_scale"),
                (|c| c.signal_variance = 0.0, "signal_variance"),
                (|c| c.signal_variance = f32::INFINITY, "signal_variance"),
                (|c| c.noise_variance = -1.0, "noise_variance"),
                (|c| c.jitter = 0.0, "jitter"),
                (|c| c.beta = 0.0, "beta"),
                (|c| c.beta = f32::NAN, "beta"),
                (|c| c.evaluations_per_line = 0, "evaluations_per_line"),
                (|c| c.threshold = Some(f32::NAN), "threshold"),
                (|c| c.max_evaluations = 0, "max_evaluations"),
            ],
        );
        let c = LineBoConfig::DEFAULT;
        check_rejected_starts("start", |s| LineBo::<2, 8>::try_new(b, s, c));
    }

    #[test]
    fn call_order_errors_and_idempotent_ask() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let c = LineBoConfig {
            max_evaluations: 3,
            ..LineBoConfig::DEFAULT
        };
        let mut s = LineBo::<2, 8>::try_new(b, Vector::zeros(), c).unwrap();
        assert_eq!(check_call_order(&mut s), Vector::<2>::zeros());
        // Past the capacity (eviction) and across line ends, with random lines.
        let c = config(Some(3.0), LineDirections::Random);
        let mut s = LineBo::<2, 8>::try_new(b, Vector::zeros(), c).unwrap();
        check_rejected_calls_change_nothing(&mut s, 20);
    }

    /// Checks: without a threshold, from the corner (−1, …, −1) (cost 10.5) the search
    /// reaches a cost below 10⁻² on the 4-D quadratic (minimum 0) within 60 episodes with
    /// coordinate lines; random lines, slower on this axis-aligned cost, reach 5·10⁻²
    /// within 100. Three seeds each.
    #[test]
    fn learns_a_quadratic() {
        let b = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        for (directions, budget, target) in [
            (LineDirections::Coordinate, 60, 1e-2),
            (LineDirections::Random, 100, 5e-2),
        ] {
            for seed in 0..3 {
                let c = LineBoConfig {
                    max_evaluations: budget,
                    ..config(None, directions)
                };
                let mut s = LineBo::<4, 64>::try_new(b, Vector::repeat(-1.0), c).unwrap();
                let hit = evaluations_to_target(&mut s, quadratic, seed, target);
                assert!(
                    hit.is_some(),
                    "{directions:?} seed {seed}: best {:?}",
                    s.best()
                );
            }
        }
    }

    /// Checks: with the threshold h = J(θ⁰) + 0.5 on the quadratic (J(θ⁰) = 5; a well
    /// specified model: a smooth cost, σ_f² = 4), no episode's cost exceeds h over 60
    /// episodes; with coordinate lines the search still ends below 2·10⁻², with random lines
    /// (which spend more episodes expanding the safe set) below a fifth of J(θ⁰). Three
    /// seeds each.
    #[test]
    fn safe_variant_stays_below_the_threshold_and_learns() {
        let b = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let start = Vector::from([-0.5, 0.5, -0.5, 0.5]);
        let h = quadratic(&start) + 0.5;
        for (directions, target) in [
            (LineDirections::Coordinate, 2e-2),
            (LineDirections::Random, 1.0),
        ] {
            for seed in 0..3 {
                let c = LineBoConfig {
                    max_evaluations: 60,
                    ..config(Some(h), directions)
                };
                let mut s = LineBo::<4, 64>::try_new(b, start, c).unwrap();
                let mut r = rng(seed);
                while let Ok(t) = s.ask(&mut r) {
                    let cost = quadratic(&t);
                    assert!(
                        cost <= h,
                        "{directions:?} seed {seed}: {cost} > {h} at {t:?}"
                    );
                    s.tell(cost).unwrap();
                }
                let best = s.best().unwrap().cost;
                assert!(best < target, "{directions:?} seed {seed}: best {best}");
            }
        }
    }

    /// Prints the state's size at the AUV's n = 18 and the hopper's n = 31 with the
    /// recommended capacity M = 64 (and M = 48 at n = 31), and checks the footprint target
    /// at n = 18: at most 24 KB. (The host figure bounds the Cortex-M one: the fields are
    /// f32 and u32 but for the GP's one `usize` count, 8 bytes here and 4 there.)
    #[test]
    fn state_size_at_the_recommended_capacity() {
        extern crate std;
        let sizes = [
            ("LineBo<18, 64>", core::mem::size_of::<LineBo<18, 64>>()),
            ("LineBo<31, 64>", core::mem::size_of::<LineBo<31, 64>>()),
            ("LineBo<31, 48>", core::mem::size_of::<LineBo<31, 48>>()),
        ];
        for (name, bytes) in sizes {
            std::println!("{name}: {bytes} B");
        }
        assert!(sizes[0].1 <= 24 * 1024, "{} B", sizes[0].1);
    }

    #[test]
    fn identical_seeds_give_identical_runs() {
        let b = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let c = LineBoConfig {
            max_evaluations: 40,
            ..config(None, LineDirections::Random)
        };
        let s = LineBo::<4, 16>::try_new(b, Vector::zeros(), c).unwrap();
        assert_eq!(check_seeded(&s, 0.01, quadratic), 40);
    }

    proptest! {
        /// Checks, for random boxes, starts, settings and cost sequences (any f32, NaN and
        /// infinities included): every candidate is inside the box, a non-finite cost is an
        /// error that leaves the whole state unchanged, the best cost never increases, and
        /// the GP never holds more than M = 8 episodes.
        #[test]
        fn candidates_in_bounds_and_bad_costs_change_nothing(
            (bounds, start) in with_start(any_bounds::<3>(1e-3)),
            length_scale in 1e-3f32..10.0,
            signal_variance in 1e-6f32..1e6,
            random in any::<bool>(),
            threshold in prop::option::of(-1e3f32..1e3),
            per_line in 1u32..6,
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..60),
        ) {
            let c = LineBoConfig {
                length_scale, signal_variance, threshold,
                evaluations_per_line: per_line,
                directions: if random { LineDirections::Random } else { LineDirections::Coordinate },
                ..LineBoConfig::DEFAULT
            };
            let mut s = LineBo::<3, 8>::try_new(bounds, start, c).unwrap();
            check_any_costs(&mut s, &bounds, &costs, 3, |s, _| {
                prop_assert!(s.remembered() <= 8);
                Ok(())
            })?;
        }

        /// Checks, for random quadratic costs with noise, thresholds and settings: every
        /// candidate has an upper confidence bound ≤ h when it is proposed, or is θ⁰
        /// (assumed safe). The bound is recomputed at θ from the
        /// GP directly, so it may differ from the line's by rounding: 10⁻⁴ (1 + |h|) of
        /// slack, far below the widths of the confidence intervals here (σ_f ≥ 0.1).
        #[test]
        fn safe_variant_proposes_only_points_below_the_threshold(
            centre in prop::array::uniform3(-1.0f32..1.0),
            curvature in 0.1f32..20.0,
            margin in 0.0f32..2.0,
            noise in 0.0f32..0.1,
            signal_variance in 1e-2f32..1e2,
            length_scale in 0.05f32..1.0,
            random in any::<bool>(),
            seed in 0u64..1000,
        ) {
            let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
            let f = |t: &Vector<3>| curvature * (t - Vector::from(centre)).norm_squared();
            let start = Vector::repeat(0.1);
            let h = f(&start) + margin;
            let c = LineBoConfig {
                signal_variance, length_scale, threshold: Some(h), max_evaluations: 40,
                directions: if random { LineDirections::Random } else { LineDirections::Coordinate },
                ..LineBoConfig::DEFAULT
            };
            let mut s = LineBo::<3, 16>::try_new(b, start, c).unwrap();
            let mut r = rng(seed);
            while s.status() == Status::Running {
                let before = s;
                let t = s.ask(&mut r).unwrap();
                if t != start {
                    let u = before.upper_bound(&t);
                    prop_assert!(u <= h + 1e-4 * (1.0 + h.abs()), "u = {} > h = {} at {:?}", u, h, t);
                }
                s.tell(f(&t) + noise * (crate::random::unit_f32(&mut r) - 0.5)).unwrap();
            }
        }
    }
}
