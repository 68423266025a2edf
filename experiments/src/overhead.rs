//! Host time per ask+tell pair for the benches, the objective excluded. One seeded run on
//! the objective records its cost sequence; fresh optimizers replay it with the same seed
//! (the search is deterministic given seed and costs, so the same candidates come back), and
//! only their `ask` and `tell` are inside the clock. Benches print the figures; nothing here
//! asserts a speed (these machines are shared and noisy).

use std::hint::black_box;
use std::time::{Duration, Instant};

use ctrl_adapt::optimizer::{Optimizer, Vector};
use host_tests::run;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The seed of the recorded run and of every replay.
const SEED: u64 = 1;

/// Nanoseconds per ask+tell over the repetitions, and the length of the recorded run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overhead {
    /// The median over the repetitions.
    pub median_ns: f64,
    /// The fastest repetition.
    pub min_ns: f64,
    /// Evaluations in the recorded run (it ends at `max_evaluations` or when the search
    /// stops).
    pub evaluations: usize,
}

/// Records one run of the optimizer `make` builds on `objective` (at most `max_evaluations`),
/// then times `repetitions` replays of at least `min_pairs` ask+tell pairs each.
///
/// # Panics
/// If the recorded run fails or a replay leaves its step (a bench set-up error).
pub fn replay<const N: usize, O: Optimizer<N>>(
    make: impl Fn() -> O,
    objective: impl Fn(&Vector<N>) -> f32,
    max_evaluations: usize,
    repetitions: usize,
    min_pairs: usize,
) -> Overhead {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(SEED);
    let costs = run(
        &mut make(),
        &mut rng,
        max_evaluations,
        |t, _| objective(t),
        |_, _, _| {},
    )
    .expect("a clean run")
    .costs;
    let replays = min_pairs.div_ceil(costs.len());
    let mut per_pair_ns: Vec<f64> = (0..repetitions)
        .map(|_| {
            let mut elapsed = Duration::ZERO;
            for _ in 0..replays {
                let mut s = black_box(make());
                let mut rng = Xoshiro128PlusPlus::seed_from_u64(SEED);
                let start = Instant::now();
                for &cost in &costs {
                    black_box(s.ask(&mut rng).expect("replay stays in step"));
                    s.tell(black_box(cost)).expect("finite cost");
                }
                elapsed += start.elapsed();
                black_box(&s);
            }
            elapsed.as_nanos() as f64 / (replays * costs.len()) as f64
        })
        .collect();
    per_pair_ns.sort_by(f64::total_cmp);
    Overhead {
        median_ns: per_pair_ns[repetitions / 2],
        min_ns: per_pair_ns[0],
        evaluations: costs.len(),
    }
}
