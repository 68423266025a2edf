//! How sharp the learned optima are: the spread-weighted cost
//! ([`hopping::spread_apex_config`], the cost the fresh-course CMA-ES learns on) of a
//! fixed policy θ and of θ with one parameter moved by ± `step` of its half-range, each the
//! mean told cost over 10 courses it was not learned on (seeds 300 000 …, the same 10 for
//! every point, so the course-to-course noise cancels in the comparison), with the ratio of
//! the worse side to θ's own cost. Then, for the sharpest move, the apex heights of θ and of
//! the moved θ on the course where the move costs most.
//!
//! ```text
//! CMAES_THETA='<mean printed by hopper_cmaes_lib>' cargo run --release -p experiments --example hopper_sensitivity [-- STEP]
//! cargo run --release -p experiments --example hopper_sensitivity -- 0.05     # θ = 0, the initial policy
//! ```
//!
//! `STEP` defaults to 0.01 (0.005 rad of a knee-reference weight, 0.28 N·m/rad of a stiffness
//! weight, 0.01 N·m·s/rad of a damping weight, 1 ms of the period). A move that leaves the
//! box is not run (`-`). `findings/hopping.md` reads the output.

use ctrl_adapt::optimizer::Vector;
use experiments::hopping::{self, K, P, told_cost};

/// The courses every point is scored on.
const COURSES: std::ops::Range<u64> = 300_000..300_010;

/// The mean told cost of `theta` over [`COURSES`], one thread per course.
fn cost(theta: Vector<P>) -> f64 {
    let apex = hopping::spread_apex_config();
    std::thread::scope(|s| {
        let runs: Vec<_> = COURSES
            .map(|seed| s.spawn(move || told_cost(theta, seed, apex).expect("episode")))
            .collect();
        let total: f64 = runs
            .into_iter()
            .map(|r| f64::from(r.join().expect("episode thread")))
            .sum();
        total / COURSES.count() as f64
    })
}

/// What parameter `i` is.
fn name(i: usize) -> String {
    match i / K {
        0 => format!("knee reference, kernel {}", i % K),
        1 => format!("stiffness k_p, kernel {}", i % K),
        2 => format!("damping k_d, kernel {}", i % K),
        _ => "period".to_owned(),
    }
}

/// Apex heights (m, 3 decimals) of `theta` on course `seed`, and whether it collapsed.
fn apexes(theta: Vector<P>, seed: u64) -> String {
    let e = hopping::episode_on(theta, seed, hopping::spread_apex_config()).expect("episode");
    let a: Vec<_> = e.apexes.iter().map(|h| format!("{h:.3}")).collect();
    format!(
        "{}{}",
        a.join(" "),
        if e.collapsed { " — collapsed" } else { "" }
    )
}

fn main() {
    let theta = hopping::theta_from_env::<f32>()
        .map_or_else(Vector::<P>::zeros, |v| Vector::<P>::from_column_slice(&v));
    let step: f32 = std::env::args()
        .nth(1)
        .map_or(0.01, |s| s.parse().expect("STEP"));
    let half = *hopping::bounds().upper();
    let base = cost(theta);
    println!("θ's cost {base:.3e} (mean over courses {COURSES:?}); step {step} of each half-range");
    println!("| parameter | θ | cost at − step | cost at + step | worse side / θ |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    let mut sharpest = (0.0, 0, 0.0);
    for i in 0..P {
        let mut sides = [None; 2];
        for (side, sign) in sides.iter_mut().zip([-1.0f32, 1.0]) {
            let moved = theta[i] + sign * step * half[i];
            if moved.abs() <= half[i] {
                let mut t = theta;
                t[i] = moved;
                *side = Some(cost(t));
                if cost_ratio(side, base) > sharpest.0 {
                    sharpest = (cost_ratio(side, base), i, sign);
                }
            }
        }
        let show = |c: Option<f64>| c.map_or("-".to_owned(), |c| format!("{c:.2e}"));
        let worse = sides.iter().flatten().copied().fold(f64::NAN, f64::max);
        println!(
            "| {} | {:.3} | {} | {} | {:.1} |",
            name(i),
            theta[i],
            show(sides[0]),
            show(sides[1]),
            worse / base
        );
    }
    let (ratio, i, sign) = sharpest;
    let mut moved = theta;
    moved[i] += sign * step * half[i];
    let sign = if sign > 0.0 { '+' } else { '−' };
    println!(
        "\nsharpest: {} ({sign}{step}), {ratio:.1}× θ's cost",
        name(i)
    );
    // The course where the move costs most, and what the leg did there.
    let apex = hopping::spread_apex_config();
    let worst = COURSES
        .map(|seed| (told_cost(moved, seed, apex).expect("episode"), seed))
        .fold((f32::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a });
    println!("its worst course, {} (told {:.2e}):", worst.1, worst.0);
    println!("  θ:       {}", apexes(theta, worst.1));
    println!("  moved θ: {}", apexes(moved, worst.1));
}

/// `side`'s cost over `base` (0 when not run).
fn cost_ratio(side: &Option<f64>, base: f64) -> f64 {
    side.map_or(0.0, |c| c / base)
}
