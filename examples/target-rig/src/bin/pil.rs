//! Processor-in-the-loop firmware for the AUV survey with the paper's local phase: the
//! library's `Adapter` over the 18-parameter corrected PD, the survey reward and
//! `CoordinateSearch<18>` ([`auv_survey`]), serving the host's plant over UART0
//! (`cargo run --release -p host-tests --bin pil`). `pil_sracos` and `pil_cem` are the same
//! firmware with SRACOS and the diagonal CEM.
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvLearner};
use ctrl_adapt::CoordinateSearch;
use ctrl_adapt_firmware::{exit_failure, pil};
use pil_link::Session;

#[cortex_m_rt::entry]
fn main() -> ! {
    // The host decides how many episodes learn (each Start frame says), so no budget here.
    let learner =
        auv::coordinate_search(u32::MAX).and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED));
    let Ok(learner) = learner else {
        defmt::error!("invalid AUV configuration");
        exit_failure()
    };
    defmt::info!(
        "footprint: size_of Session<AuvLearner<CoordinateSearch<18>>> = {=usize}",
        core::mem::size_of::<Session<AuvLearner<CoordinateSearch<18>>>>()
    );
    pil::serve(learner)
}
