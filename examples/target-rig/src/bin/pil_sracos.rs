//! Processor-in-the-loop firmware for the AUV survey with SRACOS (`Sracos<18>`, ZOOpt's
//! defaults over the AUV box) as the learner: `pil` with another optimizer
//! (`cargo run --release -p host-tests --bin pil -- --optimizer sracos`).
#![no_std]
#![no_main]

use auv_survey as auv;
use ctrl_adapt_firmware::pil;

#[cortex_m_rt::entry]
fn main() -> ! {
    pil::run_auv("Sracos<18>", auv::sracos)
}
