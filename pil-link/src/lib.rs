//! Processor-in-the-loop (PIL) link for `ctrl-adapt`.
//!
//! In a PIL run the plant is simulated on the host and the controller and the learner run on
//! the (emulated) microcontroller; every control tick the host sends the sensor state and the
//! firmware answers with the actuator command, over a serial line. This crate is the part
//! both ends share, `no_std` and allocation-free:
//!
//! * [`frame`]: the wire format (COBS framing, CRC-16, little-endian `f32` values) and a
//!   byte-at-a-time [`frame::FrameReader`] that resynchronises at the next delimiter after
//!   any corruption;
//! * [`link`]: reading and writing frames over any [`embedded_io`] serial port, with a
//!   deadline, so the same firmware code runs over QEMU's emulated UART or a real one;
//! * [`session`]: the firmware side of the protocol (episode start/end, one action per tick,
//!   the nominal fallback for a corrupted or missing state frame), generic over a
//!   [`session::Learner`] (the application: the library's `Adapter` with its controller,
//!   cost and optimizer; the AUV survey application is the `auv-survey` crate).
//!
//! # Protocol (one episode)
//! ```text
//! host                                   firmware
//! Start {episode, tick: ticks,          controller.start_episode (ask θ)
//!        values: [mode]} ──────────────►   (mode: learn / deploy / nominal, optional)
//!                      ◄──────────────── Started {episode, values: θ}
//! State {episode, tick k, values: x} ──► controller.act(x)      (valid frame)
//!                      ◄──────────────── Action {episode, k, values: u}
//!  (frame corrupted or missing)          deadline passes: controller.fallback(last x)
//!                      ◄──────────────── Action {episode, k, flags: FALLBACK, values: u_nominal}
//! ... ticks 0..ticks ...
//! End {episode} ───────────────────────► controller.end_episode (tell cost)
//!                      ◄──────────────── Report {episode, tick: fallbacks, values: the report}
//! Shutdown ────────────────────────────► Bye, firmware exits
//! ```
//! A firmware that keeps its learner on flash may be rebooted at any point (a power cut);
//! the host then asks where it stands, `Hello` ──► `Resume {episode}` (the next episode the
//! learner expects: 0 on a fresh start), and goes on from that episode.
//! The host sends a frame only after the answer to the previous one, so the firmware's
//! deadline per tick is the only timer on the target. Control frames (Start, End, Shutdown)
//! are idempotent and the host repeats them if no answer comes; the firmware answers a
//! repeated Start or End with the same Started or Report.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod frame;
pub mod link;
pub mod session;

pub use frame::{
    Frame, FrameError, FrameReader, Kind, MAX_VALUES, MAX_WIRE, Values, mode_code, mode_from_code,
};
pub use link::{LinkError, read_frame, write_frame};
pub use session::{Learner, Session, Stats};

/// Compile-time proof that the public types implement `defmt::Format` with the `defmt`
/// feature (the firmware builds with it).
#[cfg(feature = "defmt")]
const _: () = {
    const fn assert_format<T: defmt::Format>() {}
    assert_format::<Frame>();
    assert_format::<FrameError>();
    assert_format::<Kind>();
    assert_format::<LinkError<FrameError>>();
    assert_format::<Stats>();
};
