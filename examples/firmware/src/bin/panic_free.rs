//! Panic-freedom probe. Exercises the whole public API of `CoordinateSearch<18>` and `Bounds`
//! on inputs the optimiser cannot see through (`black_box`, an RNG, NaN and infinite costs),
//! and the PIL firmware's code path (frame decoding of arbitrary bytes, frame encoding,
//! reading and writing over an embedded-io port, the session and the stand-in controller
//! with its `CoordinateSearch<3>`), so that every panic path inside them stays in the binary
//! if it exists.
//!
//! Built with `--release --features panic-free` (see `scripts/panic-check`), the panic
//! handler references an undefined symbol: this binary links only if no panic is reachable
//! from any of these calls. Without the feature it runs under QEMU like the others.
#![no_std]
#![no_main]

use core::hint::black_box;

use ctrl_adapt::optimizer::unit_f32;
use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Status, Vector};
use ctrl_adapt_firmware::{exit_failure, exit_success};
use pil_link::standin::{PdCorrection, SEED, StandinConfig};
use pil_link::{Frame, FrameReader, Kind, LinkError, MAX_WIRE, Session, read_frame, write_frame};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = 18;

#[cortex_m_rt::entry]
fn main() -> ! {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(black_box(7));
    let lower = Vector::<N>::from_fn(|_, _| black_box(-2.0) * (1.0 + unit_f32(&mut rng)));
    let upper = Vector::<N>::from_fn(|_, _| black_box(2.0) * (1.0 + unit_f32(&mut rng)));
    let Ok(bounds) = Bounds::try_new(lower, upper) else {
        exit_failure()
    };
    let config = CoordinateConfig {
        initial_step: black_box(0.5),
        contraction: black_box(0.5),
        expansion: black_box(2.0),
        sufficient_decrease: black_box(1e-6),
        tolerance: black_box(1e-5),
        max_evaluations: black_box(5_000),
    };
    let start = bounds.sample_uniform(&mut rng);
    let steps = Vector::<N>::from_fn(|_, _| black_box(0.25) + unit_f32(&mut rng));
    let searches = [
        CoordinateSearch::try_new(bounds, start, config),
        CoordinateSearch::try_with_steps(bounds, start, steps, config),
    ];
    let mut told = 0u32;
    for search in searches {
        let Ok(mut search) = search else {
            exit_failure()
        };
        while search.status() == Status::Running {
            let Ok(theta) = search.ask(&mut rng) else {
                break;
            };
            // Costs from anywhere in f32, NaN and infinities included.
            let cost = match rng.next_u32() % 8 {
                0 => f32::from_bits(rng.next_u32()),
                _ => {
                    let clamped = bounds.clamp(&theta);
                    let ok = bounds.check(&clamped, "theta").is_ok() && bounds.contains(&theta);
                    black_box(ok);
                    theta.iter().map(|t| t * t).sum::<f32>()
                }
            };
            if search.tell(cost).is_ok() {
                told += 1;
            }
            black_box((search.best(), search.pending(), search.evaluations()));
            black_box((search.steps(), search.iterations(), search.config()));
            black_box(search.bounds());
        }
    }
    if !pil_session(&mut rng) {
        exit_failure()
    }
    if black_box(told) > 0 {
        exit_success()
    } else {
        exit_failure()
    }
}

/// The PIL firmware's path: random episodes of valid frames interleaved with arbitrary
/// bytes, through the reader, the session, the stand-in controller and a byte-slice port.
fn pil_session(rng: &mut Xoshiro128PlusPlus) -> bool {
    let Ok(controller) = PdCorrection::try_new(StandinConfig::DEFAULT, SEED) else {
        return false;
    };
    let mut session = Session::new(controller);
    let mut reader = FrameReader::new();
    let mut answers = 0u32;
    for step in 0..2_000u32 {
        let episode = (step / 100) as u16;
        let kind = match rng.next_u32() % 16 {
            0 => Kind::Start,
            1 => Kind::End,
            2 => Kind::Shutdown,
            _ => Kind::State,
        };
        let values = [
            f32::from_bits(rng.next_u32()),
            unit_f32(rng) - 0.5,
            unit_f32(rng),
        ];
        let count = (rng.next_u32() % 4) as usize;
        let frame = Frame::new(kind, episode, (step % 100) as u16).with_values(&values[..count]);
        // Encode into a port, then read it back, maybe with arbitrary bytes in between.
        let mut wire = [0u8; 2 * MAX_WIRE];
        let mut port: &mut [u8] = &mut wire;
        if write_frame(&mut port, &frame).is_err() {
            return false;
        }
        if rng.next_u32().is_multiple_of(4) {
            for byte in wire.iter_mut().take(MAX_WIRE) {
                *byte = rng.next_u32() as u8;
            }
        }
        let mut input: &[u8] = &wire;
        let reply = match read_frame(&mut input, &mut reader, || true) {
            Ok(f) => session.on_frame(&f),
            Err(LinkError::Timeout) => session.on_timeout(),
            Err(LinkError::Corrupt(_)) => {
                session.on_corrupt();
                None
            }
            Err(LinkError::Io(e)) => match e {},
        };
        if let Some(reply) = reply {
            answers += 1;
            let mut out = [0u8; MAX_WIRE];
            let mut out_port: &mut [u8] = &mut out;
            let _ = write_frame(&mut out_port, &reply);
            black_box(&out);
        }
        black_box((session.awaiting_tick(), session.finished(), session.stats()));
    }
    black_box(session.controller().best());
    answers > 0
}
