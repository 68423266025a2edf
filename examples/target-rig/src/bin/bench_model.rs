//! Footprint benchmark of the model-based learner at the AUV's size (N = 18 parameters,
//! state 6, command 3): the plant model `RlsModel<6, 3, 14>` (the affine regressors and the
//! four features of `experiments/examples/model_learner_auv.rs`: a depth-layer indicator and
//! |v|·v per axis), fed by the AUV adapter from every tick (`Adapter::with_model`), and
//! `ModelBased<CoordinateSearch<18>, 18>` with the recommended inner search, `Cmaes<18, 12>`
//! (σ₀ 0.5 of the trust box) for 240 imagined episodes of 240 ticks per proposal.
//!
//! The ticks come from a stand-in plant (a velocity-commanded vehicle with a first-order
//! response, quadratic drag and a constant current, not the host's AUV simulation): the
//! instruction counts depend on the sizes, not on the plant, as long as every imagined
//! episode runs its 240 ticks. A rollout that diverges ends early (and would count fewer
//! instructions), so the firmware counts the predictions that failed and fails if any did.
//!
//! Counted by SysTick under QEMU's `-icount shift=0`
//! ([`ctrl_adapt_firmware::bench::icount`], exact to ±40 instructions), logged as
//! `footprint: sample SECTION = COUNT` for `scripts/footprint`:
//! * `model_control`: one control tick of the adapter feeding the model (the fit included);
//! * `imagined_episode`: one `imagine_episode` of 240 ticks with the AUV controller and the
//!   survey cost;
//! * `imagined_episode_variance`: the same episode by `imagine_episode_with_variance`, which
//!   also sums the model's leverage zᵀPz along it (what `ModelBased::propose_bounded` with
//!   an `uncertainty_weight` pays per imagined episode);
//! * `model_propose`: one `ModelBased::propose` with the recommended budget (240 imagined
//!   episodes, the CMA-ES's asks and tells, the screen's prediction of the best real θ):
//!   the whole between-episode update.
//!
//! It also logs the `size_of` of the model, the fed model, the learner, the inner CMA-ES and
//! the adapter with the model, and the peak stack.
#![no_std]
#![no_main]

use auv_survey as auv;
use ctrl_adapt::controller::{Adapter, Unguarded};
use ctrl_adapt::cost::SurveyCost;
use ctrl_adapt::model::{
    ModelBased, ModelBasedConfig, ModelConfig, OnlineModel, Regressors, RlsModel, Source,
    imagine_episode, imagine_episode_with_variance,
};
use ctrl_adapt::optimizer::unit_f32;
use ctrl_adapt::{Bounds, Cmaes, CmaesConfig, CoordinateSearch, Error, Vector};
use ctrl_adapt_firmware::bench::icount::Counter;
use ctrl_adapt_firmware::{exit_failure, exit_success, log_size, stack};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const P: usize = auv::P;
const S: usize = auv::S;
const A: usize = auv::A;
/// The regressors: the state, the command, a constant and four features.
const R: usize = S + A + 1 + 4;
/// Ticks of an episode, real or imagined.
const TICKS: u32 = auv::TICKS as u32;
/// Imagined episodes per proposal: the recommended budget.
const INNER_EVALUATIONS: u32 = 240;
/// Real episodes run before the learner proposes: the bare controller and two small
/// exploration episodes (the model needs them to be identifiable).
const EXPLORATIONS: u32 = 2;
/// Proposals measured.
const PROPOSALS: u32 = 3;

/// z = [x, u, 1, depth layer, |v|·v per axis] (velocities clipped at 0.6 m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
struct AuvFeatures;

impl Regressors<S, A, R> for AuvFeatures {
    fn regressors(&self, x: &Vector<S>, u: &Vector<A>) -> Vector<R> {
        let drag = |v: f32| {
            let v = v.clamp(-0.6, 0.6);
            v.abs() * v
        };
        // x[2] is the depth error: 1 while the vehicle is more than 2 m above the target.
        let layer = if x[2] > 2.0 { 1.0 } else { 0.0 };
        // Written out: `Vector::from_fn` with a `match` on the index stays a loop at
        // opt-level "s" (about 230 instructions per imagined tick); this is inlined.
        Vector::from([
            x[0],
            x[1],
            x[2],
            x[3],
            x[4],
            x[5],
            u[0],
            u[1],
            u[2],
            1.0,
            layer,
            drag(x[3]),
            drag(x[4]),
            drag(x[5]),
        ])
    }
}

type Fed = OnlineModel<AuvFeatures, S, A, R>;
type ModelAdapter =
    Adapter<CoordinateSearch<P>, auv::AuvController, SurveyCost, P, S, A, Unguarded, Fed>;
type Learner = ModelBased<CoordinateSearch<P>, P>;
type Inner = Cmaes<P, 12>;

/// The stand-in plant: x = [target − position, velocity]; the velocity follows the
/// command with a 0.5 s time constant, quadratic drag and a current.
fn plant(x: &Vector<S>, u: &Vector<A>) -> Vector<S> {
    let dt = auv::DT;
    let current = [0.05, -0.03, 0.0];
    Vector::from_fn(|i, _| {
        if i < 3 {
            x[i] - dt * x[i + 3]
        } else {
            let v = x[i];
            v + dt * (2.0 * (u[i - 3] - v) - 0.3 * libm::fabsf(v) * v + current[i - 3])
        }
    })
}

/// The survey's start: 4 m, −3 m and 2.8 m from the target, at rest.
fn start() -> Vector<S> {
    Vector::from([4.0, -3.0, 2.8, 0.0, 0.0, 0.0])
}

fn observation(x: &Vector<S>) -> Vector<3> {
    Vector::<3>::new(x[0], x[1], x[2])
}

/// The inner search of a proposal: CMA-ES on the trust box from its centre.
fn inner(trust: Bounds<P>, centre: Vector<P>) -> Result<Inner, Error> {
    let config = CmaesConfig {
        initial_sigma: 0.5,
        max_evaluations: INNER_EVALUATIONS,
        ..CmaesConfig::DEFAULT
    };
    Cmaes::try_new(trust, centre, config)
}

/// A regression guard on the peak stack of the whole benchmark (the adapter with its
/// model, the learner, and during a proposal the inner CMA-ES and an imagined episode):
/// `scripts/footprint` reports it against the 16 KB target; this fails only well beyond.
const STACK_BUDGET: usize = 20 * 1024;

#[cortex_m_rt::entry]
fn main() -> ! {
    log_size!("RlsModel<6, 3, 14>", RlsModel<S, A, R>);
    log_size!("OnlineModel<AuvFeatures, 6, 3, 14>", Fed);
    log_size!("ModelBased<CoordinateSearch<18>, 18>", Learner);
    log_size!("Cmaes<18, 12> (the inner search)", Inner);
    log_size!(
        "Adapter with CoordinateSearch<18> and OnlineModel<AuvFeatures, 6, 3, 14>",
        ModelAdapter
    );
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut counter = Counter::new(peripherals.SYST);
    for _ in 0..4 {
        let ((), empty) = counter.measure(|| ());
        defmt::info!("footprint: sample empty = {=u32}", empty);
    }
    if let Err(e) = run(&mut counter) {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    let peak = stack::peak_bytes();
    defmt::info!("footprint: peak stack bench_model = {=u32}", peak);
    if peak as usize > STACK_BUDGET {
        defmt::error!("peak stack {=u32} B exceeds {=usize} B", peak, STACK_BUDGET);
        exit_failure()
    }
    exit_success()
}

/// One real episode of θ on the stand-in plant through the adapter, every tick counted;
/// its survey cost.
fn episode(
    adapter: &mut ModelAdapter,
    counter: &mut Counter,
    theta: Vector<P>,
) -> Result<f32, Error> {
    adapter
        .begin_fixed_episode(theta)
        .map_err(|_| Error::InvalidParameter("episode"))?;
    let mut x = start();
    for _ in 0..TICKS {
        let (u, count) = counter.measure(|| adapter.control(&x, &observation(&x)));
        defmt::info!("footprint: sample model_control = {=u32}", count);
        x = plant(&x, &u);
    }
    let report = adapter
        .end_episode()
        .map_err(|_| Error::InvalidParameter("episode"))?;
    Ok(report.cost)
}

#[inline(never)]
fn run(counter: &mut Counter) -> Result<(), Error> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(auv::SEED);
    let model = RlsModel::<S, A, R>::try_new(ModelConfig::DEFAULT)?;
    let mut adapter = auv::adapter(auv::coordinate_search(1)?, 1)?
        .with_model(OnlineModel::new(model, AuvFeatures))
        .map_err(|_| Error::InvalidParameter("adapter"))?;
    let bounds = auv::bounds()?;
    let bare = episode(&mut adapter, counter, Vector::zeros())?;
    let config = ModelBasedConfig {
        initial_radius: 0.15,
        margin: 0.2 * libm::fabsf(bare),
        inner_evaluations: INNER_EVALUATIONS,
        ..ModelBasedConfig::DEFAULT
    };
    let mut learner = Learner::try_new(bounds, auv::coordinate_search(15)?, config)?;
    learner.record(Vector::zeros(), bare)?;
    learner.set_reference(bare)?;
    for _ in 0..EXPLORATIONS {
        let theta = Vector::<P>::from_fn(|_, _| 0.2 * unit_f32(&mut rng) - 0.1);
        let cost = episode(&mut adapter, counter, theta)?;
        learner.record(theta, cost)?;
    }
    let Some(begin) = adapter.model().start() else {
        return Err(Error::InvalidParameter("start"));
    };
    let mut failed = 0u32;
    for k in 0..8u32 {
        let theta = Vector::<P>::from_fn(|_, _| 0.3 * unit_f32(&mut rng) - 0.15);
        let (mut controller, mut shaper) = (*adapter.controller(), *adapter.shaper());
        let fed = adapter.model();
        let (cost, count) = counter.measure(|| {
            imagine_episode(
                fed.model(),
                fed.map(),
                &begin,
                TICKS,
                auv::DT,
                &mut controller,
                &theta,
                &mut shaper,
                observation,
            )
        });
        failed += u32::from(cost.is_err());
        defmt::info!("footprint: sample imagined_episode = {=u32}", count);
        defmt::info!("imagined episode {=u32}: {=?}", k, cost.ok());
        let (imagined, count) = counter.measure(|| {
            imagine_episode_with_variance(
                fed.model(),
                fed.map(),
                &begin,
                TICKS,
                auv::DT,
                &mut controller,
                &theta,
                &mut shaper,
                observation,
            )
        });
        // The same episode: the same cost, bit for bit.
        failed += u32::from(imagined.map(|i| i.cost).ok() != cost.ok());
        defmt::info!(
            "footprint: sample imagined_episode_variance = {=u32}",
            count
        );
    }
    for _ in 0..PROPOSALS {
        let (mut controller, mut shaper) = (*adapter.controller(), *adapter.shaper());
        let fed = adapter.model();
        let mut predict = |theta: &Vector<P>| {
            let cost = imagine_episode(
                fed.model(),
                fed.map(),
                &begin,
                TICKS,
                auv::DT,
                &mut controller,
                theta,
                &mut shaper,
                observation,
            );
            failed += u32::from(cost.is_err());
            cost
        };
        let (proposal, count) = counter.measure(|| learner.propose(&mut rng, inner, &mut predict));
        let proposal = proposal?;
        defmt::info!("footprint: sample model_propose = {=u32}", count);
        let cost = episode(&mut adapter, counter, proposal.theta)?;
        defmt::info!(
            "proposal from the model: {=bool}, predicted {=?}, real {=f32}",
            matches!(proposal.source, Source::Model(_)),
            match proposal.source {
                Source::Model(c) => Some(c),
                Source::Fallback => None,
            },
            cost
        );
        learner.tell(cost)?;
    }
    defmt::info!(
        "model: {=u32} ticks fitted, one-step RMS error {=?}, {=u32} failed predictions",
        adapter.model().model().ticks(),
        adapter.model().model().one_step_error().as_slice(),
        failed
    );
    if failed > 0 {
        return Err(Error::NonFinite("prediction"));
    }
    Ok(())
}
