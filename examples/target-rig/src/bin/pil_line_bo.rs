//! Processor-in-the-loop firmware for the AUV survey with LineBO (`LineBo<18, 64>`, the host
//! experiments' settings, no threshold) as the learner: `pil` with another optimizer
//! (`cargo run --release -p host-tests --bin pil -- --optimizer linebo`).
#![no_std]
#![no_main]

use auv_survey as auv;
use ctrl_adapt_firmware::pil;

#[cortex_m_rt::entry]
fn main() -> ! {
    pil::run_auv("LineBo<18, 64>", auv::line_bo)
}
