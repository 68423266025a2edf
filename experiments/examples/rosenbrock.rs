//! Coordinate search with line-search expansions on the 10-D Rosenbrock function, printing
//! its progress (the former main job, kept for the README's Rosenbrock figure):
//!
//! ```text
//! cargo run --release -p experiments --example rosenbrock
//! ```

use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Vector};
use host_tests::{functions::rosenbrock, run};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = 10;
const BUDGET: usize = 200_000;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let bounds = Bounds::<N>::uniform(-2.0, 2.0)?;
    let start = Vector::<N>::repeat(-1.2);
    let config = CoordinateConfig {
        initial_step: 0.5,
        tolerance: 1e-6,
        ..CoordinateConfig::DEFAULT
    };
    let mut search = CoordinateSearch::try_new(bounds, start, config)?;
    // The coordinate search is deterministic; the RNG is part of the common interface.
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);

    println!("coordinate search with line-search expansions, {N}-D Rosenbrock from θ = -1.2·1");
    println!("{:>10}  {:>14}  {:>14}", "episode", "cost", "best");
    let result = run(
        &mut search,
        &mut rng,
        BUDGET,
        |theta, _| rosenbrock(theta),
        |k, cost, best| {
            if k.is_power_of_two() || k % 20_000 == 0 {
                println!("{k:>10}  {cost:>14.6e}  {best:>14.6e}");
            }
        },
    )?;
    let (up, down) = search.steps();
    println!(
        "stopped: {:?} after {} evaluations, {} iterations; best cost {:.3e}; largest step {:.2e}",
        result.status,
        result.costs.len(),
        search.iterations(),
        result.best_cost(),
        up.max().max(down.max()),
    );
    println!("best θ = {:.4?}", result.best_theta.as_slice());
    Ok(())
}
