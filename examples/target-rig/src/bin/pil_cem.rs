//! Processor-in-the-loop firmware for the AUV survey with the diagonal cross-entropy method
//! (`DiagonalCem<18, 10, 5>`, CMA-ES weights, as in the host experiments) as the learner:
//! `pil` with another optimizer (`cargo run --release -p host-tests --bin pil -- --optimizer cem`).
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvCem, AuvLearner};
use ctrl_adapt_firmware::{exit_failure, pil};
use pil_link::Session;

#[cortex_m_rt::entry]
fn main() -> ! {
    // The host decides how many episodes learn (each Start frame says), so no budget here.
    let learner = auv::cem(u32::MAX).and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED));
    let Ok(learner) = learner else {
        defmt::error!("invalid AUV configuration");
        exit_failure()
    };
    defmt::info!(
        "footprint: size_of Session<AuvLearner<DiagonalCem<18, 10, 5>>> = {=usize}",
        core::mem::size_of::<Session<AuvLearner<AuvCem>>>()
    );
    pil::serve(learner)
}
