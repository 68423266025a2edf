//! ROCK* (Reward Optimization with Compact Kernels and fast natural gradient regression),
//! after J. Hwangbo, C. Gehring, H. Sommer, R. Siegwart and J. Buchli, "ROCK*: Efficient
//! black-box optimization for policy learning", IEEE-RAS Humanoids 2014 (Algorithm 1,
//! eq. 2–5), with the defaults and details the paper leaves to the authors' code: their
//! MATLAB `ROCKstar.m`, `ROCKstarTemplate.m` and `gradient_descent.m` (ADRL/ETH Zurich,
//! 2014, revised in March 2015) and the C++ `cpp_code/Rockstar.hpp` (2015), read with their
//! history in the public copy of the GitHub repository `lomcin/c_rockstar` (BSD-licensed;
//! reimplemented here, not copied). "The code" below is the 2015 `ROCKstar.m` unless said
//! otherwise.
//!
//! One rollout, in the paper's notation (here in normalised coordinates, see below):
//!
//! 1. sample θ_N ~ N(θ*, Σ), Σ = σ² Σ_u; evaluate r_N;
//! 2. the near set I = {i : (θ_i − θ*)ᵀ Σ⁻¹ (θ_i − θ*) < λ_MD P(0.95, n)} of the remembered
//!    rollouts (the radius tripled until I holds two of them) and the auxiliary cost
//!    C = mean_{i∈I} r_i (eq. 3);
//! 3. the kernel regression of eq. 2 over I,
//!    J̃(θ) = (Σ_i r_i e_i(θ) + C) / (Σ_i e_i(θ) + 1),
//!    e_i(θ) = exp(−½ (θ_i − θ)ᵀ (2Σ_ε)⁻¹ (θ_i − θ)), Σ_ε = ϑ Σ,
//!    ϑ = −P(0.95, n)/(2 ln λ) (eq. 4; P the inverse χ² CDF, [`chi_squared_95`]);
//! 4. θ* ← argmin J̃ by natural-gradient descent (eq. 5) with the metric Σ_ε⁻¹,
//!    θ ← θ − γ Σ_ε ∇J̃, γ = g/(C − r_min), from up to four start points (below), each
//!    descent stopped when a step is shorter than `descent_tolerance` in the Σ_ε metric,
//!    after `descent_iterations` steps, or on leaving the trust region of radius
//!    `trust_radius` (Σ_ε metric) around its start point; the end point with the lowest J̃
//!    becomes θ*, Δθ the change of θ*;
//! 5. if √(Δθᵀ Σ⁻¹ Δθ) < κ χ̂_n: P_c ← (1 − c_c) P_c + c_c Δθ/σ,
//!    Σ_u ← (1 − c_cov) Σ_u + c_cov P_c P_cᵀ, Σ_u ← (ψ/det Σ_u)^{1/n} Σ_u (ψ = det Σ_u
//!    at the start: the update changes the shape, never the volume);
//! 6. if r_N > r_{N−1}: σ ← σ/(ζ ξ), else σ ← ζ σ.
//!
//! The first update comes after `initial_samples` rollouts (2, as in the paper's
//! "starts by sampling two policy parameter sets"), all drawn around the start.
//!
//! # Defaults (from the authors' MATLAB code unless said otherwise)
//! λ = 0.3 (`ROCKstar.m` and `ROCKstarTemplate.m` from their March 2015 revision on; the
//! 2014 files had 0.5, `Rockstar.hpp` had 0.3 and from May 2015 0.2, and the paper
//! recommends 0.4–0.6; on the rotated 10-D ellipsoid of condition 10³ 0.3 ends far lower
//! than 0.5, see the findings in `experiments/findings/rockstar-arm.md`), λ_MD = 10 (as a multiple of P(0.95, n) on the squared Σ-distance, see the
//! deviations), c_c = 3/((n + 6) ln(n + 6)), c_cov = 6/((n + 7) ln(n + 7)), κ = 1.5,
//! χ̂_n = √n (1 − 1/(4n) + 1/(21n²)), ζ = 1.3^{1/ln(n + 2.5)}, ξ = ζ^{0.3} (the code divides
//! σ by ζ^{1.3} after a worse rollout: `imp_factor` 1.3), two initial samples, descents of
//! at most 80 steps, trust radius √2 and step tolerance 0.01 (the code compares the squares
//! with 2 and 10⁻⁴), the four start points of `ROCKstar.m` with its gate on three of them
//! (below). Not from the code: the step
//! gain g = ½ (the paper's γ = 1/(2(C − r_min)); the code uses g = 1), σ₀ = 0.1 of the
//! box's half-width (the code's `unit_exploration_noise` is 0.05 of the user's parameter
//! scale), σ ≤ 1 and the stopping tolerance σ ≤ 10⁻⁶ (the code stops at σ < 10⁻⁸).
//!
//! # Where the paper and the authors' code differ, and what is done here
//! * **Direction of the step.** Eq. 5 and the text below it write θ − γ Σ_ε⁻¹ ∇J̃; the code
//!   steps along Σ_ε ∇J̃. The natural gradient for the metric tensor G = Σ_ε⁻¹ is G⁻¹∇J̃ =
//!   Σ_ε ∇J̃, and only that form has the units of θ (γ has units 1/cost): **the code's Σ_ε
//!   is followed**; Σ_ε⁻¹ in eq. 5 reads as a misprint.
//! * **Step size.** The paper derives γ = 1/(2(C − r_min)) from the local model
//!   A e^{−½θᵀΣ_ε⁻¹θ}, so as to cover half the distance to its minimum per step; the code
//!   uses 1/(C − r_min), which is the same rule for the kernel actually used in eq. 2
//!   (width 2Σ_ε). Both are offered by [`RockstarConfig::step_gain`] (γ = g/(C − r_min));
//!   **the paper's g = ½ is the default**. On the 10-D sphere g = 1 reaches 10⁻⁶ as well
//!   (unit test `step_gain_of_the_code_also_converges`). r_min is the lowest cost
//!   in the near set, as in the code (the paper: "the lowest cost observed").
//! * **Which rollouts enter the regression.** Eq. 2 sums over all rollouts; the code sums
//!   over the near set I of eq. 3 only, for both J̃ and C. **The code is followed**: a
//!   rollout outside I has a small kernel weight at θ* (below λ⁵ ≈ 0.0024 at λ = 0.3, by the
//!   radius below), C is the local mean the extrapolation needs, and the work per descent
//!   step is O(|I|·n).
//! * **Radius of the near set.** Eq. 3 bounds the Σ_ε-distance by λ_MD; the code bounds the
//!   squared Σ-distance by λ_MD·P(0.95, n) with λ_MD = 10 (≈ a squared Σ_ε-distance of
//!   −20 ln λ ≈ 24.1 at λ = 0.3) and multiplies the bound by 3 until I holds two rollouts.
//!   **The code is followed** ([`RockstarConfig::near_radius`] is its λ_MD).
//! * **The window.** `ROCKstar.m` searches I among the last 10n rollouts, the C++ code among
//!   the last 5n. Here the window is the memory of `M` rollouts (see "Memory").
//! * **Start points of the descent.** The paper says only "argmin". `ROCKstar.m` descends
//!   from (1) θ*, (2) the cheapest rollout of I, (3) θ_N if r_N < C, and (4) the best
//!   rollout ever seen if it is not in I, the last over *all* rollouts (with C their mean),
//!   and keeps the end point of lowest J̃; the C++ code descends from (2) only. Since its
//!   March 2015 revision `ROCKstar.m` descends from (2)–(4) only when I holds at least 2n
//!   rollouts (`if counter > n_parameter * 2`, `counter` being |I| + 1); the 2014 files
//!   always did. **`ROCKstar.m` of 2015 is followed**, gate included
//!   ([`RockstarConfig::extra_starts_from`]; with M < 2n the gate never opens); (4) runs
//!   over every remembered rollout, from the [`Optimizer::best`] θ (which outlives its
//!   eviction from the memory). Whether the gate matters is measured in the findings.
//! * **Stopping the descent.** The paper stops on a short step in the Σ_ε metric (no
//!   threshold given); the code also caps the iterations and stops once the point is more
//!   than √2 (Σ_ε metric) from where the descent started, after taking that step. **The
//!   code's rules are followed**, except that the step which leaves the trust region is
//!   shortened radially onto its boundary (here the end point never lies farther than
//!   `trust_radius` from its start: the "controlled extrapolation" the paper is about).
//! * **Order of the σ and the P_c updates.** Algorithm 1 updates P_c with Δθ/σ and then σ;
//!   the code updates σ first and divides by the new σ. **The paper is followed** (Δθ in
//!   units of the distribution that produced it).
//! * **The σ rule.** Algorithm 1 shrinks σ by ζξ if r_N > r_{N−1} and grows it by ζ
//!   otherwise (a tie grows σ); the code grows σ if r_N < r_{N−1} and shrinks it otherwise (a
//!   tie shrinks σ). The factors agree with ξ = ζ^{0.3}; **the paper's tie rule is
//!   followed** (on a plateau of equal costs the search widens rather than stops).
//! * **χ̂_n.** The C++ code has 1/(21n)² where the MATLAB code has 1/(21n²), the usual
//!   expansion of E‖N(0, I)‖; the latter is used.
//! * **ψ.** The code computes det Σ_u after each update and rescales; here Σ_u = A Aᵀ is
//!   kept as a factor, and the rank-one update is applied to A and A⁻¹ in O(n²) with the
//!   determinant restored analytically (the factored update of Igel, Suttorp and Hansen,
//!   "A computational efficient covariance matrix update and a (1+1)-CMA for evolution
//!   strategies", GECCO 2006): det Σ_u = ψ = 1 up to rounding, and every n updates A is
//!   refactored by a Cholesky decomposition of A Aᵀ and rescaled to det = 1 exactly, which
//!   also removes the drift between A and A⁻¹.
//! * **P(0.95, n)** is the exact quantile for n = 1, 2 (z²_{0.975}, −2 ln 0.05) and the
//!   Wilson–Hilferty approximation n(1 − 2/(9n) + z_{0.95} √(2/(9n)))³ for n ≥ 3 (error
//!   below 0.51 %, −0.083 % at n = 10), as f32; the code calls an exact inverse.
//!
//! # Further deviations (not in the paper nor in the code)
//! * **Normalised coordinates.** As [`Cmaes`](super::Cmaes), the search runs on
//!   x = (θ − c)/h with c and h the centre and half-width of the box, so the box is
//!   [−1, 1]ⁿ; Σ_u starts at I (ψ = 1) and σ₀ is relative to the half-widths. (Algorithm 1
//!   starts with Σ_u = Σ, σ = 1, ψ = det Σ: the same search with σ measured in other units.)
//! * **The box.** A sample outside [−1, 1]ⁿ is handed out as its projection onto the box,
//!   and the projection (the point whose cost is measured) is what is remembered. θ* is
//!   projected onto the box after each update, so it is always a deployable point.
//! * **f32 and extreme costs.** Costs enter the regression as (r_i − r_min)/(C − r_min),
//!   computed from halves (r/2 − r_min/2), so any finite f32 cost, up to ±f32::MAX, gives
//!   finite weights; J̃ and the step do not depend on the scale or offset of the costs.
//!   If every rollout of I has the same cost, J̃ is flat and θ* stays.
//! * **σ limits.** σ ≤ `max_sigma` (the box is [−1, 1]ⁿ: σ ≫ 1 only fills its faces) and
//!   σ ≥ 10⁻¹⁸ (so the kernel width stays a normal f32).
//! * **Recovery from non-finite values.** If A or A⁻¹ holds a NaN or infinity, a rank-one
//!   update or the refactoring would produce one, or A Aᵀ is not numerically positive
//!   definite, the shape is reset (Σ_u = I, P_c = 0; θ* and σ kept) and the remembered
//!   rollouts are moved to the new coordinates (forgotten if their position cannot be
//!   recovered); [`Rockstar::recoveries`] counts these. With finite costs this is a guard,
//!   not a path a normal run takes.
//! * **Stopping.** [`Status::Converged`] once σ ≤ `tolerance` after an update (σ is the
//!   geometric mean of the standard deviations, det Σ_u = 1); [`Status::BudgetSpent`] after
//!   `max_evaluations`.
//!
//! # Known limits
//! The figures of this paragraph were measured with the earlier defaults (λ = 0.5, the
//! extra start points at every update) and have not been re-measured; on the rotated 10-D
//! ellipsoid of condition 10³ the current defaults end over ten times lower after 1 000
//! rollouts (median θ* cost 2.6·10⁻⁴ against 6.0·10⁻³, seeds 0–9; findings in
//! `experiments/findings/rockstar-arm.md`).
//! On the rotated 10-D ellipsoid of condition 10⁴ (σ₀ = 0.1, memory 50, seeds 0–3), three
//! runs reached a best cost below 10⁻⁶ within 2 800 rollouts and stopped with θ*'s cost
//! below 10⁻⁶; the fourth stopped (σ ≤ 10⁻⁶) with θ*'s cost at 3·10⁻⁵ and never reached
//! 10⁻⁶: σ had shrunk before the shape was learned. Condition 10³ is in the unit tests.
//! The σ rule is the reason: two consecutive samples drawn around a θ* that does not move
//! are exchangeable, so σ shrinks by ζ^(1.3/2 − 1/2) per rollout on average whenever the
//! regression stops making progress. On the axis-aligned 4-D ellipsoid Σ 10^(w·i/3)(θ_i −
//! c_i)² in [−1, 1]⁴ from 0 (memory 20, tolerance 10⁻³, seeds 0–39) θ* ended within 0.05 of
//! the minimiser in every run for condition 1 and 10, in 39 of 40 for 10², and in 26 of 40
//! for 10³, where [`Cmaes`](super::Cmaes) (population 8, the same box, tolerance and seeds)
//! ended within 0.05 in all 40. For an ill-conditioned cost, restart from θ* with σ₀ again,
//! or use `Cmaes`.
//!
//! # Memory
//! The last `M` rollouts are remembered; when the memory is full the **oldest** is
//! forgotten. This is the authors' own rule: their code looks for the near set among the
//! last 10n (MATLAB) or 5n (C++) rollouts only, so `M` = 5n–10n reproduces it. Forgetting
//! by age also suits a robot, whose cost for a given θ drifts with wear and conditions;
//! forgetting the worst rollout far from θ* instead would keep stale low costs alive.
//! The best rollout ever is kept apart (in [`Optimizer::best`]) and still serves as a start
//! point after its eviction. `M` ≥ 2 and `M` ≤ 65 535 (checked at compile time).
//!
//! # Cost and size
//! Per rollout: O(n²) for the sample and its whitening, O(M·n) for the near set, O(M·n)
//! to move the remembered rollouts after a covariance update (they are stored whitened,
//! w_i = A⁻¹x_i, so a change of σ costs nothing and a rank-one update O(n) per rollout),
//! O(n³ + M·n²)/n on average for the refactoring every n updates, and O(s·|I|·n) for the
//! descents, with s ≤ 4·81 passes over I (usually far fewer; on the sphere tests |I| holds
//! about 15 rollouts whatever M). State: 4·(M·(n + 1) + 2n² + 9n) + 2M bytes and about
//! 300 more: `size_of` is 10 608 B for `Rockstar<18, 90>` and 29 408 B for
//! `Rockstar<31, 155>` on x86-64 (unit test `sizes`), 10 592 B and 29 392 B on thumbv7em.
//! **M = 5n** (the C++ code's window) is the recommended size; with M < 2n the default gate
//! never lets the extra start points run. On the 18- and 31-D spheres M = 2n, 3n, 5n and
//! 10n made the same progress over 800 rollouts (the near set is small there; measured
//! with the earlier defaults, λ = 0.5 and no gate); the larger memory is kept for noisy
//! costs, where the regression is meant to average over the rollouts near θ* (not
//! measured here). Host runs at
//! n = 400–500 with M ≈ 5n hold several megabytes (7 MB for `Rockstar<500, 2500>`): keep
//! the object in a `Box` or a `static`, and build it where the stack can hold it once (a
//! thread with a large stack), since [`Rockstar::try_new`] returns it by value.
//!
//! # Stack
//! Beyond the object itself a call needs O(n) bytes of stack, no n × n temporary: every
//! matrix–vector product reads A and A⁻¹ by reference (nalgebra's `A * v` on a matrix held by
//! value copies it first), the refactoring builds L in A⁻¹'s storage, the vectors of the
//! descent are updated in place, and `ask`, `tell`, the update, its extra descents, its
//! acceptance, the covariance update and the refactoring are separate (never inlined)
//! functions, so that their temporaries are on the stack one branch at a time. Build the object where it is
//! to stay and lend it (`&mut`): [`Rockstar::try_new`] must be inlined into the frame that
//! holds the result (out of line it assembles the memory on its own stack, 20 KB at
//! n = 31, and the result is copied). The `bench_rockstar` firmware (`Rockstar<31, 155>`,
//! 29 392 B, in one frame, lent to the loop) peaks at 31 264 B of stack on the Cortex-M4F,
//! 1 872 B above the object (58 956 B before these measures); the deepest paths are the
//! construction (the box, the start and the configuration) and `tell` through the update
//! and the acceptance of θ* into the covariance update.
//!
//! # Panic freedom
//! The linear algebra is written out (a Cholesky decomposition and a triangular solve, shared
//! with the line search's GP in `cholesky.rs`; a triangular
//! inverse; matrix–vector products and rank-one updates from nalgebra's static-size
//! operators) rather than taken from nalgebra's decompositions, whose panic sites LLVM does
//! not always remove (see [`Cmaes`](super::Cmaes)); indices into the memory are checked
//! with `get`. `scripts/panic-check` links `Rockstar<18, 90>`, driven with wild costs and
//! every accessor, into the firmware whose panic handler is an undefined symbol: it links.

use nalgebra::SMatrix;
use rand_core::RngCore;

use super::cholesky::{cholesky_in_place, solve_lower};
use super::{Draw, Generation, Ledger, Optimizer, Status};
use super::{check_sigmas, check_stopping, default_is_const, ledger_accessors, require};
use crate::bounds::UnitMap;
use crate::random::normal_vector_f32;
use crate::vector::{identity, times, times_into};
use crate::{Bounds, Error, Vector};

/// σ never falls below this (the kernel width ϑσ² stays a normal f32).
const SIGMA_FLOOR: f32 = 1e-18;

/// The near set's radius is multiplied by this until it holds two rollouts (`ROCKstar.m`).
const NEAR_WIDENING: f32 = 3.0;

/// z_{0.95}: the standard normal's 95 % quantile.
const Z_95: f32 = 1.644_853_6;

/// P(0.95, n): the 95 % quantile of the χ² distribution with n degrees of freedom, as used
/// by ROCK*'s kernel size (eq. 4) and near set. Exact for n = 1 (z²_{0.975} = 3.841459) and
/// n = 2 (−2 ln 0.05 = 5.991465); for n ≥ 3 the Wilson–Hilferty approximation
/// n (1 − 2/(9n) + z_{0.95} √(2/(9n)))³, whose relative error is −0.51 % at n = 3, −0.083 % at
/// n = 10, −0.014 % at n = 31 and shrinks as 1/n. Returns 0 for n = 0.
///
/// ```
/// use ctrl_adapt::optimizer::rockstar::chi_squared_95;
/// assert!((chi_squared_95(31) - 44.985343).abs() < 0.01);
/// ```
pub fn chi_squared_95(n: usize) -> f32 {
    match n {
        0 => 0.0,
        1 => 3.841_459,
        2 => 5.991_465,
        _ => {
            let n = n as f32;
            let a = 2.0 / (9.0 * n);
            let base = 1.0 - a + Z_95 * libm::sqrtf(a);
            n * base * base * base
        }
    }
}

/// Parameters of [`Rockstar`]. Plain fields, checked by [`RockstarConfig::validate`] (and by
/// [`Rockstar::try_new`]). Lengths are in normalised units: 1 is the box's half-width.
/// `None` in an `Option` field means the authors' default for n parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RockstarConfig {
    /// σ₀ > 0: the initial exploration standard deviation relative to the box's
    /// half-width, ≤ `max_sigma` (the paper finds the exploration covariance "a very
    /// critical parameter").
    pub initial_sigma: f32,
    /// The largest σ (finite, > 0).
    pub max_sigma: f32,
    /// λ ∈ (0, 1), at least 10⁻⁶ from either end: the extrapolation rate of eq. 4 (the
    /// kernel's density at the boundary of the 95 % ellipsoid of the exploration
    /// distribution); larger extrapolates more.
    pub lambda: f32,
    /// λ_MD > 0 of the authors' code: the near set holds the rollouts whose squared
    /// Mahalanobis distance to θ* under Σ is below λ_MD·P(0.95, n).
    pub near_radius: f32,
    /// Rollouts drawn around the start before the first update, 2 ≤ this ≤ M.
    pub initial_samples: u32,
    /// The extra start points of the descent (the cheapest rollout of the near set, the
    /// new rollout, the best rollout ever; θ* is always one) are used only when the near
    /// set holds at least this many rollouts. `None` means 2n, the gate of the authors'
    /// `ROCKstar.m` from its 2015 revision (it never opens when M < 2n); `Some(0)` uses
    /// them at every update, as the 2014 revision did.
    pub extra_starts_from: Option<u32>,
    /// g > 0 in γ = g/(C − r_min): ½ in the paper, 1 in the authors' code.
    pub step_gain: f32,
    /// The most steps of one natural-gradient descent (≥ 1).
    pub descent_iterations: u32,
    /// Radius (> 0, Σ_ε-Mahalanobis) of the region around its start point a descent may
    /// not leave.
    pub trust_radius: f32,
    /// A descent stops after a step shorter than this (≥ 0, Σ_ε-Mahalanobis).
    pub descent_tolerance: f32,
    /// κ > 0: the covariance is updated only when √(Δθᵀ Σ⁻¹ Δθ) < κ χ̂_n.
    pub kappa: f32,
    /// ζ > 1: σ grows by ζ after a rollout no worse than the previous one. Default
    /// 1.3^{1/ln(n + 2.5)}.
    pub zeta: Option<f32>,
    /// ξ > 0 with ζξ > 1: σ shrinks by ζξ after a worse rollout. Default ζ^{0.3}.
    pub xi: Option<f32>,
    /// c_c ∈ (0, 1]: the learning rate of the evolution path P_c. Default
    /// 3/((n + 6) ln(n + 6)).
    pub c_c: Option<f32>,
    /// c_cov ∈ (0, 1): the learning rate of the covariance shape Σ_u. Default
    /// 6/((n + 7) ln(n + 7)).
    pub c_cov: Option<f32>,
    /// The search has converged when σ ≤ this (≥ 0) after an update.
    pub tolerance: f32,
    /// Evaluations (episodes) allowed, ≥ 1.
    pub max_evaluations: u32,
}

impl RockstarConfig {
    /// The defaults of the module docs: σ₀ = 0.1, σ ≤ 1, λ = 0.3, λ_MD = 10, two initial
    /// samples, extra descent starts from a near set of 2n, g = ½, 80 descent steps, trust radius √2, step tolerance 0.01, κ = 1.5, ζ,
    /// ξ, c_c, c_cov from n, tolerance 10⁻⁶, no budget limit.
    pub const DEFAULT: Self = Self {
        initial_sigma: 0.1,
        max_sigma: 1.0,
        lambda: 0.3,
        near_radius: 10.0,
        initial_samples: 2,
        extra_starts_from: None,
        step_gain: 0.5,
        descent_iterations: 80,
        trust_radius: core::f32::consts::SQRT_2,
        descent_tolerance: 0.01,
        kappa: 1.5,
        zeta: None,
        xi: None,
        c_c: None,
        c_cov: None,
        tolerance: 1e-6,
        max_evaluations: u32::MAX,
    };

    /// `Ok` when every parameter is in its range, else the first offending field. (That
    /// `initial_samples` ≤ M is checked by [`Rockstar::try_new`].)
    pub fn validate(&self) -> Result<(), Error> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        check_sigmas(self.initial_sigma, self.max_sigma)?;
        // ϑ = −P/(2 ln λ) must be a usable, finite kernel scale.
        require(self.lambda > 1e-6 && self.lambda < 1.0 - 1e-6, "lambda")?;
        require(positive(self.near_radius), "near_radius")?;
        require(self.initial_samples >= 2, "initial_samples")?;
        require(positive(self.step_gain), "step_gain")?;
        require(self.descent_iterations != 0, "descent_iterations")?;
        require(positive(self.trust_radius), "trust_radius")?;
        require(non_negative(self.descent_tolerance), "descent_tolerance")?;
        require(positive(self.kappa), "kappa")?;
        require(self.zeta.is_none_or(|z| z.is_finite() && z > 1.0), "zeta")?;
        require(self.xi.is_none_or(positive), "xi")?;
        require(self.c_c.is_none_or(|c| c > 0.0 && c <= 1.0), "c_c")?;
        require(self.c_cov.is_none_or(|c| c > 0.0 && c < 1.0), "c_cov")?;
        check_stopping(Some(self.tolerance), self.max_evaluations)
    }
}

default_is_const!(RockstarConfig);

/// The strategy constants for n parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Constants {
    /// ϑ = −P(0.95, n)/(2 ln λ): Σ_ε = ϑ Σ.
    kernel: f32,
    /// λ_MD·P(0.95, n): the near set's bound on the squared Σ-distance.
    near_bound: f32,
    /// κ χ̂_n.
    path_bound: f32,
    c_c: f32,
    c_cov: f32,
    zeta: f32,
    xi: f32,
}

impl Constants {
    fn new(n: usize, config: &RockstarConfig) -> Result<Self, Error> {
        let p = chi_squared_95(n);
        let nf = n as f32;
        let chi_n = libm::sqrtf(nf) * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        let zeta = config
            .zeta
            .unwrap_or_else(|| libm::powf(1.3, 1.0 / libm::logf(nf + 2.5)));
        let xi = config.xi.unwrap_or_else(|| libm::powf(zeta, 0.3));
        require(zeta * xi > 1.0 && (zeta * xi).is_finite(), "xi")?;
        Ok(Self {
            kernel: -p / (2.0 * libm::logf(config.lambda)),
            near_bound: config.near_radius * p,
            path_bound: config.kappa * chi_n,
            c_c: config
                .c_c
                .unwrap_or_else(|| 3.0 / ((nf + 6.0) * libm::logf(nf + 6.0))),
            c_cov: config
                .c_cov
                .unwrap_or_else(|| 6.0 / ((nf + 7.0) * libm::logf(nf + 7.0))),
            zeta,
            xi,
        })
    }
}

/// Which remembered rollouts a regression runs over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Set {
    /// The near set I of eq. 3.
    Near,
    /// Every remembered rollout (start point 4 of `ROCKstar.m`).
    All,
}

/// The cost normalisation of one regression: ρ_i = (r_i/2 − floor)/scale, so that r_min
/// maps to 0 and C to 1 (halves: no overflow for any finite f32 costs).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Regression {
    /// r_min/2.
    floor: f32,
    /// (C − r_min)/2; 0 when all costs of the set are equal (J̃ is flat).
    scale: f32,
}

/// ROCK* over a box with a memory of `M` rollouts, as a resumable ask/tell state machine
/// (see the [module docs](self) for the algorithm, its defaults and its deviations).
///
/// [`Rockstar::theta_star`] is the regression's minimum θ*, the policy to deploy;
/// [`Optimizer::best`] is the best rollout told, as for every optimizer here.
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, Optimizer, Rockstar, RockstarConfig, Status, Vector};
/// use rand_core::SeedableRng;
///
/// let bounds = Bounds::<4>::uniform(-2.0, 2.0)?;
/// let config = RockstarConfig {
///     initial_sigma: 0.2,
///     max_evaluations: 1500,
///     ..RockstarConfig::DEFAULT
/// };
/// // Remember the last 20 rollouts (5 n, the window of the authors' C++ code).
/// let mut rock = Rockstar::<4, 20>::try_new(bounds, [1.0; 4].into(), config)?;
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(3);
/// // A rotated, badly scaled quadratic with its minimum at (0.3, 0.3, 0, 0).
/// let cost = |t: &Vector<4>| {
///     let (a, b) = (t[0] + t[1] - 0.6, t[0] - t[1]);
///     a * a + 100.0 * b * b + t[2] * t[2] + t[3] * t[3]
/// };
/// while rock.status() == Status::Running {
///     let theta = rock.ask(&mut rng)?;
///     rock.tell(cost(&theta))?;
/// }
/// // σ fell below the tolerance (10⁻⁶ of the half-width) well within the budget.
/// assert_eq!(rock.status(), Status::Converged);
/// assert!(rock.evaluations() < 1000);
/// assert!(rock.best().unwrap().cost < 1e-6);
/// // θ*, the regression's minimum, is the policy to deploy.
/// assert!(cost(&rock.theta_star()) < 1e-6);
/// assert!((rock.theta_star()[0] - 0.3).abs() < 1e-3);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
///
/// Under [`InFlight`](super::InFlight) the `initial_samples` rollouts can be in flight
/// together (drawn around the start); after them, one at a time.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Rockstar<const N: usize, const M: usize> {
    config: RockstarConfig,
    constants: Constants,
    /// The box and its map to [−1, 1]ⁿ: θ = centre + half-width ∘ x.
    unit: UnitMap<N>,
    /// θ*, normalised, always inside [−1, 1]ⁿ and finite.
    theta_star: Vector<N>,
    /// A⁻¹ θ*.
    theta_star_white: Vector<N>,
    sigma: f32,
    /// A with Σ_u = A Aᵀ, det A = 1.
    factor: SMatrix<f32, N, N>,
    /// A⁻¹.
    inverse: SMatrix<f32, N, N>,
    /// A⁻¹ P_c.
    path: Vector<N>,
    /// The remembered rollouts, whitened (A⁻¹ x_i), in a ring: the oldest at `head` once
    /// the memory is full.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    samples: [Vector<N>; M],
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    costs: [f32; M],
    len: usize,
    head: usize,
    /// Indices of the near set of the last update.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    near: [u16; M],
    near_len: usize,
    /// The pending candidate, normalised and projected, and A⁻¹ of it.
    drawn: Vector<N>,
    drawn_white: Vector<N>,
    /// r_{N−1}.
    last_cost: Option<f32>,
    /// J̃(θ*) at the last update.
    estimate: Option<f32>,
    updates: u32,
    covariance_updates: u32,
    since_refactor: u32,
    recoveries: u32,
    ledger: Ledger<N>,
}

impl<const N: usize, const M: usize> Rockstar<N, M> {
    /// A search starting at θ* = `start` (finite and inside `bounds`) with Σ = σ₀² I in
    /// normalised units (σ₀ = `config.initial_sigma` relative to each half-width).
    ///
    /// The object is large (about 4·M·n bytes): call this where it is to stay, and lend it
    /// (module docs, "Stack").
    pub fn try_new(
        bounds: Bounds<N>,
        start: Vector<N>,
        config: RockstarConfig,
    ) -> Result<Self, Error> {
        const {
            assert!(M >= 2, "ROCK* regresses on at least two rollouts");
            assert!(M <= u16::MAX as usize, "at most 65535 remembered rollouts");
        }
        config.validate()?;
        require((config.initial_samples as usize) <= M, "initial_samples")?;
        let constants = Constants::new(N, &config)?;
        bounds.check(&start, "start")?;
        let unit = UnitMap::new(bounds);
        let x = clamp_unit(unit.unit_of(&start));
        Ok(Self {
            config,
            constants,
            unit,
            theta_star: x,
            theta_star_white: x,
            sigma: config.initial_sigma,
            // Constants, copied straight into place (see `Cmaes::try_new`).
            factor: const { identity::<N>() },
            inverse: const { identity::<N>() },
            path: Vector::zeros(),
            samples: [const { crate::vector::zero::<N>() }; M],
            costs: [0.0; M],
            len: 0,
            head: 0,
            near: [0; M],
            near_len: 0,
            drawn: Vector::zeros(),
            drawn_white: Vector::zeros(),
            last_cost: None,
            estimate: None,
            updates: 0,
            covariance_updates: 0,
            since_refactor: 0,
            recoveries: 0,
            ledger: Ledger::new(config.max_evaluations),
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &RockstarConfig {
        &self.config
    }

    /// θ*, the minimum of the regressed cost J̃ (the start before the first update), in
    /// parameter units and inside the box: the policy to deploy.
    pub fn theta_star(&self) -> Vector<N> {
        self.unit.theta_of(&self.theta_star)
    }

    /// θ* in normalised units (x = (θ − centre)/half-width, inside [−1, 1]ⁿ).
    pub fn normalised_theta_star(&self) -> &Vector<N> {
        &self.theta_star
    }

    /// J̃(θ*): the regression's estimate of the cost at θ* after the last update (before
    /// θ* was projected onto the box), `None` before the first update.
    pub fn estimated_cost(&self) -> Option<f32> {
        self.estimate
    }

    /// σ: the global step size, relative to the box's half-widths (the geometric mean of the
    /// exploration standard deviations, det Σ_u = 1).
    pub fn sigma(&self) -> f32 {
        self.sigma
    }

    /// Σ_u = A Aᵀ, the exploration covariance's shape in normalised units (det = 1); the
    /// exploration covariance is σ² Σ_u and the kernel's Σ_ε = ϑ σ² Σ_u.
    pub fn shape(&self) -> SMatrix<f32, N, N> {
        self.factor * self.factor.transpose()
    }

    /// ϑ = −P(0.95, n)/(2 ln λ) of eq. 4.
    pub fn kernel_factor(&self) -> f32 {
        self.constants.kernel
    }

    /// Rollouts remembered (≤ M).
    pub fn remembered(&self) -> usize {
        self.len
    }

    /// The remembered rollouts, oldest first: θ (parameter units, recomputed from the stored
    /// whitened form, so equal to the told candidates up to rounding) and cost.
    pub fn memory(&self) -> impl Iterator<Item = (Vector<N>, f32)> + '_ {
        let start = if self.len < M { 0 } else { self.head };
        (0..self.len).filter_map(move |j| {
            let k = (start + j) % M;
            let w = self.samples.get(k)?;
            Some((
                self.unit.theta_of(&clamp_unit(times(&self.factor, w))),
                *self.costs.get(k)?,
            ))
        })
    }

    /// Regression updates (one per rollout after the initial samples).
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// Updates of the covariance shape Σ_u (those where θ* moved less than κ χ̂_n).
    pub fn covariance_updates(&self) -> u32 {
        self.covariance_updates
    }

    /// How many times a non-finite or indefinite shape was reset (see the module docs); 0
    /// in a normal run.
    pub fn recoveries(&self) -> u32 {
        self.recoveries
    }

    /// Remembers a rollout (whitened), forgetting the oldest when the memory is full.
    fn remember(&mut self, white: Vector<N>, cost: f32) {
        if let (Some(s), Some(c)) = (
            self.samples.get_mut(self.head),
            self.costs.get_mut(self.head),
        ) {
            (*s, *c) = (white, cost);
        }
        self.head = (self.head + 1) % M;
        self.len = (self.len + 1).min(M);
    }

    /// The newest remembered rollout, whitened.
    fn newest(&self) -> Option<&Vector<N>> {
        (self.len > 0)
            .then(|| self.samples.get((self.head + M - 1) % M))
            .flatten()
    }

    /// The rollouts of `set` (whitened, cost).
    fn members(&self, set: Set) -> impl Iterator<Item = (&Vector<N>, f32)> + '_ {
        let near = if set == Set::Near { self.near_len } else { 0 };
        let all = if set == Set::All { self.len } else { 0 };
        let by_index = self.near.iter().take(near).filter_map(|&k| {
            let k = usize::from(k);
            Some((self.samples.get(k)?, *self.costs.get(k)?))
        });
        let every = self
            .samples
            .iter()
            .zip(self.costs.iter().copied())
            .take(all);
        by_index.chain(every)
    }

    /// Selects the near set I around θ* (eq. 3, with the code's radius and widening);
    /// returns the index of its cheapest rollout.
    fn select_near(&mut self) -> Option<usize> {
        let need = self.len.min(2);
        let sigma2 = self.sigma * self.sigma;
        let mut bound = (self.constants.near_bound * sigma2).max(f32::MIN_POSITIVE);
        // One pass: how many lie within the bound, and the two smallest squared distances.
        let mut within = 0;
        let mut smallest = [f32::INFINITY; 2];
        for w in self.samples.iter().take(self.len) {
            let d = distance2(w, &self.theta_star_white);
            if d < bound {
                within += 1;
            }
            if d < smallest[0] {
                smallest = [d, smallest[0]];
            } else if d < smallest[1] {
                smallest[1] = d;
            }
        }
        if within < need {
            // Widen by 3 until the `need`-th nearest is inside; bounded: 200 triplings take
            // any positive f32 to +∞.
            let target = smallest[need.saturating_sub(1).min(1)];
            let mut widenings = 0;
            while target >= bound && widenings < 200 {
                bound *= NEAR_WIDENING;
                widenings += 1;
            }
        }
        let mut cheapest = self.near_where(Some(bound));
        if self.near_len < need {
            // Distances beyond f32 (a degenerate shape): regress on everything remembered.
            cheapest = self.near_where(None);
        }
        cheapest.map(|(i, _)| i)
    }

    /// Makes the near set the remembered rollouts whose squared whitened distance to θ* is
    /// below `bound` (every one if `None`); returns the cheapest of them (index and cost).
    fn near_where(&mut self, bound: Option<f32>) -> Option<(usize, f32)> {
        self.near_len = 0;
        let mut cheapest: Option<(usize, f32)> = None;
        for (i, (w, &c)) in self
            .samples
            .iter()
            .zip(self.costs.iter())
            .take(self.len)
            .enumerate()
        {
            if bound.is_none_or(|b| distance2(w, &self.theta_star_white) < b)
                && let Some(slot) = self.near.get_mut(self.near_len)
            {
                *slot = i as u16;
                self.near_len += 1;
                if cheapest.is_none_or(|(_, best)| c < best) {
                    cheapest = Some((i, c));
                }
            }
        }
        cheapest
    }

    /// r_min and C − r_min (as halves) of `set`.
    fn regression(&self, set: Set) -> Regression {
        let mut r_min = f32::INFINITY;
        let mut count = 0usize;
        for (_, r) in self.members(set) {
            r_min = r_min.min(r);
            count += 1;
        }
        let floor = 0.5 * r_min;
        let share = 1.0 / count.max(1) as f32;
        // Σ (r_i/2 − r_min/2)/|I|: every term ≤ f32::MAX/|I|, so the sum is finite.
        let scale = self
            .members(set)
            .map(|(_, r)| (0.5 * r - floor) * share)
            .sum::<f32>();
        Regression { floor, scale }
    }

    /// The kernel sums of eq. 2 and 5 at the whitened point `w` over `set`, in normalised
    /// costs (`inv_h2` = 1/(ϑσ²)): returns J̃_ρ = a/b and b = Σ e_i + 1, and writes
    /// Σ e_i d_i into `toward` and Σ e_i ρ_i d_i into `toward_cost` (d_i = w_i − w; the
    /// caller's vectors, so that the descent holds no copies of them).
    fn sums(
        &self,
        set: Set,
        reg: &Regression,
        w: &Vector<N>,
        inv_h2: f32,
        toward: &mut Vector<N>,
        toward_cost: &mut Vector<N>,
    ) -> (f32, f32) {
        // The prior term of eq. 2: C (ρ = 1) with weight 1.
        let (mut a, mut b) = (1.0f32, 1.0f32);
        toward.fill(0.0);
        toward_cost.fill(0.0);
        for (s, r) in self.members(set) {
            // exp(−½ dᵀ (2Σ_ε)⁻¹ d), in whitened units dᵀ Σ_ε⁻¹ d = ‖d‖²/(ϑσ²).
            let e = libm::expf(-0.25 * (distance2(s, w) * inv_h2));
            if e > 0.0 {
                let rho = (0.5 * r - reg.floor) / reg.scale;
                a += e * rho;
                b += e;
                // d = s − w element by element, not as a vector on the stack.
                let (e_rho, ends) = (e * rho, s.iter().zip(w.iter()));
                for ((t, c), (s_i, w_i)) in toward.iter_mut().zip(toward_cost.iter_mut()).zip(ends)
                {
                    let d = s_i - w_i;
                    *t += e * d;
                    *c += e_rho * d;
                }
            }
        }
        (a / b, b)
    }

    /// One natural-gradient descent of J̃ over `set` from the whitened `start` (eq. 5 with
    /// the code's step and stopping rules, module docs); returns the end point and J̃ there
    /// as a half cost (J̃/2).
    fn descend(&self, set: Set, reg: &Regression, start: &Vector<N>, h2: f32) -> (Vector<N>, f32) {
        if reg.scale <= 0.0 || reg.scale.is_nan() {
            // Equal costs: J̃ ≡ r_min everywhere, nothing to descend.
            return (*start, reg.floor);
        }
        let inv_h2 = 1.0 / h2;
        let trust2 = self.config.trust_radius * self.config.trust_radius * h2;
        let tol2 = self.config.descent_tolerance * self.config.descent_tolerance * h2;
        // In whitened units x = A w, the step −γ Σ_ε ∇_x J̃ is −γ ϑσ² ∇_w J̃ =
        // (γ/2) Σ_i e_i (J̃ − r_i) d_i / b; with normalised costs γ(C − r_min) = g.
        let gain = 0.5 * self.config.step_gain;
        let mut w = *start;
        // Every vector below is updated in place: on a microcontroller each temporary is
        // 4n bytes of stack. `next` first holds Σ e_i d_i.
        let (mut next, mut toward_cost) = (Vector::<N>::zeros(), Vector::<N>::zeros());
        let mut done = false;
        let mut steps = 0;
        loop {
            let (value, weight) = self.sums(set, reg, &w, inv_h2, &mut next, &mut toward_cost);
            if done || steps >= self.config.descent_iterations {
                return (w, reg.floor + value * reg.scale);
            }
            // next = w + (toward J̃ − toward_cost) g/(2b).
            next *= value;
            next -= &toward_cost;
            next *= gain / weight;
            next += &w;
            let off2 = distance2(&next, start);
            if off2 > trust2 {
                next -= start;
                next *= libm::sqrtf(trust2 / off2);
                next += start;
                done = true;
            }
            if distance2(&next, &w) < tol2 {
                done = true;
            }
            if next.iter().any(|v| !v.is_finite()) {
                done = true;
            } else {
                w = next;
            }
            steps += 1;
        }
    }

    /// Steps 2–4 of the module docs after the rollout (`cost`) just remembered, then
    /// [`Self::accept`] (steps 4–6).
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn update(&mut self, cost: f32, previous: f32) {
        if !(is_finite(&self.factor) && is_finite(&self.inverse)) {
            self.recover();
        }
        if self.len == 0 {
            // The recovery could not place the remembered rollouts: start again from this one.
            self.remember(self.drawn, cost);
        }
        if self.len < 2 {
            return;
        }
        self.updates = self.updates.saturating_add(1);
        let sigma = self.sigma;
        let h2 = (self.constants.kernel * sigma * sigma).max(f32::MIN_POSITIVE);

        let cheapest = self.select_near();
        let near = self.regression(Set::Near);
        // Start points of `ROCKstar.m`: θ*; then, once the near set is large enough (its
        // gate), the cheapest near rollout, the new rollout if it beats C, the best rollout
        // ever if it is not in the near set.
        let mut best = self.descend(Set::Near, &near, &self.theta_star_white, h2);
        if self.near_len >= self.extra_starts_from() {
            self.descend_from_near_starts(cheapest, cost, &near, h2, &mut best);
            self.descend_from_best_ever(&near, h2, &mut best);
        }

        self.accept(&best, cost, previous);
        // Every n covariance updates; here rather than in `adapt_shape`, so that the two
        // frames are not on the stack together (module docs, "Stack").
        if self.since_refactor >= N as u32 {
            self.since_refactor = 0;
            if !self.refactor() {
                self.recover();
            }
        }
    }

    /// Steps 4–6 after the descents: θ* ← the end point `best` (whitened, J̃/2), the
    /// covariance update and the σ rule.
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn accept(&mut self, best: &(Vector<N>, f32), cost: f32, previous: f32) {
        let sigma = self.sigma;
        // One vector on the stack: x = A w_best, then A⁻¹θ*, then A⁻¹Δθ.
        let mut v = times(&self.factor, &best.0);
        if v.iter().all(|v| v.is_finite()) {
            self.theta_star = clamp_unit(v);
            times_into(&self.inverse, &self.theta_star, &mut v);
            // A⁻¹Δθ = A⁻¹θ*_new − A⁻¹θ*_old, formed in the old value's place.
            core::mem::swap(&mut v, &mut self.theta_star_white);
            let mut delta = v;
            delta.zip_apply(&self.theta_star_white, |d, w| *d = w - *d);
            self.estimate = Some((2.0 * best.1).clamp(-f32::MAX, f32::MAX));
            // √(Δθᵀ Σ⁻¹ Δθ) = ‖A⁻¹Δθ‖/σ.
            if delta.norm() < self.constants.path_bound * sigma {
                delta /= sigma;
                self.adapt_shape(&delta);
            }
        } else {
            self.recover();
        }

        let sigma = if cost > previous {
            sigma / (self.constants.zeta * self.constants.xi)
        } else {
            sigma * self.constants.zeta
        };
        self.sigma = sigma.max(SIGMA_FLOOR).min(self.config.max_sigma);
        if self.sigma <= self.config.tolerance {
            self.ledger.stop(Status::Converged);
        }
    }

    /// The near set's size from which the extra start points are used
    /// ([`RockstarConfig::extra_starts_from`]; 2n by default).
    fn extra_starts_from(&self) -> usize {
        self.config.extra_starts_from.map_or(2 * N, |k| k as usize)
    }

    /// Descends from the extra start points of `ROCKstar.m` in the near set (the cheapest
    /// near rollout `cheapest`, the new rollout if its `cost` beats C) and keeps in `best`
    /// the end point of lowest J̃.
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn descend_from_near_starts(
        &self,
        cheapest: Option<usize>,
        cost: f32,
        near: &Regression,
        h2: f32,
        best: &mut (Vector<N>, f32),
    ) {
        if let Some(w) = cheapest.and_then(|i| self.samples.get(i)) {
            keep_lower(best, self.descend(Set::Near, near, w, h2));
        }
        if 0.5 * cost < near.floor + near.scale
            && let Some(w) = self.newest()
        {
            keep_lower(best, self.descend(Set::Near, near, w, h2));
        }
    }

    /// Descends from the best rollout ever if it is cheaper than the near set's cheapest
    /// (`near`), over every remembered rollout, and keeps in `best` the end point of lowest
    /// J̃ (the last extra start point of `ROCKstar.m`).
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn descend_from_best_ever(&self, near: &Regression, h2: f32, best: &mut (Vector<N>, f32)) {
        if let Some(ever) = self.ledger.best()
            && 0.5 * ever.cost < near.floor
        {
            let x = clamp_unit(self.unit.unit_of(&ever.theta));
            let w = times(&self.inverse, &x);
            let all = self.regression(Set::All);
            keep_lower(best, self.descend(Set::All, &all, &w, h2));
        }
    }

    /// P_c ← (1 − c_c) P_c + c_c Δθ/σ and the rank-one update of Σ_u with det Σ_u kept
    /// (`step` = A⁻¹Δθ/σ). In the factored form Σ_u = A Aᵀ, with z = A⁻¹P_c and
    /// t = (c_cov/(1 − c_cov)) ‖z‖², g = 1 + t:
    /// A ← g^{−1/(2n)} (A + ((√g − 1)/‖z‖²) (A z) zᵀ),
    /// A⁻¹ ← g^{1/(2n)} (A⁻¹ − ((1 − 1/√g)/‖z‖²) z (zᵀ A⁻¹)),
    /// which is (1 − c_cov) Σ_u + c_cov P_c P_cᵀ rescaled to det = 1 exactly; every whitened
    /// vector w = A⁻¹x follows in O(n).
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn adapt_shape(&mut self, step: &Vector<N>) {
        let k = self.constants;
        let z = self.path * (1.0 - k.c_c) + step * k.c_c;
        self.path = z;
        let zz = z.norm_squared();
        if !(zz > 0.0 && zz.is_finite()) {
            return;
        }
        let t = k.c_cov / (1.0 - k.c_cov) * zz;
        let log_g = libm::log1pf(t);
        let grow = libm::expm1f(0.5 * log_g) / zz; // (√g − 1)/‖z‖²
        let shrink = -libm::expm1f(-0.5 * log_g) / zz; // (1 − 1/√g)/‖z‖²
        let volume = libm::expf(log_g / (2 * N) as f32); // g^{1/(2n)}

        let az = times(&self.factor, &z);
        let zt_inv = self.inverse.tr_mul(&z); // (zᵀ A⁻¹)ᵀ
        let usable = |v: &Vector<N>| v.iter().all(|x| x.is_finite());
        if !(usable(&az) && usable(&zt_inv) && grow.is_finite() && volume.is_finite()) {
            self.recover();
            return;
        }
        self.factor.ger(grow, &az, &z, 1.0);
        self.factor *= 1.0 / volume;
        self.inverse.ger(-shrink, &z, &zt_inv, 1.0);
        self.inverse *= volume;
        let move_white = |w: &mut Vector<N>| {
            let along = z.dot(w) * shrink;
            w.axpy(-along, &z, 1.0);
            *w *= volume;
        };
        for w in self.samples.iter_mut().take(self.len) {
            move_white(w);
        }
        move_white(&mut self.theta_star_white);
        move_white(&mut self.path);
        self.covariance_updates = self.covariance_updates.saturating_add(1);
        self.since_refactor += 1;
    }

    /// A ← s L with L = chol(A Aᵀ) and s = det(L)^{−1/n}, A⁻¹ ← (s L)⁻¹, every whitened
    /// vector w ← (s L)⁻¹ A w; `false` when A Aᵀ is not numerically positive definite (A
    /// and the whitened vectors unchanged, A⁻¹ overwritten: the caller resets the shape).
    /// No N × N temporary (3.8 KB at n = 31, on a microcontroller's stack): L is built in
    /// A⁻¹'s storage, since A⁻¹ is recomputed from it.
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn refactor(&mut self) -> bool {
        gram_into(&self.factor, &mut self.inverse);
        if !cholesky_in_place(&mut self.inverse, N, None) {
            return false;
        }
        let l = &self.inverse;
        let half_log_det: f32 = (0..N).map(|i| libm::logf(l[(i, i)])).sum();
        let scale = libm::expf(-half_log_det / N as f32);
        if !(scale.is_finite() && scale > 0.0) {
            return false;
        }
        let factor = &self.factor;
        let rewhiten = |w: &mut Vector<N>| {
            let mut x = times(factor, w);
            solve_lower(l, &mut x, N);
            *w = x * (1.0 / scale);
        };
        for w in self.samples.iter_mut().take(self.len) {
            rewhiten(w);
        }
        rewhiten(&mut self.path);
        for j in 0..N {
            for i in 0..N {
                self.factor[(i, j)] = if i < j { 0.0 } else { scale * l[(i, j)] };
            }
        }
        lower_inverse_into(&self.factor, &mut self.inverse);
        self.theta_star_white = times(&self.inverse, &self.theta_star);
        if !(is_finite(&self.factor) && is_finite(&self.inverse)) {
            self.recover();
        }
        true
    }

    /// Resets the shape (module docs, "Recovery"): Σ_u = I, P_c = 0; the remembered
    /// rollouts are moved to the new coordinates (w = x), or forgotten if A w is not finite.
    fn recover(&mut self) {
        let factor = &self.factor;
        let placed = self
            .samples
            .iter()
            .take(self.len)
            .all(|w| times(factor, w).iter().all(|v| v.is_finite()));
        if placed {
            for w in self.samples.iter_mut().take(self.len) {
                *w = clamp_unit(times(factor, w));
            }
        } else {
            self.len = 0;
            self.head = 0;
        }
        self.near_len = 0;
        // In place: `= SMatrix::identity()` builds each matrix on the stack first.
        self.factor.fill_with_identity();
        self.inverse.fill_with_identity();
        self.path = Vector::zeros();
        self.theta_star_white = self.theta_star;
        self.since_refactor = 0;
        self.recoveries = self.recoveries.saturating_add(1);
    }
}

#[cfg(feature = "serde")]
impl<const N: usize, const M: usize> Rockstar<N, M> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (configuration, `initial_samples` ≤ M, the strategy constants and
    /// the unit map that follow from them, the box) and the search's: θ* finite and inside
    /// [−1, 1]ⁿ, σ finite in (0, max_sigma], A, A⁻¹, the path and the whitened θ* finite,
    /// the ring's length ≤ M and head below M (equal to the length until it is full), the
    /// remembered rollouts and costs finite, the near set's indices below the length, the
    /// pending draw inside [−1, 1]ⁿ and finite whitened, and the remembered costs finite.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::require_finite;
        self.config.validate()?;
        require(
            (self.config.initial_samples as usize) <= M,
            "initial_samples",
        )?;
        require(
            self.constants == Constants::new(N, &self.config)?,
            "constants",
        )?;
        let bounds = &self.unit.bounds;
        bounds.check_decoded()?;
        require(self.unit == UnitMap::new(*bounds), "unit")?;
        let unit_box = |x: &Vector<N>| x.iter().all(|v| (-1.0..=1.0).contains(v));
        require(unit_box(&self.theta_star), "theta_star")?;
        require_finite(&self.theta_star_white, "theta_star_white")?;
        require(
            self.sigma.is_finite() && self.sigma > 0.0 && self.sigma <= self.config.max_sigma,
            "sigma",
        )?;
        require(is_finite(&self.factor), "factor")?;
        require(is_finite(&self.inverse), "inverse")?;
        require_finite(&self.path, "path")?;
        require(
            self.len <= M && self.head < M && (self.len == M || self.head == self.len),
            "len",
        )?;
        for (w, c) in self.samples.iter().zip(&self.costs).take(self.len) {
            require_finite(w, "samples")?;
            require_finite([c], "costs")?;
        }
        require(self.near_len <= self.len, "near_len")?;
        let near = self.near.get(..self.near_len).unwrap_or(&[]);
        require(near.iter().all(|&i| usize::from(i) < self.len), "near")?;
        require(unit_box(&self.drawn), "drawn")?;
        require_finite(&self.drawn_white, "drawn_white")?;
        require_finite(self.last_cost.iter(), "last_cost")?;
        require_finite(self.estimate.iter(), "estimate")?;
        self.ledger.check_decoded(bounds)
    }
}

impl<const N: usize, const M: usize> Rockstar<N, M> {
    /// x = θ* + σ A z projected onto the unit box: the next rollout in normalised
    /// coordinates (nothing in it depends on the costs told since the last update).
    fn draw_unit<R: RngCore + ?Sized>(&self, rng: &mut R) -> Vector<N> {
        // In place.
        let mut x = times(&self.factor, &normal_vector_f32(rng));
        x *= self.sigma;
        x += &self.theta_star;
        clamp_unit(x)
    }

    /// Makes the rollout `drawn` (normalised) the pending candidate and returns its θ.
    fn hand_out_unit(&mut self, drawn: Vector<N>) -> Vector<N> {
        self.drawn = drawn;
        self.drawn_white = times(&self.inverse, &self.drawn);
        let theta = self.unit.theta_of(&self.drawn);
        self.ledger.hand_out(theta, &self.unit.bounds)
    }
}

/// The `initial_samples` rollouts before the first update are all drawn around the start,
/// so they can be in flight together; after them each rollout follows the update of the
/// one before (one at a time).
impl<const N: usize, const M: usize> Generation<N> for Rockstar<N, M> {
    fn room(&self) -> usize {
        let initial = self.config.initial_samples as usize;
        self.ledger.room(
            initial
                .saturating_sub(self.ledger.evaluations() as usize)
                .max(1),
        )
    }

    fn most(&self) -> usize {
        self.config.initial_samples as usize
    }

    fn draws_ahead(&self) -> bool {
        true
    }

    fn draw<R: RngCore + ?Sized>(&mut self, _ahead: usize, rng: &mut R) -> Result<Draw<N>, Error> {
        let drawn = self.draw_unit(rng);
        let theta = self.unit.bounds.clamp(&self.unit.theta_of(&drawn));
        Ok(Draw {
            theta,
            aux: drawn,
            excess: 0.0,
        })
    }

    fn resume(&mut self, draw: &Draw<N>) {
        self.hand_out_unit(draw.aux);
    }

    fn check_draw(&self, draw: &Draw<N>) -> Result<(), Error> {
        self.unit.bounds.check(&draw.theta, "in_flight")?;
        require(
            draw.aux.iter().all(|v| (-1.0..=1.0).contains(v)),
            "in_flight",
        )
    }
}

impl<const N: usize, const M: usize> Optimizer<N> for Rockstar<N, M> {
    // Out of line: module docs, "Stack".
    #[inline(never)]
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        let drawn = self.draw_unit(rng);
        Ok(self.hand_out_unit(drawn))
    }

    #[inline(never)]
    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        self.ledger.accept(cost)?;
        self.remember(self.drawn_white, cost);
        let previous = self.last_cost.replace(cost);
        if let Some(previous) = previous
            && self.ledger.evaluations() >= self.config.initial_samples
        {
            self.update(cost, previous);
        }
        self.ledger.settle();
        Ok(())
    }

    ledger_accessors!(unit.bounds);
}

/// `x` projected onto [−1, 1]ⁿ; NaN maps to −1. (By value and in place: no second vector.)
fn clamp_unit<const N: usize>(mut x: Vector<N>) -> Vector<N> {
    // `clamp`'s `min <= max` assertion holds for these constants and is optimised away.
    x.apply(|v| *v = if v.is_nan() { -1.0 } else { v.clamp(-1.0, 1.0) });
    x
}

/// `best` ← `candidate` if the candidate's J̃ (its second element) is lower.
fn keep_lower<const N: usize>(best: &mut (Vector<N>, f32), candidate: (Vector<N>, f32)) {
    if candidate.1 < best.1 {
        *best = candidate;
    }
}

/// ‖a − b‖², without the difference as a temporary.
fn distance2<const N: usize>(a: &Vector<N>, b: &Vector<N>) -> f32 {
    a.iter().zip(b.iter()).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn is_finite<const N: usize>(m: &SMatrix<f32, N, N>) -> bool {
    m.iter().all(|v| v.is_finite())
}

/// Writes the lower triangle of A Aᵀ into `s` (its upper triangle is left as it was: the
/// routines below read only the lower one). Written out: no transposed copy of A.
fn gram_into<const N: usize>(a: &SMatrix<f32, N, N>, s: &mut SMatrix<f32, N, N>) {
    for j in 0..N {
        for i in j..N {
            let mut v = 0.0;
            for k in 0..N {
                v += a[(i, k)] * a[(j, k)];
            }
            s[(i, j)] = v;
        }
    }
}

/// `inv` ← L⁻¹ for the lower triangle L of `l` (positive diagonal): one forward
/// substitution per column.
fn lower_inverse_into<const N: usize>(l: &SMatrix<f32, N, N>, inv: &mut SMatrix<f32, N, N>) {
    for c in 0..N {
        for i in 0..N {
            let mut v = if i == c { 1.0 } else { 0.0 };
            if i > c {
                for k in c..i {
                    v -= l[(i, k)] * inv[(k, c)];
                }
            }
            inv[(i, c)] = if i < c { 0.0 } else { v / l[(i, i)] };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::{Best, Cmaes, CmaesConfig};
    use crate::testing::{
        any_wide_bounds, check_any_costs, check_call_order, check_rejected_calls_change_nothing,
        check_rejected_configs, check_rejected_starts, check_seeded, ellipsoid,
        evaluations_to_target, rng, rotation, tell_inside, with_start,
    };
    use proptest::prelude::*;

    type M64<const D: usize> = nalgebra::SMatrix<f64, D, D>;

    fn config(max_evaluations: u32) -> RockstarConfig {
        RockstarConfig {
            max_evaluations,
            ..RockstarConfig::DEFAULT
        }
    }

    /// A search of [−1, 1]ᴺ starting at θ = 0 with `cfg`, and its box.
    fn from_origin<const N: usize, const M: usize>(
        cfg: RockstarConfig,
    ) -> (Bounds<N>, Rockstar<N, M>) {
        let bounds = Bounds::uniform(-1.0, 1.0).unwrap();
        (
            bounds,
            Rockstar::try_new(bounds, Vector::zeros(), cfg).unwrap(),
        )
    }

    fn sphere<const D: usize>(t: &Vector<D>) -> f32 {
        (t - Vector::repeat(0.3)).norm_squared()
    }

    /// The determinant by Gaussian elimination with partial pivoting (f64).
    fn determinant<const D: usize>(mut m: M64<D>) -> f64 {
        let mut det = 1.0;
        for c in 0..D {
            let pivot = (c..D)
                .max_by(|&i, &j| m[(i, c)].abs().total_cmp(&m[(j, c)].abs()))
                .unwrap();
            if pivot != c {
                m.swap_rows(pivot, c);
                det = -det;
            }
            let d = m[(c, c)];
            det *= d;
            for i in c + 1..D {
                let f = m[(i, c)] / d;
                for j in c..D {
                    m[(i, j)] -= f * m[(c, j)];
                }
            }
        }
        det
    }

    /// det(A Aᵀ) and max |A A⁻¹ − I| in f64.
    fn factor_health<const D: usize, const K: usize>(r: &Rockstar<D, K>) -> (f64, f64) {
        let a = r.factor.map(f64::from);
        let inv = r.inverse.map(f64::from);
        let det = determinant(a * a.transpose());
        let err = (a * inv - M64::<D>::identity()).amax();
        (det, err)
    }

    /// Checks P(0.95, n) against the χ² table (values computed in f64 by bisection of the
    /// regularised incomplete gamma function) for n = 1, 2, 3, 5, 10, 18, 31, 100, 500: within
    /// 1 % everywhere (exact for n = 1, 2; Wilson–Hilferty below 0.6 % from n = 3 on).
    #[test]
    fn chi_squared_matches_the_table() {
        let table = [
            (1, 3.841_459),
            (2, 5.991_465),
            (3, 7.814_728),
            (5, 11.070_498),
            (10, 18.307_038),
            (18, 28.869_299),
            (31, 44.985_343),
            (100, 124.342_11),
            (500, 553.126_8),
        ];
        for (n, p) in table {
            let got = chi_squared_95(n);
            let error = (got - p).abs() / p;
            assert!(error < 0.01, "n = {n}: {got} against {p}");
            if n >= 3 {
                assert!(error < 0.006, "n = {n}: {got} against {p}");
            } else {
                assert!(error < 1e-6, "n = {n}: {got} against {p}");
            }
        }
        assert_eq!(chi_squared_95(0), 0.0);
    }

    /// Checks the strategy constants against the authors' formulas in f64 for n = 31 and
    /// n = 3 with the default λ = 0.3: ϑ = −P(0.95, n)/(2 ln λ) and λ_MD·P(0.95, n) (to the χ²
    /// approximation's accuracy), κ χ̂_n, c_c, c_cov, ζ = 1.3^{1/ln(n + 2.5)}, ξ = ζ^{0.3}
    /// (to 1e-5); and that explicit ζ, ξ, c_c, c_cov are taken as given.
    #[test]
    fn constants_follow_the_authors_code() {
        for (n, p) in [(31usize, 44.985_343f64), (3, 7.814_728)] {
            let k = Constants::new(n, &RockstarConfig::DEFAULT).unwrap();
            let nf = n as f64;
            let close = |a: f32, b: f64, tol: f64| (f64::from(a) - b).abs() <= tol * b.abs();
            assert!(
                close(k.kernel, -p / (2.0 * 0.3f64.ln()), 6e-3),
                "{}",
                k.kernel
            );
            assert!(close(k.near_bound, 10.0 * p, 6e-3));
            let chi = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
            assert!(close(k.path_bound, 1.5 * chi, 1e-5));
            assert!(close(k.c_c, 3.0 / ((nf + 6.0) * (nf + 6.0).ln()), 1e-5));
            assert!(close(k.c_cov, 6.0 / ((nf + 7.0) * (nf + 7.0).ln()), 1e-5));
            let zeta = 1.3f64.powf(1.0 / (nf + 2.5).ln());
            assert!(close(k.zeta, zeta, 1e-5));
            assert!(close(k.xi, zeta.powf(0.3), 1e-5));
        }
        let given = RockstarConfig {
            zeta: Some(1.2),
            xi: Some(1.1),
            c_c: Some(0.3),
            c_cov: Some(0.2),
            ..RockstarConfig::DEFAULT
        };
        let k = Constants::new(5, &given).unwrap();
        assert_eq!((k.zeta, k.xi, k.c_c, k.c_cov), (1.2, 1.1, 0.3, 0.2));
    }

    /// Checks, on the 10-D sphere ‖θ − 0.3‖² in [−1, 1]¹⁰ from 0 with the defaults and a
    /// memory of 50, seeds 0–5: the best cost falls below 1e-6 within 800 evaluations; the
    /// search then stops with `Converged` (σ ≤ 10⁻⁶) before 1500, with θ* within 1e-3 of the
    /// minimiser and its cost below 1e-6; no recovery.
    #[test]
    fn minimises_the_sphere() {
        let bounds = Bounds::<10>::uniform(-1.0, 1.0).unwrap();
        for seed in 0..6 {
            let mut rock =
                Rockstar::<10, 50>::try_new(bounds, Vector::zeros(), config(1500)).unwrap();
            let hit = evaluations_to_target(&mut rock, sphere, seed, 1e-6);
            assert!(hit.is_some_and(|e| e <= 800), "seed {seed}: {hit:?}");
            assert_eq!(rock.status(), Status::Converged, "seed {seed}");
            assert!(rock.sigma() <= 1e-6);
            assert!((rock.theta_star() - Vector::repeat(0.3)).amax() < 1e-3);
            assert!(sphere(&rock.theta_star()) < 1e-6);
            assert_eq!(rock.recoveries(), 0);
        }
    }

    /// Checks, on the rotated 10-D ellipsoid of condition 10³ in [−1, 1]¹⁰ from 0, memory
    /// 50, seeds 0–3: the best cost falls below 1e-6 within 2500 evaluations, θ*'s cost too
    /// by the end; the learned shape Σ_u, seen in the ellipsoid's axes (coefficients
    /// 1000^{i/9}), has over 100 times the variance along the flattest axis than along the
    /// steepest (ideal 1000), and over 10 times the total variance on the five flattest axes
    /// than on the five steepest (the order between neighbouring axes is not resolved). With
    /// covariance adaptation all but off (c_cov = 10⁻⁶) the same budget does not reach 1e-6
    /// (seeds 0–1): the shape is what does it.
    #[test]
    fn learns_a_rotated_ellipsoid() {
        let bounds = Bounds::<10>::uniform(-1.0, 1.0).unwrap();
        let f = ellipsoid(1e3);
        let r = rotation().map(f64::from);
        for seed in 0..4 {
            let mut rock =
                Rockstar::<10, 50>::try_new(bounds, Vector::zeros(), config(2500)).unwrap();
            let hit = evaluations_to_target(&mut rock, &f, seed, 1e-6);
            assert!(hit.is_some(), "seed {seed}: best {:?}", rock.best());
            assert!(f(&rock.theta_star()) < 1e-6, "seed {seed}");
            let seen = r * rock.shape().map(f64::from) * r.transpose();
            let variances: std::vec::Vec<f64> = (0..10).map(|i| seen[(i, i)]).collect();
            assert!(
                variances[0] / variances[9] > 100.0,
                "seed {seed}: {variances:?}"
            );
            let flat: f64 = variances[..5].iter().sum();
            let steep: f64 = variances[5..].iter().sum();
            assert!(flat > 10.0 * steep, "seed {seed}: {variances:?}");
            assert_eq!(rock.recoveries(), 0);
            if seed >= 2 {
                continue;
            }
            let frozen = RockstarConfig {
                c_cov: Some(1e-6),
                ..config(2500)
            };
            let mut rock = Rockstar::<10, 50>::try_new(bounds, Vector::zeros(), frozen).unwrap();
            assert_eq!(
                evaluations_to_target(&mut rock, &f, seed, 1e-6),
                None,
                "seed {seed}"
            );
        }
    }

    /// Checks, on the 10-D sphere from 0 with σ₀ = 0.1 for both and seeds 0–7, the best cost
    /// after 200 evaluations: ROCK* (memory 50) is below CMA-ES (λ = 10, the default
    /// population) on at least 7 of the 8 seeds, and its geometric mean is below a quarter of
    /// CMA-ES's (measured: 8 of 8, about 1/14).
    #[test]
    fn fewer_evaluations_than_cmaes_on_the_sphere() {
        let bounds = Bounds::<10>::uniform(-1.0, 1.0).unwrap();
        // The best cost after 200 evaluations of the sphere.
        fn after<O: Optimizer<10>>(mut opt: O, seed: u64) -> f32 {
            let bounds = *opt.bounds();
            tell_inside(&mut opt, &bounds, &mut rng(seed), sphere, Some(200));
            opt.best().unwrap().cost
        }
        let (mut wins, mut log_ratio) = (0, 0.0f64);
        for seed in 0..8 {
            let rock = Rockstar::<10, 50>::try_new(bounds, Vector::zeros(), config(200)).unwrap();
            let cfg = CmaesConfig {
                initial_sigma: 0.1,
                max_evaluations: 200,
                ..CmaesConfig::DEFAULT
            };
            let cma = Cmaes::<10, 10>::try_new(bounds, Vector::zeros(), cfg).unwrap();
            let (ours, theirs) = (after(rock, seed), after(cma, seed));
            wins += usize::from(ours < theirs);
            log_ratio += f64::from(ours / theirs).ln();
        }
        let ratio = (log_ratio / 8.0).exp();
        assert!(wins >= 7, "{wins} of 8");
        assert!(ratio < 0.25, "geometric mean ratio {ratio}");
    }

    /// Checks the gate on the extra start points (`ROCKstar.m` of 2015): on the 3-D sphere
    /// (memory 15, seed 2, 300 rollouts), each rollout is told to the search and to two
    /// clones of it made just before, one that always uses the extra start points and one
    /// that never does. With the default gate (2n = 6) the update's θ* equals the never
    /// clone's whenever the near set holds fewer than 6 rollouts, and the always clone's
    /// otherwise; both cases occur, and in both the two clones differ at least once (so
    /// the extra start points do change θ*).
    #[test]
    fn extra_starts_wait_for_a_near_set_of_2n() {
        let (_, mut rock) = from_origin::<3, 15>(config(300));
        assert_eq!(rock.extra_starts_from(), 6);
        let mut r = rng(2);
        let (mut closed, mut open) = ((0, 0), (0, 0));
        while let Ok(t) = rock.ask(&mut r) {
            let (mut always, mut never) = (rock.clone(), rock.clone());
            always.config.extra_starts_from = Some(0);
            never.config.extra_starts_from = Some(u32::MAX);
            for search in [&mut rock, &mut always, &mut never] {
                search.tell(sphere(&t)).unwrap();
            }
            if rock.updates() == 0 {
                continue;
            }
            let differ = usize::from(always.theta_star != never.theta_star);
            if rock.near_len < 6 {
                assert_eq!(rock.theta_star, never.theta_star, "{}", rock.evaluations());
                closed = (closed.0 + 1, closed.1 + differ);
            } else {
                assert_eq!(rock.theta_star, always.theta_star, "{}", rock.evaluations());
                open = (open.0 + 1, open.1 + differ);
            }
        }
        assert!(
            closed.1 > 0 && open.1 > 0,
            "closed {closed:?}, open {open:?}"
        );
    }

    /// Checks the paper's g = ½ against the code's g = 1 (γ = g/(C − r_min)): with g = 1
    /// the 10-D sphere is also minimised below 1e-6 within 800 evaluations, seeds 0–3.
    #[test]
    fn step_gain_of_the_code_also_converges() {
        let bounds = Bounds::<10>::uniform(-1.0, 1.0).unwrap();
        let cfg = RockstarConfig {
            step_gain: 1.0,
            ..config(800)
        };
        for seed in 0..4 {
            let mut rock = Rockstar::<10, 50>::try_new(bounds, Vector::zeros(), cfg).unwrap();
            assert!(
                evaluations_to_target(&mut rock, sphere, seed, 1e-6).is_some(),
                "seed {seed}"
            );
        }
    }

    /// Checks the paper's claim about two rollouts ("the minimum is formed outside of the
    /// convex hull ... in the direction of the parameter vectors with the lower costs; always
    /// true in a two point case"): after the first update, θ* lies beyond the cheaper of the
    /// two rollouts, on the far side from the dearer one, on 8 seeds.
    #[test]
    fn two_rollouts_extrapolate_past_the_cheaper() {
        let bounds = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let f = |t: &Vector<3>| (t - Vector::from([0.8, -0.5, 0.2])).norm_squared();
        for seed in 0..8 {
            let mut rock = Rockstar::<3, 8>::try_new(bounds, Vector::zeros(), config(10)).unwrap();
            let mut r = rng(seed);
            let mut told = std::vec::Vec::new();
            for _ in 0..2 {
                let t = rock.ask(&mut r).unwrap();
                told.push((t, f(&t)));
                rock.tell(f(&t)).unwrap();
            }
            assert_eq!(rock.updates(), 1);
            told.sort_by(|a, b| a.1.total_cmp(&b.1));
            let (cheap, dear) = (told[0].0, told[1].0);
            let beyond = (rock.theta_star() - cheap).dot(&(cheap - dear));
            assert!(beyond > 0.0, "seed {seed}: θ* {:?}", rock.theta_star());
        }
    }

    /// Checks step 6 of Algorithm 1 at every update of a run: σ grows by ζ after a rollout
    /// no worse than the previous one (ties included) and shrinks by ζξ after a worse one
    /// (within the limits), σ is untouched by the initial samples.
    #[test]
    fn sigma_follows_the_paper() {
        let cfg = RockstarConfig {
            initial_samples: 3,
            ..config(300)
        };
        let (_, mut rock) = from_origin::<4, 20>(cfg);
        let k = rock.constants;
        let mut r = rng(5);
        let mut previous: Option<f32> = None;
        let (mut grew, mut shrank) = (0, 0);
        while let Ok(t) = rock.ask(&mut r) {
            // Every fifth cost repeats the previous one: ties.
            let cost = match previous {
                Some(p) if rock.evaluations() % 5 == 4 => p,
                _ => sphere(&t),
            };
            let before = rock.sigma();
            rock.tell(cost).unwrap();
            let after = rock.sigma();
            if rock.evaluations() < 3 {
                assert_eq!(after, before);
            } else if previous.is_some_and(|p| cost > p) {
                assert!((after - before / (k.zeta * k.xi)).abs() <= 1e-6 * before);
                shrank += 1;
            } else {
                assert!((after - (before * k.zeta).min(1.0)).abs() <= 1e-6 * before);
                grew += 1;
            }
            previous = Some(cost);
        }
        assert!(grew > 50 && shrank > 50, "{grew} {shrank}");
    }

    /// Checks step 5 of Algorithm 1 against an f64 transcription of the paper from the state
    /// before: P_c ← (1 − c_c) P_c + c_c Δθ/σ; Σ_u ← (1 − c_cov) Σ_u + c_cov P_c P_cᵀ;
    /// Σ_u ← (ψ/det Σ_u)^{1/n} Σ_u with ψ = 1, at every update of a 5-D run while σ ≥ 0.01,
    /// Σ_u moving far from I: A Aᵀ and A P to 1e-5 (relative); det Σ_u = 1 and A A⁻¹ = I to
    /// 1e-5; every remembered rollout and θ* keep their position A w (to 1e-5).
    #[test]
    fn covariance_update_matches_the_paper() {
        let bounds = Bounds::<5>::uniform(-1.0, 1.0).unwrap();
        let f =
            |t: &Vector<5>| 30.0 * (t[0] - t[1]).powi(2) + (t - Vector::repeat(0.2)).norm_squared();
        let mut rock = Rockstar::<5, 12>::try_new(bounds, Vector::zeros(), config(400)).unwrap();
        let mut r = rng(2);
        let mut checked = 0;
        while let Ok(t) = rock.ask(&mut r) {
            let before = rock.clone();
            rock.tell(f(&t)).unwrap();
            // While σ ≥ 0.01: below, the f32 rounding of θ* divided by σ (Δθ/σ) is no longer
            // small next to 1e-5 of P_c.
            if rock.covariance_updates() == before.covariance_updates()
                || rock.since_refactor == 0
                || before.sigma < 0.01
            {
                continue;
            }
            // Replay the update in f64 from `before` and the θ* it moved to.
            let k = before.constants;
            let (cc, ccov) = (f64::from(k.c_c), f64::from(k.c_cov));
            let a0 = before.factor.map(f64::from);
            let sigma = f64::from(before.sigma);
            let delta = (rock.theta_star - before.theta_star).map(f64::from);
            let p = a0 * before.path.map(f64::from) * (1.0 - cc) + delta * (cc / sigma);
            let mut shape = a0 * a0.transpose() * (1.0 - ccov) + p * p.transpose() * ccov;
            shape *= (1.0 / determinant(shape)).powf(1.0 / 5.0);
            let a = rock.factor.map(f64::from);
            let got = a * a.transpose();
            assert!((got - shape).amax() < 1e-5 * shape.amax(), "{got} {shape}");
            let path_error = (a * rock.path.map(f64::from) - p).amax();
            assert!(path_error < 1e-5 * p.amax(), "{path_error} {p}");
            let (det, err) = factor_health(&rock);
            assert!((det - 1.0).abs() < 1e-5 && err < 1e-5, "{det} {err}");
            let pairs = rock
                .samples
                .iter()
                .zip(before.samples.iter())
                .take(before.len);
            // The slot at `before.head` now holds the new rollout.
            for (_, (w, w0)) in pairs.enumerate().filter(|(k, _)| *k != before.head) {
                let (x, x0) = (a * w.map(f64::from), a0 * w0.map(f64::from));
                assert!((x - x0).amax() < 1e-5, "{x} {x0}");
            }
            let star = a * rock.theta_star_white.map(f64::from);
            assert!((star - rock.theta_star.map(f64::from)).amax() < 1e-5);
            checked += 1;
        }
        assert!(checked > 20, "{checked} updates checked");
        let seen = rock.shape();
        assert!(
            (seen - SMatrix::<f32, 5, 5>::identity()).amax() > 0.5,
            "{seen}"
        );
    }

    /// Checks that ψ = det Σ_u = 1 is kept over a long run on the rotated ellipsoid (4 000
    /// rollouts, hundreds of rank-one updates and refactorings): after every rollout
    /// det(A Aᵀ) = 1 and A A⁻¹ = I to 1e-4 in f64, while Σ_u itself has moved far from I.
    #[test]
    fn determinant_is_kept() {
        let cfg = RockstarConfig {
            tolerance: 0.0,
            ..config(4000)
        };
        let (_, mut rock) = from_origin::<10, 30>(cfg);
        let f = ellipsoid(1e3);
        let mut r = rng(4);
        while let Ok(t) = rock.ask(&mut r) {
            rock.tell(f(&t)).unwrap();
            let (det, err) = factor_health(&rock);
            assert!(
                (det - 1.0).abs() < 1e-4,
                "{det} after {}",
                rock.evaluations()
            );
            assert!(err < 1e-4, "{err} after {}", rock.evaluations());
        }
        assert!(
            rock.covariance_updates() > 1000,
            "{}",
            rock.covariance_updates()
        );
        let e = nalgebra::SymmetricEigen::new(rock.shape().map(f64::from));
        assert!(
            e.eigenvalues.max() / e.eigenvalues.min() > 100.0,
            "{}",
            e.eigenvalues
        );
        assert_eq!(rock.recoveries(), 0);
    }

    /// Checks the memory: with M = 8, after 30 rollouts exactly the last 8 are remembered,
    /// oldest first, with their told costs (exactly) and candidates (to 1e-5 of the box);
    /// the best rollout, long evicted, is still the ledger's best.
    #[test]
    fn memory_forgets_the_oldest() {
        let bounds = Bounds::<3>::try_new([-1.0, 0.0, 5.0].into(), [1.0, 4.0, 6.0].into()).unwrap();
        let mut rock =
            Rockstar::<3, 8>::try_new(bounds, [0.0, 2.0, 5.5].into(), config(30)).unwrap();
        let mut r = rng(3);
        let mut told = std::vec::Vec::new();
        let mut k = 0;
        while let Ok(t) = rock.ask(&mut r) {
            // The first rollout is the cheapest by far.
            let cost = if k == 0 { -100.0 } else { t.norm() + k as f32 };
            told.push((t, cost));
            rock.tell(cost).unwrap();
            k += 1;
            assert_eq!(rock.remembered(), k.min(8));
        }
        let kept: std::vec::Vec<(Vector<3>, f32)> = rock.memory().collect();
        assert_eq!(kept.len(), 8);
        for ((t, c), (t0, c0)) in kept.iter().zip(&told[22..]) {
            assert_eq!(c, c0);
            assert!((t - t0).amax() < 1e-5 * 4.0, "{t} {t0}");
        }
        assert_eq!(
            rock.best(),
            Some(Best {
                theta: told[0].0,
                cost: -100.0
            })
        );
    }

    /// Checks the box: with the minimum outside [−1, 1]³ (at (2, −3, 0.5)) and σ₀ = 1, every
    /// candidate and θ* after every update lie in the box and are finite; θ* ends on the
    /// nearest corner-face point (1, −1, 0.5) to 1e-3 and so does the best rollout.
    #[test]
    fn theta_star_stays_in_the_box() {
        let bounds = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let target = Vector::from([2.0, -3.0, 0.5]);
        let f = |t: &Vector<3>| (t - target).norm_squared();
        let cfg = RockstarConfig {
            initial_sigma: 1.0,
            ..config(600)
        };
        let mut rock = Rockstar::<3, 15>::try_new(bounds, Vector::zeros(), cfg).unwrap();
        let mut r = rng(1);
        while let Ok(t) = rock.ask(&mut r) {
            assert!(bounds.contains(&t), "{t}");
            rock.tell(f(&t)).unwrap();
            assert!(bounds.contains(&rock.theta_star()), "{}", rock.theta_star());
        }
        let corner = Vector::from([1.0, -1.0, 0.5]);
        assert!(
            (rock.theta_star() - corner).amax() < 1e-3,
            "{}",
            rock.theta_star()
        );
        assert!((rock.best().unwrap().theta - corner).amax() < 1e-3);
    }

    /// Checks flat costs: when every rollout costs the same, J̃ is flat, θ* stays at the
    /// start, σ grows at every update (ties grow, as in Algorithm 1) up to `max_sigma`, and
    /// nothing becomes non-finite.
    #[test]
    fn flat_costs_keep_theta_star_and_widen() {
        let bounds = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let start = Vector::from([0.1, -0.2, 0.3, 0.0]);
        let mut rock = Rockstar::<4, 10>::try_new(bounds, start, config(200)).unwrap();
        let mut r = rng(8);
        while let Ok(t) = rock.ask(&mut r) {
            assert!(bounds.contains(&t));
            rock.tell(7.0).unwrap();
            assert_eq!(rock.theta_star(), start);
        }
        assert_eq!(rock.sigma(), 1.0);
        assert_eq!(rock.estimated_cost(), Some(7.0));
        assert_eq!(rock.recoveries(), 0);
    }

    /// Checks extreme costs: alternating ±f32::MAX, subnormals and zeros give a finite state
    /// (θ*, σ, the shape and its inverse, the estimate) and candidates inside the box; then
    /// ordinary costs still drive θ* towards the sphere's minimum.
    #[test]
    fn extreme_costs_keep_the_state_finite() {
        let (bounds, mut rock) = from_origin::<4, 16>(config(1500));
        let mut r = rng(6);
        let wild = [
            f32::MAX,
            -f32::MAX,
            1e-45,
            0.0,
            -1e-40,
            f32::MAX,
            3.0,
            -f32::MAX,
        ];
        for k in 0..200 {
            let t = rock.ask(&mut r).unwrap();
            assert!(bounds.contains(&t));
            rock.tell(wild[k % wild.len()]).unwrap();
            assert!(rock.theta_star.iter().all(|v| v.is_finite()));
            assert!(rock.sigma().is_finite() && rock.sigma() > 0.0);
            assert!(is_finite(&rock.factor) && is_finite(&rock.inverse));
            assert!(rock.estimated_cost().is_none_or(f32::is_finite));
        }
        while let Ok(t) = rock.ask(&mut r) {
            rock.tell(sphere(&t)).unwrap();
        }
        assert!(sphere(&rock.theta_star()) < 1e-6, "{}", rock.theta_star());
    }

    /// Checks recovery: a NaN injected into the factor A (as f32 corruption would) is found
    /// at the next update; the shape is reset to I with P_c = 0, the remembered rollouts
    /// (whose positions A w are lost) are forgotten, and the search goes on with candidates
    /// in the box and still minimises the sphere below 1e-6.
    #[test]
    fn recovers_from_a_non_finite_factor() {
        let (bounds, mut rock) = from_origin::<4, 16>(config(2000));
        let mut r = rng(9);
        tell_inside(&mut rock, &bounds, &mut r, sphere, Some(40));
        rock.factor[(1, 2)] = f32::NAN;
        let t = rock.ask(&mut r).unwrap();
        assert!(bounds.contains(&t));
        rock.tell(sphere(&t)).unwrap();
        assert_eq!(rock.recoveries(), 1);
        assert_eq!(rock.remembered(), 1);
        assert_eq!(rock.path, Vector::<4>::zeros());
        assert_eq!(rock.shape(), SMatrix::<f32, 4, 4>::identity());
        tell_inside(&mut rock, &bounds, &mut r, sphere, None);
        assert_eq!(rock.recoveries(), 1);
        assert!(rock.best().unwrap().cost < 1e-6);
    }

    /// Checks recovery from a singular shape: a factor whose first row is zero (finite, but
    /// A Aᵀ has a zero row, which the rank-one updates A + (A z)·(…)ᵀ keep, so it is not
    /// positive definite) fails the next refactoring's Cholesky decomposition with a zero
    /// pivot; the shape is reset to I, the remembered rollouts keep their positions (A w is
    /// finite), and the sphere is still minimised. (A zero column, used before, is repaired
    /// by the first rank-one update, so whether a refactoring failed was up to rounding.)
    #[test]
    fn recovers_from_a_singular_shape() {
        let (bounds, mut rock) = from_origin::<4, 16>(config(2000));
        let mut r = rng(10);
        tell_inside(&mut rock, &bounds, &mut r, sphere, Some(40));
        rock.factor.row_mut(0).fill(0.0);
        let positions: std::vec::Vec<Vector<4>> = rock.memory().map(|(t, _)| t).collect();
        while rock.recoveries() == 0 {
            let t = rock.ask(&mut r).unwrap();
            rock.tell(sphere(&t)).unwrap();
            assert!(rock.evaluations() < 200, "no refactoring reached");
        }
        assert_eq!(rock.path, Vector::<4>::zeros());
        assert_eq!(rock.shape(), SMatrix::<f32, 4, 4>::identity());
        // The rollouts remembered before the corruption that are still there did not move.
        let now: std::vec::Vec<Vector<4>> = rock.memory().map(|(t, _)| t).collect();
        let kept = positions
            .iter()
            .filter(|p| now.iter().any(|q| (*p - q).amax() < 1e-5));
        assert!(kept.count() > 0);
        while let Ok(t) = rock.ask(&mut r) {
            rock.tell(sphere(&t)).unwrap();
        }
        assert!(rock.best().unwrap().cost < 1e-6);
    }

    /// Checks: `tell` without a pending candidate, and NaN or infinite costs, are errors that
    /// leave the whole state unchanged (the candidate stays pending and is told afterwards),
    /// before and after the first update; a repeated `ask` returns the pending candidate.
    #[test]
    fn rejected_calls_change_nothing() {
        let (_, mut rock) = from_origin::<3, 6>(config(100));
        check_rejected_calls_change_nothing(&mut rock, 10);
        assert_eq!((rock.evaluations(), rock.updates()), (10, 9));
    }

    /// Checks: the search stops with `Converged` once σ ≤ tolerance (then `ask` is
    /// `Stopped`), and with `BudgetSpent` when the budget runs out first; θ* and the best stay
    /// available.
    #[test]
    fn stops_on_tolerance_and_budget() {
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let cfg = RockstarConfig {
            tolerance: 1e-3,
            ..config(10_000)
        };
        let mut rock = Rockstar::<2, 10>::try_new(bounds, Vector::repeat(0.5), cfg).unwrap();
        let mut r = rng(6);
        while let Ok(t) = rock.ask(&mut r) {
            rock.tell(t.norm_squared()).unwrap();
        }
        assert_eq!(rock.status(), Status::Converged);
        assert!(rock.sigma() <= 1e-3);
        assert_eq!(rock.ask(&mut r), Err(Error::Stopped));
        assert!(rock.theta_star().norm() < 1e-2);

        let mut rock = Rockstar::<2, 10>::try_new(bounds, Vector::zeros(), config(9)).unwrap();
        while let Ok(t) = rock.ask(&mut r) {
            rock.tell(t.norm_squared()).unwrap();
        }
        assert_eq!(rock.status(), Status::BudgetSpent);
        assert_eq!(rock.evaluations(), 9);
        assert_eq!(rock.ask(&mut r), Err(Error::Stopped));
        assert!(rock.best().is_some() && rock.estimated_cost().is_some());
    }

    /// Checks: the same seed gives the same candidates, another seed differs.
    #[test]
    fn identical_seeds_give_identical_runs() {
        let bounds = Bounds::<5>::uniform(-2.0, 2.0).unwrap();
        let rock = Rockstar::<5, 20>::try_new(bounds, Vector::zeros(), config(200)).unwrap();
        assert_eq!(check_seeded(&rock, 0.0, |t| t.norm()), 200);
    }

    /// Checks the shared call-order contract (tell without ask, repeated ask, budget stop).
    #[test]
    fn call_order() {
        let (_, mut rock) = from_origin::<3, 6>(config(3));
        check_call_order(&mut rock);
    }

    /// Checks: every invalid configuration field and start is rejected with the error
    /// naming it.
    #[test]
    fn constructor_names_the_bad_parameter() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let z = Vector::<2>::zeros();
        check_rejected_configs(
            RockstarConfig::DEFAULT,
            |c| Rockstar::<2, 4>::try_new(b, z, c),
            &[
                (|c| c.initial_sigma = 0.0, "initial_sigma"),
                (|c| c.initial_sigma = 2.0, "initial_sigma"),
                (|c| c.max_sigma = f32::NAN, "max_sigma"),
                (|c| c.lambda = 1.0, "lambda"),
                (|c| c.lambda = 0.0, "lambda"),
                (|c| c.near_radius = 0.0, "near_radius"),
                (|c| c.initial_samples = 1, "initial_samples"),
                (|c| c.initial_samples = 5, "initial_samples"),
                (|c| c.step_gain = -1.0, "step_gain"),
                (|c| c.descent_iterations = 0, "descent_iterations"),
                (|c| c.trust_radius = f32::INFINITY, "trust_radius"),
                (|c| c.descent_tolerance = -1.0, "descent_tolerance"),
                (|c| c.kappa = 0.0, "kappa"),
                (|c| c.zeta = Some(1.0), "zeta"),
                (|c| c.xi = Some(0.0), "xi"),
                (|c| c.xi = Some(0.5), "xi"),
                (|c| c.c_c = Some(1.5), "c_c"),
                (|c| c.c_cov = Some(1.0), "c_cov"),
                (|c| c.tolerance = f32::NAN, "tolerance"),
                (|c| c.max_evaluations = 0, "max_evaluations"),
            ],
        );
        let c = RockstarConfig::DEFAULT;
        check_rejected_starts("start", |s| Rockstar::<2, 4>::try_new(b, s, c));
    }

    /// Checks the sizes quoted in the module docs: `Rockstar<18, 90>` and
    /// `Rockstar<31, 155>` (M = 5n, the window of the authors' C++ code).
    #[test]
    fn sizes() {
        assert_eq!(core::mem::size_of::<Rockstar<18, 90>>(), 10_608);
        assert_eq!(core::mem::size_of::<Rockstar<31, 155>>(), 29_408);
    }

    fn any_cost() -> impl Strategy<Value = f32> {
        prop_oneof![
            proptest::num::f32::ANY,
            proptest::num::f32::SUBNORMAL | proptest::num::f32::ZERO,
            Just(f32::MAX),
            Just(-f32::MAX),
            Just(f32::NAN),
            Just(f32::INFINITY),
            -10.0f32..10.0,
        ]
    }

    proptest! {
        /// Checks, for random boxes (widths from 1e-2 to 1e30), starts, σ₀, λ, memory sizes
        /// and cost sequences (any f32: NaN, ±∞, ±f32::MAX, subnormals): every candidate and
        /// θ* are finite and inside the box; a non-finite cost is an error that leaves the
        /// whole state unchanged; σ stays in (0, max_sigma]; det Σ_u = 1 and A A⁻¹ = I to
        /// 1e-3; the best cost never increases.
        #[test]
        fn candidates_in_bounds_and_bad_costs_change_nothing(
            (bounds, start) in with_start(any_wide_bounds::<4>()),
            sigma in 1e-6f32..1.0,
            lambda in 0.05f32..0.95,
            costs in prop::collection::vec(any_cost(), 1..150),
        ) {
            let cfg = RockstarConfig {
                initial_sigma: sigma,
                lambda,
                ..RockstarConfig::DEFAULT
            };
            let mut s = Rockstar::<4, 6>::try_new(bounds, start, cfg).unwrap();
            // Inside the box implies finite: `Bounds` are finite.
            check_any_costs(&mut s, &bounds, &costs, 1, |s, _| {
                let star = s.theta_star();
                prop_assert!(star.iter().all(|v| v.is_finite()) && bounds.contains(&star));
                prop_assert!(s.sigma() > 0.0 && s.sigma() <= 1.0);
                let (det, err) = factor_health(s);
                prop_assert!((det - 1.0).abs() < 1e-3 && err < 1e-3, "{} {}", det, err);
                Ok(())
            })?;
        }
    }
}
