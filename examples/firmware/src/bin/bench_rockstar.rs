//! Footprint benchmark of ROCK* (`Rockstar`), apart from the `bench` firmware because its
//! state is large: `Rockstar<18, 90>` (the AUV's 18 parameters with the recommended memory
//! of 5n rollouts) and `Rockstar<31, 155>` (the hopping leg's 31 parameters, 5n again).
//! `scripts/footprint` runs it under QEMU with an instruction trace and counts the
//! instructions of each `ask` and `tell` between the [`ctrl_adapt_firmware::bench`] markers,
//! on the ill-conditioned ellipsoid of the same dimension over the box [−1, 1]ⁿ; it also
//! prints the `size_of` of both and of the AUV adapter around the 18-parameter one, and the
//! peak stack.
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvAdapter};
use ctrl_adapt::{Bounds, Error, Rockstar, RockstarConfig, Vector};
use ctrl_adapt_firmware::bench::sections;
use ctrl_adapt_firmware::{exit_failure, exit_success, log_size, measure_optimizer, stack};

/// The AUV's parameters.
const N: usize = auv::P;
/// The hopping leg's parameters (10 periodic kernels for each of three gains, and the period).
const N_HOPPER: usize = 31;
/// Measured evaluations per size: past the two initial samples and the first covariance
/// refactorings (every n updates), with the memory filled and then evicting.
const MEASURED: u32 = 200;

#[cortex_m_rt::entry]
fn main() -> ! {
    log_size!("Rockstar<18, 90>", Rockstar<N, 90>);
    log_size!("Rockstar<31, 155>", Rockstar<N_HOPPER, 155>);
    log_size!("Adapter with Rockstar<18, 90>", AuvAdapter<Rockstar<N, 90>>);
    for _ in 0..8 {
        sections::empty::measure(|| ());
    }
    if let Err(e) = auv_size().and_then(|()| hopper_size()) {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    defmt::info!(
        "footprint: peak stack bench_rockstar = {=u32}",
        stack::peak_bytes()
    );
    exit_success()
}

#[inline(never)]
fn auv_size() -> Result<(), Error> {
    measure_optimizer!(
        Rockstar::<N, 90>::try_new(auv::bounds()?, Vector::zeros(), RockstarConfig::DEFAULT),
        N,
        MEASURED,
        rockstar_ask,
        rockstar_tell
    )
}

#[inline(never)]
fn hopper_size() -> Result<(), Error> {
    measure_optimizer!(
        Rockstar::<N_HOPPER, 155>::try_new(
            Bounds::uniform(-1.0, 1.0)?,
            Vector::zeros(),
            RockstarConfig::DEFAULT
        ),
        N_HOPPER,
        MEASURED,
        rockstar_hopper_ask,
        rockstar_hopper_tell
    )
}
