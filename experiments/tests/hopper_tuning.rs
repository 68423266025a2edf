//! How [`NominalHopping::TUNED`] was found: the procedure of `host_tests::hopper_tuning` (the
//! paper's "initial policy was found from optimization in simulation with constant control
//! gains": a grid, then the library's coordinate search over 6 parameters on flat ground).
//! About 200 episodes of 8 s (5 s in release, much longer in debug), so it is compiled in
//! release builds only (debug `cargo test` skips it) and CI runs it in release:
//!
//! ```text
//! cargo test --release -p experiments --test hopper_tuning -- --nocapture
//! ```
//!
//! `TUNED` is the result rounded to two significant decimals.

#![cfg(not(debug_assertions))]

use host_tests::hopper::{HopperConfig, NominalHopping};
use host_tests::hopper_tuning::{episode, tune};

/// Checks: the tuning procedure ends on a controller that hops on flat ground with every apex
/// (after three hops) within 1 cm of 0.6 m, without limit violations, and prints it next to
/// `TUNED`, which must meet the same test.
#[test]
fn reproduce_the_nominal_hopping_tuning() {
    let t = tune(HopperConfig::SCARLETH).unwrap();
    println!("grid start {:?} (cost {:.4})", t.start.0, t.start.1);
    println!(
        "coordinate search: {} episodes, status {:?}, cost {:.4}\n  found {:?}\n  TUNED {:?}",
        t.episodes,
        t.status,
        t.cost,
        t.nominal,
        NominalHopping::TUNED
    );
    for nominal in [t.nominal, NominalHopping::TUNED] {
        let hopper = episode(HopperConfig::flat(), nominal);
        let a = &hopper.apex_heights()[3..];
        let max = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = a.iter().copied().fold(f64::INFINITY, f64::min);
        let s = hopper.stats();
        println!("  apex {min:.4}..{max:.4} m over {} hops", a.len());
        assert!(max - min < 0.01 && (max - 0.6).abs() < 0.01 && (min - 0.6).abs() < 0.01);
        assert_eq!((s.torque_limit_steps, s.joint_limit_steps), (0, 0));
    }
}
