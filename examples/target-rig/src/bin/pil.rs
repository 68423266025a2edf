//! Processor-in-the-loop firmware for the AUV survey with the paper's local phase: the
//! library's `Adapter` over the 18-parameter corrected PD, the survey reward and
//! `CoordinateSearch<18>` ([`auv_survey`]), serving the host's plant over UART0
//! (`cargo run --release -p host-tests --bin pil`). `pil_sracos` and `pil_cem` are the same
//! firmware with SRACOS and the diagonal CEM.
#![no_std]
#![no_main]

use auv_survey as auv;
use ctrl_adapt_firmware::pil;

#[cortex_m_rt::entry]
fn main() -> ! {
    pil::run_auv("CoordinateSearch<18>", auv::coordinate_search)
}
