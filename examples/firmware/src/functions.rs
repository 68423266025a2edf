//! Test functions in `f32` on the target (libm for the transcendental parts), mirroring the
//! host harness's `host-tests/src/functions.rs`.

use ctrl_adapt::Vector;

/// The ill-conditioned ellipsoid Σ 10^(3i/(N−1)) (θ_i − c_i)² (condition number 1e3) with
/// minimiser c_i = 0.5 − i/(2N) and minimum 0.
pub fn ellipsoid<const N: usize>(theta: &Vector<N>) -> f32 {
    let mut sum = 0.0f32;
    for i in 0..N {
        let exponent = if N > 1 {
            3.0 * i as f32 / (N - 1) as f32
        } else {
            0.0
        };
        let d = theta[i] - ellipsoid_minimiser::<N>(i);
        sum += libm::powf(10.0, exponent) * d * d;
    }
    sum
}

/// Coordinate `i` of the ellipsoid's minimiser.
pub fn ellipsoid_minimiser<const N: usize>(i: usize) -> f32 {
    0.5 - i as f32 / (2 * N) as f32
}
