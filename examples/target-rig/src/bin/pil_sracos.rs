//! Processor-in-the-loop firmware for the AUV survey with SRACOS (`Sracos<18>`, ZOOpt's
//! defaults over the AUV box) as the learner: `pil` with another optimizer
//! (`cargo run --release -p host-tests --bin pil -- --optimizer sracos`).
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvLearner};
use ctrl_adapt::Sracos;
use ctrl_adapt_firmware::{exit_failure, pil};
use pil_link::Session;

#[cortex_m_rt::entry]
fn main() -> ! {
    // The host decides how many episodes learn (each Start frame says), so no budget here.
    let learner = auv::sracos(u32::MAX).and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED));
    let Ok(learner) = learner else {
        defmt::error!("invalid AUV configuration");
        exit_failure()
    };
    defmt::info!(
        "footprint: size_of Session<AuvLearner<Sracos<18>>> = {=usize}",
        core::mem::size_of::<Session<AuvLearner<Sracos<18>>>>()
    );
    pil::serve(learner)
}
