//! Imagined episodes: the controller, its correction θ and the cost shaper run against a
//! learned model instead of the plant (the inner loop of PILCO and Black-DROPS, which
//! evaluate a policy on the model's predicted trajectory).
//!
//! [`imagine_episode`] mirrors one episode of the [`Adapter`](crate::controller::Adapter):
//! the same [`Controller`] (its `corrected` law, with the time of each tick), the same
//! [`Shaper`] (observing each tick's observation after the command is computed) and the same
//! control period, with the model's prediction standing in for the plant's next state. So the
//! adapter's own controller and shaper score a candidate on the model exactly as they would
//! on the robot. [`rollout`] is the bare loop, for a policy or cost of another form.
//!
//! The predicted cost is only as good as the model over the states the candidate visits: a
//! θ that drives the state where no tick was recorded is scored by extrapolation. Use it to
//! rank candidates near the ones the robot has run, and check the ranking against real
//! episodes (the AUV study in `experiments/findings/model.md`).

use super::{Regressors, RlsModel};
use crate::controller::Controller;
use crate::cost::Shaper;
use crate::error::Error;
use crate::vector::{Vector, all_finite};

/// Rolls the model forward `ticks` ticks from `start`: each tick `step(k, &state)` returns
/// the command, and the model predicts the next state. Returns the final state.
///
/// Errors: a non-finite `start` ([`Error::NonFinite`]`("start")`) or a prediction that
/// leaves the finite numbers ([`Error::NonFinite`]`("prediction")`): the rollout stops there.
///
/// ```
/// use ctrl_adapt::model::{Affine, ModelConfig, RlsModel, rollout};
/// use ctrl_adapt::Vector;
/// let mut model = RlsModel::<1, 1, 3>::try_new(ModelConfig::DEFAULT)?;
/// let mut x = Vector::<1>::new(0.0);
/// for k in 0..100 {
///     // An integrator: x' = x + 0.1 u.
///     let u = Vector::<1>::new(if k % 7 < 3 { 1.0 } else { -0.5 });
///     let next = x + u * 0.1;
///     model.update(&Affine, &x, &u, &next)?;
///     x = next;
/// }
/// // Ten ticks of u = 1 from 0 reach about 1.
/// let end = rollout(&model, &Affine, &Vector::<1>::new(0.0), 10, |_, _| Vector::<1>::new(1.0))?;
/// assert!((end[0] - 1.0).abs() < 1e-2);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
pub fn rollout<const S: usize, const A: usize, const R: usize, M: Regressors<S, A, R>>(
    model: &RlsModel<S, A, R>,
    map: &M,
    start: &Vector<S>,
    ticks: u32,
    step: impl FnMut(u32, &Vector<S>) -> Vector<A>,
) -> Result<Vector<S>, Error> {
    roll::<S, A, R, M, false>(model, map, start, ticks, step).map(|(end, _)| end)
}

/// [`rollout`], and the sum of the leverages zₜᵀPzₜ of its ticks when `LEVERAGE` (0
/// otherwise, and the per-tick quadratic form is not computed).
fn roll<
    const S: usize,
    const A: usize,
    const R: usize,
    M: Regressors<S, A, R>,
    const LEVERAGE: bool,
>(
    model: &RlsModel<S, A, R>,
    map: &M,
    start: &Vector<S>,
    ticks: u32,
    mut step: impl FnMut(u32, &Vector<S>) -> Vector<A>,
) -> Result<(Vector<S>, f32), Error> {
    if !all_finite(start) {
        return Err(Error::NonFinite("start"));
    }
    let mut state = *start;
    let mut leverage = 0.0f32;
    for k in 0..ticks {
        let command = step(k, &state);
        state = if LEVERAGE {
            let (next, h) = model.predict_with_leverage(map, &state, &command);
            leverage += h;
            next
        } else {
            model.predict(map, &state, &command)
        };
        if !all_finite(&state) {
            return Err(Error::NonFinite("prediction"));
        }
    }
    Ok((state, leverage))
}

/// The predicted cost of one episode of `controller` corrected by `theta`, scored by
/// `shaper`, on the model: from `start`, `ticks` control periods of `dt` seconds. Each tick,
/// as in the adapter: the command is `controller.corrected(theta, state, k·dt)` (a
/// non-finite command falls back to `controller.nominal`, then to its safe action), the
/// shaper observes `observation(&state)` over `dt`, and the model predicts the next state.
/// The controller and the shaper are reset first; the model is not changed.
///
/// Errors as [`rollout`]'s; a non-finite cost (the shaper saw nothing valid) is
/// [`Error::NonFinite`]`("cost")`.
///
/// ```
/// use ctrl_adapt::controller::{Controller, CorrectedPd, IdentityFeatures, LinearPolicy, Pd};
/// use ctrl_adapt::cost::{QuadraticCost, Shaper};
/// use ctrl_adapt::model::{Affine, ModelConfig, RlsModel, imagine_episode};
/// use ctrl_adapt::Vector;
/// // A 1-D position error e with velocity v; the command is an acceleration (dt = 0.1):
/// // state [e, v], e' = e − 0.1 v, v' = v + 0.1 u.
/// let plant = |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
/// let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT)?;
/// let mut x = Vector::<2>::new(1.0, 0.0);
/// for k in 0..300 {
///     let u = Vector::<1>::new(((k * 37) % 11) as f32 / 5.0 - 1.0 + x[0] - 1.5 * x[1]);
///     let next = plant(&x, &u);
///     model.update(&Affine, &x, &u, &next)?;
///     x = next;
/// }
/// let pd = Pd::try_new(Vector::<1>::new(1.0), Vector::<1>::new(1.5))?;
/// let policy = LinearPolicy::try_new(IdentityFeatures, Vector::<1>::new(1.0))?;
/// let mut controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
/// let mut cost = QuadraticCost::try_new(Vector::<1>::new(1.0))?;
/// let start = Vector::<2>::new(1.0, 0.0);
/// let theta = Vector::<2>::new(0.5, 0.0);
/// let imagined = imagine_episode(&model, &Affine, &start, 100, 0.1, &mut controller, &theta,
///     &mut cost, |x| Vector::<1>::new(x[0]))?;
/// // The same episode on the plant itself.
/// cost.reset();
/// let mut x = start;
/// for k in 0..100 {
///     let u = controller.corrected(&theta, &x, k as f32 * 0.1);
///     cost.observe(&Vector::<1>::new(x[0]), 0.1);
///     x = plant(&x, &u);
/// }
/// assert!((imagined - cost.cost()).abs() < 1e-2 * cost.cost());
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
#[allow(clippy::too_many_arguments)]
pub fn imagine_episode<
    const P: usize,
    const S: usize,
    const A: usize,
    const R: usize,
    M: Regressors<S, A, R>,
    C: Controller<P, S, A>,
    Sh: Shaper,
>(
    model: &RlsModel<S, A, R>,
    map: &M,
    start: &Vector<S>,
    ticks: u32,
    dt: f32,
    controller: &mut C,
    theta: &Vector<P>,
    shaper: &mut Sh,
    observation: impl Fn(&Vector<S>) -> Sh::Observation,
) -> Result<f32, Error> {
    controller.reset();
    shaper.reset();
    continue_episode::<P, S, A, R, M, C, Sh, false>(
        model,
        map,
        start,
        0,
        ticks,
        dt,
        controller,
        theta,
        u32::MAX,
        shaper,
        observation,
    )
    .map(|i| i.cost)
}

/// The cost a running episode is forecast to end with if `theta` keeps correcting for
/// `candidate_ticks` more ticks and the bare (nominal) controller runs the rest: a hand-over
/// `candidate_ticks` from now, imagined on the model. `state` is the state at `tick` (before
/// that tick's control), `ticks` the episode's length; `controller` and `shaper` are copies
/// of the adapter's as they are now ([`Adapter::controller`], [`Adapter::shaper`]: their
/// state, e.g. the PD's previous error and the running cost, carries on; nothing is reset).
/// Each tick as in [`imagine_episode`].
///
/// This is the forecast of a *predictive safety filter* with the nominal controller as the
/// backup (the filters surveyed by Brunke et al., "Safe Learning in Robotics", Annual
/// Review of Control, Robotics, and Autonomous Systems 2022): give it to the guard as a
/// safety signal ([`Source::Signal`]) with a limit, and the episode is handed back while
/// the backup is still forecast to end it within the limit, `candidate_ticks` ahead of the
/// point where, by the model, it no longer would. Unlike the filters of that survey, the
/// backup's outcome is a forecast on a learned point model, not a certified invariant set:
/// it is as good as the model around the states the episode visits (see
/// `experiments/findings/guard.md`, where dividing by the model's own forecast of the bare
/// episode removed the model's bias).
///
/// Errors as [`imagine_episode`]'s.
///
/// [`Adapter::controller`]: crate::controller::Adapter::controller
/// [`Adapter::shaper`]: crate::controller::Adapter::shaper
/// [`Source::Signal`]: crate::controller::guard::Source::Signal
///
/// ```
/// use ctrl_adapt::controller::{Controller, CorrectedPd, IdentityFeatures, LinearPolicy, Pd};
/// use ctrl_adapt::cost::{QuadraticCost, Shaper};
/// use ctrl_adapt::model::{Affine, ModelConfig, RlsModel, imagine_episode, imagine_handover};
/// use ctrl_adapt::Vector;
/// // The plant of `imagine_episode`'s example, its model fitted on varied commands.
/// let plant = |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
/// let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT)?;
/// let mut x = Vector::<2>::new(1.0, 0.0);
/// for k in 0..300 {
///     let u = Vector::<1>::new(((k * 37) % 11) as f32 / 5.0 - 1.0 + x[0] - 1.5 * x[1]);
///     let next = plant(&x, &u);
///     model.update(&Affine, &x, &u, &next)?;
///     x = next;
/// }
/// let pd = Pd::try_new(Vector::<1>::new(1.0), Vector::<1>::new(1.5))?;
/// let policy = LinearPolicy::try_new(IdentityFeatures, Vector::<1>::new(1.0))?;
/// let mut controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
/// let mut cost = QuadraticCost::try_new(Vector::<1>::new(1.0))?;
/// let start = Vector::<2>::new(1.0, 0.0);
/// let theta = Vector::<2>::new(-0.8, 0.0); // a correction that slows the PD down
/// // The episode on the plant, 30 ticks of θ so far.
/// controller.reset();
/// cost.reset();
/// let mut x = start;
/// for k in 0..30 {
///     let u = controller.corrected(&theta, &x, k as f32 * 0.1);
///     cost.observe(&Vector::<1>::new(x[0]), 0.1);
///     x = plant(&x, &u);
/// }
/// // Handing over in 5 ticks is forecast to end lower than keeping θ to the end.
/// let handover = imagine_handover(&model, &Affine, &x, 30, 100, 0.1, controller, &theta, 5,
///     cost, |x| Vector::<1>::new(x[0]))?;
/// let keep = imagine_handover(&model, &Affine, &x, 30, 100, 0.1, controller, &theta, 100,
///     cost, |x| Vector::<1>::new(x[0]))?;
/// assert!(handover < keep);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
#[allow(clippy::too_many_arguments)]
pub fn imagine_handover<
    const P: usize,
    const S: usize,
    const A: usize,
    const R: usize,
    M: Regressors<S, A, R>,
    C: Controller<P, S, A>,
    Sh: Shaper,
>(
    model: &RlsModel<S, A, R>,
    map: &M,
    state: &Vector<S>,
    tick: u32,
    ticks: u32,
    dt: f32,
    mut controller: C,
    theta: &Vector<P>,
    candidate_ticks: u32,
    mut shaper: Sh,
    observation: impl Fn(&Vector<S>) -> Sh::Observation,
) -> Result<f32, Error> {
    continue_episode::<P, S, A, R, M, C, Sh, false>(
        model,
        map,
        state,
        tick,
        ticks,
        dt,
        &mut controller,
        theta,
        tick.saturating_add(candidate_ticks),
        &mut shaper,
        observation,
    )
    .map(|i| i.cost)
}

/// Ticks `first..ticks` of an episode on the model from `state`, `controller` and `shaper`
/// as they are: θ corrects before tick `correct_until`, the nominal controller after. The
/// one imagined-episode loop behind [`imagine_episode`], [`imagine_handover`] and
/// [`imagine_episode_with_variance`]; the leverage is summed only when `LEVERAGE`.
#[allow(clippy::too_many_arguments)]
fn continue_episode<
    const P: usize,
    const S: usize,
    const A: usize,
    const R: usize,
    M: Regressors<S, A, R>,
    C: Controller<P, S, A>,
    Sh: Shaper,
    const LEVERAGE: bool,
>(
    model: &RlsModel<S, A, R>,
    map: &M,
    state: &Vector<S>,
    first: u32,
    ticks: u32,
    dt: f32,
    controller: &mut C,
    theta: &Vector<P>,
    correct_until: u32,
    shaper: &mut Sh,
    observation: impl Fn(&Vector<S>) -> Sh::Observation,
) -> Result<Imagined<S>, Error> {
    let (_, leverage) = roll::<S, A, R, M, LEVERAGE>(
        model,
        map,
        state,
        ticks.saturating_sub(first),
        |k, state| {
            let tick = first + k;
            let time = tick as f32 * dt;
            let mut command = if tick < correct_until {
                controller.corrected(theta, state, time)
            } else {
                controller.nominal(state, time)
            };
            if !all_finite(&command) {
                command = controller.nominal(state, time);
                if !all_finite(&command) {
                    command = controller.safe_action();
                }
            }
            shaper.observe(&observation(state), dt);
            command
        },
    )?;
    let cost = shaper.cost();
    if !cost.is_finite() {
        return Err(Error::NonFinite("cost"));
    }
    let variance = model.residual_variance() * leverage;
    if !(leverage.is_finite() && variance.iter().all(|v| v.is_finite())) {
        return Err(Error::NonFinite("variance"));
    }
    Ok(Imagined {
        cost,
        leverage,
        variance,
    })
}

/// An imagined episode's predicted cost and the model's uncertainty along its trajectory
/// ([`imagine_episode_with_variance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Imagined<const S: usize> {
    /// The predicted cost, as [`imagine_episode`] returns it.
    pub cost: f32,
    /// Σₜ zₜᵀPzₜ over the episode's ticks: the summed [`RlsModel::leverage`] of the states
    /// and commands the candidate visits.
    pub leverage: f32,
    /// Σₜ σ̂²·zₜᵀPzₜ per state dimension: the summed one-step
    /// [`RlsModel::predictive_variance`] along the imagined trajectory.
    pub variance: Vector<S>,
}

impl<const S: usize> Imagined<S> {
    /// √(Σⱼ varianceⱼ): the root of the summed predictive variance over the state
    /// dimensions, in the state's units, as one number per candidate (what
    /// [`Prediction::uncertainty`](super::learner::Prediction) takes when the state's
    /// dimensions share a unit; weight them yourself otherwise).
    pub fn deviation(&self) -> f32 {
        libm::sqrtf(self.variance.sum())
    }
}

/// [`imagine_episode`], and the model's predictive variance summed along the imagined
/// trajectory ([`Imagined`]): a candidate-dependent measure of how far the episode
/// leaves the states and commands the model was fitted on.
///
/// Each tick t adds the leverage hₜ = zₜᵀPzₜ of the imagined state and command; the episode's
/// variance is σ̂²·Σₜ hₜ per state dimension (σ̂² the model's [`RlsModel::residual_variance`]).
/// PILCO (Deisenroth & Rasmussen, ICML 2011) propagates the Gaussian process's predictive
/// distribution through the dynamics by moment matching and takes the expected cost;
/// Black-DROPS (Chatzilygeroudis et al., IROS 2017) evaluates the policy on sampled models.
/// This is cheaper and cruder: the one-step variances along the *mean* trajectory are
/// summed, as if the one-step errors were independent and did not feed back through the
/// dynamics or the controller, and the result is a variance of the state, not of the cost.
/// It ranks candidates by how much they extrapolate, which is what a screen needs; it is
/// not a calibrated confidence interval of the cost.
///
/// Costs R² + R multiply-adds per tick beyond [`imagine_episode`] (210 for R = 14): at the
/// AUV's size on a Cortex-M4F at opt-level 3, about 285,000 instructions per 240-tick
/// episode instead of 156,000 (the `bench_model` firmware).
/// Errors as [`imagine_episode`]'s; a non-finite variance is [`Error::NonFinite`]`("variance")`.
///
/// ```
/// use ctrl_adapt::controller::{Controller, CorrectedPd, IdentityFeatures, LinearPolicy, Pd};
/// use ctrl_adapt::cost::QuadraticCost;
/// use ctrl_adapt::model::{Affine, ModelConfig, RlsModel, imagine_episode_with_variance};
/// use ctrl_adapt::Vector;
/// // The double integrator [e, v] of `imagine_episode`'s example, its model fitted on three
/// // episodes of the bare PD with a small dither on the command.
/// let plant = |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
/// let pd = Pd::try_new(Vector::<1>::new(1.0), Vector::<1>::new(1.5))?;
/// let policy = LinearPolicy::try_new(IdentityFeatures, Vector::<1>::new(10.0))?;
/// let mut controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
/// let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT)?;
/// let start = Vector::<2>::new(1.0, 0.0);
/// for episode in 0..3u32 {
///     let mut x = start;
///     for k in 0..100u32 {
///         let dither = ((k * 7919 + episode * 13) % 11) as f32 / 50.0 - 0.1;
///         let u = controller.nominal(&x, k as f32 * 0.1) + Vector::<1>::new(dither);
///         let noise = ((k * 104_729) % 13) as f32 / 1300.0 - 0.005;
///         let next = plant(&x, &u) + Vector::<2>::new(noise, -noise);
///         model.update(&Affine, &x, &u, &next)?;
///         x = next;
///     }
/// }
/// let mut cost = QuadraticCost::try_new(Vector::<1>::new(1.0))?;
/// let mut imagine = |theta: Vector<2>| imagine_episode_with_variance(&model, &Affine, &start,
///     100, 0.1, &mut controller, &theta, &mut cost, |x| Vector::<1>::new(x[0]));
/// // The bare PD, as recorded, and a large correction the ticks never saw: the model
/// // extrapolates along the second, and says so.
/// let near = imagine(Vector::<2>::new(0.0, 0.0))?;
/// let far = imagine(Vector::<2>::new(1.0, -1.0))?;
/// assert!(far.deviation() > 1.5 * near.deviation());
/// assert!(far.leverage > 2.0 * near.leverage);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
#[allow(clippy::too_many_arguments)]
pub fn imagine_episode_with_variance<
    const P: usize,
    const S: usize,
    const A: usize,
    const R: usize,
    M: Regressors<S, A, R>,
    C: Controller<P, S, A>,
    Sh: Shaper,
>(
    model: &RlsModel<S, A, R>,
    map: &M,
    start: &Vector<S>,
    ticks: u32,
    dt: f32,
    controller: &mut C,
    theta: &Vector<P>,
    shaper: &mut Sh,
    observation: impl Fn(&Vector<S>) -> Sh::Observation,
) -> Result<Imagined<S>, Error> {
    controller.reset();
    shaper.reset();
    continue_episode::<P, S, A, R, M, C, Sh, true>(
        model,
        map,
        start,
        0,
        ticks,
        dt,
        controller,
        theta,
        u32::MAX,
        shaper,
        observation,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{CorrectedPd, IdentityFeatures, LinearPolicy, Pd};
    use crate::cost::QuadraticCost;
    use crate::model::{Affine, ModelConfig};

    #[test]
    fn a_diverging_model_is_an_error_not_a_cost() {
        let mut model = RlsModel::<1, 1, 3>::try_new(ModelConfig::DEFAULT).unwrap();
        // x' = 3 x: the rollout grows past f32::MAX.
        let mut x = Vector::<1>::new(1.0);
        for k in 0..50 {
            let u = Vector::<1>::new((k % 3) as f32);
            let next = x * 3.0 + u * 0.01;
            model.update(&Affine, &x, &u, &next).unwrap();
            x = Vector::<1>::new(((k % 5) as f32) - 2.0);
        }
        let end = rollout(&model, &Affine, &Vector::<1>::new(1.0), 200, |_, _| {
            Vector::<1>::zeros()
        });
        assert_eq!(end, Err(Error::NonFinite("prediction")));
        let start = Vector::<1>::new(f32::NAN);
        assert_eq!(
            rollout(&model, &Affine, &start, 1, |_, _| Vector::<1>::zeros()),
            Err(Error::NonFinite("start"))
        );
    }

    #[test]
    fn a_handover_at_the_ends_is_the_bare_or_the_candidates_episode() {
        // Any fitted model will do: the identities are exact.
        let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT).unwrap();
        let mut x = Vector::<2>::new(1.0, 0.0);
        for k in 0..200u32 {
            let u = Vector::<1>::new((k.wrapping_mul(7919) % 13) as f32 / 6.0 - 1.0);
            let next = Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
            model.update(&Affine, &x, &u, &next).unwrap();
            x = next;
        }
        let pd = Pd::try_new(Vector::<1>::new(1.0), Vector::<1>::new(1.0)).unwrap();
        let policy = LinearPolicy::try_new(IdentityFeatures, Vector::<1>::new(2.0)).unwrap();
        let mut controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
        let mut shaper = QuadraticCost::try_new(Vector::<1>::new(1.0)).unwrap();
        let start = Vector::<2>::new(1.0, 0.0);
        let theta = Vector::<2>::new(0.7, -0.3);
        let obs = |x: &Vector<2>| Vector::<1>::new(x[0]);
        let mut episode = |theta: &Vector<2>| {
            imagine_episode(
                &model,
                &Affine,
                &start,
                60,
                0.1,
                &mut controller,
                theta,
                &mut shaper,
                obs,
            )
            .unwrap()
        };
        let (bare, candidate) = (episode(&Vector::zeros()), episode(&theta));
        controller.reset();
        shaper.reset();
        let handover = |candidate_ticks| {
            imagine_handover(
                &model,
                &Affine,
                &start,
                0,
                60,
                0.1,
                controller,
                &theta,
                candidate_ticks,
                shaper,
                obs,
            )
            .unwrap()
        };
        assert_eq!(handover(0), bare);
        assert_eq!(handover(60), candidate);
        assert_eq!(handover(u32::MAX), candidate);
        // Past the episode's end nothing is left to run: the shaper's cost as it is.
        assert_eq!(
            imagine_handover(
                &model, &Affine, &start, 60, 60, 0.1, controller, &theta, 3, shaper, obs
            ),
            Err(Error::NonFinite("cost"))
        );
    }

    #[test]
    fn the_variance_variant_sums_the_leverage_and_keeps_the_cost() {
        let plant =
            |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
        let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT).unwrap();
        let mut x = Vector::<2>::new(1.0, 0.0);
        for k in 0..300u32 {
            let u = Vector::<1>::new((k.wrapping_mul(7919) % 13) as f32 / 60.0 - 0.1);
            let noise = (k.wrapping_mul(104_729) % 17) as f32 / 1700.0 - 0.005;
            let next = plant(&x, &u) + Vector::<2>::new(noise, noise);
            model.update(&Affine, &x, &u, &next).unwrap();
            x = if k % 50 == 49 {
                Vector::<2>::new(1.0, 0.0)
            } else {
                next
            };
        }
        let pd = Pd::try_new(Vector::<1>::new(0.2), Vector::<1>::new(0.5)).unwrap();
        let policy = LinearPolicy::try_new(IdentityFeatures, Vector::<1>::new(10.0)).unwrap();
        let mut controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
        let mut shaper = QuadraticCost::try_new(Vector::<1>::new(1.0)).unwrap();
        let start = Vector::<2>::new(1.0, 0.0);
        let mut deviations = [0.0f32; 3];
        for (i, t) in [[0.0, 0.0], [0.3, 0.0], [2.0, -2.0]].iter().enumerate() {
            let theta = Vector::<2>::new(t[0], t[1]);
            let observe = |x: &Vector<2>| Vector::<1>::new(x[0]);
            let cost = imagine_episode(
                &model,
                &Affine,
                &start,
                60,
                0.1,
                &mut controller,
                &theta,
                &mut shaper,
                observe,
            )
            .unwrap();
            let with = imagine_episode_with_variance(
                &model,
                &Affine,
                &start,
                60,
                0.1,
                &mut controller,
                &theta,
                &mut shaper,
                observe,
            )
            .unwrap();
            // The same episode, bit for bit; the leverage summed by hand along it.
            assert_eq!(with.cost.to_bits(), cost.to_bits());
            let mut sum = 0.0f32;
            controller.reset();
            rollout(&model, &Affine, &start, 60, |k, x| {
                let u = controller.corrected(&theta, x, k as f32 * 0.1);
                sum += model.leverage(&Affine, x, &u);
                u
            })
            .unwrap();
            assert_eq!(with.leverage, sum);
            assert_eq!(with.variance, model.residual_variance() * sum);
            deviations[i] = with.deviation();
        }
        // Larger corrections drive the model further from its ticks.
        assert!(
            deviations[0] < deviations[1] && deviations[1] < deviations[2],
            "{deviations:?}"
        );
    }

    #[test]
    fn the_imagined_cost_ranks_like_the_plant() {
        // A double integrator with a PD; θ scales the correction on [e, v].
        let plant =
            |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
        let mut model = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT).unwrap();
        let mut x = Vector::<2>::new(1.0, 0.0);
        for k in 0..400u32 {
            let u = Vector::<1>::new((k.wrapping_mul(7919) % 13) as f32 / 6.0 - 1.0);
            let next = plant(&x, &u);
            model.update(&Affine, &x, &u, &next).unwrap();
            x = if k % 50 == 49 {
                Vector::<2>::new(1.0, 0.0)
            } else {
                next
            };
        }
        let pd = Pd::try_new(Vector::<1>::new(1.0), Vector::<1>::new(1.0)).unwrap();
        let policy = LinearPolicy::try_new(IdentityFeatures, Vector::<1>::new(2.0)).unwrap();
        let mut controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
        let mut shaper = QuadraticCost::try_new(Vector::<1>::new(1.0)).unwrap();
        let start = Vector::<2>::new(1.0, 0.0);
        let thetas = [[-0.5, 0.0], [0.0, 0.0], [0.5, 0.5], [1.0, 1.0], [0.5, -0.5]];
        let mut imagined = [0.0f32; 5];
        let mut real = [0.0f32; 5];
        for (i, t) in thetas.iter().enumerate() {
            let theta = Vector::<2>::new(t[0], t[1]);
            imagined[i] = imagine_episode(
                &model,
                &Affine,
                &start,
                80,
                0.1,
                &mut controller,
                &theta,
                &mut shaper,
                |x| Vector::<1>::new(x[0]),
            )
            .unwrap();
            shaper.reset();
            let mut x = start;
            for k in 0..80 {
                let u = controller.corrected(&theta, &x, k as f32 * 0.1);
                shaper.observe(&Vector::<1>::new(x[0]), 0.1);
                x = plant(&x, &u);
            }
            real[i] = shaper.cost();
        }
        for i in 0..5 {
            assert!(
                (imagined[i] - real[i]).abs() <= 1e-2 * real[i],
                "{imagined:?} {real:?}"
            );
        }
    }
}
