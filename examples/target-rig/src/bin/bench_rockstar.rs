//! Footprint benchmark of ROCK* (`Rockstar`), apart from the `bench` firmware because its
//! state is large and its calls long: `Rockstar<18, 90>` (the AUV's 18 parameters with the
//! recommended memory of 5n rollouts) and `Rockstar<31, 155>` (the hopping leg's 31
//! parameters, 5n again), each for [`MEASURED`] evaluations of the ill-conditioned
//! ellipsoid of its dimension over the box [−1, 1]ⁿ from 0: past the memory's filling and
//! into its eviction.
//!
//! A `tell` runs about a million instructions, too many to trace one by one, so the counts
//! come from SysTick under QEMU's `-icount shift=0`
//! ([`ctrl_adapt_firmware::bench::icount`], exact to ±40 instructions): each `ask` and
//! `tell` logs `footprint: sample rockstar_ask = N` (…`_tell`, and `rockstar_hopper_…` for
//! N = 31), which `scripts/footprint` turns into the table's statistics. It also prints the
//! `size_of` of both, of the AUV adapter around the 18-parameter one, and the peak stack.
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvAdapter};
use ctrl_adapt::{Bounds, Error, Optimizer, Rockstar, RockstarConfig, Status, Vector};
use ctrl_adapt_firmware::bench::icount::Counter;
use ctrl_adapt_firmware::functions::Ellipsoid;
use ctrl_adapt_firmware::{exit_failure, exit_success, log_size, stack};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The AUV's parameters.
const N: usize = auv::P;
/// The hopping leg's parameters (10 periodic kernels for each of three gains, and the period).
const N_HOPPER: usize = 31;
/// Measured evaluations per size: more than the larger memory (155), so the counts include
/// the memory full and evicting, and several refactorings of the covariance (every n).
pub const MEASURED: u32 = 200;

/// Builds `Rockstar<D, M>` with the defaults over the box `bounds` gives, from 0, and
/// measures it. Never inlined: the optimizer lives in this frame only (kept in its
/// `Result`, lent to [`measure`]), so the peak stack holds one copy of it.
#[inline(never)]
fn build_and_measure<const D: usize, const M: usize>(
    counter: &mut Counter,
    name: &str,
    bounds: fn() -> Result<Bounds<D>, Error>,
) -> Result<(), Error> {
    let mut built = build::<D, M>(bounds);
    let rock = built.as_mut().map_err(|e| *e)?;
    measure(counter, name, rock)
}

/// The construction, out of line: its temporaries (the box, the configuration) are not in
/// the frame that holds the optimizer while it runs; the optimizer itself is written into
/// the caller's `Result`.
#[inline(never)]
fn build<const D: usize, const M: usize>(
    bounds: fn() -> Result<Bounds<D>, Error>,
) -> Result<Rockstar<D, M>, Error> {
    bounds().and_then(|b| Rockstar::try_new(b, Vector::zeros(), RockstarConfig::DEFAULT))
}

/// The hopping leg's box, [−1, 1]ⁿ.
fn unit_box() -> Result<Bounds<N_HOPPER>, Error> {
    Bounds::uniform(-1.0, 1.0)
}

/// Runs `MEASURED` ask/tell pairs of `rock` on the `D`-D ellipsoid, logging each call's
/// instruction count as `footprint: sample {name}_ask = N` and `…_tell`.
#[inline(never)]
fn measure<const D: usize, const M: usize>(
    counter: &mut Counter,
    name: &str,
    rock: &mut Rockstar<D, M>,
) -> Result<(), Error> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    for _ in 0..MEASURED {
        if rock.status() != Status::Running {
            break;
        }
        let (cost, ask) = ask_and_evaluate(counter, rock, &mut rng)?;
        let (told, tell) = counter.measure(|| rock.tell(cost));
        told?;
        defmt::info!("footprint: sample {=str}_ask = {=u32}", name, ask);
        defmt::info!("footprint: sample {=str}_tell = {=u32}", name, tell);
    }
    defmt::info!(
        "footprint: measured {=str} evaluations = {=u32}",
        name,
        rock.evaluations()
    );
    Ok(())
}

/// One measured `ask` and the cost of its candidate on the `D`-D ellipsoid, with the
/// `ask`'s instruction count. Out of line, and the ellipsoid (8n bytes) made here each
/// time: neither it nor the candidate is in the frame that waits on `tell`.
#[inline(never)]
fn ask_and_evaluate<const D: usize, const M: usize>(
    counter: &mut Counter,
    rock: &mut Rockstar<D, M>,
    rng: &mut Xoshiro128PlusPlus,
) -> Result<(f32, u32), Error> {
    let (theta, ask) = counter.measure(|| rock.ask(rng));
    Ok((Ellipsoid::<D>::new().eval(&theta?), ask))
}

/// The stack ROCK* may take beyond its own state (the rule every optimizer follows).
const STACK_BEYOND_STATE: usize = 2048;

#[cortex_m_rt::entry]
fn main() -> ! {
    log_size!("Rockstar<18, 90>", Rockstar<N, 90>);
    log_size!("Rockstar<31, 155>", Rockstar<N_HOPPER, 155>);
    log_size!("Adapter with Rockstar<18, 90>", AuvAdapter<Rockstar<N, 90>>);
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut counter = Counter::new(peripherals.SYST);
    // Calibration: an empty call, whose count is the reads' own cost (0 or 40).
    for _ in 0..4 {
        let ((), empty) = counter.measure(|| ());
        defmt::info!("footprint: sample empty = {=u32}", empty);
    }
    let measured =
        build_and_measure::<N, 90>(&mut counter, "rockstar", auv::bounds).and_then(|()| {
            build_and_measure::<N_HOPPER, 155>(&mut counter, "rockstar_hopper", unit_box)
        });
    if let Err(e) = measured {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    let peak = stack::peak_bytes();
    defmt::info!("footprint: peak stack bench_rockstar = {=u32}", peak);
    // ROCK* needs O(n) stack beyond its own state, like every other optimizer: the largest
    // one measured here may take at most its state + 2 KB.
    let budget = core::mem::size_of::<Rockstar<N_HOPPER, 155>>() + STACK_BEYOND_STATE;
    if peak as usize > budget {
        defmt::error!(
            "peak stack {=u32} B exceeds state + 2 KB = {=usize} B",
            peak,
            budget
        );
        exit_failure()
    }
    exit_success()
}
