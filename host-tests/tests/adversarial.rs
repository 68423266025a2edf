//! The adversarial driver ([`host_tests::adversarial`]) on every optimizer and on the
//! adapter: a million operations each in release, twenty thousand in a debug `cargo test`;
//! `ADVERSARIAL_OPERATIONS` sets another count (CI runs `ADVERSARIAL_OPERATIONS=250000
//! cargo test --release -p host-tests --test adversarial`, `scripts/research adversarial`
//! the million). Each test
//! checks, after every operation, the contract listed in the driver's docs, and prints what
//! it exercised. `a_planted_bug_is_caught` shows the driver failing on an optimizer with a
//! deliberate defect. The `in_flight_*` tests drive the same optimizers wrapped in
//! `InFlight` ([`host_tests::adversarial::drive_in_flight`]): tickets handed out, reported
//! in any order, cancelled and made up, mixed with the sequential calls.
//!
//! The `forged_*` tests run the forged-record sweep ([`host_tests::forgery`]) on every
//! persistent optimizer, on an adapter (also with a guard and a plant model, and with a
//! guard whose failure cost and span sit near the top of f32), on the model-based learner
//! and on a plant model: a record taken mid-run, every byte overwritten in
//! turn (0x00, 0xFF, 0x7F, +1; NaN and ±∞ over every four bytes), the checksum recomputed;
//! what loads runs 1,000 asks and tells (5,000 in release, on records taken at three points
//! of the run) without a panic, a non-finite θ, a θ outside the box or an action outside the
//! envelope. Each prints how many forgeries loaded and why the others were refused.

use ctrl_adapt::controller::{
    Adapter, AdapterConfig, CorrectedPd, LinearPolicy, Pd, StateFeatures,
};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::optimizer::{
    AnyOptimizer, Best, Bounds, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch,
    CoordinateConfig, CoordinateSearch, CrsConfig, DiagonalCem, Error, LineBo, LineBoConfig,
    LineDirections, Optimizer, Phase, Racos, Replacement, Rockstar, RockstarConfig, Sracos,
    SracosConfig, Status, Suppression, TwoPhase, Vector, Weighting,
};
use ctrl_adapt::record::Persistent;
use host_tests::adversarial::{
    ACTION_LIMIT, DriverRng, ENVELOPE, Tally, cap, count, drive, drive_adapter,
    drive_in_conditions, drive_in_flight, field, point_in,
};
use host_tests::forgery::{
    self, ForgedAdapter, ForgedModelBased, ForgedRlsModel, Forgeries, adapter_mid_run, mid_run,
    model_based_mid_run, rls_model_mid_run, run_adapter, run_model_based, run_optimizer,
    run_rls_model,
};
use rand_core::{RngCore, SeedableRng};

/// Operations per optimizer: `ADVERSARIAL_OPERATIONS` if set (a positive integer), else a
/// million in release and twenty thousand in debug builds.
fn operations() -> u64 {
    let default = if cfg!(debug_assertions) {
        20_000
    } else {
        1_000_000
    };
    match std::env::var("ADVERSARIAL_OPERATIONS") {
        Ok(v) => match v.trim().parse::<u64>() {
            Ok(n) if n > 0 => n,
            _ => panic!("ADVERSARIAL_OPERATIONS={v:?}: expected a positive integer"),
        },
        Err(_) => default,
    }
}

const N: usize = 3;

fn report(name: &str, result: Result<Tally, host_tests::adversarial::Violation>) {
    match result {
        Ok(tally) => {
            println!("{name}: {tally}");
            assert!(tally.operations >= operations(), "{name}: ran {tally}");
            assert!(tally.built > 0 && tally.accepted_tells > 0 && tally.refused_calls > 0);
        }
        Err(v) => panic!("{name}: {v}"),
    }
}

fn coordinate(
    rng: &mut DriverRng,
    bounds: Bounds<N>,
    limit: u32,
) -> Result<CoordinateSearch<N>, Error> {
    let d = CoordinateConfig::DEFAULT;
    let config = CoordinateConfig {
        initial_step: field(rng, d.initial_step),
        contraction: field(rng, d.contraction),
        expansion: field(rng, d.expansion),
        sufficient_decrease: field(rng, d.sufficient_decrease),
        tolerance: field(rng, d.tolerance),
        max_evaluations: limit,
    };
    let start = point_in(rng, &bounds);
    CoordinateSearch::try_new(bounds, start, config)
}

fn crs_config(rng: &mut DriverRng, limit: u32) -> CrsConfig {
    let d = CrsConfig::DEFAULT;
    CrsConfig {
        tolerance: field(rng, d.tolerance),
        max_evaluations: limit,
        max_redraws: cap(rng, d.max_redraws),
    }
}

fn sracos_config(rng: &mut DriverRng, limit: u32) -> SracosConfig {
    let d = SracosConfig::DEFAULT;
    SracosConfig {
        exploration_rate: field(rng, d.exploration_rate),
        uncertain_bits: (rng.next_u32().is_multiple_of(4)).then(|| (rng.next_u32() % 5) as u8),
        replacement: [
            Replacement::Worst,
            Replacement::Random,
            Replacement::LargestMargin,
        ][(rng.next_u32() % 3) as usize],
        suppression: (rng.next_u32().is_multiple_of(3)).then(|| Suppression {
            non_update_allowed: count(rng, 5),
            resample_times: count(rng, 2),
            balance_rate: field(rng, 0.5),
        }),
        max_evaluations: limit,
    }
}

#[test]
fn coordinate_search() {
    report("CoordinateSearch<3>", drive(1, operations(), coordinate));
}

fn crs(
    rng: &mut DriverRng,
    bounds: Bounds<N>,
    limit: u32,
) -> Result<ControlledRandomSearch<N, 8>, Error> {
    ControlledRandomSearch::<N, 8>::try_new(bounds, crs_config(rng, limit))
}

#[test]
fn controlled_random_search() {
    report("ControlledRandomSearch<3, 8>", drive(2, operations(), crs));
}

fn two_phase_build(
    rng: &mut DriverRng,
    bounds: Bounds<N>,
    limit: u32,
) -> Result<TwoPhase<ControlledRandomSearch<N, 8>, N>, Error> {
    // The two budgets add up to `limit`, which the driver checks.
    let global_budget = limit / 2;
    let global = ControlledRandomSearch::<N, 8>::try_new(bounds, crs_config(rng, u32::MAX))?;
    let local = CoordinateConfig {
        max_evaluations: limit - global_budget,
        ..CoordinateConfig::DEFAULT
    };
    TwoPhase::try_new(global, global_budget, local)
}

#[test]
fn two_phase() {
    report(
        "TwoPhase<ControlledRandomSearch<3, 8>>",
        drive_in_conditions(3, operations(), two_phase_build, |two| {
            u8::from(two.phase() == Phase::Local)
        }),
    );
}

fn sracos_build(rng: &mut DriverRng, bounds: Bounds<N>, limit: u32) -> Result<Sracos<N>, Error> {
    Sracos::<N>::try_new(bounds, sracos_config(rng, limit))
}

#[test]
fn sracos() {
    report("Sracos<3>", drive(4, operations(), sracos_build));
}

fn racos_build(rng: &mut DriverRng, bounds: Bounds<N>, limit: u32) -> Result<Racos<N>, Error> {
    let s = sracos_config(rng, limit);
    Racos::<N>::try_new(
        bounds,
        SracosConfig {
            replacement: Replacement::Worst,
            suppression: None,
            max_evaluations: limit,
            ..s
        },
    )
}

#[test]
fn racos() {
    report("Racos<3>", drive(5, operations(), racos_build));
}

fn cem(rng: &mut DriverRng, bounds: Bounds<N>, limit: u32) -> Result<DiagonalCem<N, 6, 3>, Error> {
    let d = CemConfig::DEFAULT;
    let config = CemConfig {
        weighting: match rng.next_u32() % 3 {
            0 => Weighting::Cem,
            1 => Weighting::CmaEs,
            _ => Weighting::PiBb {
                h: field(rng, 10.0),
            },
        },
        elite: (rng.next_u32().is_multiple_of(3)).then(|| (rng.next_u32() % 5) as usize),
        initial_variance: field(rng, d.initial_variance),
        adapt_covariance: rng.next_u32().is_multiple_of(2),
        learning_rate: field(rng, d.learning_rate),
        exploration_floor: field(rng, d.exploration_floor),
        min_variance: field(rng, d.min_variance),
        max_variance: field(rng, d.max_variance),
        first_is_mean: rng.next_u32().is_multiple_of(2),
        tolerance: field(rng, 1e-6),
        max_evaluations: limit,
    };
    let mean = point_in(rng, &bounds);
    DiagonalCem::<N, 6, 3>::try_new(bounds, mean, config)
}

#[test]
fn diagonal_cem() {
    report("DiagonalCem<3, 6, 3>", drive(6, operations(), cem));
}

fn cmaes_build(rng: &mut DriverRng, bounds: Bounds<N>, limit: u32) -> Result<Cmaes<N, 7>, Error> {
    let d = CmaesConfig::DEFAULT;
    let config = CmaesConfig {
        initial_sigma: field(rng, d.initial_sigma),
        max_sigma: field(rng, d.max_sigma),
        penalty: field(rng, d.penalty),
        eigen_interval: count(rng, d.eigen_interval),
        tolerance: field(rng, d.tolerance),
        max_evaluations: limit,
        active: rng.next_u32().is_multiple_of(2),
    };
    let mean = point_in(rng, &bounds);
    Cmaes::<N, 7>::try_new(bounds, mean, config)
}

#[test]
fn cmaes() {
    report("Cmaes<3, 7>", drive(7, operations(), cmaes_build));
}

fn rockstar_build(
    rng: &mut DriverRng,
    bounds: Bounds<N>,
    limit: u32,
) -> Result<Rockstar<N, 15>, Error> {
    let d = RockstarConfig::DEFAULT;
    let maybe =
        |rng: &mut DriverRng, v: f32| (rng.next_u32().is_multiple_of(4)).then(|| field(rng, v));
    let config = RockstarConfig {
        initial_sigma: field(rng, d.initial_sigma),
        max_sigma: field(rng, d.max_sigma),
        lambda: field(rng, d.lambda),
        near_radius: field(rng, d.near_radius),
        initial_samples: count(rng, d.initial_samples),
        extra_starts_from: (rng.next_u32().is_multiple_of(2)).then(|| count(rng, 6)),
        step_gain: field(rng, d.step_gain),
        descent_iterations: cap(rng, d.descent_iterations),
        trust_radius: field(rng, d.trust_radius),
        descent_tolerance: field(rng, d.descent_tolerance),
        kappa: field(rng, d.kappa),
        zeta: maybe(rng, 1.2),
        xi: maybe(rng, 1.05),
        c_c: maybe(rng, 0.3),
        c_cov: maybe(rng, 0.2),
        tolerance: field(rng, d.tolerance),
        max_evaluations: limit,
    };
    let start = point_in(rng, &bounds);
    Rockstar::<N, 15>::try_new(bounds, start, config)
}

#[test]
fn rockstar() {
    report("Rockstar<3, 15>", drive(8, operations(), rockstar_build));
}

fn line_bo_build(
    rng: &mut DriverRng,
    bounds: Bounds<N>,
    limit: u32,
) -> Result<LineBo<N, 12>, Error> {
    let d = LineBoConfig::DEFAULT;
    let config = LineBoConfig {
        length_scale: field(rng, d.length_scale),
        signal_variance: field(rng, d.signal_variance),
        noise_variance: field(rng, d.noise_variance),
        jitter: field(rng, d.jitter),
        beta: field(rng, d.beta),
        directions: if rng.next_u32().is_multiple_of(2) {
            LineDirections::Coordinate
        } else {
            LineDirections::Random
        },
        evaluations_per_line: count(rng, d.evaluations_per_line),
        threshold: (rng.next_u32().is_multiple_of(2)).then(|| field(rng, 1.0)),
        max_evaluations: limit,
    };
    let start = point_in(rng, &bounds);
    LineBo::<N, 12>::try_new(bounds, start, config)
}

#[test]
fn line_bo() {
    report("LineBo<3, 12>", drive(9, operations(), line_bo_build));
}

/// Room for this many candidates in flight in the in-flight runs (more than the CEM's 6, the
/// CMA-ES's 7, the CRS's 8 hand out at once, so the capacity comes from the algorithm).
const C: usize = 8;

fn in_flight_report(name: &str, result: Result<Tally, host_tests::adversarial::Violation>) {
    report(&format!("InFlight<{name}, 3, {C}>"), result);
}

#[test]
fn in_flight_sequential_ones() {
    in_flight_report(
        "CoordinateSearch<3>",
        drive_in_flight::<N, _, C>(21, operations(), true, coordinate),
    );
    in_flight_report(
        "Sracos<3>",
        drive_in_flight::<N, _, C>(24, operations(), true, sracos_build),
    );
    in_flight_report(
        "Racos<3>",
        drive_in_flight::<N, _, C>(25, operations(), true, racos_build),
    );
}

#[test]
fn in_flight_controlled_random_search() {
    in_flight_report(
        "ControlledRandomSearch<3, 8>",
        drive_in_flight::<N, _, C>(22, operations(), true, crs),
    );
    // TwoPhase changes conditions at its hand-over: its best is checked to be a told cost.
    in_flight_report(
        "TwoPhase<ControlledRandomSearch<3, 8>>",
        drive_in_flight::<N, _, C>(23, operations(), false, two_phase_build),
    );
}

#[test]
fn in_flight_diagonal_cem() {
    in_flight_report(
        "DiagonalCem<3, 6, 3>",
        drive_in_flight::<N, _, C>(26, operations(), true, cem),
    );
}

#[test]
fn in_flight_cmaes() {
    in_flight_report(
        "Cmaes<3, 7>",
        drive_in_flight::<N, _, C>(27, operations(), true, cmaes_build),
    );
}

#[test]
fn in_flight_rockstar() {
    in_flight_report(
        "Rockstar<3, 15>",
        drive_in_flight::<N, _, C>(28, operations(), true, rockstar_build),
    );
}

#[test]
fn in_flight_line_bo() {
    in_flight_report(
        "LineBo<3, 12>",
        drive_in_flight::<N, _, C>(29, operations(), true, line_bo_build),
    );
}

#[test]
fn adapter() {
    // One adapter per optimizer family, a quarter of the operations each.
    let quarter = operations() / 4;
    let runs = [
        drive_adapter(11, quarter, |rng, bounds, limit| {
            let d = CoordinateConfig::DEFAULT;
            let config = CoordinateConfig {
                initial_step: field(rng, d.initial_step),
                max_evaluations: limit,
                ..d
            };
            let start = point_in(rng, &bounds);
            CoordinateSearch::<2>::try_new(bounds, start, config)
        })
        .map(|t| ("Adapter<CoordinateSearch<2>>", t)),
        drive_adapter(12, quarter, |rng, bounds, limit| {
            Sracos::<2>::try_new(bounds, sracos_config(rng, limit))
        })
        .map(|t| ("Adapter<Sracos<2>>", t)),
        drive_adapter(13, quarter, |rng, bounds, limit| {
            let mean = point_in(rng, &bounds);
            Cmaes::<2, 6>::try_new(
                bounds,
                mean,
                CmaesConfig {
                    initial_sigma: field(rng, 0.3),
                    max_evaluations: limit,
                    ..CmaesConfig::DEFAULT
                },
            )
        })
        .map(|t| ("Adapter<Cmaes<2, 6>>", t)),
        drive_adapter(14, quarter, |rng, bounds, limit| {
            let start = point_in(rng, &bounds);
            Rockstar::<2, 10>::try_new(
                bounds,
                start,
                RockstarConfig {
                    initial_sigma: field(rng, 0.1),
                    max_evaluations: limit,
                    ..RockstarConfig::DEFAULT
                },
            )
        })
        .map(|t| ("Adapter<Rockstar<2, 10>>", t)),
    ];
    let mut total = 0;
    for run in runs {
        match run {
            Ok((name, tally)) => {
                println!("{name}: {tally}");
                assert!(tally.built > 0 && tally.accepted_tells > 0 && tally.refused_calls > 0);
                assert!(tally.faulty_ticks > 0 && tally.failed_episodes > 0);
                total += tally.operations;
            }
            Err(v) => panic!("adapter: {v}"),
        }
    }
    assert!(total >= 4 * quarter);
}

/// A coordinate search with one deliberate defect, chosen by `bug`: 1, a candidate one ulp
/// above the box on the 20th ask; 2, a refused tell (NaN) that still tells the search
/// (after the 20th ask); 3, a best that ignores the costs told after the 10th evaluation.
#[derive(Debug, Clone, PartialEq)]
struct Planted {
    inner: CoordinateSearch<N>,
    bug: u8,
    asks: u32,
    stale_best: Option<Best<N>>,
}

impl Optimizer<N> for Planted {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        let mut theta = self.inner.ask(rng)?;
        self.asks += 1;
        if self.bug == 1 && self.asks == 20 {
            theta[0] = self.inner.bounds().upper()[0].next_up();
        }
        Ok(theta)
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        if self.bug == 2 && cost.is_nan() && self.asks > 20 && self.inner.pending().is_some() {
            // The defect: the rejected call clears the pending candidate.
            let _ = self.inner.tell(1e30);
            return Err(Error::NonFinite("cost"));
        }
        self.inner.tell(cost)?;
        if self.bug == 3 && self.inner.evaluations() == 10 {
            self.stale_best = self.inner.best();
        }
        Ok(())
    }

    fn best(&self) -> Option<Best<N>> {
        self.stale_best.or(self.inner.best())
    }

    fn pending(&self) -> Option<&Vector<N>> {
        self.inner.pending()
    }

    fn evaluations(&self) -> u32 {
        self.inner.evaluations()
    }

    fn status(&self) -> Status {
        self.inner.status()
    }

    fn bounds(&self) -> &Bounds<N> {
        self.inner.bounds()
    }
}

#[test]
fn a_planted_bug_is_caught() {
    let expected = ["outside", "refused tell", "best cost"];
    for bug in 1..=3u8 {
        let result = drive(21, 200_000, |rng, bounds, limit| {
            let config = CoordinateConfig {
                max_evaluations: limit,
                ..CoordinateConfig::DEFAULT
            };
            Ok::<_, Error>(Planted {
                inner: CoordinateSearch::try_new(bounds, point_in(rng, &bounds), config)?,
                bug,
                asks: 0,
                stale_best: None,
            })
        });
        match result {
            Err(v) => {
                println!("planted bug {bug} caught: {v}");
                let what = expected[usize::from(bug) - 1];
                assert!(
                    v.message.contains(what),
                    "bug {bug} caught as something else: {v}"
                );
            }
            Ok(tally) => panic!("planted bug {bug} not caught: {tally}"),
        }
    }
}

/// Loaded forgeries run this many asks and tells (adapters: ticks, in episodes of 10).
const FORGED_STEPS: u64 = if cfg!(debug_assertions) { 1_000 } else { 5_000 };

/// The steps after which the record to forge is taken (one more ask leaves a candidate
/// pending): one in debug builds, three in release.
const CUTS: &[usize] = if cfg!(debug_assertions) {
    &[30]
} else {
    &[7, 30, 100]
};

/// Sweeps the forgeries of `o`'s record after each of [`CUTS`] (every state on the way must
/// load back as itself) and runs each forgery that loads for [`FORGED_STEPS`]: no panic, no
/// θ outside the box or non-finite (see [`forged_report`]).
fn forge<const N: usize, O: Optimizer<N> + Persistent + Clone>(name: &str, o: O) {
    forge_for(name, o, FORGED_STEPS);
}

/// [`forge`] with each loaded forgery run for `steps` asks and tells.
fn forge_for<const N: usize, O: Optimizer<N> + Persistent + Clone>(name: &str, o: O, steps: u64) {
    for &cut in CUTS {
        let result = mid_run(o.clone(), cut)
            .map(|record| forgery::sweep::<O>(&record, |o, rng| run_optimizer(o, rng, steps)));
        forged_report(&format!("{name} after {cut} steps"), result);
    }
}

/// Prints the tally; no loaded forgery may break a check, and some must load and run and
/// some be refused as invalid states (else the sweep tested nothing).
fn forged_report(name: &str, result: Result<Forgeries, String>) {
    match result {
        Ok(tally) => {
            println!("{name}: {tally}");
            assert_eq!(tally.violations, 0, "{name}: {tally}");
            assert!(tally.loaded > 0 && tally.steps > 0 && tally.invalid() > 0);
        }
        Err(e) => panic!("{name}: {e}"),
    }
}

/// A coordinate search that keeps going for about a thousand steps on the noisy sphere
/// before its steps fall below the tolerance (with the default 1e-4 it stops after a few
/// dozen, and the loaded forgeries would run little).
const FINE_SEARCH: CoordinateConfig = CoordinateConfig {
    initial_step: 0.3,
    tolerance: 1e-30,
    ..CoordinateConfig::DEFAULT
};

fn unit_box() -> Bounds<2> {
    Bounds::uniform(-1.0, 1.0).unwrap()
}

#[test]
fn forged_coordinate_search() {
    let s = CoordinateSearch::<2>::try_new(unit_box(), Vector::zeros(), FINE_SEARCH).unwrap();
    forge("CoordinateSearch<2>", s);
}

#[test]
fn forged_controlled_random_search() {
    let s = ControlledRandomSearch::<2, 8>::try_new(unit_box(), CrsConfig::DEFAULT).unwrap();
    forge("ControlledRandomSearch<2, 8>", s);
}

#[test]
fn forged_two_phase() {
    // The hand-over after 12 evaluations: the record holds both phases.
    let global = ControlledRandomSearch::<2, 8>::try_new(unit_box(), CrsConfig::DEFAULT).unwrap();
    let s = TwoPhase::try_new(global, 12, FINE_SEARCH).unwrap();
    forge("TwoPhase<ControlledRandomSearch<2, 8>>", s);
}

#[test]
fn forged_sracos() {
    // With value suppression re-evaluating often, so that records hold its round.
    let config = SracosConfig {
        suppression: Some(Suppression {
            non_update_allowed: 2,
            resample_times: 3,
            balance_rate: 0.5,
        }),
        ..SracosConfig::DEFAULT
    };
    forge(
        "Sracos<2, 2, 6>",
        Sracos::<2, 2, 6>::try_new(unit_box(), config).unwrap(),
    );
}

#[test]
fn forged_racos() {
    let s = Racos::<2, 2, 5>::try_new(unit_box(), SracosConfig::DEFAULT).unwrap();
    forge("Racos<2, 2, 5>", s);
}

#[test]
fn forged_diagonal_cem() {
    let s =
        DiagonalCem::<2, 6, 3>::try_new(unit_box(), Vector::zeros(), CemConfig::DEFAULT).unwrap();
    forge("DiagonalCem<2, 6, 3>", s);
}

#[test]
fn forged_cmaes() {
    let config = CmaesConfig {
        active: true,
        ..CmaesConfig::DEFAULT
    };
    let s = Cmaes::<2, 4>::try_new(unit_box(), Vector::zeros(), config).unwrap();
    forge("Cmaes<2, 4>", s);
}

#[test]
fn forged_rockstar() {
    let config = RockstarConfig {
        initial_samples: 4,
        ..RockstarConfig::DEFAULT
    };
    let s = Rockstar::<2, 8>::try_new(unit_box(), Vector::zeros(), config).unwrap();
    forge("Rockstar<2, 8>", s);
}

#[test]
fn forged_line_bo() {
    let config = LineBoConfig {
        threshold: Some(1.0),
        directions: LineDirections::Random,
        ..LineBoConfig::DEFAULT
    };
    let s = LineBo::<2, 6>::try_new(unit_box(), Vector::zeros(), config).unwrap();
    // A tenth of the other optimizers' steps: every LineBO ask is a posterior pass over its
    // 64-point grid, and 5,000 steps per forgery took about 5 minutes per cut in release.
    // 500 steps still fill the GP (M = 6) many times over, evicting and refactoring.
    forge_for("LineBo<2, 6>", s, FORGED_STEPS / 10);
}

#[test]
fn forged_any_optimizer() {
    let s: AnyOptimizer<2, 4, 2, 8> =
        DiagonalCem::try_new(unit_box(), Vector::zeros(), CemConfig::DEFAULT)
            .unwrap()
            .into();
    forge("AnyOptimizer<2, 4, 2, 8>::Cem", s);
}

/// The adapter the forged-adapter tests save: the driver's PD and correction envelope, a
/// quadratic cost, `optimizer` from θ = 0, a failure cost of 100.
fn forged_adapter_around<O: Optimizer<2>>(optimizer: O) -> ForgedAdapter<O> {
    forged_adapter_failing_at(optimizer, 100.0)
}

/// [`forged_adapter_around`] with the failure cost `failure_cost`.
fn forged_adapter_failing_at<O: Optimizer<2>>(optimizer: O, failure_cost: f32) -> ForgedAdapter<O> {
    let pd = Pd::<1>::try_new(Vector::repeat(3.0), Vector::repeat(0.7))
        .and_then(|pd| pd.with_limit(Vector::repeat(ACTION_LIMIT)))
        .unwrap();
    let policy =
        LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(ENVELOPE)).unwrap();
    let config = AdapterConfig {
        dt: 0.1,
        failure_cost,
        max_faulty_ticks: 0,
        learning_episodes: 1_000,
    };
    let shaper = QuadraticCost::try_new(Vector::repeat(1.0)).unwrap();
    Adapter::try_new(
        optimizer,
        CorrectedPd::new(pd, policy),
        shaper,
        config,
        Vector::zeros(),
    )
    .unwrap()
}

#[test]
fn forged_adapter() {
    let cmaes = Cmaes::<2, 4>::try_new(unit_box(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    let adapter = forged_adapter_around(cmaes);
    for &cut in CUTS {
        let result = adapter_mid_run(adapter.clone(), cut).map(|record| {
            forgery::sweep::<ForgedAdapter<Cmaes<2, 4>>>(&record, |a, rng| {
                run_adapter(a, rng, FORGED_STEPS / 10, 10)
            })
        });
        forged_report(
            &format!("Adapter<Cmaes<2, 4>> after {cut} episodes"),
            result,
        );
    }
}

/// `episodes` bare episodes of 8 ticks on states drawn in [−0.5, 0.5]² (RNG `seed`), in
/// [`Mode::Nominal`](ctrl_adapt::controller::Mode::Nominal), to teach a forged adapter's guard
/// its envelope; the adapter is left in `Mode::Learn`.
fn teach_envelope<O, G, M>(adapter: &mut ForgedAdapter<O, G, M>, episodes: usize, seed: u64)
where
    O: Optimizer<2>,
    G: ctrl_adapt::controller::guard::Supervisor<2>,
    M: ctrl_adapt::model::TickModel<2, 1>,
{
    use ctrl_adapt::controller::Mode;
    adapter.set_mode(Mode::Nominal).unwrap();
    let mut rng = host_tests::adversarial::DriverRng::seed_from_u64(seed);
    for _ in 0..episodes {
        adapter.begin_episode(&mut rng).unwrap();
        for _ in 0..8 {
            let state = Vector::<2>::from_fn(|_, _| rng.next_u32() as f32 / u32::MAX as f32 - 0.5);
            adapter.control(&state, &Vector::from([state[0]]));
        }
        adapter.end_episode().unwrap();
    }
    adapter.set_mode(Mode::Learn).unwrap();
}

/// The adapter of `forged_adapter` with a runtime guard (a limit on each state coordinate,
/// an envelope learned from three bare episodes) and a plant model fitted to every tick:
/// the guard's envelope, counters and running trip and the model's fit are in the record
/// too.
#[test]
fn forged_guarded_and_modelled_adapter() {
    use ctrl_adapt::controller::guard::{Guard, GuardConfig, Limit, Source};
    use ctrl_adapt::model::{Affine, ModelConfig, OnlineModel, RlsModel};
    type Forged = ForgedAdapter<CoordinateSearch<2>, Guard<2, 8>, OnlineModel<Affine, 2, 1, 4>>;
    let search = CoordinateSearch::<2>::try_new(unit_box(), Vector::zeros(), FINE_SEARCH).unwrap();
    let limit = |k: u16| Limit {
        source: Source::State(k),
        low: -1.5,
        high: 1.5,
    };
    let guard = Guard::<2, 8>::try_new(GuardConfig {
        limits: [limit(0), limit(1)],
        relative_margin: 0.5,
        absolute_margin: 0.1,
        ..GuardConfig::DEFAULT
    })
    .unwrap();
    let model = OnlineModel::new(RlsModel::try_new(ModelConfig::default()).unwrap(), Affine);
    let mut adapter: Forged = forged_adapter_around(search)
        .with_guard(guard)
        .and_then(|a| a.with_model(model))
        .unwrap();
    // Three bare episodes teach the guard its envelope.
    teach_envelope(&mut adapter, 3, 7);
    for &cut in CUTS {
        let result = adapter_mid_run(adapter, cut).map(|record| {
            forgery::sweep::<Forged>(&record, |a, rng| run_adapter(a, rng, FORGED_STEPS / 10, 10))
        });
        forged_report(
            &format!(
                "Adapter<CoordinateSearch<2>> with Guard<2, 8> and a plant model after {cut} episodes"
            ),
            result,
        );
    }
}

/// A guarded adapter near the top of f32: a failure cost of 2e38 and a tripped-cost span of
/// 1e38 (their sum finite), and margins of 10× the envelope tapered to nothing at the last
/// tick. A forgery that raises either of the pair until the sum overflows must be refused,
/// as [`Adapter::with_guard`] refuses that pair (it loaded before the decoded adapter made
/// the constructor's check), and a forged envelope, however large, must leave every
/// threshold a number (10 × a large envelope overflows, times the last tick's weight 0 was
/// NaN). Both are checked on each loaded forgery before it runs.
#[test]
fn forged_guarded_adapter_near_the_top_of_f32() {
    use ctrl_adapt::controller::guard::{Guard, GuardConfig};
    type Forged = ForgedAdapter<CoordinateSearch<2>, Guard<0, 8>>;
    let search = CoordinateSearch::<2>::try_new(unit_box(), Vector::zeros(), FINE_SEARCH).unwrap();
    let guard = Guard::<0, 8>::try_new(GuardConfig {
        relative_margin: 10.0,
        margin_taper: 0.0,
        tripped_cost_span: 1e38,
        ..GuardConfig::DEFAULT
    })
    .unwrap();
    let mut adapter: Forged = forged_adapter_failing_at(search, 2e38)
        .with_guard(guard)
        .unwrap();
    // Two bare episodes teach the guard its envelope.
    teach_envelope(&mut adapter, 2, 8);
    for &cut in CUTS {
        let result = adapter_mid_run(adapter, cut).map(|record| {
            forgery::sweep::<Forged>(&record, |a, rng| {
                let failure = a.config().failure_cost;
                let span = a.guard().config().tripped_cost_span;
                let top = failure + span;
                if !(top.is_finite() && top > failure) {
                    return Err(format!(
                        "loaded a failure cost {failure:e} and a tripped-cost span {span:e} \
                         that with_guard refuses"
                    ));
                }
                if let Some(t) = (0..8).find(|&t| a.guard().threshold(t).is_some_and(f32::is_nan)) {
                    return Err(format!("a NaN threshold at tick {t}"));
                }
                run_adapter(a, rng, FORGED_STEPS / 10, 10)
            })
        });
        if let Ok(tally) = &result {
            let span = tally
                .rejected
                .keys()
                .any(|e| e.contains("tripped_cost_span"));
            assert!(span, "no forgery refused for its span: {tally}");
        }
        forged_report(
            &format!(
                "Adapter<CoordinateSearch<2>> with Guard<0, 8> near f32::MAX after {cut} episodes"
            ),
            result,
        );
    }
}

/// The model-based learner, restarting its trust region after 3 stalled proposals: each
/// loaded forgery proposes (a coordinate search on a model that is off by a shift and
/// sometimes fails) and is told real costs, a tenth of [`FORGED_STEPS`] proposals (each of
/// them 30 predictions).
#[test]
fn forged_model_based() {
    use ctrl_adapt::model::{ModelBased, ModelBasedConfig};
    let fallback =
        CoordinateSearch::<2>::try_new(unit_box(), Vector::zeros(), FINE_SEARCH).unwrap();
    let config = ModelBasedConfig {
        inner_evaluations: 30,
        restart_after: 3,
        ..ModelBasedConfig::DEFAULT
    };
    let learner: ForgedModelBased = ModelBased::try_new(unit_box(), fallback, config).unwrap();
    for &cut in CUTS {
        let result = model_based_mid_run(learner, cut as u64).map(|record| {
            forgery::sweep::<ForgedModelBased>(&record, |l, rng| {
                run_model_based(l, rng, FORGED_STEPS / 10)
            })
        });
        forged_report(
            &format!("ModelBased<CoordinateSearch<2>, 2> after {cut} proposals"),
            result,
        );
    }
}

/// The plant model alone: each loaded forgery fits [`FORGED_STEPS`] ticks of a linear
/// plant (non-finite and huge ticks among them; a random, square-wave or nearly constant
/// command) and must fit every ordinary tick and stay a valid state.
#[test]
fn forged_rls_model() {
    use ctrl_adapt::model::{ModelConfig, RlsModel};
    // The default, and a fast-forgetting model whose running error is the last tick's.
    let fast = ModelConfig {
        forgetting: 0.99,
        error_window: 1,
        ..ModelConfig::default()
    };
    for config in [ModelConfig::default(), fast] {
        let model: ForgedRlsModel = RlsModel::try_new(config).unwrap();
        for &cut in CUTS {
            let result = rls_model_mid_run(model, cut as u64).map(|record| {
                forgery::sweep::<ForgedRlsModel>(&record, |m, rng| {
                    run_rls_model(m, rng, FORGED_STEPS)
                })
            });
            forged_report(
                &format!(
                    "RlsModel<2, 1, 4> (forgetting {}, error window {}) after {cut} ticks",
                    config.forgetting, config.error_window
                ),
                result,
            );
        }
    }
}

/// The adapter with the runtime guard on (see `drive_guarded_adapter`): every check of the
/// guard after every episode.
#[test]
fn the_guarded_adapter_survives_the_adversarial_driver() {
    let tally = host_tests::adversarial::drive_guarded_adapter(21, operations())
        .unwrap_or_else(|v| panic!("guarded adapter: {v}"));
    println!("guarded adapter: {tally:?}");
    assert!(tally.built > 0 && tally.refused_guards > 0 && tally.round_trips > 0);
    assert!(tally.limit_trips > 0 && tally.envelope_trips > 0);
}
