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
        /// One control tick of the AUV adapter with the runtime guard: 6 state limits and a
        /// 240-tick envelope (`Guard<6, 240>`), `Adapter::control`.
        guarded_control = 13;
    }
}

/// Instruction counts of long calls from SysTick, for code too long to trace.
///
/// An exec trace costs a host-side line per executed instruction, which is too slow for
/// calls of a million instructions (ROCK*'s `tell`) repeated hundreds of times. Under QEMU's
/// `-icount shift=0` every instruction advances the virtual clock by exactly 1 ns, and QEMU
/// clocks the mps2-an386's SysTick (processor clock source) at 25 MHz of that virtual
/// time: one SysTick count is 40 instructions. [`Counter::measure`] reads the counter
/// before and after a call, so its figure is exact to ±40 instructions, plus the two reads
/// (a few instructions). Without `-icount` the figures are host-speed dependent and
/// meaningless: `scripts/footprint` always passes it.
pub mod icount {
    use cortex_m::peripheral::SYST;
    use cortex_m::peripheral::syst::SystClkSource;

    /// Instructions per SysTick count under `-icount shift=0` (1 GHz virtual, 25 MHz clock).
    pub const INSTRUCTIONS_PER_COUNT: u32 = 40;
    /// SysTick's counter is 24 bits wide.
    const MASK: u32 = 0x00FF_FFFF;

    /// A free-running SysTick.
    pub struct Counter {
        _syst: SYST,
    }

    impl Counter {
        /// Starts SysTick counting down from 2²⁴ − 1 on the processor clock, no interrupt.
        pub fn new(mut syst: SYST) -> Self {
            syst.set_clock_source(SystClkSource::Core);
            syst.set_reload(MASK);
            syst.clear_current();
            syst.disable_interrupt();
            syst.enable_counter();
            Self { _syst: syst }
        }

        /// Runs `f` and returns its result with the instructions it took (one wrap of the
        /// counter, 671 million instructions, at most).
        #[inline(always)]
        pub fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
            let start = SYST::get_current();
            let r = core::hint::black_box(f());
            let end = SYST::get_current();
            (r, (start.wrapping_sub(end) & MASK) * INSTRUCTIONS_PER_COUNT)
        }
    }
}

/// Instruction counts of optimizers whose calls are too long to trace (ROCK*, LineBO),
/// from [`icount::Counter`]: each `ask` and `tell` logs `footprint: sample {name}_ask = N`
/// (and `…_tell`), which `scripts/footprint` turns into the table's statistics.
pub mod long {
    use ctrl_adapt::{Error, Optimizer, Status, Vector};
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    use super::icount::Counter;
    use crate::functions::Ellipsoid;

    /// Which evaluations to measure, and under which names.
    #[derive(Clone, Copy)]
    pub struct Plan<'a> {
        /// The section name of the samples: `footprint: sample {name}_ask = N`.
        pub name: &'a str,
        /// Evaluations to run (fewer if the optimizer stops).
        pub evaluations: u32,
        /// From this evaluation on (counting from 0), the samples are logged under
        /// `later` instead of `name`: the steady state of an optimizer whose memory has
        /// filled (`u32::MAX`: never).
        pub split: u32,
        /// The section name after `split`.
        pub later: &'a str,
    }

    /// Builds the optimizer with `build` and measures it as `plan` says on the `D`-D
    /// ellipsoid. Never inlined: the optimizer lives in this frame only (kept in its
    /// `Result`, lent to [`measure`]), so the peak stack holds one copy of it.
    #[inline(never)]
    pub fn build_and_measure<const D: usize, O: Optimizer<D>>(
        counter: &mut Counter,
        plan: Plan<'_>,
        build: fn() -> Result<O, Error>,
    ) -> Result<(), Error> {
        let mut built = build();
        let optimizer = built.as_mut().map_err(|e| *e)?;
        measure(counter, plan, optimizer)
    }

    /// Runs the ask/tell pairs of `plan` of `optimizer` on the `D`-D ellipsoid, logging
    /// each call's instruction count as `footprint: sample {name}_ask = N` and `…_tell`.
    #[inline(never)]
    pub fn measure<const D: usize, O: Optimizer<D>>(
        counter: &mut Counter,
        plan: Plan<'_>,
        optimizer: &mut O,
    ) -> Result<(), Error> {
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
        for k in 0..plan.evaluations {
            if optimizer.status() != Status::Running {
                break;
            }
            let (cost, ask) = ask_and_evaluate(counter, optimizer, &mut rng)?;
            let (told, tell) = counter.measure(|| optimizer.tell(cost));
            told?;
            let name = if k < plan.split {
                plan.name
            } else {
                plan.later
            };
            defmt::info!("footprint: sample {=str}_ask = {=u32}", name, ask);
            defmt::info!("footprint: sample {=str}_tell = {=u32}", name, tell);
        }
        let name = plan.name;
        defmt::info!(
            "footprint: measured {=str} evaluations = {=u32}",
            name,
            optimizer.evaluations()
        );
        Ok(())
    }

    /// One measured `ask` and the cost of its candidate on the `D`-D ellipsoid, with the
    /// `ask`'s instruction count. Out of line, and the ellipsoid (8n bytes) made here each
    /// time: neither it nor the candidate is in the frame that waits on `tell`.
    #[inline(never)]
    fn ask_and_evaluate<const D: usize, O: Optimizer<D>>(
        counter: &mut Counter,
        optimizer: &mut O,
        rng: &mut Xoshiro128PlusPlus,
    ) -> Result<(f32, u32), Error> {
        let (theta, ask): (Result<Vector<D>, Error>, u32) = counter.measure(|| optimizer.ask(rng));
        Ok((Ellipsoid::<D>::new().eval(&theta?), ask))
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
        // Borrowed where it was built, inside the `Result`: moving it out would put a second
        // copy of its state on the stack.
        let mut built = $optimizer;
        let optimizer = match &mut built {
            Ok(optimizer) => optimizer,
            Err(e) => return Err(*e),
        };
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
