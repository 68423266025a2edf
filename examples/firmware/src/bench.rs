//! Markers for deterministic instruction counts (see `scripts/footprint`).
//!
//! QEMU does not implement the DWT cycle counter, so the footprint script runs the `bench`
//! firmware with one instruction per translation block and an execution log
//! (`-d exec,nochain` with `-singlestep` / `one-insn-per-tb`): every executed instruction
//! is one `Trace` line. Each measured section is wrapped in a pair of never-inlined marker
//! functions, `bench::sections::<name>::start` and `..::end`; the script finds their
//! addresses with `nm` and counts the trace lines between a return from `start` and the
//! call of `end`. The count is exact for this binary (no interrupts are enabled) and
//! independent of the host's speed.
//!
//! Add a section with one line in the `sections!` invocation below and wrap the code to
//! measure in `sections::<name>::measure(|| ..)`; the script picks it up by name.

/// Defines one module per measured section, each with `start`/`end` markers and `measure`.
/// Each marker body passes a distinct constant through `black_box`, so LLVM's function
/// merging can never fold two markers into one address.
macro_rules! sections {
    ($($(#[$doc:meta])* $name:ident = $id:literal;)*) => {
        $(
            $(#[$doc])*
            pub mod $name {
                /// Marks the start of one measured run of the section.
                #[inline(never)]
                pub fn start() {
                    core::hint::black_box(2 * $id as u32);
                }
                /// Marks the end of one measured run of the section.
                #[inline(never)]
                pub fn end() {
                    core::hint::black_box(2 * $id as u32 + 1);
                }
                /// Runs `f` between the two markers.
                #[inline(always)]
                pub fn measure<R>(f: impl FnOnce() -> R) -> R {
                    start();
                    let r = core::hint::black_box(f());
                    end();
                    r
                }
            }
        )*
    };
}

/// One module per measured section.
pub mod sections {
    sections! {
        /// Calibration: nothing between the markers, so its count is the markers' own
        /// overhead, which the script subtracts from every other section.
        empty = 0;
        /// One control tick of the AUV adapter: `Adapter::control` (N = 18).
        control = 1;
        /// The policy correction alone: `LinearPolicy::correction`, clamp(W·φ) (N = 18).
        correction = 2;
        /// `CoordinateSearch::<18>::ask`.
        coordinate_ask = 3;
        /// `CoordinateSearch::<18>::tell`.
        coordinate_tell = 4;
        /// `Sracos::<18>::ask`.
        sracos_ask = 5;
        /// `Sracos::<18>::tell`.
        sracos_tell = 6;
        /// `DiagonalCem::<18, 10, 5>::ask`.
        cem_ask = 7;
        /// `DiagonalCem::<18, 10, 5>::tell`.
        cem_tell = 8;
        /// `ControlledRandomSearch::<18, 100>::ask`.
        crs_ask = 9;
        /// `ControlledRandomSearch::<18, 100>::tell`.
        crs_tell = 10;
        /// `Cmaes::<18, 12>::ask`.
        cmaes_ask = 11;
        /// `Cmaes::<18, 12>::tell`.
        cmaes_tell = 12;
        /// `Rockstar::<18, 90>::ask`.
        rockstar_ask = 13;
        /// `Rockstar::<18, 90>::tell`.
        rockstar_tell = 14;
        /// `Rockstar::<31, 155>::ask` (the hopping leg's 31 parameters).
        rockstar_hopper_ask = 15;
        /// `Rockstar::<31, 155>::tell`.
        rockstar_hopper_tell = 16;
    }
}

/// Logs `footprint: size_of NAME = N` for the type `$t`.
#[macro_export]
macro_rules! log_size {
    ($name:literal, $t:ty) => {
        defmt::info!(
            "footprint: size_of {=str} = {=usize}",
            $name,
            core::mem::size_of::<$t>()
        )
    };
}

/// Runs up to `$measured` ask/tell pairs of `$optimizer` (a `Result<O, Error>` expression)
/// on the `$n`-D ill-conditioned ellipsoid, each call between the markers of sections
/// `$ask` and `$tell`, and logs how many pairs were measured. Evaluates to
/// `Result<(), Error>`; use it in a never-inlined function per optimizer, so that each one's
/// state lives in its own stack frame.
#[macro_export]
macro_rules! measure_optimizer {
    ($optimizer:expr, $n:expr, $measured:expr, $ask:ident, $tell:ident) => {{
        use ctrl_adapt::{Optimizer as _, Status};
        use rand_core::SeedableRng as _;
        let mut optimizer = $optimizer?;
        let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
        let ellipsoid = $crate::functions::Ellipsoid::<{ $n }>::new();
        for _ in 0..$measured {
            if optimizer.status() != Status::Running {
                break;
            }
            let theta = $crate::bench::sections::$ask::measure(|| optimizer.ask(&mut rng))?;
            let cost = ellipsoid.eval(&theta);
            $crate::bench::sections::$tell::measure(|| optimizer.tell(cost))?;
        }
        defmt::info!(
            "footprint: measured {=str} + tell pairs = {=u32}",
            stringify!($ask),
            optimizer.evaluations()
        );
        Ok::<(), ctrl_adapt::Error>(())
    }};
}
