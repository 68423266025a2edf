//! The firmware side of the PIL protocol (see the [crate docs](crate)).
//!
//! [`Session`] turns received frames (or a passed deadline) into answers and calls the
//! [`Learner`] at the right moments. It has no clock and no port: the firmware's loop
//! reads a frame with a deadline ([`crate::read_frame`]) and hands the outcome to
//! [`Session::on_frame`], [`Session::on_corrupt`] or [`Session::on_timeout`]. The host's
//! pure-host reference run drives the very same `Session` without a link, so the two runs
//! differ only in where the arithmetic is done.

use crate::frame::{FALLBACK, Frame, Kind, Values};

/// What runs on the microcontroller behind the session: the policy, the cost and the
/// optimizer, usually the library's `Adapter` (the AUV survey application's `AuvLearner`
/// implements it).
pub trait Learner {
    /// Episode `episode` starts: choose its parameters (the optimizer's `ask`) and write the
    /// ones to report to the host into `theta`. `request` holds the Start frame's values
    /// (what the host asks of the episode; the AUV learner reads a mode there, see
    /// [`crate::mode_code`]).
    fn start_episode(&mut self, episode: u16, request: &[f32], theta: &mut Values);

    /// The action for a valid state received for the current tick, into `action`; also
    /// accumulates the episode's cost.
    fn act(&mut self, state: &[f32], action: &mut Values);

    /// The nominal action for a tick without a valid state (corrupted or missing frame):
    /// `last_state` is the last valid state of this episode, if any.
    fn fallback(&mut self, last_state: Option<&[f32]>, action: &mut Values);

    /// The episode is over: report its cost to the optimizer (`tell`) and write what the host
    /// should log into `report`.
    fn end_episode(&mut self, report: &mut Values);

    /// The next episode this learner expects, for the answer to a Hello: 0 unless it resumed
    /// from a checkpoint (then one past the last episode whose end it saved).
    fn next_episode(&self) -> u16 {
        0
    }
}

/// A learner borrowed for the session: firmware builds its learner once, in place, and lends it,
/// so the session holds a pointer instead of a second copy of the learner's state on the stack.
impl<L: Learner + ?Sized> Learner for &mut L {
    fn start_episode(&mut self, episode: u16, request: &[f32], theta: &mut Values) {
        (**self).start_episode(episode, request, theta)
    }

    fn act(&mut self, state: &[f32], action: &mut Values) {
        (**self).act(state, action)
    }

    fn fallback(&mut self, last_state: Option<&[f32]>, action: &mut Values) {
        (**self).fallback(last_state, action)
    }

    fn end_episode(&mut self, report: &mut Values) {
        (**self).end_episode(report)
    }

    fn next_episode(&self) -> u16 {
        (**self).next_episode()
    }
}

/// Counters of link events since the session began.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// Frames rejected by the codec (CRC, COBS, length).
    pub corrupt: u32,
    /// Ticks answered with the nominal fallback because the deadline passed.
    pub fallbacks: u32,
    /// Valid frames ignored: an old tick, another episode, or a kind the firmware never
    /// receives.
    pub ignored: u32,
}

#[derive(Debug, Clone, PartialEq)]
enum Phase {
    /// Between episodes; keeps the last report to answer a repeated End.
    Idle {
        last_report: Option<Frame>,
    },
    Running {
        started: Frame,
        ticks: u16,
        next_tick: u16,
        last_state: Option<Values>,
        fallbacks: u16,
    },
    Finished,
}

/// The protocol state machine around a [`Learner`].
#[derive(Debug, Clone)]
pub struct Session<C> {
    controller: C,
    phase: Phase,
    stats: Stats,
}

impl<C: Learner> Session<C> {
    /// A session waiting for the first Start.
    pub const fn new(controller: C) -> Self {
        Self {
            controller,
            phase: Phase::Idle { last_report: None },
            stats: Stats {
                corrupt: 0,
                fallbacks: 0,
                ignored: 0,
            },
        }
    }

    /// The controller.
    pub fn controller(&self) -> &C {
        &self.controller
    }

    /// Link counters.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// Whether a tick is due: an episode is running and has ticks left. Only then does a
    /// deadline apply (between episodes the firmware waits for the host indefinitely).
    pub fn awaiting_tick(&self) -> bool {
        matches!(self.phase, Phase::Running { ticks, next_tick, .. } if next_tick < ticks)
    }

    /// Whether the host has said Shutdown.
    pub fn finished(&self) -> bool {
        self.phase == Phase::Finished
    }

    /// A corrupted frame arrived; it is counted and otherwise ignored (the tick's deadline
    /// still decides when the fallback happens).
    pub fn on_corrupt(&mut self) {
        self.stats.corrupt = self.stats.corrupt.saturating_add(1);
    }

    /// The tick's deadline passed without a valid state: the fallback action, if a tick is
    /// due.
    pub fn on_timeout(&mut self) -> Option<Frame> {
        let Phase::Running {
            started,
            ticks,
            next_tick,
            last_state,
            fallbacks,
        } = &mut self.phase
        else {
            return None;
        };
        if *next_tick >= *ticks {
            return None;
        }
        let mut reply = Frame::new(Kind::Action, started.episode, *next_tick);
        reply.flags = FALLBACK;
        self.controller
            .fallback(last_state.as_deref(), &mut reply.values);
        *next_tick += 1;
        *fallbacks = fallbacks.saturating_add(1);
        self.stats.fallbacks = self.stats.fallbacks.saturating_add(1);
        Some(reply)
    }

    /// A valid frame arrived: the answer to send, if any.
    pub fn on_frame(&mut self, frame: &Frame) -> Option<Frame> {
        let reply = match (frame.kind, &mut self.phase) {
            (Kind::Shutdown, _) => {
                self.phase = Phase::Finished;
                Some(Frame::new(Kind::Bye, frame.episode, 0))
            }
            (_, Phase::Finished) => None,
            // Where the learner stands (a firmware that resumed from flash says so); answered
            // in any phase, and changes nothing.
            (Kind::Hello, _) => Some(Frame::new(Kind::Resume, self.controller.next_episode(), 0)),
            // A repeated Start (its Started was lost): the same answer, no new ask.
            (Kind::Start, Phase::Running { started, .. }) if started.episode == frame.episode => {
                Some(started.clone())
            }
            // A Start while idle, or for another episode (the host gave the running one up:
            // its candidate stays pending in the optimizer and is handed out again).
            (Kind::Start, _) => {
                let mut started = Frame::new(Kind::Started, frame.episode, frame.tick);
                self.controller
                    .start_episode(frame.episode, &frame.values, &mut started.values);
                self.phase = Phase::Running {
                    started: started.clone(),
                    ticks: frame.tick,
                    next_tick: 0,
                    last_state: None,
                    fallbacks: 0,
                };
                Some(started)
            }
            (
                Kind::State,
                Phase::Running {
                    started,
                    ticks,
                    next_tick,
                    last_state,
                    ..
                },
            ) if started.episode == frame.episode
                && frame.tick >= *next_tick
                && frame.tick < *ticks =>
            {
                let mut action = Frame::new(Kind::Action, frame.episode, frame.tick);
                self.controller.act(&frame.values, &mut action.values);
                *next_tick = frame.tick.saturating_add(1);
                *last_state = Some(frame.values.clone());
                Some(action)
            }
            (
                Kind::End,
                Phase::Running {
                    started, fallbacks, ..
                },
            ) if started.episode == frame.episode => {
                let mut report = Frame::new(Kind::Report, frame.episode, *fallbacks);
                self.controller.end_episode(&mut report.values);
                self.phase = Phase::Idle {
                    last_report: Some(report.clone()),
                };
                Some(report)
            }
            // A repeated End (its Report was lost): the same report, no second tell.
            (
                Kind::End,
                Phase::Idle {
                    last_report: Some(report),
                },
            ) if report.episode == frame.episode => Some(report.clone()),
            _ => None,
        };
        if reply.is_none() {
            self.stats.ignored = self.stats.ignored.saturating_add(1);
        }
        reply
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records the calls; its action is the state's first value negated (fallback: 99).
    #[derive(Default, Debug, Clone)]
    struct Probe {
        starts: u32,
        acts: u32,
        fallbacks: Vec<Option<f32>>,
        ends: u32,
    }

    impl Learner for Probe {
        fn start_episode(&mut self, _: u16, _: &[f32], theta: &mut Values) {
            self.starts += 1;
            theta.push(self.starts as f32).unwrap();
        }
        fn act(&mut self, state: &[f32], action: &mut Values) {
            self.acts += 1;
            action.push(-state[0]).unwrap();
        }
        fn fallback(&mut self, last: Option<&[f32]>, action: &mut Values) {
            self.fallbacks.push(last.map(|s| s[0]));
            action.push(99.0).unwrap();
        }
        fn end_episode(&mut self, report: &mut Values) {
            self.ends += 1;
            report.push(self.acts as f32).unwrap();
        }
    }

    fn state(episode: u16, tick: u16, x: f32) -> Frame {
        Frame::new(Kind::State, episode, tick).with_values(&[x])
    }

    /// Checks one episode with a missing frame: every tick gets exactly one action, the
    /// missing tick gets the fallback (flagged, from the last valid state), the report counts
    /// it, and a stale frame for an old tick is ignored.
    #[test]
    fn episode_with_a_missing_frame() {
        let mut s = Session::new(Probe::default());
        assert!(!s.awaiting_tick());
        assert_eq!(s.on_timeout(), None, "no deadline between episodes");
        let started = s.on_frame(&Frame::new(Kind::Start, 4, 3)).unwrap();
        assert_eq!((started.kind, started.values[0]), (Kind::Started, 1.0));
        let a0 = s.on_frame(&state(4, 0, 2.0)).unwrap();
        assert_eq!(
            (a0.kind, a0.tick, a0.flags, a0.values[0]),
            (Kind::Action, 0, 0, -2.0)
        );
        s.on_corrupt();
        let a1 = s.on_timeout().unwrap();
        assert_eq!((a1.tick, a1.flags, a1.values[0]), (1, FALLBACK, 99.0));
        assert_eq!(s.controller().fallbacks, vec![Some(2.0)]);
        assert_eq!(s.on_frame(&state(4, 1, 5.0)), None, "tick 1 is over");
        let a2 = s.on_frame(&state(4, 2, 3.0)).unwrap();
        assert_eq!((a2.tick, a2.values[0]), (2, -3.0));
        assert!(!s.awaiting_tick(), "all 3 ticks answered");
        assert_eq!(s.on_timeout(), None);
        let report = s.on_frame(&Frame::new(Kind::End, 4, 0)).unwrap();
        assert_eq!(
            (report.kind, report.tick, report.values[0]),
            (Kind::Report, 1, 2.0)
        );
        assert_eq!(
            s.stats(),
            Stats {
                corrupt: 1,
                fallbacks: 1,
                ignored: 1
            }
        );
    }

    /// Checks: repeated Start and End frames get the same answers without a second
    /// `start_episode` or `end_episode` (no extra ask or tell); Shutdown finishes.
    #[test]
    fn control_frames_are_idempotent() {
        let mut s = Session::new(Probe::default());
        let first = s.on_frame(&Frame::new(Kind::Start, 1, 1)).unwrap();
        assert_eq!(s.on_frame(&Frame::new(Kind::Start, 1, 1)), Some(first));
        s.on_frame(&state(1, 0, 1.0)).unwrap();
        let report = s.on_frame(&Frame::new(Kind::End, 1, 0)).unwrap();
        assert_eq!(s.on_frame(&Frame::new(Kind::End, 1, 0)), Some(report));
        assert_eq!((s.controller().starts, s.controller().ends), (1, 1));
        assert_eq!(s.on_frame(&Frame::new(Kind::End, 2, 0)), None);
        let resume = s.on_frame(&Frame::new(Kind::Hello, 0, 0)).unwrap();
        assert_eq!((resume.kind, resume.episode), (Kind::Resume, 0));
        assert_eq!((s.controller().starts, s.controller().ends), (1, 1));
        let bye = s.on_frame(&Frame::new(Kind::Shutdown, 0, 0)).unwrap();
        assert_eq!(bye.kind, Kind::Bye);
        assert!(s.finished());
        assert_eq!(s.on_frame(&Frame::new(Kind::Start, 2, 1)), None);
    }

    /// Checks: a fallback at the first tick of an episode has no last state, and a state
    /// from another episode is ignored.
    #[test]
    fn first_tick_fallback_and_foreign_episode() {
        let mut s = Session::new(Probe::default());
        s.on_frame(&Frame::new(Kind::Start, 2, 2)).unwrap();
        assert_eq!(s.on_frame(&state(1, 0, 1.0)), None);
        let a0 = s.on_timeout().unwrap();
        assert_eq!((a0.tick, a0.flags), (0, FALLBACK));
        assert_eq!(s.controller().fallbacks, vec![None]);
    }
}
