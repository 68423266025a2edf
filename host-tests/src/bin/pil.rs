//! Processor-in-the-loop run of the AUV survey: starts the `pil` firmware on QEMU's
//! mps2-an386 (the library's `Adapter` with the 18-parameter corrected PD and its optimizer),
//! simulates the AUV here, exchanges one state frame and one action frame per control tick
//! over the emulated UART, and prints the learning curve.
//!
//! ```sh
//! (cd examples/target-rig && cargo build --release)
//! cargo run --release -p host-tests --bin pil -- [--optimizer coordinate|sracos|cem|linebo]
//!     [--elf PATH] [--episodes N] [--ticks K] [--no-faults] [--no-learning-check]
//!     [--firmware-log PATH]
//! ```
//!
//! The run: one episode of the bare PD on the target (`Nominal`), N learning episodes
//! (default 150, the paper's local phase), one episode of the best θ found (`Deploy`), in the
//! paper's "real" 0.6 m/s current without noise (so a run is exactly repeatable). The
//! firmware binary must match `--optimizer` (`pil`, `pil_sracos`, `pil_cem`, `pil_line_bo`; the default ELF
//! follows the option); a mismatch shows as a failed comparison with the reference.
//!
//! Exits non-zero unless (1) the firmware exits cleanly, (2) every injected fault (a
//! corrupted or dropped state frame) was answered with the nominal fallback, (3) the PIL
//! run's episode returns (the host's and the firmware's) match the pure-host reference run
//! of the same configuration within [`MATCH_TOLERANCE`] and every θ is identical, and (4) the
//! learned policy beats the bare PD: the deployed episode's return (host measure) is above
//! the bare PD's.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use auv_survey::{self as auv, AuvLearner, Report, SEED};
use ctrl_adapt::controller::Controller as _;
use ctrl_adapt::controller::Mode;
use ctrl_adapt::optimizer::AnyOptimizer;
use ctrl_adapt::optimizer::{Optimizer, Vector};
use host_tests::auv::AuvConfig;
#[path = "pil/persist.rs"]
mod persist;

use host_tests::pil::{
    AuvPlant, EpisodeRecord, FaultPlan, PilPlant, Qemu, RunConfig, reference_run, run_episodes,
};

/// Tolerance between the PIL run and the pure-host reference, on every episode return
/// (m or s: |a − b| ≤ tolerance · max(1, |b|)). f32 on the target vs f32 on the host: both
/// IEEE 754 single precision with round-to-nearest and no fused multiply-add, so they are
/// expected to agree exactly; the tolerance is the claim.
const MATCH_TOLERANCE: f64 = 1e-4;
/// Seed of the AUV plant (no disturbance is on, so it draws nothing).
const PLANT_SEED: u64 = 1;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Firmware {
    Coordinate,
    Sracos,
    Cem,
    LineBo,
}

impl Firmware {
    /// The optimizer this firmware runs, built as the firmware builds it.
    fn optimizer(self) -> Result<AnyAuvOptimizer, ctrl_adapt::optimizer::Error> {
        Ok(match self {
            Self::Coordinate => auv::coordinate_search(u32::MAX)?.into(),
            Self::Sracos => auv::sracos(u32::MAX)?.into(),
            Self::Cem => auv::cem(u32::MAX)?.into(),
            Self::LineBo => auv::line_bo(u32::MAX)?.into(),
        })
    }

    fn elf_name(self, persist: bool) -> &'static str {
        match self {
            Self::Coordinate if persist => "pil_persist",
            Self::Coordinate => "pil",
            Self::Sracos => "pil_sracos",
            Self::Cem => "pil_cem",
            Self::LineBo => "pil_line_bo",
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Self::Coordinate => "CoordinateSearch<18> (step 0.25, tolerance 1e-3)",
            Self::Sracos => "Sracos<18> (ZOOpt defaults)",
            Self::Cem => "DiagonalCem<18, 10, 5> (CMA-ES weights, sigma0 0.25)",
            Self::LineBo => {
                "LineBo<18, 64> (sigma_f = the bare cost, length scale 0.15, no threshold)"
            }
        }
    }
}

struct Args {
    firmware: Firmware,
    elf: Option<PathBuf>,
    episodes: u16,
    ticks: u16,
    faults: bool,
    /// Require the learned policy to beat the bare PD (off for short smoke runs of the global
    /// optimizers, whose first episodes are random draws over the box).
    check_learning: bool,
    log: PathBuf,
    /// The persistent firmware (`pil_persist`): an uninterrupted run, then one killed at
    /// seeded points, compared bit for bit.
    persist: bool,
    /// Seeded kill points besides the two fixed ones (persistent run).
    kills: u32,
    kill_seed: u64,
    /// The host demo's checkpoint to start from (persistent run).
    handoff: Option<PathBuf>,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        firmware: Firmware::Coordinate,
        elf: None,
        episodes: 150,
        ticks: auv::TICKS,
        faults: true,
        check_learning: true,
        log: std::env::temp_dir().join("ctrl-adapt-pil-firmware.log"),
        persist: false,
        kills: 6,
        kill_seed: 2026,
        handoff: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = || it.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--optimizer" => {
                args.firmware = match value()?.as_str() {
                    "coordinate" => Firmware::Coordinate,
                    "sracos" => Firmware::Sracos,
                    "cem" => Firmware::Cem,
                    "linebo" => Firmware::LineBo,
                    other => return Err(format!("unknown optimizer {other}")),
                }
            }
            "--elf" => args.elf = Some(value()?.into()),
            "--episodes" => {
                args.episodes = value()?.parse().map_err(|e| format!("--episodes: {e}"))?
            }
            "--ticks" => args.ticks = value()?.parse().map_err(|e| format!("--ticks: {e}"))?,
            "--no-faults" => args.faults = false,
            "--no-learning-check" => args.check_learning = false,
            "--firmware-log" => args.log = value()?.into(),
            "--persist" => args.persist = true,
            "--kills" => args.kills = value()?.parse().map_err(|e| format!("--kills: {e}"))?,
            "--kill-seed" => {
                args.kill_seed = value()?.parse().map_err(|e| format!("--kill-seed: {e}"))?
            }
            "--handoff" => args.handoff = Some(value()?.into()),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if (args.handoff.is_some() || args.kills != 6) && !args.persist {
        return Err("--handoff and --kills need --persist".into());
    }
    if args.persist && args.firmware != Firmware::Coordinate {
        return Err("--persist runs the coordinate-search firmware (pil_persist)".into());
    }
    if args.episodes > u16::MAX - 2 {
        return Err("--episodes: at most 65533".into());
    }
    Ok(args)
}

fn plant() -> AuvPlant {
    AuvPlant::new(AuvConfig::REAL, PLANT_SEED)
}

/// One clean host episode (no link, no faults) of the AUV controller with correction θ
/// (`None`: the bare PD); the host's cost.
fn host_episode(theta: Option<&Vector<{ auv::P }>>, ticks: u16) -> f64 {
    let mut controller = auv::controller().expect("documented configuration");
    let mut plant = plant();
    plant.reset(0);
    for _ in 0..ticks {
        let x = Vector::<{ auv::S }>::from_column_slice(&plant.observe());
        let u = match theta {
            Some(t) => controller.corrected(t, &x, 0.0),
            None => controller.nominal(&x, 0.0),
        };
        plant.step(u.as_slice());
    }
    plant.cost()
}

/// The episode's mode: the bare PD first, then learning, the best θ last.
fn mode_of(episode: u16, learning: u16) -> Mode {
    match episode {
        0 => Mode::Nominal,
        e if e <= learning => Mode::Learn,
        _ => Mode::Deploy,
    }
}

fn differs(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(1.0)
    }
}

fn report_of(values: &[f32]) -> Report {
    Report::read(values).unwrap_or(Report {
        cost: f32::NAN,
        told: f32::NAN,
        best: f32::NAN,
        mode: None,
        faulty_ticks: 0,
    })
}

/// Any of the PIL firmwares' optimizers, as one type for the host's replay.
type AnyAuvOptimizer =
    AnyOptimizer<{ auv::P }, { auv::CEM_SAMPLES }, { auv::CEM_ELITE }, { auv::CRS_POINTS }>;

/// The firmware's learner over `optimizer`, as `examples/target-rig/src/bin/pil*.rs` build it.
fn learner<O: Optimizer<{ auv::P }>>(
    optimizer: Result<O, ctrl_adapt::optimizer::Error>,
) -> AuvLearner<O> {
    optimizer
        .and_then(|o| AuvLearner::try_new(o, u32::MAX, SEED))
        .expect("documented configuration")
}

/// The replay of `records` on the host with `learner`: (max difference of the host's
/// returns, of the firmware's returns, whether every θ is identical).
fn compare<O: Optimizer<{ auv::P }>>(
    learner: AuvLearner<O>,
    ticks: u16,
    records: &[EpisodeRecord],
) -> (f64, f64, bool) {
    let mut replay_plant = plant();
    let reference = reference_run(learner, &mut replay_plant, ticks, records);
    let (mut host, mut fw, mut theta_equal) = (0.0f64, 0.0f64, reference.len() == records.len());
    for (r, q) in records.iter().zip(&reference) {
        host = host.max(differs(r.host_cost, q.host_cost));
        let (a, b) = (report_of(&r.report), report_of(&q.report));
        for (x, y) in [(a.cost, b.cost), (a.told, b.told), (a.best, b.best)] {
            // NaN (nothing told yet) must be NaN on both sides.
            let d = match (x.is_nan(), y.is_nan()) {
                (true, true) => 0.0,
                (false, false) => differs(f64::from(x), f64::from(y)),
                _ => f64::INFINITY,
            };
            fw = fw.max(d);
        }
        theta_equal &= r.theta == q.theta;
    }
    (host, fw, theta_equal)
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("pil: {e}");
            return ExitCode::from(2);
        }
    };
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let elf = args.elf.clone().unwrap_or_else(|| {
        root.join("examples/target-rig/target/thumbv7em-none-eabihf/release")
            .join(args.firmware.elf_name(args.persist))
    });
    let learning = args.episodes;
    let total = learning + 2;
    let config = RunConfig {
        episodes: total,
        ticks: args.ticks,
        faults: if args.faults {
            FaultPlan {
                corrupt_every: 151,
                drop_every: 197,
            }
        } else {
            FaultPlan::NONE
        },
    };
    let bare = host_episode(None, args.ticks);
    println!(
        "PIL: AUV survey (0.6 m/s current) on the host; Adapter + {} in the firmware (QEMU mps2-an386)",
        args.firmware.describe()
    );
    println!(
        "1 bare-PD episode, {learning} learning episodes, 1 episode of the best theta; {} ticks of {} s; faults: {:?}",
        args.ticks,
        auv::DT,
        config.faults
    );
    println!("firmware: {}; log: {}", elf.display(), args.log.display());
    println!(
        "bare PD (host only, no faults): return J = {:.4} (J = -d if d >= D, t_D - D if d < D)\n",
        -bare
    );
    if args.persist {
        return persist::main(&args, &elf, config, bare);
    }
    println!(
        "{:>7}  {:>7}  {:>9}  {:>9}  {:>9}  {:>9}  {:>8}",
        "episode", "mode", "host J", "fw J", "fw best J", "fallbacks", "injected"
    );

    let started = Instant::now();
    let (mut qemu, mut link) = match Qemu::start(&elf, &args.log) {
        Ok(q) => q,
        Err(e) => {
            eprintln!("pil: cannot start the firmware {}: {e}", elf.display());
            return ExitCode::FAILURE;
        }
    };
    let mut run_plant = plant();
    let request = |e: u16| vec![pil_link::mode_code(mode_of(e, learning))];
    let run = run_episodes(&mut link, &mut run_plant, config, request, |r| {
        let report = report_of(&r.report);
        println!(
            "{:>7}  {:>7}  {:>9.4}  {:>9.4}  {:>9.4}  {:>9}  {:>8}",
            r.episode,
            format!("{:?}", mode_of(r.episode, learning)),
            -r.host_cost,
            -report.cost,
            -report.best,
            r.fallback_ticks.len(),
            r.injected.len(),
        );
    });
    let records = match run {
        Ok(r) => r,
        Err(e) => {
            eprintln!(
                "pil: link failed: {e} (firmware log: {})",
                args.log.display()
            );
            return ExitCode::FAILURE;
        }
    };
    let elapsed = started.elapsed();
    let status = qemu.wait(Duration::from_secs(10));

    let (worst_host, worst_fw, theta_equal) =
        compare(learner(args.firmware.optimizer()), args.ticks, &records);
    let missed: Vec<(u16, u16)> = records
        .iter()
        .flat_map(|r| {
            r.injected
                .iter()
                .filter(|(t, _)| !r.fallback_ticks.contains(t))
                .map(move |&(t, _)| (r.episode, t))
        })
        .collect();
    let injected: usize = records.iter().map(|r| r.injected.len()).sum();
    let fallbacks: usize = records.iter().map(|r| r.fallback_ticks.len()).sum();
    let deployed = records.last();
    let learned = deployed.map_or(f64::NAN, |r| r.host_cost);
    let learned_theta: Option<Vector<{ auv::P }>> = deployed
        .filter(|r| r.theta.len() == auv::P)
        .map(|r| Vector::from_column_slice(&r.theta));
    let learned_clean = learned_theta
        .as_ref()
        .map_or(f64::NAN, |t| host_episode(Some(t), args.ticks));
    let on_target_bare = records.first().map_or(f64::NAN, |r| r.host_cost);
    let ticks_total = u32::from(total) * u32::from(args.ticks);

    println!();
    println!(
        "{} control ticks in {:.1} s ({:.0} µs per tick round trip)",
        ticks_total,
        elapsed.as_secs_f64(),
        elapsed.as_secs_f64() * 1e6 / f64::from(ticks_total.max(1))
    );
    println!(
        "faults: {injected} injected, {} answered with the fallback, {} fallbacks not injected (missed deadlines), {} corrupt frames from the firmware",
        injected - missed.len(),
        fallbacks - (injected - missed.len()),
        link.corrupt_received
    );
    println!(
        "PIL vs pure-host reference: max difference of the returns {worst_host:.2e} (host measure), {worst_fw:.2e} (firmware's cost, told, best); theta {} (tolerance {MATCH_TOLERANCE:.0e} relative, absolute below 1)",
        if theta_equal {
            "identical"
        } else {
            "DIFFERENT"
        }
    );
    println!(
        "return J: bare PD {:.4} (on the target with faults: {:.4}); learned, deployed on the target {:.4} (the same theta on the host without faults: {:.4})",
        -bare, -on_target_bare, -learned, -learned_clean
    );
    if let Some(t) = learned_theta {
        println!("learned W (row-major 3x6, rows x, y, z; columns e_x e_y e_z v_x v_y v_z):");
        for row in t.as_slice().chunks(auv::S) {
            println!("  {row:>7.3?}");
        }
    }

    let mut ok = true;
    match status {
        Ok(s) if s.success() => {}
        Ok(s) => {
            eprintln!("FAIL: the firmware exited with {s}");
            ok = false;
        }
        Err(e) => {
            eprintln!("FAIL: {e}");
            ok = false;
        }
    }
    if !missed.is_empty() {
        eprintln!(
            "FAIL: injected faults not answered with the fallback (episode, tick): {missed:?}"
        );
        ok = false;
    }
    if !(worst_host <= MATCH_TOLERANCE && worst_fw <= MATCH_TOLERANCE && theta_equal) {
        eprintln!("FAIL: the PIL run does not match the pure-host reference");
        ok = false;
    }
    if args.check_learning && learned.partial_cmp(&bare) != Some(std::cmp::Ordering::Less) {
        eprintln!("FAIL: the learned policy did not beat the bare PD");
        ok = false;
    }
    if ok {
        println!("ok: PIL run passed");
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
