//! `Cmaes` overhead, printed as a Markdown table (asserts nothing; run with
//! `cargo bench -p experiments --bench cmaes`): host time per ask+tell pair (the objective
//! excluded; the eigendecomposition after every λ-th tell included, amortised) and
//! `size_of` the optimizer, for the AUV's N = 18 and the hopper's N = 31.
//!
//! Timing method: `experiments::overhead::replay` on the shifted sphere (a recorded run's
//! costs replayed with the same seed, only `ask` and `tell` inside the clock; median over
//! repetitions).

use ctrl_adapt::optimizer::{Bounds, Cmaes, CmaesConfig, Vector};
use experiments::overhead::replay;
use host_tests::functions::sphere;

const REPETITIONS: usize = 9;
const MIN_PAIRS_PER_REPETITION: usize = 20_000;

fn bench<const N: usize, const L: usize>(eigen_interval: u32) {
    let make = || {
        Cmaes::<N, L>::try_new(
            Bounds::uniform(-1.0, 1.0).expect("valid box"),
            Vector::zeros(),
            CmaesConfig {
                initial_sigma: 0.3,
                eigen_interval,
                ..CmaesConfig::DEFAULT
            },
        )
        .expect("valid config")
    };
    let o = replay(
        make,
        |t| sphere(t, 0.2),
        100 * N,
        REPETITIONS,
        MIN_PAIRS_PER_REPETITION,
    );
    println!(
        "| {N} | {L} | {eigen_interval} | {:.0} | {:.0} | {} |",
        o.median_ns,
        o.min_ns,
        std::mem::size_of::<Cmaes<N, L>>(),
    );
}

fn main() {
    println!(
        "host: {} {}\n",
        std::env::consts::ARCH,
        std::env::consts::OS
    );
    println!("| N | λ | eigen interval | ns/ask+tell (median) | (min) | size_of (B) |");
    println!("|---:|---:|---:|---:|---:|---:|");
    bench::<18, 10>(1);
    bench::<18, 12>(1);
    bench::<31, 14>(1);
    bench::<31, 14>(7);
}
