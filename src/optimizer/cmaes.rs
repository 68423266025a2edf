//! The (μ/μ_w, λ)-CMA-ES with a full covariance matrix and cumulative step-size adaptation,
//! after N. Hansen, "The CMA Evolution Strategy: A Tutorial" (arXiv:1604.00772, 2016),
//! section 4 and appendix A (the "Summary of the update equations" and the default
//! constants of its table 1; positive weights only unless [`CmaesConfig::active`]).
//!
//! One generation, in the tutorial's notation (here in normalised coordinates, see below):
//!
//! 1. sample λ points x_k = m + σ y_k, y_k = B D z_k, z_k ~ N(0, I), where C = B D² Bᵀ;
//! 2. rank them by cost; ⟨y⟩_w = Σ_{i≤μ} w_i y_{i:λ}; m ← m + σ ⟨y⟩_w;
//! 3. p_σ ← (1 − c_σ) p_σ + √(c_σ(2 − c_σ)μ_eff) C^{−1/2} ⟨y⟩_w;
//!    σ ← σ exp((c_σ/d_σ)(‖p_σ‖/E‖N(0, I)‖ − 1));
//! 4. h_σ = 1 if ‖p_σ‖/√(1 − (1 − c_σ)^{2(g+1)}) < (1.4 + 2/(n + 1)) E‖N(0, I)‖, else 0;
//!    p_c ← (1 − c_c) p_c + h_σ √(c_c(2 − c_c)μ_eff) ⟨y⟩_w;
//! 5. C ← (1 + c₁δ(h_σ) − c₁ − c_μ) C + c₁ p_c p_cᵀ + c_μ Σ_{i≤μ} w_i y_{i:λ} y_{i:λ}ᵀ,
//!    δ(h_σ) = (1 − h_σ) c_c (2 − c_c) (rank-one + rank-μ update); with
//!    [`CmaesConfig::active`], the tutorial's full update: the sums run over all λ samples,
//!    the weights w_{μ+1..λ} are negative (below), the factor of C is
//!    1 + c₁δ(h_σ) − c₁ − c_μ Σ_j w_j, and a negative w_i is applied as
//!    w_i · n/‖C^{−1/2} y_{i:λ}‖² (the mean still moves by the μ best only);
//! 6. C = B D² Bᵀ again by an eigendecomposition (nalgebra's [`SymmetricEigen`]).
//!
//! Default constants (table 1 of the tutorial, positive weights, as pycma and the host
//! diagnostic `host-tests/examples/hopper_cmaes.rs`): λ = L (the const generic; the
//! tutorial's default is 4 + ⌊3 ln n⌋, [`default_population`]), μ = ⌊λ/2⌋,
//! w_i ∝ ln((λ + 1)/2) − ln i (i = 1..μ, Σ w_i = 1), μ_eff = 1/Σ w_i²,
//! c_σ = (μ_eff + 2)/(n + μ_eff + 5), d_σ = 1 + 2 max(0, √((μ_eff − 1)/(n + 1)) − 1) + c_σ,
//! c_c = (4 + μ_eff/n)/(n + 4 + 2μ_eff/n), c₁ = 2/((n + 1.3)² + μ_eff),
//! c_μ = min(1 − c₁, 2(μ_eff − 2 + 1/μ_eff)/((n + 2)² + μ_eff)),
//! E‖N(0, I)‖ ≈ √n (1 − 1/(4n) + 1/(21n²)); with `active`, w_i ∝ ln((λ + 1)/2) − ln i ≤ 0
//! for i = μ+1..λ, scaled to sum to −min(1 + c₁/c_μ, 1 + 2μ_eff⁻/(μ_eff + 2),
//! (1 − c₁ − c_μ)/(n c_μ)), μ_eff⁻ = (Σ w_i)²/Σ w_i² over those i (the tutorial's
//! eq. 50–53; none when c_μ = 0).
//!
//! # Ask/tell
//! As every optimizer here, one candidate per [`Optimizer::ask`]: each ask draws one sample
//! of the current generation and hands out its projection onto the box; the told costs are
//! kept for the μ best samples only (all λ with `active`), and the update runs when the
//! λ-th cost of the generation is told. A firmware holds one candidate at a time; the
//! optimizer holds the draws z of those samples (y = B D z).
//!
//! # Deviations from the tutorial (documented)
//! * **Normalised coordinates.** The search runs on x_i = (θ_i − c_i)/h_i, with c and h the
//!   centre and half-width of the box, so the box is [−1, 1]ⁿ, σ is relative to the box
//!   (σ₀ = 0.15 spreads the first samples over ±15 % of each half-range) and C starts at I.
//! * **The box** (the tutorial is unconstrained). A sample x outside [−1, 1]ⁿ is handed out
//!   as its projection p onto the box (candidates always lie inside the [`Bounds`]); the
//!   ranking uses the told cost plus `penalty` · ‖x − p‖² (normalised units), and the update
//!   learns from the unprojected sample x, as pycma's `BoundPenalty` does, but with a fixed
//!   penalty weight (pycma adapts it). The best-so-far is the projected point with its
//!   unpenalised cost.
//! * **f32.** All arithmetic is single precision (the Cortex-M4F FPU). Covariance
//!   eigenvalues below ≈ 10⁻⁷ of the largest are resolved poorly by an f32 decomposition,
//!   so the search distribution's axis ratio is useful up to ≈ 10³ (condition of C up to
//!   ≈ 10⁶–10⁷); beyond, convergence along the thinnest axes slows.
//! * **Eigenvalue floor.** After each decomposition every eigenvalue is raised to at least
//!   10⁻¹⁴ × the largest (and the smallest positive normal f32), so D⁻¹ (in C^{−1/2}) is
//!   always finite; C itself is not changed.
//! * **Recovery from non-finite values.** If after an update C, the paths, the mean or σ
//!   hold a NaN or infinity, or C's largest eigenvalue is not positive, or the decomposition
//!   does not converge, the search restarts its shape: C = B = D = I, p_σ = p_c = 0, the
//!   mean kept (or the previous mean if the new one is not finite), σ kept if finite and
//!   positive (else σ₀); [`Cmaes::recoveries`] counts these. With finite costs, only the
//!   ranking enters the update, so this is a guard, not a path a normal run takes.
//! * **σ limit.** σ is clamped to `max_sigma` after each update (not in the tutorial):
//!   with the box [−1, 1]ⁿ, σ ≫ 1 only puts candidates on the faces.
//! * **Lazy eigendecomposition (optional).** `eigen_interval` = k decomposes C every k
//!   generations; B and D are stale in between for both sampling and C^{−1/2}, as the
//!   tutorial allows (its code uses k ≈ λ/((c₁ + c_μ) n · 10), ≈ 7 for n = 31, λ = 14 —
//!   O(n²) per evaluation). The default is k = 1 (every generation, like the diagnostic):
//!   on a robot a generation is λ episodes, and one decomposition of a 31 × 31 matrix is a
//!   few milliseconds.
//! * **C^{−1/2}⟨y⟩_w** is computed as B⟨z⟩_w from the standard normal draws z of the μ
//!   best samples (as in Hansen's earlier `cmaes.m`), not as B D⁻¹ Bᵀ⟨y⟩_w (the tutorial's
//!   appendix code): equal in exact arithmetic, since B and D are fixed within a generation,
//!   but in f32 the eigenvectors of the thinnest axes carry errors of ≈ 10⁻⁷·λ_max/λ_min,
//!   which D⁻¹ would amplify into p_σ. (The two forms were not compared on their own: the
//!   first comparison was confounded by the box penalty.) The samples keep z, not y:
//!   y = B D z is recomputed for the update.
//! * **Stopping.** [`Status::Converged`] when σ · √λ_max(C) (the largest standard deviation
//!   of the search distribution, normalised units) ≤ `tolerance` after an update;
//!   [`Status::BudgetSpent`] after `max_evaluations` told costs, possibly mid-generation. No
//!   other termination criteria of the tutorial (TolFun, NoEffectAxis, ConditionCov, ...),
//!   no restarts.
//! * **Active weights are optional** (`active`, off by default, so that earlier figures
//!   stay valid; the tutorial's default is on). On a rotated 10-D discus (one axis 100×
//!   thinner) they reach 10⁻⁶ with 56 % of the evaluations (unit test
//!   `active_weights_learn_a_thin_axis_sooner`). On the hopping leg they did not raise the
//!   share of learning runs that reach the paper's apex variation (4 of 16 seeds, against 2
//!   of 8 without).
//! * **Ties** in the ranking rank in the order told.
//! * **Normal draws.** Marsaglia's polar method in f32 ([`normal_pair_f32`](super::normal_pair_f32)), truncated at
//!   radius 7.99.
//!
//! # The eigendecomposition
//! B and D come from cyclic Jacobi rotations of Bᵀ C B, started in the previous basis B
//! (`cmaes/eigen.rs`; Golub and Van Loan, section 8.5), run until every off-diagonal entry
//! is below f32's rounding unit relative to its diagonal. Not the tutorial's choice of
//! method (it calls any symmetric eigensolver), and not nalgebra's QR iteration, which this
//! type used before: nalgebra's `SymmetricEigen` keeps four panic sites in a firmware that
//! the compiler cannot remove, where the Jacobi rotations have none, so `Cmaes` is in the
//! panic-freedom proof (`scripts/panic-check`) with every other optimizer. The price: at
//! n = 18, λ = 12 on a Cortex-M4F the generation's last `tell` (update, a Gram–Schmidt
//! pass that keeps B orthonormal from one warm start to the next, and two to three sweeps of
//! 153 rotations) takes a median 394k instructions, against about 310k with nalgebra's; an
//! ask + tell 43k on average, against 35k (`bash scripts/footprint`).
//!
//! # Sizes
//! About 4·(2N² + (L + 12)·N + 3L) bytes: C and B (N × N each), room for the L draws of a
//! generation (μ of them used without `active`), the paths, mean, scales, box and weights:
//! `size_of` is 11 088 B for `Cmaes<31, 14>` and 4 352 B for `Cmaes<18, 10>` (`cargo bench
//! -p experiments --bench cmaes`; the active weights add 64 and 40 B).

use heapless::Vec;
use nalgebra::allocator::Allocator;
use nalgebra::{
    ArrayStorage, Const, DefaultAllocator, DimDiff, DimSub, SMatrix, SymmetricEigen, U1,
};
use rand_core::RngCore;

use super::{Draw, Generation, Ledger, Optimizer, Status, keep_ranked};
use super::{check_sigmas, check_stopping, default_is_const, ledger_accessors, require};
use crate::bounds::UnitMap;
use crate::random::normal_vector_f32;
use crate::vector::{identity, times};
use crate::{Bounds, Error, Vector};

mod eigen;

/// Eigenvalues of C are floored at this fraction of the largest.
const EIGEN_FLOOR: f32 = 1e-14;

/// The tutorial's default population size 4 + ⌊3 ln n⌋ for n parameters (n ≥ 1): 7 for
/// n = 3, 10 for n = 10, 12 for n = 18, 14 for n = 31. Use it to pick `L`.
///
/// ```
/// assert_eq!(ctrl_adapt::optimizer::cmaes::default_population(31), 14);
/// ```
pub fn default_population(n: usize) -> usize {
    4 + libm::floorf(3.0 * libm::logf(n.max(1) as f32)) as usize
}

/// Formerly a bound on [`Cmaes`]'s impls: the sizes N for which nalgebra's
/// [`SymmetricEigen`] runs on an N × N `f32` matrix
/// (1 ≤ N ≤ 127: nalgebra needs `Const<N>: DimSub<U1>`, which it implements through typenum
/// up to 127). Implemented for every such `Const<N>`; a bound on [`Cmaes`]'s impls.
///
/// Written as a trait of its own because a `where DefaultAllocator: Allocator<…>` bound
/// directly on `Cmaes`'s impls would stop the compiler from resolving nalgebra's storage of
/// the other static matrices there.
#[deprecated(
    since = "0.2.0",
    note = "`Cmaes` decomposes by Jacobi rotations of its own and needs no bound on N"
)]
pub trait SymmetricEigenSize<const N: usize> {
    /// (B, λ): the eigenvectors (columns) and eigenvalues of the symmetric `m` (lower
    /// triangle read), or `None` when the QR iteration needs more than `max_iterations`.
    fn symmetric_eigen(
        m: SMatrix<f32, N, N>,
        max_iterations: usize,
    ) -> Option<(SMatrix<f32, N, N>, Vector<N>)>;
}

#[allow(deprecated)]
impl<const N: usize> SymmetricEigenSize<N> for Const<N>
where
    Const<N>: DimSub<U1>,
    DefaultAllocator: Allocator<DimDiff<Const<N>, U1>>,
{
    fn symmetric_eigen(
        m: SMatrix<f32, N, N>,
        max_iterations: usize,
    ) -> Option<(SMatrix<f32, N, N>, Vector<N>)> {
        let eig = SymmetricEigen::try_new(m, f32::EPSILON, max_iterations)?;
        // Copied out element-wise: under this impl's bounds the compiler does not see that
        // nalgebra's results are `ArrayStorage`-backed.
        let mut vectors = [[0.0f32; N]; N];
        let mut values = [[0.0f32; N]; 1];
        for (j, column) in vectors.iter_mut().enumerate() {
            for (i, v) in column.iter_mut().enumerate() {
                *v = eig.eigenvectors.get((i, j)).copied().unwrap_or(f32::NAN);
            }
            values[0][j] = eig.eigenvalues.get(j).copied().unwrap_or(f32::NAN);
        }
        Some((
            SMatrix::from_array_storage(ArrayStorage(vectors)),
            Vector::from_array_storage(ArrayStorage(values)),
        ))
    }
}

/// Parameters of [`Cmaes`]. Plain fields, checked by [`CmaesConfig::validate`] (and by
/// [`Cmaes::try_new`]). Lengths are in normalised units: 1 is the box's half-width.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CmaesConfig {
    /// σ₀ > 0: the initial step size relative to the box's half-width, ≤ `max_sigma`.
    pub initial_sigma: f32,
    /// The largest σ (finite, > 0).
    pub max_sigma: f32,
    /// Weight (≥ 0, finite) of the squared distance of a sample to the box added to its
    /// cost for the ranking. Set it comparable to the cost differences that matter: a
    /// sample one box-width outside then ranks like a clearly worse point.
    pub penalty: f32,
    /// Generations between eigendecompositions of C (≥ 1).
    pub eigen_interval: u32,
    /// The search has converged when σ·√λ_max(C) ≤ this (≥ 0) after an update.
    pub tolerance: f32,
    /// Evaluations (episodes) allowed, ≥ 1.
    pub max_evaluations: u32,
    /// Active CMA-ES: the λ − μ worst samples of a generation enter the covariance update
    /// with negative weights, shrinking C along the directions that did badly (the
    /// tutorial's default since 2016; Jastrebski and Arnold 2006). Off in
    /// [`CmaesConfig::DEFAULT`], so that the figures measured before it existed stay valid.
    /// When on, the search keeps all λ draws of a generation instead of the μ best (the
    /// room is there either way: the size does not change).
    pub active: bool,
}

impl CmaesConfig {
    /// σ₀ = 0.3 (the tutorial suggests a fifth to a third of the search range), σ ≤ 10,
    /// penalty 1, a decomposition every generation, tolerance 10⁻⁶ (a few f32 ulps at 1),
    /// no budget limit, positive weights only (`active` off).
    pub const DEFAULT: Self = Self {
        initial_sigma: 0.3,
        max_sigma: 10.0,
        penalty: 1.0,
        eigen_interval: 1,
        tolerance: 1e-6,
        max_evaluations: u32::MAX,
        active: false,
    };

    /// `Ok` when every parameter is in its range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        check_sigmas(self.initial_sigma, self.max_sigma)?;
        require(non_negative(self.penalty), "penalty")?;
        require(self.eigen_interval != 0, "eigen_interval")?;
        check_stopping(Some(self.tolerance), self.max_evaluations)
    }
}

default_is_const!(CmaesConfig);

/// The strategy parameters of the tutorial's table 1 for n = N, λ = L.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Constants<const L: usize> {
    /// w_1..w_μ (normalised), 0 beyond μ.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    weights: [f32; L],
    /// The active update's weights w_{μ+1}..w_λ (≤ 0), 0 up to μ.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    negative: [f32; L],
    mu: usize,
    mu_eff: f32,
    c_sigma: f32,
    d_sigma: f32,
    c_c: f32,
    c_1: f32,
    c_mu: f32,
    /// E‖N(0, I)‖.
    chi_n: f32,
}

impl<const L: usize> Constants<L> {
    fn new(n: usize) -> Self {
        let n = n as f32;
        let mu = L / 2;
        let mut weights = [0.0f32; L];
        let top = libm::logf((L as f32 + 1.0) / 2.0);
        for (i, w) in weights.iter_mut().take(mu).enumerate() {
            // ln((λ + 1)/2) − ln i > 0 for i ≤ ⌊λ/2⌋.
            *w = top - libm::logf((i + 1) as f32);
        }
        let sum: f32 = weights.iter().sum();
        // sum ≥ w_1 = ln((λ + 1)/2) ≥ ln 1.5 > 0 (λ ≥ 2).
        for w in weights.iter_mut() {
            *w /= sum;
        }
        let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f32>();
        let c_sigma = (mu_eff + 2.0) / (n + mu_eff + 5.0);
        let d_sigma =
            1.0 + 2.0 * (libm::sqrtf((mu_eff - 1.0) / (n + 1.0)) - 1.0).max(0.0) + c_sigma;
        let c_c = (4.0 + mu_eff / n) / (n + 4.0 + 2.0 * mu_eff / n);
        let c_1 = 2.0 / ((n + 1.3) * (n + 1.3) + mu_eff);
        let c_mu =
            (2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((n + 2.0) * (n + 2.0) + mu_eff)).min(1.0 - c_1);
        let chi_n = libm::sqrtf(n) * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n * n));
        // The tutorial's negative weights: w'_i = ln((λ + 1)/2) − ln i ≤ 0 for i > μ, scaled
        // to sum to −min(α_μ⁻, α_μeff⁻, α_posdef⁻) (its eq. 50–53).
        let mut negative = [0.0f32; L];
        for (i, w) in negative.iter_mut().enumerate().skip(mu) {
            *w = top - libm::logf((i + 1) as f32);
        }
        let neg_sum: f32 = negative.iter().map(|w| -w).sum();
        let neg_sq: f32 = negative.iter().map(|w| w * w).sum();
        if neg_sum > 0.0 && c_mu > 0.0 {
            let mu_eff_neg = neg_sum * neg_sum / neg_sq;
            let alpha = (1.0 + c_1 / c_mu)
                .min(1.0 + 2.0 * mu_eff_neg / (mu_eff + 2.0))
                .min((1.0 - c_1 - c_mu) / (n * c_mu));
            for w in negative.iter_mut() {
                *w *= alpha / neg_sum;
            }
        } else {
            // c_μ = 0 (λ = 2 for small n) or nothing to weigh: no active update.
            negative = [0.0; L];
        }
        Self {
            weights,
            negative,
            mu,
            mu_eff,
            c_sigma,
            d_sigma,
            c_c,
            c_1,
            c_mu,
            chi_n,
        }
    }
}

/// A ranked sample of the current generation: its penalised cost and its standard normal
/// draw z (the step is y = (x − m)/σ = B D z).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Sample<const N: usize> {
    rank_cost: f32,
    z: Vector<N>,
}

/// The (μ/μ_w, λ)-CMA-ES over a box, λ = `L` samples per generation, as a resumable
/// ask/tell state machine (see the [module docs](self) for the algorithm and its
/// deviations). `O(N²)` work per `ask` (N normal draws and B·D·z), `O(μ)` per `tell`, and
/// `O(μN² + N³)` for the update and eigendecomposition after each λ-th `tell`; about
/// `8·N²` bytes of state (C and B).
///
/// `L` ≥ 2 (checked at compile time); the tutorial's default is [`default_population`]`(N)`.
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, Cmaes, CmaesConfig, Optimizer, Status};
/// use rand_core::SeedableRng;
///
/// let bounds = Bounds::<4>::uniform(-2.0, 2.0)?;
/// let config = CmaesConfig { initial_sigma: 0.3, tolerance: 1e-5, ..CmaesConfig::DEFAULT };
/// // λ = 8 = 4 + ⌊3 ln 4⌋ samples per generation.
/// let mut cma = Cmaes::<4, 8>::try_new(bounds, [1.0; 4].into(), config)?;
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(3);
/// while cma.status() == Status::Running {
///     let theta = cma.ask(&mut rng)?;
///     // A rotated, badly scaled quadratic: (θ₀ + θ₁ − 0.6)² + 100 (θ₀ − θ₁)² + ...
///     let (a, b) = (theta[0] + theta[1] - 0.6, theta[0] - theta[1]);
///     cma.tell(a * a + 100.0 * b * b + theta[2] * theta[2] + theta[3] * theta[3])?;
/// }
/// assert_eq!(cma.status(), Status::Converged);
/// assert!(cma.best().unwrap().cost < 1e-8);
/// assert!((cma.mean()[0] - 0.3).abs() < 1e-4);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
///
/// Under [`InFlight`](super::InFlight) a whole generation of λ = L can be in flight (its
/// samples do not depend on the generation's costs), with the sequential run's results.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Cmaes<const N: usize, const L: usize> {
    config: CmaesConfig,
    constants: Constants<L>,
    /// The box and its map to [−1, 1]ⁿ: θ = centre + half-width ∘ x.
    unit: UnitMap<N>,
    /// m, normalised (may lie outside [−1, 1]ⁿ).
    mean: Vector<N>,
    sigma: f32,
    /// C, normalised.
    covariance: SMatrix<f32, N, N>,
    /// B: eigenvectors of C (columns), from the last decomposition.
    basis: SMatrix<f32, N, N>,
    /// D: square roots of the (floored) eigenvalues of C, from the last decomposition.
    scales: Vector<N>,
    p_sigma: Vector<N>,
    p_c: Vector<N>,
    /// The pending candidate's draw z and its squared distance to the box.
    drawn: Vector<N>,
    drawn_excess: f32,
    /// The μ best samples of the current generation (all of them when `active`), by
    /// penalised cost.
    elite: Vec<Sample<N>, L>,
    /// Costs told in the current generation (0..L).
    told: usize,
    generations: u32,
    /// Generations since p_σ was last zero (for h_σ's correction factor).
    path_generations: u32,
    recoveries: u32,
    ledger: Ledger<N>,
}

impl<const N: usize, const L: usize> Cmaes<N, L> {
    /// A search around `mean` (finite and inside `bounds`) with C = I and
    /// σ = `config.initial_sigma` (relative to each half-width of the box).
    pub fn try_new(bounds: Bounds<N>, mean: Vector<N>, config: CmaesConfig) -> Result<Self, Error> {
        const {
            assert!(L >= 2, "a generation needs at least two samples to rank");
        }
        config.validate()?;
        bounds.check(&mean, "mean")?;
        let unit = UnitMap::new(bounds);
        let normalised = unit.unit_of(&mean);
        Ok(Self {
            config,
            constants: Constants::new(N),
            unit,
            mean: normalised.map(|v| v.clamp(-1.0, 1.0)),
            sigma: config.initial_sigma,
            // Constants, copied straight into place: `SMatrix::identity()` would assemble
            // each matrix on the stack first (1.3 KB at N = 18) and then move it in.
            covariance: const { identity::<N>() },
            basis: const { identity::<N>() },
            scales: Vector::repeat(1.0),
            p_sigma: Vector::zeros(),
            p_c: Vector::zeros(),
            drawn: Vector::zeros(),
            drawn_excess: 0.0,
            elite: Vec::new(),
            told: 0,
            generations: 0,
            path_generations: 0,
            recoveries: 0,
            ledger: Ledger::new(config.max_evaluations),
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &CmaesConfig {
        &self.config
    }

    /// The mean of the search distribution in parameter units, projected onto the box (the
    /// policy the search currently believes in).
    pub fn mean(&self) -> Vector<N> {
        self.unit.theta_of(&self.mean.map(|v| v.clamp(-1.0, 1.0)))
    }

    /// The mean in normalised units (x = (θ − centre)/half-width), not projected.
    pub fn normalised_mean(&self) -> &Vector<N> {
        &self.mean
    }

    /// σ: the step size, relative to the box's half-widths.
    pub fn sigma(&self) -> f32 {
        self.sigma
    }

    /// C in normalised units.
    pub fn covariance(&self) -> &SMatrix<f32, N, N> {
        &self.covariance
    }

    /// √(λ_max/λ_min) of C at the last decomposition (the search distribution's axis ratio).
    pub fn axis_ratio(&self) -> f32 {
        self.scales.max() / self.scales.min()
    }

    /// μ = ⌊L/2⌋, the number of samples per generation that enter the update.
    pub fn parents(&self) -> usize {
        self.constants.mu
    }

    /// Completed generations (updates).
    pub fn generations(&self) -> u32 {
        self.generations
    }

    /// Costs told in the current, incomplete generation (0..L).
    pub fn told_in_generation(&self) -> usize {
        self.told
    }

    /// How many times a non-finite state was reset (see the module docs); 0 in a normal run.
    pub fn recoveries(&self) -> u32 {
        self.recoveries
    }

    /// y = B D z.
    fn step_of(&self, z: &Vector<N>) -> Vector<N> {
        self.times_basis(&self.scales.component_mul(z))
    }

    /// B v, without copying B ([`times`]).
    fn times_basis(&self, v: &Vector<N>) -> Vector<N> {
        times(&self.basis, v)
    }

    /// x = m + σ B D z projected onto the unit box, as θ, with z and the excess ‖x − x̂‖²
    /// that `tell` needs. Nothing in it depends on the costs of the generation.
    fn draw_candidate<R: RngCore + ?Sized>(&self, rng: &mut R) -> Draw<N> {
        let z = normal_vector_f32(rng);
        let x = self.mean + self.step_of(&z) * self.sigma;
        // A NaN coordinate projects to −1 and its excess is NaN, ranked as +∞ in `tell`.
        let projected = x.map(|v| if v.is_nan() { -1.0 } else { v.clamp(-1.0, 1.0) });
        Draw {
            theta: self.unit.bounds.clamp(&self.unit.theta_of(&projected)),
            aux: z,
            excess: (x - projected).norm_squared(),
        }
    }

    /// Keeps `sample` if it is among the μ best of the generation so far (all L with
    /// active weights).
    fn keep(&mut self, sample: Sample<N>) {
        let room = if self.config.active {
            L
        } else {
            self.constants.mu
        };
        keep_ranked(&mut self.elite, room, sample, |s| s.rank_cost);
    }

    /// Steps 2–6 of the module docs on the kept samples, then starts the next generation.
    fn update(&mut self) {
        let k = self.constants;
        let mut z_mean = Vector::<N>::zeros();
        for (s, w) in self.elite.iter().zip(k.weights.iter()).take(k.mu) {
            z_mean += s.z * *w;
        }
        // ⟨y⟩_w = B D ⟨z⟩_w (B and D are those the generation was drawn with).
        let step = self.step_of(&z_mean);
        let old_mean = self.mean;
        let mean = self.mean + step * self.sigma;

        // C^{−1/2} ⟨y⟩_w = B D⁻¹ Bᵀ B D ⟨z⟩_w = B ⟨z⟩_w (module docs, deviations).
        let white = self.times_basis(&z_mean);
        let p_sigma = self.p_sigma * (1.0 - k.c_sigma)
            + white * libm::sqrtf(k.c_sigma * (2.0 - k.c_sigma) * k.mu_eff);
        let path_generations = self.path_generations.saturating_add(1);
        let norm = p_sigma.norm();
        let decay = libm::powf(1.0 - k.c_sigma, 2.0 * path_generations as f32);
        let threshold = (1.4 + 2.0 / (N as f32 + 1.0)) * k.chi_n * libm::sqrtf(1.0 - decay);
        let h_sigma = if norm < threshold { 1.0 } else { 0.0 };
        let p_c = self.p_c * (1.0 - k.c_c)
            + step * (h_sigma * libm::sqrtf(k.c_c * (2.0 - k.c_c) * k.mu_eff));

        let delta = (1.0 - h_sigma) * k.c_c * (2.0 - k.c_c);
        // C is updated in place: a copy of it, and nalgebra's temporaries for the scaled and
        // the transposed matrix, would be 1.3 KB of stack each at N = 18. Nothing is lost if
        // the update turns out non-finite: `recover` below resets C to the identity then.
        //
        // Active CMA-ES (ranks μ+1..λ with w_i° = w_i n/‖C^{−1/2} y_i‖², where
        // ‖C^{−1/2} y‖ = ‖B z‖ = ‖z‖): the decay factor of C is 1 + c₁δ − c₁ − c_μ Σ_j w_j
        // over all λ weights; the positive ones sum to 1, the negative ones add the rest.
        let negative_total: f32 = if self.config.active {
            k.negative
                .iter()
                .skip(k.mu)
                .take(self.elite.len().saturating_sub(k.mu))
                .sum()
        } else {
            0.0
        };
        self.covariance *= 1.0 - k.c_1 - k.c_mu + k.c_1 * delta - k.c_mu * negative_total;
        self.covariance.ger(k.c_1, &p_c, &p_c, 1.0);
        for (s, w) in self.elite.iter().zip(k.weights.iter()).take(k.mu) {
            let y = self.step_of(&s.z);
            self.covariance.ger(k.c_mu * *w, &y, &y, 1.0);
        }
        if self.config.active {
            for (s, w) in self.elite.iter().zip(k.negative.iter()).skip(k.mu) {
                let zz = s.z.norm_squared();
                if zz > 0.0 {
                    let y = self.step_of(&s.z);
                    self.covariance
                        .ger(k.c_mu * *w * N as f32 / zz, &y, &y, 1.0);
                }
            }
        }
        // Rounding makes C slightly asymmetric: average each pair of mirrored entries.
        for j in 0..N {
            for i in 0..j {
                let (Some(&upper), Some(&lower)) =
                    (self.covariance.get((i, j)), self.covariance.get((j, i)))
                else {
                    continue;
                };
                let mean = (upper + lower) * 0.5;
                if let Some(x) = self.covariance.get_mut((i, j)) {
                    *x = mean;
                }
                if let Some(x) = self.covariance.get_mut((j, i)) {
                    *x = mean;
                }
            }
        }
        let sigma = (self.sigma * libm::expf((k.c_sigma / k.d_sigma) * (norm / k.chi_n - 1.0)))
            .min(self.config.max_sigma);

        self.generations = self.generations.saturating_add(1);
        self.elite.clear();
        self.told = 0;

        let finite = |v: &Vector<N>| v.iter().all(|x| x.is_finite());
        if finite(&mean)
            && finite(&p_sigma)
            && finite(&p_c)
            && self.covariance.iter().all(|x| x.is_finite())
            && sigma.is_finite()
        {
            self.mean = mean;
            self.p_sigma = p_sigma;
            self.p_c = p_c;
            self.sigma = sigma;
            self.path_generations = path_generations;
            if self.generations.is_multiple_of(self.config.eigen_interval) && !self.decompose() {
                self.recover(old_mean);
            }
        } else {
            self.mean = mean;
            self.sigma = sigma;
            self.recover(old_mean);
        }
        if self.sigma * self.scales.max() <= self.config.tolerance {
            self.ledger.stop(Status::Converged);
        }
    }

    /// B, D ← eig(C) with the floor of the module docs; `false` (nothing changed) when C's
    /// largest eigenvalue is not positive and finite or the decomposition fails.
    fn decompose(&mut self) -> bool {
        // B is rotated in place: on failure the caller resets it with `recover`.
        let Some(values) = eigen::symmetric_eigen(&self.covariance, &mut self.basis) else {
            return false;
        };
        let largest = values.max();
        if !(largest.is_finite() && largest > 0.0) {
            return false;
        }
        let floor = (largest * EIGEN_FLOOR).max(f32::MIN_POSITIVE);
        self.scales = values.map(|e| libm::sqrtf(e.max(floor)));
        true
    }

    /// Resets the shape of the search distribution (module docs, "Recovery").
    fn recover(&mut self, old_mean: Vector<N>) {
        if self.mean.iter().any(|v| !v.is_finite()) {
            self.mean = old_mean;
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            self.sigma = self.config.initial_sigma;
        }
        // In place: `= SMatrix::identity()` builds each matrix on the stack first.
        self.covariance.fill_with_identity();
        self.basis.fill_with_identity();
        self.scales = Vector::repeat(1.0);
        self.p_sigma = Vector::zeros();
        self.p_c = Vector::zeros();
        self.path_generations = 0;
        self.recoveries = self.recoveries.saturating_add(1);
    }
}

#[cfg(feature = "serde")]
impl<const N: usize, const L: usize> Cmaes<N, L> {
    /// The checks of a decoded search ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (configuration, box, the strategy constants and the unit map that
    /// follow from them) and the distribution's: a finite mean, σ finite in (0, max_sigma],
    /// C, B, the paths and the pending draw finite, D finite and positive, the draw's excess
    /// not negative, fewer than λ costs told, and as many kept samples as told (up to μ, or
    /// λ when active), none with a finite-less z or a NaN rank.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::require_finite;
        self.config.validate()?;
        let bounds = &self.unit.bounds;
        bounds.check_decoded()?;
        require(self.unit == UnitMap::new(*bounds), "unit")?;
        require(self.constants == Constants::new(N), "constants")?;
        require_finite(&self.mean, "mean")?;
        require(
            self.sigma.is_finite() && self.sigma > 0.0 && self.sigma <= self.config.max_sigma,
            "sigma",
        )?;
        require_finite(self.covariance.iter(), "covariance")?;
        require_finite(self.basis.iter(), "basis")?;
        require_finite(&self.scales, "scales")?;
        require(self.scales.iter().all(|d| *d > 0.0), "scales")?;
        require_finite(&self.p_sigma, "p_sigma")?;
        require_finite(&self.p_c, "p_c")?;
        require_finite(&self.drawn, "drawn")?;
        // NaN is a draw's excess too (a NaN coordinate), ranked as +∞ when told.
        let excess = self.drawn_excess;
        require(excess >= 0.0 || excess.is_nan(), "drawn_excess")?;
        require(self.told < L, "told")?;
        let room = if self.config.active {
            L
        } else {
            self.constants.mu
        };
        require(self.elite.len() == self.told.min(room), "elite")?;
        for sample in &self.elite {
            require_finite(&sample.z, "elite")?;
            require(!sample.rank_cost.is_nan(), "elite")?;
        }
        self.ledger.check_decoded(bounds)
    }
}

impl<const N: usize, const L: usize> Optimizer<N> for Cmaes<N, L> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if let Some(pending) = self.ledger.reissue()? {
            return Ok(pending);
        }
        let draw = self.draw_candidate(rng);
        self.resume(&draw);
        Ok(draw.theta)
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        self.ledger.accept(cost)?;
        let excess = self.drawn_excess;
        // cost is finite; the penalty term is ≥ 0 or +∞ (0 · ∞ and NaN excesses are +∞).
        let penalty = if excess == 0.0 {
            0.0
        } else {
            self.config.penalty * excess
        };
        let rank_cost = if penalty.is_nan() {
            f32::INFINITY
        } else {
            cost + penalty
        };
        self.keep(Sample {
            rank_cost,
            z: self.drawn,
        });
        self.told += 1;
        if self.told >= L {
            self.update();
        }
        self.ledger.settle();
        Ok(())
    }

    ledger_accessors!(unit.bounds);
}

/// A generation's λ samples are drawn with the same m, σ, B and D whatever the costs told
/// so far, so all of it can be in flight.
impl<const N: usize, const L: usize> Generation<N> for Cmaes<N, L> {
    fn room(&self) -> usize {
        self.ledger.room(L.saturating_sub(self.told))
    }

    fn most(&self) -> usize {
        L
    }

    fn draws_ahead(&self) -> bool {
        true
    }

    fn draw<R: RngCore + ?Sized>(&mut self, _ahead: usize, rng: &mut R) -> Result<Draw<N>, Error> {
        Ok(self.draw_candidate(rng))
    }

    fn resume(&mut self, draw: &Draw<N>) {
        self.drawn = draw.aux;
        self.drawn_excess = draw.excess;
        self.ledger.hand_out(draw.theta, &self.unit.bounds);
    }

    fn check_draw(&self, draw: &Draw<N>) -> Result<(), Error> {
        self.unit.bounds.check(&draw.theta, "in_flight")?;
        require(draw.aux.iter().all(|z| z.is_finite()), "in_flight")?;
        require(draw.excess >= 0.0 || draw.excess.is_nan(), "in_flight")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::{Best, CemConfig, DiagonalCem, Weighting};
    use crate::testing::{
        any_bounds, check_any_costs, check_rejected_calls_change_nothing, check_rejected_configs,
        check_rejected_starts, check_seeded, ellipsoid, evaluations_to_target, rng, rotation,
        tell_inside, with_start,
    };
    use proptest::prelude::*;

    fn config(initial_sigma: f32, max_evaluations: u32) -> CmaesConfig {
        CmaesConfig {
            initial_sigma,
            max_evaluations,
            ..CmaesConfig::DEFAULT
        }
    }

    /// Checks the strategy parameters (with the active weights) against table 1 and
    /// eq. 50–53 of the tutorial computed in f64 for n = 31, λ = 14 (the hopper) and n = 3,
    /// λ = 2 (the smallest population: μ = 1, c_μ = 0, no active weights), and the default
    /// population sizes 4 + ⌊3 ln n⌋.
    #[test]
    fn constants_follow_the_tutorial() {
        fn check<const L: usize>(n: usize) {
            let k = Constants::<L>::new(n);
            let nf = n as f64;
            let mu = L / 2;
            let raw: std::vec::Vec<f64> = (1..=mu)
                .map(|i| ((L as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
                .collect();
            let sum: f64 = raw.iter().sum();
            let w: std::vec::Vec<f64> = raw.iter().map(|r| r / sum).collect();
            let mu_eff = 1.0 / w.iter().map(|w| w * w).sum::<f64>();
            let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
            let d_sigma =
                1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
            let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
            let c_1 = 2.0 / ((nf + 1.3).powi(2) + mu_eff);
            let c_mu = (2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff))
                .min(1.0 - c_1);
            let chi = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
            let close = |a: f32, b: f64| (f64::from(a) - b).abs() <= 1e-6 * b.abs().max(1e-3);
            assert_eq!(k.mu, mu);
            for i in 0..L {
                assert!(
                    close(k.weights[i], w.get(i).copied().unwrap_or(0.0)),
                    "w[{i}]"
                );
            }
            assert!(close(k.mu_eff, mu_eff));
            assert!(close(k.c_sigma, c_sigma));
            assert!(close(k.d_sigma, d_sigma));
            assert!(close(k.c_c, c_c));
            assert!(close(k.c_1, c_1));
            assert!(close(k.c_mu, c_mu), "{} {c_mu}", k.c_mu);
            assert!(close(k.chi_n, chi));
            // The active weights (eq. 50–53), none when c_μ = 0.
            let raw: std::vec::Vec<f64> = (mu + 1..=L)
                .map(|i| ((L as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
                .collect();
            let neg_sum: f64 = raw.iter().map(|r| -r).sum();
            let mu_eff_neg = neg_sum * neg_sum / raw.iter().map(|r| r * r).sum::<f64>();
            let alpha = (1.0 + c_1 / c_mu)
                .min(1.0 + 2.0 * mu_eff_neg / (mu_eff + 2.0))
                .min((1.0 - c_1 - c_mu) / (nf * c_mu));
            for i in 0..L {
                let expected = match i.checked_sub(mu) {
                    Some(j) if c_mu > 0.0 => alpha * raw[j] / neg_sum,
                    _ => 0.0,
                };
                assert!(close(k.negative[i], expected), "negative w[{i}]");
            }
        }
        check::<14>(31);
        check::<2>(3);
        assert_eq!(Constants::<2>::new(3).c_mu, 0.0);
        let defaults: std::vec::Vec<usize> = [1, 2, 3, 10, 18, 31, 100]
            .iter()
            .map(|&n| default_population(n))
            .collect();
        assert_eq!(defaults, [4, 6, 7, 10, 12, 14, 17]);
    }

    /// Replays one generation (N = 4, λ = 8, after a first generation so that C ≠ I and
    /// p_c, p_σ ≠ 0) and checks the update against an f64 transcription of the tutorial's
    /// equations from the drawn z, the told costs and the state before: mean, σ, paths and C
    /// to 1e-5 (relative to their size).
    #[test]
    fn one_generation_matches_the_tutorial() {
        one_generation_as_the_tutorial(false);
    }

    /// As `one_generation_matches_the_tutorial`, with active weights: the negative weights,
    /// their n/‖C^{−1/2} y‖² factors (from an f64 C^{−1/2}, not from the draws z) and the
    /// decay factor of C computed in f64 from the tutorial's equations.
    #[test]
    fn one_active_generation_matches_the_tutorial() {
        one_generation_as_the_tutorial(true);
    }

    fn one_generation_as_the_tutorial(active: bool) {
        type M = nalgebra::SMatrix<f64, 4, 4>;
        type V = nalgebra::SVector<f64, 4>;
        let bounds = Bounds::<4>::uniform(-10.0, 10.0).unwrap();
        let target = Vector::from([3.0, -2.0, 1.0, 0.5]);
        let f = |t: &Vector<4>| (t - target).norm_squared() + 5.0 * (t[0] - t[1]).powi(2);
        let config = CmaesConfig {
            active,
            ..config(0.1, 100)
        };
        let mut cma = Cmaes::<4, 8>::try_new(bounds, Vector::zeros(), config).unwrap();
        let mut r = rng(4);
        for generation in 0..2 {
            let before = cma.clone();
            let k = before.constants;
            let mut told = std::vec::Vec::new();
            for _ in 0..8 {
                let t = cma.ask(&mut r).unwrap();
                told.push((f(&t), cma.drawn));
                cma.tell(f(&t)).unwrap();
            }
            assert_eq!(cma.generations(), generation + 1);
            // Every sample lies well inside the box here: no penalty, ranking by cost.
            told.sort_by(|a, b| a.0.total_cmp(&b.0));
            let b = before.basis.map(f64::from);
            let d = before.scales.map(f64::from);
            let y: std::vec::Vec<V> = told
                .iter()
                .map(|(_, z)| b * d.component_mul(&z.map(f64::from)))
                .collect();
            let w: std::vec::Vec<f64> = k.weights.iter().map(|&w| f64::from(w)).collect();
            let sigma = f64::from(before.sigma);
            let n = 4.0;
            let (cs, cc, c1, cmu, mueff) = (
                f64::from(k.c_sigma),
                f64::from(k.c_c),
                f64::from(k.c_1),
                f64::from(k.c_mu),
                f64::from(k.mu_eff),
            );
            let yw: V = (0..4).map(|i| y[i] * w[i]).sum();
            let mean = before.mean.map(f64::from) + yw * sigma;
            // C^{-1/2} from the f64 decomposition of the f32 C the generation used.
            let c0 = before.covariance.map(f64::from);
            let e = nalgebra::SymmetricEigen::new(c0);
            let inv_sqrt = e.eigenvectors
                * M::from_diagonal(&e.eigenvalues.map(|l| 1.0 / l.sqrt()))
                * e.eigenvectors.transpose();
            let ps = before.p_sigma.map(f64::from) * (1.0 - cs)
                + inv_sqrt * yw * (cs * (2.0 - cs) * mueff).sqrt();
            let g = f64::from(before.path_generations + 1);
            let chi = f64::from(k.chi_n);
            let h =
                ps.norm() / (1.0 - (1.0 - cs).powf(2.0 * g)).sqrt() < (1.4 + 2.0 / (n + 1.0)) * chi;
            let h = if h { 1.0 } else { 0.0 };
            let pc = before.p_c.map(f64::from) * (1.0 - cc)
                + yw * (h * (cc * (2.0 - cc) * mueff).sqrt());
            let mut rank_mu: M = (0..4).map(|i| y[i] * y[i].transpose() * w[i]).sum();
            let mut weight_sum = 1.0;
            if active {
                // Eq. 50–53 of the tutorial for λ = 8, μ = 4, n = 4.
                let raw: std::vec::Vec<f64> =
                    (5..=8).map(|i| (4.5f64).ln() - f64::from(i).ln()).collect();
                let neg_sum: f64 = raw.iter().map(|r| -r).sum();
                let mu_eff_neg = neg_sum * neg_sum / raw.iter().map(|r| r * r).sum::<f64>();
                let alpha = (1.0 + c1 / cmu)
                    .min(1.0 + 2.0 * mu_eff_neg / (mueff + 2.0))
                    .min((1.0 - c1 - cmu) / (n * cmu));
                for (j, r) in raw.iter().enumerate() {
                    let wi = alpha * r / neg_sum;
                    let yi = y[4 + j];
                    let white = (inv_sqrt * yi).norm_squared();
                    rank_mu += yi * yi.transpose() * (wi * n / white);
                    weight_sum += wi;
                }
            }
            let delta = (1.0 - h) * cc * (2.0 - cc);
            let c = c0 * (1.0 - c1 - cmu * weight_sum + c1 * delta)
                + pc * pc.transpose() * c1
                + rank_mu * cmu;
            let new_sigma = sigma * ((cs / f64::from(k.d_sigma)) * (ps.norm() / chi - 1.0)).exp();
            let near = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-5 * scale.max(1e-3);
            for i in 0..4 {
                assert!(
                    near(f64::from(cma.mean[i]), mean[i], mean.amax()),
                    "mean[{i}]"
                );
                assert!(
                    near(f64::from(cma.p_sigma[i]), ps[i], ps.amax()),
                    "p_sigma[{i}]"
                );
                assert!(near(f64::from(cma.p_c[i]), pc[i], pc.amax()), "p_c[{i}]");
                for j in 0..4 {
                    let got = f64::from(cma.covariance[(i, j)]);
                    assert!(
                        near(got, c[(i, j)], c.amax()),
                        "C[{i},{j}] {got} {}",
                        c[(i, j)]
                    );
                }
            }
            assert!(near(f64::from(cma.sigma), new_sigma, new_sigma));
            // B D² Bᵀ reproduces C after the decomposition.
            let bd = cma.basis
                * SMatrix::from_diagonal(&cma.scales.map(|s| s * s))
                * cma.basis.transpose();
            assert!((bd - cma.covariance).amax() < 1e-5 * cma.covariance.amax());
        }
    }

    /// Checks, on the 10-D sphere ‖θ − 0.3‖² in [−1, 1]¹⁰ from 0, σ₀ = 0.3, λ = 10, seeds
    /// 0–5: the best cost falls below 1e-6 within 1200 evaluations and the search then
    /// stops with `Converged` (default tolerance) before 2500, with C still round (axis
    /// ratio < 3) and the mean within 1e-3 of the minimiser.
    #[test]
    fn minimises_the_sphere() {
        let bounds = Bounds::<10>::uniform(-1.0, 1.0).unwrap();
        let sphere = |t: &Vector<10>| (t - Vector::repeat(0.3)).norm_squared();
        for seed in 0..6 {
            let mut cma =
                Cmaes::<10, 10>::try_new(bounds, Vector::zeros(), config(0.3, 2500)).unwrap();
            let hit = evaluations_to_target(&mut cma, sphere, seed, 1e-6);
            assert!(hit.is_some_and(|e| e <= 1200), "seed {seed}: {hit:?}");
            assert_eq!(cma.status(), Status::Converged, "seed {seed}");
            assert!(cma.axis_ratio() < 3.0, "seed {seed}: {}", cma.axis_ratio());
            assert!((cma.mean() - Vector::repeat(0.3)).amax() < 1e-3);
            assert_eq!(cma.recoveries(), 0);
        }
    }

    /// Checks what active weights are for, on the rotated 10-D discus 10⁴ z₁² + Σ_{i>1} z_i²
    /// (z = R(θ − 0.3): one thin axis, not along a coordinate; box [−10, 10]¹⁰, σ₀ = 0.03,
    /// from 0), seeds 0–3: with and without them the best cost falls below 1e-6; with them
    /// it takes fewer evaluations on every seed, and at most 80 % of them in total (they
    /// shrink C along the thin axis from the worst samples too; measured: 56 %).
    #[test]
    fn active_weights_learn_a_thin_axis_sooner() {
        let bounds = Bounds::<10>::uniform(-10.0, 10.0).unwrap();
        let r = rotation();
        let discus = |t: &Vector<10>| {
            let z = r * (t - Vector::repeat(0.3));
            1e4 * z[0] * z[0] + z.rows(1, 9).norm_squared()
        };
        let (mut passive_total, mut active_total) = (0, 0);
        for seed in 0..4 {
            let mut hits = [0; 2];
            for (hit, active) in hits.iter_mut().zip([false, true]) {
                let config = CmaesConfig {
                    active,
                    tolerance: 0.0,
                    ..config(0.03, 10_000)
                };
                let mut cma = Cmaes::<10, 10>::try_new(bounds, Vector::zeros(), config).unwrap();
                let found = evaluations_to_target(&mut cma, discus, seed, 1e-6);
                *hit = found.unwrap_or_else(|| panic!("seed {seed}, active {active}: not found"));
                assert_eq!(cma.recoveries(), 0);
            }
            assert!(hits[1] < hits[0], "seed {seed}: {hits:?}");
            passive_total += hits[0];
            active_total += hits[1];
        }
        std::println!(
            "rotated discus, evaluations to 1e-6 over 4 seeds: \
             {passive_total} passive, {active_total} active"
        );
        assert!(
            active_total * 5 <= passive_total * 4,
            "{active_total} against {passive_total}"
        );
    }

    /// Checks, on the rotated 10-D ellipsoid of condition 10⁶ in a wide box ([−10, 10]¹⁰,
    /// σ₀ = 0.03, i.e. 0.3 in parameter units, from 0), seeds 0–5: CMA-ES gets the best cost
    /// below 1e-6 within 7000 evaluations, having learned the shape (axis ratio > 300 of the
    /// ideal 1000); the diagonal CEM with the same population, CMA-ES weights and initial
    /// σ, on the same budget, stays above 1 on every seed (its axis-aligned Gaussian cannot
    /// follow the rotated valley).
    #[test]
    fn learns_a_rotated_ill_conditioned_ellipsoid() {
        let bounds = Bounds::<10>::uniform(-10.0, 10.0).unwrap();
        for seed in 0..6 {
            let mut cma =
                Cmaes::<10, 10>::try_new(bounds, Vector::zeros(), config(0.03, 7000)).unwrap();
            let hit = evaluations_to_target(&mut cma, ellipsoid(1e6), seed, 1e-6);
            assert!(hit.is_some(), "seed {seed}: best {:?}", cma.best());
            assert!(
                cma.axis_ratio() > 300.0,
                "seed {seed}: {}",
                cma.axis_ratio()
            );

            let cem_config = CemConfig {
                weighting: Weighting::CmaEs,
                initial_variance: 0.09,
                exploration_floor: 1e-10,
                first_is_mean: false,
                max_evaluations: 7000,
                ..CemConfig::DEFAULT
            };
            let mut cem =
                DiagonalCem::<10, 10, 5>::try_new(bounds, Vector::zeros(), cem_config).unwrap();
            evaluations_to_target(&mut cem, ellipsoid(1e6), seed, 1e-6);
            let best = cem.best().unwrap().cost;
            assert!(best > 1.0, "seed {seed}: diagonal CEM {best}");
        }
    }

    /// Checks: `tell` without a pending candidate, and NaN or infinite costs, are errors that
    /// leave the whole state unchanged (the candidate stays pending and is told afterwards),
    /// at every point of two generations; a repeated `ask` returns the pending candidate.
    #[test]
    fn rejected_calls_change_nothing() {
        let bounds = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let mut cma = Cmaes::<3, 4>::try_new(bounds, Vector::zeros(), config(0.5, 100)).unwrap();
        check_rejected_calls_change_nothing(&mut cma, 8);
        assert_eq!((cma.evaluations(), cma.generations()), (8, 2));
    }

    /// Checks: with the mean in a corner of a box of unequal sides and σ₀ = 3 (three
    /// half-widths), every candidate lies inside the box and most coordinates sit on a face
    /// (projections); the penalty pulls the mean back inside, and the best is a projected
    /// point with its told (unpenalised) cost.
    #[test]
    fn candidates_are_projections_inside_the_box() {
        let bounds =
            Bounds::<3>::try_new([0.0, -5.0, 10.0].into(), [1.0, 5.0, 10.5].into()).unwrap();
        let cfg = CmaesConfig {
            penalty: 1.0,
            ..config(3.0, 400)
        };
        let mut cma = Cmaes::<3, 7>::try_new(bounds, [0.0, -5.0, 10.0].into(), cfg).unwrap();
        let mut r = rng(8);
        let mut on_face = 0;
        let mut first = std::vec::Vec::new();
        while let Ok(t) = cma.ask(&mut r) {
            assert!(bounds.contains(&t), "{t:?}");
            if cma.evaluations() < 70 {
                on_face += (0..3)
                    .filter(|&i| t[i] == bounds.lower()[i] || t[i] == bounds.upper()[i])
                    .count();
            }
            let cost = (t - Vector::from([0.5, 0.0, 10.25])).norm_squared();
            first.push((t, cost));
            cma.tell(cost).unwrap();
        }
        assert!(on_face > 105, "{on_face} of 210 coordinates on a face");
        assert!(
            cma.normalised_mean().amax() < 1.0,
            "{:?}",
            cma.normalised_mean()
        );
        let best = first.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        assert_eq!(
            cma.best(),
            Some(Best {
                theta: best.0,
                cost: best.1
            })
        );
    }

    /// Checks: a non-finite covariance (injected: f32 overflow that a normal run does not
    /// reach) is detected at the end of the generation and reset to the identity with zero
    /// paths; the search goes on, its candidates finite and inside the box, and still
    /// minimises the sphere.
    #[test]
    fn recovers_from_a_non_finite_covariance() {
        let bounds = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let mut cma = Cmaes::<4, 8>::try_new(bounds, Vector::zeros(), config(0.2, 3000)).unwrap();
        let mut r = rng(9);
        let sphere = |t: &Vector<4>| (t - Vector::repeat(-0.4)).norm_squared();
        tell_inside(&mut cma, &bounds, &mut r, sphere, Some(16));
        cma.covariance[(1, 2)] = f32::INFINITY;
        cma.covariance[(0, 0)] = f32::NAN;
        tell_inside(&mut cma, &bounds, &mut r, sphere, Some(8));
        assert_eq!(cma.recoveries(), 1);
        assert_eq!(cma.covariance(), &SMatrix::<f32, 4, 4>::identity());
        assert_eq!((cma.p_sigma, cma.p_c), (Vector::zeros(), Vector::zeros()));
        tell_inside(&mut cma, &bounds, &mut r, sphere, None);
        assert_eq!(cma.recoveries(), 1);
        assert!(cma.best().unwrap().cost < 1e-8);
    }

    /// Checks: with a lazy eigendecomposition (every 5 generations) the sphere is still
    /// minimised, and B, D change only at generations that are multiples of 5.
    #[test]
    fn lazy_eigendecomposition() {
        let bounds = Bounds::<10>::uniform(-1.0, 1.0).unwrap();
        let cfg = CmaesConfig {
            eigen_interval: 5,
            ..config(0.3, 2500)
        };
        let mut cma = Cmaes::<10, 10>::try_new(bounds, Vector::zeros(), cfg).unwrap();
        let mut r = rng(1);
        let mut basis = cma.basis;
        while let Ok(t) = cma.ask(&mut r) {
            cma.tell((t - Vector::repeat(0.3)).norm_squared()).unwrap();
            if cma.told_in_generation() == 0 {
                assert_eq!(cma.basis != basis, cma.generations().is_multiple_of(5));
                basis = cma.basis;
            }
        }
        assert!(cma.best().unwrap().cost < 1e-6);
    }

    /// Checks: the search stops with `Converged` once σ·√λ_max ≤ tolerance (then `ask` is
    /// `Stopped`), and with `BudgetSpent` mid-generation when the budget runs out first; the
    /// best stays available.
    #[test]
    fn stops_on_tolerance_and_budget() {
        let bounds = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let cfg = CmaesConfig {
            tolerance: 1e-3,
            ..config(0.3, 10_000)
        };
        let mut cma = Cmaes::<2, 6>::try_new(bounds, Vector::repeat(0.5), cfg).unwrap();
        let mut r = rng(6);
        while let Ok(t) = cma.ask(&mut r) {
            cma.tell(t.norm_squared()).unwrap();
        }
        assert_eq!(cma.status(), Status::Converged);
        assert!(cma.sigma() * cma.scales.max() <= 1e-3);
        assert_eq!(cma.told_in_generation(), 0);
        assert_eq!(cma.ask(&mut r), Err(Error::Stopped));

        let mut cma = Cmaes::<2, 6>::try_new(bounds, Vector::zeros(), config(0.3, 9)).unwrap();
        while let Ok(t) = cma.ask(&mut r) {
            cma.tell(t.norm_squared()).unwrap();
        }
        assert_eq!(cma.status(), Status::BudgetSpent);
        assert_eq!((cma.evaluations(), cma.generations()), (9, 1));
        assert_eq!(cma.ask(&mut r), Err(Error::Stopped));
        assert!(cma.best().is_some());
    }

    /// Checks: the same seed gives the same candidates, another seed differs.
    #[test]
    fn identical_seeds_give_identical_runs() {
        let bounds = Bounds::<5>::uniform(-2.0, 2.0).unwrap();
        let cma = Cmaes::<5, 8>::try_new(bounds, Vector::zeros(), config(0.3, 200)).unwrap();
        assert_eq!(check_seeded(&cma, 0.0, |t| t.norm()), 200);
    }

    /// Checks: every invalid configuration field and mean is rejected with the error
    /// naming it.
    #[test]
    fn constructor_names_the_bad_parameter() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let z = Vector::<2>::zeros();
        check_rejected_configs(
            CmaesConfig::DEFAULT,
            |c| Cmaes::<2, 4>::try_new(b, z, c),
            &[
                (|c| c.initial_sigma = 0.0, "initial_sigma"),
                (|c| c.initial_sigma = f32::NAN, "initial_sigma"),
                (|c| c.initial_sigma = 20.0, "initial_sigma"),
                (|c| c.max_sigma = f32::INFINITY, "max_sigma"),
                (|c| c.max_sigma = -1.0, "max_sigma"),
                (|c| c.penalty = -1.0, "penalty"),
                (|c| c.penalty = f32::INFINITY, "penalty"),
                (|c| c.eigen_interval = 0, "eigen_interval"),
                (|c| c.tolerance = -1e-3, "tolerance"),
                (|c| c.max_evaluations = 0, "max_evaluations"),
            ],
        );
        let c = CmaesConfig::DEFAULT;
        check_rejected_starts("mean", |m| Cmaes::<2, 4>::try_new(b, m, c));
    }

    proptest! {
        /// Checks, for random boxes (widths from 1e-2 to 1e30), starts, configurations and
        /// cost sequences (any f32, NaN and infinities included): every candidate is inside
        /// the box; a non-finite cost is an error that leaves the whole state unchanged;
        /// σ stays in (0, max_sigma]; the best cost never increases.
        #[test]
        fn candidates_in_bounds_and_bad_costs_change_nothing(
            (bounds, start) in with_start(any_bounds::<4>(1e-3)),
            sigma in 1e-6f32..5.0,
            penalty in prop_oneof![Just(0.0f32), 1e-6f32..1e6],
            eigen_interval in 1u32..4,
            active in any::<bool>(),
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..120),
        ) {
            let cfg = CmaesConfig {
                initial_sigma: sigma,
                max_sigma: 5.0,
                penalty,
                eigen_interval,
                active,
                ..CmaesConfig::DEFAULT
            };
            let mut s = Cmaes::<4, 5>::try_new(bounds, start, cfg).unwrap();
            check_any_costs(&mut s, &bounds, &costs, 1, |s, _| {
                prop_assert!(s.sigma() > 0.0 && s.sigma() <= 5.0 || s.status() == Status::Converged);
                Ok(())
            })?;
        }
    }
}
