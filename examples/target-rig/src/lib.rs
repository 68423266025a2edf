//! Support code shared by the firmware binaries and the on-target tests for QEMU's
//! `mps2-an386` (Cortex-M4F): semihosting exit codes, the panic and HardFault handlers, the
//! peak-stack scan, the exec-trace markers of the footprint benchmark and the test
//! functions.
//!
//! # `unsafe` in this crate
//! The library (`ctrl-adapt`) is `#![forbid(unsafe_code)]`. This crate needs `unsafe` only
//! where it touches the machine below Rust's object model, and each block says why it is
//! sound: the memory-mapped UART registers ([`uart`]), the painted stack words outside any
//! Rust object ([`stack`]), and the deliberately undefined symbol of the panic-freedom build.
//! Everything else is safe code.
#![no_std]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

use cortex_m as _; // its critical-section implementation (single core), used by the logger
// The global defmt logger (semihosting stdout). Left out of the panic-free build: its
// re-entrancy check is a `panic!` that defmt.x keeps alive in every binary that links it.
#[cfg(not(feature = "panic-free"))]
use defmt_semihosting as _;

pub mod bench;
pub mod clock;
pub mod functions;
pub mod host_flash;
pub mod pil;
pub mod stack;
pub mod uart;

/// Ends the emulation with exit code 0 (semihosting `SYS_EXIT`).
pub fn exit_success() -> ! {
    semihosting::process::exit(0)
}

/// Ends the emulation with a non-zero exit code, so QEMU (and CI) report a failure.
pub fn exit_failure() -> ! {
    semihosting::process::exit(1)
}

/// Any panic logs where it happened and ends QEMU with a failure code (without this, QEMU
/// would spin forever in the default handler and CI would hang until its timeout). Only the
/// location is logged: formatting the message would link `core::fmt` (about 10 KB of flash).
/// A failed `defmt::assert!` logs its own message before it panics.
#[cfg(not(feature = "panic-free"))]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    exit_failure()
}

/// The panic-freedom proof (`--features panic-free`, release with LTO): the handler calls a
/// function that no object defines. If any panic path survives optimisation the handler is
/// reachable and the link fails with `undefined symbol: ctrl_adapt_reachable_panic`; a build
/// that links has no reachable panic at all.
#[cfg(feature = "panic-free")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    unsafe extern "C" {
        fn ctrl_adapt_reachable_panic() -> !;
    }
    // SAFETY: never executed: the symbol is undefined, so a binary in which this call is
    // reachable does not link.
    unsafe { ctrl_adapt_reachable_panic() }
}

// defmt's own `panic!`/`unwrap!` go through core's panic, hence through the handler above.
#[cfg(not(feature = "panic-free"))]
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    core::panic!()
}

/// A fault (bad memory access, undefined instruction, a `bkpt` without a debugger) logs the
/// faulting PC and ends QEMU with a failure code instead of hanging. The panic-free build
/// does not log here: defmt-semihosting's logger panics if it is re-entered (a fault while
/// logging), which would put a panic path into every binary.
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    #[cfg(not(feature = "panic-free"))]
    defmt::error!(
        "HardFault at pc={=u32:#010x} lr={=u32:#010x}",
        frame.pc(),
        frame.lr()
    );
    #[cfg(feature = "panic-free")]
    let _ = frame;
    exit_failure()
}
