//! Cheap checks (debug) that the experiment tasks wire the library's controller stack to the
//! plants correctly: the zero correction is the bare controller, the bare AUV PD fails under
//! the current as the paper says, and the leg's zero-correction `PeriodicPd` (the kernel fit
//! of the tuned nominal, with eq. 6's reference-rate term) hops like the tuned nominal.

use ctrl_adapt::controller::Mode;
use ctrl_adapt::optimizer::Vector;
use host_tests::auv::{Auv, AuvConfig};
use host_tests::hopper::{Hopper, HopperConfig, NominalHopping};
use host_tests::{auv_task, hopper_task};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

fn rng() -> Xoshiro128PlusPlus {
    Xoshiro128PlusPlus::seed_from_u64(6)
}

/// Checks (paper, figure 3, through the library's `Adapter` + `CorrectedPd`): the bare PD never
/// gets within D = 1 m of the target, in the real (0.6 m/s) and simulator (0.5 m/s) currents,
/// undisturbed and with the experiments' disturbances; deploying W = 0 gives exactly the
/// bare PD's episode.
#[test]
fn auv_bare_pd_never_reaches_the_target() {
    let mut r = rng();
    for config in [AuvConfig::REAL, AuvConfig::simulator()] {
        for mut auv in [Auv::new(config, 1), auv_task::plant(config, 1)] {
            let search = auv_task::coordinate_search(Vector::zeros(), 10).unwrap();
            let mut adapter = auv_task::adapter(search, 10, Vector::zeros()).unwrap();
            adapter.set_mode(Mode::Nominal).unwrap();
            let bare = auv_task::run_episode(&mut adapter, &mut auv, &mut r, true).unwrap();
            println!(
                "bare PD, {} m/s, noise {}: d = {:.3} m",
                config.current_speed,
                auv.config().position_noise_std,
                bare.min_distance
            );
            assert!(bare.min_distance >= 1.0 && bare.reward() <= -1.0);
            assert!(!bare.report.failed);
        }
        let bare = {
            let search = auv_task::coordinate_search(Vector::zeros(), 10).unwrap();
            let mut adapter = auv_task::adapter(search, 10, Vector::zeros()).unwrap();
            adapter.set_mode(Mode::Nominal).unwrap();
            auv_task::run_episode(&mut adapter, &mut Auv::new(config, 1), &mut r, true).unwrap()
        };
        let zero =
            auv_task::evaluate(Vector::zeros(), &mut Auv::new(config, 1), &mut r, true).unwrap();
        assert_eq!(bare.trajectory, zero.trajectory);
        assert_eq!(bare.report.cost, zero.report.cost);
    }
}

/// Checks: the 10 periodic kernels reproduce the tuned nominal's cosine knee reference to
/// within 0.02 rad (least squares over one period).
#[test]
fn kernel_fit_reproduces_the_nominal_knee_reference() {
    let map = hopper_task::kernels();
    let nominal = NominalHopping::TUNED;
    let w = hopper_task::nominal_knee_weights(&map, &nominal);
    let err = hopper_task::fit_error(&map, &nominal, &w);
    println!(
        "knee weights {:.4?}, largest fit error {err:.4} rad",
        w.as_slice()
    );
    assert!(err < 0.02, "fit error {err}");
}

/// Checks: on flat ground the library's zero-correction `PeriodicPd` hops stably (no collapse,
/// ≥ 15 hops in 12 s) with the steady apex (after 3 hops) within 1 cm
/// of 0.6 m and of the plant's tuned nominal controller, spread below 1 cm.
#[test]
fn zero_correction_leg_hops_like_the_tuned_nominal() {
    let mut r = rng();
    let e = hopper_task::evaluate(
        Vector::zeros(),
        &mut hopper_task::plant(false, 1),
        &mut r,
        false,
    )
    .unwrap();
    let mut nominal = Hopper::new(HopperConfig::flat(), 1);
    for _ in 0..nominal.steps_per_episode() {
        let tau = NominalHopping::TUNED.torques(nominal.config(), &nominal.state());
        nominal.step(tau);
    }
    let steady = &nominal.apex_heights()[hopper_task::TRANSIENT_HOPS..];
    let nominal_mean = steady.iter().sum::<f64>() / steady.len() as f64;
    println!(
        "flat ground: PeriodicPd {} hops, apex mean {:.4} m, spread {:.2} cm; \
         plant nominal apex mean {nominal_mean:.4} m; cost {:.2e}; apexes {:.3?}",
        e.hops(),
        e.apex_mean(),
        e.apex_spread() * 100.0,
        e.report.cost,
        e.apexes
    );
    assert!(e.hops_stably());
    assert!((e.apex_mean() - 0.6).abs() < 0.01);
    assert!((e.apex_mean() - nominal_mean).abs() < 0.01);
    assert!(e.apex_spread() < 0.01);
    assert!(!e.report.failed);
}

/// Checks the runtime guard wired to the AUV (experiments/findings/guard.md): after two bare
/// episodes teach it the envelope, W = 0 (the bare PD) runs untripped, while a correction
/// that holds the vehicle back is handed back to the PD mid-episode.
#[test]
fn auv_guard_hands_a_bad_correction_back_to_the_pd() {
    use ctrl_adapt::controller::guard::{Guard, GuardConfig, Limit, Source};
    let mut r = rng();
    let guard = Guard::<1, 240>::try_new(GuardConfig {
        limits: [Limit {
            source: Source::Signal(0),
            low: 0.0,
            high: 8.0,
        }],
        relative_margin: 0.5,
        absolute_margin: 0.5,
        tripped_cost_span: 5.0,
        ..GuardConfig::DEFAULT
    })
    .unwrap();
    let search = auv_task::coordinate_search(Vector::zeros(), 10).unwrap();
    let mut adapter = auv_task::adapter(search, 10, Vector::zeros())
        .unwrap()
        .with_guard(guard)
        .unwrap();
    let mut auv = auv_task::plant(AuvConfig::REAL, 3);
    let mut episode = |adapter: &mut _, theta: Option<Vector<18>>| {
        let adapter: &mut ctrl_adapt::controller::Adapter<_, _, _, 18, 6, 3, _> = adapter;
        auv.reset();
        match theta {
            Some(theta) => adapter.begin_fixed_episode(theta).unwrap(),
            None => {
                adapter.begin_episode(&mut r).unwrap();
            }
        }
        for _ in 0..auv.steps_per_episode() {
            let error = auv_task::true_error(&auv);
            let u =
                adapter.control_with_signal(&auv_task::policy_state(&auv), &error, &[error.norm()]);
            auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
        }
        adapter.end_episode().unwrap()
    };
    adapter.set_mode(Mode::Nominal).unwrap();
    for _ in 0..2 {
        assert_eq!(episode(&mut adapter, None).trip, None);
    }
    adapter.set_mode(Mode::Learn).unwrap();
    assert_eq!(episode(&mut adapter, Some(Vector::zeros())).trip, None);
    // −1 on W's error diagonal: the correction cancels the saturated PD far from the target,
    // so the vehicle stays near its start while the bare PD closes in (an envelope trip).
    let away = Vector::<18>::from_fn(|i, _| if i % 7 == 0 { -1.0 } else { 0.0 });
    let report = episode(&mut adapter, Some(away));
    let trip = report.trip.expect("the guard trips");
    println!("away from the target: {trip:?}, cost {}", report.cost);
    assert!(trip.tick > 0 && trip.tick < report.ticks);
    // The learning episode (W = 0 is the search's first candidate) told its own cost.
    let learned = episode(&mut adapter, None);
    assert!(learned.told.is_some() && learned.told < Some(10.0));
}
