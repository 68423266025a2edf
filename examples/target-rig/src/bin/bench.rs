//! Footprint benchmark of the optimizers: every measured call sits between exec-trace markers
//! ([`ctrl_adapt_firmware::bench`]); `scripts/footprint` runs this firmware under QEMU with an
//! instruction trace and counts the instructions of each call. Measured: one `ask` and one
//! `tell` of each optimizer over the AUV box of [`auv_survey`] (N = 18), 400 evaluations
//! each, on the 18-D ill-conditioned ellipsoid (its minimiser is inside the box): the
//! coordinate search, SRACOS, the diagonal CEM, the controlled random search (100 points) and
//! the full-covariance CMA-ES (λ = 12, the default population for 18 parameters).
//! The control tick is measured by the `tick` firmware.
//!
//! It also prints the `size_of` of each optimizer and of the AUV adapter around it.
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvAdapter, AuvCem, AuvCrs};
use ctrl_adapt::{Cmaes, CmaesConfig, CoordinateSearch, Error, Sracos};
use ctrl_adapt_firmware::bench::sections;
use ctrl_adapt_firmware::{exit_failure, exit_success, log_size, measure_optimizer, stack};

const N: usize = auv::P;
/// The CMA-ES measured: the tutorial's default population 4 + ⌊3 ln 18⌋ = 12.
type AuvCmaes = Cmaes<N, 12>;
/// Measured evaluations per optimizer: enough to pass through every phase of their state
/// machines (the coordinate search's probes, expansions, contractions and several sweeps;
/// SRACOS's 12 initial samples and the model updates; 40 CEM updates; CRS's 100 initial
/// points and 300 trial points).
///
/// On the Cortex-M0 (thumbv6m-none-eabi, no FPU: every `f32` operation is a library call)
/// an exec trace of as many would take too long for CI (400 evaluations of CMA-ES alone are
/// some 600 million instructions there), so fewer are measured: 50 of each optimizer, 120
/// of CRS (its 100 initial points, then 20 trial points) and 12 of CMA-ES (one whole
/// generation with its decomposition, so the mean is that of a generation).
const MEASURED: u32 = if M0 { 50 } else { 400 };
/// See [`MEASURED`].
const MEASURED_CRS: u32 = if M0 { 120 } else { 400 };
/// See [`MEASURED`].
const MEASURED_CMAES: u32 = if M0 { 12 } else { 400 };
/// Whether this build is for the Cortex-M0 (soft-float ABI) rather than the Cortex-M4F.
const M0: bool = cfg!(target_abi = "eabi");

#[cortex_m_rt::entry]
fn main() -> ! {
    log_size!("CoordinateSearch<18>", CoordinateSearch<N>);
    log_size!("Sracos<18>", Sracos<N>);
    log_size!("DiagonalCem<18, 10, 5>", AuvCem);
    log_size!("ControlledRandomSearch<18, 100>", AuvCrs);
    log_size!("Cmaes<18, 12>", AuvCmaes);
    log_size!(
        "Adapter with CoordinateSearch<18>",
        AuvAdapter<CoordinateSearch<N>>
    );
    log_size!("Adapter with Sracos<18>", AuvAdapter<Sracos<N>>);
    log_size!("Adapter with DiagonalCem<18, 10, 5>", AuvAdapter<AuvCem>);
    log_size!(
        "Adapter with ControlledRandomSearch<18, 100>",
        AuvAdapter<AuvCrs>
    );
    log_size!("Adapter with Cmaes<18, 12>", AuvAdapter<AuvCmaes>);
    for _ in 0..8 {
        sections::empty::measure(|| ());
    }
    let measured = coordinate_search()
        .and_then(|()| sracos())
        .and_then(|()| cem())
        .and_then(|()| crs())
        .and_then(|()| cmaes());
    if let Err(e) = measured {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    defmt::info!("footprint: peak stack bench = {=u32}", stack::peak_bytes());
    exit_success()
}

// One function per optimizer, never inlined, so that each one's state lives in its own
// stack frame and the peak stack is that of the largest, not of all of them together.

#[inline(never)]
fn coordinate_search() -> Result<(), Error> {
    measure_optimizer!(
        auv::coordinate_search(u32::MAX),
        N,
        MEASURED,
        coordinate_ask,
        coordinate_tell
    )
}

#[inline(never)]
fn sracos() -> Result<(), Error> {
    measure_optimizer!(auv::sracos(u32::MAX), N, MEASURED, sracos_ask, sracos_tell)
}

#[inline(never)]
fn cem() -> Result<(), Error> {
    measure_optimizer!(auv::cem(u32::MAX), N, MEASURED, cem_ask, cem_tell)
}

#[inline(never)]
fn crs() -> Result<(), Error> {
    measure_optimizer!(auv::crs(u32::MAX), N, MEASURED_CRS, crs_ask, crs_tell)
}

#[inline(never)]
fn cmaes() -> Result<(), Error> {
    // σ₀ 0.25 of the box's half-width, as the AUV's coordinate-search step; a decomposition
    // every generation (the default).
    let config = CmaesConfig {
        initial_sigma: 0.25,
        max_evaluations: u32::MAX,
        ..CmaesConfig::DEFAULT
    };
    measure_optimizer!(
        AuvCmaes::try_new(auv::bounds()?, ctrl_adapt::Vector::zeros(), config),
        N,
        MEASURED_CMAES,
        cmaes_ask,
        cmaes_tell
    )
}
