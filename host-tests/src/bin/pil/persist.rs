//! `pil --persist`: the `pil_persist` firmware, whose learner is checkpointed on a flash the
//! host keeps ([`host_tests::pil_flash`]). Runs the episodes once without interruption, then
//! again from the same flash image with QEMU killed (SIGKILL) at seeded points in the middle
//! of episodes and in the middle of flash writes and restarted, and requires the two runs to
//! be bit-identical: every θ, every report, every host return, and the final checkpoint.
//! With `--handoff FILE` both runs start from the host demo's checkpoint of its global phase.

use std::path::Path;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use auv_survey::checkpoint::{AuvCheckpoint, ITEM, RECORD, SLOTS};
use auv_survey::{self as auv, AuvLearner};
use ctrl_adapt::checkpoint::CheckpointStore;
use ctrl_adapt::optimizer::{CoordinateSearch, Vector};
use ctrl_adapt::record;
use host_tests::pil::{EpisodeRecord, RunConfig};
use host_tests::pil_flash::{
    FlashImage, ImageFlash, KillPoint, PersistentRun, Shared, make_pipes, run_persistent,
};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

use super::{Args, MATCH_TOLERANCE, compare, host_episode, mode_of, plant, report_of};

type Checkpoint = AuvCheckpoint<CoordinateSearch<{ auv::P }>>;

/// The checkpoint in `image`'s newest intact slot, and its record's bytes.
fn newest(image: &mut FlashImage) -> Result<(Checkpoint, Vec<u8>), String> {
    let mut store =
        CheckpointStore::try_new(ImageFlash(image), SLOTS).map_err(|e| e.to_string())?;
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let state = store
        .load::<Checkpoint>(&mut rec, &mut item)
        .map_err(|e| e.to_string())?
        .ok_or("no checkpoint on the flash")?;
    let bytes = record::save(&state, &mut rec)
        .map_err(|e| e.to_string())?
        .to_vec();
    Ok((state, bytes))
}

/// The flash image the runs start from: erased, or holding the hand-over checkpoint.
fn initial_image(
    dir: &Path,
    handoff: Option<&Path>,
) -> Result<Option<(Vec<u8>, Checkpoint)>, String> {
    let Some(path) = handoff else { return Ok(None) };
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let state: Checkpoint = record::load(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut image =
        FlashImage::create(&dir.join("handoff.bin"), None).map_err(|e| e.to_string())?;
    let mut store =
        CheckpointStore::try_new(ImageFlash(&mut image), SLOTS).map_err(|e| e.to_string())?;
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    store
        .save(&state, &mut rec, &mut item)
        .map_err(|e| e.to_string())?;
    Ok(Some((image.bytes().to_vec(), state)))
}

/// The kill points (runs of at least 48 episodes): three fixed kinds early in the run, each at
/// a seeded episode in the 10 after the previous one: the save's last flash operation torn
/// (part of its commit; no restart before it, so the flash is laid out as in the
/// uninterrupted run), a kill just after a save, and the first page erase from there on torn;
/// then `k` seeded points over the rest of the run, alternately mid-episode (a seeded tick)
/// and mid-save (a seeded operation of that save; its count in the uninterrupted run).
fn kill_plan(k: u32, seed: u64, episodes: u16, ticks: u16, save_ops: &[u64]) -> Vec<KillPoint> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut draw = |n: u64| rng.next_u64() % n.max(1);
    let mut kills = Vec::new();
    if episodes < 48 {
        return kills;
    }
    let commit = 1 + draw(10) as u16;
    kills.push(KillPoint::MidSave {
        episode: commit,
        op: save_ops[usize::from(commit)],
    });
    let after = commit + 1 + draw(10) as u16;
    kills.push(KillPoint::AfterSave { episode: after });
    // A page erase torn: the first one from a seeded episode in the 10 after that on.
    let erase = after + 1 + draw(10) as u16;
    kills.push(KillPoint::NextErase { episode: erase });
    // Past the episodes an erase may still be pending for (one every few saves).
    let first = erase + 12;
    let mut used = std::collections::BTreeSet::new();
    let span = u64::from(episodes - first);
    for i in 0..u64::from(k).min(span) {
        let episode = loop {
            let e = first + draw(span) as u16;
            if used.insert(e) {
                break e;
            }
        };
        kills.push(if i % 2 == 0 {
            KillPoint::MidEpisode {
                episode,
                tick: draw(u64::from(ticks)) as u16,
            }
        } else {
            KillPoint::MidSave {
                episode,
                op: 1 + draw(save_ops[usize::from(episode)]),
            }
        });
    }
    kills.sort_by_key(|k| (k.episode(), !matches!(k, KillPoint::MidEpisode { .. })));
    kills
}

fn bits(r: &EpisodeRecord) -> (Vec<u32>, Vec<u32>, u64, &[u16]) {
    (
        r.theta.iter().map(|v| v.to_bits()).collect(),
        r.report.iter().map(|v| v.to_bits()).collect(),
        r.host_cost.to_bits(),
        &r.fallback_ticks,
    )
}

fn row(r: &EpisodeRecord, learning: u16) {
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
}

struct Run {
    run: PersistentRun,
    image: FlashImage,
    seconds: f64,
}

fn run(
    args: &Args,
    elf: &Path,
    dir: &Path,
    initial: Option<&[u8]>,
    config: RunConfig,
    kills: &[KillPoint],
    print: bool,
) -> Result<Run, String> {
    let learning = args.episodes;
    let image = FlashImage::create(&dir.join("flash.bin"), initial).map_err(|e| e.to_string())?;
    let shared = Arc::new(Mutex::new(Shared {
        image,
        cut_at: None,
        cut_erase: false,
        torn: None,
    }));
    let started = Instant::now();
    let mut run_plant = plant();
    let request = |e: u16| vec![pil_link::mode_code(mode_of(e, learning))];
    let run = run_persistent(
        elf,
        &args.log,
        dir,
        &shared,
        &mut run_plant,
        config,
        request,
        kills,
        |r| {
            if print {
                row(r, learning);
            }
        },
    )
    .map_err(|e| format!("{e} (firmware log: {})", args.log.display()))?;
    let seconds = started.elapsed().as_secs_f64();
    let image = Arc::try_unwrap(shared)
        .map_err(|_| "the flash is still shared".to_string())?
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .image;
    Ok(Run {
        run,
        image,
        seconds,
    })
}

/// The persistent run; `bare` is the bare PD's host cost.
pub fn main(args: &Args, elf: &Path, config: RunConfig, bare: f64) -> ExitCode {
    match persist(args, elf, config, bare) {
        Ok(true) => {
            println!("ok: persistent PIL run passed");
            ExitCode::SUCCESS
        }
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("pil --persist: {e}");
            ExitCode::FAILURE
        }
    }
}

fn persist(args: &Args, elf: &Path, config: RunConfig, bare: f64) -> Result<bool, String> {
    let dir = std::env::temp_dir().join(format!("ctrl-adapt-pil-flash-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    make_pipes(&dir).map_err(|e| e.to_string())?;
    let outcome = persist_in(args, elf, config, bare, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    outcome
}

fn persist_in(
    args: &Args,
    elf: &Path,
    config: RunConfig,
    bare: f64,
    dir: &Path,
) -> Result<bool, String> {
    let handoff = initial_image(dir, args.handoff.as_deref())?;
    let (initial, start) = match handoff {
        Some((image, state)) => {
            println!(
                "hand-over: {} ({} B record) saved into the flash; the local phase starts from the global phase's best W",
                args.handoff
                    .as_deref()
                    .map_or(String::new(), |p| p.display().to_string()),
                record::save(&state, &mut [0u8; RECORD]).map_or(0, |r| r.len()),
            );
            (Some(image), state)
        }
        None => {
            println!("no hand-over: erased flash, the local phase starts from W = 0");
            let fresh = auv::coordinate_search(u32::MAX)
                .and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED))
                .map_err(|e| e.to_string())?;
            (None, Checkpoint::fresh(fresh))
        }
    };
    println!(
        "\nuninterrupted run (pil_persist, checkpoint after every episode):\n{:>7}  {:>7}  {:>9}  {:>9}  {:>9}  {:>9}  {:>8}",
        "episode", "mode", "host J", "fw J", "fw best J", "fallbacks", "injected"
    );
    let plain = run(args, elf, dir, initial.as_deref(), config, &[], true)?;
    let saves = plain.run.save_ops.len();
    println!(
        "{} episodes in {:.1} s; flash: {} programs ({} B), {} page erases in {} saves",
        plain.run.records.len(),
        plain.seconds,
        plain.image.programs,
        plain.image.programmed_bytes,
        plain.image.erases,
        saves
    );

    let kills = kill_plan(
        args.kills,
        args.kill_seed,
        config.episodes,
        config.ticks,
        &plain.run.save_ops,
    );
    println!(
        "\nkilled run: the same from the same flash image, QEMU killed (SIGKILL) at {} points (seed {}) and restarted",
        kills.len(),
        args.kill_seed
    );
    let killed = run(args, elf, dir, initial.as_deref(), config, &kills, false)?;
    println!(
        "{:>26}  {:>58}  {:>10}",
        "kill point", "what was lost", "resumed at"
    );
    for k in &killed.run.kills {
        let (point, lost) = match k.point {
            KillPoint::MidEpisode { episode, tick } => (
                format!("episode {episode}, tick {tick}"),
                "the episode".to_string(),
            ),
            KillPoint::MidSave { episode, op } => (
                format!("save {episode}, flash op {op}"),
                if k.torn {
                    format!(
                        "the save ({} {op} torn; {} ops in the uninterrupted run)",
                        if k.torn_erase { "erase" } else { "program" },
                        plain.run.save_ops[usize::from(episode)]
                    )
                } else {
                    format!("nothing (the save had {} ops)", k.ops_done)
                },
            ),
            KillPoint::AfterSave { episode } => {
                (format!("after save {episode}"), "nothing".to_string())
            }
            KillPoint::NextErase { episode } => (
                format!("first erase from save {episode}"),
                format!(
                    "the save of episode {} (its erase {} torn)",
                    k.expected,
                    k.ops_done + 1
                ),
            ),
        };
        println!("{point:>26}  {lost:>58}  {:>10}", k.resumed_at);
    }
    println!(
        "{} boots, {} episodes run for {} ({} rerun) in {:.1} s",
        killed.run.boots,
        killed.run.episodes_run,
        killed.run.records.len(),
        killed.run.episodes_run as usize - killed.run.records.len(),
        killed.seconds
    );

    // Bit for bit.
    let mut differing = Vec::new();
    for (a, b) in plain.run.records.iter().zip(&killed.run.records) {
        if bits(a) != bits(b) || a.injected != b.injected {
            differing.push(a.episode);
        }
    }
    let (mut plain_image, mut killed_image) = (plain.image, killed.image);
    let (final_plain, plain_bytes) = newest(&mut plain_image)?;
    let (_, killed_bytes) = newest(&mut killed_image)?;
    let same_final = plain_bytes == killed_bytes;
    println!(
        "killed vs uninterrupted: {} of {} episodes differ (theta, report, host return, fallback ticks, as bits); final checkpoint ({} B record) {}",
        differing.len(),
        plain.run.records.len(),
        plain_bytes.len(),
        if same_final { "identical" } else { "DIFFERENT" }
    );
    println!(
        "bytes per checkpoint: record {} B; flash programmed {:.0} B and {:.2} page erases per save (uninterrupted run)",
        plain_bytes.len(),
        plain_image.programmed_bytes as f64 / saves as f64,
        plain_image.erases as f64 / saves as f64
    );

    // The uninterrupted run against the pure-host replay, and the usual checks.
    let (worst_host, worst_fw, theta_equal) =
        compare(start.learner, config.ticks, &plain.run.records);
    println!(
        "uninterrupted PIL vs pure-host reference: max difference of the returns {worst_host:.2e} (host measure), {worst_fw:.2e} (firmware's); theta {}",
        if theta_equal {
            "identical"
        } else {
            "DIFFERENT"
        }
    );
    let missed: usize = plain
        .run
        .records
        .iter()
        .map(|r| {
            r.injected
                .iter()
                .filter(|(t, _)| !r.fallback_ticks.contains(t))
                .count()
        })
        .sum();
    let deployed = plain.run.records.last();
    let learned = deployed.map_or(f64::NAN, |r| r.host_cost);
    let learned_clean = deployed
        .filter(|r| r.theta.len() == auv::P)
        .map_or(f64::NAN, |r| {
            host_episode(Some(&Vector::from_column_slice(&r.theta)), config.ticks)
        });
    println!(
        "return J: bare PD {:.4}; learned, deployed on the target {:.4} (the same theta on the host without faults: {:.4}); next episode in the final checkpoint {}",
        -bare, -learned, -learned_clean, final_plain.next_episode
    );

    // A deadline the firmware missed (the host too loaded) is a fallback nobody injected: it
    // changes that episode, in one run and not the other.
    let missed_deadlines = |r: &PersistentRun| -> usize {
        r.records
            .iter()
            .map(|e| {
                e.fallback_ticks
                    .iter()
                    .filter(|t| !e.injected.iter().any(|(i, _)| i == *t))
                    .count()
            })
            .sum()
    };
    let (late_plain, late_killed) = (missed_deadlines(&plain.run), missed_deadlines(&killed.run));
    println!(
        "fallbacks not injected (missed deadlines): {late_plain} in the uninterrupted run, {late_killed} in the killed run"
    );
    let mut ok = true;
    if !differing.is_empty() || !same_final {
        eprintln!(
            "FAIL: the killed run differs from the uninterrupted one (episodes {differing:?}){}",
            if late_plain + late_killed > 0 {
                "; a missed deadline changes an episode: rerun on a less loaded machine"
            } else {
                ""
            }
        );
        ok = false;
    }
    if !killed.run.kills.iter().any(|k| k.torn && !k.torn_erase) {
        eprintln!("FAIL: no kill tore a flash write");
        ok = false;
    }
    let erase_planned = kills
        .iter()
        .any(|k| matches!(k, KillPoint::NextErase { .. }));
    if erase_planned && !killed.run.kills.iter().any(|k| k.torn_erase) {
        eprintln!("FAIL: no kill tore a page erase");
        ok = false;
    }
    if missed > 0 {
        eprintln!("FAIL: {missed} injected faults not answered with the fallback");
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
    Ok(ok)
}
