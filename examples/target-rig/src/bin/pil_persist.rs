//! Processor-in-the-loop firmware of the AUV survey whose learner survives a power cut: the
//! `pil` firmware (the library's `Adapter` with `CoordinateSearch<18>`) plus a
//! `CheckpointStore` on a flash that the host keeps outside the emulator
//! ([`ctrl_adapt_firmware::host_flash`]). At boot it loads the newest checkpoint (or starts
//! fresh on erased flash), answers the host's Hello with the episode to go on from, and saves
//! the checkpoint (adapter, RNG, next episode) at the end of every episode, before the Report.
//!
//! `cargo run --release -p host-tests --bin pil -- --persist` runs it: uninterrupted, then
//! killed and restarted at seeded points, and checks the two runs are bit-identical. With
//! `--handoff FILE` the flash starts with the host demo's checkpoint of the global phase.
#![no_std]
#![no_main]

use auv_survey::checkpoint::{AuvCheckpoint, Persisting, SLOTS};
use auv_survey::{self as auv, AuvLearner};
use ctrl_adapt::CoordinateSearch;
use ctrl_adapt::checkpoint::CheckpointStore;
use ctrl_adapt_firmware::host_flash::HostFlash;
use ctrl_adapt_firmware::{exit_failure, pil};

#[cortex_m_rt::entry]
fn main() -> ! {
    let Ok(flash) = HostFlash::open() else {
        defmt::error!("pil_persist: cannot open the host's flash");
        exit_failure()
    };
    let Ok(store) = CheckpointStore::try_new(flash, SLOTS) else {
        defmt::error!("pil_persist: invalid flash layout");
        exit_failure()
    };
    let fresh = auv::coordinate_search(u32::MAX)
        .and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED))
        .map(AuvCheckpoint::fresh);
    let Ok(fresh) = fresh else {
        defmt::error!("invalid AUV configuration");
        exit_failure()
    };
    let learner = match Persisting::<CoordinateSearch<{ auv::P }>, _>::boot(store, || fresh) {
        Ok((learner, loaded)) => {
            if loaded {
                defmt::info!(
                    "pil_persist: resumed from checkpoint generation {=?}: next episode {=u16}",
                    learner.generation(),
                    learner.state().next_episode
                );
            } else {
                defmt::info!("pil_persist: no checkpoint, fresh start");
            }
            learner
        }
        Err(e) => {
            defmt::error!("pil_persist: flash error at boot: {}", e);
            exit_failure()
        }
    };
    defmt::info!(
        "footprint: size_of Persisting<CoordinateSearch<18>> = {=usize}",
        core::mem::size_of::<Persisting<CoordinateSearch<{ auv::P }>, HostFlash>>()
    );
    pil::serve(learner)
}
