//! Choosing the algorithm at run time without `dyn` or heap: [`AnyOptimizer`], a closed
//! enum over the library's optimizers, and [`forward_optimizer!`](crate::forward_optimizer),
//! the macro that forwards the [`Optimizer`] methods of such an enum to its variants (the
//! pattern of smoltcp's `enum Socket`).
//!
//! Firmware that knows its algorithm at compile time should keep the generic path
//! (`Adapter<CoordinateSearch<18>, …>`): the enum is as large as its largest variant and
//! every call is a `match`. The enum is for host tools, benchmarks and firmware that must
//! switch algorithms from a configuration value.

use super::{
    Cmaes, ControlledRandomSearch, CoordinateSearch, DiagonalCem, LineBo, Optimizer, Rockstar,
    Sracos, TwoPhase,
};

/// Forwards every method of [`Optimizer<N>`](crate::optimizer::Optimizer) to the
/// single-field tuple variants of an enum. Write the `impl` header yourself (with your
/// generics and bounds; the parameter count must be named `N`) and call the macro inside it
/// with the variant names.
///
/// ```
/// use ctrl_adapt::optimizer::{CemConfig, DiagonalCem, Optimizer};
/// use ctrl_adapt::{Bounds, Vector};
///
/// /// The same CEM with 5 or with all 10 samples as elites, chosen at run time.
/// enum Cem<const N: usize> {
///     Half(DiagonalCem<N, 10, 5>),
///     All(DiagonalCem<N, 10, 10>),
/// }
///
/// impl<const N: usize> Optimizer<N> for Cem<N> {
///     ctrl_adapt::forward_optimizer!(Half, All);
/// }
///
/// let bounds = Bounds::<2>::uniform(-1.0, 1.0)?;
/// let cem = Cem::Half(DiagonalCem::try_new(bounds, Vector::zeros(), CemConfig::DEFAULT)?);
/// assert_eq!(cem.evaluations(), 0);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
#[macro_export]
macro_rules! forward_optimizer {
    ($($variant:ident),+ $(,)?) => {
        fn ask<R: $crate::rand_core::RngCore + ?Sized>(
            &mut self,
            rng: &mut R,
        ) -> Result<$crate::Vector<N>, $crate::Error> {
            match self {
                $(Self::$variant(o) => o.ask(rng),)+
            }
        }

        fn tell(&mut self, cost: f32) -> Result<(), $crate::Error> {
            match self {
                $(Self::$variant(o) => o.tell(cost),)+
            }
        }

        fn best(&self) -> Option<$crate::optimizer::Best<N>> {
            match self {
                $(Self::$variant(o) => o.best(),)+
            }
        }

        fn pending(&self) -> Option<&$crate::Vector<N>> {
            match self {
                $(Self::$variant(o) => o.pending(),)+
            }
        }

        fn evaluations(&self) -> u32 {
            match self {
                $(Self::$variant(o) => o.evaluations(),)+
            }
        }

        fn status(&self) -> $crate::optimizer::Status {
            match self {
                $(Self::$variant(o) => o.status(),)+
            }
        }

        fn bounds(&self) -> &$crate::Bounds<N> {
            match self {
                $(Self::$variant(o) => o.bounds(),)+
            }
        }
    };
}

/// Defines `AnyOptimizer` from one list of its variants: the enum, `Optimizer` forwarded
/// to every variant, and `From` each variant's optimizer.
macro_rules! any_optimizer {
    ($(#[$enum_doc:meta])* ; $($(#[$doc:meta])* $variant:ident($ty:ty),)+) => {
        $(#[$enum_doc])*
        // No heap to box the largest variant (LineBO's GP) into: the enum is as large as
        // it, as the module docs say.
        #[allow(clippy::large_enum_variant)]
        #[derive(Debug, Clone, PartialEq)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
        pub enum AnyOptimizer<
            const N: usize,
            const L: usize = 12,
            const E: usize = 6,
            const M: usize = 100,
            const G: usize = 64,
        > {
            $($(#[$doc])* $variant($ty),)+
        }

        impl<const N: usize, const L: usize, const E: usize, const M: usize, const G: usize>
            Optimizer<N> for AnyOptimizer<N, L, E, M, G>
        {
            crate::forward_optimizer!($($variant),+);
        }

        impl<const N: usize, const L: usize, const E: usize, const M: usize, const G: usize>
            super::Generation<N> for AnyOptimizer<N, L, E, M, G>
        {
            fn room(&self) -> usize {
                match self {
                    $(Self::$variant(o) => o.room(),)+
                }
            }

            fn most(&self) -> usize {
                match self {
                    $(Self::$variant(o) => o.most(),)+
                }
            }

            fn draws_ahead(&self) -> bool {
                match self {
                    $(Self::$variant(o) => o.draws_ahead(),)+
                }
            }

            fn adopts_pending(&self) -> bool {
                match self {
                    $(Self::$variant(o) => o.adopts_pending(),)+
                }
            }

            fn draw<R: rand_core::RngCore + ?Sized>(
                &mut self,
                ahead: usize,
                rng: &mut R,
            ) -> Result<super::Draw<N>, crate::Error> {
                match self {
                    $(Self::$variant(o) => o.draw(ahead, rng),)+
                }
            }

            fn resume(&mut self, draw: &super::Draw<N>) {
                match self {
                    $(Self::$variant(o) => o.resume(draw),)+
                }
            }

            fn check_draw(&self, draw: &super::Draw<N>) -> Result<(), crate::Error> {
                match self {
                    $(Self::$variant(o) => o.check_draw(draw),)+
                }
            }
        }

        #[cfg(feature = "serde")]
        impl<const N: usize, const L: usize, const E: usize, const M: usize, const G: usize>
            AnyOptimizer<N, L, E, M, G>
        {
            /// The checks of the variant's optimizer
            /// ([`Persistent::validate`](crate::record::Persistent)).
            pub(crate) fn check_decoded(&self) -> Result<(), crate::Error> {
                match self {
                    $(Self::$variant(o) => crate::record::Persistent::validate(o),)+
                }
            }
        }

        $(
            impl<const N: usize, const L: usize, const E: usize, const M: usize, const G: usize>
                From<$ty> for AnyOptimizer<N, L, E, M, G>
            {
                fn from(optimizer: $ty) -> Self {
                    Self::$variant(optimizer)
                }
            }
        )+
    };
}

any_optimizer!(
    /// One of the library's optimizers, chosen at run time.
    ///
    /// `N` parameters; `L` is the population of the diagonal CEM and of CMA-ES (the tutorial's
    /// default for n = 18 is 12, [`default_population`](super::cmaes::default_population)), `E`
    /// the CEM's elites, `M` the controlled random search's points (also the global phase of
    /// [`TwoPhase`]) and the rollouts [`Rockstar`] remembers (5n is its recommended memory),
    /// `G` the episodes [`LineBo`]'s Gaussian process remembers (64, about 16 KB of its
    /// Cholesky factor, is the recommendation at n = 18). Each variant is built with its own `try_new`; `From` wraps it.
    ///
    /// ```
    /// use ctrl_adapt::optimizer::{AnyOptimizer, CoordinateConfig, CoordinateSearch, Optimizer};
    /// use ctrl_adapt::{Bounds, Vector};
    /// use rand_core::SeedableRng;
    ///
    /// let bounds = Bounds::<2>::uniform(-1.0, 1.0)?;
    /// let search = CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT)?;
    /// let mut any: AnyOptimizer<2> = search.into();
    /// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
    /// let theta = any.ask(&mut rng)?;
    /// any.tell(theta.norm_squared())?;
    /// assert_eq!(any.evaluations(), 1);
    /// # Ok::<(), ctrl_adapt::Error>(())
    /// ```
    ;
    /// [`CoordinateSearch`]: the local phase.
    Coordinate(CoordinateSearch<N>),
    /// [`ControlledRandomSearch`]: the global phase.
    Crs(ControlledRandomSearch<N, M>),
    /// [`TwoPhase`] with a controlled random search as its global phase.
    TwoPhase(TwoPhase<ControlledRandomSearch<N, M>, N>),
    /// [`Sracos`] with ZOOpt's default set sizes.
    Sracos(Sracos<N>),
    /// [`DiagonalCem`] with `L` samples and `E` elites per update.
    Cem(DiagonalCem<N, L, E>),
    /// [`Cmaes`] with population `L`.
    Cmaes(Cmaes<N, L>),
    /// [`Rockstar`] remembering `M` rollouts.
    Rockstar(Rockstar<N, M>),
    /// [`LineBo`] remembering `G` episodes.
    LineBo(LineBo<N, G>),
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::{
        CemConfig, CmaesConfig, CoordinateConfig, LineBoConfig, Racos, RockstarConfig,
        SracosConfig, Status,
    };
    use crate::testing::{check_tell_after, every_optimizer};
    use crate::{Bounds, Error, Vector};
    use proptest::prelude::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    proptest! {
        /// Checks, for every optimizer (and RACOS): `tell` with any f32, with or without a
        /// pending candidate, after any number of finite costs (extremes, subnormals and zero
        /// included, so at any point of a batch or generation), never panics and is rejected
        /// exactly when there is no candidate or the cost is not finite.
        #[test]
        fn tell_never_panics(
            cost in proptest::num::f32::ANY,
            ask_first in any::<bool>(),
            warmup in prop::collection::vec(
                prop_oneof![
                    proptest::num::f32::NORMAL | proptest::num::f32::SUBNORMAL,
                    Just(f32::MAX),
                    Just(-f32::MAX),
                    Just(0.0f32),
                ],
                0..40,
            ),
        ) {
            for mut s in every_optimizer() {
                check_tell_after(&mut s, &warmup, ask_first, cost)?;
            }
            let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
            let mut racos: Racos<3> = Racos::try_new(b, SracosConfig::DEFAULT).unwrap();
            check_tell_after(&mut racos, &warmup, ask_first, cost)?;
        }
    }

    /// Checks: through the enum, each variant answers exactly as the optimizer it wraps
    /// (same candidates, best, counters and status over 30 evaluations of a sphere), and a
    /// misuse error comes through unchanged.
    #[test]
    fn forwards_every_method_to_the_variant() {
        let bounds = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
        let start = Vector::repeat(0.5);
        let variants: [AnyOptimizer<3, 7, 3, 10, 16>; 6] = [
            CoordinateSearch::try_new(bounds, start, CoordinateConfig::DEFAULT)
                .unwrap()
                .into(),
            Sracos::try_new(bounds, SracosConfig::DEFAULT)
                .unwrap()
                .into(),
            DiagonalCem::try_new(bounds, start, CemConfig::DEFAULT)
                .unwrap()
                .into(),
            Cmaes::try_new(bounds, start, CmaesConfig::DEFAULT)
                .unwrap()
                .into(),
            Rockstar::try_new(bounds, start, RockstarConfig::DEFAULT)
                .unwrap()
                .into(),
            LineBo::try_new(bounds, start, LineBoConfig::DEFAULT)
                .unwrap()
                .into(),
        ];
        for any in variants {
            let mut wrapped = any.clone();
            let mut rng_a = Xoshiro128PlusPlus::seed_from_u64(3);
            let mut rng_b = rng_a.clone();
            let mut any = any;
            assert_eq!(any.tell(1.0), Err(Error::NoPendingAsk));
            for _ in 0..30 {
                let a = any.ask(&mut rng_a).unwrap();
                let b = match &mut wrapped {
                    AnyOptimizer::Coordinate(o) => o.ask(&mut rng_b),
                    AnyOptimizer::Sracos(o) => o.ask(&mut rng_b),
                    AnyOptimizer::Cem(o) => o.ask(&mut rng_b),
                    AnyOptimizer::Cmaes(o) => o.ask(&mut rng_b),
                    AnyOptimizer::Rockstar(o) => o.ask(&mut rng_b),
                    AnyOptimizer::LineBo(o) => o.ask(&mut rng_b),
                    _ => unreachable!(),
                }
                .unwrap();
                assert_eq!(a, b);
                assert_eq!(any.pending(), Some(&a));
                any.tell(a.norm_squared()).unwrap();
                wrapped.tell(b.norm_squared()).unwrap();
            }
            assert_eq!(any, wrapped);
            assert_eq!(any.evaluations(), 30);
            assert_eq!(any.status(), Status::Running);
            assert_eq!(any.bounds(), &bounds);
            assert!(any.best().is_some_and(|b| b.cost < 0.75));
        }
    }
}
