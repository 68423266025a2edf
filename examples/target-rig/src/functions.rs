//! Test functions in `f32` on the target (libm for the transcendental parts), mirroring the
//! host harness's `host-tests/src/functions.rs`.

use ctrl_adapt::Vector;

/// The ill-conditioned ellipsoid Σ 10^(3i/(N−1)) (θ_i − c_i)² (condition number 1e3) with
/// minimiser c_i = 0.5 − i/(2N) and minimum 0.
pub fn ellipsoid<const N: usize>(theta: &Vector<N>) -> f32 {
    Ellipsoid::<N>::new().eval(theta)
}

/// Coordinate `i` of the ellipsoid's minimiser.
pub fn ellipsoid_minimiser<const N: usize>(i: usize) -> f32 {
    0.5 - i as f32 / (2 * N) as f32
}

/// [`ellipsoid`] with its weights and minimiser computed once (18 `powf` calls per
/// evaluation would dominate an exec trace of the optimizer).
pub struct Ellipsoid<const N: usize> {
    weights: [f32; N],
    minimiser: [f32; N],
}

impl<const N: usize> Ellipsoid<N> {
    /// Weights 10^(3i/(N−1)) by libm's `powf`, minimiser c_i = 0.5 − i/(2N).
    pub fn new() -> Self {
        Self {
            weights: core::array::from_fn(|i| {
                let exponent = if N > 1 {
                    3.0 * i as f32 / (N - 1) as f32
                } else {
                    0.0
                };
                libm::powf(10.0, exponent)
            }),
            minimiser: core::array::from_fn(ellipsoid_minimiser::<N>),
        }
    }

    /// The cost at `theta`.
    pub fn eval(&self, theta: &Vector<N>) -> f32 {
        let mut sum = 0.0f32;
        for i in 0..N {
            let d = theta[i] - self.minimiser[i];
            sum += self.weights[i] * d * d;
        }
        sum
    }
}

impl<const N: usize> Default for Ellipsoid<N> {
    fn default() -> Self {
        Self::new()
    }
}
