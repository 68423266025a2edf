//! Panic-freedom probe. Exercises the whole public API of `CoordinateSearch<18>` and `Bounds`
//! on inputs the optimiser cannot see through (`black_box`, an RNG, NaN and infinite costs),
//! so that every panic path inside them stays in the binary if it exists.
//!
//! Built with `--release --features panic-free` (see `scripts/panic-check`), the panic
//! handler references an undefined symbol: this binary links only if no panic is reachable
//! from any of these calls. Without the feature it runs under QEMU like the others.
#![no_std]
#![no_main]

use core::hint::black_box;

use ctrl_adapt::optimizer::unit_f32;
use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Status, Vector};
use ctrl_adapt_firmware::{exit_failure, exit_success};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = 18;

#[cortex_m_rt::entry]
fn main() -> ! {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(black_box(7));
    let lower = Vector::<N>::from_fn(|_, _| black_box(-2.0) * (1.0 + unit_f32(&mut rng)));
    let upper = Vector::<N>::from_fn(|_, _| black_box(2.0) * (1.0 + unit_f32(&mut rng)));
    let Ok(bounds) = Bounds::try_new(lower, upper) else {
        exit_failure()
    };
    let config = CoordinateConfig {
        initial_step: black_box(0.5),
        contraction: black_box(0.5),
        expansion: black_box(2.0),
        sufficient_decrease: black_box(1e-6),
        tolerance: black_box(1e-5),
        max_evaluations: black_box(5_000),
    };
    let start = bounds.sample_uniform(&mut rng);
    let steps = Vector::<N>::from_fn(|_, _| black_box(0.25) + unit_f32(&mut rng));
    let searches = [
        CoordinateSearch::try_new(bounds, start, config),
        CoordinateSearch::try_with_steps(bounds, start, steps, config),
    ];
    let mut told = 0u32;
    for search in searches {
        let Ok(mut search) = search else {
            exit_failure()
        };
        while search.status() == Status::Running {
            let Ok(theta) = search.ask(&mut rng) else {
                break;
            };
            // Costs from anywhere in f32, NaN and infinities included.
            let cost = match rng.next_u32() % 8 {
                0 => f32::from_bits(rng.next_u32()),
                _ => {
                    let clamped = bounds.clamp(&theta);
                    let ok = bounds.check(&clamped, "theta").is_ok() && bounds.contains(&theta);
                    black_box(ok);
                    theta.iter().map(|t| t * t).sum::<f32>()
                }
            };
            if search.tell(cost).is_ok() {
                told += 1;
            }
            black_box((search.best(), search.pending(), search.evaluations()));
            black_box((search.steps(), search.iterations(), search.config()));
            black_box(search.bounds());
        }
    }
    if black_box(told) > 0 {
        exit_success()
    } else {
        exit_failure()
    }
}
