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
//!
//! ```text
//! python-reference rls <ticks>
//! python-reference model-based <coordinate|cmaes> <seed> <episodes>
//! ```
//!
//! The plant model and the model-based learner ([`ctrl_adapt::model`]): `rls` fits
//! `RlsModel<2, 1, 4>` (affine) and `RlsModel<2, 1, 5>` (plus the feature |x₁|·x₁) to
//! `ticks` ticks of a fixed plant and prints both records (hex); `model-based` runs
//! `ModelBased<F, 3>` over [−1, 1]³ (margin 0.1, 60 predictions per proposal, an inner
//! `Cmaes<3, 7>` of 60 evaluations), the bare θ = 0 recorded as the reference, a model that
//! is the real cost plus 0.01, and prints the proposals (bit patterns) and the record.

use std::process::ExitCode;

use ctrl_adapt::model::{
    Affine, AffineWith, ModelBased, ModelBasedConfig, ModelConfig, RlsModel, Source,
};
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

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn saved<T: Persistent>(value: &T) -> Result<String, String> {
    let mut buf = vec![0u8; 1 << 16];
    record::save(value, &mut buf)
        .map(|bytes| hex(bytes))
        .map_err(|e| e.to_string())
}

/// `rls <ticks>`: x' = [x₀ + 0.1 x₁, 0.95 x₁ + 0.2 u + 0.05 − 0.1 |x₁| x₁] under
/// u_k = (37k mod 11)/5 − 1, in f32.
fn rls(ticks: usize) -> Result<String, String> {
    let e = |e: ctrl_adapt::Error| e.to_string();
    let mut affine = RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT).map_err(e)?;
    let mut dragged = RlsModel::<2, 1, 5>::try_new(ModelConfig::DEFAULT).map_err(e)?;
    let drag = AffineWith::new(|x: &Vector<2>, _: &Vector<1>| Vector::<1>::new(x[1].abs() * x[1]));
    let mut x = Vector::<2>::zeros();
    for k in 0..ticks {
        let u = Vector::<1>::new(((k * 37) % 11) as f32 / 5.0 - 1.0);
        let next = Vector::<2>::new(
            x[0] + 0.1 * x[1],
            0.95 * x[1] + 0.2 * u[0] + 0.05 - 0.1 * (x[1].abs() * x[1]),
        );
        affine.update(&Affine, &x, &u, &next).map_err(e)?;
        dragged.update(&drag, &x, &u, &next).map_err(e)?;
        x = next;
    }
    Ok(format!(
        "{{\"affine\":\"{}\",\"features\":\"{}\"}}",
        saved(&affine)?,
        saved(&dragged)?
    ))
}

/// Σᵢ (1 + i)(θᵢ − 0.25)², in f32.
fn bowl(theta: &Vector<3>) -> f32 {
    let mut sum = 0.0f32;
    for i in 0..3 {
        let d = theta[i] - 0.25;
        sum += (1.0 + i as f32) * (d * d);
    }
    sum
}

fn model_based<F: Optimizer<3> + Persistent>(
    fallback: F,
    seed: u64,
    episodes: usize,
) -> Result<String, String> {
    let e = |e: ctrl_adapt::Error| e.to_string();
    let config = ModelBasedConfig {
        margin: 0.1,
        inner_evaluations: 60,
        ..ModelBasedConfig::DEFAULT
    };
    let bounds = *fallback.bounds();
    let mut learner = ModelBased::try_new(bounds, fallback, config).map_err(e)?;
    let zero = Vector::<3>::zeros();
    learner.record(zero, bowl(&zero)).map_err(e)?;
    learner.set_reference(bowl(&zero)).map_err(e)?;
    let inner = |b: Bounds<3>, start: Vector<3>| {
        let config = CmaesConfig {
            max_evaluations: 60,
            ..CmaesConfig::DEFAULT
        };
        Cmaes::<3, 7>::try_new(b, start, config)
    };
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut proposals = vec![];
    for _ in 0..episodes {
        let p = learner
            .propose(&mut rng, inner, |t| Ok(bowl(t) + 0.01))
            .map_err(e)?;
        let bits: Vec<String> = p.theta.iter().map(|v| v.to_bits().to_string()).collect();
        let predicted = match p.source {
            Source::Model(c) => c.to_bits().to_string(),
            Source::Fallback => "null".into(),
        };
        proposals.push(format!("[[{}],{predicted}]", bits.join(",")));
        learner.tell(bowl(&p.theta)).map_err(e)?;
    }
    Ok(format!(
        "{{\"proposals\":[{}],\"record\":\"{}\"}}",
        proposals.join(","),
        saved(&learner)?
    ))
}

/// The `rls` and `model-based` runs, if `argv` asks for one.
fn model_run(argv: &[String]) -> Option<Result<String, String>> {
    let number = |i: usize| -> Result<u64, String> {
        argv.get(i)
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| "usage: python-reference rls <ticks> | model-based <coordinate|cmaes> <seed> <episodes>".to_string())
    };
    let bounds = Bounds::<3>::uniform(-1.0, 1.0);
    match argv.first().map(String::as_str) {
        Some("rls") => Some(number(1).and_then(|t| rls(t as usize))),
        Some("model-based") => Some((|| {
            let bounds = bounds.map_err(|e| e.to_string())?;
            let (seed, episodes) = (number(2)?, number(3)? as usize);
            let zero = Vector::<3>::zeros();
            match argv.get(1).map(String::as_str) {
                Some("coordinate") => model_based(
                    CoordinateSearch::try_new(bounds, zero, CoordinateConfig::DEFAULT)
                        .map_err(|e| e.to_string())?,
                    seed,
                    episodes,
                ),
                Some("cmaes") => model_based(
                    Cmaes::<3, 7>::try_new(bounds, zero, CmaesConfig::DEFAULT)
                        .map_err(|e| e.to_string())?,
                    seed,
                    episodes,
                ),
                _ => Err("model-based: the fallback is coordinate or cmaes".into()),
            }
        })()),
        _ => None,
    }
}

fn main() -> ExitCode {
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let result = model_run(&argv).unwrap_or_else(|| {
        parse().and_then(|(algorithm, n, args)| match n {
            // CRS = 10(n + 1), λ = 4 + ⌊3 ln n⌋, ROCK*'s memory 5n: the package's sizes.
            3 => at::<3, 40, 7, 15>(&algorithm, &args),
            18 => at::<18, 190, 12, 90>(&algorithm, &args),
            _ => Err(format!("n = {n}: the reference is written for 3 and 18")),
        })
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
