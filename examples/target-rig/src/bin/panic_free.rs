//! Panic-freedom probe. Exercises, on inputs the optimiser cannot see through (`black_box`,
//! an RNG, NaN and infinite costs and states):
//!
//! * every optimizer's `ask`/`tell` and accessors at N = 18: `CoordinateSearch` (both
//!   constructors), `Sracos` (every replacement strategy, with and without value
//!   suppression), `Racos`, `DiagonalCem` (every weighting, fixed and adapted covariance),
//!   `ControlledRandomSearch`, `TwoPhase`, `Rockstar` (memory 90 = 5n), `Cmaes` (λ = 12,
//!   active weights, a decomposition every generation), `LineBo` (64 episodes remembered,
//!   with and without a threshold, coordinate and random lines, run past its capacity so
//!   the eviction runs); and `Bounds`,
//!   `unit_f32`, `normal_pair_f32`;
//! * the controller layer: `Pd` (output, update, limits), `LinearPolicy`, `CorrectedPd`, and
//!   the AUV `Adapter`'s whole API (`begin_episode`, `control` on finite and non-finite
//!   states, `end_episode`, `abort_episode`, `set_mode` in every mode, the accessors), with
//!   the survey reward;
//! * the plant model and the model-based learner: `RlsModel<6, 3, 14>` with features of its
//!   own (`update` with wild ticks, `predict`, `episode_error`, `validate`), fed by the AUV
//!   adapter (`Adapter::with_model`, `OnlineModel`), `imagine_episode` with the AUV
//!   controller and the survey cost (and `imagine_episode_with_variance`, the model's
//!   `predictive_variance` and `predict_with_leverage`), and
//!   `ModelBased<CoordinateSearch<18>, 18>` (`propose` and `propose_bounded` with an
//!   uncertainty weight, with an inner `Cmaes<18, 12>` and predictions that are sometimes
//!   NaN or errors,
//!   `tell` and `record` with wild costs, restarting its trust region after 3 stalled
//!   proposals, `set_reference`, the accessors);
//! * the PIL firmware's path: frame decoding of arbitrary bytes, frame encoding, reading and
//!   writing over an embedded-io port, the session and the AUV learner (`AuvLearner` with
//!   `CoordinateSearch<18>`, with `Sracos<18>` and with `LineBo<18, 64>`),
//!
//! so that every panic path inside them stays in the binary if it exists.
//!
//! Built with `--release --features panic-free` (see `scripts/panic-check`), the panic
//! handler references an undefined symbol: this binary links only if no panic is reachable
//! from any of these calls. Without the feature it runs under QEMU like the others.
#![no_std]
#![no_main]

use core::hint::black_box;

use auv_survey::{self as auv, AuvLearner};
use ctrl_adapt::controller::{
    Controller as _, CorrectedPd, Derivative, LinearPolicy, Mode, Pd, StateFeatures,
};
use ctrl_adapt::cost::{Shaper, SurveyCost};
use ctrl_adapt::model::{
    AffineWith, ModelBased, ModelBasedConfig, ModelConfig, OnlineModel, Prediction, RlsModel,
    imagine_episode, imagine_episode_with_variance,
};
use ctrl_adapt::optimizer::{normal_pair_f32, unit_f32};
use ctrl_adapt::{
    Bounds, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
    CoordinateSearch, CrsConfig, DiagonalCem, LineBo, LineBoConfig, LineDirections, Optimizer,
    Racos, Replacement, Rockstar, RockstarConfig, Sracos, SracosConfig, Status, Suppression,
    TwoPhase, Vector, Weighting,
};
use ctrl_adapt_firmware::{exit_failure, exit_success};
use pil_link::{
    Frame, FrameReader, Kind, Learner, LinkError, MAX_WIRE, Session, read_frame, write_frame,
};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = 18;

type Rng = Xoshiro128PlusPlus;

#[cortex_m_rt::entry]
fn main() -> ! {
    let mut rng = Rng::seed_from_u64(black_box(7));
    let lower = Vector::<N>::from_fn(|_, _| black_box(-2.0) * (1.0 + unit_f32(&mut rng)));
    let upper = Vector::<N>::from_fn(|_, _| black_box(2.0) * (1.0 + unit_f32(&mut rng)));
    let Ok(bounds) = Bounds::try_new(lower, upper) else {
        exit_failure()
    };
    let mut told = coordinate_search(&mut rng, bounds);
    told += other_optimizers(&mut rng, bounds);
    if !controller_layer(&mut rng) {
        exit_failure()
    }
    if !model_layer(&mut rng, bounds) {
        exit_failure()
    }
    if !pil_session(&mut rng) {
        exit_failure()
    }
    if black_box(told) > 0 {
        exit_success()
    } else {
        exit_failure()
    }
}

/// A cost from anywhere in f32 one time in eight (NaN, infinities, subnormals), else the
/// squared norm of θ.
fn wild_cost(rng: &mut Rng, theta: &Vector<N>) -> f32 {
    match rng.next_u32() % 8 {
        0 => f32::from_bits(rng.next_u32()),
        _ => theta.iter().map(|t| t * t).sum::<f32>(),
    }
}

/// Asks and tells `optimizer` until it stops or `budget` costs were accepted, with wild
/// costs and the whole read-only API; returns the accepted costs. Never inlined: one copy
/// per optimizer type, each kept whole.
#[inline(never)]
fn drive<O: Optimizer<N>>(optimizer: &mut O, rng: &mut Rng, budget: u32) -> u32 {
    let mut told = 0u32;
    while optimizer.status() == Status::Running && told < budget {
        let Ok(theta) = optimizer.ask(rng) else {
            break;
        };
        let bounds = optimizer.bounds();
        let ok = bounds.check(&bounds.clamp(&theta), "theta").is_ok() && bounds.contains(&theta);
        black_box(ok);
        if optimizer.tell(wild_cost(rng, &theta)).is_ok() {
            told += 1;
        }
        black_box((
            optimizer.best(),
            optimizer.pending(),
            optimizer.evaluations(),
        ));
    }
    // A tell without a pending ask.
    black_box(optimizer.tell(black_box(1.0)).is_err());
    told
}

/// The coordinate search's whole public API, both constructors.
fn coordinate_search(rng: &mut Rng, bounds: Bounds<N>) -> u32 {
    let config = CoordinateConfig {
        initial_step: black_box(0.5),
        contraction: black_box(0.5),
        expansion: black_box(2.0),
        sufficient_decrease: black_box(1e-6),
        tolerance: black_box(1e-5),
        max_evaluations: black_box(5_000),
    };
    let start = bounds.sample_uniform(rng);
    let steps = Vector::<N>::from_fn(|_, _| black_box(0.25) + unit_f32(rng));
    let searches = [
        CoordinateSearch::try_new(bounds, start, config),
        CoordinateSearch::try_with_steps(bounds, start, steps, config),
    ];
    let mut told = 0;
    for search in searches {
        let Ok(mut search) = search else {
            exit_failure()
        };
        told += drive(&mut search, rng, u32::MAX);
        black_box((search.steps(), search.iterations(), search.config()));
    }
    told
}

/// SRACOS, RACOS, the diagonal CEM, CRS and the two-phase search, with configurations the
/// compiler cannot see.
fn other_optimizers(rng: &mut Rng, bounds: Bounds<N>) -> u32 {
    let mut told = 0;
    for replacement in [
        Replacement::Worst,
        Replacement::Random,
        Replacement::LargestMargin,
    ] {
        let suppression = rng.next_u32().is_multiple_of(2).then_some(Suppression {
            non_update_allowed: black_box(5),
            resample_times: black_box(2),
            balance_rate: black_box(0.5),
        });
        let config = SracosConfig {
            exploration_rate: black_box(0.01),
            uncertain_bits: black_box(Some(2)),
            replacement: black_box(replacement),
            suppression,
            max_evaluations: black_box(300),
        };
        let Ok(mut s) = Sracos::<N>::try_new(bounds, config) else {
            exit_failure()
        };
        told += drive(&mut s, rng, u32::MAX);
        black_box((s.positives(), s.negatives(), s.is_resampling()));
        black_box((s.uncertain_bits(), s.config()));
    }
    let racos = SracosConfig {
        exploration_rate: black_box(0.01),
        uncertain_bits: black_box(None),
        replacement: black_box(Replacement::Worst),
        suppression: black_box(None),
        max_evaluations: black_box(300),
    };
    let Ok(mut r) = Racos::<N>::try_new(bounds, racos) else {
        exit_failure()
    };
    told += drive(&mut r, rng, u32::MAX);
    black_box((r.positives(), r.negatives(), r.uncertain_bits(), r.config()));
    for weighting in [
        Weighting::Cem,
        Weighting::CmaEs,
        Weighting::PiBb { h: black_box(10.0) },
    ] {
        let config = CemConfig {
            weighting,
            elite: black_box(Some(3)),
            initial_variance: black_box(0.1),
            adapt_covariance: black_box(!rng.next_u32().is_multiple_of(4)),
            learning_rate: black_box(0.7),
            exploration_floor: black_box(1e-6),
            min_variance: black_box(0.0),
            max_variance: black_box(4.0),
            first_is_mean: black_box(true),
            tolerance: black_box(0.0),
            max_evaluations: black_box(300),
        };
        let mean = bounds.sample_uniform(rng);
        let variances = Vector::<N>::from_fn(|_, _| black_box(0.01) + unit_f32(rng));
        let cems = [
            DiagonalCem::<N, 10, 5>::try_new(bounds, mean, config),
            DiagonalCem::<N, 10, 5>::try_with_variances(bounds, mean, variances, config),
        ];
        for cem in cems {
            let Ok(mut cem) = cem else { exit_failure() };
            told += drive(&mut cem, rng, u32::MAX);
            black_box((
                cem.mean(),
                cem.variances(),
                cem.updates(),
                cem.told_in_batch(),
            ));
            black_box(cem.config());
        }
    }
    let crs = CrsConfig {
        tolerance: black_box(1e-6),
        max_evaluations: black_box(400),
        max_redraws: black_box(64),
    };
    let Ok(mut c) = ControlledRandomSearch::<N, 40>::try_new(bounds, crs) else {
        exit_failure()
    };
    told += drive(&mut c, rng, u32::MAX);
    black_box((c.set(), c.len(), c.is_empty(), c.config()));
    let Ok(global) = ControlledRandomSearch::<N, 40>::try_new(bounds, crs) else {
        exit_failure()
    };
    let local = CoordinateConfig {
        initial_step: black_box(0.25),
        max_evaluations: black_box(200),
        ..CoordinateConfig::DEFAULT
    };
    let steps = Vector::<N>::from_fn(|_, _| black_box(0.1) + unit_f32(rng));
    let two = [
        TwoPhase::try_new(global.clone(), black_box(100), local),
        TwoPhase::try_with_steps(global, black_box(100), steps, local),
    ];
    for t in two {
        let Ok(mut t) = t else { exit_failure() };
        told += drive(&mut t, rng, black_box(60));
        black_box(t.hand_over().is_ok());
        told += drive(&mut t, rng, u32::MAX);
        black_box((t.phase(), t.global().best(), t.local().map(|l| l.best())));
    }
    told += rockstar(rng, bounds);
    told += cmaes(rng, bounds);
    told += line_bo(rng, bounds);
    black_box(normal_pair_f32(rng));
    told
}

/// CMA-ES (λ = 12, the default at n = 18) with a configuration the compiler cannot see, and
/// its accessors: the eigendecomposition runs at every generation.
fn cmaes(rng: &mut Rng, bounds: Bounds<N>) -> u32 {
    let config = CmaesConfig {
        initial_sigma: black_box(0.3),
        max_sigma: black_box(4.0),
        penalty: black_box(1.0),
        eigen_interval: black_box(1),
        tolerance: black_box(1e-6),
        max_evaluations: black_box(600),
        active: black_box(true),
    };
    let Ok(mut c) = Cmaes::<N, 12>::try_new(bounds, bounds.sample_uniform(rng), config) else {
        exit_failure()
    };
    let told = drive(&mut c, rng, u32::MAX);
    black_box((c.mean(), c.normalised_mean(), c.sigma(), c.covariance()));
    black_box((c.axis_ratio(), c.parents(), c.generations()));
    black_box((c.told_in_generation(), c.recoveries(), c.config()));
    told
}

/// LineBO remembering 64 episodes (the recommendation at n = 18), with and without a
/// threshold, along coordinate and random lines, with configurations the compiler cannot
/// see, for 100 episodes each (past the GP's capacity: the eviction and rank-one update
/// run), and its accessors.
fn line_bo(rng: &mut Rng, bounds: Bounds<N>) -> u32 {
    let mut told = 0;
    for (threshold, directions) in [
        (None, LineDirections::Coordinate),
        (None, LineDirections::Random),
        (Some(black_box(50.0)), LineDirections::Coordinate),
        (Some(black_box(50.0)), LineDirections::Random),
    ] {
        let config = LineBoConfig {
            length_scale: black_box(0.15),
            signal_variance: black_box(100.0),
            noise_variance: black_box(1.0),
            jitter: black_box(1e-4),
            beta: black_box(2.0),
            directions: black_box(directions),
            evaluations_per_line: black_box(3),
            threshold: black_box(threshold),
            max_evaluations: black_box(100),
        };
        let start = bounds.sample_uniform(rng);
        let Ok(mut l) = LineBo::<N, 64>::try_new(bounds, start, config) else {
            exit_failure()
        };
        told += drive(&mut l, rng, u32::MAX);
        let probe = Vector::<N>::from_fn(|_, _| black_box(f32::from_bits(rng.next_u32())));
        black_box((l.upper_bound(&probe), l.upper_bound(&start)));
        black_box((l.remembered(), l.config()));
    }
    told
}

/// ROCK* with a configuration the compiler cannot see, and its accessors.
fn rockstar(rng: &mut Rng, bounds: Bounds<N>) -> u32 {
    let config = RockstarConfig {
        initial_sigma: black_box(0.2),
        lambda: black_box(0.3),
        initial_samples: black_box(3),
        step_gain: black_box(0.5),
        descent_iterations: black_box(40),
        tolerance: black_box(1e-6),
        max_evaluations: black_box(300),
        ..RockstarConfig::DEFAULT
    };
    let Ok(mut r) = Rockstar::<N, 90>::try_new(bounds, bounds.sample_uniform(rng), config) else {
        exit_failure()
    };
    let told = drive(&mut r, rng, u32::MAX);
    black_box((
        r.theta_star(),
        r.normalised_theta_star(),
        r.estimated_cost(),
    ));
    black_box((r.sigma(), r.shape(), r.kernel_factor(), r.remembered()));
    black_box((
        r.updates(),
        r.covariance_updates(),
        r.recoveries(),
        r.config(),
    ));
    for (theta, cost) in r.memory() {
        black_box((theta, cost));
    }
    told
}

/// A state: finite in range, or from anywhere in f32 (NaN, infinities) one time in four.
fn wild_state<const S: usize>(rng: &mut Rng) -> Vector<S> {
    Vector::from_fn(|_, _| match rng.next_u32() % 4 {
        0 => f32::from_bits(rng.next_u32()),
        _ => 12.0 * unit_f32(rng) - 6.0,
    })
}

/// The PD, the policy and the AUV adapter's whole API.
fn controller_layer(rng: &mut Rng) -> bool {
    let gains = |rng: &mut Rng| Vector::<3>::from_fn(|_, _| black_box(0.1) + unit_f32(rng));
    let Ok(pd) = Pd::try_new(gains(rng), gains(rng)) else {
        return false;
    };
    let Ok(pd) = pd.with_limit(gains(rng)) else {
        return false;
    };
    let mut pd_fd = pd.with_derivative(black_box(Derivative::OnError));
    let scale = Vector::<6>::from_fn(|_, _| black_box(0.5) + unit_f32(rng));
    let (Ok(features), Ok(policy)) = (
        StateFeatures::scaled(scale),
        LinearPolicy::<3, 6, StateFeatures<6>>::try_new(StateFeatures::identity(), gains(rng)),
    ) else {
        return false;
    };
    let scaled = LinearPolicy::<3, 6, _>::try_new(features, gains(rng));
    let Ok(scaled) = scaled else { return false };
    let mut corrected = CorrectedPd::<3, 6, 6, 18, _>::new(pd, scaled);
    for _ in 0..500 {
        let theta = wild_state::<18>(rng);
        let x = wild_state::<6>(rng);
        let e = Vector::<3>::new(x[0], x[1], x[2]);
        let v = Vector::<3>::new(x[3], x[4], x[5]);
        black_box(pd.output(&e, &v));
        black_box(pd_fd.update(&e, &v, black_box(0.1)));
        black_box(policy.correction(&theta, &x, 0.0));
        black_box(corrected.nominal(&x, 0.0));
        black_box(corrected.corrected(&theta, &x, 0.0));
    }
    pd_fd.reset();
    black_box((
        pd.kp(),
        pd.kd(),
        pd.limit(),
        policy.envelope(),
        policy.map(),
    ));

    // The AUV adapter: learning, deploying and nominal episodes, some aborted, with finite,
    // NaN and infinite states and observations.
    let Ok(search) = auv::coordinate_search(black_box(400)) else {
        return false;
    };
    let Ok(mut adapter) = auv::adapter(search, black_box(60)) else {
        return false;
    };
    for episode in 0..80u32 {
        let mode = match rng.next_u32() % 8 {
            0 => Mode::Deploy,
            1 => Mode::Nominal,
            _ => Mode::Learn,
        };
        black_box(adapter.set_mode(mode).is_ok());
        let started = adapter.begin_episode(rng).is_ok();
        black_box(adapter.begin_episode(rng).is_err());
        black_box(started);
        for _ in 0..(rng.next_u32() % 40) {
            let x = wild_state::<6>(rng);
            let error = Vector::<3>::new(x[0], x[1], x[2]);
            black_box(adapter.control(&x, &error));
        }
        let report = if episode % 7 == 3 {
            adapter.abort_episode()
        } else {
            adapter.end_episode()
        };
        black_box(report.is_ok());
        black_box(adapter.end_episode().is_err());
        black_box((adapter.mode(), adapter.deployed_theta()));
        black_box((adapter.learning_episodes(), adapter.in_episode()));
        black_box((adapter.optimizer().best(), adapter.config()));
        let shaper = adapter.shaper();
        black_box((shaper.cost(), shaper.skipped(), shaper.min_distance()));
        black_box((shaper.time_within(), shaper.reward()));
    }
    // Outside an episode `control` runs the nominal law.
    black_box(adapter.control(&wild_state::<6>(rng), &Vector::zeros()));
    let Ok(mut survey) = SurveyCost::try_new(black_box(1.0)) else {
        return false;
    };
    survey.observe(&wild_state::<3>(rng), black_box(0.1));
    survey.reset();
    black_box(survey.cost());
    true
}

/// The plant model, fed by the AUV adapter and directly with wild ticks, imagined episodes,
/// and the model-based learner with wild predictions and costs.
fn model_layer(rng: &mut Rng, bounds: Bounds<N>) -> bool {
    let config = ModelConfig {
        forgetting: black_box(0.999),
        ..ModelConfig::DEFAULT
    };
    let Ok(model) = RlsModel::<6, 3, 14>::try_new(config) else {
        return false;
    };
    let features = AffineWith::new(|x: &Vector<6>, _: &Vector<3>| {
        Vector::<4>::new(
            x[2],
            libm::fabsf(x[3]) * x[3],
            libm::fabsf(x[4]) * x[4],
            libm::fabsf(x[5]) * x[5],
        )
    });
    let Ok(search) = auv::coordinate_search(black_box(400)) else {
        return false;
    };
    let Ok(adapter) = auv::adapter(search, black_box(60)) else {
        return false;
    };
    let Ok(mut adapter) = adapter.with_model(OnlineModel::new(model, features)) else {
        return false;
    };
    for _ in 0..12u32 {
        black_box(adapter.begin_episode(rng).is_ok());
        for _ in 0..(rng.next_u32() % 60) {
            let x = wild_state::<6>(rng);
            black_box(adapter.control(&x, &Vector::<3>::new(x[0], x[1], x[2])));
        }
        black_box(adapter.end_episode().is_ok());
    }
    let fed = *adapter.model();
    black_box((fed.refused(), fed.start(), fed.model().ticks()));
    if let Ok(m) = adapter.model_mut() {
        m.model_mut().reset();
    }
    let mut model = *fed.model();
    for _ in 0..200 {
        let (x, u, next) = (
            wild_state::<6>(rng),
            wild_state::<3>(rng),
            wild_state::<6>(rng),
        );
        black_box(model.update(&features, &x, &u, &next).is_ok());
        black_box(model.predict(&features, &x, &u));
        black_box(model.predictive_variance(&features, &x, &u));
        black_box(model.predict_with_leverage(&features, &x, &u));
    }
    black_box((model.one_step_error(), model.validate().is_ok()));
    black_box((
        model.weights()[(0, 0)],
        model.covariance()[(1, 1)],
        model.config(),
    ));
    let states: [Vector<6>; 9] = core::array::from_fn(|_| wild_state::<6>(rng));
    let commands: [Vector<3>; 8] = core::array::from_fn(|_| wild_state::<3>(rng));
    black_box(model.episode_error(&features, &states, &commands).is_ok());
    black_box(
        model
            .episode_error(&features, &states[..3], &commands)
            .is_ok(),
    );

    let Ok(fallback) = CoordinateSearch::try_new(
        bounds,
        bounds.sample_uniform(rng),
        CoordinateConfig::DEFAULT,
    ) else {
        return false;
    };
    let config = ModelBasedConfig {
        inner_evaluations: black_box(24),
        margin: black_box(0.5),
        uncertainty_weight: black_box(0.5),
        restart_after: black_box(3),
        ..ModelBasedConfig::DEFAULT
    };
    let Ok(mut learner) = ModelBased::try_new(bounds, fallback, config) else {
        return false;
    };
    black_box(
        learner
            .record(bounds.sample_uniform(rng), wild_cost(rng, &Vector::zeros()))
            .is_ok(),
    );
    black_box(
        learner
            .set_reference(wild_cost(rng, &Vector::zeros()))
            .is_ok(),
    );
    let inner = |trust: Bounds<N>, centre: Vector<N>| {
        let config = CmaesConfig {
            max_evaluations: black_box(24),
            ..CmaesConfig::DEFAULT
        };
        Cmaes::<N, 12>::try_new(trust, centre, config)
    };
    let (mut controller, mut shaper) = (*adapter.controller(), *adapter.shaper());
    let mut draws = Rng::seed_from_u64(black_box(9));
    let ticks = black_box(12);
    for round in 0..16 {
        let proposal = if black_box(round % 2 == 0) {
            let predict = |theta: &Vector<N>| match draws.next_u32() % 4 {
                0 => Ok(f32::from_bits(draws.next_u32())),
                1 => Err(ctrl_adapt::Error::NonFinite("prediction")),
                _ => imagine_episode(
                    &model,
                    &features,
                    &wild_state::<6>(&mut draws),
                    ticks,
                    black_box(0.1),
                    &mut controller,
                    theta,
                    &mut shaper,
                    |x| Vector::<3>::new(x[0], x[1], x[2]),
                ),
            };
            learner.propose(rng, inner, predict)
        } else {
            let bounded = |theta: &Vector<N>| match draws.next_u32() % 4 {
                0 => Ok(Prediction {
                    cost: f32::from_bits(draws.next_u32()),
                    uncertainty: f32::from_bits(draws.next_u32()),
                }),
                1 => Err(ctrl_adapt::Error::NonFinite("prediction")),
                _ => imagine_episode_with_variance(
                    &model,
                    &features,
                    &wild_state::<6>(&mut draws),
                    ticks,
                    black_box(0.1),
                    &mut controller,
                    theta,
                    &mut shaper,
                    |x| Vector::<3>::new(x[0], x[1], x[2]),
                )
                .map(|i| Prediction {
                    cost: i.cost,
                    uncertainty: i.deviation(),
                }),
            };
            learner.propose_bounded(rng, inner, bounded)
        };
        black_box(proposal.is_ok());
        let theta = proposal.map_or(Vector::zeros(), |p| p.theta);
        black_box(learner.record(theta, 1.0).is_err());
        black_box(learner.tell(wild_cost(rng, &theta)).is_ok());
        black_box((learner.best(), learner.pending(), learner.radius()));
        black_box((
            learner.evaluations(),
            learner.stalled(),
            learner.restarts(),
            learner.fallback().best(),
            learner.config(),
        ));
    }
    true
}

/// The PIL firmware's path: random episodes of valid frames interleaved with arbitrary
/// bytes, through the reader, the session, the AUV learner and a byte-slice port, with
/// `CoordinateSearch<18>` (the `pil` firmware), `Sracos<18>` (`pil_sracos`) and
/// `LineBo<18, 64>` (`pil_line_bo`).
fn pil_session(rng: &mut Rng) -> bool {
    let coordinate = auv::coordinate_search(black_box(u32::MAX))
        .and_then(|o| AuvLearner::try_new(o, black_box(u32::MAX), auv::SEED));
    let sracos = auv::sracos(black_box(u32::MAX))
        .and_then(|o| AuvLearner::try_new(o, black_box(u32::MAX), auv::SEED));
    let line_bo = auv::line_bo(black_box(u32::MAX))
        .and_then(|o| AuvLearner::try_new(o, black_box(u32::MAX), auv::SEED));
    let (Ok(coordinate), Ok(sracos), Ok(line_bo)) = (coordinate, sracos, line_bo) else {
        return false;
    };
    let a = session(rng, coordinate);
    let b = session(rng, sracos);
    let c = session(rng, line_bo);
    a && b && c
}

#[inline(never)]
fn session<C: Learner>(rng: &mut Rng, controller: C) -> bool {
    let mut session = Session::new(controller);
    let mut reader = FrameReader::new();
    let mut answers = 0u32;
    for step in 0..2_000u32 {
        let episode = (step / 100) as u16;
        let kind = match rng.next_u32() % 16 {
            0 => Kind::Start,
            1 => Kind::End,
            2 => Kind::Shutdown,
            _ => Kind::State,
        };
        let mut values = [0.0f32; 7];
        for v in values.iter_mut() {
            *v = match rng.next_u32() % 4 {
                0 => f32::from_bits(rng.next_u32()),
                1 => (rng.next_u32() % 3) as f32, // a mode code in a Start frame
                _ => 12.0 * unit_f32(rng) - 6.0,
            };
        }
        let count = (rng.next_u32() % 8) as usize;
        let frame = Frame::new(kind, episode, (step % 100) as u16)
            .with_values(values.get(..count).unwrap_or(&[]));
        // Encode into a port, then read it back, maybe with arbitrary bytes in between.
        let mut wire = [0u8; 2 * MAX_WIRE];
        let mut port: &mut [u8] = &mut wire;
        if write_frame(&mut port, &frame).is_err() {
            return false;
        }
        if rng.next_u32().is_multiple_of(4) {
            for byte in wire.iter_mut().take(MAX_WIRE) {
                *byte = rng.next_u32() as u8;
            }
        }
        let mut input: &[u8] = &wire;
        let reply = match read_frame(&mut input, &mut reader, || true) {
            Ok(f) => session.on_frame(&f),
            Err(LinkError::Timeout) => session.on_timeout(),
            Err(LinkError::Corrupt(_)) => {
                session.on_corrupt();
                None
            }
            Err(LinkError::Io(e)) => match e {},
        };
        if let Some(reply) = reply {
            answers += 1;
            let mut out = [0u8; MAX_WIRE];
            let mut out_port: &mut [u8] = &mut out;
            let _ = write_frame(&mut out_port, &reply);
            black_box(&out);
        }
        black_box((session.awaiting_tick(), session.finished(), session.stats()));
    }
    answers > 0
}
