//! The change detector on the AUV survey, through the product API: an `Adapter` with the
//! seed's coordinate search learns on the disturbed "real" AUV (`auv_task::plant`, 60
//! learning episodes from the zero correction), deploys its best θ for 40 episodes with a
//! `ChangeDetector` (its defaults, chosen on Gaussian costs, never on the AUV) watching each
//! deployed episode's cost, and then the plant changes and the deployment goes on for 30
//! more episodes. Per change, over the seeds given: how many runs detected it, the median
//! delay (1 = at the first changed episode), the false alarms before the change, and how
//! much the change moved the deployed θ's cost (the median over runs of the shift of the
//! mean cost, changed episodes against the 30 deployed before the change, in standard
//! deviations of those 30: what the detector has to see). The run with no change
//! deploys 100 episodes and counts false alarms.
//!
//! ```text
//! cargo run --release -p experiments --example change_auv            # seeds 1–10
//! cargo run --release -p experiments --example change_auv -- 101 110
//! ```
//!
//! The changes: the current 1.3× stronger and turned 45° (in the horizontal plane), the
//! vehicle's mass +30 %, the thrusters' force × 0.8 (the plant has a thrust limit, not a
//! gain: its limit is scaled). Each changed plant draws its own disturbance sequence.

use ctrl_adapt::controller::{ChangeConfig, ChangeDetector, Mode, Verdict};
use ctrl_adapt::optimizer::Vector;
use host_tests::auv::AuvConfig;
use host_tests::auv_task::{self, P};
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const LEARNING: u32 = 60;
const DEPLOYED_BEFORE: usize = 40;
const DEPLOYED_AFTER: usize = 30;
const NO_CHANGE: usize = 100;

/// The changes of the study, by name.
fn changes() -> Vec<(&'static str, AuvConfig)> {
    let real = AuvConfig::REAL;
    let turned = {
        let (s, c) = (
            std::f64::consts::FRAC_PI_4.sin(),
            std::f64::consts::FRAC_PI_4.cos(),
        );
        let d = real.current_direction;
        [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]
    };
    vec![
        (
            "current ×1.3, turned 45°",
            AuvConfig {
                current_speed: real.current_speed * 1.3,
                current_direction: turned,
                ..real
            },
        ),
        (
            "mass +30 %",
            AuvConfig {
                mass: real.mass * 1.3,
                ..real
            },
        ),
        (
            "thrust × 0.8",
            AuvConfig {
                max_thrust: real.max_thrust.map(|f| f * 0.8),
                ..real
            },
        ),
    ]
}

/// One run: what the detector said on each deployed episode after the learning, and the
/// deployed episodes' costs. `change`: the plant from deployed episode `DEPLOYED_BEFORE` on.
fn run(seed: u64, change: Option<AuvConfig>, deployed: usize) -> (Vec<bool>, Vec<f32>) {
    let mut auv = auv_task::plant(AuvConfig::REAL, seed);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let search = auv_task::coordinate_search(Vector::<P>::zeros(), LEARNING).expect("valid search");
    let mut adapter = auv_task::adapter(search, LEARNING, Vector::zeros()).expect("valid adapter");
    let mut detector = ChangeDetector::try_new(ChangeConfig::DEFAULT).expect("valid detector");
    let (mut alarms, mut costs) = (Vec::new(), Vec::new());
    while alarms.len() < deployed {
        if alarms.len() == DEPLOYED_BEFORE
            && let Some(config) = change
        {
            auv = auv_task::plant(config, seed + 10_000);
        }
        let episode = auv_task::run_episode(&mut adapter, &mut auv, &mut rng, false)
            .expect("the loop's calls are in order");
        if episode.report.mode != Mode::Deploy {
            continue;
        }
        let verdict = detector
            .observe(episode.report.cost, None)
            .expect("finite costs");
        alarms.push(matches!(verdict, Verdict::Changed(_)));
        costs.push(episode.report.cost);
    }
    (alarms, costs)
}

fn main() {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("seeds are integers"))
        .collect();
    let (first, last) = match args[..] {
        [first, last] => (first, last),
        [] => (1, 10),
        _ => panic!("usage: change_auv [FIRST LAST]"),
    };
    let seeds: Vec<u64> = (first..=last).collect();
    println!("change detector on the AUV, seeds {first}–{last}, ChangeConfig::DEFAULT");
    println!(
        "| change | detected | median delay (episodes) | false alarms before it | shift of the mean cost, in standard deviations of the 30 deployed episodes before it (median) |"
    );
    println!("|---|---|---|---|---|");
    for (name, config) in changes() {
        let (mut detected, mut early, mut delays, mut ratios) = (0, 0, Vec::new(), Vec::new());
        for &seed in &seeds {
            let (alarms, costs) = run(seed, Some(config), DEPLOYED_BEFORE + DEPLOYED_AFTER);
            let first = alarms.iter().position(|a| *a);
            match first {
                Some(k) if k < DEPLOYED_BEFORE => early += 1,
                Some(k) => {
                    detected += 1;
                    delays.push((k - DEPLOYED_BEFORE + 1) as f64);
                }
                None => {}
            }
            let mean = |c: &[f32]| c.iter().map(|c| f64::from(*c)).sum::<f64>() / c.len() as f64;
            let before = &costs[DEPLOYED_BEFORE - 30..DEPLOYED_BEFORE];
            let m = mean(before);
            let sd = (before
                .iter()
                .map(|c| (f64::from(*c) - m).powi(2))
                .sum::<f64>()
                / (before.len() - 1) as f64)
                .sqrt();
            ratios.push((mean(&costs[DEPLOYED_BEFORE..]) - m) / sd);
        }
        let delay = if delays.is_empty() {
            "–".to_string()
        } else {
            format!("{}", median(delays))
        };
        println!(
            "| {name} | {detected}/{} | {delay} | {early} | {:.2} |",
            seeds.len(),
            median(ratios)
        );
    }
    let mut alarms_total = 0;
    for &seed in &seeds {
        let (alarms, _) = run(seed, None, NO_CHANGE);
        // The detector stays alarmed once it alarms: count runs that alarmed.
        alarms_total += usize::from(alarms.iter().any(|a| *a));
    }
    println!(
        "\nno change: {alarms_total} of {} runs alarmed within {NO_CHANGE} deployed episodes ({} episodes)",
        seeds.len(),
        seeds.len() * NO_CHANGE
    );
}
