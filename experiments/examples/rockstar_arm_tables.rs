//! Table I of Hwangbo, Gehring, Sommer, Siegwart & Buchli, "ROCK*: Efficient black-box
//! optimization for policy learning" (Humanoids 2014) on the paper's two 50-link arm tasks,
//! and the exploration sweeps behind the tuned values (not run in CI; findings in
//! `experiments/findings/rockstar-arm.md`):
//!
//! ```text
//! cargo run --release -p experiments --example rockstar_arm_tables -- tables [SEEDS]
//! cargo run --release -p experiments --example rockstar_arm_tables -- sweep50
//! cargo run --release -p experiments --example rockstar_arm_tables -- sweep500 [STD ...]
//! cargo run --release -p experiments --example rockstar_arm_tables -- sweep400 [STD ...]
//! ```
//!
//! * `tables`: the reaching task ([`ReachingArm::paper`]: 50 links, DMPs of 10 basis
//!   functions, 500 parameters) and the rhythmic task ([`RhythmicArm`]: 50 links, 8 kernels
//!   per joint, 400 parameters), `SEEDS` (default 10) sessions of 3,000 rollouts per method,
//!   seeds 0..SEEDS. Prints the mean and median lowest sampled cost after 3,000 rollouts
//!   (the paper's statistic; see [`experiments::rockstar_arm`]), the mean cost of the
//!   deployable point (θ* or the mean; one evaluation outside the budget) and the rollouts
//!   ROCK* needs to reach each seed's best baseline cost; writes the mean learning curves
//!   to `target/experiments/rockstar_reaching500.svg` and `rockstar_rhythmic400.svg`.
//!   About 4 minutes on one core with 10 seeds (ROCK* at n = 500 costs ≈ 5 ms a
//!   rollout).
//! * `sweep50`, `sweep500`, `sweep400`: the initial exploration of each method on tuning
//!   seeds 100.. (disjoint from the test seeds 0..10): 5 seeds for the 50-parameter arm,
//!   2 for the large tasks; 3,000 rollouts each. The mean lowest cost per standard
//!   deviation is printed; the smallest mean picks the tuned value.
//!
//! **CMA-ES is omitted from the 500- and 400-parameter rows**: the library's `Cmaes<N, L>`
//! needed N ≤ 127 (nalgebra's static eigendecomposition) when they were written; it no
//! longer does, and adding its rows is left to do. PI-BB ([`DiagonalCem`] with [`Weighting::PiBb`], K = 10) runs in two forms,
//! fixed exploration (PI-BB as Stulp & Sigaud define it) and adapted diagonal covariance
//! with a floor (PI²-CMA style); the table reports both. PI² (the paper's last column) has
//! no counterpart here.
//!
//! 500-parameter optimizers are large (`Rockstar<500, 2500>` holds 7 MB): every run is on a
//! thread with a 256 MB stack and the optimizers are boxed.
//!
//! [`DiagonalCem`]: ctrl_adapt::optimizer::DiagonalCem
//! [`Weighting::PiBb`]: ctrl_adapt::optimizer::Weighting::PiBb

use std::time::Instant;

use ctrl_adapt::optimizer::{Bounds, Vector};
use experiments::rockstar_arm::{
    self, Method, PiBbExploration, Session, mean_curve, mean_median, out_dir, tuned,
};
use host_tests::arm::{self, ViaPointArm};
use host_tests::plots::{Series, log_cost_curves};
use host_tests::reaching::ReachingArm;
use host_tests::rhythmic::{self, RhythmicArm};

/// Rollouts per session (the paper's table).
const ROLLOUTS: usize = 3000;
/// Half-width of the reaching tasks' box (every DMP weight in ±10⁴).
const REACH_HALF: f32 = arm::WEIGHT_LIMIT;

/// One session of `method` on an n-parameter task (`M` = 5n remembered rollouts for ROCK*;
/// no CMA-ES above n = 127).
fn session<const N: usize, const M: usize>(
    method: Method,
    bounds: &Bounds<N>,
    start: Vector<N>,
    half: f32,
    std: f32,
    seed: u64,
    cost: &mut impl FnMut(&Vector<N>) -> f32,
) -> Session {
    let run = match method {
        Method::Rockstar => {
            rockstar_arm::rockstar::<N, M>(*bounds, start, half, std, ROLLOUTS, seed, cost)
        }
        Method::PiBbFixed | Method::PiBbAdapted => rockstar_arm::pibb::<N>(
            *bounds,
            start,
            std,
            if method == Method::PiBbFixed {
                PiBbExploration::Fixed
            } else {
                PiBbExploration::Adapted
            },
            ROLLOUTS,
            seed,
            cost,
        ),
        Method::Cmaes => panic!("CMA-ES is run only on the 50-parameter arm"),
    };
    run.expect("a valid configuration")
}

fn sweep50() {
    let arm = ViaPointArm::new();
    let start = arm.minimum_jerk_theta();
    let bounds = arm::bounds();
    let mut cost = |t: &Vector<50>| arm.cost(t);
    let seeds: Vec<u64> = (100..105).collect();
    println!("## 50-parameter via-point arm, tuning seeds {seeds:?}, {ROLLOUTS} rollouts");
    println!("| method | std | mean lowest | median lowest | fewest rollouts run | seconds |");
    println!("|---|---:|---:|---:|---:|---:|");
    for method in [
        Method::Rockstar,
        Method::Cmaes,
        Method::PiBbFixed,
        Method::PiBbAdapted,
    ] {
        for std in [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0] {
            let clock = Instant::now();
            let sessions: Vec<Session> = seeds
                .iter()
                .map(|&seed| match method {
                    Method::Cmaes => rockstar_arm::cmaes::<50, 15>(
                        bounds, start, REACH_HALF, std, ROLLOUTS, seed, &mut cost,
                    )
                    .expect("a valid configuration"),
                    _ => {
                        session::<50, 250>(method, &bounds, start, REACH_HALF, std, seed, &mut cost)
                    }
                })
                .collect();
            let finals: Vec<f32> = sessions.iter().map(Session::final_lowest).collect();
            let fewest = sessions.iter().map(|s| s.rollouts).min().unwrap_or(0);
            let (mean, median) = mean_median(&finals);
            println!(
                "| {} | {std} | {mean:.4e} | {median:.4e} | {fewest} | {:.1} |",
                method.name(),
                clock.elapsed().as_secs_f64()
            );
        }
    }
}

/// A large task: its name, box, start, half-width and cost.
struct Task<const N: usize, C: FnMut(&Vector<N>) -> f32> {
    name: &'static str,
    file: &'static str,
    bounds: Bounds<N>,
    start: Vector<N>,
    half: f32,
    cost: C,
}

fn sweep_big<const N: usize, const M: usize, C: FnMut(&Vector<N>) -> f32>(
    task: &mut Task<N, C>,
    stds: &[f32],
) {
    let seeds = [100u64, 101];
    println!(
        "## {}, tuning seeds {seeds:?}, {ROLLOUTS} rollouts",
        task.name
    );
    println!("| method | std | mean lowest | fewest rollouts run | seconds |");
    println!("|---|---:|---:|---:|---:|");
    for method in [Method::Rockstar, Method::PiBbFixed, Method::PiBbAdapted] {
        for &std in stds {
            let clock = Instant::now();
            let sessions: Vec<Session> = seeds
                .iter()
                .map(|&seed| {
                    session::<N, M>(
                        method,
                        &task.bounds,
                        task.start,
                        task.half,
                        std,
                        seed,
                        &mut task.cost,
                    )
                })
                .collect();
            let finals: Vec<f32> = sessions.iter().map(Session::final_lowest).collect();
            let fewest = sessions.iter().map(|s| s.rollouts).min().unwrap_or(0);
            let (mean, _) = mean_median(&finals);
            println!(
                "| {} | {std} | {mean:.4e} | {fewest} | {:.1} |",
                method.name(),
                clock.elapsed().as_secs_f64()
            );
        }
    }
}

fn table_big<const N: usize, const M: usize, C: FnMut(&Vector<N>) -> f32>(
    task: &mut Task<N, C>,
    stds: [(Method, f32); 3],
    seeds: u64,
) {
    println!(
        "## {}: {seeds} seeds (0..{seeds}), {ROLLOUTS} rollouts",
        task.name
    );
    let mut all: Vec<(Method, f32, Vec<Session>, f64)> = Vec::new();
    for (method, std) in stds {
        let clock = Instant::now();
        let sessions: Vec<Session> = (0..seeds)
            .map(|seed| {
                session::<N, M>(
                    method,
                    &task.bounds,
                    task.start,
                    task.half,
                    std,
                    seed,
                    &mut task.cost,
                )
            })
            .collect();
        all.push((method, std, sessions, clock.elapsed().as_secs_f64()));
    }
    println!(
        "| method | std | mean lowest | median lowest | mean deployed | per-seed lowest | fewest rollouts run | seconds |"
    );
    println!("|---|---:|---:|---:|---:|---|---:|---:|");
    for (method, std, sessions, seconds) in &all {
        let finals: Vec<f32> = sessions.iter().map(Session::final_lowest).collect();
        let deployed: Vec<f32> = sessions.iter().map(|s| s.deployed).collect();
        let (mean, median) = mean_median(&finals);
        let (deployed_mean, _) = mean_median(&deployed);
        let per_seed: Vec<String> = finals.iter().map(|c| format!("{c:.3e}")).collect();
        let fewest = sessions.iter().map(|s| s.rollouts).min().unwrap_or(0);
        println!(
            "| {} | {std} | {mean:.4e} | {median:.4e} | {deployed_mean:.4e} | {} | {fewest} | {seconds:.0} |",
            method.name(),
            per_seed.join(" ")
        );
    }
    let rock = &all[0].2;
    for (method, _, sessions, _) in &all[1..] {
        let reach: Vec<String> = rock
            .iter()
            .zip(sessions)
            .map(|(r, b)| match r.rollouts_to_reach(b.final_lowest()) {
                Some(k) => k.to_string(),
                None => "—".to_string(),
            })
            .collect();
        let (baseline_mean, _) = mean_median(
            &sessions
                .iter()
                .map(Session::final_lowest)
                .collect::<Vec<_>>(),
        );
        let to_mean = rockstar_arm::mean_curve(rock)
            .iter()
            .position(|&c| c <= baseline_mean)
            .map_or("—".to_string(), |k| (k + 1).to_string());
        println!(
            "ROCK* rollouts to reach {}'s 3,000-rollout cost, per seed: {} (mean curve to mean: {to_mean})",
            method.name(),
            reach.join(" ")
        );
    }
    let curves: Vec<(String, Vec<f64>)> = all
        .iter()
        .map(|(m, std, s, _)| (format!("{} (std {std})", m.name()), mean_curve(s)))
        .collect();
    let series: Vec<Series> = curves
        .iter()
        .map(|(name, values)| Series { name, values })
        .collect();
    let dir = out_dir();
    std::fs::create_dir_all(&dir).expect("target/experiments is writable");
    let path = dir.join(task.file);
    log_cost_curves(
        &path,
        &format!("{}: mean lowest cost over {seeds} seeds", task.name),
        &series,
        "lowest cost so far",
    )
    .expect("the plot is written");
    println!("curves: {}", path.display());
}

fn reaching() -> Task<500, impl FnMut(&Vector<500>) -> f32> {
    let arm = ReachingArm::paper();
    let start = Vector::<500>::from_iterator(arm.minimum_jerk_theta());
    Task {
        name: "reaching, 50 links, 500 parameters",
        file: "rockstar_reaching500.svg",
        bounds: Bounds::uniform(-REACH_HALF, REACH_HALF).expect("a valid box"),
        start,
        half: REACH_HALF,
        cost: move |t: &Vector<500>| arm.cost(t.as_slice()),
    }
}

fn rhythmic_task() -> Task<400, impl FnMut(&Vector<400>) -> f32> {
    let arm = RhythmicArm::new();
    Task {
        name: "rhythmic, 50 links, 400 parameters",
        file: "rockstar_rhythmic400.svg",
        bounds: Bounds::uniform(-rhythmic::WEIGHT_LIMIT, rhythmic::WEIGHT_LIMIT)
            .expect("a valid box"),
        start: Vector::zeros(),
        half: rhythmic::WEIGHT_LIMIT,
        cost: move |t: &Vector<400>| arm.cost(t.as_slice()),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.first().map_or("tables", String::as_str).to_string();
    let seeds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    // `sweep500`/`sweep400` take an optional list of standard deviations (a subset of the
    // grid; each value's figures do not depend on the others).
    let grid: Option<Vec<f32>> =
        (args.len() > 1).then(|| args[1..].iter().filter_map(|s| s.parse().ok()).collect());
    let worker = std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(move || match mode.as_str() {
            "sweep50" => sweep50(),
            "sweep500" => sweep_big::<500, 2500, _>(
                &mut reaching(),
                &grid.unwrap_or(vec![0.2, 0.5, 1.0, 2.0, 5.0, 20.0, 50.0, 200.0]),
            ),
            "sweep400" => sweep_big::<400, 2000, _>(
                &mut rhythmic_task(),
                &grid.unwrap_or(vec![0.0001, 0.0003, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3]),
            ),
            "tables" => {
                table_big::<500, 2500, _>(&mut reaching(), tuned::REACHING_500, seeds);
                table_big::<400, 2000, _>(&mut rhythmic_task(), tuned::RHYTHMIC_400, seeds);
            }
            other => {
                eprintln!("unknown mode {other}: tables [SEEDS] | sweep50 | sweep500 | sweep400")
            }
        })
        .expect("a worker thread");
    worker.join().expect("the worker finished");
}
