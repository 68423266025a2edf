//! Learning that survives a power cut, in a firmware: an adapter over a controller of your
//! own, saved on NOR flash after every episode, each episode's RNG derived from a device
//! seed so that nothing but the adapter is saved.
#![no_std]
#![forbid(unsafe_code)]

use core::ops::Range;

use ctrl_adapt::checkpoint::{CheckpointError, CheckpointStore};
use ctrl_adapt::controller::{Adapter, AdapterConfig, AdapterError, Controller};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::record::{Persistent, Shape};
use ctrl_adapt::{Bounds, Error, Sracos, SracosConfig, Vector};
use embassy_embedded_hal::adapter::BlockingAsync;
use embedded_storage::nor_flash::NorFlash;
use rand_xoshiro::Xoshiro128PlusPlus;
use serde::{Deserialize, Serialize};

/// A controller of your own: a PD on [error, velocity] plus a learned feed-forward
/// c = clamp(θ₀ + θ₁·error, ±C_MAX). To be saved it derives `Serialize`/`Deserialize`
/// and implements `Persistent`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct FeedForwardPd {
    kp: f32,
    kd: f32,
}

/// The largest learned correction (m/s²).
pub const C_MAX: f32 = 3.0;

impl Controller<2, 2, 1> for FeedForwardPd {
    fn nominal(&mut self, state: &Vector<2>, _time: f32) -> Vector<1> {
        Vector::from([self.kp * state[0] - self.kd * state[1]])
    }

    fn corrected(&mut self, theta: &Vector<2>, state: &Vector<2>, time: f32) -> Vector<1> {
        let c = (theta[0] + theta[1] * state[0]).clamp(-C_MAX, C_MAX);
        self.nominal(state, time) + Vector::from([c])
    }
}

impl Persistent for FeedForwardPd {
    // A four-byte tag of your own, then the type's const-generic sizes (none here). A
    // checkpoint written by a firmware whose controller has another tag or sizes is refused.
    const SHAPE: Shape = Shape::new(*b"FFPD", &[]);

    // Checks a decoded controller as a constructor would check a new one: `load` refuses a
    // record whose gains are not finite (a writer's bug, a forged file).
    fn validate(&self) -> Result<(), Error> {
        if self.kp.is_finite() && self.kd.is_finite() {
            Ok(())
        } else {
            Err(Error::NonFinite("gains"))
        }
    }
}

/// Everything learning needs across a power cut: the adapter (optimizer, controller, cost,
/// counters). No RNG: each episode derives its own from [`DEVICE_SEED`].
pub type Learner = Adapter<Sracos<2>, FeedForwardPd, QuadraticCost<1>, 2, 2, 1>;

/// This device's seed (e.g. from its unique ID); another seed explores other candidates.
pub const DEVICE_SEED: u32 = 0x2C0F_FEE5;

/// Two slots of two 4 KiB pages each (the least a slot can have), at the start of the flash
/// range handed to the store.
pub const SLOTS: [Range<u32>; 2] = [0..0x2000, 0x2000..0x4000];

/// The record buffer: at least the largest record (a `Learner`'s is 273 bytes).
pub const RECORD: usize = 512;

/// The item buffer: the size of one chunk written to flash.
pub const ITEM: usize = 256;

/// The learner, built once when no checkpoint is found.
pub fn fresh_learner() -> Result<Learner, Error> {
    let search = Sracos::try_new(Bounds::uniform(-5.0, 5.0)?, SracosConfig::DEFAULT)?;
    let controller = FeedForwardPd { kp: 4.0, kd: 3.6 };
    let cost = QuadraticCost::try_new(Vector::repeat(1.0))?; // ∫ error² dt
    let config = AdapterConfig {
        dt: 0.02,
        failure_cost: 100.0,
        max_faulty_ticks: 0,
        learning_episodes: 200,
    };
    Adapter::try_new(search, controller, cost, config, Vector::zeros())
}

/// Your robot: its sensors, actuators and timers.
pub trait Robot {
    /// Brings the robot to its start pose.
    fn start_pose(&mut self);
    /// Waits for the next control tick.
    fn wait_for_tick(&mut self);
    /// The state [setpoint − position, velocity].
    fn read_state(&mut self) -> Vector<2>;
    /// Commands the actuator.
    fn write_command(&mut self, u: &Vector<1>);
    /// Whether the watchdog fired: the episode is aborted (told the failure cost).
    fn tripped(&mut self) -> bool;
}

/// What stops the learning loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// The learner's configuration is invalid.
    Config(Error),
    /// The flash driver failed, or the store's ranges are invalid.
    Checkpoint(CheckpointError),
    /// An adapter call out of order.
    Adapter(AdapterError),
}

/// The store and its two buffers.
pub struct Persistence<F> {
    store: CheckpointStore<BlockingAsync<F>>,
    record: [u8; RECORD],
    item: [u8; ITEM],
}

/// Boot: the newest checkpoint on `hal_flash` (your HAL's blocking `NorFlash`), or a fresh
/// learner on erased flash or over a checkpoint of another firmware.
pub fn boot<F: NorFlash>(hal_flash: F) -> Result<(Persistence<F>, Learner), Fault> {
    let flash = BlockingAsync::new(hal_flash);
    let store = CheckpointStore::try_new(flash, SLOTS).map_err(Fault::Checkpoint)?;
    let mut p = Persistence {
        store,
        record: [0; RECORD],
        item: [0; ITEM],
    };
    let learner = match p.store.load::<Learner>(&mut p.record, &mut p.item) {
        Ok(Some(learner)) => learner,
        // Erased flash, or another firmware's checkpoint (the next save replaces it).
        Ok(None) | Err(CheckpointError::Record(_)) => fresh_learner().map_err(Fault::Config)?,
        // A flash error is not "no checkpoint": starting afresh would overwrite it.
        Err(e) => return Err(Fault::Checkpoint(e)),
    };
    Ok((p, learner))
}

/// One episode, then a checkpoint. A power cut during the episode loses that episode only:
/// after boot, the same candidate runs again (the same optimizer state, the same RNG).
pub fn episode<F: NorFlash>(
    p: &mut Persistence<F>,
    learner: &mut Learner,
    robot: &mut impl Robot,
    ticks: u32,
) -> Result<(), Fault> {
    robot.start_pose();
    learner
        .begin_seeded_episode::<Xoshiro128PlusPlus>(DEVICE_SEED)
        .map_err(Fault::Adapter)?;
    for _ in 0..ticks {
        robot.wait_for_tick();
        let state = robot.read_state();
        let u = learner.control(&state, &Vector::repeat(state[0]));
        robot.write_command(&u);
        if robot.tripped() {
            learner.abort_episode().map_err(Fault::Adapter)?;
            return save(p, learner);
        }
    }
    learner.end_episode().map_err(Fault::Adapter)?;
    save(p, learner)
}

/// Saves the learner after its episode was told.
fn save<F: NorFlash>(p: &mut Persistence<F>, learner: &Learner) -> Result<(), Fault> {
    let saved = p.store.save(learner, &mut p.record, &mut p.item);
    saved.map_err(Fault::Checkpoint)
}

/// The firmware's main loop: boot, then episodes for ever (after the 200 learning episodes
/// the adapter runs the best θ and tells nothing). Returns only the fault that stops it.
pub fn run<F: NorFlash>(hal_flash: F, robot: &mut impl Robot) -> Fault {
    let (mut p, mut learner) = match boot(hal_flash) {
        Ok(booted) => booted,
        Err(fault) => return fault,
    };
    loop {
        match episode(&mut p, &mut learner, robot, 500) {
            // A failed save leaves the previous checkpoint the newest; the next one retries.
            Ok(()) | Err(Fault::Checkpoint(_)) => {}
            Err(fault) => return fault,
        }
    }
}
