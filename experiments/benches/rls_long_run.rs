//! The plant model over tens of millions of ticks, printed as a Markdown table (asserts
//! nothing; run with `cargo bench -p experiments --bench rls_long_run`, or
//! `RLS_TICKS=1000000 cargo bench ...` for a shorter run):
//!
//! for each case (the model's size, its forgetting factor, the command), the ticks fitted,
//! the ordinary ticks refused (every tick here is finite and of ordinary size: the target is
//! none), whether the model validates at the end (its factors prove P positive definite
//! within the bound), the smallest D, the largest diagonal entry of P over `max_variance`,
//! the one-step RMS error at the end, and the host time per tick.
//!
//! The cases are those under which the plain (unfactorised) update lost positive
//! definiteness: forgetting 0.99 with a square-wave command switched every 1,000 ticks, and
//! the default forgetting with a command that barely moves; each at a two-state size and at
//! the AUV's (six states, three commands, fourteen regressors: the affine ones and four
//! features of the user's).

use std::time::Instant;

use ctrl_adapt::Vector;
use ctrl_adapt::model::{AffineWith, ModelConfig, Regressors, RlsModel};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

#[derive(Clone, Copy, Debug)]
enum Command {
    /// ±1, switched every 1,000 ticks.
    Square,
    /// 0.3 with a 10⁻⁶ wobble.
    NearlyConstant,
    /// Uniform in [−1, 1] every tick.
    Random,
}

fn unit(rng: &mut impl RngCore) -> f32 {
    (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
}

impl Command {
    fn at(self, tick: u64, rng: &mut impl RngCore) -> f32 {
        match self {
            Self::Square if (tick / 1000).is_multiple_of(2) => 1.0,
            Self::Square => -1.0,
            Self::NearlyConstant => 0.3 + 1e-6 * unit(rng),
            Self::Random => unit(rng),
        }
    }
}

struct Row {
    refused: u64,
    valid: bool,
    min_d: f32,
    max_diagonal: f32,
    error: f32,
    ns_per_tick: f64,
}

/// `ticks` ticks of a damped plant with S states and A commands (each state driven by the
/// command of its index modulo A, a little noise, quadratic drag on the states S/2.. as the
/// AUV's velocities) fitted by `model` with the regressors `map`.
fn run<const S: usize, const A: usize, const R: usize>(
    mut model: RlsModel<S, A, R>,
    map: &impl Regressors<S, A, R>,
    command: Command,
    ticks: u64,
    seed: u64,
) -> Row {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut x = Vector::<S>::zeros();
    let mut refused = 0;
    let start = Instant::now();
    for tick in 0..ticks {
        let u = Vector::<A>::from_fn(|_, _| command.at(tick, &mut rng));
        let next = Vector::<S>::from_fn(|i, _| {
            let drag = if i >= S / 2 {
                0.05 * x[i].abs() * x[i]
            } else {
                0.0
            };
            0.97 * x[i] + 0.1 * u[i % A] - drag + 0.001 * unit(&mut rng)
        });
        if model.update(map, &x, &u, &next).is_err() {
            refused += 1;
        }
        x = next;
    }
    let ns_per_tick = start.elapsed().as_nanos() as f64 / ticks as f64;
    let (_, d) = model.covariance_factors();
    let p = model.covariance();
    Row {
        refused,
        valid: model.validate().is_ok(),
        min_d: d.min(),
        max_diagonal: p.diagonal().max() / model.config().max_variance,
        error: model.one_step_error().max(),
        ns_per_tick,
    }
}

fn main() {
    let ticks: u64 = std::env::var("RLS_TICKS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(10_000_000);
    let fast = ModelConfig {
        forgetting: 0.99,
        ..ModelConfig::DEFAULT
    };
    let small = AffineWith::new(|x: &Vector<2>, _: &Vector<1>| Vector::<1>::new(x[1].abs() * x[1]));
    let auv = AffineWith::new(|x: &Vector<6>, _: &Vector<3>| {
        Vector::<4>::new(
            x[3].abs() * x[3],
            x[4].abs() * x[4],
            x[5].abs() * x[5],
            if x[2] > 0.0 { 1.0 } else { 0.0 },
        )
    });
    println!(
        "| size (S, A, R) | forgetting | command | ticks | ordinary ticks refused | validates | min D | max Pᵢᵢ / max_variance | one-step RMS error | ns per tick |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut total = 0;
    let mut total_refused = 0;
    for (config, command) in [
        (fast, Command::Square),
        (ModelConfig::DEFAULT, Command::NearlyConstant),
        (ModelConfig::DEFAULT, Command::Random),
    ] {
        for auv_size in [false, true] {
            let (size, row) = if auv_size {
                let model = RlsModel::<6, 3, 14>::try_new(config).unwrap();
                ("(6, 3, 14)", run(model, &auv, command, ticks, 1))
            } else {
                let model = RlsModel::<2, 1, 5>::try_new(config).unwrap();
                ("(2, 1, 5)", run(model, &small, command, ticks, 2))
            };
            total += ticks;
            total_refused += row.refused;
            println!(
                "| {size} | {} | {command:?} | {ticks} | {} | {} | {:.3e} | {:.4} | {:.3e} | {:.0} |",
                config.forgetting,
                row.refused,
                if row.valid { "yes" } else { "NO" },
                row.min_d,
                row.max_diagonal,
                row.error,
                row.ns_per_tick
            );
        }
    }
    println!("\nrls long run: {total_refused} ordinary ticks refused of {total}");
}
