//! The acceptance check of a fixed hopping policy ([`hopping::robustness`]): its spreads on
//! the 20 unseen courses, 100 draws of every parameter ± 2 % of its range, and the leg and
//! ground variants (leg mass ± 10 %, ground stiffness and dissipation ×0.5–×2), each run
//! judged absolutely (stable, spread ≤ 3 cm) and relatively (stable, ≤ 2× its own spread);
//! then the extra apex after the 5.5 cm block. θ from `CMAES_THETA` (as `hopper_rockstar`
//! prints it as "kept θ"), θ = 0 (the initial gait) without it.
//!
//! ```text
//! CMAES_THETA='[…]' cargo run --release -p experiments --example hopper_check
//! ```

use ctrl_adapt::optimizer::Vector;
use experiments::hopping::{self, P, UNSEEN_COURSES};

fn main() {
    let theta =
        hopping::theta_from_env::<f32>().map_or(Vector::<P>::zeros(), Vector::<P>::from_iterator);
    let r = hopping::robustness(theta, hopping::CHECK_DRAWS, 7).expect("episode");
    println!("{}", r.summary());
    for l in &r.legs {
        println!(
            "  mass ×{}, stiffness ×{}, dissipation ×{}: median {:.2} cm, max {:.2}; {}/{} absolute, {}/{} relative, {} collapse, {} off the gait",
            l.leg.mass,
            l.leg.stiffness,
            l.leg.damping,
            host_tests::median(l.spreads.clone()),
            l.spreads.iter().copied().fold(0.0, f64::max),
            l.runs.absolute,
            l.runs.runs,
            l.runs.relative,
            l.runs.runs,
            l.runs.collapsed,
            l.runs.off_gait
        );
    }
    let extra = hopping::block_extra_apex(theta, UNSEEN_COURSES).expect("episode");
    println!("extra apex after the 5.5 cm block: {extra:.2} cm");
}
