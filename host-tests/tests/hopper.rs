//! Physical checks of the hopping-leg plant and of the nominal controller the experiments start
//! from (Hwangbo et al., ROCK*, section IV): stable hopping at 0.6 m on flat ground, and an
//! apex that varies by several centimetres over the paper's random blocks.

use host_tests::hopper::{BLOCK_HEIGHTS, Contact, Hopper, HopperConfig, NominalHopping};

/// Hops left out of the apex statistics: the start (a drop from rest at 0.6 m) is a transient.
const TRANSIENT_HOPS: usize = 3;

/// Runs one episode of the nominal controller and returns the plant at its end.
fn nominal_episode(config: HopperConfig, seed: u64) -> Hopper {
    let nominal = NominalHopping::TUNED;
    let mut hopper = Hopper::new(config, seed);
    for _ in 0..hopper.steps_per_episode() {
        let tau = nominal.torques(&config, &hopper.state());
        hopper.step(tau);
    }
    hopper
}

/// (max − min, standard deviation, mean) of the apexes after the transient.
fn apex_spread(hopper: &Hopper) -> (f64, f64, f64) {
    let a = &hopper.apex_heights()[TRANSIENT_HOPS..];
    let n = a.len() as f64;
    let mean = a.iter().sum::<f64>() / n;
    let sd = (a.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
    let max = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = a.iter().copied().fold(f64::INFINITY, f64::min);
    (max - min, sd, mean)
}

/// Checks: with zero torques the whole leg falls freely from rest: after 0.1 s (before the
/// foot lands) the body moves at −g·t and the joints have not moved (uniform gravity exerts
/// no torque about the joints), to 1e-9.
#[test]
fn a_limp_leg_falls_freely() {
    let mut hopper = Hopper::new(HopperConfig::flat(), 1);
    let q0 = hopper.state().joint_angles;
    for _ in 0..100 {
        hopper.step([0.0, 0.0]);
    }
    let s = hopper.state();
    assert!(!s.contact);
    let g = hopper.config().gravity;
    assert!((s.body_velocity + g * s.time).abs() < 1e-9, "{s:?}");
    assert!((s.joint_angles[0] - q0[0]).abs() < 1e-9 && (s.joint_angles[1] - q0[1]).abs() < 1e-9);
}

/// Checks: standing still on the ground under a joint PD, the leg comes to rest with the foot
/// sunk by the static depth of the contact law under the total weight (within 2 %), stuck
/// under the hip (|x_f| < 1 mm); on the linear ground and on the default one.
#[test]
fn standing_still_the_ground_carries_the_weight() {
    for contact in [Contact::LINEAR_SPRING_DAMPER, Contact::RUBBER_FOOT_ON_WOOD] {
        stands_on(HopperConfig {
            contact,
            ..HopperConfig::flat()
        });
    }
}

fn stands_on(base: HopperConfig) {
    let knee = -1.0;
    let config = HopperConfig {
        initial_knee: knee,
        initial_height: base.leg_length(knee),
        ..base
    };
    let mut hopper = Hopper::new(config, 1);
    let refs = [config.hip_angle_for_foot_under_hip(knee), knee];
    for _ in 0..3000 {
        let s = hopper.state();
        let tau: [f64; 2] = core::array::from_fn(|j| {
            30.0 * (refs[j] - s.joint_angles[j]) - 1.0 * s.joint_velocities[j]
        });
        hopper.step(tau);
    }
    let s = hopper.state();
    assert!(s.contact && s.body_velocity.abs() < 1e-4, "{s:?}");
    let sink = -hopper.foot_position()[1];
    let expected = config
        .contact
        .static_depth(config.total_mass() * config.gravity);
    assert!(
        (sink - expected).abs() < 0.02 * expected,
        "sink {sink}, expected {expected}"
    );
    assert!(hopper.foot_position()[0].abs() < 1e-3);
}

/// Checks: the foot is under the hip at the hip angle the config gives for any knee angle in
/// range, and for equal segments that angle is −q_k/2.
#[test]
fn hip_reference_puts_the_foot_under_the_hip() {
    let config = HopperConfig::flat();
    for i in 0..=20 {
        let knee = config.knee_range[0]
            + (config.knee_range[1] - config.knee_range[0]) * f64::from(i) / 20.0;
        let hopper = Hopper::new(
            HopperConfig {
                initial_knee: knee,
                ..config
            },
            1,
        );
        assert!(hopper.foot_position()[0].abs() < 1e-12);
        assert!((config.hip_angle_for_foot_under_hip(knee) + knee / 2.0).abs() < 1e-12);
    }
}

/// Checks: commanded torques beyond the limit are saturated and counted, non-finite ones are
/// applied as 0 and counted, and the state stays finite.
#[test]
fn torque_limits_are_enforced_and_counted() {
    let mut hopper = Hopper::new(HopperConfig::flat(), 1);
    hopper.step([100.0, -5.0]);
    assert_eq!(hopper.applied_torques(), [30.0, -5.0]);
    assert_eq!(hopper.stats().torque_limit_steps, 1);
    hopper.step([f64::NAN, f64::INFINITY]);
    assert_eq!(hopper.applied_torques(), [0.0, 0.0]);
    assert_eq!(hopper.stats().torque_limit_steps, 2);
    let s = hopper.state();
    assert!(s.body_height.is_finite() && s.joint_angles.iter().all(|q| q.is_finite()));
}

/// Checks (the initial policy of the paper): on flat ground the nominal controller hops
/// stably for 12 s: after the first three hops every apex is within 1 cm of the others and
/// the mean within 1 cm of the set height 0.6 m; the leg never collapses nor touches a joint
/// stop nor saturates a torque.
#[test]
fn nominal_controller_hops_stably_on_flat_ground() {
    let hopper = nominal_episode(HopperConfig::flat(), 1);
    let (range, sd, mean) = apex_spread(&hopper);
    let stats = hopper.stats();
    println!(
        "flat ground: {} hops, apex mean {mean:.4} m, range {:.2} cm, sd {:.2} cm; {stats:?}",
        stats.hops,
        range * 100.0,
        sd * 100.0
    );
    assert!(hopper.apex_heights().len() >= 15);
    assert!(range < 0.01 && (mean - 0.6).abs() < 0.01);
    assert!(!hopper.collapsed());
    assert_eq!((stats.joint_limit_steps, stats.torque_limit_steps), (0, 0));
}

/// Checks (paper: "the apex height from initial policy fluctuates by about 5 cm in the
/// presence of 5.5 cm block"): over the random 0 / 1.5 / 5.5 cm ground, for each of seeds
/// 1..=5, the nominal controller keeps hopping (no collapse, ≥ 15 hops in 12 s) and its apex
/// (after the first three hops) spreads by more than 3 cm (max − min). Prints the figures.
#[test]
fn random_blocks_make_the_nominal_apex_vary_by_several_cm() {
    let mut ranges = Vec::new();
    for seed in 1..=5 {
        let hopper = nominal_episode(HopperConfig::default(), seed);
        let (range, sd, mean) = apex_spread(&hopper);
        println!(
            "blocks, seed {seed}: {} hops, apex mean {mean:.3} m, range {:.1} cm, sd {:.1} cm",
            hopper.apex_heights().len(),
            range * 100.0,
            sd * 100.0
        );
        assert!(!hopper.collapsed() && hopper.apex_heights().len() >= 15);
        assert!(range > 0.03, "seed {seed}: range {range}");
        ranges.push(range);
    }
    ranges.sort_by(f64::total_cmp);
    println!(
        "median apex range over seeds 1..=5: {:.1} cm",
        ranges[2] * 100.0
    );
}

/// Checks: the ground changes only at a flight apex and only to heights of the set; over an
/// episode every block height of the set occurs; on the flat config it never changes; the
/// same seed replays the same block sequence and another seed gives another.
#[test]
fn ground_changes_at_apexes_from_the_set_and_is_seeded() {
    let nominal = NominalHopping::TUNED;
    let sequence = |config: HopperConfig, seed: u64| {
        let mut hopper = Hopper::new(config, seed);
        let mut grounds = vec![hopper.state().ground_height];
        for _ in 0..hopper.steps_per_episode() {
            let before = hopper.state().ground_height;
            hopper.step(nominal.torques(&config, &hopper.state()));
            let after = hopper.state().ground_height;
            if after != before {
                assert!(hopper.new_apex().is_some(), "changed outside an apex");
                assert!(!hopper.state().contact);
                grounds.push(after);
            }
        }
        grounds
    };
    let a = sequence(HopperConfig::default(), 11);
    assert!(a.iter().all(|h| BLOCK_HEIGHTS.contains(h)));
    assert!(BLOCK_HEIGHTS.iter().all(|h| a.contains(h)), "{a:?}");
    assert_eq!(a, sequence(HopperConfig::default(), 11));
    assert_ne!(a, sequence(HopperConfig::default(), 12));
    assert_eq!(sequence(HopperConfig::flat(), 11), vec![0.0]);
}

/// Checks, on the series-elastic leg (`HopperConfig::SCARLETH_SEA`): standing still under the
/// same joint PD as above, it comes to rest with the foot sunk by total weight / ground
/// stiffness (within 2 %), and the torque loops track the command at rest: each spring torque
/// equals the commanded joint torque within 1e-3 N·m, with the spring deflected by
/// torque / k (so the torque is really carried by the springs, not a direct path).
#[test]
fn series_elastic_leg_stands_on_its_springs() {
    let base = HopperConfig {
        ground_heights: &[0.0],
        ..HopperConfig::SCARLETH_SEA
    };
    let sea = base.series_elasticity.unwrap();
    let knee = -1.0;
    let config = HopperConfig {
        initial_knee: knee,
        initial_height: base.leg_length(knee),
        ..base
    };
    let mut hopper = Hopper::new(config, 1);
    let refs = [config.hip_angle_for_foot_under_hip(knee), knee];
    let mut tau = [0.0; 2];
    for _ in 0..3000 {
        let s = hopper.state();
        tau = core::array::from_fn(|j| {
            30.0 * (refs[j] - s.joint_angles[j]) - 1.0 * s.joint_velocities[j]
        });
        hopper.step(tau);
    }
    let s = hopper.state();
    assert!(s.contact && s.body_velocity.abs() < 1e-4, "{s:?}");
    let sink = -hopper.foot_position()[1];
    let expected = config
        .contact
        .static_depth(config.total_mass() * config.gravity);
    assert!(
        (sink - expected).abs() < 0.02 * expected,
        "sink {sink}, expected {expected}"
    );
    let spring = hopper.joint_torques();
    let motor = hopper.motor_angles();
    for j in 0..2 {
        assert!((spring[j] - tau[j]).abs() < 1e-3, "{spring:?} vs {tau:?}");
        let deflection = motor[j] - s.joint_angles[j];
        assert!((sea.stiffness * deflection - tau[j]).abs() < 1e-3);
    }
    assert!(tau[1].abs() > 1.0, "the knee carries load: {tau:?}");
}

/// Checks: `NominalHopping::SEA_TUNED` hops on the series-elastic leg over flat ground, every
/// apex after the first three within 1.5 cm of 0.6 m (measured 0.592–0.594 m), with no
/// commanded torque beyond its limit.
#[test]
fn series_elastic_leg_hops_with_its_nominal_gait() {
    let config = HopperConfig {
        ground_heights: &[0.0],
        episode_duration: 6.0,
        ..HopperConfig::SCARLETH_SEA
    };
    let nominal = NominalHopping::SEA_TUNED;
    let mut hopper = Hopper::new(config, 1);
    for _ in 0..hopper.steps_per_episode() {
        hopper.step(nominal.torques(&config, &hopper.state()));
    }
    assert!(!hopper.collapsed());
    let a = &hopper.apex_heights()[TRANSIENT_HOPS..];
    assert!(a.len() >= 5, "{a:?}");
    assert!(a.iter().all(|h| (h - 0.6).abs() < 0.015), "{a:?}");
    assert_eq!(hopper.stats().torque_limit_steps, 0);
}

/// Checks: both contact laws give no force at zero penetration whatever the speed, no force
/// out of contact, and never a negative (pulling) force, over a grid of depths and rates;
/// Hunt–Crossley's force is continuous at touchdown (≤ 1 N at 1 µm at 3 m/s) where the
/// linear law jumps to c·v.
#[test]
fn contact_force_is_zero_at_touchdown_and_never_pulls() {
    let laws = [
        Contact::LINEAR_SPRING_DAMPER,
        Contact::RUBBER_FOOT_ON_WOOD,
        Contact::HuntCrossley {
            stiffness: 5e4,
            exponent: 1.0,
            damping: 1e4,
        },
    ];
    for law in laws {
        law.validate().unwrap();
        for rate in [-10.0, -3.0, -0.5, 0.0, 0.5, 3.0, 10.0] {
            assert_eq!(law.normal_force(0.0, rate), 0.0, "{law:?} at rate {rate}");
            assert_eq!(law.normal_force(-1e-3, rate), 0.0, "{law:?} out of contact");
            for i in 1..=100 {
                let depth = f64::from(i) * 1e-4;
                let f = law.normal_force(depth, rate);
                assert!(f >= 0.0 && f.is_finite(), "{law:?} δ {depth} δ̇ {rate}: {f}");
            }
        }
    }
    let hc = Contact::RUBBER_FOOT_ON_WOOD.normal_force(1e-6, 3.0);
    let linear = Contact::LINEAR_SPRING_DAMPER.normal_force(1e-6, 3.0);
    assert!(hc < 1.0, "Hunt–Crossley at touchdown: {hc} N");
    assert!(linear > 590.0, "the linear damper jumps: {linear} N");
}

/// Checks: an invalid contact law is rejected by name.
#[test]
fn invalid_contact_laws_are_named() {
    let bad = |contact| {
        HopperConfig {
            contact,
            ..HopperConfig::SCARLETH
        }
        .validate()
    };
    assert_eq!(bad(Contact::hertz(-1.0, 0.2)), Err("contact.stiffness"));
    assert_eq!(bad(Contact::hertz(1e6, f64::NAN)), Err("contact.damping"));
    let n = Contact::HuntCrossley {
        stiffness: 1e6,
        exponent: 3.0,
        damping: 0.0,
    };
    assert_eq!(bad(n), Err("contact.exponent"));
}

/// Checks: the linear spring–damper reproduces the plant as it was before the contact law
/// became configurable, bit for bit: the 19 apexes of the nominal gait over the blocks of
/// seed 3 (recorded with the earlier code).
#[test]
fn the_linear_contact_reproduces_the_earlier_plant_bit_for_bit() {
    let config = HopperConfig {
        contact: Contact::LINEAR_SPRING_DAMPER,
        ..HopperConfig::default()
    };
    let hopper = nominal_episode(config, 3);
    let recorded: [u64; 19] = [
        0x3fe2cbdec6e3bb19,
        0x3fe35ef16e8e7824,
        0x3fe50843b795e901,
        0x3fe36b218cfdaaea,
        0x3fe34b9e75f5edb1,
        0x3fe3e8adf53775ae,
        0x3fe3b7ac2a8cb35d,
        0x3fe4f8eb4b13b72e,
        0x3fe3540d2cd9abbb,
        0x3fe2d024ad94ada4,
        0x3fe3d6942ac8d5f6,
        0x3fe5283d7437382a,
        0x3fe3c6445e0d81a4,
        0x3fe35e0d1ee7a69b,
        0x3fe34e0b1932bc7c,
        0x3fe327eae728c74e,
        0x3fe33b78948c9caf,
        0x3fe33af6e2a028d4,
        0x3fe4fa1ca460342c,
    ];
    let bits: Vec<u64> = hopper.apex_heights().iter().map(|a| a.to_bits()).collect();
    assert_eq!(bits, recorded);
}
