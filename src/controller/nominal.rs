//! Your own controller, made adaptive as it is: [`Corrected`] adds a learned, clamped,
//! state-linear correction to any [`Nominal`] law, including a closure around the PD your
//! firmware already runs, state and all.
//!
//! ```text
//!  u = sat( u_nominal(state, t) + L ∘ clamp(Θ · (state ⊘ scale), −1, 1) )
//! ```
//!
//! Θ (A rows of S weights, θ row-major, P = A·S) is dimensionless and lives in the unit box
//! [−1, 1]^P: a weight of 1 means "state component j at ±`scale[j]` alone commands the whole
//! correction `L[i]` on axis i". The correction is added to the nominal *output*, as in
//! [`CorrectedPd`](super::CorrectedPd) (Leonetti et al. 2012, section 5), so it keeps its
//! authority when the nominal law saturates; the optional output limit `sat` bounds the sum.

use super::{Controller, LinearPolicy, StateFeatures, clamp};
use crate::error::{Error, require};
use crate::vector::Vector;

/// A nominal control law of your own: the action for a state, `time` seconds after the
/// episode began. It may keep state between calls (a PD's previous error).
///
/// Every `FnMut(&Vector<S>, f32) -> Vector<A>` is one, so a closure around your PD is
/// enough. Implement the trait yourself when the law should forget its state at the start
/// of an episode ([`Nominal::reset`]).
pub trait Nominal<const S: usize, const A: usize> {
    /// The nominal action for `state`.
    fn action(&mut self, state: &Vector<S>, time: f32) -> Vector<A>;

    /// Called when an episode begins. Nothing by default, and a closure cannot be reset:
    /// give your law a type and implement this trait for it when it should forget its
    /// memory at the start of an episode. (`time` is no substitute: outside episodes the
    /// adapter runs the nominal law with `time` = 0 on every tick.)
    fn reset(&mut self) {}
}

impl<F, const S: usize, const A: usize> Nominal<S, A> for F
where
    F: FnMut(&Vector<S>, f32) -> Vector<A>,
{
    fn action(&mut self, state: &Vector<S>, time: f32) -> Vector<A> {
        self(state, time)
    }
}

/// A [`Nominal`] law corrected by a state-linear policy (see the [module docs](self)):
/// A actions, S state values, P = A·S parameters in [−1, 1] (checked at compile time).
///
/// ```
/// use ctrl_adapt::controller::{Controller, Corrected};
/// use ctrl_adapt::Vector;
/// // A PD that differentiates its own error over the 0.02 s tick: it keeps state.
/// let mut previous = None;
/// let pd = move |s: &Vector<1>, _t: f32| {
///     let rate = previous.map_or(0.0, |p: f32| (s[0] - p) / 0.02);
///     previous = Some(s[0]);
///     Vector::from([4.0 * s[0] + 0.5 * rate])
/// };
/// // Correction up to ±3, full when the error reaches 0.5.
/// let mut controller = Corrected::<_, 1, 1, 1>::try_new(pd, [3.0].into(), [0.5].into())?;
/// assert_eq!(controller.nominal(&Vector::from([0.1]), 0.0), Vector::from([0.4]));
/// // θ = 1: 0.1 / 0.5 of the full correction 3; the PD's rate term is (0.2 − 0.1) / 0.02.
/// let u = controller.corrected(&Vector::from([1.0]), &Vector::from([0.2]), 0.02);
/// assert!((u[0] - (0.8 + 0.5 * 5.0 + 1.2)).abs() < 1e-5);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Corrected<N, const A: usize, const S: usize, const P: usize> {
    nominal: N,
    policy: LinearPolicy<A, S, StateFeatures<S>>,
    limit: Vector<A>,
    output_limit: Vector<A>,
}

impl<N, const A: usize, const S: usize, const P: usize> Corrected<N, A, S, P>
where
    N: Nominal<S, A>,
{
    /// `nominal` corrected by up to ±`limit[i]` on axis i (finite, > 0), with the features
    /// φ_j = state_j / `scale[j]` (finite, > 0: the size of state component j at which it
    /// alone may command the whole correction). No output limit.
    pub fn try_new(nominal: N, limit: Vector<A>, scale: Vector<S>) -> Result<Self, Error> {
        const { assert!(P == A * S, "θ holds the A·S weights") };
        check_limits(&limit, &Vector::repeat(f32::INFINITY))?;
        require(scale.iter().all(|s| s.is_finite() && *s > 0.0), "scale")?;
        let features = StateFeatures::scaled(scale.map(|s| 1.0 / s))?;
        Ok(Self {
            nominal,
            policy: LinearPolicy::try_new(features, Vector::repeat(1.0))?,
            limit,
            output_limit: Vector::repeat(f32::INFINITY),
        })
    }

    /// Limits |u_i| of the corrected action to `output_limit[i]` (> 0; `f32::INFINITY` for
    /// none), e.g. the actuator's range. The nominal action is never limited: it is yours.
    pub fn with_output_limit(mut self, output_limit: Vector<A>) -> Result<Self, Error> {
        check_limits(&self.limit, &output_limit)?;
        self.output_limit = output_limit;
        Ok(self)
    }

    /// The nominal law.
    pub fn nominal_law(&self) -> &N {
        &self.nominal
    }

    /// The nominal law, to change it between episodes (new gains from the operator).
    pub fn nominal_law_mut(&mut self) -> &mut N {
        &mut self.nominal
    }

    /// The correction limit L.
    pub fn limit(&self) -> &Vector<A> {
        &self.limit
    }

    /// The correction L ∘ clamp(Θ φ, ±1) alone, within ±L for any θ and state (NaN → 0).
    pub fn correction(&self, theta: &Vector<P>, state: &Vector<S>) -> Vector<A> {
        self.policy
            .correction(theta, state, 0.0)
            .component_mul(&self.limit)
    }
}

#[cfg(feature = "serde")]
impl<N, const A: usize, const S: usize, const P: usize> Corrected<N, A, S, P>
where
    N: crate::record::Persistent,
{
    /// The checks of [`Corrected::try_new`] and [`Corrected::with_output_limit`] and those
    /// of the nominal law, run on a decoded controller.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        check_limits(&self.limit, &self.output_limit)?;
        self.policy.check_decoded()?;
        require(
            *self.policy.envelope() == Vector::<A>::repeat(1.0),
            "envelope",
        )?;
        self.nominal.validate()
    }
}

/// Correction limits finite and > 0; output limits > 0 (+∞ for none).
fn check_limits<const A: usize>(limit: &Vector<A>, output_limit: &Vector<A>) -> Result<(), Error> {
    require(limit.iter().all(|l| l.is_finite() && *l > 0.0), "limit")?;
    require(output_limit.iter().all(|l| *l > 0.0), "output_limit")
}

impl<N, const A: usize, const S: usize, const P: usize> Controller<P, S, A>
    for Corrected<N, A, S, P>
where
    N: Nominal<S, A>,
{
    fn nominal(&mut self, state: &Vector<S>, time: f32) -> Vector<A> {
        self.nominal.action(state, time)
    }

    fn corrected(&mut self, theta: &Vector<P>, state: &Vector<S>, time: f32) -> Vector<A> {
        let u = self.nominal.action(state, time) + self.correction(theta, state);
        u.zip_map(&self.output_limit, |v, l| clamp(v, -l, l))
    }

    fn reset(&mut self) {
        self.nominal.reset();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn linear(gain: f32) -> impl FnMut(&Vector<2>, f32) -> Vector<1> {
        move |s: &Vector<2>, _t: f32| Vector::from([gain * s[0]])
    }

    #[test]
    fn limits_and_scales_are_validated() {
        let ok2 = Vector::<2>::repeat(1.0);
        let ok1 = Vector::<1>::repeat(1.0);
        let new = |l: Vector<1>, s: Vector<2>| Corrected::<_, 1, 2, 2>::try_new(linear(1.0), l, s);
        assert_eq!(
            new(Vector::repeat(0.0), ok2).err(),
            Some(Error::InvalidParameter("limit"))
        );
        assert_eq!(
            new(Vector::repeat(f32::INFINITY), ok2).err(),
            Some(Error::InvalidParameter("limit"))
        );
        assert_eq!(
            new(ok1, Vector::from([1.0, f32::NAN])).err(),
            Some(Error::InvalidParameter("scale"))
        );
        assert_eq!(
            new(ok1, Vector::from([1.0, -1.0])).err(),
            Some(Error::InvalidParameter("scale"))
        );
        let c = new(ok1, ok2).unwrap();
        assert_eq!(
            c.with_output_limit(Vector::repeat(0.0)).err(),
            Some(Error::InvalidParameter("output_limit"))
        );
    }

    /// A law that counts its resets, to check that `Controller::reset` reaches it.
    struct Counting(u32);

    impl Nominal<2, 1> for Counting {
        fn action(&mut self, state: &Vector<2>, _time: f32) -> Vector<1> {
            Vector::from([state[0]])
        }
        fn reset(&mut self) {
            self.0 += 1;
        }
    }

    #[test]
    fn reset_reaches_the_nominal_law() {
        let mut c =
            Corrected::<_, 1, 2, 2>::try_new(Counting(0), Vector::repeat(1.0), Vector::repeat(1.0))
                .unwrap();
        c.reset();
        c.reset();
        assert_eq!(c.nominal_law().0, 2);
    }

    /// Checks: the library's `Pd`, differentiating by finite differences (`Pd::update`,
    /// `&mut self`), serves as the nominal law: the corrected controller's first tick has
    /// no rate, its second the measured one, as the bare `Pd` alone gives.
    #[test]
    fn the_library_pd_with_state_serves_as_nominal_law() {
        use crate::controller::Pd;
        let pd = Pd::<1>::try_new(Vector::repeat(3.0), Vector::repeat(0.5)).unwrap();
        let mut reference = pd;
        let setpoint = Vector::<1>::repeat(1.0);
        // State: [position]; the law sees the setpoint and the measurement.
        let mut inner = pd;
        let law = move |s: &Vector<1>, _t: f32| inner.update(&setpoint, s, 0.1);
        let mut c = Corrected::<_, 1, 1, 1>::try_new(law, Vector::repeat(1.0), Vector::repeat(1.0))
            .unwrap();
        let theta = Vector::zeros();
        for x in [0.0, 0.2, 0.3] {
            let s = Vector::from([x]);
            assert_eq!(
                c.corrected(&theta, &s, 0.0),
                reference.update(&setpoint, &s, 0.1)
            );
        }
    }

    /// Checks: a `Corrected` whose law has a type of its own is saved and loaded bit for
    /// bit, with its law; a record whose correction limit was forged to NaN is refused.
    #[cfg(feature = "serde")]
    #[test]
    fn a_corrected_law_round_trips_and_forged_limits_are_refused() {
        use crate::record::{self, Persistent, RecordError, Shape};

        #[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
        struct Gain(f32);
        impl Nominal<1, 1> for Gain {
            fn action(&mut self, state: &Vector<1>, _time: f32) -> Vector<1> {
                state * self.0
            }
        }
        impl Persistent for Gain {
            const SHAPE: Shape = Shape::new(*b"GAIN", &[]);
            fn validate(&self) -> Result<(), Error> {
                require(self.0.is_finite(), "gain")
            }
        }

        let c = Corrected::<_, 1, 1, 1>::try_new(Gain(2.0), [1.5].into(), [0.5].into()).unwrap();
        let mut buf = [0u8; 128];
        let bytes = record::save(&c, &mut buf).unwrap().to_vec();
        assert_eq!(record::load::<Corrected<Gain, 1, 1, 1>>(&bytes), Ok(c));
        let mut forged = c;
        forged.limit = Vector::repeat(f32::NAN);
        let bytes = record::save_unchecked(&forged, &mut buf).unwrap().to_vec();
        assert_eq!(
            record::load::<Corrected<Gain, 1, 1, 1>>(&bytes),
            Err(RecordError::Invalid(Error::InvalidParameter("limit")))
        );
        let mut forged = c;
        forged.nominal = Gain(f32::INFINITY);
        let bytes = record::save_unchecked(&forged, &mut buf).unwrap().to_vec();
        assert_eq!(
            record::load::<Corrected<Gain, 1, 1, 1>>(&bytes),
            Err(RecordError::Invalid(Error::InvalidParameter("gain")))
        );
    }

    proptest! {
        /// Checks: for any θ in the box and any state (NaN and ±∞ included), the correction
        /// stays within ±L (NaN becomes 0); the corrected action differs from the nominal one
        /// by at most L before the output limit, and stays within the output limit.
        #[test]
        fn the_correction_stays_within_its_limit(
            theta in proptest::array::uniform4(-1.0f32..=1.0),
            state in proptest::array::uniform2(prop_oneof![
                -1e6f32..1e6,
                Just(f32::NAN),
                Just(f32::INFINITY),
                Just(f32::NEG_INFINITY),
            ]),
            e in 0.0f32..5.0,
        ) {
            let limit = Vector::from([0.5, 2.0]);
            let scale = Vector::from([0.1, 3.0]);
            let nominal = |s: &Vector<2>, _t: f32| Vector::from([s[0].clamp(-1.0, 1.0), 0.0]);
            let mut c = Corrected::<_, 2, 2, 4>::try_new(nominal, limit, scale)
                .unwrap()
                .with_output_limit(Vector::from([1.2, f32::INFINITY]))
                .unwrap();
            let theta = Vector::from(theta);
            let state = Vector::from([state[0], state[1] * e]);
            let corr = c.correction(&theta, &state);
            for i in 0..2 {
                prop_assert!(corr[i].abs() <= limit[i], "{corr}");
            }
            let u = c.corrected(&theta, &state, 0.0);
            let n = c.nominal(&state, 0.0);
            if n.iter().all(|v| v.is_finite()) {
                prop_assert!(u[0].abs() <= 1.2);
                prop_assert!((u[1] - n[1]).abs() <= limit[1]);
            }
        }
    }
}
