//! The SRACOS paper's synthetic set-up (Hu, Qian & Yu 2017, "On synthetic functions"):
//! Sphere and Ackley shifted to 0.2 on [−1, 1]^n, budget 20n, n ∈ {10, 100}, comparing
//! SRACOS with batch RACOS and uniform random search over fixed seeds; and value suppression
//! on a noisy 18-parameter objective with lucky episodes.
//!
//! Set sizes are ZOOpt's for the budget ([`zoopt_set_sizes`]): (k, m) = (2, 10) for budget
//! 200, (2, 20) for 2000.

use ctrl_adapt::optimizer::sracos::zoopt_set_sizes;
use ctrl_adapt::optimizer::{Bounds, Racos, Sracos, SracosConfig, Suppression, Vector, unit_f32};
use host_tests::functions::{ackley, sphere};
use host_tests::{random_search, run};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const SEEDS: u64 = 15;

fn mean(v: &[f32]) -> f32 {
    v.iter().sum::<f32>() / v.len() as f32
}

/// Mean best cost of SRACOS, RACOS and random search over `SEEDS` seeds.
fn compare<const N: usize, const K: usize, const M: usize>(f: fn(&Vector<N>) -> f32) -> [f32; 3] {
    let budget = 20 * N as u32;
    assert_eq!(zoopt_set_sizes(budget), (K, M));
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).unwrap();
    let (mut s, mut q, mut u) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 1..=SEEDS {
        let config = SracosConfig {
            max_evaluations: budget,
            ..SracosConfig::DEFAULT
        };
        let mut opt: Sracos<N, K, M> = Sracos::try_new(bounds, config).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
        let r = run(&mut opt, &mut rng, usize::MAX, |t, _| f(t), |_, _, _| {}).unwrap();
        assert_eq!(r.costs.len(), budget as usize);
        s.push(r.best_cost());

        let config = SracosConfig {
            max_evaluations: budget,
            ..SracosConfig::DEFAULT
        };
        let mut opt: Racos<N, K, M> = Racos::try_new(bounds, config).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
        let r = run(&mut opt, &mut rng, usize::MAX, |t, _| f(t), |_, _, _| {}).unwrap();
        assert_eq!(r.costs.len(), budget as usize);
        q.push(r.best_cost());

        let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
        u.push(random_search(&bounds, budget as usize, &mut rng, f));
    }
    let means = [mean(&s), mean(&q), mean(&u)];
    println!(
        "n = {N:>3}: SRACOS {:.4}  RACOS {:.4}  random {:.4}",
        means[0], means[1], means[2]
    );
    means
}

fn sphere_02<const N: usize>(t: &Vector<N>) -> f32 {
    sphere(t, 0.2)
}

fn ackley_02<const N: usize>(t: &Vector<N>) -> f32 {
    ackley(t, 0.2)
}

/// Checks the paper's claim on its synthetic set-up: over 15 fixed seeds, SRACOS's mean
/// best value is below RACOS's and below uniform random search's, on Sphere and Ackley at
/// n = 10 and n = 100 with budget 20n.
#[test]
fn sracos_beats_racos_and_random_search() {
    for [s, q, u] in [
        compare::<10, 2, 10>(sphere_02::<10>),
        compare::<10, 2, 10>(ackley_02::<10>),
        compare::<100, 2, 20>(sphere_02::<100>),
        compare::<100, 2, 20>(ackley_02::<100>),
    ] {
        assert!(s < q, "SRACOS {s} vs RACOS {q}");
        assert!(s < u, "SRACOS {s} vs random search {u}");
    }
}

/// An episode cost: the 18-D shifted sphere plus zero-mean noise of standard deviation 0.2
/// (Irwin–Hall, 12 uniforms), the set-up value suppression was designed for.
fn noisy_episode<const N: usize>(theta: &Vector<N>, rng: &mut Xoshiro128PlusPlus) -> f32 {
    let gauss: f32 = (0..12).map(|_| unit_f32(rng)).sum::<f32>() - 6.0;
    sphere(theta, 0.2) + 0.2 * gauss
}

/// Mean over 15 seeds of the *true* cost of the parameters a robot would keep (the first
/// positive) after 1000 noisy episodes of the default 18-parameter SRACOS.
fn kept_true_cost(suppression: Option<Suppression>) -> f32 {
    let bounds = Bounds::<18>::uniform(-1.0, 1.0).unwrap();
    let kept: Vec<f32> = (1..=SEEDS)
        .map(|seed| {
            let config = SracosConfig {
                suppression,
                max_evaluations: 1000,
                ..SracosConfig::DEFAULT
            };
            let mut opt: Sracos<18> = Sracos::try_new(bounds, config).unwrap();
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            run(&mut opt, &mut rng, usize::MAX, noisy_episode, |_, _, _| {}).unwrap();
            sphere(&opt.positives()[0].theta, 0.2)
        })
        .collect();
    mean(&kept)
}

/// Checks value suppression on noisy episodes (18 parameters, 1000 episodes, noise σ = 0.2,
/// 15 seeds): with it on, scaled to the episode budget (re-evaluate after 20 samples that do
/// not enter the positive set, 4 re-evaluations, balance 0.5), the kept parameters' true
/// cost is lower on average than without it, where a lucky draw keeps a positive slot.
#[test]
fn value_suppression_helps_under_noise() {
    let off = kept_true_cost(None);
    let on = kept_true_cost(Some(Suppression {
        non_update_allowed: 20,
        resample_times: 4,
        balance_rate: 0.5,
    }));
    println!("kept true cost: suppression off {off:.4}, on {on:.4}");
    assert!(on < off, "on {on} vs off {off}");
}
