//! The main job: the AUV survey adaptation of Leonetti et al. 2012 end to end, through the
//! library's own adapter, controller and optimizers (f32), on the host plants (f64).
//!
//! ```text
//! cargo run --release                      # AUV demo, figures in target/demo/
//! cargo run --release -- --hopper          # hopping-leg demo instead
//! cargo run --release -- --out DIR --seed 3
//! ```
//!
//! AUV: the bare PD in the "real" 0.6 m/s current; the global phase (CRS, 100 initial
//! samples, 300 episodes) in the "simulator" 0.5 m/s current; the local phase (coordinate
//! search from the global best, 150 episodes: the paper's hour) in the real current. Prints a
//! summary and writes learning curves and x–z trajectories as SVG, and the hand-over to the
//! robot: `auv-handoff.ckpt`, a checkpoint record of the local phase (coordinate search from
//! the global phase's best) that the persistent PIL firmware starts from
//! (`cargo run --release -p host-tests --bin pil -- --persist --handoff FILE`).

use std::path::PathBuf;
use std::time::Instant;

use ctrl_adapt::controller::Mode;
use ctrl_adapt::optimizer::{Optimizer, Phase, TwoPhase, Vector};
use host_tests::auv::AuvConfig;
use host_tests::plots::{self, Curve, Hops, Track};
use host_tests::{auv_task, hopper_task};
use indicatif::{ProgressBar, ProgressStyle};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const USAGE: &str = "usage: host-tests [--hopper] [--out DIR] [--seed N]
  (default) AUV survey demo: bare PD, global phase in the simulator current, local phase in
            the real current; summary table and SVG figures
  --hopper  hopping-leg demo: apex heights per hop before/after learning
  --out DIR where to write the figures (default target/demo)
  --seed N  seed of the disturbances and of the optimizers (default 1); for --hopper, of the
            unseen evaluation course (learning always uses the training course)";

struct Options {
    hopper: bool,
    out: PathBuf,
    seed: u64,
}

fn options() -> Result<Options, String> {
    let mut o = Options {
        hopper: false,
        out: PathBuf::from("target/demo"),
        seed: 1,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--hopper" => o.hopper = true,
            "--out" => o.out = args.next().ok_or("--out needs a directory")?.into(),
            "--seed" => {
                o.seed = args
                    .next()
                    .and_then(|s| s.parse().ok())
                    .ok_or("--seed needs a number")?;
            }
            "-h" | "--help" => return Err(String::new()),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(o)
}

fn bar(len: u64, prefix: &str) -> ProgressBar {
    let style =
        ProgressStyle::with_template("{prefix:>14} [{bar:40.cyan/blue}] {pos:>3}/{len} {msg}")
            .expect("valid template")
            .progress_chars("=> ");
    ProgressBar::new(len)
        .with_style(style)
        .with_prefix(prefix.to_string())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            if !e.is_empty() {
                eprintln!("{e}");
            }
            eprintln!("{USAGE}");
            std::process::exit(if e.is_empty() { 0 } else { 2 });
        }
    };
    std::fs::create_dir_all(&o.out)?;
    let start = Instant::now();
    if o.hopper {
        hopper_demo(&o)?;
    } else {
        auv_demo(&o)?;
    }
    println!("done in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

const GLOBAL_BUDGET: u32 = 300;
/// The global phase's result for the robot, in the output directory.
const HANDOFF_FILE: &str = "auv-handoff.ckpt";
const LOCAL_BUDGET: u32 = 150;

fn auv_demo(o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "AUV survey (Leonetti et al. 2012, section 5): reach the target on the sea bed at 4.8 m\n\
         under a current the thrusters cannot stem; reward J = -d (d >= 1 m) or t_D - 1 (within 1 m)"
    );
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(o.seed);
    let mut real = auv_task::plant(AuvConfig::REAL, o.seed);
    let mut sim = auv_task::plant(AuvConfig::simulator(), 100 + o.seed);

    let two = TwoPhase::try_new(
        auv_task::global_search(GLOBAL_BUDGET)?,
        GLOBAL_BUDGET,
        auv_task::local_config(LOCAL_BUDGET),
    )?;
    let mut adapter = auv_task::adapter(two, GLOBAL_BUDGET + LOCAL_BUDGET, Vector::zeros())?;

    adapter.set_mode(Mode::Nominal)?;
    let bare = auv_task::run_episode(&mut adapter, &mut real, &mut rng, true)?;
    let bare_sim = auv_task::run_episode(&mut adapter, &mut sim, &mut rng, false)?;
    adapter.set_mode(Mode::Learn)?;

    let (mut global, mut local) = (Vec::new(), Vec::new());
    let global_bar = bar(u64::from(GLOBAL_BUDGET), "global (sim)");
    let mut local_bar = None;
    for _ in 0..GLOBAL_BUDGET + LOCAL_BUDGET {
        let phase = adapter.optimizer().phase();
        let (plant, log, pb) = match phase {
            Phase::Global => (&mut sim, &mut global, &global_bar),
            Phase::Local => {
                if local_bar.is_none() {
                    global_bar.finish();
                    local_bar = Some(bar(u64::from(LOCAL_BUDGET), "local (real)"));
                }
                (
                    &mut real,
                    &mut local,
                    local_bar.as_ref().expect("set above"),
                )
            }
        };
        let e = auv_task::run_episode(&mut adapter, plant, &mut rng, false)?;
        log.push(e);
        let best = auv_task::best_so_far(log);
        pb.set_message(format!("best J {:6.2}", best[best.len() - 1]));
        pb.inc(1);
    }
    if let Some(pb) = &local_bar {
        pb.finish();
    }

    let phase1 = adapter
        .optimizer()
        .global()
        .best()
        .ok_or("the global phase told nothing")?
        .theta;
    // After the hand-over, TwoPhase::best is the local phase's best: what the robot measured
    // (the phases scored in different currents, so their costs are never compared).
    let learned = adapter.deployed_theta();
    let phase1_real = auv_task::evaluate(phase1, &mut real, &mut rng, true)?;
    let learned_real = auv_task::evaluate(learned, &mut real, &mut rng, true)?;

    let first = |v: &[auv_task::AuvEpisode]| {
        auv_task::episodes_to_success(v).map_or("never".to_string(), |k| k.to_string())
    };
    let best =
        |v: &[auv_task::AuvEpisode]| auv_task::best_so_far(v).last().copied().unwrap_or(f32::NAN);
    println!();
    println!("| policy | current | d (m) | t_D (s) | J |");
    println!("| --- | --- | ---: | ---: | ---: |");
    let row = |name: &str, current: &str, e: &auv_task::AuvEpisode| {
        println!(
            "| {name} | {current} | {:.2} | {:.1} | {:.2} |",
            e.min_distance,
            e.time_within,
            e.reward()
        );
    };
    row("bare PD", "0.6 m/s (real)", &bare);
    row("bare PD", "0.5 m/s (simulator)", &bare_sim);
    row("phase-1 best (CRS)", "0.6 m/s (real)", &phase1_real);
    row("learned (phase 2)", "0.6 m/s (real)", &learned_real);
    println!();
    println!(
        "global phase: {} episodes in the simulator, first J > -1 at episode {}, best J {:.2}",
        global.len(),
        first(&global),
        best(&global)
    );
    println!(
        "local phase: {} episodes in the real current from the global best, first J > -1 at \
         episode {}, best J {:.2}",
        local.len(),
        first(&local),
        best(&local)
    );
    println!("learned W = {:.3?}", learned.as_slice());

    // The hand-over to the robot: the local phase from the global phase's best, as the
    // persistent PIL firmware keeps it on flash (a checkpoint record).
    let handoff = auv_survey::checkpoint::handoff(phase1, auv_survey::SEED)?;
    let mut buf = [0u8; auv_survey::checkpoint::RECORD];
    let record = ctrl_adapt::record::save(&handoff, &mut buf)?;
    let handoff_path = o.out.join(HANDOFF_FILE);
    std::fs::write(&handoff_path, &record)?;
    println!(
        "hand-over: the local phase from the global best, {} B checkpoint in {} \
         (cargo run --release -p host-tests --bin pil -- --persist --handoff {})",
        record.len(),
        handoff_path.display(),
        handoff_path.display()
    );

    let values = |v: &[auv_task::AuvEpisode]| -> Vec<f64> {
        v.iter().map(|e| f64::from(e.reward())).collect()
    };
    let bests = |v: &[auv_task::AuvEpisode]| -> Vec<f64> {
        auv_task::best_so_far(v)
            .into_iter()
            .map(f64::from)
            .collect()
    };
    let (gv, gb, lv, lb) = (
        values(&global),
        bests(&global),
        values(&local),
        bests(&local),
    );
    let curves_path = o.out.join("auv_learning_curves.svg");
    plots::learning_curves(
        &curves_path,
        &[
            Curve {
                title: "phase 1: CRS in the simulator (0.5 m/s)",
                values: &gv,
                best: &gb,
                best_label: "best single episode so far (simulator; the table re-runs it)",
                log_y: false,
                threshold: Some((-1.0, "J = -1 (within 1 m)")),
            },
            Curve {
                title: "phase 2: coordinate search, real (0.6 m/s)",
                values: &lv,
                best: &lb,
                best_label: "best single episode so far (noisy; re-run: the table)",
                log_y: false,
                threshold: Some((-1.0, "J = -1 (within 1 m)")),
            },
        ],
        "reward J",
    )?;
    let config = real.config();
    let tracks_path = o.out.join("auv_trajectories.svg");
    let track = |e: &auv_task::AuvEpisode| e.trajectory.clone().unwrap_or_default();
    let (tb, tp, tl) = (track(&bare), track(&phase1_real), track(&learned_real));
    plots::auv_trajectories(
        &tracks_path,
        &[
            Track {
                name: "bare PD",
                points: &tb,
            },
            Track {
                name: "phase-1 policy",
                points: &tp,
            },
            Track {
                name: "learned policy",
                points: &tl,
            },
        ],
        config.target,
        config.target_radius,
        config.current_depth,
        config.seabed_depth,
        "AUV in the real 0.6 m/s current (x-z; start at y = 2 m)",
    )?;
    println!(
        "figures: {} and {}",
        curves_path.display(),
        tracks_path.display()
    );
    Ok(())
}

fn hopper_demo(o: &Options) -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "Hopping leg (Hwangbo et al., section IV): hold a 0.6 m apex while 0 / 1.5 / 5.5 cm \
         blocks are slid under the foot unseen"
    );
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(o.seed);
    let budget = hopper_task::LEARNING_EPISODES;
    let mut adapter = hopper_task::adapter(
        hopper_task::coordinate_search(Vector::zeros(), budget)?,
        budget,
        Vector::zeros(),
    )?;
    let pb = bar(u64::from(budget), "learning");
    let mut costs = Vec::new();
    for _ in 0..budget {
        let mut course = hopper_task::training_course();
        let e = hopper_task::run_episode(&mut adapter, &mut course, &mut rng, false)?;
        costs.push(f64::from(e.report.cost));
        let best = adapter.optimizer().best().map_or(f32::NAN, |b| b.cost);
        pb.set_message(format!("best cost {best:.2e}"));
        pb.inc(1);
    }
    pb.finish();
    let learned = adapter.deployed_theta();
    // A course neither policy has seen.
    let eval_seed = 10_000 + o.seed;
    let before = hopper_task::evaluate(
        Vector::zeros(),
        &mut hopper_task::plant(true, eval_seed),
        &mut rng,
        false,
    )?;
    let after = hopper_task::evaluate(
        learned,
        &mut hopper_task::plant(true, eval_seed),
        &mut rng,
        false,
    )?;
    println!();
    println!("| policy | hops | apex mean (m) | apex spread after 3 hops (cm) | cost |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    for (name, e) in [
        ("initial (tuned on flat ground)", &before),
        ("learned", &after),
    ] {
        println!(
            "| {name} | {} | {:.3} | {:.1} | {:.2e} |",
            e.hops(),
            e.apex_mean(),
            e.apex_spread() * 100.0,
            e.report.cost
        );
    }
    let mut best = Vec::with_capacity(costs.len());
    let mut b = f64::INFINITY;
    for c in &costs {
        b = b.min(*c);
        best.push(b);
    }
    let curve_path = o.out.join("hopper_learning_curve.svg");
    plots::learning_curves(
        &curve_path,
        &[Curve {
            title: "coordinate search on the training course",
            values: &costs,
            best: &best,
            best_label: "best so far",
            log_y: true,
            threshold: None,
        }],
        "cost",
    )?;
    let apex_path = o.out.join("hopper_apex_heights.svg");
    plots::apex_heights(
        &apex_path,
        &[
            Hops {
                name: "initial policy",
                apexes: &before.apexes,
                grounds: &before.grounds,
            },
            Hops {
                name: "learned policy",
                apexes: &after.apexes,
                grounds: &after.grounds,
            },
        ],
        f64::from(hopper_task::SET_HEIGHT),
        "apex height per hop over random blocks (unseen course)",
    )?;
    println!(
        "figures: {} and {}",
        curve_path.display(),
        apex_path.display()
    );
    Ok(())
}
