//! The hot path of the Python package's optimizers: `ask`, `tell`, `suggest` and `report`
//! of every instance the package compiles, for every algorithm but ROCK* (the coordinate
//! search, SRACOS, the diagonal CEM, the controlled random search, the two-phase method
//! over it, CMA-ES and LineBO), compiled optimised.
//!
//! Why a crate of its own: the package compiles each algorithm at every dimension from 1 to
//! [`MAX_DIMENSION`], and generic code is compiled in the crate that names its concrete
//! types, at that crate's optimisation level. Optimising the whole package takes over
//! 13 minutes of one core, almost all of it in the records' (de)serialisation code, which
//! is not on the per-episode path; unoptimised, the steps of CRS, CMA-ES and LineBO cost
//! an order of magnitude more than optimised (python/README.md has the table). So the
//! package stays unoptimised and calls [`Steps`] for its steps: the impls of the algorithms
//! above are written for every concrete type, so they (and the library code they reach)
//! are compiled here, in release builds at opt-level 3; ROCK*'s impl is generic, compiled
//! in the package like the rest of it.
//!
//! Optimised and unoptimised builds of the same Rust compute the same `f32`s (Rust does not
//! reassociate or contract floating-point operations at any level), so the candidates stay
//! bit for bit the firmware's; the package's tests check it against the release build of
//! the Rust reference.

#![forbid(unsafe_code)]

use ctrl_adapt::optimizer::{
    Cmaes, ControlledRandomSearch, CoordinateSearch, DiagonalCem, InFlight, LineBo, Optimizer,
    Rockstar, Sracos, Ticket, TwoPhase,
};
use ctrl_adapt::{Error, Vector};
use rand_xoshiro::Xoshiro128PlusPlus;

/// The largest dimension the package compiles.
pub const MAX_DIMENSION: usize = 64;
/// The most candidates in flight at once in the package, whatever the algorithm allows (a
/// CRS's Step 0 at n = 18 allows 190).
pub const IN_FLIGHT: usize = 64;
/// The CEM's samples per update.
pub const CEM_SAMPLES: usize = 10;
/// The CEM's elites per update.
pub const CEM_ELITES: usize = 5;
/// The episodes LineBO's Gaussian process remembers.
pub const LINE_BO_MEMORY: usize = 64;

/// The per-episode calls of an optimizer held in an [`InFlight`] with room for
/// [`IN_FLIGHT`] candidates: the same calls as [`Optimizer`]'s and [`InFlight`]'s own,
/// compiled here for the algorithms named in the [crate docs](crate).
pub trait Steps<const N: usize> {
    /// [`Optimizer::ask`].
    fn step_ask(&mut self, rng: &mut Xoshiro128PlusPlus) -> Result<Vector<N>, Error>;
    /// [`Optimizer::tell`].
    fn step_tell(&mut self, cost: f32) -> Result<(), Error>;
    /// [`InFlight::suggest`].
    fn step_suggest(
        &mut self,
        rng: &mut Xoshiro128PlusPlus,
    ) -> Result<Option<(Ticket, Vector<N>)>, Error>;
    /// [`InFlight::report`].
    fn step_report(&mut self, ticket: Ticket, cost: f32) -> Result<(), Error>;
}

/// The body of every [`Steps`] impl: the library's calls, nothing added.
macro_rules! steps_body {
    ($n:tt) => {
        fn step_ask(&mut self, rng: &mut Xoshiro128PlusPlus) -> Result<Vector<$n>, Error> {
            Optimizer::ask(self, rng)
        }

        fn step_tell(&mut self, cost: f32) -> Result<(), Error> {
            Optimizer::tell(self, cost)
        }

        fn step_suggest(
            &mut self,
            rng: &mut Xoshiro128PlusPlus,
        ) -> Result<Option<(Ticket, Vector<$n>)>, Error> {
            self.suggest(rng)
        }

        fn step_report(&mut self, ticket: Ticket, cost: f32) -> Result<(), Error> {
            self.report(ticket, cost)
        }
    };
}

/// ROCK*'s impl is generic: compiled in the crate that names the type (the package,
/// unoptimised). Its step (a Gaussian process over its rollouts, and the search of its
/// mean) costs milliseconds; optimising its 64 instances would lengthen the build by about
/// half of this crate's.
impl<const N: usize, const M: usize> Steps<N> for InFlight<Rockstar<N, M>, N, IN_FLIGHT> {
    steps_body!(N);
}

/// Concrete impls, one per dimension: compiled here, optimised.
macro_rules! concrete_steps {
    ((); $($n:literal $lambda:literal),+ $(,)?) => {
        $(
            impl Steps<$n> for InFlight<CoordinateSearch<$n>, $n, IN_FLIGHT> {
                steps_body!($n);
            }
            impl Steps<$n> for InFlight<Sracos<$n>, $n, IN_FLIGHT> {
                steps_body!($n);
            }
            impl Steps<$n> for InFlight<DiagonalCem<$n, CEM_SAMPLES, CEM_ELITES>, $n, IN_FLIGHT> {
                steps_body!($n);
            }
            impl Steps<$n> for InFlight<ControlledRandomSearch<$n, { 10 * ($n + 1) }>, $n, IN_FLIGHT> {
                steps_body!($n);
            }
            impl Steps<$n>
                for InFlight<TwoPhase<ControlledRandomSearch<$n, { 10 * ($n + 1) }>, $n>, $n, IN_FLIGHT>
            {
                steps_body!($n);
            }
            impl Steps<$n> for InFlight<Cmaes<$n, $lambda>, $n, IN_FLIGHT> {
                steps_body!($n);
            }
            impl Steps<$n> for InFlight<LineBo<$n, LINE_BO_MEMORY>, $n, IN_FLIGHT> {
                steps_body!($n);
            }
        )+
    };
}

/// The compiled dimensions with the CMA-ES population of each: calls `$m!(($($extra)*);
/// 1 4, 2 6, …, 64 16)`, the pairs `n λ` for n = 1..=[`MAX_DIMENSION`], λ = 4 + ⌊3 ln n⌋
/// (CMA-ES's default population, written out: const generics cannot call a function of n
/// on stable Rust; the package's tests check it against the library's rule). The package
/// builds its `match` over the dimension from it, and this crate its impls, so the two
/// cannot disagree.
#[macro_export]
macro_rules! every_dimension {
    ($m:ident!($($extra:tt)*)) => {
        $m! {($($extra)*);
            1 4, 2 6, 3 7, 4 8, 5 8, 6 9, 7 9, 8 10, 9 10, 10 10, 11 11, 12 11, 13 11, 14 11,
            15 12, 16 12, 17 12, 18 12, 19 12, 20 12, 21 13, 22 13, 23 13, 24 13, 25 13, 26 13,
            27 13, 28 13, 29 14, 30 14, 31 14, 32 14, 33 14, 34 14, 35 14, 36 14, 37 14, 38 14,
            39 14, 40 15, 41 15, 42 15, 43 15, 44 15, 45 15, 46 15, 47 15, 48 15, 49 15, 50 15,
            51 15, 52 15, 53 15, 54 15, 55 16, 56 16, 57 16, 58 16, 59 16, 60 16, 61 16, 62 16,
            63 16, 64 16}
    };
}

every_dimension!(concrete_steps!());
