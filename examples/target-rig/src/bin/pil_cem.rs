//! Processor-in-the-loop firmware for the AUV survey with the diagonal cross-entropy method
//! (`DiagonalCem<18, 10, 5>`, CMA-ES weights, as in the host experiments) as the learner:
//! `pil` with another optimizer (`cargo run --release -p host-tests --bin pil -- --optimizer cem`).
#![no_std]
#![no_main]

use auv_survey as auv;
use ctrl_adapt_firmware::pil;

#[cortex_m_rt::entry]
fn main() -> ! {
    pil::run_auv("DiagonalCem<18, 10, 5>", auv::cem)
}
