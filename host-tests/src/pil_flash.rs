//! The persistent PIL run: a flash on the host behind a link, and QEMU killed and restarted.
//!
//! * [`FlashImage`]: the bytes of the firmware's NOR flash (4-byte words, 2 KiB pages, the
//!   layout of [`auv_survey::checkpoint`]), kept in a file that every program and erase
//!   writes through to. [`ImageFlash`] is the same flash for a host-side
//!   [`CheckpointStore`](ctrl_adapt::checkpoint::CheckpointStore) (the hand-over image, the
//!   final checkpoints).
//! * [`FlashServer`]: serves the `pil_persist` firmware's flash requests (two named pipes
//!   in QEMU's working directory, see the firmware's `host_flash` module) from a
//!   [`FlashImage`], one request at a time, and can tear the n-th program or erase
//!   ([`Shared::cut_at`]): it applies half of it and answers nothing more, the firmware
//!   waits, and the harness kills QEMU: a power cut in the middle of a flash write.
//! * [`run_persistent`]: the episodes of a PIL run against that firmware, with QEMU killed
//!   (SIGKILL) at [`KillPoint`]s and restarted; after each boot it asks the firmware where it
//!   stands (Hello → Resume) and goes on from there.

use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::unix::fs::{FileExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use auv_survey::checkpoint::{FLASH_SIZE, PAGE};
use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use pil_link::frame::FALLBACK;
use pil_link::{Frame, Kind};

use crate::pil::{EpisodeRecord, Fault, Link, PilPlant, Qemu, RunConfig, SocketLink};

/// The flash's write unit.
pub const WORD: usize = 4;
/// The pipes' names in QEMU's working directory (firmware → host, host → firmware).
pub const PIPES: [&str; 2] = ["flash-req", "flash-resp"];

/// The flash's bytes, kept in a file (see the [module docs](self)).
#[derive(Debug)]
pub struct FlashImage {
    bytes: Vec<u8>,
    file: File,
    /// Programs applied (torn ones included).
    pub programs: u64,
    /// Erases applied (torn ones included).
    pub erases: u64,
    /// Bytes programmed.
    pub programmed_bytes: u64,
}

impl FlashImage {
    /// A flash of [`FLASH_SIZE`] bytes in the file `path`: erased, or `initial`.
    pub fn create(path: &Path, initial: Option<&[u8]>) -> io::Result<Self> {
        let bytes = match initial {
            Some(b) if b.len() == FLASH_SIZE as usize => b.to_vec(),
            Some(_) => return Err(io::Error::other("flash image of the wrong size")),
            None => vec![0xFF; FLASH_SIZE as usize],
        };
        let file = OpenOptions::new()
            .create(true)
            .truncate(true)
            .read(true)
            .write(true)
            .open(path)?;
        file.write_all_at(&bytes, 0)?;
        Ok(Self {
            bytes,
            file,
            programs: 0,
            erases: 0,
            programmed_bytes: 0,
        })
    }

    /// The flash's bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Programs and erases so far.
    pub fn ops(&self) -> u64 {
        self.programs + self.erases
    }

    fn range(&self, offset: u32, len: u32, align: u32) -> Option<std::ops::Range<usize>> {
        let end = offset.checked_add(len)?;
        (end <= FLASH_SIZE && offset.is_multiple_of(align) && len.is_multiple_of(align))
            .then_some(offset as usize..end as usize)
    }

    fn read(&self, offset: u32, len: u32) -> Option<&[u8]> {
        self.range(offset, len, 1).map(|r| &self.bytes[r])
    }

    /// Programs `data` at `offset` as NOR flash does (bits only go from 1 to 0); with
    /// `torn`, only the first half of the words and half of the next one (a power cut).
    fn program(&mut self, offset: u32, data: &[u8], torn: bool) -> io::Result<bool> {
        let Some(range) = self.range(offset, data.len() as u32, WORD as u32) else {
            return Ok(false);
        };
        let applied = if torn {
            (data.len() / WORD / 2) * WORD + WORD / 2
        } else {
            data.len()
        }
        .min(data.len());
        let target = &mut self.bytes[range.start..range.start + applied];
        for (t, d) in target.iter_mut().zip(data) {
            *t &= d;
        }
        self.file.write_all_at(target, u64::from(offset))?;
        self.programs += 1;
        self.programmed_bytes += applied as u64;
        Ok(true)
    }

    /// Erases the pages `from..to`; with `torn`, only the first half of the range.
    fn erase(&mut self, from: u32, to: u32, torn: bool) -> io::Result<bool> {
        let Some(range) = to
            .checked_sub(from)
            .and_then(|len| self.range(from, len, PAGE))
        else {
            return Ok(false);
        };
        let end = if torn {
            range.start + range.len() / 2
        } else {
            range.end
        };
        self.bytes[range.start..end].fill(0xFF);
        self.file
            .write_all_at(&self.bytes[range.start..end], u64::from(from))?;
        self.erases += 1;
        Ok(true)
    }
}

/// A [`FlashImage`] as an `embedded-storage-async` NOR flash, for a host-side
/// `CheckpointStore`.
pub struct ImageFlash<'a>(pub &'a mut FlashImage);

/// The host flash refused an operation (out of range or misaligned) or its file failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageError;

impl NorFlashError for ImageError {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::Other
    }
}

impl ErrorType for ImageFlash<'_> {
    type Error = ImageError;
}

impl ReadNorFlash for ImageFlash<'_> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), ImageError> {
        let from = self.0.read(offset, bytes.len() as u32).ok_or(ImageError)?;
        bytes.copy_from_slice(from);
        Ok(())
    }

    fn capacity(&self) -> usize {
        FLASH_SIZE as usize
    }
}

impl NorFlash for ImageFlash<'_> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), ImageError> {
        match self.0.erase(from, to, false) {
            Ok(true) => Ok(()),
            _ => Err(ImageError),
        }
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), ImageError> {
        match self.0.program(offset, bytes, false) {
            Ok(true) => Ok(()),
            _ => Err(ImageError),
        }
    }
}

/// What the flash server and the harness share.
#[derive(Debug)]
pub struct Shared {
    /// The flash.
    pub image: FlashImage,
    /// Tear the program or erase that finds [`FlashImage::ops`] equal to this, then stop.
    pub cut_at: Option<u64>,
    /// Tear the next erase, whenever it comes.
    pub cut_erase: bool,
    /// The operation torn last: `b'W'` (a program) or `b'E'` (an erase).
    pub torn: Option<u8>,
}

/// Locks `shared`, poisoned or not (a panicking server thread leaves the image consistent:
/// every change is applied before anything can panic).
pub fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    shared
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Creates the two named pipes in `dir` (with `mkfifo`).
pub fn make_pipes(dir: &Path) -> io::Result<()> {
    for name in PIPES {
        let path = dir.join(name);
        let _ = std::fs::remove_file(&path);
        let status = std::process::Command::new("mkfifo").arg(&path).status()?;
        if !status.success() {
            return Err(io::Error::other(format!(
                "mkfifo {}: {status}",
                path.display()
            )));
        }
    }
    Ok(())
}

/// `O_NONBLOCK` (Linux): opening a pipe's end without waiting for the other.
const O_NONBLOCK: i32 = 0o4000;

/// The thread that serves one boot's flash requests.
pub struct FlashServer {
    thread: Option<JoinHandle<io::Result<()>>>,
    dir: PathBuf,
    /// Set by the server when it has torn an operation and stopped answering.
    pub cut: Arc<AtomicBool>,
    release: Arc<AtomicBool>,
}

impl FlashServer {
    /// Serves the pipes in `dir` from `shared` until the firmware closes them (QEMU exits
    /// or is killed) or a cut.
    pub fn spawn(dir: &Path, shared: Arc<Mutex<Shared>>) -> Self {
        let cut = Arc::new(AtomicBool::new(false));
        let release = Arc::new(AtomicBool::new(false));
        let thread = {
            let (dir, cut, release) = (dir.to_path_buf(), cut.clone(), release.clone());
            std::thread::spawn(move || serve(&dir, &shared, &cut, &release))
        };
        Self {
            thread: Some(thread),
            dir: dir.to_path_buf(),
            cut,
            release,
        }
    }

    /// After QEMU has ended: lets the server go and waits for it. Its error, if any.
    pub fn finish(mut self) -> io::Result<()> {
        self.release.store(true, Ordering::SeqCst);
        let Some(thread) = self.thread.take() else {
            return Ok(());
        };
        // A server still waiting to open a pipe (the firmware never opened it) is let through
        // by opening the other ends here, without waiting.
        let deadline = Instant::now() + Duration::from_secs(5);
        while !thread.is_finished() && Instant::now() < deadline {
            let _w = OpenOptions::new()
                .write(true)
                .custom_flags(O_NONBLOCK)
                .open(self.dir.join(PIPES[0]));
            let _r = OpenOptions::new()
                .read(true)
                .custom_flags(O_NONBLOCK)
                .open(self.dir.join(PIPES[1]));
            std::thread::sleep(Duration::from_millis(5));
        }
        if !thread.is_finished() {
            return Err(io::Error::other("the flash server did not stop"));
        }
        thread
            .join()
            .map_err(|_| io::Error::other("the flash server panicked"))?
    }
}

fn serve(
    dir: &Path,
    shared: &Mutex<Shared>,
    cut: &AtomicBool,
    release: &AtomicBool,
) -> io::Result<()> {
    let mut requests = File::open(dir.join(PIPES[0]))?;
    let mut answers = OpenOptions::new().write(true).open(dir.join(PIPES[1]))?;
    loop {
        let mut header = [0u8; 9];
        match requests.read_exact(&mut header) {
            Ok(()) => {}
            // The firmware's end closed: QEMU exited or was killed.
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(e),
        }
        if release.load(Ordering::SeqCst) {
            return Ok(());
        }
        let a = u32::from_le_bytes([header[1], header[2], header[3], header[4]]);
        let b = u32::from_le_bytes([header[5], header[6], header[7], header[8]]);
        let answer = match header[0] {
            b'R' => {
                let s = lock(shared);
                let Some(bytes) = s.image.read(a, b) else {
                    return Err(io::Error::other(format!(
                        "flash read out of range: {a}+{b}"
                    )));
                };
                let bytes = bytes.to_vec();
                drop(s);
                answers.write_all(&bytes)?;
                continue;
            }
            op @ (b'W' | b'E') => {
                let mut data = Vec::new();
                if op == b'W' {
                    if b > FLASH_SIZE {
                        return Err(io::Error::other(format!("flash write too long: {b} B")));
                    }
                    data = vec![0u8; b as usize];
                    requests.read_exact(&mut data)?;
                }
                let mut s = lock(shared);
                let torn = s.cut_at == Some(s.image.ops()) || (op == b'E' && s.cut_erase);
                if torn {
                    s.torn = Some(op);
                }
                let done = if op == b'W' {
                    s.image.program(a, &data, torn)?
                } else {
                    s.image.erase(a, b, torn)?
                };
                drop(s);
                if torn {
                    // Power is gone: no answer; the harness kills QEMU.
                    cut.store(true, Ordering::SeqCst);
                    while !release.load(Ordering::SeqCst) {
                        std::thread::sleep(Duration::from_millis(1));
                    }
                    return Ok(());
                }
                u8::from(!done)
            }
            other => return Err(io::Error::other(format!("unknown flash request {other}"))),
        };
        answers.write_all(&[answer])?;
    }
}

/// Where QEMU is killed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KillPoint {
    /// After the firmware answered tick `tick` of `episode`.
    MidEpisode {
        /// The episode.
        episode: u16,
        /// The tick.
        tick: u16,
    },
    /// At the `op`-th flash program or erase (from 1) of the save that ends `episode`: that
    /// operation is torn. If the save has fewer, QEMU is killed after its Report.
    MidSave {
        /// The episode whose save is cut.
        episode: u16,
        /// The operation torn.
        op: u64,
    },
    /// Just after the save that ends `episode` (its Report received).
    AfterSave {
        /// The episode.
        episode: u16,
    },
    /// At the first page erase of the saves from the one that ends `episode` on (the
    /// erase is torn: half of the page's bytes erased).
    NextErase {
        /// The first episode whose save may be cut.
        episode: u16,
    },
}

impl KillPoint {
    /// The episode it interrupts.
    pub fn episode(&self) -> u16 {
        match *self {
            Self::MidEpisode { episode, .. }
            | Self::MidSave { episode, .. }
            | Self::AfterSave { episode }
            | Self::NextErase { episode } => episode,
        }
    }
}

/// What a kill did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KillOutcome {
    /// Where.
    pub point: KillPoint,
    /// Whether a flash operation was torn (a [`KillPoint::MidSave`] within the save).
    pub torn: bool,
    /// Whether that operation was an erase (else a program).
    pub torn_erase: bool,
    /// Flash programs and erases of that save before the torn one (or in all, if none).
    pub ops_done: u64,
    /// The episode the restarted firmware said it would go on from.
    pub resumed_at: u16,
    /// The episode the harness expected it to go on from.
    pub expected: u16,
}

/// A persistent PIL run.
#[derive(Debug, Clone)]
pub struct PersistentRun {
    /// The last run of every episode (an interrupted one is run again).
    pub records: Vec<EpisodeRecord>,
    /// QEMU starts.
    pub boots: u32,
    /// The kills, in order.
    pub kills: Vec<KillOutcome>,
    /// Flash programs and erases of the save at the end of each episode (its last run).
    pub save_ops: Vec<u64>,
    /// Episodes started, reruns included.
    pub episodes_run: u32,
}

/// How long the host waits for any answer before it repeats a control frame or gives up.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(5);

/// Sends `frame` and returns the first answer of `kind` for the same episode (and tick, for
/// actions), or `None` once the flash server has cut the power.
fn exchange(
    link: &mut SocketLink,
    frame: &Frame,
    fault: Option<Fault>,
    kind: Kind,
    cut: &AtomicBool,
) -> io::Result<Option<Frame>> {
    let attempts = if frame.kind == Kind::State { 1 } else { 3 };
    for _ in 0..attempts {
        link.send(frame, fault)?;
        let deadline = Instant::now() + ANSWER_TIMEOUT;
        loop {
            if cut.load(Ordering::SeqCst) {
                return Ok(None);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            if let Some(answer) = link.receive(left.min(Duration::from_millis(20)))? {
                let same_tick = kind != Kind::Action || answer.tick == frame.tick;
                let same_episode = kind == Kind::Resume || answer.episode == frame.episode;
                if answer.kind == kind && same_episode && same_tick {
                    return Ok(Some(answer));
                }
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

fn lost_power() -> io::Error {
    io::Error::other("the flash server cut the power outside a save")
}

/// Runs `config.episodes` episodes of `plant` against the `pil_persist` firmware `elf`, its
/// flash `shared` served from `dir` (which holds the pipes), QEMU killed at `kills` and
/// restarted; faults are placed by (episode, tick), so a rerun episode gets the same ones.
/// `on_episode` sees each episode's record as its Report arrives.
#[allow(clippy::too_many_arguments)]
pub fn run_persistent(
    elf: &Path,
    log: &Path,
    dir: &Path,
    shared: &Arc<Mutex<Shared>>,
    plant: &mut impl PilPlant,
    config: RunConfig,
    request: impl Fn(u16) -> Vec<f32>,
    kills: &[KillPoint],
    mut on_episode: impl FnMut(&EpisodeRecord),
) -> io::Result<PersistentRun> {
    let episodes = usize::from(config.episodes);
    let mut records: Vec<Option<EpisodeRecord>> = vec![None; episodes];
    let mut save_ops = vec![0u64; episodes];
    let mut pending: VecDeque<KillPoint> = {
        let mut k = kills.to_vec();
        k.sort_by_key(|k| (k.episode(), !matches!(k, KillPoint::MidEpisode { .. })));
        k.into()
    };
    let mut outcomes: Vec<KillOutcome> = Vec::new();
    let mut boots = 0;
    let mut episodes_run = 0;
    std::fs::File::create(log)?;
    'boot: loop {
        boots += 1;
        let (mut qemu, mut link) = Qemu::start_in(elf, log, Some(dir))?;
        let server = FlashServer::spawn(dir, shared.clone());
        let hello = exchange(
            &mut link,
            &Frame::new(Kind::Hello, 0, 0),
            None,
            Kind::Resume,
            &server.cut,
        )?
        .ok_or_else(lost_power)?;
        let next = hello.episode;
        if let Some(last) = outcomes.last_mut() {
            last.resumed_at = next;
            if next != last.expected {
                qemu.kill();
                server.finish()?;
                return Err(io::Error::other(format!(
                    "after the kill at {:?} the firmware resumed at episode {next}, expected {}",
                    last.point, last.expected
                )));
            }
        } else if next != 0 && boots == 1 && records.iter().all(Option::is_none) {
            // A hand-over checkpoint says episode 0; anything else is a stale flash.
            qemu.kill();
            server.finish()?;
            return Err(io::Error::other(format!(
                "the flash's checkpoint starts at episode {next}, not 0"
            )));
        }
        for episode in next..config.episodes {
            let request = request(episode);
            episodes_run += 1;
            let started = exchange(
                &mut link,
                &Frame::new(Kind::Start, episode, config.ticks).with_values(&request),
                None,
                Kind::Started,
                &server.cut,
            )?
            .ok_or_else(lost_power)?;
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
                let fault = config
                    .faults
                    .fault(u64::from(episode) * u64::from(config.ticks) + u64::from(tick));
                if let Some(f) = fault {
                    record.injected.push((tick, f));
                }
                let action = exchange(&mut link, &state, fault, Kind::Action, &server.cut)?
                    .ok_or_else(lost_power)?;
                if action.flags & FALLBACK != 0 {
                    record.fallback_ticks.push(tick);
                }
                plant.step(&action.values);
                if pending.front() == Some(&KillPoint::MidEpisode { episode, tick }) {
                    qemu.kill();
                    server.finish()?;
                    outcomes.push(KillOutcome {
                        point: pending.pop_front().expect("front checked"),
                        torn: false,
                        torn_erase: false,
                        ops_done: 0,
                        resumed_at: u16::MAX,
                        expected: episode,
                    });
                    continue 'boot;
                }
            }
            record.host_cost = plant.cost();
            let ops_before = lock(shared).image.ops();
            let cut_op = match pending.front() {
                Some(&KillPoint::MidSave { episode: e, op }) if e == episode => Some(op.max(1)),
                Some(&KillPoint::AfterSave { episode: e }) if e == episode => Some(u64::MAX),
                _ => None,
            };
            let cut_erase = matches!(
                pending.front(),
                Some(&KillPoint::NextErase { episode: e }) if e <= episode
            );
            lock(shared).cut_at = cut_op.map(|op| ops_before.saturating_add(op - 1));
            lock(shared).cut_erase = cut_erase;
            let report = exchange(
                &mut link,
                &Frame::new(Kind::End, episode, 0),
                None,
                Kind::Report,
                &server.cut,
            )?;
            let ops_done = lock(shared).image.ops() - ops_before;
            lock(shared).cut_at = None;
            lock(shared).cut_erase = false;
            let Some(report) = report else {
                // Torn: the save is lost, the firmware goes on from this episode.
                qemu.kill();
                server.finish()?;
                let torn_erase = lock(shared).torn.take() == Some(b'E');
                outcomes.push(KillOutcome {
                    point: pending.pop_front().expect("a cut is armed only for a kill"),
                    torn: true,
                    torn_erase,
                    ops_done: ops_done.saturating_sub(1),
                    resumed_at: u16::MAX,
                    expected: episode,
                });
                continue 'boot;
            };
            record.report = report.values.to_vec();
            save_ops[usize::from(episode)] = ops_done;
            on_episode(&record);
            records[usize::from(episode)] = Some(record);
            if cut_op.is_some() {
                // The save had fewer operations: killed after it, the Report received.
                qemu.kill();
                server.finish()?;
                outcomes.push(KillOutcome {
                    point: pending.pop_front().expect("a cut is armed only for a kill"),
                    torn: false,
                    torn_erase: false,
                    ops_done,
                    resumed_at: u16::MAX,
                    expected: episode + 1,
                });
                continue 'boot;
            }
        }
        exchange(
            &mut link,
            &Frame::new(Kind::Shutdown, 0, 0),
            None,
            Kind::Bye,
            &server.cut,
        )?
        .ok_or_else(lost_power)?;
        let status = qemu.wait(Duration::from_secs(10))?;
        server.finish()?;
        if !status.success() {
            return Err(io::Error::other(format!(
                "the firmware exited with {status}"
            )));
        }
        break;
    }
    if let Some(k) = pending.front() {
        return Err(io::Error::other(format!("kill point {k:?} never reached")));
    }
    let records = records
        .into_iter()
        .enumerate()
        .map(|(e, r)| r.ok_or_else(|| io::Error::other(format!("episode {e} never reported"))))
        .collect::<io::Result<Vec<_>>>()?;
    Ok(PersistentRun {
        records,
        boots,
        kills: outcomes,
        save_ops,
        episodes_run,
    })
}
