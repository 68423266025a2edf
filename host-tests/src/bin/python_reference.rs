//! The reference run for the Python package's tests (python/tests), with the library's
//! concrete types written out as firmware writes them (not through the package's dispatch):
//!
//! ```text
//! python-reference <algorithm> <n> <seed> <steps> [--from FILE | --save-at K FILE] [--seed-after S]
//! ```
//!
//! Runs `steps` ask/tell pairs of `<algorithm>` (the package's names, default
//! configurations) at dimension `n` ∈ {3, 18} over the box [−1, 1]ⁿ from θ⁰ = 0, with
//! `Xoshiro128PlusPlus::seed_from_u64(seed)` and a fixed cost (a shifted, scaled sphere
//! computed in f32), and prints one JSON object: the candidates and the costs as the bit
//! patterns of their f32 values. `--from FILE` starts from the record in FILE (the RNG
//! seeded by `--seed-after`); `--save-at K FILE` writes the record after K pairs and then
//! reseeds the RNG with `--seed-after`, as a board would after loading it.

use std::process::ExitCode;

use ctrl_adapt::optimizer::{
    Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig, CoordinateSearch, CrsConfig,
    DiagonalCem, LineBo, LineBoConfig, Optimizer, Rockstar, RockstarConfig, Sracos, SracosConfig,
    TwoPhase,
};
use ctrl_adapt::record::{self, Persistent};
use ctrl_adapt::{Bounds, CemConfig, Vector};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

struct Args {
    seed: u64,
    steps: usize,
    from: Option<String>,
    save_at: Option<(usize, String)>,
    seed_after: u64,
}

/// The cost: Σ wᵢ (θᵢ − cᵢ)², cᵢ = 0.3 sin(i + 1), wᵢ = 1 + i mod 3, in f32.
fn cost<const N: usize>(theta: &Vector<N>) -> f32 {
    (0..N)
        .map(|i| {
            let c = 0.3 * (i as f32 + 1.0).sin();
            (1.0 + (i % 3) as f32) * (theta[i] - c) * (theta[i] - c)
        })
        .sum()
}

fn run<O: Optimizer<N> + Persistent, const N: usize>(
    mut o: O,
    args: &Args,
) -> Result<String, String> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(args.seed);
    if let Some(file) = &args.from {
        let bytes = std::fs::read(file).map_err(|e| format!("{file}: {e}"))?;
        o = record::load(&bytes).map_err(|e| format!("{file}: {e}"))?;
        rng = Xoshiro128PlusPlus::seed_from_u64(args.seed_after);
    }
    let (mut candidates, mut costs) = (vec![], vec![]);
    for step in 0..args.steps {
        if let Some((_, file)) = args.save_at.as_ref().filter(|(k, _)| *k == step) {
            let mut buf = vec![0u8; 1 << 20];
            let bytes = record::save(&o, &mut buf).map_err(|e| e.to_string())?;
            std::fs::write(file, bytes).map_err(|e| format!("{file}: {e}"))?;
            rng = Xoshiro128PlusPlus::seed_from_u64(args.seed_after);
        }
        let Ok(theta) = o.ask(&mut rng) else { break };
        let c = cost(&theta);
        o.tell(c).map_err(|e| e.to_string())?;
        let bits: Vec<String> = theta.iter().map(|v| v.to_bits().to_string()).collect();
        candidates.push(format!("[{}]", bits.join(",")));
        costs.push(c.to_bits().to_string());
    }
    Ok(format!(
        "{{\"candidates\":[{}],\"costs\":[{}]}}",
        candidates.join(","),
        costs.join(",")
    ))
}

fn at<const N: usize, const CRS: usize, const LAMBDA: usize, const MEMORY: usize>(
    algorithm: &str,
    args: &Args,
) -> Result<String, String> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).map_err(|e| e.to_string())?;
    let zero = Vector::<N>::zeros();
    let e = |e: ctrl_adapt::Error| e.to_string();
    match algorithm {
        "coordinate" => run(
            CoordinateSearch::try_new(bounds, zero, CoordinateConfig::DEFAULT).map_err(e)?,
            args,
        ),
        "sracos" => run(
            Sracos::<N>::try_new(bounds, SracosConfig::DEFAULT).map_err(e)?,
            args,
        ),
        "cem" => run(
            DiagonalCem::<N, 10, 5>::try_new(bounds, zero, CemConfig::DEFAULT).map_err(e)?,
            args,
        ),
        "crs" => run(
            ControlledRandomSearch::<N, CRS>::try_new(bounds, CrsConfig::DEFAULT).map_err(e)?,
            args,
        ),
        "two-phase" => {
            let crs =
                ControlledRandomSearch::<N, CRS>::try_new(bounds, CrsConfig::DEFAULT).map_err(e)?;
            run(
                TwoPhase::try_new(crs, 150, CoordinateConfig::DEFAULT).map_err(e)?,
                args,
            )
        }
        "cmaes" => run(
            Cmaes::<N, LAMBDA>::try_new(bounds, zero, CmaesConfig::DEFAULT).map_err(e)?,
            args,
        ),
        "rockstar" => run(
            Rockstar::<N, MEMORY>::try_new(bounds, zero, RockstarConfig::DEFAULT).map_err(e)?,
            args,
        ),
        "linebo" => run(
            LineBo::<N, 64>::try_new(bounds, zero, LineBoConfig::DEFAULT).map_err(e)?,
            args,
        ),
        other => Err(format!("unknown algorithm {other}")),
    }
}

fn parse() -> Result<(String, usize, Args), String> {
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let usage = || {
        "usage: python-reference <algorithm> <n> <seed> <steps> [--from FILE | --save-at K FILE] [--seed-after S]".to_string()
    };
    let number = |s: Option<&String>| -> Result<u64, String> {
        s.ok_or_else(usage)?.parse().map_err(|_| usage())
    };
    let mut args = Args {
        seed: number(argv.get(2))?,
        steps: number(argv.get(3))? as usize,
        from: None,
        save_at: None,
        seed_after: 0,
    };
    let mut rest = argv.iter().skip(4);
    while let Some(flag) = rest.next() {
        match flag.as_str() {
            "--from" => args.from = Some(rest.next().ok_or_else(usage)?.clone()),
            "--save-at" => {
                let k = number(rest.next())? as usize;
                args.save_at = Some((k, rest.next().ok_or_else(usage)?.clone()));
            }
            "--seed-after" => args.seed_after = number(rest.next())?,
            _ => return Err(usage()),
        }
    }
    let algorithm = argv.first().ok_or_else(usage)?.clone();
    Ok((algorithm, number(argv.get(1))? as usize, args))
}

fn main() -> ExitCode {
    let result = parse().and_then(|(algorithm, n, args)| match n {
        // CRS = 10(n + 1), λ = 4 + ⌊3 ln n⌋, ROCK*'s memory 5n: the package's sizes.
        3 => at::<3, 40, 7, 15>(&algorithm, &args),
        18 => at::<18, 190, 12, 90>(&algorithm, &args),
        _ => Err(format!("n = {n}: the reference is written for 3 and 18")),
    });
    match result {
        Ok(json) => {
            println!("{json}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("python-reference: {e}");
            ExitCode::FAILURE
        }
    }
}
