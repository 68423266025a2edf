#![doc = include_str!("../README.md")]
// The library never allocates and never needs std; its own unit tests run on the host with
// std (the heapless idiom), so proptest and the test harness are available there.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod optimizer;

pub use optimizer::{
    Best, Bounds, CoordinateConfig, CoordinateSearch, Error, Optimizer, Status, Vector,
};
pub use optimizer::{Racos, RacosConfig, Replacement, Sracos, SracosConfig, Suppression};

/// Compile-time proof that the public types implement `defmt::Format` when the `defmt`
/// feature is on (checked by the cross-builds with `--features defmt`).
#[cfg(feature = "defmt")]
const _: () = {
    const fn assert_format<T: defmt::Format>() {}
    assert_format::<Error>();
    assert_format::<Status>();
    assert_format::<Best<3>>();
    assert_format::<Bounds<3>>();
    assert_format::<CoordinateConfig>();
    assert_format::<CoordinateSearch<3>>();
    assert_format::<Replacement>();
    assert_format::<Suppression>();
    assert_format::<SracosConfig>();
    assert_format::<RacosConfig>();
    assert_format::<Sracos<3>>();
    assert_format::<Racos<3, 1, 3>>();
};
