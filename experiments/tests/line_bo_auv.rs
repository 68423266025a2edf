//! LineBO against the library's other optimizers on the AUV survey from W = 0 (the peers'
//! `auv` trial: 150 episodes, 10 seeds, success = cost < 1, within D = 1 m) and on the
//! hopper (the peers' `hopper` trial: 200 episodes, success = cost ≤ 3·10⁻⁴), and the unsafe
//! episodes of every method (`experiments::peers::Scored`): on the AUV episodes whose cost
//! exceeds the bare controller's (the start θ in the seed's first episode) by more than
//! [`SAFETY_MARGIN`], on the hopper episodes off the gait. `linebo-safe` is LineBO given
//! that cost bound as its threshold. `auv_after_a_warm_up_episode` and
//! `auv_in_a_rotated_current` are the AUV off the conditions LineBO's settings were chosen in
//! ([`Conditions::WARM_UP`], [`Conditions::ROTATED`]). Release only:
//!
//! ```text
//! cargo test --release -p experiments --test line_bo_auv -- --nocapture
//! ```
//!
//! The seeds are 1–10 (the reported block) unless `SEEDS` names others (`SEEDS=101-110`, the
//! block the settings are chosen on, or a list `1,2,5`); the settings tables read
//! `CONDITIONS` (`nominal`, the default, `warm-up` or `rotated`, or `warm-up:K`,
//! `rotated:DEGREES`) and `SETTINGS` (rows `ℓ/β/σ_f/per-line`, comma-separated, instead of
//! the grid); the methods tables keep only the methods of `METHODS` when it is set.

#![cfg(not(debug_assertions))]

use experiments::peers::{Conditions, SAFETY_MARGIN, Task, Trial, run_library};
use host_tests::median;

/// The seeds of `SEEDS` (`a-b` or `a,b,c`), 1–10 without it.
fn seeds() -> Vec<u64> {
    let Ok(text) = std::env::var("SEEDS") else {
        return (1..=10).collect();
    };
    let parse = |t: &str| t.trim().parse::<u64>().expect("SEEDS: a-b or a,b,c");
    match text.split_once('-') {
        Some((a, b)) => (parse(a)..=parse(b)).collect(),
        None => text.split(',').map(parse).collect(),
    }
}

/// The conditions of `CONDITIONS`, nominal without it.
fn conditions() -> Conditions {
    std::env::var("CONDITIONS").map_or(Conditions::NOMINAL, |c| {
        Conditions::parse(&c).expect("CONDITIONS: nominal, warm-up[:K] or rotated[:DEGREES]")
    })
}

/// The p-quantile (linear interpolation) of sorted `v`.
fn quantile(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let x = p * (v.len() - 1) as f64;
    let (i, f) = (x.floor() as usize, x.fract());
    let next = v[(i + 1).min(v.len() - 1)];
    // Failures are +∞: a quartile between two of them, or on one, is +∞ (not ∞ − ∞).
    if f == 0.0 || next == v[i] {
        v[i]
    } else {
        v[i] + f * (next - v[i])
    }
}

/// Prints, per method of `methods` on `task` in `conditions`: successes, median [IQR] episodes to success (failures as
/// +∞ in the median), median deployed cost of the returned θ, optimizer time per
/// evaluation, and the unsafe episodes summed over the seeds. Checks that every method ran
/// its whole budget on every seed.
fn methods_table(task: Task, conditions: Conditions, methods: &[&str]) {
    let seeds = seeds();
    println!(
        "{} from the start, {conditions:?}, {} episodes, seeds {seeds:?}; unsafe: off the gait (hopper), else cost > (1 + {SAFETY_MARGIN}) × bare",
        task.name(),
        task.budget()
    );
    let bare: Vec<f32> = seeds
        .iter()
        .map(|&s| {
            Trial::with_conditions(task, s, conditions)
                .start_cost()
                .unwrap()
        })
        .collect();
    println!("bare controller's cost per seed: {bare:.3?}");
    println!(
        "| method | successes | episodes to success, median [IQR] | deployed cost, median | optimizer µs/eval | unsafe episodes |"
    );
    println!("|---|---|---|---|---|---|");
    // `METHODS` (comma-separated) keeps only those of `methods`.
    let only = std::env::var("METHODS").ok();
    let keep = |m: &str| {
        only.as_deref()
            .is_none_or(|o| o.split(',').any(|x| x.trim() == m))
    };
    for &method in methods.iter().filter(|m| keep(m)) {
        let (mut firsts, mut deployed, mut micros) = (vec![], vec![], vec![]);
        let (mut successes, mut unsafe_episodes) = (0, 0);
        for &seed in &seeds {
            let mut trial = Trial::with_conditions(task, seed, conditions);
            let report = run_library(method, &mut trial, task.budget(), seed).unwrap();
            assert_eq!(
                report.costs.len(),
                task.budget() as usize,
                "{method} seed {seed}"
            );
            let first = report.first_success(trial.threshold());
            successes += usize::from(first.is_some());
            firsts.push(first.map_or(f64::INFINITY, |k| k as f64));
            unsafe_episodes += report.unsafe_episodes;
            deployed.push(f64::from(trial.deployed(&report.returned).unwrap()));
            micros.push(report.optimizer_ns / 1e3);
        }
        let mut sorted = firsts.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "| {method} | {successes}/{} | {:.1} [{:.1}, {:.1}] | {:.3e} | {:.1} | {unsafe_episodes} |",
            seeds.len(),
            median(firsts),
            quantile(&sorted, 0.25),
            quantile(&sorted, 0.75),
            median(deployed),
            median(micros),
        );
    }
}

/// The methods of the peer comparison, and `cem` (the sweep's `DiagonalCem`).
const ALL_METHODS: [&str; 8] = [
    "coordinate",
    "sracos",
    "crs",
    "cmaes",
    "cem",
    "rockstar",
    "linebo",
    "linebo-safe",
];

/// The methods of the off-condition tables: LineBO with and without its threshold, and the
/// three that the guide's summary ranks it against.
const RANKED_METHODS: [&str; 5] = ["linebo", "linebo-safe", "coordinate", "cmaes", "cem"];

#[test]
fn line_bo_on_the_auv() {
    methods_table(Task::Auv, Conditions::NOMINAL, &ALL_METHODS);
}

/// One episode of the bare controller before learning: the same task, the disturbances of
/// each learning episode drawn one episode later.
#[test]
fn auv_after_a_warm_up_episode() {
    methods_table(Task::Auv, Conditions::WARM_UP, &RANKED_METHODS);
}

/// The current turned by 30° about the vertical.
#[test]
fn auv_in_a_rotated_current() {
    methods_table(Task::Auv, Conditions::ROTATED, &RANKED_METHODS);
}

/// The hopper (31 parameters, 200 episodes); its unsafe episodes are those off the gait.
#[test]
fn line_bo_on_the_hopper() {
    methods_table(Task::Hopper, Conditions::NOMINAL, &ALL_METHODS);
}

/// LineBO on the AUV (in the conditions of `CONDITIONS`) with each setting (ℓ, β, σ_f as a
/// multiple of the bare cost, episodes per line), with the threshold (`safe`) or without:
/// the unsafe episodes summed over the seeds, the successes, the median episodes to success
/// (a failure as +∞), the median deployed cost of the returned θ, and the episodes to
/// success of the seeds that succeed. Prints a table; checks
/// only that every run used its budget (the figures are the result, not a pass mark).
fn settings_table(safe: bool, settings: &[(f32, f32, f32, u32)]) {
    use ctrl_adapt::optimizer::{Bounds, LineBo, LineBoConfig, Optimizer, Vector};
    use experiments::peers::line_bo_config;
    use rand_core::SeedableRng;
    let (task, conditions, seeds) = (Task::Auv, conditions(), seeds());
    println!("threshold: {safe}; {conditions:?}; seeds {seeds:?}");
    println!(
        "| ℓ | β | σ_f / bare | episodes per line | unsafe episodes | successes | median | deployed cost, median | episodes to success |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    // (successes, unsafe episodes, median, setting) of every row, for the rule below.
    let mut rows = vec![];
    for &(length_scale, beta, signal, per_line) in settings {
        let (mut unsafe_episodes, mut firsts, mut deployed) = (0, vec![], vec![]);
        for &seed in &seeds {
            let mut trial = Trial::with_conditions(task, seed, conditions);
            let bare = trial.start_cost().unwrap();
            let config = LineBoConfig {
                length_scale,
                beta,
                signal_variance: (signal * bare).powi(2),
                evaluations_per_line: per_line,
                ..line_bo_config(&trial, task.budget(), safe).unwrap()
            };
            let bounds = Bounds::try_new(
                Vector::from_column_slice(trial.lower()),
                Vector::from_column_slice(trial.upper()),
            )
            .unwrap();
            let mut s = LineBo::<18, 64>::try_new(bounds, Vector::zeros(), config).unwrap();
            let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(seed);
            let (mut k, mut first) = (0, None);
            while let Ok(theta) = s.ask(&mut rng) {
                let scored = trial.episode(theta.as_slice()).unwrap();
                let cost = scored.cost;
                k += 1;
                unsafe_episodes += usize::from(scored.unsafe_episode);
                if first.is_none() && cost < trial.threshold() {
                    first = Some(k);
                }
                s.tell(cost).unwrap();
            }
            assert_eq!(k, task.budget());
            firsts.extend(first);
            let returned = s
                .best()
                .map_or_else(|| trial.start().to_vec(), |b| b.theta.as_slice().to_vec());
            deployed.push(f64::from(trial.deployed(&returned).unwrap()));
        }
        firsts.sort();
        let successes = firsts.len();
        let mut all: Vec<f64> = firsts.iter().map(|&k| f64::from(k)).collect();
        all.resize(seeds.len(), f64::INFINITY);
        println!(
            "| {length_scale} | {beta} | {signal} | {per_line} | {unsafe_episodes} | {successes}/{} | {:.1} | {:.3e} | {firsts:?} |",
            seeds.len(),
            median(all.clone()),
            median(deployed),
        );
        rows.push((
            successes,
            unsafe_episodes,
            median(all),
            (length_scale, beta, signal, per_line),
        ));
    }
    // The rule the recommended settings are chosen by (on seeds 101–110, nominal conditions):
    // among the settings that succeed on at least 9 seeds in 10 (if none does, those with the
    // most successes), the fewest unsafe episodes, then the lower median episodes to success,
    // then the earlier row.
    let most = rows.iter().map(|r| r.0).max().unwrap_or(0);
    let floor = (seeds.len() * 9).div_ceil(10).min(most);
    let chosen = rows
        .iter()
        .filter(|r| r.0 >= floor)
        .min_by(|a, b| a.1.cmp(&b.1).then(a.2.total_cmp(&b.2)));
    if let Some((successes, unsafe_episodes, median, (l, beta, signal, per_line))) = chosen {
        println!(
            "chosen (≥ {floor}/{} successes, fewest unsafe, then median): ℓ = {l}, β = {beta}, σ_f / bare = {signal}, {per_line} per line: {successes}/{}, median {median:.1}, {unsafe_episodes} unsafe",
            seeds.len(),
            seeds.len()
        );
    }
}

/// The settings of both tables: ℓ ∈ {0.05, 0.1, 0.15, 0.2, 0.25, 0.4} of the box, β ∈ {2, 3},
/// σ_f ∈ {1, 2} × the bare cost, 1, 2 or 3 episodes per line (72 settings).
fn grid() -> Vec<(f32, f32, f32, u32)> {
    let mut settings = vec![];
    for per_line in [1, 2, 3] {
        for signal in [1.0, 2.0] {
            for beta in [2.0, 3.0] {
                for length_scale in [0.05, 0.1, 0.15, 0.2, 0.25, 0.4] {
                    settings.push((length_scale, beta, signal, per_line));
                }
            }
        }
    }
    settings
}

/// The settings of `SETTINGS` (`ℓ/β/σ_f/per-line,…`, e.g. `0.1/2/1/1,0.15/2/1/1`), else
/// [`grid`].
fn settings() -> Vec<(f32, f32, f32, u32)> {
    let Ok(text) = std::env::var("SETTINGS") else {
        return grid();
    };
    text.split(',')
        .map(|row| {
            let v: Vec<&str> = row.split('/').collect();
            let f = |i: usize| {
                v[i].trim()
                    .parse::<f32>()
                    .expect("SETTINGS: ℓ/β/σ_f/per-line")
            };
            assert_eq!(v.len(), 4, "SETTINGS: ℓ/β/σ_f/per-line");
            (f(0), f(1), f(2), f(3) as u32)
        })
        .collect()
}

/// With the threshold (`linebo-safe`): the trade-off between unsafe episodes and learning.
#[test]
fn safe_settings_on_the_auv() {
    settings_table(true, &settings());
}

/// Without a threshold (`linebo`).
#[test]
fn unthresholded_settings_on_the_auv() {
    settings_table(false, &settings());
}
