//! The oracle: scores θ on the robots' tasks over a line protocol on stdin/stdout, so that
//! optimizers outside Rust (pycma, ZOOpt, nevergrad, SafeOpt, bayesian-optimization;
//! `peers/compare.py`) are driven on exactly the episodes the library's optimizers see. One
//! request per line, one reply per line; numbers are space-separated, `err <why>` answers a
//! bad request.
//!
//! ```text
//! task <name> <seed>            → ok <n> <budget> <threshold> <safe threshold>
//!                                 (a new trial; success is a cost below <threshold>, the
//!                                 safe methods' cost bound is <safe threshold>)
//! lower | upper | start         → n numbers: the box and the start θ
//! eval <θ₁ … θₙ>                → <cost> <safe|unsafe>: one learning episode of θ (clipped
//!                                 into the box), and whether it was unsafe (on the hopper
//!                                 off the gait, elsewhere a cost above the safe threshold)
//! deploy <θ₁ … θₙ>              → θ's mean cost over 5 fresh episodes (not counted)
//! run <method> <budget> <seed>  → <evaluations> <first success or -> <best> <deployed>
//!                                 <optimizer ns per evaluation> <unsafe episodes>
//!                                 <fallback episodes or ->: a library method (coordinate,
//!                                 sracos, crs, cmaes, rockstar, linebo, linebo-safe, and
//!                                 model, the model-based learner, whose optimizer time
//!                                 includes its imagined episodes and which alone reports
//!                                 the episodes its fallback proposed) on a fresh copy of
//!                                 the trial
//! quit
//! ```
//!
//! `cargo run --release -p experiments --bin oracle`

use std::io::{BufRead, Write};

use experiments::peers::{Task, Trial, run_library};

fn numbers(v: &[f32]) -> String {
    v.iter()
        .map(|x| format!("{x:e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn parse_theta<'a>(words: impl Iterator<Item = &'a str>) -> Option<Vec<f32>> {
    words.map(|w| w.parse::<f32>().ok()).collect()
}

fn reply(trial: &mut Option<(Task, u64, Trial)>, line: &str) -> String {
    let mut words = line.split_whitespace();
    let command = words.next().unwrap_or("");
    if command == "task" {
        let task = words.next().and_then(Task::parse);
        let seed = words.next().and_then(|w| w.parse::<u64>().ok());
        return match (task, seed) {
            (Some(task), Some(seed)) => {
                let t = Trial::new(task, seed);
                let answer = format!(
                    "ok {} {} {:e} {:e}",
                    task.dimension(),
                    task.budget(),
                    t.threshold(),
                    t.safe_threshold().unwrap_or(f32::NAN)
                );
                *trial = Some((task, seed, t));
                answer
            }
            _ => {
                "err usage: task <auv|auv-calm|auv-rotated|hopper|arm|sphere|ackley> <seed>".into()
            }
        };
    }
    let Some((task, seed, t)) = trial.as_mut() else {
        return "err no task: send `task <name> <seed>` first".into();
    };
    match command {
        "lower" => numbers(t.lower()),
        "upper" => numbers(t.upper()),
        "start" => numbers(t.start()),
        "eval" => match parse_theta(words).and_then(|x| t.episode(&x)) {
            Some(e) => format!(
                "{:e} {}",
                e.cost,
                if e.unsafe_episode { "unsafe" } else { "safe" }
            ),
            None => format!("err eval needs {} finite numbers", task.dimension()),
        },
        "deploy" => match parse_theta(words).and_then(|x| t.deployed(&x)) {
            Some(c) => format!("{c:e}"),
            None => format!("err deploy needs {} finite numbers", task.dimension()),
        },
        "run" => {
            let method = words.next().unwrap_or("");
            let budget = words.next().and_then(|w| w.parse::<u32>().ok());
            let run_seed = words.next().and_then(|w| w.parse::<u64>().ok());
            let (Some(budget), Some(run_seed)) = (budget, run_seed) else {
                return "err usage: run <method> <budget> <seed>".into();
            };
            let mut fresh = Trial::new(*task, *seed);
            match run_library(method, &mut fresh, budget, run_seed) {
                Some(r) => {
                    let first = r
                        .first_success(fresh.threshold())
                        .map_or("-".to_string(), |k| k.to_string());
                    let deployed = fresh.deployed(&r.returned).unwrap_or(f32::NAN);
                    let fallback = r
                        .fallback_episodes
                        .map_or("-".to_string(), |k| k.to_string());
                    format!(
                        "{} {first} {:e} {:e} {:.0} {} {fallback}",
                        r.costs.len(),
                        r.best(),
                        deployed,
                        r.optimizer_ns,
                        r.unsafe_episodes
                    )
                }
                None => format!("err unknown method {method} (or none for this task)"),
            }
        }
        _ => format!("err unknown command {command}"),
    }
}

fn main() {
    let stdin = std::io::stdin();
    let mut out = std::io::stdout().lock();
    let mut trial = None;
    for line in stdin.lock().lines() {
        let Ok(line) = line else { break };
        if line.trim() == "quit" {
            break;
        }
        let answer = reply(&mut trial, &line);
        if writeln!(out, "{answer}")
            .and_then(|()| out.flush())
            .is_err()
        {
            break;
        }
    }
}
