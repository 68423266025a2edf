//! The PIL protocol end to end without QEMU: the firmware's `Session` and stand-in
//! controller behind an in-process byte pipe, with the host's episode runner, fault
//! injection and reference replay (`src/pil.rs`). The QEMU run is `cargo run -p host-tests
//! --bin pil` (scripts/firmware-ci).

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

use host_tests::pil::{
    DoubleIntegrator, Fault, FaultPlan, Link, RunConfig, reference_run, run_episodes, wire,
};
use pil_link::standin::{PdCorrection, StandinConfig};
use pil_link::{Frame, FrameReader, Session};

/// A [`Link`] to a firmware simulated in-process: the firmware's `Session` behind a byte
/// pipe, with the firmware's deadline replaced by "no complete frame arrived".
struct Loopback {
    session: Session<PdCorrection>,
    reader: FrameReader,
    outbox: VecDeque<Frame>,
}

impl Link for Loopback {
    fn send(&mut self, frame: &Frame, fault: Option<Fault>) -> io::Result<()> {
        let bytes = if fault == Some(Fault::Drop) {
            Vec::new()
        } else {
            wire(frame, fault)
        };
        let mut got_frame = false;
        for b in bytes {
            match self.reader.push(b) {
                Some(Ok(f)) => {
                    got_frame = true;
                    self.outbox.extend(self.session.on_frame(&f));
                }
                Some(Err(_)) => self.session.on_corrupt(),
                None => {}
            }
        }
        if !got_frame {
            self.outbox.extend(self.session.on_timeout());
        }
        Ok(())
    }
    fn receive(&mut self, _: Duration) -> io::Result<Option<Frame>> {
        Ok(self.outbox.pop_front())
    }
}

/// Checks, without QEMU: with faults injected, every faulty tick is answered with the
/// fallback and no other tick is; the reference replay reproduces the run exactly (same
/// code, same arithmetic); and learning beats the first (bare PD) episode.
#[test]
fn loopback_run_matches_the_reference_and_learns() {
    let controller = || PdCorrection::try_new(StandinConfig::DEFAULT, 1).unwrap();
    let mut link = Loopback {
        session: Session::new(controller()),
        reader: FrameReader::new(),
        outbox: VecDeque::new(),
    };
    let config = RunConfig {
        episodes: 30,
        ticks: 200,
        faults: FaultPlan {
            corrupt_every: 151,
            drop_every: 197,
        },
    };
    let mut plant = DoubleIntegrator::DEMO;
    let records = run_episodes(&mut link, &mut plant, config, |_| {}).unwrap();
    for r in &records {
        let injected: Vec<u16> = r.injected.iter().map(|&(t, _)| t).collect();
        assert_eq!(r.fallback_ticks, injected, "episode {}", r.episode);
    }
    assert!(records.iter().map(|r| r.injected.len()).sum::<usize>() > 40);
    let mut replay_plant = DoubleIntegrator::DEMO;
    let reference = reference_run(controller(), &mut replay_plant, 200, &records);
    for (r, q) in records.iter().zip(&reference) {
        assert_eq!(
            (&r.theta, r.host_cost, &r.report),
            (&q.theta, q.host_cost, &q.report)
        );
    }
    let first = records[0].host_cost;
    let last = records.last().unwrap().host_cost;
    assert!(last < 0.8 * first, "first {first}, last {last}");
}
