#![doc = include_str!("../README.md")]
// The library never allocates and never needs std; its own unit tests run on the host with
// std (the heapless idiom), so proptest and the test harness are available there.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod controller;
pub mod optimizer;
pub mod reward;

pub use optimizer::{
    Best, Bounds, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
    CoordinateSearch, CrsConfig, DiagonalCem, Error, Optimizer, Racos, RacosConfig, Replacement,
    Rockstar, RockstarConfig, Sracos, SracosConfig, Status, Suppression, TwoPhase, Vector,
    Weighting,
};

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
    assert_format::<ControlledRandomSearch<3, 8>>();
    assert_format::<TwoPhase<ControlledRandomSearch<3, 8>, 3>>();
    assert_format::<controller::Pd<3>>();
    assert_format::<controller::Mode>();
    assert_format::<controller::AdapterConfig>();
    assert_format::<controller::EpisodeReport<3>>();
    assert_format::<controller::CorrectedPd<3, 6, 6, 18, controller::StateFeatures<6>>>();
    assert_format::<controller::PeriodicPd<10, 31>>();
    assert_format::<reward::SurveyReward>();
    assert_format::<reward::QuadraticCost<3>>();
    assert_format::<reward::ApexHeightCost>();
    assert_format::<
        controller::Adapter<
            CoordinateSearch<18>,
            controller::CorrectedPd<3, 6, 6, 18, controller::StateFeatures<6>>,
            reward::SurveyReward,
            18,
            6,
            3,
        >,
    >();
    assert_format::<Weighting>();
    assert_format::<CemConfig>();
    assert_format::<DiagonalCem<3, 4, 2>>();
    assert_format::<CmaesConfig>();
    assert_format::<Cmaes<3, 7>>();
    assert_format::<Replacement>();
    assert_format::<Suppression>();
    assert_format::<SracosConfig>();
    assert_format::<RacosConfig>();
    assert_format::<Sracos<3>>();
    assert_format::<Racos<3, 1, 3>>();
    assert_format::<RockstarConfig>();
    assert_format::<Rockstar<3, 8>>();
};
