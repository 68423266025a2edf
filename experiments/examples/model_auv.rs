//! How well does a recursive least-squares model of the AUV, fitted on the ticks of a few
//! episodes, rank correction policies θ by their predicted survey cost?
//!
//! ```text
//! cargo run --release -p experiments --example model_auv
//! ```
//!
//! Per seed s (1–10): the disturbed "real" AUV (0.6 m/s current, seed s) runs the bare PD
//! (θ = 0) and then θ drawn uniformly in [−0.3, 0.3]^18 (small perturbations inside the box,
//! so the vehicle is pushed in every direction); an `RlsModel` of the policy state
//! x = [target − p, v] (S = 6) and the velocity command u (A = 3) is fitted on every tick.
//! After 1, 3 and 5 fitting episodes it reports the model's running one-step RMS error, its
//! open-loop (240-tick) RMS error on fresh episodes, and the Spearman rank correlation
//! between `imagine_episode`'s predicted cost and the true cost of a fresh real episode, for
//! 30 θ drawn in the whole box [−1, 1]^18 and 30 in [−0.3, 0.3]^18 around zero. Feature
//! sets compared: `Affine` (z = [x, u, 1], R = 10); `drag` (+ the current-layer indicator
//! [depth > 2 m] and |v|·v per axis, R = 14); `layer` (`drag` + the indicator times v per
//! axis, R = 17); `bounded drag` (`drag` with v clamped to ±0.6 m/s inside |v|·v, R = 14).
//! The error columns are the Euclidean norm over the three axes of the per-axis RMS errors.
//! Findings: experiments/findings/model.md.

use ctrl_adapt::controller::Controller;
use ctrl_adapt::cost::{Shaper, SurveyCost};
use ctrl_adapt::model::{Affine, AffineWith, ModelConfig, Regressors, RlsModel, imagine_episode};
use ctrl_adapt::optimizer::Vector;
use host_tests::auv::{Auv, AuvConfig};
use host_tests::auv_task::{self, P, RADIUS, plant, policy_state, true_error};
use host_tests::{median, spearman};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

const SEEDS: std::ops::RangeInclusive<u64> = 1..=10;
const DT: f32 = 0.1;
const FIT_EPISODES: [usize; 3] = [1, 3, 5];
const RANKED: usize = 30;
/// Depth of the current layer's top (m) and of the target (m): depth = 4.8 − x[2].
const LAYER: f32 = 2.0;
const TARGET_DEPTH: f32 = 4.8;

/// One real episode: the states the policy saw, the commands, the true cost.
struct Episode {
    states: Vec<Vector<6>>,
    commands: Vec<Vector<3>>,
    cost: f32,
}

fn run(theta: &Vector<P>, auv: &mut Auv) -> Episode {
    let mut controller = auv_task::controller();
    let mut shaper = SurveyCost::try_new(RADIUS).unwrap();
    controller.reset();
    auv.reset();
    let mut states = vec![policy_state(auv)];
    let mut commands = Vec::new();
    for k in 0..auv.steps_per_episode() {
        let x = *states.last().unwrap();
        let u = controller.corrected(theta, &x, k as f32 * DT);
        shaper.observe(&true_error(auv), DT);
        auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
        commands.push(u);
        states.push(policy_state(auv));
    }
    Episode {
        states,
        commands,
        cost: shaper.cost(),
    }
}

fn uniform(rng: &mut impl RngCore, half_width: f32) -> Vector<P> {
    Vector::from_fn(|_, _| {
        let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
        half_width * (2.0 * unit - 1.0)
    })
}

fn in_layer(x: &Vector<6>) -> f32 {
    if TARGET_DEPTH - x[2] > LAYER {
        1.0
    } else {
        0.0
    }
}

/// What one feature set scored on one seed after some fitting episodes.
#[derive(Default, Clone)]
struct Score {
    one_step: [f32; 6],
    open_loop: [f32; 6],
    rho_box: f64,
    rho_near: f64,
    diverged: usize,
}

fn score<const R: usize, M: Regressors<6, 3, R>>(
    map: &M,
    fit: &[Episode],
    tests: &[(Vector<P>, Episode)],
    near: &[(Vector<P>, Episode)],
) -> Score {
    let mut model = RlsModel::<6, 3, R>::try_new(ModelConfig::DEFAULT).unwrap();
    for e in fit {
        for (k, u) in e.commands.iter().enumerate() {
            model
                .update(map, &e.states[k], u, &e.states[k + 1])
                .unwrap();
        }
    }
    let mut open_loop = [0.0f32; 6];
    let mut counted = 0;
    let mut diverged = 0;
    for (_, e) in tests.iter().chain(near) {
        match model.episode_error(map, &e.states, &e.commands) {
            Ok(rms) => {
                counted += 1;
                for i in 0..6 {
                    open_loop[i] += rms[i];
                }
            }
            Err(_) => diverged += 1,
        }
    }
    for o in &mut open_loop {
        // NaN when every open-loop rollout diverged (the median then says NaN, not 0).
        *o = if counted == 0 {
            f32::NAN
        } else {
            *o / counted as f32
        };
    }
    let start = fit[0].states[0];
    let rho = |set: &[(Vector<P>, Episode)], diverged: &mut usize| {
        let (mut predicted, mut real) = (Vec::new(), Vec::new());
        for (theta, e) in set {
            let mut controller = auv_task::controller();
            let mut shaper = SurveyCost::try_new(RADIUS).unwrap();
            let ticks = e.commands.len() as u32;
            let cost = imagine_episode(
                &model,
                map,
                &start,
                ticks,
                DT,
                &mut controller,
                theta,
                &mut shaper,
                |x| Vector::<3>::new(x[0], x[1], x[2]),
            )
            // A rollout that leaves the finite numbers ranks last.
            .unwrap_or_else(|_| {
                *diverged += 1;
                f32::MAX
            });
            predicted.push(cost);
            real.push(e.cost);
        }
        spearman(&predicted, &real)
    };
    let rho_box = rho(tests, &mut diverged);
    let rho_near = rho(near, &mut diverged);
    let e = model.one_step_error();
    Score {
        one_step: [e[0], e[1], e[2], e[3], e[4], e[5]],
        open_loop,
        rho_box,
        rho_near,
        diverged,
    }
}

fn main() {
    let drag = AffineWith::new(|x: &Vector<6>, _: &Vector<3>| {
        Vector::<4>::new(
            in_layer(x),
            x[3].abs() * x[3],
            x[4].abs() * x[4],
            x[5].abs() * x[5],
        )
    });
    let layer = AffineWith::new(|x: &Vector<6>, _: &Vector<3>| {
        let d = in_layer(x);
        Vector::<7>::from_column_slice(&[
            d,
            x[3].abs() * x[3],
            x[4].abs() * x[4],
            x[5].abs() * x[5],
            d * x[3],
            d * x[4],
            d * x[5],
        ])
    });
    // |v|·v with v clamped to ±0.6 m/s (the vehicle's reach): bounded, so it cannot drive
    // an imagined rollout off to infinity.
    let bounded = AffineWith::new(|x: &Vector<6>, _: &Vector<3>| {
        let q = |v: f32| {
            let v = v.clamp(-0.6, 0.6);
            v.abs() * v
        };
        Vector::<4>::new(in_layer(x), q(x[3]), q(x[4]), q(x[5]))
    });
    let names = [
        "affine (R=10)",
        "drag (R=14)",
        "layer (R=17)",
        "bounded drag (R=14)",
    ];
    // results[feature set][fit index] = one Score per seed.
    let mut results = vec![vec![Vec::new(); FIT_EPISODES.len()]; names.len()];
    for seed in SEEDS {
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
        let mut auv = plant(AuvConfig::REAL, seed);
        let mut fit = vec![run(&Vector::zeros(), &mut auv)];
        while fit.len() < *FIT_EPISODES.last().unwrap() {
            let theta = uniform(&mut rng, 0.3);
            fit.push(run(&theta, &mut auv));
        }
        let mut draw = |half: f32, auv: &mut Auv| -> Vec<(Vector<P>, Episode)> {
            (0..RANKED)
                .map(|_| {
                    let theta = uniform(&mut rng, half);
                    let e = run(&theta, auv);
                    (theta, e)
                })
                .collect()
        };
        let tests = draw(1.0, &mut auv);
        let near = draw(0.3, &mut auv);
        for (f, &n) in FIT_EPISODES.iter().enumerate() {
            let fit = &fit[..n];
            results[0][f].push(score::<10, _>(&Affine, fit, &tests, &near));
            results[1][f].push(score::<14, _>(&drag, fit, &tests, &near));
            results[2][f].push(score::<17, _>(&layer, fit, &tests, &near));
            results[3][f].push(score::<14, _>(&bounded, fit, &tests, &near));
        }
        eprintln!("seed {seed} done");
    }
    println!(
        "| features | fit episodes | one-step RMS e (m) / v (m/s), median | open-loop RMS e (m) / v (m/s), median | Spearman ρ, θ ∈ [−1, 1]^18: median (min–max) | Spearman ρ, θ ∈ [−0.3, 0.3]^18: median (min–max) | diverged rollouts |"
    );
    println!("| --- | ---: | --- | --- | --- | --- | ---: |");
    for (name, per_fit) in names.iter().zip(&results) {
        for (n, scores) in FIT_EPISODES.iter().zip(per_fit) {
            let med = |f: &dyn Fn(&Score) -> f64| median(scores.iter().map(f).collect());
            let range = |f: &dyn Fn(&Score) -> f64| {
                let v: Vec<f64> = scores.iter().map(f).collect();
                (
                    median(v.clone()),
                    v.iter().copied().fold(f64::INFINITY, f64::min),
                    v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                )
            };
            let pos = |s: &[f32; 6]| f64::from((s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt());
            let vel = |s: &[f32; 6]| f64::from((s[3] * s[3] + s[4] * s[4] + s[5] * s[5]).sqrt());
            let (b, bl, bh) = range(&|s| s.rho_box);
            let (c, cl, ch) = range(&|s| s.rho_near);
            println!(
                "| {name} | {n} | {:.4} / {:.4} | {:.3} / {:.3} | {b:.2} ({bl:.2}–{bh:.2}) | {c:.2} ({cl:.2}–{ch:.2}) | {} |",
                med(&|s| pos(&s.one_step)),
                med(&|s| vel(&s.one_step)),
                med(&|s| pos(&s.open_loop)),
                med(&|s| vel(&s.open_loop)),
                scores.iter().map(|s| s.diverged).sum::<usize>(),
            );
        }
    }
}
