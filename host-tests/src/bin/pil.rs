//! Processor-in-the-loop run: starts the `pil` firmware on QEMU's mps2-an386, simulates the
//! plant here, exchanges one state frame and one action frame per control tick over the
//! emulated UART, and prints the learning curve.
//!
//! ```sh
//! (cd examples/firmware && cargo build --release)
//! cargo run --release -p host-tests --bin pil -- [--elf PATH] [--episodes N] [--ticks K]
//!                                                 [--no-faults] [--firmware-log PATH]
//! ```
//!
//! Exits non-zero unless (1) the firmware exits cleanly, (2) every injected fault (a
//! corrupted or dropped state frame) was answered with the nominal fallback, (3) the
//! firmware's episode costs and the host's match the pure-host reference run of the same
//! configuration within a relative 1e-4, and (4) the learned controller beats the bare PD:
//! the mean host cost of the last five episodes is below the PD's.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use host_tests::pil::{
    DoubleIntegrator, FaultPlan, PilPlant, Qemu, RunConfig, reference_run, run_episodes,
};
use pil_link::standin::{PdCorrection, SEED, StandinConfig};

/// Relative tolerance between the PIL run and the pure-host reference (f32 on the target vs
/// f32 on the host: both IEEE 754 single precision with round-to-nearest and no fused
/// multiply-add, so they are expected to agree exactly; the tolerance is the claim).
const MATCH_TOLERANCE: f64 = 1e-4;

struct Args {
    elf: PathBuf,
    episodes: u16,
    ticks: u16,
    faults: bool,
    log: PathBuf,
}

fn parse_args() -> Result<Args, String> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut args = Args {
        elf: root.join("examples/firmware/target/thumbv7em-none-eabihf/release/pil"),
        episodes: 40,
        ticks: 200,
        faults: true,
        log: std::env::temp_dir().join("ctrl-adapt-pil-firmware.log"),
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = || it.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--elf" => args.elf = value()?.into(),
            "--episodes" => {
                args.episodes = value()?.parse().map_err(|e| format!("--episodes: {e}"))?
            }
            "--ticks" => args.ticks = value()?.parse().map_err(|e| format!("--ticks: {e}"))?,
            "--no-faults" => args.faults = false,
            "--firmware-log" => args.log = value()?.into(),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(args)
}

/// The bare PD's episode cost (no correction, no faults), on the host.
fn nominal_cost(ticks: u16) -> f64 {
    let pd = PdCorrection::try_new(StandinConfig::DEFAULT, SEED).expect("valid config");
    let mut plant = DoubleIntegrator::DEMO;
    plant.reset(0);
    (0..ticks)
        .map(|_| {
            let u = pd.nominal(plant.x as f32, plant.v as f32);
            plant.step(&[u])
        })
        .sum()
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-12)
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("pil: {e}");
            return ExitCode::from(2);
        }
    };
    let config = RunConfig {
        episodes: args.episodes,
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
    let nominal = nominal_cost(args.ticks);
    println!(
        "PIL: 1-D double integrator (d = {}) on the host, PD + coordinate-search-tuned correction in the firmware (QEMU mps2-an386)",
        DoubleIntegrator::DEMO.disturbance
    );
    println!(
        "{} episodes x {} ticks; faults: {:?}; firmware log: {}",
        args.episodes,
        args.ticks,
        config.faults,
        args.log.display()
    );
    println!("bare PD cost: {nominal:.6}\n");
    println!(
        "{:>7}  {:>10}  {:>10}  {:>10}  {:>9}  {:>8}  theta",
        "episode", "host cost", "fw cost", "fw best", "fallbacks", "injected"
    );

    let started = Instant::now();
    let (mut qemu, mut link) = match Qemu::start(&args.elf, &args.log) {
        Ok(q) => q,
        Err(e) => {
            eprintln!("pil: cannot start the firmware {}: {e}", args.elf.display());
            return ExitCode::FAILURE;
        }
    };
    let mut plant = DoubleIntegrator::DEMO;
    let run = run_episodes(&mut link, &mut plant, config, |r| {
        let value = |i: usize| r.report.get(i).copied().unwrap_or(f32::NAN);
        println!(
            "{:>7}  {:>10.6}  {:>10.6}  {:>10.6}  {:>9}  {:>8}  {:.3?}",
            r.episode,
            r.host_cost,
            value(0),
            value(1),
            r.fallback_ticks.len(),
            r.injected.len(),
            r.theta
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

    let controller = PdCorrection::try_new(StandinConfig::DEFAULT, SEED).expect("valid config");
    let mut replay_plant = DoubleIntegrator::DEMO;
    let reference = reference_run(controller, &mut replay_plant, args.ticks, &records);
    let mut worst_host = 0.0f64;
    let mut worst_fw = 0.0f64;
    let mut theta_equal = true;
    for (r, q) in records.iter().zip(&reference) {
        worst_host = worst_host.max(relative(r.host_cost, q.host_cost));
        let fw = |v: &[f32]| f64::from(v.first().copied().unwrap_or(f32::NAN));
        worst_fw = worst_fw.max(relative(fw(&r.report), fw(&q.report)));
        theta_equal &= r.theta == q.theta;
    }
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
    let tail = records.len().clamp(1, 5);
    let learned = records
        .iter()
        .rev()
        .take(tail)
        .map(|r| r.host_cost)
        .sum::<f64>()
        / tail as f64;
    let ticks_total = u32::from(args.episodes) * u32::from(args.ticks);

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
        "PIL vs pure-host reference: max relative difference {worst_host:.2e} (host cost), {worst_fw:.2e} (firmware cost), theta {} (tolerance {MATCH_TOLERANCE:.0e})",
        if theta_equal {
            "identical"
        } else {
            "DIFFERENT"
        }
    );
    println!(
        "learning: mean cost of the last {tail} episodes {learned:.6} vs bare PD {nominal:.6} ({:+.1}%)",
        100.0 * (learned - nominal) / nominal
    );

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
    if learned.partial_cmp(&nominal) != Some(std::cmp::Ordering::Less) {
        eprintln!("FAIL: learning did not beat the bare PD");
        ok = false;
    }
    if ok {
        println!("ok: PIL run passed");
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
