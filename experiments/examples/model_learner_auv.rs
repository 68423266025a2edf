//! A model-based learner on the AUV survey, as a research prototype and through the
//! library's `model::ModelBased` (the last row, which must equal the chosen setting's): after
//! every real episode the `RlsModel` is refitted on its ticks, CMA-ES searches
//! `imagine_episode`'s predicted cost inside a trust region around the best real θ, and the
//! model's best is run on the robot only if its predicted cost passes a threshold and beats
//! the predicted cost of the best real θ; otherwise the episode goes to a model-free
//! coordinate search. Compared with the coordinate search alone.
//!
//! ```text
//! cargo run --release -p experiments --example model_learner_auv -- 101 110   # choose settings
//! cargo run --release -p experiments --example model_learner_auv -- 1 10      # report
//! ```
//!
//! Per seed s: the disturbed real AUV (seed s), RNG seed s, 15 real episodes: episode 1 is
//! the bare PD (θ = 0, cost c₀); then a few exploration episodes with θ uniform in a small
//! box around zero (optionally screened: the first of up to 20 draws the model predicts
//! under the threshold); then the loop above. Threshold: predicted cost ≤ 1.2·c₀ (c₀ > 0 on
//! every seed). Trust region: the box of half-width r around the best real θ, clipped to
//! [−1, 1]^18; r starts at r₀, grows by 1.5 (to at most 1) after an episode that improves
//! the best real cost and shrinks by 0.6 (to at least 0.05) otherwise. Optionally the
//! model's candidate is considered only if the model ranks the real episodes so far with
//! Spearman ρ ≥ a minimum, and a second, affine model may have to agree with the screen.
//! Inner search: `Cmaes<18, 12>` from the best real θ, σ₀ 0.5
//! of the trust box, 240 imagined episodes. Every setting of the grid in `main` is printed;
//! the one reported in the findings was chosen on seeds 101–110 (most seeds within 1 m,
//! then fewest episodes above 1.2·c₀, then the smallest median).
//! Findings: experiments/findings/model.md.

use ctrl_adapt::controller::Controller;
use ctrl_adapt::cost::{Shaper, SurveyCost};
use ctrl_adapt::model::{
    Affine, AffineWith, ModelBased, ModelBasedConfig, ModelConfig, Regressors, RlsModel, Source,
    imagine_episode,
};
use ctrl_adapt::optimizer::{Bounds, Cmaes, CmaesConfig, Optimizer, Vector};
use experiments::model_learner::bounded_drag;
use host_tests::auv::{Auv, AuvConfig};
use host_tests::auv_task::{self, P, RADIUS, plant, policy_state, true_error};
use host_tests::{median, spearman};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

const DT: f32 = 0.1;
const BUDGET: usize = 15;
const INNER_BUDGET: u32 = 240;
const R: usize = 14;

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

fn uniform(rng: &mut impl RngCore, half_width: f32) -> Vector<P> {
    Vector::from_fn(|_, _| {
        let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
        half_width * (2.0 * unit - 1.0)
    })
}

/// `imagine_episode`'s survey cost of θ from `start`; 100 if the rollout diverges.
fn predicted_cost<const Q: usize, M: Regressors<6, 3, Q>>(
    model: &RlsModel<6, 3, Q>,
    map: &M,
    start: &Vector<6>,
    theta: &Vector<P>,
) -> f32 {
    let mut controller = auv_task::controller();
    let mut shaper = SurveyCost::try_new(RADIUS).unwrap();
    imagine_episode(
        model,
        map,
        start,
        240,
        DT,
        &mut controller,
        theta,
        &mut shaper,
        |x| Vector::<3>::new(x[0], x[1], x[2]),
    )
    .unwrap_or(100.0)
}

#[derive(Clone, Copy)]
struct Settings {
    /// The trust region's initial half-width r₀.
    radius: f32,
    /// The exploration episodes' half-width.
    explore: f32,
    /// How many exploration episodes follow the bare one.
    explorations: usize,
    /// Screen the exploration draws with the model fitted so far.
    screen_exploration: bool,
    /// The model's candidate is considered only when its Spearman ρ over the real episodes
    /// so far is at least this (−1: always).
    min_rho: f64,
    /// A second opinion: an affine model (R = 10) fitted on the same ticks must also
    /// predict the candidate under the threshold and below the best real θ.
    second_opinion: bool,
}

/// What one learning run did: the real costs in order, and which episodes the model chose.
struct Run {
    costs: Vec<f32>,
    from_model: usize,
    /// Where each episode's θ came from: 'b' bare, 'e' exploration, 'm' model, 'f' fallback.
    source: Vec<char>,
}

fn learn(seed: u64, settings: Settings) -> Run {
    let map = AffineWith::new(bounded_drag);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut auv = plant(AuvConfig::REAL, seed);
    let mut model = RlsModel::<6, 3, R>::try_new(ModelConfig::DEFAULT).unwrap();
    let fit = |model: &mut RlsModel<6, 3, R>, e: &Episode| {
        for (k, u) in e.commands.iter().enumerate() {
            model
                .update(&map, &e.states[k], u, &e.states[k + 1])
                .unwrap();
        }
    };
    let mut second = RlsModel::<6, 3, 10>::try_new(ModelConfig::DEFAULT).unwrap();
    let fit_second = |model: &mut RlsModel<6, 3, 10>, e: &Episode| {
        for (k, u) in e.commands.iter().enumerate() {
            model
                .update(&Affine, &e.states[k], u, &e.states[k + 1])
                .unwrap();
        }
    };
    let bare = run(&Vector::zeros(), &mut auv);
    fit(&mut model, &bare);
    fit_second(&mut second, &bare);
    let start = bare.states[0];
    let threshold = 1.2 * bare.cost;
    let mut real: Vec<(Vector<P>, f32)> = vec![(Vector::zeros(), bare.cost)];
    let mut source = vec!['b'];
    for _ in 0..settings.explorations {
        // Screened exploration: the first of up to 20 draws the model predicts under the
        // threshold (the last draw if none does).
        let mut theta = uniform(&mut rng, settings.explore);
        if settings.screen_exploration {
            for _ in 0..20 {
                if predicted_cost(&model, &map, &start, &theta) <= threshold {
                    break;
                }
                theta = uniform(&mut rng, settings.explore);
            }
        }
        source.push('e');
        let e = run(&theta, &mut auv);
        fit(&mut model, &e);
        fit_second(&mut second, &e);
        real.push((theta, e.cost));
    }
    let box_ = auv_task::bounds();
    let mut fallback = auv_task::coordinate_search(Vector::zeros(), BUDGET as u32).unwrap();
    let mut radius = settings.radius;
    let mut from_model = 0;
    let predict =
        |model: &RlsModel<6, 3, R>, theta: &Vector<P>| predicted_cost(model, &map, &start, theta);
    while real.len() < BUDGET {
        let (best_theta, best_cost) = *real.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        let lower = Vector::<P>::from_fn(|i, _| (best_theta[i] - radius).max(-1.0));
        let upper = Vector::<P>::from_fn(|i, _| (best_theta[i] + radius).min(1.0));
        let trust = Bounds::try_new(lower, upper).unwrap();
        let config = CmaesConfig {
            initial_sigma: 0.5,
            max_evaluations: INNER_BUDGET,
            ..CmaesConfig::DEFAULT
        };
        let mut inner = Cmaes::<P, 12>::try_new(trust, best_theta, config).unwrap();
        while let Ok(theta) = inner.ask(&mut rng) {
            let cost = predict(&model, &theta);
            if inner.tell(cost).is_err() {
                break;
            }
        }
        // Can the model rank? Spearman's ρ of its predictions of the real episodes so far.
        let predicted: Vec<f32> = real.iter().map(|(t, _)| predict(&model, t)).collect();
        let measured: Vec<f32> = real.iter().map(|(_, c)| *c).collect();
        let ranks = spearman(&predicted, &measured) >= settings.min_rho;
        let candidate = inner.best().map(|b| (b.theta, b.cost)).filter(|_| ranks);
        let agrees = |theta: &Vector<P>| {
            !settings.second_opinion || {
                let c = predicted_cost(&second, &Affine, &start, theta);
                c <= threshold && c < predicted_cost(&second, &Affine, &start, &best_theta)
            }
        };
        let screened = candidate.filter(|(theta, predicted)| {
            *predicted <= threshold
                && *predicted < predict(&model, &best_theta)
                && box_.contains(theta)
                && agrees(theta)
        });
        let (theta, chose_model) = match screened {
            Some((theta, _)) => (theta, true),
            None => match fallback.ask(&mut rng) {
                Ok(theta) => (theta, false),
                Err(_) => (best_theta, false),
            },
        };
        let e = run(&theta, &mut auv);
        fit(&mut model, &e);
        fit_second(&mut second, &e);
        source.push(if chose_model { 'm' } else { 'f' });
        if chose_model {
            from_model += 1;
        } else {
            let _ = fallback.tell(e.cost);
        }
        radius = if e.cost < best_cost {
            (radius * 1.5).min(1.0)
        } else {
            (radius * 0.6).max(0.05)
        };
        real.push((theta, e.cost));
    }
    Run {
        costs: real.iter().map(|r| r.1).collect(),
        from_model,
        source,
    }
}

/// The same loop through the library's `ModelBased` (the chosen setting only): its rows
/// must equal the prototype's.
fn learn_with_library(seed: u64, settings: Settings) -> Run {
    let map = AffineWith::new(bounded_drag);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut auv = plant(AuvConfig::REAL, seed);
    let mut model = RlsModel::<6, 3, R>::try_new(ModelConfig::DEFAULT).unwrap();
    let fit = |model: &mut RlsModel<6, 3, R>, e: &Episode| {
        for (k, u) in e.commands.iter().enumerate() {
            model
                .update(&map, &e.states[k], u, &e.states[k + 1])
                .unwrap();
        }
    };
    let bare = run(&Vector::zeros(), &mut auv);
    fit(&mut model, &bare);
    let start = bare.states[0];
    let fallback = auv_task::coordinate_search(Vector::zeros(), BUDGET as u32).unwrap();
    let config = ModelBasedConfig {
        initial_radius: settings.radius,
        margin: 0.2 * bare.cost,
        inner_evaluations: INNER_BUDGET,
        ..ModelBasedConfig::DEFAULT
    };
    let mut learner = ModelBased::try_new(auv_task::bounds(), fallback, config).unwrap();
    learner.record(Vector::zeros(), bare.cost).unwrap();
    learner.set_reference(bare.cost).unwrap();
    let mut costs = vec![bare.cost];
    let mut source = vec!['b'];
    for _ in 0..settings.explorations {
        let theta = uniform(&mut rng, settings.explore);
        let e = run(&theta, &mut auv);
        fit(&mut model, &e);
        learner.record(theta, e.cost).unwrap();
        costs.push(e.cost);
        source.push('e');
    }
    let inner = |trust: Bounds<P>, centre: Vector<P>| {
        let config = CmaesConfig {
            initial_sigma: 0.5,
            max_evaluations: INNER_BUDGET,
            ..CmaesConfig::DEFAULT
        };
        Cmaes::<P, 12>::try_new(trust, centre, config)
    };
    let mut from_model = 0;
    while costs.len() < BUDGET {
        let predict = |theta: &Vector<P>| {
            let mut controller = auv_task::controller();
            let mut shaper = SurveyCost::try_new(RADIUS).unwrap();
            imagine_episode(
                &model,
                &map,
                &start,
                240,
                DT,
                &mut controller,
                theta,
                &mut shaper,
                |x| Vector::<3>::new(x[0], x[1], x[2]),
            )
        };
        let proposal = learner.propose(&mut rng, inner, predict).unwrap();
        let e = run(&proposal.theta, &mut auv);
        fit(&mut model, &e);
        learner.tell(e.cost).unwrap();
        let chose_model = matches!(proposal.source, Source::Model(_));
        from_model += usize::from(chose_model);
        source.push(if chose_model { 'm' } else { 'f' });
        costs.push(e.cost);
    }
    Run {
        costs,
        from_model,
        source,
    }
}

/// The coordinate search alone from θ = 0 (the bare PD is its first candidate).
fn coordinate(seed: u64) -> Run {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut auv = plant(AuvConfig::REAL, seed);
    let mut search = auv_task::coordinate_search(Vector::zeros(), BUDGET as u32).unwrap();
    let mut costs = Vec::new();
    while costs.len() < BUDGET {
        let Ok(theta) = search.ask(&mut rng) else {
            break;
        };
        let e = run(&theta, &mut auv);
        search.tell(e.cost).unwrap();
        costs.push(e.cost);
    }
    let source = vec!['f'; costs.len()];
    Run {
        costs,
        from_model: 0,
        source,
    }
}

fn summary(name: &str, runs: &[Run]) {
    let first: Vec<Option<usize>> = runs
        .iter()
        .map(|r| r.costs.iter().position(|c| *c < RADIUS).map(|k| k + 1))
        .collect();
    let reached = first.iter().flatten().count();
    // Seeds that never get within 1 m count as BUDGET + 1 in the median.
    let med = median(
        first
            .iter()
            .map(|f| f.unwrap_or(BUDGET + 1) as f64)
            .collect(),
    );
    let unsafe_by = |kind: char| -> usize {
        runs.iter()
            .map(|r| {
                r.costs
                    .iter()
                    .zip(&r.source)
                    .filter(|(c, s)| **c > 1.2 * r.costs[0] && **s == kind)
                    .count()
            })
            .sum()
    };
    let unsafe_episodes = format!(
        "{} (explore {}, model {}, fallback {})",
        unsafe_by('e') + unsafe_by('m') + unsafe_by('f'),
        unsafe_by('e'),
        unsafe_by('m'),
        unsafe_by('f')
    );
    let best = median(
        runs.iter()
            .map(|r| f64::from(r.costs.iter().copied().fold(f32::INFINITY, f32::min)))
            .collect(),
    );
    let chosen: usize = runs.iter().map(|r| r.from_model).sum();
    println!(
        "| {name} | {reached}/{} | {med} | {unsafe_episodes} | {best:.2} | {chosen} | {:?} |",
        runs.len(),
        first
    );
}

fn main() {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("seed"))
        .collect();
    let (from, to) = match args.as_slice() {
        [a, b] => (*a, *b),
        _ => (1, 10),
    };
    let seeds: Vec<u64> = (from..=to).collect();
    println!(
        "seeds {from}–{to}, {BUDGET} real episodes; 'within 1 m' = first episode with cost < 1 (median counts a miss as {})",
        BUDGET + 1
    );
    println!(
        "| learner | seeds within 1 m | median episodes to 1 m | episodes above 1.2 × bare cost | median best cost | episodes chosen by the model | first episode within 1 m per seed |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | --- |");
    let runs: Vec<Run> = seeds.iter().map(|&s| coordinate(s)).collect();
    summary("coordinate search", &runs);
    for (radius, explore, explorations, screen_exploration, min_rho, second_opinion) in [
        (0.3, 0.3, 2, false, -1.0, false),
        (0.6, 0.3, 2, false, -1.0, false),
        (0.3, 0.15, 2, false, -1.0, false),
        (0.3, 0.1, 2, false, -1.0, false),
        (0.3, 0.3, 2, true, -1.0, false),
        (0.3, 0.15, 2, true, -1.0, false),
        (0.3, 0.1, 2, false, 0.5, false),
        (0.3, 0.15, 2, true, 0.5, false),
        (0.3, 0.1, 4, false, -1.0, false),
        (0.3, 0.05, 4, false, -1.0, false),
        (0.15, 0.1, 2, false, -1.0, false),
        (0.15, 0.05, 4, false, -1.0, false),
        (0.15, 0.05, 3, false, -1.0, false),
        (0.15, 0.05, 3, false, -1.0, true),
        (0.3, 0.05, 4, false, -1.0, true),
        (0.3, 0.1, 2, false, -1.0, true),
    ] {
        let settings = Settings {
            radius,
            explore,
            explorations,
            screen_exploration,
            min_rho,
            second_opinion,
        };
        let runs: Vec<Run> = seeds.iter().map(|&s| learn(s, settings)).collect();
        let screened = if screen_exploration { ", screened" } else { "" };
        let rho = if min_rho > -1.0 {
            format!(", ρ ≥ {min_rho}")
        } else {
            String::new()
        };
        let opinion = if second_opinion {
            ", second opinion"
        } else {
            ""
        };
        summary(
            &format!(
                "model-based, r₀ = {radius}, {explorations} explorations ±{explore}{screened}{rho}{opinion}"
            ),
            &runs,
        );
    }
    let chosen = Settings {
        radius: 0.15,
        explore: 0.05,
        explorations: 3,
        screen_exploration: false,
        min_rho: -1.0,
        second_opinion: false,
    };
    let runs: Vec<Run> = seeds
        .iter()
        .map(|&s| learn_with_library(s, chosen))
        .collect();
    summary(
        "library `ModelBased`, r₀ = 0.15, 3 explorations ±0.05",
        &runs,
    );
}
