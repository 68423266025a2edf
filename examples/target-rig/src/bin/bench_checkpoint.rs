//! Footprint of a checkpoint on the M4F: the persistent PIL firmware's checkpoint (the AUV
//! `Adapter` with `CoordinateSearch<18>`, its RNG and the next episode) saved into and loaded
//! from a `CheckpointStore` over a flash in RAM with the PIL firmware's layout (two slots of
//! three 2 KiB pages, 256-byte items), after each of [`EPISODES`] learning episodes.
//!
//! Counted with SysTick under QEMU's `-icount shift=0`
//! ([`ctrl_adapt_firmware::bench::icount`], exact to ±40 instructions): the instructions of
//! the processor for `save` and `load` (serialising, CRCs, `sequential-storage`'s search of
//! the slot, copying to and from the flash; a real flash adds its program and erase times,
//! see the part's datasheet). Logs `footprint: sample checkpoint_save = N` and
//! `…_load`, the record's length and the flash bytes written and pages erased per save.
#![no_std]
#![no_main]

use auv_survey::checkpoint::{AuvCheckpoint, FLASH_SIZE, ITEM, PAGE, RECORD, SLOTS};
use auv_survey::{self as auv, AuvLearner};
use ctrl_adapt::CoordinateSearch;
use ctrl_adapt::checkpoint::CheckpointStore;
use ctrl_adapt_firmware::bench::icount::Counter;
use ctrl_adapt_firmware::{exit_failure, exit_success, stack};
use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use pil_link::{Learner as _, Values};

/// Learning episodes, each followed by a save and a load.
const EPISODES: u16 = 24;
/// Control ticks per episode (the states are made up: only the learner's state matters).
const TICKS: u16 = 20;

type Checkpoint = AuvCheckpoint<CoordinateSearch<{ auv::P }>>;

/// A NOR flash in RAM that counts what is written and erased.
struct RamFlash {
    bytes: [u8; FLASH_SIZE as usize],
    written: u32,
    erased: u32,
}

#[derive(Debug, Clone, Copy)]
struct OutOfBounds;

impl NorFlashError for OutOfBounds {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::OutOfBounds
    }
}

impl ErrorType for RamFlash {
    type Error = OutOfBounds;
}

impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), OutOfBounds> {
        let start = offset as usize;
        let from = self
            .bytes
            .get(start..start + bytes.len())
            .ok_or(OutOfBounds)?;
        bytes.copy_from_slice(from);
        Ok(())
    }

    fn capacity(&self) -> usize {
        FLASH_SIZE as usize
    }
}

impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), OutOfBounds> {
        let pages = self
            .bytes
            .get_mut(from as usize..to as usize)
            .ok_or(OutOfBounds)?;
        pages.fill(0xFF);
        self.erased += (to - from) / PAGE;
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), OutOfBounds> {
        let start = offset as usize;
        let to = self
            .bytes
            .get_mut(start..start + bytes.len())
            .ok_or(OutOfBounds)?;
        for (t, b) in to.iter_mut().zip(bytes) {
            *t &= *b;
        }
        self.written += bytes.len() as u32;
        Ok(())
    }
}

static mut FLASH: RamFlash = RamFlash {
    bytes: [0xFF; FLASH_SIZE as usize],
    written: 0,
    erased: 0,
};

#[cortex_m_rt::entry]
fn main() -> ! {
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut counter = Counter::new(peripherals.SYST);
    // SAFETY: the only reference to FLASH, taken once before anything else runs (no
    // interrupt handler touches it).
    let flash = unsafe { &mut *core::ptr::addr_of_mut!(FLASH) };
    let Ok(mut store) = CheckpointStore::try_new(flash, SLOTS) else {
        exit_failure()
    };
    let fresh = auv::coordinate_search(u32::MAX)
        .and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED))
        .map(Checkpoint::fresh);
    let Ok(mut state) = fresh else { exit_failure() };
    let mut record = [0u8; RECORD];
    let mut item = [0u8; ITEM];
    for _ in 0..4 {
        let ((), empty) = counter.measure(|| ());
        defmt::info!("footprint: sample empty = {=u32}", empty);
    }
    let (mut written, mut erased) = (0, 0);
    for episode in 0..EPISODES {
        let mut values = Values::new();
        state.learner.start_episode(episode, &[], &mut values);
        for tick in 0..TICKS {
            let x = 0.1 * f32::from(tick);
            state
                .learner
                .act(&[-5.0 + x, -2.0, 4.8 - x, 0.1, 0.0, -0.1], &mut values);
        }
        state.learner.end_episode(&mut values);
        state.next_episode = episode + 1;
        let (saved, save) = counter.measure(|| store.save(&state, &mut record, &mut item));
        if saved.is_err() {
            defmt::error!("save failed: {}", saved);
            exit_failure()
        }
        let len = ctrl_adapt::record::save(&state, &mut record).map_or(0, |r| r.len());
        let flash = store.into_inner();
        defmt::info!(
            "footprint: sample checkpoint_bytes = {=usize}, flash written {=u32}, pages erased {=u32}",
            len,
            flash.written - written,
            flash.erased - erased
        );
        (written, erased) = (flash.written, flash.erased);
        let Ok(s) = CheckpointStore::try_new(flash, SLOTS) else {
            exit_failure()
        };
        store = s;
        let (loaded, load) = counter.measure(|| store.load::<Checkpoint>(&mut record, &mut item));
        match loaded {
            Ok(Some(l)) if l.next_episode == state.next_episode => {}
            _ => {
                defmt::error!("the checkpoint did not load back");
                exit_failure()
            }
        }
        defmt::info!("footprint: sample checkpoint_save = {=u32}", save);
        defmt::info!("footprint: sample checkpoint_load = {=u32}", load);
    }
    defmt::info!(
        "footprint: size_of CheckpointStore = {=usize}",
        core::mem::size_of::<CheckpointStore<&mut RamFlash>>()
    );
    defmt::info!(
        "footprint: peak stack bench_checkpoint = {=u32}",
        stack::peak_bytes()
    );
    exit_success()
}
