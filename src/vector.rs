//! The parameter vector θ, shared by the optimizers (which propose it) and the controllers
//! (which apply it).

use nalgebra::SVector;

/// A parameter vector θ ∈ R^N in the on-target number type (`f32`: the Cortex-M4F FPU is
/// single precision, `f64` would be emulated in software).
pub type Vector<const N: usize> = SVector<f32, N>;
