//! The library's `model::ModelBased` on the AUV survey in the nominal current and in the
//! current rotated by 45° (the guard study's, `experiments/tests/guard_auv.rs`): where do
//! the episodes above 1.2 × the bare cost come from (exploration, the model's choice, the
//! fallback), and which settings remove them (the pessimistic screen `error_weight`, smaller
//! exploration, smaller fallback steps).
//!
//! ```text
//! cargo run --release -p experiments --example model_safety_auv -- 101 110   # choose
//! cargo run --release -p experiments --example model_safety_auv -- 1 10      # report
//! BUDGET=150 GRID=chosen cargo run --release -p experiments --example model_safety_auv -- 1 10
//! GRID=chosen cargo run --release -p experiments --example model_safety_auv -- 101 110 trace
//! GRID=uncertainty cargo run --release -p experiments --example model_safety_auv -- 101 110
//! GRID=bounded cargo run --release -p experiments --example model_safety_auv -- 101 110 trace
//! ```
//!
//! `trace` prints every episode (its cost, the model's prediction and uncertainty of it)
//! and, per current, whether the uncertainty tells a wrong prediction: Spearman's ρ of the
//! uncertainty of the model's own proposals with their |real − predicted| and with real −
//! predicted, for the first two proposals and for the later ones.
//!
//! The learner's loop, the model and its imagined episodes are `experiments::model_learner`'s
//! (`learn`, `AuvModels`), shared with the oracle's `model` method; the episodes are this
//! example's own (the task's controller and `SurveyCost` ticked directly).
//!
//! Per seed s and current: the disturbed real AUV (seed s), RNG seed s, 15 real episodes:
//! episode 1 is the bare PD (θ = 0, cost c₀); then `explorations` episodes with θ uniform in
//! a small box around zero (half-width `explore` on the weights of the position error,
//! `explore · velocity_scale` on those of the velocity); then `ModelBased` proposals (inner
//! `Cmaes<18, 12>`, σ₀ 0.5 of the trust box, 240 imagined episodes; threshold 1.2·c₀, i.e.
//! margin 0.2·c₀; model `RlsModel<6, 3, 14>` with the bounded-drag features of
//! `model_auv`, refitted on every episode's ticks) with a coordinate-search fallback from
//! θ = 0 (initial step `fallback_step` on the position weights, `fallback_step ·
//! velocity_scale` on the velocity weights). An episode is unsafe when its cost exceeds
//! 1.2·c₀ (the definition of `model_learner_auv`). "Episodes to 1 m" counts the bare episode;
//! a seed that never gets within 1 m counts as 16 in the median. Unsafe episodes are
//! counted twice: above 1.2 × the run's own first (bare) episode, and above 1.2 × the
//! bare controller's mean over 15 bare episodes on a fresh plant of the same seed (scoring
//! only: one bare episode is a noisy reference, and in the rotated current the bare PD
//! itself exceeds 1.2 × its first episode's cost in some repeats).
//!
//! The settings: by default the 23 of the findings (`FINDINGS_GRID`), `GRID=chosen` the
//! chosen one alone, `GRID=uncertainty` the candidate-dependent screen's
//! (`UNCERTAINTY_GRID`), `GRID=bounded` the one chosen from it, or `GRID="r₀,explore,explorations,velocity scale,fallback step,k,e₀,
//! ensemble[,k_u];…"`. Rule for
//! choosing, written before seeds 1–10 were run: among the settings run on seeds 101–110,
//! keep those that reach 1 m in at least as many of the 20 runs (10 seeds × 2 currents) as
//! the previous setting; of those, the fewest unsafe episodes against the bare mean summed
//! over both currents; then the smaller of the two currents' larger median. If no other
//! setting qualifies, the previous one stays.
//! Findings: experiments/findings/model.md.

use ctrl_adapt::controller::Controller;
use ctrl_adapt::cost::{Shaper, SurveyCost};
use ctrl_adapt::model::{ModelBasedConfig, Prediction};
use ctrl_adapt::optimizer::{CoordinateSearch, Error, Optimizer, Vector};
use experiments::model_learner::{
    self, AuvModels, InitialError, Plant, Real, auv_fallback, inner_cmaes,
};
use host_tests::auv::{Auv, AuvConfig};
use host_tests::auv_task::{self, P, RADIUS, plant, policy_state, true_error};
use host_tests::{median, spearman};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const DT: f32 = 0.1;
/// Real episodes per run: 15, or `BUDGET` from the environment (the issue's 150).
fn budget() -> usize {
    std::env::var("BUDGET").map_or(15, |b| b.parse().expect("BUDGET"))
}
const INNER_BUDGET: u32 = 240;

struct Episode {
    states: Vec<Vector<6>>,
    commands: Vec<Vector<3>>,
    cost: f32,
}

fn run(theta: &Vector<P>, auv: &mut Auv) -> Episode {
    let mut controller = auv_task::controller();
    let mut shaper = SurveyCost::try_new(RADIUS).unwrap();
    controller.reset();
    auv.reset();
    let mut states = vec![policy_state(auv)];
    let mut commands = Vec::new();
    for k in 0..auv.steps_per_episode() {
        let x = *states.last().unwrap();
        let u = controller.corrected(theta, &x, k as f32 * DT);
        shaper.observe(&true_error(auv), DT);
        auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
        commands.push(u);
        states.push(policy_state(auv));
    }
    Episode {
        states,
        commands,
        cost: shaper.cost(),
    }
}

/// Per-weight scale: 1 on the weights of the position error (θ[6a + 0..3]), `velocity` on
/// those of the velocity (θ[6a + 3..6]).
fn scale(velocity: f32) -> Vector<P> {
    Vector::from_fn(|i, _| if i % 6 < 3 { 1.0 } else { velocity })
}

#[derive(Clone, Copy, Debug)]
struct Settings {
    radius: f32,
    explore: f32,
    explorations: usize,
    velocity_scale: f32,
    fallback_step: f32,
    error_weight: f32,
    initial_error: f32,
    /// Models fitted on subsets of the episodes (model j leaves out the episodes whose index
    /// is j modulo `ensemble`); the prediction is the worst of theirs and the full model's.
    /// 0: the full model alone.
    ensemble: usize,
    /// k_u of the candidate-dependent screen (`ModelBasedConfig::uncertainty_weight`): the
    /// inner search and the screen use the predicted cost plus k_u × the imagined
    /// episode's `Imagined::deviation` (full model). 0: the point prediction.
    uncertainty_weight: f32,
}

impl Settings {
    fn name(&self) -> String {
        format!(
            "r₀ {}, {}×±{} (v ×{}), fallback step {}, k {}, e₀ {}, ensemble {}{}",
            self.radius,
            self.explorations,
            self.explore,
            self.velocity_scale,
            self.fallback_step,
            self.error_weight,
            self.initial_error,
            self.ensemble,
            if self.uncertainty_weight > 0.0 {
                format!(", k_u {}", self.uncertainty_weight)
            } else {
                String::new()
            }
        )
    }
}

/// One learning run: real costs, where each θ came from ('b' bare, 'e' exploration, 'm'
/// model, 'f' fallback), and the model's prediction of each proposal.
struct Run {
    /// The mean cost of 15 bare episodes on a fresh plant of the same seed: the bare
    /// controller's cost for the second unsafe count (scoring only; the learner never sees it).
    bare_mean: f32,
    costs: Vec<f32>,
    source: Vec<char>,
    predicted: Vec<Option<f32>>,
    /// The model's uncertainty about each proposal.
    uncertainty: Vec<Option<f32>>,
    errors: Vec<f32>,
}

fn fallback(settings: &Settings) -> CoordinateSearch<P> {
    auv_fallback(
        scale(settings.velocity_scale) * settings.fallback_step,
        budget() as u32,
    )
}

/// The real AUV with its models (`experiments::model_learner::AuvModels`), episodes by
/// [`run`].
struct Surveyed {
    auv: Auv,
    models: AuvModels,
}

impl Plant<P> for Surveyed {
    fn episode(&mut self, theta: &Vector<P>) -> Real {
        let e = run(theta, &mut self.auv);
        self.models.fit(&e.states, &e.commands);
        Real {
            cost: e.cost,
            flagged: false,
        }
    }

    fn predict(&self, theta: &Vector<P>) -> Result<f32, Error> {
        self.models.predict(theta)
    }

    fn prediction(&self, theta: &Vector<P>) -> Result<Prediction, Error> {
        self.models.prediction(theta)
    }
}

/// The learner's loop (`experiments::model_learner::learn`): the bare episode, the
/// explorations (each predicted by the models fitted before it ran), then the proposals.
fn learn(seed: u64, current: AuvConfig, settings: Settings) -> Run {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut plant = Surveyed {
        auv: plant(current, seed),
        models: AuvModels::new(settings.ensemble),
    };
    let learner = model_learner::Settings {
        config: ModelBasedConfig {
            initial_radius: settings.radius,
            inner_evaluations: INNER_BUDGET,
            error_weight: settings.error_weight,
            uncertainty_weight: settings.uncertainty_weight,
            ..ModelBasedConfig::DEFAULT
        },
        margin: 0.2,
        explorations: settings.explorations,
        explore: scale(settings.velocity_scale) * settings.explore,
        // A prediction that failed counts as an error of the failure cost, 10.
        initial_error: if settings.initial_error < 0.0 {
            InitialError::Measured { cap: 10.0 }
        } else {
            InitialError::Fixed(settings.initial_error)
        },
    };
    let r = model_learner::learn(
        &mut plant,
        auv_task::bounds(),
        fallback(&settings),
        inner_cmaes::<P, 12>(INNER_BUDGET),
        &learner,
        budget(),
        &mut rng,
    )
    .expect("a valid learner");
    Run {
        bare_mean: bare_mean(seed, current),
        source: r.origin.iter().map(|o| o.letter()).collect(),
        costs: r.costs,
        predicted: r.predicted,
        uncertainty: r.uncertainty,
        errors: r.errors,
    }
}

/// The coordinate search alone from θ = 0 (the bare PD is its first candidate).
fn coordinate(seed: u64, current: AuvConfig, settings: &Settings) -> Run {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut auv = plant(current, seed);
    let mut search = fallback(settings);
    let mut costs = Vec::new();
    while costs.len() < budget() {
        let Ok(theta) = search.ask(&mut rng) else {
            break;
        };
        let e = run(&theta, &mut auv);
        search.tell(e.cost).unwrap();
        costs.push(e.cost);
    }
    let n = costs.len();
    let mut source = vec!['f'; n];
    source[0] = 'b';
    Run {
        bare_mean: bare_mean(seed, current),
        costs,
        source,
        predicted: vec![None; n],
        uncertainty: vec![None; n],
        errors: vec![0.0; n],
    }
}

/// The bare PD run 15 times: how often does the bare controller itself exceed 1.2 × its
/// first episode's cost?
fn bare(seed: u64, current: AuvConfig) -> Run {
    let mut auv = plant(current, seed);
    let costs: Vec<f32> = (0..budget())
        .map(|_| run(&Vector::zeros(), &mut auv).cost)
        .collect();
    let mut source = vec!['e'; budget()];
    source[0] = 'b';
    Run {
        bare_mean: costs.iter().sum::<f32>() / budget() as f32,
        costs,
        source,
        predicted: vec![None; budget()],
        uncertainty: vec![None; budget()],
        errors: vec![0.0; budget()],
    }
}

fn bare_mean(seed: u64, current: AuvConfig) -> f32 {
    bare(seed, current).bare_mean
}

/// 1.2 × `reference` (for a positive reference; reference + 0.2·|reference| in general).
fn limit(reference: f32) -> f32 {
    reference + 0.2 * reference.abs()
}

/// Episodes from `kind` above 1.2 × the first (bare) episode's cost, or above 1.2 × the
/// bare controller's mean cost if `mean`.
fn unsafe_by(runs: &[Run], kind: char, mean: bool) -> usize {
    runs.iter()
        .map(|r| {
            let reference = if mean { r.bare_mean } else { r.costs[0] };
            r.costs
                .iter()
                .zip(&r.source)
                .filter(|(c, s)| **c > limit(reference) && **s == kind)
                .count()
        })
        .sum()
}

struct Summary {
    reached: usize,
    median: f64,
    unsafe_total: usize,
}

fn summary(current: &str, name: &str, runs: &[Run]) -> Summary {
    let first: Vec<Option<usize>> = runs
        .iter()
        .map(|r| r.costs.iter().position(|c| *c < RADIUS).map(|k| k + 1))
        .collect();
    let reached = first.iter().flatten().count();
    let med = median(
        first
            .iter()
            .map(|f| f.unwrap_or(budget() + 1) as f64)
            .collect(),
    );
    let split = |mean: bool| {
        let (b, e, m, f) = (
            unsafe_by(runs, 'b', mean),
            unsafe_by(runs, 'e', mean),
            unsafe_by(runs, 'm', mean),
            unsafe_by(runs, 'f', mean),
        );
        (
            b + e + m + f,
            format!(
                "{} (bare {b}, explore {e}, model {m}, fallback {f})",
                b + e + m + f
            ),
        )
    };
    let (_, first_ref) = split(false);
    let (unsafe_total, mean_ref) = split(true);
    let best = median(
        runs.iter()
            .map(|r| f64::from(r.costs.iter().copied().fold(f32::INFINITY, f32::min)))
            .collect(),
    );
    let chosen: usize = runs
        .iter()
        .map(|r| r.source.iter().filter(|s| **s == 'm').count())
        .sum();
    let fell_back: usize = runs
        .iter()
        .map(|r| r.source.iter().filter(|s| **s == 'f').count())
        .sum();
    let per_seed: Vec<String> = first
        .iter()
        .map(|f| f.map_or("–".to_string(), |k| k.to_string()))
        .collect();
    println!(
        "| {current} | {name} | {reached}/{} | {med} | {first_ref} | {mean_ref} | {best:.2} | {chosen} | {fell_back} | {} |",
        runs.len(),
        per_seed.join(" ")
    );
    Summary {
        reached,
        median: med,
        unsafe_total,
    }
}

fn trace(seed: u64, r: &Run) {
    for (k, c) in r.costs.iter().enumerate() {
        println!(
            "seed {seed} ep {:2} {} cost {c:7.3} {} predicted {:>8} uncertainty {:>8} error {:.3}",
            k + 1,
            r.source[k],
            if *c > limit(r.bare_mean) {
                "UNSAFE"
            } else {
                "      "
            },
            r.predicted[k].map_or("-".into(), |p| format!("{p:.3}")),
            r.uncertainty[k].map_or("-".into(), |u| format!("{u:.3}")),
            r.errors[k]
        );
    }
}

/// Does the model's uncertainty say when its prediction is wrong? Over the model's own
/// proposals (episodes `first..=last`, counting the bare one as 1): Spearman's ρ of the
/// uncertainty with |real − predicted| and with real − predicted (the model's optimism),
/// and the mean uncertainty of the unsafe (vs the bare mean) and the safe ones.
fn calibration(current: &str, runs: &[Run], first: usize, last: usize) {
    let (mut uncertainty, mut size, mut optimism) = (Vec::new(), Vec::new(), Vec::new());
    let (mut unsafe_, mut safe) = (Vec::new(), Vec::new());
    for r in runs {
        for k in (first - 1)..last.min(r.costs.len()) {
            let (Some(p), Some(u), 'm') = (r.predicted[k], r.uncertainty[k], r.source[k]) else {
                continue;
            };
            uncertainty.push(u);
            size.push((r.costs[k] - p).abs());
            optimism.push(r.costs[k] - p);
            if r.costs[k] > limit(r.bare_mean) {
                unsafe_.push(u);
            } else {
                safe.push(u);
            }
        }
    }
    let mean = |v: &[f32]| {
        if v.is_empty() {
            "–".to_string()
        } else {
            format!("{:.3}", v.iter().sum::<f32>() / v.len() as f32)
        }
    };
    println!(
        "  {current}, model proposals in episodes {first}–{last}: {} proposals, ρ(uncertainty, |error|) {:.2}, ρ(uncertainty, real − predicted) {:.2}, mean uncertainty unsafe {} ({}) / safe {} ({})",
        uncertainty.len(),
        spearman(&uncertainty, &size),
        spearman(&uncertainty, &optimism),
        mean(&unsafe_),
        unsafe_.len(),
        mean(&safe),
        safe.len()
    );
}

fn rotated() -> AuvConfig {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    AuvConfig {
        current_direction: [s, s, 0.0],
        ..AuvConfig::REAL
    }
}

/// The settings of the findings' tables, in their order (`r₀,explore,explorations,velocity
/// scale,fallback step,k,e₀,ensemble`; e₀ = −1: measured on the explorations). The first
/// is the previous setting of `model_learner_auv`, and the one chosen.
const FINDINGS_GRID: [&str; 23] = [
    "0.15,0.05,3,1,0.25,0,0,0",
    "0.15,0.05,3,1,0.25,1,1,0",
    "0.15,0.05,3,1,0.25,2,1,0",
    "0.15,0.05,3,1,0.25,0,0,2",
    "0.15,0.05,3,1,0.25,1,1,2",
    "0.15,0.05,3,1,0.25,2,1,2",
    "0.15,0.05,3,1,0.25,0,0,3",
    "0.15,0.05,3,1,0.25,1,1,3",
    "0.15,0.05,3,1,0.25,2,1,3",
    "0.05,0.05,3,1,0.05,0,0,0",
    "0.05,0.05,3,1,0.05,1,1,0",
    "0.05,0.02,3,5,0.05,0,0,0",
    "0.05,0.02,3,5,0.05,1,1,0",
    "0.1,0.05,3,1,0.05,0,0,0",
    "0.1,0.05,3,1,0.05,1,1,0",
    "0.1,0.02,3,5,0.05,0,0,0",
    "0.1,0.02,3,5,0.05,1,1,0",
    "0.15,0.05,3,1,0.25,0.5,-1,0",
    "0.15,0.05,3,1,0.25,1,-1,0",
    "0.15,0.05,3,1,0.25,2,-1,0",
    "0.15,0.05,3,1,0.05,0.5,-1,0",
    "0.15,0.05,3,1,0.05,1,-1,0",
    "0.15,0.05,3,1,0.05,2,-1,0",
];

/// The candidate-dependent screen's grid (`GRID=uncertainty`; 9th field k_u, the
/// `ModelBasedConfig::uncertainty_weight`): the previous setting with k_u from 0 to 10, and
/// the small-step setting (r₀ 0.05, fallback step 0.05) with k_u 0.3, 1 and 3.
const UNCERTAINTY_GRID: [&str; 10] = [
    "0.15,0.05,3,1,0.25,0,0,0,0",
    "0.15,0.05,3,1,0.25,0,0,0,0.03",
    "0.15,0.05,3,1,0.25,0,0,0,0.1",
    "0.15,0.05,3,1,0.25,0,0,0,0.3",
    "0.15,0.05,3,1,0.25,0,0,0,1",
    "0.15,0.05,3,1,0.25,0,0,0,3",
    "0.15,0.05,3,1,0.25,0,0,0,10",
    "0.05,0.05,3,1,0.05,0,0,0,0.3",
    "0.05,0.05,3,1,0.05,0,0,0,1",
    "0.05,0.05,3,1,0.05,0,0,0,3",
];

/// The setting chosen from `UNCERTAINTY_GRID` on seeds 101–110 by the findings' rule
/// (`GRID=bounded`): r₀ 0.05, fallback step 0.05, k_u 0.3.
const BOUNDED: usize = 7;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let from: u64 = args.first().map_or(1, |a| a.parse().expect("seed"));
    let to: u64 = args.get(1).map_or(10, |a| a.parse().expect("seed"));
    let tracing = args.get(2).is_some_and(|a| a == "trace");
    let seeds: Vec<u64> = (from..=to).collect();
    let currents = [("nominal", AuvConfig::REAL), ("rotated 45°", rotated())];
    let previous = Settings {
        radius: 0.15,
        explore: 0.05,
        explorations: 3,
        velocity_scale: 1.0,
        fallback_step: 0.25,
        error_weight: 0.0,
        initial_error: 0.0,
        ensemble: 0,
        uncertainty_weight: 0.0,
    };
    let grid: String = match std::env::var("GRID") {
        Err(_) => FINDINGS_GRID.join(";"),
        Ok(g) if g == "chosen" => FINDINGS_GRID[0].to_string(),
        Ok(g) if g == "uncertainty" => UNCERTAINTY_GRID.join(";"),
        Ok(g) if g == "bounded" => UNCERTAINTY_GRID[BOUNDED].to_string(),
        Ok(g) => g,
    };
    let grid: Vec<Settings> = Some(grid)
        .map(|g| {
            g.split(';')
                .map(|s| {
                    let v: Vec<f32> = s.split(',').map(|x| x.trim().parse().unwrap()).collect();
                    Settings {
                        radius: v[0],
                        explore: v[1],
                        explorations: v[2] as usize,
                        velocity_scale: v[3],
                        fallback_step: v[4],
                        error_weight: v[5],
                        initial_error: v[6],
                        ensemble: v[7] as usize,
                        uncertainty_weight: v.get(8).copied().unwrap_or(0.0),
                    }
                })
                .collect()
        })
        .unwrap_or_default();
    println!("seeds {from}–{to}, {} real episodes per run", budget());
    println!(
        "| current | learner | seeds within 1 m | median episodes to 1 m | episodes above 1.2 × the first bare episode's cost | episodes above 1.2 × the bare mean cost | median best cost | episodes chosen by the model | fallback episodes | first episode within 1 m per seed |"
    );
    println!("| --- | --- | ---: | ---: | --- | --- | ---: | ---: | ---: | --- |");
    for (name, current) in currents {
        let runs: Vec<Run> = seeds.iter().map(|&s| bare(s, current)).collect();
        summary(name, "bare PD, repeated", &runs);
        let runs: Vec<Run> = seeds
            .iter()
            .map(|&s| coordinate(s, current, &previous))
            .collect();
        summary(name, "coordinate search, step 0.25", &runs);
    }
    for settings in &grid {
        let mut total = (0, 0.0f64, 0);
        for (name, current) in currents {
            let runs: Vec<Run> = seeds
                .iter()
                .map(|&s| learn(s, current, *settings))
                .collect();
            let s = summary(name, &format!("`ModelBased`, {}", settings.name()), &runs);
            total.0 += s.reached;
            total.1 = total.1.max(s.median);
            total.2 += s.unsafe_total;
            if tracing {
                for (seed, r) in seeds.iter().zip(&runs) {
                    trace(*seed, r);
                }
                let first = 2 + settings.explorations;
                calibration(name, &runs, first, first + 1);
                calibration(name, &runs, first + 2, budget());
            }
        }
        println!(
            "  total: within 1 m {}, worst median {}, unsafe {}",
            total.0, total.1, total.2
        );
    }
}
