//! The PIL protocol end to end without QEMU: the firmware's `Session` and AUV learner (the
//! library's `Adapter` with `CoordinateSearch<18>`) behind an in-process byte pipe, with the
//! host's episode runner, fault injection and reference replay (`src/pil.rs`). The QEMU run
//! is `cargo run --release -p host-tests --bin pil` (scripts/firmware-ci).

use std::collections::VecDeque;
use std::io;
use std::time::Duration;

use auv_survey::{self as auv, AuvLearner, Report};
use ctrl_adapt::controller::Mode;
use host_tests::auv::AuvConfig;
use host_tests::pil::{
    AuvPlant, Fault, FaultPlan, Link, PilPlant, RunConfig, reference_run, run_episodes, wire,
};
use pil_link::{Frame, FrameReader, Session};

type Learner = AuvLearner<ctrl_adapt::CoordinateSearch<{ auv::P }>>;

/// A [`Link`] to a firmware simulated in-process: the firmware's `Session` behind a byte
/// pipe, with the firmware's deadline replaced by "no complete frame arrived".
struct Loopback {
    session: Session<Learner>,
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

fn learner() -> Learner {
    AuvLearner::try_new(
        auv::coordinate_search(u32::MAX).unwrap(),
        u32::MAX,
        auv::SEED,
    )
    .unwrap()
}

fn plant() -> AuvPlant {
    AuvPlant::new(AuvConfig::REAL, 1)
}

/// Checks, without QEMU, 1 bare-PD + 25 learning + 1 deployed AUV episodes with faults
/// injected: every faulty tick is answered with the fallback and no other tick is; the
/// reference replay reproduces the run bit for bit (same code, same arithmetic); the first
/// learning episode runs W = 0 (the bare PD) and the deployed best θ beats the bare PD;
/// the firmware's report agrees with the host's measure of the survey.
#[test]
fn loopback_auv_run_matches_the_reference_and_learns() {
    let mut link = Loopback {
        session: Session::new(learner()),
        reader: FrameReader::new(),
        outbox: VecDeque::new(),
    };
    let learning = 25;
    let mode = |e: u16| match e {
        0 => Mode::Nominal,
        e if e <= learning => Mode::Learn,
        _ => Mode::Deploy,
    };
    let config = RunConfig {
        episodes: learning + 2,
        ticks: auv::TICKS,
        faults: FaultPlan {
            corrupt_every: 151,
            drop_every: 197,
        },
    };
    let mut run_plant = plant();
    let request = |e| vec![pil_link::mode_code(mode(e))];
    let records = run_episodes(&mut link, &mut run_plant, config, request, |_| {}).unwrap();
    for r in &records {
        let injected: Vec<u16> = r.injected.iter().map(|&(t, _)| t).collect();
        assert_eq!(r.fallback_ticks, injected, "episode {}", r.episode);
        let report = Report::read(&r.report).unwrap();
        assert_eq!(report.mode, Some(mode(r.episode)));
        assert_eq!(report.faulty_ticks, 0);
        // The firmware's f32 survey cost against the host's f64 measure of the same
        // episode: equal to within f32 rounding when every state frame arrived; otherwise
        // the firmware observed only a subset of the ticks, so its minimum distance is no
        // smaller and its time within D no longer: its cost is no lower.
        let (fw, host) = (f64::from(report.cost), r.host_cost);
        let tolerance = 1e-4 * host.abs().max(1.0);
        if r.fallback_ticks.is_empty() {
            assert!((fw - host).abs() <= tolerance, "episode {}", r.episode);
        } else {
            assert!(fw >= host - tolerance, "episode {}", r.episode);
        }
    }
    assert!(records.iter().map(|r| r.injected.len()).sum::<usize>() > 50);
    let mut replay_plant = plant();
    let reference = reference_run(learner(), &mut replay_plant, auv::TICKS, &records);
    assert_eq!(reference.len(), records.len());
    // Bit for bit (the reports hold NaN where nothing was told).
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (r, q) in records.iter().zip(&reference) {
        assert_eq!(
            (bits(&r.theta), r.host_cost.to_bits(), bits(&r.report)),
            (bits(&q.theta), q.host_cost.to_bits(), bits(&q.report))
        );
    }
    let bare = records[0].host_cost;
    assert_eq!(records[1].theta, vec![0.0; auv::P]);
    // Not bit-equal: the faults fall on other ticks of the two episodes, and a fallback
    // tick runs the PD on the state one tick old; a few such ticks move d by far less than
    // a millimetre.
    assert!((records[1].host_cost - bare).abs() < 1e-3);
    let deployed = records.last().unwrap();
    assert!(
        deployed.host_cost < bare,
        "bare {bare}, deployed {}",
        deployed.host_cost
    );
}

/// Checks: the host's survey measure of the plant is the documented cost: the minimum
/// distance over the states the commands are computed from, here with the vehicle at rest
/// at the start (7.21 m from the target) under a zero command.
#[test]
fn auv_plant_scores_the_survey() {
    let mut p = plant();
    p.reset(0);
    let state = p.observe();
    assert_eq!(state.len(), 6);
    assert_eq!(&state[..3], &[-5.0, -2.0, 4.8]);
    p.step(&[0.0, 0.0, 0.0]);
    let start = (25.0f64 + 4.0 + 4.8 * 4.8).sqrt();
    assert!((p.cost() - start).abs() < 1e-12);
}
