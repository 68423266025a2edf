//! Processor-in-the-loop firmware: the controller and the learner run here, the plant runs
//! on the host (`cargo run -p host-tests --bin pil`), and the two exchange one state frame
//! and one action frame per control tick over UART0 ([`pil_link`] frames).
//!
//! The controller is [`pil_link::standin::PdCorrection`] until the controller layer's
//! `Adapter` replaces it (docs/firmware.md says how). A state frame that is corrupted, or
//! that has not arrived [`TICK_DEADLINE_MS`] after the previous answer, makes this tick's
//! action the nominal PD's (flagged `FALLBACK` in the action frame).
#![no_std]
#![no_main]

use ctrl_adapt_firmware::clock::Millis;
use ctrl_adapt_firmware::uart::{CmsdkUart, UART0_BASE};
use ctrl_adapt_firmware::{exit_failure, exit_success, stack};
use pil_link::standin::{PdCorrection, SEED, StandinConfig};
use pil_link::{FrameReader, Kind, LinkError, Session, read_frame, write_frame};

/// How long a tick waits for its state frame before falling back. The host answers within
/// microseconds; the margin absorbs a loaded CI machine (QEMU's clock is the host's).
const TICK_DEADLINE_MS: u32 = 50;
/// Core clock of QEMU's mps2 boards (SYSCLK).
const CORE_HZ: u32 = 25_000_000;

#[cortex_m_rt::entry]
fn main() -> ! {
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut clock = Millis::new(peripherals.SYST, CORE_HZ);
    // SAFETY: UART0 of mps2-an386 is a CMSDK APB UART at this address (QEMU hw/arm/mps2.c),
    // and this is its only user.
    let mut uart = unsafe { CmsdkUart::new(UART0_BASE, 16) };
    let Ok(controller) = PdCorrection::try_new(StandinConfig::DEFAULT, SEED) else {
        defmt::error!("invalid stand-in configuration");
        exit_failure()
    };
    let mut session = Session::new(controller);
    defmt::info!(
        "footprint: size_of Session<PdCorrection> = {=usize}",
        core::mem::size_of::<Session<PdCorrection>>()
    );
    defmt::info!("pil: waiting for the host on UART0");

    let mut reader = FrameReader::new();
    let mut deadline = clock.now().wrapping_add(TICK_DEADLINE_MS);
    loop {
        let awaiting = session.awaiting_tick();
        let received = read_frame(&mut uart, &mut reader, || {
            awaiting && clock.now().wrapping_sub(deadline) as i32 >= 0
        });
        let reply = match received {
            Ok(frame) => session.on_frame(&frame),
            Err(LinkError::Timeout) => session.on_timeout(),
            Err(LinkError::Corrupt(why)) => {
                defmt::debug!("corrupt frame: {}", why);
                session.on_corrupt();
                None
            }
            Err(LinkError::Io(_)) => {
                // A lost byte: whatever frame it belonged to is damaged.
                session.on_corrupt();
                reader = FrameReader::new();
                None
            }
        };
        let Some(reply) = reply else { continue };
        match reply.kind {
            Kind::Started => defmt::info!(
                "episode {=u16}: theta = {=[?]}",
                reply.episode,
                reply.values.as_slice()
            ),
            Kind::Report => defmt::info!(
                "episode {=u16}: cost {=[?]}, fallback ticks {=u16}",
                reply.episode,
                reply.values.as_slice(),
                reply.tick
            ),
            _ => {}
        }
        if write_frame(&mut uart, &reply).is_err() {
            defmt::error!("UART write failed");
            exit_failure()
        }
        deadline = clock.now().wrapping_add(TICK_DEADLINE_MS);
        if session.finished() {
            let stats = session.stats();
            defmt::info!(
                "pil: done; corrupt frames {=u32}, fallback ticks {=u32}, ignored frames {=u32}",
                stats.corrupt,
                stats.fallbacks,
                stats.ignored
            );
            defmt::info!("footprint: peak stack pil = {=u32}", stack::peak_bytes());
            exit_success()
        }
    }
}
