//! What a learner on fresh courses sees: the cost and the apex spread of one fixed policy
//! over 60 block sequences it was not learned on (seeds 200 000 …), as mean ± standard
//! deviation, with the cost split into the first 3 apexes' squared deviation, the later
//! apexes' and the rest (energy, limits, missing hops), and the spread's median and 10 / 90 %
//! points.
//!
//! ```text
//! cargo run --release -p experiments --example hopper_noise                       # θ = 0 (the initial policy)
//! CMAES_THETA='<mean printed by hopper_cmaes_lib>' cargo run --release -p experiments --example hopper_noise
//! cargo run --release -p experiments --example hopper_noise -- 0.5                # blocks redrawn at half the apexes
//! ```
//!
//! The optional argument is the plant's probability of redrawing the ground at an apex (the
//! experiments use 1).

use ctrl_adapt::optimizer::Vector;
use experiments::hopping::{self, P, evaluate, plant_for};
use host_tests::hopper::HopperConfig;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Mean and sample standard deviation.
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
    (m, var.sqrt())
}

fn main() {
    let theta = hopping::theta_from_env::<f32>()
        .map_or_else(Vector::<P>::zeros, |v| Vector::<P>::from_column_slice(&v));
    let change_probability: f64 = std::env::args()
        .nth(1)
        .map_or(1.0, |p| p.parse().expect("probability"));
    let config = HopperConfig {
        change_probability,
        ..HopperConfig::SCARLETH
    };
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2);
    let (mut cost, mut first, mut later, mut rest, mut spread) =
        (vec![], vec![], vec![], vec![], vec![]);
    let mut unstable = 0;
    for s in 0..60u64 {
        let e = evaluate(
            theta,
            &mut plant_for(config, true, 200_000 + s),
            &mut rng,
            false,
        )
        .expect("episode");
        let n = e.apexes.len().max(1) as f64;
        let sq = |a: &[f64]| a.iter().map(|h| (h - 0.6).powi(2)).sum::<f64>() / n;
        let (f, l) = (
            sq(&e.apexes[..3.min(e.apexes.len())]),
            sq(e.steady_apexes()),
        );
        cost.push(f64::from(e.report.cost));
        first.push(f);
        later.push(l);
        rest.push(f64::from(e.report.cost) - f - l);
        spread.push(e.apex_spread() * 100.0);
        unstable += usize::from(!e.hops_stably());
    }
    let show = |name: &str, v: &[f64]| {
        let (m, sd) = mean_sd(v);
        println!("{name:<28} {m:.3e} ± {sd:.2e}");
    };
    println!("60 courses, ground redrawn at an apex with probability {change_probability}");
    show("cost", &cost);
    show("  first 3 apexes", &first);
    show("  later apexes", &later);
    show("  rest (energy, limits, hops)", &rest);
    let (m, sd) = mean_sd(&spread);
    spread.sort_by(f64::total_cmp);
    println!(
        "apex spread (cm)             {m:.2} ± {sd:.2}; median {:.2}, 10 % {:.2}, 90 % {:.2}",
        host_tests::median(spread.clone()),
        spread[6],
        spread[54]
    );
    println!("courses off the stable gait: {unstable}");
}
