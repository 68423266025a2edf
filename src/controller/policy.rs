//! Linear correction policies: c = clamp(W·φ(state, t)), with W the optimizer's θ.
//!
//! The correction c is added to what the firmware's own controller does: to its output (the
//! AUV of Leonetti et al. 2012, section 5: "the actions are the continuous velocities summed
//! to the controller's one", 18 parameters) or to its reference and gains (the hopping leg
//! of Hwangbo et al., section IV: knee reference, k_p and k_d each on 10 periodic Gaussian
//! kernels, plus the period, 31 parameters).
//!
//! # Layout of θ
//! θ = [W row 0 | W row 1 | … | W row C−1 | learned feature-map parameters], W being C×F
//! row-major: θ[F·a + f] weighs feature f in correction a. A feature map with learned
//! parameters (the period of [`PeriodicRbf`]) takes them from the tail. The length is checked
//! at compile time: P = C·F + [`FeatureMap::LEARNED`].
//!
//! # The envelope
//! Every correction component is clamped to ±envelope\[a\] whatever θ and the state are; a
//! NaN component (from a NaN state) becomes 0, so the correction never leaves the envelope.
//! This is the second layer of the safety envelope, after the parameter box.

use core::f32::consts::TAU;

use super::{Controller, Pd, clamp};
use crate::error::{Error, require};
use crate::vector::{Vector, unrolled};

/// Features φ ∈ R^F of the state and of the time since the episode began.
pub trait FeatureMap<const S: usize, const F: usize> {
    /// How many θ entries (after the weights) the map learns itself.
    const LEARNED: usize = 0;

    /// φ(state, time), given the map's learned parameters (`LEARNED` values).
    fn features(&self, state: &Vector<S>, time: f32, learned: &[f32]) -> Vector<F>;
}

/// φ = state: the state itself as features, with nothing stored and nothing computed per
/// tick (the AUV policy: position error and velocity, 6 features). Use it rather than
/// [`StateFeatures::identity`], which keeps S ones and multiplies every feature by one.
///
/// ```
/// use ctrl_adapt::controller::{FeatureMap, IdentityFeatures};
/// use ctrl_adapt::Vector;
/// let state = Vector::<2>::new(0.5, -1.0);
/// assert_eq!(IdentityFeatures.features(&state, 0.0, &[]), state);
/// assert_eq!(core::mem::size_of::<IdentityFeatures>(), 0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct IdentityFeatures;

impl<const S: usize> FeatureMap<S, S> for IdentityFeatures {
    fn features(&self, state: &Vector<S>, _time: f32, _learned: &[f32]) -> Vector<S> {
        *state
    }
}

/// φ = scale ∘ state: the state-linear features of the AUV policy (position error and
/// velocity, 6 features). `scale` normalises units so one step size suits every weight.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StateFeatures<const S: usize> {
    scale: Vector<S>,
}

impl<const S: usize> StateFeatures<S> {
    /// φ = state.
    pub fn identity() -> Self {
        Self {
            scale: Vector::repeat(1.0),
        }
    }

    /// φ = scale ∘ state; every scale must be finite.
    pub fn scaled(scale: Vector<S>) -> Result<Self, Error> {
        let features = Self { scale };
        features.check_decoded()?;
        Ok(features)
    }

    /// The checks of [`StateFeatures::scaled`], also run on decoded features.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        require(self.scale.iter().all(|s| s.is_finite()), "scale")
    }
}

impl<const S: usize> FeatureMap<S, S> for StateFeatures<S> {
    fn features(&self, state: &Vector<S>, _time: f32, _learned: &[f32]) -> Vector<S> {
        // `component_mul`, unrolled (see `LinearPolicy::correction_from_features`).
        let mut phi = Vector::<S>::zeros();
        unrolled::<S>(|i| phi[i] = self.scale[i] * state[i]);
        phi
    }
}

/// K periodically recurring Gaussian kernels of the phase ϕ = (t / T) mod 1, normalised to
/// sum to 1 (the rhythmic movement primitive of Hwangbo et al., after Ijspeert et al.):
/// ψ_i = exp(h (cos 2π(ϕ − i/K) − 1)), φ_i = ψ_i / Σ_j ψ_j.
///
/// The period is learned: T = clamp(T₀ + θ_last, T_min, T_max) ([`FeatureMap::LEARNED`] = 1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PeriodicRbf<const K: usize> {
    period: f32,
    min_period: f32,
    max_period: f32,
    width: f32,
}

impl<const K: usize> PeriodicRbf<K> {
    /// Kernels with nominal period `period` (s), learned period kept in
    /// `[min_period, max_period]`, and the default width h = (K/π)², for which a kernel's
    /// standard deviation (1/√h rad) is half the spacing between kernels (2π/K rad).
    pub fn try_new(period: f32, min_period: f32, max_period: f32) -> Result<Self, Error> {
        const { assert!(K > 0, "at least one kernel") };
        let k = K as f32 / core::f32::consts::PI;
        let kernels = Self {
            period,
            min_period,
            max_period,
            width: k * k,
        };
        kernels.check_decoded()?;
        Ok(kernels)
    }

    /// Sets the kernel width h (> 0, finite).
    pub fn with_width(mut self, width: f32) -> Result<Self, Error> {
        require(width.is_finite() && width > 0.0, "width")?;
        self.width = width;
        Ok(self)
    }

    /// The checks of [`PeriodicRbf::try_new`] and [`PeriodicRbf::with_width`], also run on
    /// decoded kernels.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        let (period, min_period, max_period) = (self.period, self.min_period, self.max_period);
        require(min_period.is_finite() && min_period > 0.0, "min_period")?;
        require(
            max_period.is_finite() && max_period >= min_period,
            "max_period",
        )?;
        require(period >= min_period && period <= max_period, "period")?;
        require(self.width.is_finite() && self.width > 0.0, "width")
    }

    /// The period T for a learned offset (NaN offsets give the nominal period).
    pub fn period(&self, offset: f32) -> f32 {
        let t = self.period + offset;
        if t.is_nan() {
            self.period
        } else {
            // `f32::clamp` without its panic path (see `controller::clamp`); `try_new`
            // checks min_period ≤ max_period.
            clamp(t, self.min_period, self.max_period)
        }
    }

    /// The normalised features and their time derivatives at `time` for period `period`.
    /// The derivative feeds the reference rate ẋ_d of eq. 6 (derivative on error).
    pub fn features_and_rates(&self, time: f32, period: f32) -> (Vector<K>, Vector<K>) {
        let phase = time / period;
        let phase = phase - libm::floorf(phase);
        let mut psi = Vector::<K>::zeros();
        let mut dpsi = Vector::<K>::zeros();
        for i in 0..K {
            let angle = TAU * (phase - i as f32 / K as f32);
            let p = libm::expf(self.width * (libm::cosf(angle) - 1.0));
            psi[i] = p;
            // dψ/dt = ψ · (−h sin angle) · 2π/T
            dpsi[i] = -p * self.width * libm::sinf(angle) * TAU / period;
        }
        // Σψ ≥ the largest kernel ≥ exp(−h(1 − cos(π/K))) > 0: the nearest centre is at most
        // half a spacing away. Guard anyway against underflow for absurd widths.
        let sum = psi.sum();
        if !(sum.is_finite() && sum >= f32::MIN_POSITIVE) {
            return (Vector::repeat(1.0 / K as f32), Vector::zeros());
        }
        let dsum = dpsi.sum();
        let phi = psi / sum;
        let dphi = (dpsi - phi * dsum) / sum;
        (phi, dphi)
    }
}

impl<const S: usize, const K: usize> FeatureMap<S, K> for PeriodicRbf<K> {
    const LEARNED: usize = 1;

    fn features(&self, _state: &Vector<S>, time: f32, learned: &[f32]) -> Vector<K> {
        let offset = learned.first().copied().unwrap_or(0.0);
        self.features_and_rates(time, self.period(offset)).0
    }
}

/// c = clamp(W·φ): C corrections linear in F features, W taken from θ (layout in the
/// [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LinearPolicy<const C: usize, const F: usize, M> {
    map: M,
    envelope: Vector<C>,
}

impl<const C: usize, const F: usize, M> LinearPolicy<C, F, M> {
    /// A policy over `map` whose correction a stays within ±`envelope[a]` (> 0, finite).
    pub fn try_new(map: M, envelope: Vector<C>) -> Result<Self, Error> {
        check_envelope(&envelope)?;
        Ok(Self { map, envelope })
    }

    /// The feature map.
    pub fn map(&self) -> &M {
        &self.map
    }

    /// The correction envelope.
    pub fn envelope(&self) -> &Vector<C> {
        &self.envelope
    }

    /// The learned feature-map parameters: θ after the C·F weights.
    pub fn learned<const P: usize>(theta: &Vector<P>) -> &[f32] {
        theta.as_slice().get(C * F..).unwrap_or(&[])
    }

    /// clamp(W·φ) for given features (when the caller needs φ itself, as [`PeriodicPd`]).
    pub fn correction_from_features<const P: usize>(
        &self,
        theta: &Vector<P>,
        phi: &Vector<F>,
    ) -> Vector<C> {
        const { assert!(P >= C * F, "θ must hold the C·F weights") };
        let mut c = Vector::<C>::zeros();
        // Straight-line code for the common sizes (see `unrolled`): this runs every control
        // tick, and firmware is built for size, where loops stay rolled.
        unrolled::<C>(|a| {
            // -0.0 is the neutral element of `+` (0.0 is not: 0.0 + -0.0 = 0.0), so the first
            // addition folds away, as in `Iterator::sum`.
            let mut sum = -0.0;
            unrolled::<F>(|f| sum += theta[F * a + f] * phi[f]);
            let limit = self.envelope[a];
            // clamp(sum, −limit, limit), NaN → 0, with one comparison of |sum| on the common
            // path (inside the envelope; the ordered `<=` is false for NaN), and the sign
            // past it.
            c[a] = if sum.abs() <= limit {
                sum
            } else if sum > 0.0 {
                limit
            } else if sum < 0.0 {
                -limit
            } else {
                0.0 // NaN
            };
        });
        c
    }

    /// c = clamp(W·φ(state, time)), within ±envelope for any θ and state.
    pub fn correction<const S: usize, const P: usize>(
        &self,
        theta: &Vector<P>,
        state: &Vector<S>,
        time: f32,
    ) -> Vector<C>
    where
        M: FeatureMap<S, F>,
    {
        const { assert!(P == C * F + M::LEARNED, "θ length must be C·F + learned") };
        let phi = self.map.features(state, time, Self::learned(theta));
        self.correction_from_features(theta, &phi)
    }
}

/// Every bound of the correction envelope finite and > 0.
fn check_envelope<const C: usize>(envelope: &Vector<C>) -> Result<(), Error> {
    require(
        envelope.iter().all(|e| e.is_finite() && *e > 0.0),
        "envelope",
    )
}

#[cfg(feature = "serde")]
impl<const C: usize, const F: usize, M: crate::record::Persistent> LinearPolicy<C, F, M> {
    /// The checks of [`LinearPolicy::try_new`] and of the feature map, also run on a
    /// decoded policy ([`Persistent::validate`](crate::record::Persistent)).
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        check_envelope(&self.envelope)?;
        self.map.validate()
    }
}

/// A PD on A axes whose output is corrected: u = sat(sat(k_p e − k_d ẏ) + c), the AUV policy.
///
/// State layout (S = 2A): [error = setpoint − measurement (A) | measured rate ẏ (A)]; the PD
/// differentiates on measurement (ė = −ẏ). The nominal action is u = sat(k_p e − k_d ẏ).
///
/// The correction is added to the controller's *output*, after the PD's own saturation ("the
/// actions are the continuous velocities summed to the controller's one", Leonetti et al.
/// 2012, section 5), and the sum is saturated to the same limit. Adding c inside the PD's
/// saturation instead would make the correction powerless whenever the PD saturates, which
/// on the AUV is the whole approach to the target (k_p · 5 m ≫ v_max).
///
/// ```
/// use ctrl_adapt::controller::{Controller, CorrectedPd, LinearPolicy, Pd, StateFeatures};
/// use ctrl_adapt::optimizer::Vector;
/// // AUV: 3 velocity commands, corrected linearly in [position error, velocity]: 18 weights.
/// let pd = Pd::<3>::try_new(Vector::repeat(0.3), Vector::repeat(0.1))?
///     .with_limit(Vector::repeat(2.0))?;
/// let policy = LinearPolicy::<3, 6, _>::try_new(StateFeatures::<6>::identity(), Vector::repeat(0.5))?;
/// let mut auv = CorrectedPd::<3, 6, 6, 18, _>::new(pd, policy);
/// let state = Vector::<6>::from([2.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
/// let mut theta = Vector::<18>::zeros();
/// assert_eq!(auv.corrected(&theta, &state, 0.0), auv.nominal(&state, 0.0));
/// theta[2] = 10.0; // correction x grows with the depth error, clamped to 0.5
/// assert!((auv.corrected(&theta, &state, 0.0)[0] - (0.6 + 0.5)).abs() < 1e-6);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CorrectedPd<const A: usize, const S: usize, const F: usize, const P: usize, M> {
    pd: Pd<A>,
    policy: LinearPolicy<A, F, M>,
}

impl<const A: usize, const S: usize, const F: usize, const P: usize, M> CorrectedPd<A, S, F, P, M>
where
    M: FeatureMap<S, F>,
{
    /// The PD `pd` corrected by `policy`; S = 2A and P = A·F + learned, checked at compile
    /// time.
    pub fn new(pd: Pd<A>, policy: LinearPolicy<A, F, M>) -> Self {
        const { assert!(S == 2 * A, "state is [error (A) | rate (A)]") };
        const { assert!(P == A * F + M::LEARNED, "θ length must be A·F + learned") };
        Self { pd, policy }
    }

    /// The PD.
    pub fn pd(&self) -> &Pd<A> {
        &self.pd
    }

    /// The correction policy.
    pub fn policy(&self) -> &LinearPolicy<A, F, M> {
        &self.policy
    }

    /// k_p ∘ e + k_d ∘ ė with e the state's first A entries and ė = −(its last A).
    fn unsaturated(&self, state: &Vector<S>) -> Vector<A> {
        // `pd.raw` of the two halves, without assembling them first.
        let (kp, kd) = (self.pd.kp(), self.pd.kd());
        let mut u = Vector::<A>::zeros();
        unrolled::<A>(|i| u[i] = kp[i] * state[i] + kd[i] * -state[A + i]);
        u
    }
}

#[cfg(feature = "serde")]
impl<const A: usize, const S: usize, const F: usize, const P: usize, M> CorrectedPd<A, S, F, P, M>
where
    M: crate::record::Persistent,
{
    /// The checks of the PD and of the policy, run on a decoded controller.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        self.pd.check_decoded()?;
        self.policy.check_decoded()
    }
}

impl<const A: usize, const S: usize, const F: usize, const P: usize, M> Controller<P, S, A>
    for CorrectedPd<A, S, F, P, M>
where
    M: FeatureMap<S, F>,
{
    fn nominal(&mut self, state: &Vector<S>, _time: f32) -> Vector<A> {
        self.pd.saturate(&self.unsaturated(state))
    }

    fn corrected(&mut self, theta: &Vector<P>, state: &Vector<S>, time: f32) -> Vector<A> {
        let c = self.policy.correction(theta, state, time);
        let mut u = self.nominal(state, time);
        unrolled::<A>(|i| u[i] += c[i]);
        self.pd.saturate(&u)
    }
}

/// Periodic variable-impedance PD of a hopping leg (Hwangbo et al., section IV, eq. 6):
/// τ = k_p (x_d − x) + k_d (ẋ_d − ẋ) on [knee, hip], scalar gains shared by both joints.
///
/// * Knee reference x_d1(ϕ) = w₀·φ(ϕ) + c₀: nominal kernel weights w₀ (rad) plus correction.
/// * Hip reference x_d2 = g·x_d1 + o: "constrained by the leg configuration given x_d1" in the
///   paper (for a foot kept under the hip with equal links, g = −1/2).
/// * Gains k_p = max(k_p0 + c₁, 0), k_d = max(k_d0 + c₂, 0).
/// * c = clamp(W·φ) with W 3×K, and the period learned: θ has 3K + 1 entries (31 for K = 10).
///
/// State layout (S = 4): [x_knee, x_hip, ẋ_knee, ẋ_hip]; action: [τ_knee, τ_hip].
/// P = 3K + 1 is checked at compile time.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PeriodicPd<const K: usize, const P: usize> {
    pd: Pd<2>,
    knee_weights: Vector<K>,
    hip_gain: f32,
    hip_offset: f32,
    policy: LinearPolicy<3, K, PeriodicRbf<K>>,
}

impl<const K: usize, const P: usize> PeriodicPd<K, P> {
    /// `pd` holds the nominal gains (its k_p and k_d for the knee are k_p0, k_d0 and are used
    /// for both joints, as in eq. 6) and torque limits; `knee_weights` the nominal knee
    /// reference on the kernels of `policy`'s map; the hip follows x_d2 = g·x_d1 + o.
    pub fn try_new(
        pd: Pd<2>,
        knee_weights: Vector<K>,
        hip_gain: f32,
        hip_offset: f32,
        policy: LinearPolicy<3, K, PeriodicRbf<K>>,
    ) -> Result<Self, Error> {
        const { assert!(P == 3 * K + 1, "θ = [W (3×K) | period offset]") };
        check_reference(&knee_weights, hip_gain, hip_offset)?;
        Ok(Self {
            pd,
            knee_weights,
            hip_gain,
            hip_offset,
            policy,
        })
    }

    /// The checks of [`PeriodicPd::try_new`], of the PD and of the policy, run on a decoded
    /// controller.
    #[cfg(feature = "serde")]
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        check_reference(&self.knee_weights, self.hip_gain, self.hip_offset)?;
        self.pd.check_decoded()?;
        self.policy.check_decoded()
    }

    /// The correction policy (its map holds the nominal period).
    pub fn policy(&self) -> &LinearPolicy<3, K, PeriodicRbf<K>> {
        &self.policy
    }

    /// Knee and hip torques for correction `c` = [Δx_d1, Δk_p, Δk_d] with weights-rate
    /// `dref` (ẋ_d1) and reference `reference` (x_d1).
    fn torques(
        &self,
        state: &Vector<4>,
        reference: f32,
        reference_rate: f32,
        c: &Vector<3>,
    ) -> Vector<2> {
        let x_d = Vector::<2>::from([reference, self.hip_gain * reference + self.hip_offset]);
        let xdot_d = Vector::<2>::from([reference_rate, self.hip_gain * reference_rate]);
        let x = Vector::<2>::from([state[0], state[1]]);
        let xdot = Vector::<2>::from([state[2], state[3]]);
        let kp = (self.pd.kp()[0] + c[1]).max(0.0);
        let kd = (self.pd.kd()[0] + c[2]).max(0.0);
        self.pd.output_with_gains(
            &Vector::repeat(kp),
            &Vector::repeat(kd),
            &(x_d - x),
            &(xdot_d - xdot),
        )
    }
}

/// The nominal knee weights and the hip's gain and offset finite.
fn check_reference<const K: usize>(
    knee_weights: &Vector<K>,
    hip_gain: f32,
    hip_offset: f32,
) -> Result<(), Error> {
    require(knee_weights.iter().all(|w| w.is_finite()), "knee_weights")?;
    require(hip_gain.is_finite() && hip_offset.is_finite(), "hip")
}

impl<const K: usize, const P: usize> Controller<P, 4, 2> for PeriodicPd<K, P> {
    fn nominal(&mut self, state: &Vector<4>, time: f32) -> Vector<2> {
        let map = self.policy.map();
        let (phi, dphi) = map.features_and_rates(time, map.period(0.0));
        let (r, dr) = (self.knee_weights.dot(&phi), self.knee_weights.dot(&dphi));
        self.torques(state, r, dr, &Vector::zeros())
    }

    fn corrected(&mut self, theta: &Vector<P>, state: &Vector<4>, time: f32) -> Vector<2> {
        let map = self.policy.map();
        let learned = LinearPolicy::<3, K, PeriodicRbf<K>>::learned(theta);
        let period = map.period(learned.first().copied().unwrap_or(0.0));
        let (phi, dphi) = map.features_and_rates(time, period);
        let c = self.policy.correction_from_features(theta, &phi);
        // ẋ_d1: the nominal part always moves; the correction's part only while unclamped.
        let knee_row = Vector::<K>::from_fn(|i, _| theta.as_slice().get(i).copied().unwrap_or(0.0));
        let unclamped = c[0].abs() < self.policy.envelope()[0];
        let dc = if unclamped { knee_row.dot(&dphi) } else { 0.0 };
        let r = self.knee_weights.dot(&phi) + c[0];
        let dr = self.knee_weights.dot(&dphi) + dc;
        self.torques(state, r, dr, &c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn auv() -> CorrectedPd<3, 6, 6, 18, StateFeatures<6>> {
        let pd = Pd::<3>::try_new(Vector::repeat(0.3), Vector::repeat(0.1))
            .unwrap()
            .with_limit(Vector::repeat(1.0))
            .unwrap();
        let policy = LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(0.4)).unwrap();
        CorrectedPd::new(pd, policy)
    }

    fn leg() -> PeriodicPd<10, 31> {
        let pd = Pd::<2>::try_new(Vector::repeat(40.0), Vector::repeat(1.0))
            .unwrap()
            .with_limit(Vector::repeat(30.0))
            .unwrap();
        let map = PeriodicRbf::<10>::try_new(0.6, 0.4, 0.9).unwrap();
        let policy = LinearPolicy::try_new(map, Vector::from([0.3, 20.0, 1.0])).unwrap();
        let weights = Vector::from_fn(|i, _| -1.2 + 0.3 * libm::cosf(TAU * i as f32 / 10.0));
        PeriodicPd::try_new(pd, weights, -0.5, 0.0, policy).unwrap()
    }

    #[test]
    fn periodic_features_sum_to_one_and_rates_match_finite_differences() {
        let map = PeriodicRbf::<10>::try_new(0.5, 0.3, 1.0).unwrap();
        for k in 0..200 {
            let t = k as f32 * 0.0137;
            let (phi, dphi) = map.features_and_rates(t, 0.5);
            assert!((phi.sum() - 1.0).abs() < 1e-5);
            assert!(phi.iter().all(|p| *p >= 0.0));
            let h = 1e-3;
            let (ahead, _) = map.features_and_rates(t + h, 0.5);
            let (behind, _) = map.features_and_rates(t - h, 0.5);
            let fd = (ahead - behind) / (2.0 * h);
            assert!((fd - dphi).amax() < 0.05 * dphi.amax().max(1.0), "t={t}");
        }
        // Periodic: the same features one period later.
        let (a, _) = map.features_and_rates(0.123, 0.5);
        let (b, _) = map.features_and_rates(0.623, 0.5);
        assert!((a - b).amax() < 1e-4);
    }

    #[test]
    fn period_is_learned_and_bounded() {
        let map = PeriodicRbf::<4>::try_new(0.5, 0.3, 1.0).unwrap();
        assert_eq!(map.period(0.1), 0.6);
        assert_eq!(map.period(5.0), 1.0);
        assert_eq!(map.period(f32::NAN), 0.5);
        assert_eq!(
            PeriodicRbf::<4>::try_new(0.2, 0.3, 1.0),
            Err(Error::InvalidParameter("period"))
        );
    }

    #[test]
    fn zero_correction_is_the_nominal_controller() {
        let mut auv = auv();
        let s = Vector::<6>::from([3.0, -1.0, 0.5, 0.2, 0.0, -0.3]);
        assert_eq!(
            auv.corrected(&Vector::<18>::zeros(), &s, 0.0),
            auv.nominal(&s, 0.0)
        );
        let mut leg = leg();
        let q = Vector::<4>::from([-1.0, 0.5, 0.3, -0.1]);
        for t in [0.0, 0.11, 0.37] {
            let a = leg.corrected(&Vector::<31>::zeros(), &q, t);
            let b = leg.nominal(&q, t);
            assert!((a - b).amax() < 1e-5);
        }
    }

    /// Checks: the correction acts on the PD's saturated output, so it still changes the
    /// action while the PD saturates (k_p e = 0.3·5 = 1.5 > limit 1): a correction of −0.4
    /// gives 1 − 0.4 = 0.6, not sat(1.5 − 0.4) = 1; the sum is saturated again.
    #[test]
    fn correction_is_added_to_the_saturated_pd_output() {
        let mut auv = auv();
        let s = Vector::<6>::from([5.0, -5.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(auv.nominal(&s, 0.0), Vector::from([1.0, -1.0, 0.0]));
        let mut theta = Vector::<18>::zeros();
        theta[0] = -1.0; // c_x = −e_x, clamped to −0.4
        theta[7] = 1.0; // c_y = e_y, clamped to −0.4: −1.4 saturates to −1
        theta[12] = 1.0; // c_z = e_x, clamped to +0.4
        let u = auv.corrected(&theta, &s, 0.0);
        assert!((u - Vector::from([0.6, -1.0, 0.4])).amax() < 1e-6, "{u}");
    }

    #[test]
    fn weights_follow_the_documented_layout() {
        // θ[6·a + f] weighs feature f in correction a.
        let auv = auv();
        let s = Vector::<6>::from([0.0, 0.0, 0.0, 0.0, 0.1, 0.0]);
        let mut theta = Vector::<18>::zeros();
        theta[6 * 2 + 4] = 2.0; // z correction from y velocity
        let c = auv.policy().correction(&theta, &s, 0.0);
        assert_eq!(c, Vector::from([0.0, 0.0, 0.2]));
    }

    /// The textbook clamp(W·φ), NaN → 0, as loops: what the unrolled correction must equal.
    fn reference<const P: usize>(theta: &Vector<P>, phi: &Vector<6>, limit: f32) -> Vector<3> {
        Vector::from_fn(|a, _| {
            let sum: f32 = (0..6).map(|f| theta[6 * a + f] * phi[f]).sum();
            if sum.is_nan() {
                0.0
            } else {
                sum.clamp(-limit, limit)
            }
        })
    }

    #[test]
    fn non_finite_sums_saturate_or_vanish() {
        // Checks: +∞ and −∞ sums clamp to ±envelope, a NaN sum (∞ − ∞, or a NaN state) gives
        // 0, and the identity map gives what a scale of ones gives.
        let policy =
            LinearPolicy::<3, 6, _>::try_new(IdentityFeatures, Vector::repeat(0.4)).unwrap();
        let mut theta = Vector::<18>::zeros();
        theta[0] = f32::MAX;
        theta[1] = f32::MAX;
        theta[6] = -f32::MAX;
        theta[7] = -f32::MAX;
        theta[12] = f32::MAX;
        theta[13] = -f32::MAX;
        let state = Vector::<6>::from([f32::MAX, f32::MAX, 0.0, 0.0, 0.0, 0.0]);
        let c = policy.correction(&theta, &state, 0.0);
        assert_eq!(c, Vector::from([0.4, -0.4, 0.0]));
        let nan = Vector::<6>::from([f32::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(policy.correction(&theta, &nan, 0.0), Vector::<3>::zeros());
        let scaled = auv().policy().correction(&theta, &state, 0.0);
        assert_eq!(scaled, c);
    }

    proptest! {
        /// Checks: the unrolled correction equals the textbook loops bit for bit (the same
        /// products summed in the same order), for both the identity and a scaled map.
        #[test]
        fn correction_equals_the_textbook_loops(
            theta in prop::array::uniform18(-1e3f32..1e3),
            state in prop::array::uniform6(-1e3f32..1e3),
            scale in prop::array::uniform6(-2f32..2.0),
        ) {
            let (theta, state, scale) =
                (Vector::from(theta), Vector::from(state), Vector::from(scale));
            let identity = LinearPolicy::<3, 6, _>::try_new(IdentityFeatures, Vector::repeat(0.4))
                .unwrap();
            let c = identity.correction(&theta, &state, 0.0);
            prop_assert_eq!(c, reference(&theta, &state, 0.4));
            let scaled = LinearPolicy::<3, 6, _>::try_new(
                StateFeatures::scaled(scale).unwrap(),
                Vector::repeat(0.4),
            )
            .unwrap();
            let c = scaled.correction(&theta, &state, 0.0);
            prop_assert_eq!(c, reference(&theta, &scale.component_mul(&state), 0.4));
        }

        /// Checks: for any θ and any state (NaN and infinities included), the AUV correction
        /// stays within its envelope, and the action within the PD's output limit.
        #[test]
        fn auv_correction_stays_in_its_envelope(
            theta in prop::array::uniform18(proptest::num::f32::ANY),
            state in prop::array::uniform6(proptest::num::f32::ANY),
        ) {
            let mut auv = auv();
            let (theta, state) = (Vector::from(theta), Vector::from(state));
            let c = auv.policy().correction(&theta, &state, 0.0);
            prop_assert!(c.iter().all(|v| v.abs() <= 0.4));
            let u = auv.corrected(&theta, &state, 0.0);
            prop_assert!(u.iter().all(|v| v.is_nan() || v.abs() <= 1.0));
            if state.iter().all(|v| v.is_finite() && v.abs() < 1e6) {
                prop_assert!(u.iter().all(|v| v.is_finite()));
            }
        }

        /// Checks: the unrolled PD of `CorrectedPd` gives what nalgebra's vector operations
        /// give, bit for bit: nominal = sat(k_p ∘ e + k_d ∘ (−v)), corrected = sat(nominal +
        /// c), with gains and limits of their own per axis and signed zeros in the state.
        #[test]
        fn corrected_pd_is_the_vector_formula_bit_for_bit(
            theta in prop::array::uniform18(-2f32..2.0),
            state in prop::array::uniform6(prop_oneof![8 => -5f32..5.0, 1 => Just(0.0f32), 1 => Just(-0.0f32)]),
        ) {
            let (kp, kd, limit) = (
                Vector::<3>::new(0.3, 1.7, -0.0),
                Vector::<3>::new(0.1, 0.0, 2.3),
                Vector::<3>::new(1.0, 0.5, f32::INFINITY),
            );
            let pd = Pd::<3>::try_new(kp, kd).unwrap().with_limit(limit).unwrap();
            let policy = LinearPolicy::try_new(IdentityFeatures, Vector::repeat(0.4)).unwrap();
            let mut controller: CorrectedPd<3, 6, 6, 18, _> = CorrectedPd::new(pd, policy);
            let (theta, state) = (Vector::from(theta), Vector::from(state));
            let error = Vector::<3>::new(state[0], state[1], state[2]);
            let rate = -Vector::<3>::new(state[3], state[4], state[5]);
            let sat = |u: Vector<3>| u.zip_map(&limit, |v, l| v.clamp(-l, l));
            let nominal = sat(kp.component_mul(&error) + kd.component_mul(&rate));
            let corrected = sat(nominal + controller.policy().correction(&theta, &state, 0.0));
            prop_assert_eq!(controller.nominal(&state, 0.0).map(f32::to_bits), nominal.map(f32::to_bits));
            prop_assert_eq!(
                controller.corrected(&theta, &state, 0.0).map(f32::to_bits),
                corrected.map(f32::to_bits)
            );
            prop_assert_eq!(pd.raw(&error, &rate).map(f32::to_bits),
                (kp.component_mul(&error) + kd.component_mul(&rate)).map(f32::to_bits));
        }

        /// Checks: for any θ (31 entries) and any time, the leg's corrections stay within
        /// their envelope and the torques within the limit.
        #[test]
        fn leg_correction_stays_in_its_envelope(
            w in prop::collection::vec(-1e3f32..1e3, 31),
            time in 0.0f32..100.0,
            state in prop::array::uniform4(-10.0f32..10.0),
        ) {
            let mut leg = leg();
            let theta = Vector::<31>::from_column_slice(&w);
            let phi = leg.policy().map().features_and_rates(time, 0.6).0;
            let c = leg.policy().correction_from_features(&theta, &phi);
            prop_assert!(c[0].abs() <= 0.3 && c[1].abs() <= 20.0 && c[2].abs() <= 1.0);
            let tau = leg.corrected(&theta, &Vector::from(state), time);
            prop_assert!(tau.iter().all(|t| t.is_finite() && t.abs() <= 30.0));
        }
    }
}
