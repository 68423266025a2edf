//! The AUV experiments of Leonetti et al. 2012, section 5, through the library's own
//! controller stack ([`Adapter`](ctrl_adapt::controller::Adapter) over `CorrectedPd`, the
//! optimizers unchanged), over 10 seeds. Heavy: compiled in release builds only (debug
//! `cargo test` skips it),
//!
//! ```text
//! cargo test --release -p experiments --test auv_experiments -- --nocapture
//! ```
//!
//! Each seed s fixes the disturbances of the "real" plant (0.6 m/s, seed s), of the
//! "simulator" (0.5 m/s, seed 100 + s) and the optimizers' RNG (seed s). Episodes are 24 s;
//! the reward is the paper's J (cost −J); "success" is J > −1, i.e. within D = 1 m.

#![cfg(not(debug_assertions))]

use ctrl_adapt::controller::Mode;
use ctrl_adapt::optimizer::two_phase::Phase;
use ctrl_adapt::optimizer::{TwoPhase, Vector};
use host_tests::auv::AuvConfig;
use host_tests::auv_task::{
    self, AuvEpisode, best_so_far, episodes_to_success, global_search, local_config, plant,
    run_episode,
};
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const SEEDS: std::ops::RangeInclusive<u64> = 1..=10;
/// The global phase's budget in the simulator: the 100 initial samples and 200 CRS trials.
const GLOBAL_BUDGET: u32 = 300;
/// The local phase's budget on the "real" plant: the paper's 150 episodes.
const LOCAL_BUDGET: u32 = 150;
/// Episodes over which "better from the first episodes" is judged.
const EARLY: usize = 10;

/// One seed's run of the whole experiment.
struct SeedRun {
    bare_real: AuvEpisode,
    bare_sim: AuvEpisode,
    /// Coordinate search from W = 0 in the real current.
    from_zero: Vec<AuvEpisode>,
    /// The global phase (CRS in the simulator).
    global: Vec<AuvEpisode>,
    /// The local phase from the global best, in the real current.
    from_global: Vec<AuvEpisode>,
}

fn run_seed(seed: u64) -> SeedRun {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut real = plant(AuvConfig::REAL, seed);
    let mut sim = plant(AuvConfig::simulator(), 100 + seed);

    // Bare PD, then the coordinate search from zero, on the real plant.
    let search = auv_task::coordinate_search(Vector::zeros(), LOCAL_BUDGET).unwrap();
    let mut adapter = auv_task::adapter(search, LOCAL_BUDGET, Vector::zeros()).unwrap();
    adapter.set_mode(Mode::Nominal).unwrap();
    let bare_real = run_episode(&mut adapter, &mut real, &mut rng, false).unwrap();
    let bare_sim = run_episode(&mut adapter, &mut sim, &mut rng, false).unwrap();
    adapter.set_mode(Mode::Learn).unwrap();
    let from_zero = (0..LOCAL_BUDGET)
        .map(|_| run_episode(&mut adapter, &mut real, &mut rng, false).unwrap())
        .collect();

    // The two phases behind one optimizer: CRS in the simulator, then the coordinate search
    // from its best θ on the real plant (TwoPhase hands over when the global budget is spent).
    let two = TwoPhase::try_new(
        global_search(GLOBAL_BUDGET).unwrap(),
        GLOBAL_BUDGET,
        local_config(LOCAL_BUDGET),
    )
    .unwrap();
    let mut adapter =
        auv_task::adapter(two, GLOBAL_BUDGET + LOCAL_BUDGET, Vector::zeros()).unwrap();
    let (mut global, mut from_global) = (Vec::new(), Vec::new());
    for _ in 0..GLOBAL_BUDGET + LOCAL_BUDGET {
        match adapter.optimizer().phase() {
            Phase::Global => {
                global.push(run_episode(&mut adapter, &mut sim, &mut rng, false).unwrap())
            }
            Phase::Local => {
                from_global.push(run_episode(&mut adapter, &mut real, &mut rng, false).unwrap())
            }
        }
    }
    SeedRun {
        bare_real,
        bare_sim,
        from_zero,
        global,
        from_global,
    }
}

fn show(first: Option<usize>) -> String {
    first.map_or("-".into(), |k| k.to_string())
}

/// Checks the paper's claims on each of 10 seeds, with margins:
/// * the bare PD never gets within 1 m, in the real (0.6 m/s) or simulator (0.5 m/s) current;
/// * the global phase (CRS, 100 initial samples, simulator current) reaches J > −1 within
///   its 300 episodes;
/// * the local coordinate search on the real current reaches J > −1 within 150 episodes
///   both from W = 0 and from the global best;
/// * from the global best it is better from the first episodes: the best J over the first
///   10 episodes beats the one from W = 0.
///
/// Prints the per-seed table and the medians (the figures in findings/auv.md).
#[test]
fn auv_two_phase_experiment() {
    let runs: Vec<(u64, SeedRun)> = SEEDS.map(|s| (s, run_seed(s))).collect();
    println!(
        "seed | bare d real / sim (m) | zero: first J>-1, best J | global: first J>-1, best J | \
         from global: first J>-1, best J | best J in first {EARLY}: zero / global"
    );
    let (mut zero_first, mut global_first, mut local_first) = (vec![], vec![], vec![]);
    for (seed, r) in &runs {
        let zf = episodes_to_success(&r.from_zero);
        let gf = episodes_to_success(&r.global);
        let lf = episodes_to_success(&r.from_global);
        let (bz, bg, bl) = (
            best_so_far(&r.from_zero),
            best_so_far(&r.global),
            best_so_far(&r.from_global),
        );
        println!(
            "{seed:>4} | {:.2} / {:.2} | {:>3}, {:5.2} | {:>3}, {:5.2} | {:>3}, {:5.2} | {:5.2} / {:5.2}",
            r.bare_real.min_distance,
            r.bare_sim.min_distance,
            show(zf),
            bz[bz.len() - 1],
            show(gf),
            bg[bg.len() - 1],
            show(lf),
            bl[bl.len() - 1],
            bz[EARLY - 1],
            bl[EARLY - 1],
        );
        assert!(r.bare_real.min_distance >= 1.0 && r.bare_sim.min_distance >= 1.0);
        assert_eq!(r.global.len(), GLOBAL_BUDGET as usize);
        assert_eq!(r.from_global.len(), LOCAL_BUDGET as usize);
        assert!(
            gf.is_some(),
            "seed {seed}: the global phase never reached J > -1"
        );
        assert!(
            zf.is_some(),
            "seed {seed}: no success from zero in 150 episodes"
        );
        assert!(
            lf.is_some(),
            "seed {seed}: no success from the global best in 150 episodes"
        );
        assert!(
            bl[EARLY - 1] > bz[EARLY - 1],
            "seed {seed}: not better in the first {EARLY} episodes"
        );
        zero_first.push(zf.unwrap() as f64);
        global_first.push(gf.unwrap() as f64);
        local_first.push(lf.unwrap() as f64);
    }
    let summary = |name: &str, v: &[f64]| {
        let min = v.iter().copied().fold(f64::INFINITY, f64::min);
        let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        println!(
            "{name}: episodes to J > -1: median {}, min {min}, max {max}",
            median(v.to_vec())
        );
    };
    summary("global phase (CRS, simulator)", &global_first);
    summary("local from W = 0 (real)", &zero_first);
    summary("local from the global best (real)", &local_first);
}
