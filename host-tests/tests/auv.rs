//! Physical checks of the AUV survey plant and the two facts of Leonetti et al. 2012, section 5
//! that the experiments rest on: the bare PD fails under the current, and the 18-parameter
//! linear correction can make it succeed.
//!
//! The controller here is a test-only f64 copy of the formula the library's controller layer
//! implements (see docs/plants.md):
//! v_cmd,i = sat(kp (target_i − p_i) − kd v_i, v_max) + clamp((W φ)_i, c_max), saturated again
//! to v_max, with φ = [target − p, v] and W row-major, θ[6r + c].

use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Vector};
use host_tests::auv::{Auv, AuvConfig, AuvState};
use host_tests::run;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// Nominal PD gain on the position error (1/s).
const KP: f64 = 0.3;
/// Nominal PD gain on the velocity (dimensionless).
const KD: f64 = 0.2;
/// Saturation of each velocity-command component (m/s).
const V_MAX: f64 = 0.5;
/// Clamp of each component of the learned correction (m/s).
const C_MAX: f64 = 0.5;
/// Box of every entry of W.
const W_BOUND: f32 = 1.0;

/// PD plus the clamped linear correction, both saturated (the formula in the module docs).
fn command(s: &AuvState, target: [f64; 3], w: &[f64; 18]) -> [f64; 3] {
    let e: [f64; 3] = core::array::from_fn(|i| target[i] - s.position[i]);
    let phi = [
        e[0],
        e[1],
        e[2],
        s.velocity[0],
        s.velocity[1],
        s.velocity[2],
    ];
    core::array::from_fn(|i| {
        let nominal = (KP * e[i] - KD * s.velocity[i]).clamp(-V_MAX, V_MAX);
        let dv: f64 = (0..6).map(|c| w[6 * i + c] * phi[c]).sum();
        (nominal + dv.clamp(-C_MAX, C_MAX)).clamp(-V_MAX, V_MAX)
    })
}

/// The survey outcome of one episode.
#[derive(Debug, Clone, Copy)]
struct Survey {
    /// Minimum distance to the target d (m).
    min_distance: f64,
    /// Time spent within D of the target t_D (s).
    time_within: f64,
    /// The paper's reward J = −d if d ≥ D, t_D − D otherwise.
    reward: f64,
}

/// Runs one episode of the policy W on `auv` (reset first) and scores it.
fn episode(auv: &mut Auv, w: &[f64; 18]) -> Survey {
    auv.reset();
    let radius = auv.config().target_radius;
    let (mut min_distance, mut time_within) = (f64::INFINITY, 0.0);
    for _ in 0..auv.steps_per_episode() {
        let cmd = command(&auv.measurement(), auv.target(), w);
        auv.step(cmd);
        let d = auv.distance_to_target();
        min_distance = min_distance.min(d);
        if d < radius {
            time_within += auv.dt();
        }
    }
    let reward = if min_distance >= radius {
        -min_distance
    } else {
        time_within - radius
    };
    Survey {
        min_distance,
        time_within,
        reward,
    }
}

fn still_water() -> AuvConfig {
    AuvConfig {
        current_speed: 0.0,
        ..AuvConfig::default()
    }
}

/// Checks: in still water a held command beyond the top speed settles at the speed where full
/// thrust meets drag, √(F_max/d_q) (within 0.5 %).
#[test]
fn top_speed_is_where_full_thrust_meets_drag() {
    let mut auv = Auv::new(still_water(), 1);
    for _ in 0..300 {
        auv.step([1.0, 0.0, 0.0]);
    }
    let expected = (30.0f64 / 148.0).sqrt();
    assert!((auv.config().top_speed()[0] - expected).abs() < 1e-12);
    let v = auv.state().velocity[0];
    assert!((v - expected).abs() < 0.005 * expected, "v = {v}");
}

/// Checks: in still water a small velocity step is tracked without overshoot, reaching 63 %
/// of the step between τ_v and τ_v + τ_t (the two first-order lags in cascade) and settling
/// within 1 %.
#[test]
fn small_commands_are_tracked_with_first_order_lags() {
    let mut auv = Auv::new(still_water(), 1);
    let step = 0.1;
    let mut t63 = None;
    let mut peak: f64 = 0.0;
    for _ in 0..200 {
        auv.step([0.0, step, 0.0]);
        let v = auv.state().velocity[1];
        peak = peak.max(v);
        if t63.is_none() && v >= 0.632 * step {
            t63 = Some(auv.state().time);
        }
    }
    let c = auv.config();
    let t63 = t63.expect("reached 63 %");
    assert!(
        t63 >= c.velocity_time_constant
            && t63 <= c.velocity_time_constant + c.thruster_time_constant + c.control_period,
        "t63 = {t63}"
    );
    assert!(peak <= step * 1.001, "peak {peak}");
    assert!((auv.state().velocity[1] - step).abs() < 0.01 * step);
}

/// Checks: inside the 0.6 m/s current, full thrust upstream cannot hold station: the vehicle
/// drifts downstream at the current minus the top speed through the water (0.15 m/s ± 0.005);
/// above the current layer the same vehicle stays put with a zero command.
#[test]
fn the_current_cannot_be_compensated() {
    let config = AuvConfig {
        start: [0.0, 0.0, 3.0],
        ..AuvConfig::default()
    };
    let mut auv = Auv::new(config, 1);
    for _ in 0..400 {
        auv.step([-1.0, 0.0, 0.0]);
    }
    let drift = auv.state().velocity[0];
    let expected = config.current_speed - config.top_speed()[0];
    assert!(
        (drift - expected).abs() < 0.005,
        "drift {drift}, expected {expected}"
    );
    assert!(auv.thrust()[0] <= -config.max_thrust[0] * 0.999);

    let mut calm = Auv::new(
        AuvConfig {
            start: [0.0, 0.0, 1.9],
            ..config
        },
        1,
    );
    for _ in 0..100 {
        calm.step([0.0; 3]);
    }
    assert_eq!(calm.state().position, [0.0, 0.0, 1.9]);
}

/// Checks: the sea bed and the surface are hard limits (diving or climbing hard for 30 s
/// ends exactly on them, not beyond), and non-finite commands leave the state finite.
#[test]
fn limits_hold_and_bad_commands_are_ignored() {
    let mut auv = Auv::new(AuvConfig::default(), 1);
    for _ in 0..300 {
        auv.step([0.0, 0.0, 2.0]);
    }
    assert_eq!(auv.state().position[2], auv.config().seabed_depth);
    for _ in 0..300 {
        auv.step([0.0, 0.0, -2.0]);
    }
    assert_eq!(auv.state().position[2], 0.0);
    for cmd in [
        [f64::NAN, 0.1, 0.0],
        [f64::INFINITY, f64::NEG_INFINITY, f64::NAN],
    ] {
        auv.step(cmd);
        let s = auv.state();
        assert!(s.position.iter().chain(&s.velocity).all(|v| v.is_finite()));
    }
}

/// Checks: without disturbances the measurement is the true state; with noise and
/// turbulence on, a seed replays exactly the same episodes, another seed differs, the
/// measurement differs from the truth, and successive episodes of one plant differ.
#[test]
fn disturbances_are_seeded_and_off_by_default() {
    let w = [0.0; 18];
    let mut quiet = Auv::new(AuvConfig::default(), 3);
    for _ in 0..50 {
        quiet.step(command(&quiet.measurement(), quiet.target(), &w));
        assert_eq!(quiet.measurement(), quiet.state());
    }
    let noisy = AuvConfig {
        position_noise_std: 0.05,
        velocity_noise_std: 0.02,
        turbulence_std: 0.1,
        ..AuvConfig::default()
    };
    let (mut a, mut b, mut c) = (Auv::new(noisy, 7), Auv::new(noisy, 7), Auv::new(noisy, 8));
    let (ea, eb, ec) = (
        episode(&mut a, &w),
        episode(&mut b, &w),
        episode(&mut c, &w),
    );
    assert_eq!(a.state(), b.state());
    assert_eq!(ea.min_distance, eb.min_distance);
    assert_ne!(a.state(), c.state());
    assert_ne!(ea.min_distance, ec.min_distance);
    assert_ne!(a.measurement(), a.state());
    let again = episode(&mut a, &w);
    assert_ne!(again.min_distance, ea.min_distance);
}

/// Checks (paper, figure 3): the bare PD (W = 0) never gets within D = 1 m of the target in
/// the "real" 0.6 m/s current, nor in the "simulator" 0.5 m/s one (reward −d ≤ −1), while in
/// still water the same PD reaches the target (within 0.1 m), so it is a competent controller
/// "under normal operation conditions".
#[test]
fn the_bare_pd_fails_only_because_of_the_current() {
    let zero = [0.0; 18];
    for config in [AuvConfig::default(), AuvConfig::simulator()] {
        let s = episode(&mut Auv::new(config, 1), &zero);
        println!(
            "bare PD, current {} m/s: d = {:.3} m, reward {:.3}",
            config.current_speed, s.min_distance, s.reward
        );
        assert!(s.min_distance >= 1.0 && s.reward <= -1.0, "{s:?}");
    }
    let calm = episode(&mut Auv::new(still_water(), 1), &zero);
    println!(
        "bare PD, still water: d = {:.3} m, t_D = {:.1} s",
        calm.min_distance, calm.time_within
    );
    assert!(calm.min_distance < 0.1, "{calm:?}");
}

/// Checks (paper, section 5.1): the task is solvable by the 18-parameter policy class: the
/// library's `CoordinateSearch`, from W = 0 in the "simulator" current (0.5 m/s), box
/// [−1, 1]^18, initial step 0.25, finds a W with reward above −1 within 300 episodes. Prints
/// the episode it first did so and how the best W fares in the "real" current.
#[test]
fn the_policy_class_solves_the_survey() {
    let mut auv = Auv::new(AuvConfig::simulator(), 1);
    let bounds = Bounds::<18>::uniform(-W_BOUND, W_BOUND).unwrap();
    let config = CoordinateConfig {
        initial_step: 0.25,
        tolerance: 1e-3,
        max_evaluations: 300,
        ..CoordinateConfig::DEFAULT
    };
    let mut search = CoordinateSearch::try_new(bounds, Vector::zeros(), config).unwrap();
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let to_w = |theta: &Vector<18>| -> [f64; 18] { core::array::from_fn(|i| f64::from(theta[i])) };
    let result = run(
        &mut search,
        &mut rng,
        300,
        // Minimisation: the cost is −J.
        |theta, _| -episode(&mut auv, &to_w(theta)).reward as f32,
        |_, _, _| {},
    )
    .unwrap();
    let first = result
        .best_costs
        .iter()
        .position(|&c| c < 1.0)
        .map(|k| k + 1);
    let best = to_w(&result.best_theta);
    let real = episode(&mut Auv::new(AuvConfig::default(), 1), &best);
    println!(
        "simulator current: reward > -1 first at episode {first:?}; best reward {:.2} after {} \
         episodes; best W in the real current: d = {:.3}, reward {:.2}",
        -result.best_cost(),
        result.costs.len(),
        real.min_distance,
        real.reward
    );
    println!("best W = {:.3?}", result.best_theta.as_slice());
    assert!(first.is_some(), "best reward {}", -result.best_cost());
    assert!(bounds.contains(&result.best_theta));
}
