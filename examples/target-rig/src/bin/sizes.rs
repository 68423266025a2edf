//! RAM of every optimizer at the number of parameters you choose: its state (`size_of`) and
//! its peak stack, measured by paint and scan ([`ctrl_adapt_firmware::stack::measure`]).
//!
//! N comes from the environment variable `CTRL_ADAPT_N` at build time (default 18):
//!
//! ```sh
//! cd examples/target-rig
//! CTRL_ADAPT_N=12 cargo run --release --bin sizes
//! ```
//!
//! (`scripts/sizes 12 18 31` builds and runs it for each N and prints one table.) Cargo
//! rebuilds only this binary when the variable changes (`option_env!` makes it a dependency
//! of this crate alone).
//!
//! Each optimizer runs [`EVALUATIONS`] ask/tell pairs (ROCK*: its memory M = 5N plus N, so
//! the memory is full and evicting) of the N-D ill-conditioned ellipsoid over the box
//! [−1, 1]ᴺ from 0, twice: once built inside the measured call (the stack a firmware needs
//! when the optimizer lives on the stack: its state, the construction and the calls), once
//! built first and only the ask/tell calls measured (what to add when the state lives in a
//! `static` or in `main`'s frame). Each row is one log line:
//!
//! `sizes: row NAME [N, ...] state S stack T calls C evaluations E`
//!
//! The configurations are those of the footprint benchmark (`bench`), at N: CMA-ES with the
//! tutorial's default population 4 + ⌊3 ln N⌋, CRS with the paper's 100 points (2(N + 1)
//! from N = 99 on), the diagonal CEM with 10 samples and 5 elites, ROCK* with M = 5N,
//! LineBO (its defaults: no threshold, three episodes per coordinate line) remembering
//! [`LINE_BO_M`] episodes, for M + 8 evaluations.
#![no_std]
#![no_main]

use ctrl_adapt::optimizer::cmaes::default_population;
use ctrl_adapt::{
    Bounds, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
    CoordinateSearch, CrsConfig, DiagonalCem, Error, LineBo, LineBoConfig, Optimizer, Rockstar,
    RockstarConfig, Sracos, SracosConfig, Status, Vector, Weighting,
};
use ctrl_adapt_firmware::functions::Ellipsoid;
use ctrl_adapt_firmware::{exit_failure, exit_success, stack};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The number of parameters: `CTRL_ADAPT_N` at build time, 18 (the AUV's) without it.
const N: usize = parse_n(option_env!("CTRL_ADAPT_N"));
/// CMA-ES's population: the tutorial's default 4 + ⌊3 ln N⌋ (checked at run time against
/// [`default_population`]).
const CMAES_L: usize = 4 + floor_3_ln(N);
/// CRS's points: the paper's 100 while that is more than N, else 2(N + 1).
const CRS_M: usize = if N < 99 { 100 } else { 2 * (N + 1) };
/// The diagonal CEM's samples per update and elites, as on the AUV.
const CEM_K: usize = 10;
/// See [`CEM_K`].
const CEM_E: usize = 5;
/// ROCK*'s memory: the recommended 5N rollouts.
const ROCKSTAR_M: usize = 5 * N;
/// The episodes LineBO's GP remembers: the recommended 64 up to N = 18, 48 beyond (the
/// docs' figure at N = 31).
const LINE_BO_M: usize = if N <= 18 { 64 } else { 48 };
/// Evaluations per optimizer: through every phase of their state machines, as in `bench`
/// (CRS's 100 initial points and 300 trials, 40 CEM updates, a CMA-ES generation and its
/// decomposition many times over).
const EVALUATIONS: u32 = 400;
/// ROCK*'s evaluations: its memory filled and then evicting for N more (each `tell` is
/// millions of instructions at N = 31).
const EVALUATIONS_ROCKSTAR: u32 = (ROCKSTAR_M + N) as u32;
/// LineBO's evaluations: its GP filled and then evicting for 8 more (each call is millions
/// of instructions).
const EVALUATIONS_LINE_BO: u32 = (LINE_BO_M + 8) as u32;

/// Optimizers not to run (their names, separated by commas): `CTRL_ADAPT_SKIP` at build time.
/// `scripts/sizes` sets it for those whose stack overflowed the RAM in a run before.
const SKIP: &str = match option_env!("CTRL_ADAPT_SKIP") {
    Some(names) => names,
    None => "",
};

/// Whether `name` is one of [`SKIP`].
fn skipped(name: &str) -> bool {
    SKIP.split(',').any(|skip| skip == name)
}

/// `CTRL_ADAPT_N` as a number from 1 to 127; anything else stops the build with a message.
const fn parse_n(text: Option<&str>) -> usize {
    let Some(text) = text else { return 18 };
    let bytes = text.as_bytes();
    assert!(
        !bytes.is_empty(),
        "CTRL_ADAPT_N is empty: set it to a number"
    );
    let mut n = 0usize;
    let mut i = 0;
    while i < bytes.len() {
        let digit = bytes[i];
        assert!(
            digit.is_ascii_digit(),
            "CTRL_ADAPT_N must be a decimal number"
        );
        n = n * 10 + (digit - b'0') as usize;
        assert!(n <= 127, "CTRL_ADAPT_N must be at most 127");
        i += 1;
    }
    assert!(n >= 2, "CTRL_ADAPT_N must be at least 2");
    n
}

/// ⌊3 ln n⌋ in a constant: the largest k with eᵏ ≤ n³.
const fn floor_3_ln(n: usize) -> usize {
    let cube = (n * n * n) as f64;
    let mut k = 0;
    let mut e_k = core::f64::consts::E;
    while e_k <= cube {
        k += 1;
        e_k *= core::f64::consts::E;
    }
    k
}

/// The box [−1, 1]ᴺ.
fn unit_box() -> Result<Bounds<N>, Error> {
    Bounds::uniform(-1.0, 1.0)
}

/// Runs up to `evaluations` ask/tell pairs of `optimizer` on the N-D ellipsoid (fewer if it
/// stops) and returns how many it ran.
#[inline(always)]
fn ask_tell<O: Optimizer<N>>(optimizer: &mut O, evaluations: u32) -> Result<u32, Error> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let ellipsoid = Ellipsoid::<N>::new();
    let mut run = 0;
    while run < evaluations && optimizer.status() == Status::Running {
        let theta = optimizer.ask(&mut rng)?;
        optimizer.tell(ellipsoid.eval(&theta))?;
        run += 1;
    }
    Ok(run)
}

/// One optimizer: `fn $build() -> Result<$t, Error>` and `fn $run(&mut $t) -> Result<u32,
/// Error>` ([`ask_tell`] for `$evaluations`), both out of line and not generic, so each
/// optimizer's code has names of its own in the ELF (`scripts/sizes` adds up their sizes).
macro_rules! optimizer {
    ($build:ident, $run:ident, $t:ty, $evaluations:expr, $construct:expr) => {
        #[inline(never)]
        fn $build() -> Result<$t, Error> {
            $construct
        }

        #[inline(never)]
        fn $run(optimizer: &mut $t) -> Result<u32, Error> {
            ask_tell(optimizer, $evaluations)
        }
    };
}

optimizer!(
    build_coordinate,
    run_coordinate,
    CoordinateSearch<N>,
    EVALUATIONS,
    CoordinateSearch::try_new(
        unit_box()?,
        Vector::zeros(),
        CoordinateConfig {
            initial_step: 0.25,
            tolerance: 1e-3,
            max_evaluations: u32::MAX,
            ..CoordinateConfig::DEFAULT
        },
    )
);
optimizer!(
    build_sracos,
    run_sracos,
    Sracos<N>,
    EVALUATIONS,
    Sracos::try_new(
        unit_box()?,
        SracosConfig {
            max_evaluations: u32::MAX,
            ..SracosConfig::DEFAULT
        },
    )
);
optimizer!(
    build_cem,
    run_cem,
    DiagonalCem<N, CEM_K, CEM_E>,
    EVALUATIONS,
    DiagonalCem::try_new(
        unit_box()?,
        Vector::zeros(),
        CemConfig {
            weighting: Weighting::CmaEs,
            initial_variance: 0.25 * 0.25,
            max_variance: 0.5 * 0.5,
            max_evaluations: u32::MAX,
            ..CemConfig::DEFAULT
        },
    )
);
optimizer!(
    build_crs,
    run_crs,
    ControlledRandomSearch<N, CRS_M>,
    EVALUATIONS,
    ControlledRandomSearch::try_new(
        unit_box()?,
        CrsConfig {
            max_evaluations: u32::MAX,
            ..CrsConfig::DEFAULT
        },
    )
);
optimizer!(
    build_cmaes,
    run_cmaes,
    Cmaes<N, CMAES_L>,
    EVALUATIONS,
    Cmaes::try_new(
        unit_box()?,
        Vector::zeros(),
        CmaesConfig {
            initial_sigma: 0.25,
            max_evaluations: u32::MAX,
            ..CmaesConfig::DEFAULT
        },
    )
);
optimizer!(
    build_rockstar,
    run_rockstar,
    Rockstar<N, ROCKSTAR_M>,
    EVALUATIONS_ROCKSTAR,
    Rockstar::try_new(unit_box()?, Vector::zeros(), RockstarConfig::DEFAULT)
);

optimizer!(
    build_line_bo,
    run_line_bo,
    LineBo<N, LINE_BO_M>,
    EVALUATIONS_LINE_BO,
    LineBo::try_new(unit_box()?, Vector::zeros(), LineBoConfig::DEFAULT)
);

/// Builds the optimizer in this frame and runs it: the stack of a firmware that keeps it on
/// the stack.
#[inline(never)]
fn build_and_run<O>(
    build: fn() -> Result<O, Error>,
    run: fn(&mut O) -> Result<u32, Error>,
) -> Result<u32, Error> {
    // Borrowed where it was built, inside the `Result`: moving it out would put a second
    // copy of its state on the stack.
    let mut built = build();
    run(built.as_mut().map_err(|e| *e)?)
}

/// Builds the optimizer, then measures the stack of its ask/tell calls alone: what a
/// firmware adds to the state when the state lives elsewhere.
#[inline(never)]
fn build_then_measure<O>(
    build: fn() -> Result<O, Error>,
    run: fn(&mut O) -> Result<u32, Error>,
) -> Result<u32, Error> {
    let mut built = build();
    let optimizer = built.as_mut().map_err(|e| *e)?;
    let (evaluations, calls) = stack::measure(|| run(optimizer));
    evaluations.map(|_| calls)
}

/// Measures one optimizer and logs its row; `params` are its const generics after N.
fn report<O>(
    name: &str,
    params: &[usize],
    build: fn() -> Result<O, Error>,
    run: fn(&mut O) -> Result<u32, Error>,
) -> Result<(), Error> {
    let state = core::mem::size_of::<O>();
    if state >= stack::region_bytes() as usize || skipped(name) {
        // Its state alone would overflow the stack (into the statics, then out of RAM), or
        // a run before this one overflowed it: say so instead of running.
        defmt::warn!(
            "sizes: row {=str} {=[?]} state {=usize} does not fit the stack region ({=u32} B)",
            name,
            params,
            state,
            stack::region_bytes()
        );
        return Ok(());
    }
    // Should the run overflow the stack, QEMU stops with a lockup and this line tells
    // scripts/sizes which optimizer to skip in the next build.
    defmt::info!("sizes: measuring {=str}", name);
    let (evaluations, whole) = stack::measure(|| build_and_run(build, run));
    let evaluations = evaluations?;
    let calls = build_then_measure(build, run)?;
    defmt::info!(
        "sizes: row {=str} {=[?]} state {=usize} stack {=u32} calls {=u32} evaluations {=u32}",
        name,
        params,
        state,
        whole,
        calls,
        evaluations
    );
    Ok(())
}

#[cortex_m_rt::entry]
fn main() -> ! {
    if CMAES_L != default_population(N) {
        defmt::error!(
            "CMA-ES population {=usize}, the default is {=usize}",
            CMAES_L,
            default_population(N)
        );
        exit_failure()
    }
    let measured = report("CoordinateSearch", &[N], build_coordinate, run_coordinate)
        .and_then(|()| report("Sracos", &[N], build_sracos, run_sracos))
        .and_then(|()| report("DiagonalCem", &[N, CEM_K, CEM_E], build_cem, run_cem))
        .and_then(|()| report("ControlledRandomSearch", &[N, CRS_M], build_crs, run_crs))
        .and_then(|()| report("Cmaes", &[N, CMAES_L], build_cmaes, run_cmaes))
        .and_then(|()| report("Rockstar", &[N, ROCKSTAR_M], build_rockstar, run_rockstar))
        .and_then(|()| report("LineBo", &[N, LINE_BO_M], build_line_bo, run_line_bo));
    if let Err(e) = measured {
        defmt::error!("sizes failed: {}", e);
        exit_failure()
    }
    exit_success()
}
