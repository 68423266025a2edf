//! Test functions for minimisation, evaluated in f64 and returned as the f32 cost the
//! library takes (as a plant simulated in f64 would report it).

use ctrl_adapt::optimizer::Vector;

/// Sphere Σ (θ_i − c)², minimum 0 at θ = c·1.
pub fn sphere<const N: usize>(theta: &Vector<N>, centre: f64) -> f32 {
    theta
        .iter()
        .map(|&t| (f64::from(t) - centre).powi(2))
        .sum::<f64>() as f32
}

/// An ill-conditioned convex quadratic Σ 10^(i/(N−1)·k) (θ_i − c_i)² with condition
/// number 10^k, minimum 0 at θ = c with c_i = 0.5 − i/(2N).
pub fn ellipsoid<const N: usize>(theta: &Vector<N>, log10_condition: f64) -> f32 {
    let scale = |i: usize| {
        if N > 1 {
            10f64.powf(log10_condition * i as f64 / (N - 1) as f64)
        } else {
            1.0
        }
    };
    theta
        .iter()
        .enumerate()
        .map(|(i, &t)| scale(i) * (f64::from(t) - ellipsoid_centre::<N>(i)).powi(2))
        .sum::<f64>() as f32
}

/// Coordinate `i` of the ellipsoid's minimiser.
pub fn ellipsoid_centre<const N: usize>(i: usize) -> f64 {
    0.5 - i as f64 / (2 * N) as f64
}

/// Rosenbrock Σ 100 (θ_{i+1} − θ_i²)² + (1 − θ_i)², minimum 0 at θ = 1.
pub fn rosenbrock<const N: usize>(theta: &Vector<N>) -> f32 {
    (0..N - 1)
        .map(|i| {
            let (a, b) = (f64::from(theta[i]), f64::from(theta[i + 1]));
            100.0 * (b - a * a).powi(2) + (1.0 - a).powi(2)
        })
        .sum::<f64>() as f32
}

/// Ackley −20·exp(−0.2·√(mean (θ_i − c)²)) − exp(mean cos 2π(θ_i − c)) + e + 20, highly
/// multimodal, minimum 0 at θ = c·1 (the SRACOS paper's form with c = 0.2).
pub fn ackley<const N: usize>(theta: &Vector<N>, centre: f64) -> f32 {
    let n = N as f64;
    let (squares, cosines) = theta.iter().fold((0.0, 0.0), |(s, c), &t| {
        let d = f64::from(t) - centre;
        (s + d * d, c + (2.0 * std::f64::consts::PI * d).cos())
    });
    (-20.0 * (-0.2 * (squares / n).sqrt()).exp() - (cosines / n).exp() + std::f64::consts::E + 20.0)
        as f32
}
