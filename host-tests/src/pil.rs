//! Processor-in-the-loop harness: the plant runs here, the controller and the learner run in
//! the firmware on QEMU's emulated Cortex-M4F, one state frame and one action frame per
//! control tick over the emulated UART (QEMU `-serial unix:`; [`pil_link`] frames).
//!
//! * [`PilPlant`] is what a plant provides; [`AuvPlant`] is the AUV survey.
//! * [`Qemu`] starts the firmware and connects its UART0 to a Unix socket ([`Link`]).
//! * [`run_episodes`] drives N episodes over any [`Link`], injecting the [`FaultPlan`]'s
//!   corrupted and dropped state frames, and records what happened in each episode.
//! * [`reference_run`] replays the same episodes with the firmware's own [`Session`] and
//!   controller code running on the host, with the ticks the firmware answered with the
//!   fallback replayed as timeouts: the two runs then differ only in where the `f32`
//!   arithmetic is done.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use pil_link::frame::FALLBACK;
use pil_link::{Frame, FrameReader, Kind, Learner, MAX_WIRE, Session};

use crate::auv::{Auv, AuvConfig};

/// A plant simulated on the host for a PIL run.
pub trait PilPlant {
    /// Puts the plant in its initial state for `episode`.
    fn reset(&mut self, episode: u16);
    /// The sensor state sent to the firmware this tick.
    fn observe(&self) -> Vec<f32>;
    /// Applies the firmware's action for one control period.
    fn step(&mut self, action: &[f32]);
    /// The host's own measure of the episode so far (lower is better), from the plant's
    /// true state in f64, independent of the firmware's.
    fn cost(&self) -> f64;
}

/// The AUV survey plant ([`Auv`]) for a PIL run: the firmware sees the policy's state
/// `[target − p, v]` from [`Auv::measurement`] in `f32` and answers the velocity command.
/// The host scores the episode with the survey cost of Leonetti et al. (section 5) from the
/// *true* positions in f64: d if d ≥ D, D − t_D if d < D (d the minimum distance to the
/// target, t_D the time within D), observed, like the firmware's reward, at the state each
/// command is computed from (t = 0, 0.1, …, 23.9 s).
#[derive(Debug, Clone)]
pub struct AuvPlant {
    auv: Auv,
    min_distance: f64,
    time_within: f64,
}

impl AuvPlant {
    /// A plant over `Auv::new(config, seed)`.
    pub fn new(config: AuvConfig, seed: u64) -> Self {
        Self {
            auv: Auv::new(config, seed),
            min_distance: f64::INFINITY,
            time_within: 0.0,
        }
    }

    /// The vehicle.
    pub fn auv(&self) -> &Auv {
        &self.auv
    }

    /// d, the minimum true distance to the target so far (m).
    pub fn min_distance(&self) -> f64 {
        self.min_distance
    }

    /// t_D, the time spent within D so far (s).
    pub fn time_within(&self) -> f64 {
        self.time_within
    }
}

impl PilPlant for AuvPlant {
    fn reset(&mut self, _episode: u16) {
        self.auv.reset();
        self.min_distance = f64::INFINITY;
        self.time_within = 0.0;
    }

    fn observe(&self) -> Vec<f32> {
        let (m, t) = (self.auv.measurement(), self.auv.target());
        let error = (0..3).map(|i| (t[i] - m.position[i]) as f32);
        error.chain(m.velocity.iter().map(|&v| v as f32)).collect()
    }

    fn step(&mut self, action: &[f32]) {
        let d = self.auv.distance_to_target();
        self.min_distance = self.min_distance.min(d);
        if d < self.auv.config().target_radius {
            self.time_within += self.auv.dt();
        }
        let command = |i: usize| action.get(i).map_or(0.0, |&u| f64::from(u));
        self.auv.step([command(0), command(1), command(2)]);
    }

    fn cost(&self) -> f64 {
        let radius = self.auv.config().target_radius;
        if self.min_distance >= radius {
            self.min_distance
        } else {
            radius - self.time_within
        }
    }
}

/// A fault injected into one state frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// One bit of the frame flipped on the way (the delimiter spared).
    Corrupt,
    /// The frame never sent.
    Drop,
}

/// Which state frames are faulty: global tick g (counted over the whole run) is corrupted
/// when g % corrupt_every == corrupt_every / 3, dropped when g % drop_every == drop_every / 2
/// (0 disables). Deterministic, so a run is reproducible.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultPlan {
    /// Period of corrupted frames (0: none).
    pub corrupt_every: u64,
    /// Period of dropped frames (0: none).
    pub drop_every: u64,
}

impl FaultPlan {
    /// No faults.
    pub const NONE: Self = Self {
        corrupt_every: 0,
        drop_every: 0,
    };

    /// The fault for global tick `g`, if any.
    pub fn fault(&self, g: u64) -> Option<Fault> {
        if self.corrupt_every > 0 && g % self.corrupt_every == self.corrupt_every / 3 {
            Some(Fault::Corrupt)
        } else if self.drop_every > 0 && g % self.drop_every == self.drop_every / 2 {
            Some(Fault::Drop)
        } else {
            None
        }
    }
}

/// A byte link to the firmware that carries frames.
pub trait Link {
    /// Sends `frame`, damaged by `fault` if given.
    fn send(&mut self, frame: &Frame, fault: Option<Fault>) -> io::Result<()>;
    /// The next valid frame, or `None` if none arrives within `timeout`. Corrupted frames
    /// from the firmware are counted and skipped.
    fn receive(&mut self, timeout: Duration) -> io::Result<Option<Frame>>;
}

/// The wire form of `frame`, with one bit flipped for [`Fault::Corrupt`].
pub fn wire(frame: &Frame, fault: Option<Fault>) -> Vec<u8> {
    let mut buf = [0u8; MAX_WIRE];
    let n = frame.encode(&mut buf);
    let mut bytes = buf[..n].to_vec();
    if fault == Some(Fault::Corrupt) {
        // A bit in the middle of the body; never the delimiter at the end.
        let i = (n - 1) / 2;
        bytes[i] ^= 0x08;
    }
    bytes
}

/// A [`Link`] over a Unix socket connected to QEMU's `-serial unix:` backend.
pub struct SocketLink {
    stream: UnixStream,
    reader: FrameReader,
    ready: VecDeque<Frame>,
    /// Frames from the firmware that failed to decode (expected: 0).
    pub corrupt_received: u32,
}

impl SocketLink {
    /// Wraps a connected stream.
    pub fn new(stream: UnixStream) -> Self {
        Self {
            stream,
            reader: FrameReader::new(),
            ready: VecDeque::new(),
            corrupt_received: 0,
        }
    }
}

impl Link for SocketLink {
    fn send(&mut self, frame: &Frame, fault: Option<Fault>) -> io::Result<()> {
        if fault == Some(Fault::Drop) {
            return Ok(());
        }
        self.stream.write_all(&wire(frame, fault))
    }

    fn receive(&mut self, timeout: Duration) -> io::Result<Option<Frame>> {
        let deadline = Instant::now() + timeout;
        let mut buf = [0u8; 256];
        loop {
            if let Some(frame) = self.ready.pop_front() {
                return Ok(Some(frame));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            self.stream.set_read_timeout(Some(left))?;
            let n = match self.stream.read(&mut buf) {
                Ok(0) => return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "UART closed")),
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Ok(None);
                }
                Err(e) => return Err(e),
            };
            for &byte in &buf[..n] {
                match self.reader.push(byte) {
                    Some(Ok(frame)) => self.ready.push_back(frame),
                    Some(Err(_)) => self.corrupt_received += 1,
                    None => {}
                }
            }
        }
    }
}

/// The firmware running in QEMU (mps2-an386), its UART0 on a Unix socket.
pub struct Qemu {
    child: Child,
    decoder: Option<Child>,
    dir: PathBuf,
}

impl Qemu {
    /// Starts `elf` and waits (up to 30 s) for QEMU to connect UART0. The firmware's defmt
    /// log (semihosting stdout) goes through `defmt-print -e elf` into `log` if defmt-print
    /// is installed, raw (undecoded) otherwise.
    pub fn start(elf: &Path, log: &Path) -> io::Result<(Self, SocketLink)> {
        std::fs::File::create(log)?;
        Self::start_in(elf, log, None)
    }

    /// [`Qemu::start`] with QEMU's working directory `cwd` (where the firmware's semihosting
    /// opens files by relative name), if given; the log is appended to `log` (a restarted
    /// firmware's log follows the one before).
    pub fn start_in(elf: &Path, log: &Path, cwd: Option<&Path>) -> io::Result<(Self, SocketLink)> {
        let dir = std::env::temp_dir().join(format!("ctrl-adapt-pil-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let socket = dir.join("uart0.sock");
        let _ = std::fs::remove_file(&socket);
        let listener = UnixListener::bind(&socket)?;
        listener.set_nonblocking(true)?;
        let log_file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(log)?;
        // The firmware's log (semihosting stdout) is decoded by defmt-print into `log`, or
        // written there raw when defmt-print is not installed (QEMU's stdout must never be a
        // closed pipe: the firmware would see its log writes fail).
        let decode = Command::new("defmt-print")
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        let mut qemu = Command::new("qemu-system-arm");
        // The ELF's path must survive the change of working directory.
        let elf = &std::fs::canonicalize(elf)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", elf.display())))?;
        if let Some(cwd) = cwd {
            qemu.current_dir(cwd);
        }
        let mut child = qemu
            .args(["-cpu", "cortex-m4", "-machine", "mps2-an386"])
            .args(["-display", "none", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-serial")
            .arg(format!("unix:{}", socket.display()))
            .arg("-kernel")
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(if decode {
                Stdio::piped()
            } else {
                Stdio::from(log_file.try_clone()?)
            })
            .spawn()
            .map_err(|e| io::Error::new(e.kind(), format!("qemu-system-arm: {e}")))?;
        let decoder = match child.stdout.take() {
            Some(stdout) => Some(
                Command::new("defmt-print")
                    .arg("-e")
                    .arg(elf)
                    .stdin(Stdio::from(stdout))
                    .stdout(log_file.try_clone()?)
                    .stderr(log_file)
                    .spawn()?,
            ),
            None => None,
        };
        let mut qemu = Self {
            child,
            decoder,
            dir,
        };
        let started = Instant::now();
        loop {
            match listener.accept() {
                Ok((stream, _)) => {
                    stream.set_nonblocking(false)?;
                    return Ok((qemu, SocketLink::new(stream)));
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    if let Some(status) = qemu.child.try_wait()? {
                        return Err(io::Error::other(format!("QEMU exited early: {status}")));
                    }
                    if started.elapsed() > Duration::from_secs(30) {
                        qemu.kill();
                        return Err(io::Error::other("QEMU did not connect its UART"));
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// Waits up to `timeout` for QEMU to exit (the firmware exits through semihosting).
    pub fn wait(&mut self, timeout: Duration) -> io::Result<ExitStatus> {
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait()? {
                if let Some(d) = self.decoder.as_mut() {
                    let _ = d.wait();
                }
                return Ok(status);
            }
            if started.elapsed() > timeout {
                self.kill();
                return Err(io::Error::other("QEMU did not exit"));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Kills QEMU at once (SIGKILL): the emulated processor stops at whatever instruction
    /// it was running, as at a power cut.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if let Some(d) = self.decoder.as_mut() {
            let _ = d.wait();
        }
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            self.kill();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// What happened in one episode of a PIL run.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeRecord {
    /// Episode number.
    pub episode: u16,
    /// What the host asked of the episode (the Start frame's values).
    pub request: Vec<f32>,
    /// The parameters the firmware ran (its Started frame).
    pub theta: Vec<f32>,
    /// The host's measure of the episode ([`PilPlant::cost`] at its end).
    pub host_cost: f64,
    /// The firmware's Report values (the AUV learner: [`auv_survey::Report`]).
    pub report: Vec<f32>,
    /// Ticks whose action came back flagged FALLBACK.
    pub fallback_ticks: Vec<u16>,
    /// Ticks whose state frame was damaged or dropped on purpose.
    pub injected: Vec<(u16, Fault)>,
}

/// How a PIL run is laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunConfig {
    /// Episodes to run.
    pub episodes: u16,
    /// Control ticks per episode.
    pub ticks: u16,
    /// Faults to inject into state frames.
    pub faults: FaultPlan,
}

/// How long the host waits for any answer before it repeats a control frame or gives up.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(5);

/// Sends `frame` and returns the first answer of `kind` for the same episode (and, for
/// actions, the same tick); other frames are stale and skipped. Control frames are repeated
/// up to three times (the firmware answers a repeat with the same frame).
fn exchange(
    link: &mut impl Link,
    frame: &Frame,
    fault: Option<Fault>,
    kind: Kind,
) -> io::Result<Frame> {
    let attempts = if frame.kind == Kind::State { 1 } else { 3 };
    for _ in 0..attempts {
        link.send(frame, fault)?;
        let deadline = Instant::now() + ANSWER_TIMEOUT;
        while let Some(answer) = link.receive(deadline.saturating_duration_since(Instant::now()))? {
            let same_tick = kind != Kind::Action || answer.tick == frame.tick;
            if answer.kind == kind && answer.episode == frame.episode && same_tick {
                return Ok(answer);
            }
        }
    }
    Err(io::Error::new(
        io::ErrorKind::TimedOut,
        format!(
            "no {kind:?} answer to {:?} (episode {}, tick {})",
            frame.kind, frame.episode, frame.tick
        ),
    ))
}

/// Runs `config.episodes` episodes of `plant` against the firmware behind `link`, calling
/// `on_episode` after each; then sends Shutdown. `request(episode)` gives the values of each
/// Start frame (what the host asks of the episode).
pub fn run_episodes(
    link: &mut impl Link,
    plant: &mut impl PilPlant,
    config: RunConfig,
    request: impl Fn(u16) -> Vec<f32>,
    mut on_episode: impl FnMut(&EpisodeRecord),
) -> io::Result<Vec<EpisodeRecord>> {
    let mut records = Vec::new();
    let mut global_tick = 0u64;
    for episode in 0..config.episodes {
        let request = request(episode);
        let started = exchange(
            link,
            &Frame::new(Kind::Start, episode, config.ticks).with_values(&request),
            None,
            Kind::Started,
        )?;
        plant.reset(episode);
        let mut record = EpisodeRecord {
            episode,
            request,
            theta: started.values.to_vec(),
            host_cost: 0.0,
            report: Vec::new(),
            fallback_ticks: Vec::new(),
            injected: Vec::new(),
        };
        for tick in 0..config.ticks {
            let state = Frame::new(Kind::State, episode, tick).with_values(&plant.observe());
            let fault = config.faults.fault(global_tick);
            global_tick += 1;
            if let Some(f) = fault {
                record.injected.push((tick, f));
            }
            let action = exchange(link, &state, fault, Kind::Action)?;
            if action.flags & FALLBACK != 0 {
                record.fallback_ticks.push(tick);
            }
            plant.step(&action.values);
        }
        record.host_cost = plant.cost();
        let report = exchange(link, &Frame::new(Kind::End, episode, 0), None, Kind::Report)?;
        record.report = report.values.to_vec();
        on_episode(&record);
        records.push(record);
    }
    exchange(link, &Frame::new(Kind::Shutdown, 0, 0), None, Kind::Bye)?;
    Ok(records)
}

/// One episode of the [`reference_run`].
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceEpisode {
    /// The parameters the controller ran.
    pub theta: Vec<f32>,
    /// The host's measure of the episode.
    pub host_cost: f64,
    /// The controller's report.
    pub report: Vec<f32>,
}

/// Replays a PIL run entirely on the host: the same [`Session`] and `controller` code the
/// firmware runs, fed the plant's states directly, with a timeout wherever the firmware
/// answered with the fallback in `pil` (injected faults and any deadline it missed).
pub fn reference_run<C: Learner>(
    controller: C,
    plant: &mut impl PilPlant,
    ticks: u16,
    pil: &[EpisodeRecord],
) -> Vec<ReferenceEpisode> {
    let mut session = Session::new(controller);
    let mut out = Vec::new();
    for record in pil {
        let episode = record.episode;
        let theta = session
            .on_frame(&Frame::new(Kind::Start, episode, ticks).with_values(&record.request))
            .map_or_else(Vec::new, |f| f.values.to_vec());
        plant.reset(episode);
        for tick in 0..ticks {
            let action = if record.fallback_ticks.contains(&tick) {
                session.on_timeout()
            } else {
                session
                    .on_frame(&Frame::new(Kind::State, episode, tick).with_values(&plant.observe()))
            };
            let values = action.map_or_else(Vec::new, |a| a.values.to_vec());
            plant.step(&values);
        }
        let host_cost = plant.cost();
        let report = session
            .on_frame(&Frame::new(Kind::End, episode, 0))
            .map_or_else(Vec::new, |f| f.values.to_vec());
        out.push(ReferenceEpisode {
            theta,
            host_cost,
            report,
        });
    }
    out
}
