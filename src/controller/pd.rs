//! A PD controller per axis, `f32`, no state unless you ask for finite differences.
//!
//! The law is u = sat(k_p ∘ e + k_d ∘ ė), with e = setpoint − measurement, per axis, and
//! sat the optional symmetric output limit. It is the controller of the seeds' robots: the
//! AUV's position loop producing velocity commands (Leonetti et al. 2012, section 5) and the
//! hopping leg's joint impedance τ = k_p (x_d − x) + k_d (ẋ_d − ẋ) (Hwangbo et al., eq. 6).
//!
//! # Derivative on measurement or on error
//! [`Pd::output`] takes the error *rate* from the caller, which decides:
//! * **on error**, ė = ṙ − ẏ: what eq. 6 of the hopping paper does with a reference
//!   trajectory whose rate ṙ is known;
//! * **on measurement**, ė = −ẏ: no derivative kick when the setpoint jumps (a new waypoint);
//!   it equals the former for a constant setpoint. The AUV loop uses it with the DVL's
//!   velocity as ẏ.
//!
//! Robots usually measure ẏ (DVL, joint encoders' velocity estimate); without a rate sensor,
//! [`Pd::update`] differentiates by finite differences, on the error or on the measurement
//! as [`Derivative`] says.

use super::clamp;
use crate::error::{Error, require};
use crate::vector::{Vector, unrolled};

/// Which signal [`Pd::update`] differentiates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Derivative {
    /// ė from successive errors: follows setpoint changes (and kicks on steps).
    OnError,
    /// ė = −ẏ from successive measurements: ignores setpoint steps.
    OnMeasurement,
}

/// A per-axis PD controller with an optional symmetric output limit.
///
/// ```
/// use ctrl_adapt::controller::Pd;
/// use ctrl_adapt::optimizer::Vector;
/// // Position loop of a vehicle: velocity command from position error and measured velocity.
/// let pd = Pd::<3>::try_new(Vector::repeat(0.5), Vector::repeat(0.2))?
///     .with_limit(Vector::repeat(1.0))?;
/// let error = Vector::from([4.0, 0.0, -1.0]);
/// let velocity = Vector::from([0.0, 0.5, 0.0]);
/// let cmd = pd.output(&error, &-velocity); // derivative on measurement: ė = −v
/// assert_eq!(cmd, Vector::from([1.0, -0.1, -0.5])); // x saturated at 1.0
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Pd<const A: usize> {
    kp: Vector<A>,
    kd: Vector<A>,
    limit: Vector<A>,
    derivative: Derivative,
    /// Previous differentiated signal for [`Pd::update`].
    previous: Option<Vector<A>>,
}

impl<const A: usize> Pd<A> {
    /// Gains per axis; each must be finite and ≥ 0. No output limit, derivative on
    /// measurement for [`Pd::update`].
    pub fn try_new(kp: Vector<A>, kd: Vector<A>) -> Result<Self, Error> {
        check_gains(&kp, &kd)?;
        Ok(Self {
            kp,
            kd,
            limit: Vector::repeat(f32::INFINITY),
            derivative: Derivative::OnMeasurement,
            previous: None,
        })
    }

    /// Limits |u_i| to `limit[i]` (> 0; `f32::INFINITY` for no limit on that axis).
    pub fn with_limit(mut self, limit: Vector<A>) -> Result<Self, Error> {
        check_limit(&limit)?;
        self.limit = limit;
        Ok(self)
    }

    /// The checks of [`Pd::try_new`] and [`Pd::with_limit`], run on a PD decoded from a
    /// record ([`Persistent::validate`](crate::record::Persistent)). The previous sample
    /// is not checked: any measurement, NaN included, may have been the last one.
    #[cfg(feature = "serde")]
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        check_gains(&self.kp, &self.kd)?;
        check_limit(&self.limit)
    }

    /// Chooses what [`Pd::update`] differentiates.
    pub fn with_derivative(mut self, derivative: Derivative) -> Self {
        self.derivative = derivative;
        self.previous = None;
        self
    }

    /// Proportional gains.
    pub fn kp(&self) -> &Vector<A> {
        &self.kp
    }

    /// Derivative gains.
    pub fn kd(&self) -> &Vector<A> {
        &self.kd
    }

    /// Output limits.
    pub fn limit(&self) -> &Vector<A> {
        &self.limit
    }

    /// k_p ∘ e + k_d ∘ ė before saturation.
    #[inline]
    pub fn raw(&self, error: &Vector<A>, error_rate: &Vector<A>) -> Vector<A> {
        // `kp.component_mul(error) + kd.component_mul(error_rate)`, unrolled (see
        // `unrolled`): the PD runs on every control tick and every imagined one.
        let mut u = Vector::<A>::zeros();
        unrolled::<A>(|i| u[i] = self.kp[i] * error[i] + self.kd[i] * error_rate[i]);
        u
    }

    /// `u` clamped to the output limits (NaN stays NaN, for the caller to detect).
    #[inline]
    pub fn saturate(&self, u: &Vector<A>) -> Vector<A> {
        // `f32::clamp` without its panic path (see `controller::clamp`).
        let mut saturated = *u;
        unrolled::<A>(|i| saturated[i] = clamp(u[i], -self.limit[i], self.limit[i]));
        saturated
    }

    /// u = sat(k_p ∘ e + k_d ∘ ė). Stateless.
    pub fn output(&self, error: &Vector<A>, error_rate: &Vector<A>) -> Vector<A> {
        self.saturate(&self.raw(error, error_rate))
    }

    /// u = sat(k_p ∘ e + k_d ∘ ė) with gains supplied for this tick (gain scheduling, as the
    /// hopping leg's variable impedance); the configured limit applies.
    pub fn output_with_gains(
        &self,
        kp: &Vector<A>,
        kd: &Vector<A>,
        error: &Vector<A>,
        error_rate: &Vector<A>,
    ) -> Vector<A> {
        self.saturate(&(kp.component_mul(error) + kd.component_mul(error_rate)))
    }

    /// One control period without a rate sensor: ė by finite difference over `dt` of the
    /// error or of the measurement (see [`Derivative`]); the first call after
    /// [`Pd::reset`] uses ė = 0. A non-finite or non-positive `dt` also gives ė = 0.
    pub fn update(&mut self, setpoint: &Vector<A>, measurement: &Vector<A>, dt: f32) -> Vector<A> {
        let error = setpoint - measurement;
        let (signal, sign) = match self.derivative {
            Derivative::OnError => (error, 1.0),
            Derivative::OnMeasurement => (*measurement, -1.0),
        };
        let rate = match self.previous {
            Some(prev) if dt.is_finite() && dt > 0.0 => (signal - prev) * (sign / dt),
            _ => Vector::zeros(),
        };
        self.previous = Some(signal);
        self.output(&error, &rate)
    }

    /// Forgets the previous sample used by [`Pd::update`] (call between episodes).
    pub fn reset(&mut self) {
        self.previous = None;
    }
}

/// Gains finite and ≥ 0.
fn check_gains<const A: usize>(kp: &Vector<A>, kd: &Vector<A>) -> Result<(), Error> {
    require(kp.iter().all(|k| k.is_finite() && *k >= 0.0), "kp")?;
    require(kd.iter().all(|k| k.is_finite() && *k >= 0.0), "kd")
}

/// Output limits > 0 (+∞ for none).
fn check_limit<const A: usize>(limit: &Vector<A>) -> Result<(), Error> {
    require(limit.iter().all(|l| *l > 0.0), "limit")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gains_and_limits_are_validated() {
        let ok = Vector::<2>::repeat(1.0);
        assert_eq!(
            Pd::try_new(Vector::from([1.0, -1.0]), ok),
            Err(Error::InvalidParameter("kp"))
        );
        assert_eq!(
            Pd::try_new(ok, Vector::from([f32::NAN, 0.0])),
            Err(Error::InvalidParameter("kd"))
        );
        let pd = Pd::try_new(ok, ok).unwrap();
        assert_eq!(
            pd.with_limit(Vector::from([0.0, 1.0])),
            Err(Error::InvalidParameter("limit"))
        );
        assert!(pd.with_limit(Vector::from([f32::INFINITY, 1.0])).is_ok());
    }

    /// Checks: `saturate` (no `f32::clamp`, see `controller::clamp`) equals `f32::clamp` bit
    /// for bit, signed zeros and infinite limits included, and passes NaN through.
    #[test]
    fn saturate_matches_clamp_and_keeps_nan() {
        let pd = Pd::<3>::try_new(Vector::repeat(1.0), Vector::repeat(1.0))
            .unwrap()
            .with_limit(Vector::from([0.5, 2.0, f32::INFINITY]))
            .unwrap();
        let values = [
            0.0,
            -0.0,
            0.25,
            -0.7,
            1e30,
            -1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
            2.0,
            -2.0,
        ];
        for v in values {
            let u = pd.saturate(&Vector::repeat(v));
            for (i, l) in pd.limit().iter().enumerate() {
                assert_eq!(u[i].to_bits(), v.clamp(-l, *l).to_bits(), "{v} limit {l}");
            }
        }
        assert!(
            pd.saturate(&Vector::repeat(f32::NAN))
                .iter()
                .all(|u| u.is_nan())
        );
    }

    #[test]
    fn finite_difference_matches_the_measured_rate() {
        // A measurement moving at 2 units/s towards a fixed setpoint: derivative on
        // measurement gives ė = −2 after the first sample, like `output` with the true rate.
        let pd0 = Pd::<1>::try_new(Vector::repeat(3.0), Vector::repeat(0.5)).unwrap();
        let mut pd = pd0;
        let sp = Vector::repeat(10.0);
        assert_eq!(
            pd.update(&sp, &Vector::repeat(1.0), 0.1),
            Vector::<1>::repeat(27.0)
        );
        let u = pd.update(&sp, &Vector::repeat(1.2), 0.1);
        let expected = pd0.output(&Vector::repeat(8.8), &Vector::repeat(-2.0));
        assert!((u[0] - expected[0]).abs() < 1e-4);
        // On error, a setpoint step kicks; on measurement it does not.
        let mut on_error = pd0.with_derivative(Derivative::OnError);
        let mut on_meas = pd0;
        for pd in [&mut on_error, &mut on_meas] {
            pd.update(&sp, &Vector::repeat(1.0), 0.1);
        }
        let step = Vector::repeat(11.0);
        let ue = on_error.update(&step, &Vector::repeat(1.0), 0.1)[0];
        let um = on_meas.update(&step, &Vector::repeat(1.0), 0.1)[0];
        assert!((ue - (30.0 + 0.5 * 10.0)).abs() < 1e-3);
        assert_eq!(um, 30.0);
    }
}
