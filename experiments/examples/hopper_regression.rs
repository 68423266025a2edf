//! Hop-to-hop structure of the learned hopping policy (findings/hopping.md, "What the learned
//! policy does, hop to hop"):
//!
//! ```text
//! cargo run --release -p experiments --example hopper_regression   # ≈ 15 s
//! ```
//!
//! Learns as `tests/hopper_experiments.rs` does (coordinate search, 400 episodes on the
//! training course), then runs the learned θ on 20 unseen courses (seeds 10 001–10 020) and
//! fits, by least squares over every hop after the transient,
//! A_k ≈ c + a₀ g_k + a₁ g_{k−1} + a₂ g_{k−2} + b A_{k−1}, where A_k is an apex height and
//! g_k the ground height of the stance that launched it. Prints the coefficients, the
//! residual and the mean apex for each pair (g_k, g_{k−1}).

use ctrl_adapt::optimizer::{Optimizer, Vector};
use experiments::hopping::{
    self, LEARNING_EPISODES, TRANSIENT_HOPS, coordinate_search, evaluate, plant, run_episode,
    training_course,
};
use nalgebra::{SMatrix, SVector};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// One hop: [A_k, g_k, g_{k−1}, g_{k−2}, A_{k−1}].
type Hop = [f64; 5];

fn features(h: &Hop) -> SVector<f64, 5> {
    SVector::from([1.0, h[1], h[2], h[3], h[4]])
}

fn main() {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let search = coordinate_search(Vector::zeros(), LEARNING_EPISODES).expect("valid search");
    let mut adapter =
        hopping::adapter(search, LEARNING_EPISODES, Vector::zeros()).expect("valid adapter");
    for _ in 0..LEARNING_EPISODES {
        run_episode(&mut adapter, &mut training_course(), &mut rng, false).expect("episode");
    }
    let best = adapter.optimizer().best().expect("told");
    println!("learned: training cost {:.3e}", best.cost);

    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2);
    let mut hops: Vec<Hop> = Vec::new();
    for seed in 10_001..=10_020 {
        let e = evaluate(best.theta, &mut plant(true, seed), &mut rng, false).expect("episode");
        for k in (TRANSIENT_HOPS + 1)..e.apexes.len() {
            hops.push([
                e.apexes[k],
                e.grounds[k],
                e.grounds[k - 1],
                e.grounds[k - 2],
                e.apexes[k - 1],
            ]);
        }
    }
    let mut ata = SMatrix::<f64, 5, 5>::zeros();
    let mut atb = SVector::<f64, 5>::zeros();
    for h in &hops {
        let f = features(h);
        ata += f * f.transpose();
        atb += f * h[0];
    }
    let Some(fit) = ata.cholesky() else {
        println!("the hops do not determine the fit");
        return;
    };
    let x = fit.solve(&atb);
    let residuals: Vec<f64> = hops.iter().map(|h| h[0] - x.dot(&features(h))).collect();
    let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / hops.len() as f64).sqrt();
    println!(
        "{} hops: A_k = {:.4} + {:.3} g_k + {:.3} g_k-1 + {:.3} g_k-2 + {:.3} A_k-1, \
         residual r.m.s. {:.3} cm",
        hops.len(),
        x[0],
        x[1],
        x[2],
        x[3],
        x[4],
        rms * 100.0
    );
    for g in hopping::plant(true, 0).config().ground_heights {
        for g_prev in hopping::plant(true, 0).config().ground_heights {
            let apexes: Vec<f64> = hops
                .iter()
                .filter(|h| h[1] == *g && h[2] == *g_prev)
                .map(|h| h[0])
                .collect();
            if !apexes.is_empty() {
                println!(
                    "g_k {:.3} m, g_k-1 {:.3} m: {:3} hops, mean apex {:.4} m",
                    g,
                    g_prev,
                    apexes.len(),
                    apexes.iter().sum::<f64>() / apexes.len() as f64
                );
            }
        }
    }
}
