//! The AUV learner on flash (`serde` feature): the checkpoint the persistent PIL firmware
//! saves after every episode, and the one the host demo writes at the end of its global
//! phase for the firmware to start its local phase from.
//!
//! * [`AuvCheckpoint`]: the learner (adapter with its optimizer, controller and cost, and the
//!   RNG) and the next episode it expects, as one [`Persistent`] record.
//! * [`Persisting`]: a [`pil_link::Learner`] that runs an [`AuvCheckpoint`]'s learner and
//!   saves the checkpoint into a [`CheckpointStore`] at the end of every episode, before the
//!   Report goes out: a Report the host has received is on flash. After a reboot it answers
//!   the host's Hello with the episode to go on from.
//! * [`FLASH_SIZE`], [`PAGE`], [`SLOTS`], [`ITEM`], [`RECORD`]: the flash layout both sides
//!   use (two slots of three 2 KiB pages, 256-byte items).

use core::ops::Range;

use ctrl_adapt::checkpoint::{CheckpointError, CheckpointStore};
use ctrl_adapt::optimizer::{CoordinateConfig, CoordinateSearch, Optimizer};
use ctrl_adapt::record::{Persistent, Shape};
use ctrl_adapt::{Error, Vector};
use embedded_storage_async::nor_flash::NorFlash;
use pil_link::Values;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use ctrl_adapt::controller::Adapter;
use ctrl_adapt::cost::SurveyCost;

use crate::{
    AuvAdapter, AuvLearner, LOCAL_STEP, LOCAL_TOLERANCE, P, RADIUS, adapter_config, bounds,
    controller,
};

/// The flash page (erase unit).
pub const PAGE: u32 = 2048;
/// Pages per slot.
pub const SLOT_PAGES: u32 = 3;
/// The two slots of the [`CheckpointStore`].
pub const SLOTS: [Range<u32>; 2] = [
    0..SLOT_PAGES * PAGE,
    SLOT_PAGES * PAGE..2 * SLOT_PAGES * PAGE,
];
/// The flash's size: the two slots.
pub const FLASH_SIZE: u32 = 2 * SLOT_PAGES * PAGE;
/// The item buffer: 250 record bytes per chunk.
pub const ITEM: usize = 256;
/// The record buffer (an `AuvCheckpoint<CoordinateSearch<18>>` is about 800 bytes).
pub const RECORD: usize = 1024;

/// The AUV learner and the next episode it expects: what the persistent firmware keeps on
/// flash.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(bound = "O: Serialize + DeserializeOwned")]
pub struct AuvCheckpoint<O> {
    /// The adapter (optimizer, controller, cost) and its RNG.
    pub learner: AuvLearner<O>,
    /// The next episode: 0 before any, one past the last episode ended.
    pub next_episode: u16,
}

impl<O> Persistent for AuvCheckpoint<O>
where
    O: Optimizer<P> + Persistent,
    AuvAdapter<O>: Persistent,
{
    const SHAPE: Shape = Shape::new(*b"AUVC", &[]).nest(<AuvAdapter<O> as Persistent>::SHAPE);

    /// The adapter's checks; the RNG and the episode counter can hold any value.
    fn validate(&self) -> Result<(), Error> {
        self.learner.adapter.validate()
    }
}

impl<O: Optimizer<P>> AuvCheckpoint<O> {
    /// A learner that has run no episode.
    pub fn fresh(learner: AuvLearner<O>) -> Self {
        Self {
            learner,
            next_episode: 0,
        }
    }
}

/// The local phase from `theta0` (the global phase's best): coordinate search from there,
/// initial step [`LOCAL_STEP`], tolerance [`LOCAL_TOLERANCE`], the adapter's initial θ
/// `theta0` too (what it deploys before anything is told), RNG seeded with `seed`, episode 0.
pub fn handoff(theta0: Vector<P>, seed: u64) -> Result<AuvCheckpoint<CoordinateSearch<P>>, Error> {
    let search = CoordinateSearch::try_new(
        bounds()?,
        theta0,
        CoordinateConfig {
            initial_step: LOCAL_STEP,
            tolerance: LOCAL_TOLERANCE,
            max_evaluations: u32::MAX,
            ..CoordinateConfig::DEFAULT
        },
    )?;
    let adapter = Adapter::try_new(
        search,
        controller()?,
        SurveyCost::try_new(RADIUS)?,
        adapter_config(u32::MAX),
        theta0,
    )?;
    Ok(AuvCheckpoint::fresh(AuvLearner::from_adapter(
        adapter, seed,
    )))
}

/// Counters of the saves of a [`Persisting`] learner.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SaveStats {
    /// Saves that completed.
    pub saved: u32,
    /// Saves that failed (the previous checkpoint stays the newest).
    pub failed: u32,
    /// The last error, if any.
    pub last_error: Option<CheckpointError>,
}

/// A [`pil_link::Learner`] that saves its [`AuvCheckpoint`] after every episode.
pub struct Persisting<O, F> {
    state: AuvCheckpoint<O>,
    store: CheckpointStore<F>,
    record: [u8; RECORD],
    item: [u8; ITEM],
    episode: u16,
    stats: SaveStats,
}

impl<O, F> Persisting<O, F>
where
    O: Optimizer<P> + Persistent,
    AuvAdapter<O>: Persistent,
    F: NorFlash,
{
    /// Boots from `store`: the newest checkpoint, or `fresh` when there is none (or when the
    /// newest is of another type, sizes or format version: a save will replace it). The
    /// second value says whether a checkpoint was loaded; a flash error is returned.
    pub fn boot(
        mut store: CheckpointStore<F>,
        fresh: impl FnOnce() -> AuvCheckpoint<O>,
    ) -> Result<(Self, bool), CheckpointError> {
        let mut record = [0u8; RECORD];
        let mut item = [0u8; ITEM];
        let (state, loaded) = match store.load::<AuvCheckpoint<O>>(&mut record, &mut item) {
            Ok(Some(state)) => (state, true),
            Ok(None) | Err(CheckpointError::Record(_)) => (fresh(), false),
            Err(e) => return Err(e),
        };
        let episode = state.next_episode;
        Ok((
            Self {
                state,
                store,
                record,
                item,
                episode,
                stats: SaveStats::default(),
            },
            loaded,
        ))
    }

    /// The checkpoint as it stands.
    pub fn state(&self) -> &AuvCheckpoint<O> {
        &self.state
    }

    /// The store's generation of the newest checkpoint.
    pub fn generation(&self) -> Option<u32> {
        self.store.generation()
    }

    /// Counters of the saves.
    pub fn stats(&self) -> SaveStats {
        self.stats
    }

    /// Saves the checkpoint now.
    pub fn save(&mut self) -> Result<(), CheckpointError> {
        let saved = self
            .store
            .save(&self.state, &mut self.record, &mut self.item);
        match saved {
            Ok(()) => self.stats.saved = self.stats.saved.saturating_add(1),
            Err(e) => {
                self.stats.failed = self.stats.failed.saturating_add(1);
                self.stats.last_error = Some(e);
            }
        }
        saved
    }
}

impl<O, F> pil_link::Learner for Persisting<O, F>
where
    O: Optimizer<P> + Persistent,
    AuvAdapter<O>: Persistent,
    F: NorFlash,
{
    fn start_episode(&mut self, episode: u16, request: &[f32], theta: &mut Values) {
        self.episode = episode;
        self.state.learner.start_episode(episode, request, theta);
    }

    fn act(&mut self, state: &[f32], action: &mut Values) {
        self.state.learner.act(state, action);
    }

    fn fallback(&mut self, last_state: Option<&[f32]>, action: &mut Values) {
        self.state.learner.fallback(last_state, action);
    }

    fn end_episode(&mut self, report: &mut Values) {
        self.state.learner.end_episode(report);
        self.state.next_episode = self.episode.saturating_add(1);
        // A failed save leaves the previous checkpoint the newest; it is counted, and the
        // next episode's save tries again.
        let _ = self.save();
    }

    fn next_episode(&self) -> u16 {
        self.state.next_episode
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coordinate_search;
    use ctrl_adapt::record;
    use embedded_storage_async::nor_flash::{ErrorType, NorFlashErrorKind, ReadNorFlash};
    use pil_link::Learner;

    /// A NOR flash in memory with the firmware's layout.
    struct RamFlash(Vec<u8>);

    #[derive(Debug)]
    struct Bad;

    impl embedded_storage_async::nor_flash::NorFlashError for Bad {
        fn kind(&self) -> NorFlashErrorKind {
            NorFlashErrorKind::OutOfBounds
        }
    }

    impl ErrorType for &mut RamFlash {
        type Error = Bad;
    }

    impl ReadNorFlash for &mut RamFlash {
        const READ_SIZE: usize = 1;
        async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Bad> {
            let o = offset as usize;
            bytes.copy_from_slice(self.0.get(o..o + bytes.len()).ok_or(Bad)?);
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.0.len()
        }
    }

    impl NorFlash for &mut RamFlash {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = PAGE as usize;
        async fn erase(&mut self, from: u32, to: u32) -> Result<(), Bad> {
            self.0
                .get_mut(from as usize..to as usize)
                .ok_or(Bad)?
                .fill(0xFF);
            Ok(())
        }
        async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Bad> {
            let o = offset as usize;
            let to = self.0.get_mut(o..o + bytes.len()).ok_or(Bad)?;
            to.iter_mut().zip(bytes).for_each(|(t, b)| *t &= b);
            Ok(())
        }
    }

    fn fresh() -> AuvCheckpoint<CoordinateSearch<P>> {
        AuvCheckpoint::fresh(
            AuvLearner::try_new(coordinate_search(u32::MAX).unwrap(), u32::MAX, 1).unwrap(),
        )
    }

    fn episode(l: &mut impl Learner, e: u16) -> Values {
        let mut theta = Values::new();
        l.start_episode(e, &[], &mut theta);
        let mut action = Values::new();
        for k in 0..5 {
            l.act(&[-5.0 + k as f32, -2.0, 4.8, 0.1, 0.0, 0.0], &mut action);
        }
        let mut report = Values::new();
        l.end_episode(&mut report);
        theta
    }

    /// Checks: a learner booted from the flash after 3 saved episodes says episode 3, holds
    /// the very state of the one that ran them, and draws the same next θ; erased flash
    /// boots fresh at episode 0.
    #[test]
    fn a_rebooted_learner_resumes_where_it_saved() {
        let mut flash = RamFlash(vec![0xFF; FLASH_SIZE as usize]);
        let store = CheckpointStore::try_new(&mut flash, SLOTS).unwrap();
        let (mut first, loaded) = Persisting::boot(store, fresh).unwrap();
        assert!(!loaded);
        assert_eq!(first.next_episode(), 0);
        for e in 0..3 {
            episode(&mut first, e);
        }
        assert_eq!(first.stats().saved, 3);
        let mut before = [0u8; RECORD];
        let before = record::save(first.state(), &mut before).unwrap().to_vec();
        let next = episode(&mut first.state().learner.clone(), 3);
        // `first` borrows the flash: its last use is above.

        let store = CheckpointStore::try_new(&mut flash, SLOTS).unwrap();
        let (mut second, loaded) = Persisting::boot(store, fresh).unwrap();
        assert!(loaded);
        assert_eq!(second.next_episode(), 3);
        let mut after = [0u8; RECORD];
        assert_eq!(
            record::save(second.state(), &mut after).unwrap(),
            &before[..]
        );
        assert_eq!(episode(&mut second, 3), next);
    }

    /// Checks: the hand-over starts the coordinate search at θ₀ (the first θ asked) and its
    /// record loads back as the same type.
    #[test]
    fn handoff_starts_the_local_phase_at_theta0() {
        let theta0 = Vector::<P>::from_fn(|i, _| 0.05 * i as f32 - 0.4);
        let mut h = handoff(theta0, 1).unwrap();
        let mut buf = [0u8; RECORD];
        let bytes = record::save(&h, &mut buf).unwrap().to_vec();
        let mut loaded: AuvCheckpoint<CoordinateSearch<P>> = record::load(&bytes).unwrap();
        assert_eq!(loaded.next_episode, 0);
        let (a, b) = (episode(&mut h.learner, 0), episode(&mut loaded.learner, 0));
        assert_eq!(a, b);
        assert_eq!(a.as_slice(), theta0.as_slice());
    }
}
