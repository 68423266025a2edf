// The README is the crate page. Its links to the repository's files are reference-style,
// defined at its end relative to the repository (right on the repository's own pages);
// here the same labels are defined first, as docs.rs addresses of the packaged files of
// this very version (`/crate/NAME/VERSION/source/PATH`), and the first definition of a
// label wins. The docs.rs source view shows no anchors: the labels whose README target
// names a section go to its page. `scripts/check-doc-links` checks the rendered page.
#![doc = concat!(
    "[getting-started]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/getting-started.md\n",
    "[choosing-an-optimizer]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/choosing-an-optimizer.md\n",
    "[model-based]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/model-based.md\n",
    "[peers-table]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/choosing-an-optimizer.md\n",
    "[tuning]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/tuning.md\n",
    "[safety]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/safety.md\n",
    "[persistence]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/persistence.md\n",
    "[persistence-recipe]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/persistence.md\n",
    "[firmware]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/firmware.md\n",
    "[porting]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/porting.md\n",
    "[plants]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/plants.md\n",
    "[in-service]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/in-service.md\n",
    "[figures-json]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/docs/figures.json\n",
    "[changelog]: https://docs.rs/crate/ctrl-adapt/", env!("CARGO_PKG_VERSION"), "/source/CHANGELOG.md\n",
)]
#![doc = include_str!("../README.md")]
// The library never allocates and never needs std; its own unit tests run on the host with
// std (the heapless idiom), so proptest and the test harness are available there.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// docs.rs builds with `--cfg docsrs` on nightly: `doc_cfg` marks every feature-gated item
// with the feature that enables it ("Available on crate feature ... only").
#![cfg_attr(docsrs, feature(doc_cfg))]

pub mod bounds;
#[cfg(feature = "checkpoint")]
#[cfg_attr(docsrs, doc(cfg(feature = "checkpoint")))]
pub mod checkpoint;
pub mod controller;
pub mod cost;
pub mod error;
pub mod model;
pub mod optimizer;
pub mod random;
#[cfg(feature = "serde")]
#[cfg_attr(docsrs, doc(cfg(feature = "serde")))]
pub mod record;
pub mod vector;

#[cfg(test)]
mod testing;

/// The cost shapers' former module name.
#[deprecated(since = "0.2.0", note = "renamed to `cost`: the shapers return costs")]
pub mod reward {
    pub use crate::cost::*;

    /// The survey cost's former name.
    #[deprecated(since = "0.2.0", note = "renamed to `cost::SurveyCost`")]
    pub type SurveyReward = crate::cost::SurveyCost;
}

/// The RNG trait every `ask` takes (re-exported for [`forward_optimizer!`]).
pub use rand_core;

pub use bounds::Bounds;
pub use error::Error;
pub use optimizer::{
    AnyOptimizer, Best, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
    CoordinateSearch, CrsConfig, DiagonalCem, Generation, InFlight, LineBo, LineBoConfig,
    LineDirections, Optimizer, Racos, Replacement, Rockstar, RockstarConfig, Sracos, SracosConfig,
    Status, Suppression, Ticket, TwoPhase, Weighting,
};
pub use vector::Vector;

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
    assert_format::<controller::AdapterError>();
    assert_format::<controller::AdapterConfig>();
    assert_format::<controller::EpisodeReport<3>>();
    assert_format::<controller::CorrectedPd<3, 6, 6, 18, controller::StateFeatures<6>>>();
    assert_format::<controller::PeriodicPd<10, 31>>();
    assert_format::<controller::AdapterBuilder<1, 2, 2>>();
    assert_format::<controller::Corrected<controller::Pd<1>, 1, 2, 2>>();
    assert_format::<model::RlsModel<6, 3, 14>>();
    assert_format::<model::ModelConfig>();
    assert_format::<model::Affine>();
    assert_format::<model::ModelBasedConfig>();
    assert_format::<model::Source>();
    assert_format::<model::Proposal<3>>();
    assert_format::<model::Prediction>();
    assert_format::<model::Imagined<6>>();
    assert_format::<model::ModelBased<CoordinateSearch<3>, 3>>();
    assert_format::<model::Unmodelled>();
    assert_format::<model::OnlineModel<model::Affine, 6, 3, 10>>();
    assert_format::<cost::SurveyCost>();
    assert_format::<cost::QuadraticCost<3>>();
    assert_format::<cost::ApexHeightCost>();
    assert_format::<
        controller::Adapter<
            CoordinateSearch<18>,
            controller::CorrectedPd<3, 6, 6, 18, controller::StateFeatures<6>>,
            cost::SurveyCost,
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
    assert_format::<Sracos<3>>();
    assert_format::<Racos<3, 1, 3>>();
    assert_format::<RockstarConfig>();
    assert_format::<Rockstar<3, 8>>();
    assert_format::<LineDirections>();
    assert_format::<LineBoConfig>();
    assert_format::<LineBo<3, 8>>();
    assert_format::<AnyOptimizer<3>>();
};

#[cfg(all(feature = "defmt", feature = "serde"))]
const _: () = {
    const fn assert_format<T: defmt::Format>() {}
    assert_format::<record::RecordError>();
    assert_format::<record::Shape>();
    #[cfg(feature = "checkpoint")]
    assert_format::<checkpoint::CheckpointError>();
};

/// The guide's Rust snippets, compiled and run as doc tests so the guide cannot drift from
/// the API.
#[cfg(doctest)]
mod guide {
    #[doc = include_str!("../docs/getting-started.md")]
    struct GettingStarted;
    #[doc = include_str!("../docs/choosing-an-optimizer.md")]
    struct ChoosingAnOptimizer;
    #[doc = include_str!("../docs/model-based.md")]
    struct ModelBasedGuide;
    #[doc = include_str!("../docs/plants.md")]
    struct Plants;
    #[doc = include_str!("../docs/in-service.md")]
    struct InService;
}
