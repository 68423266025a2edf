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
    theta
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            axis_scale::<N>(i, log10_condition) * (f64::from(t) - ellipsoid_centre::<N>(i)).powi(2)
        })
        .sum::<f64>() as f32
}

/// The ellipsoids' coefficient of axis `i`: 10^(k·i/(N−1)), 1 when N = 1.
fn axis_scale<const N: usize>(i: usize, log10_condition: f64) -> f64 {
    if N > 1 {
        10f64.powf(log10_condition * i as f64 / (N - 1) as f64)
    } else {
        1.0
    }
}

/// Coordinate `i` of the ellipsoid's minimiser.
pub fn ellipsoid_centre<const N: usize>(i: usize) -> f64 {
    0.5 - i as f64 / (2 * N) as f64
}

/// The rotated ellipsoid Σ 10^(k·i/(N−1)) (R(θ − 0.3·1))_i² with condition number 10^k and
/// axes not aligned with the coordinates: R = H_a H_b, two Householder reflections
/// H_v = I − 2 v vᵀ/‖v‖² with a_i = i + 1 and b_i = (N − i)·(1, −½, 1, −½, …), as the
/// library's own unit tests rotate it. Minimum 0 at θ = 0.3·1. O(N) per evaluation.
pub fn rotated_ellipsoid<const N: usize>(theta: &Vector<N>, log10_condition: f64) -> f32 {
    let reflect = |v: &dyn Fn(usize) -> f64, x: &mut [f64; N]| {
        let (dot, norm2) = (0..N).fold((0.0, 0.0), |(d, q), i| (d + v(i) * x[i], q + v(i) * v(i)));
        for (i, xi) in x.iter_mut().enumerate() {
            *xi -= 2.0 * dot / norm2 * v(i);
        }
    };
    let mut z: [f64; N] = core::array::from_fn(|i| f64::from(theta[i]) - 0.3);
    reflect(
        &|i| (N - i) as f64 * if i % 2 == 0 { 1.0 } else { -0.5 },
        &mut z,
    );
    reflect(&|i| (i + 1) as f64, &mut z);
    z.iter()
        .enumerate()
        .map(|(i, zi)| axis_scale::<N>(i, log10_condition) * zi * zi)
        .sum::<f64>() as f32
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

/// Ackley −20 exp(−0.2 √(Σ (θ_i − c)²/N)) − exp(Σ cos(2π(θ_i − c))/N) + 20 + e, minimum 0 at
/// θ = c·1, with a local minimum near every point of the integer lattice around c.
pub fn ackley<const N: usize>(theta: &Vector<N>, centre: f64) -> f32 {
    let n = N as f64;
    let (squares, cosines) = theta.iter().fold((0.0, 0.0), |(s, c), &t| {
        let x = f64::from(t) - centre;
        (s + x * x, c + (std::f64::consts::TAU * x).cos())
    });
    let value = -20.0 * (-0.2 * (squares / n).sqrt()).exp() - (cosines / n).exp()
        + 20.0
        + std::f64::consts::E;
    // Rounding leaves ±1e-15 at the minimiser; costs are non-negative.
    value.max(0.0) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks the rotated ellipsoid: below 1e-12 at the f32 nearest its minimiser 0.3·1; with condition 1 it is the
    /// sphere around 0.3 (R is orthogonal) to 1e-6 relative, at 20 points; with condition
    /// 10³ it differs from the unrotated ellipsoid Σ 10^(i/3) (θ_i − 0.3)² (axes mixed).
    #[test]
    fn rotated_ellipsoid_is_a_rotation() {
        // 0.3 as f32 is 1.2e-8 from the minimiser: a cost of order 1e-13 there.
        let at_minimum = rotated_ellipsoid(&Vector::<10>::repeat(0.3), 3.0);
        assert!(at_minimum < 1e-12, "{at_minimum}");
        for k in 0..20 {
            let t = Vector::<10>::from_fn(|i, _| ((i * 7 + k * 3) % 11) as f32 / 10.0 - 0.5);
            let (rotated, sphere) = (rotated_ellipsoid(&t, 0.0), sphere(&t, 0.3));
            assert!(
                (rotated - sphere).abs() <= 1e-6 * sphere,
                "{rotated} {sphere}"
            );
        }
        let t = Vector::<10>::from_fn(|i, _| if i == 0 { 1.3 } else { 0.3 });
        // Along θ_0 the unrotated ellipsoid has coefficient 1; rotated, the steep axes enter.
        assert!(
            rotated_ellipsoid(&t, 3.0) > 10.0,
            "{}",
            rotated_ellipsoid(&t, 3.0)
        );
    }
}
