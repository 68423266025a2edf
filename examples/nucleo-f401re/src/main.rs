//! Your PD loop made adaptive on a real board: the minimal adapter's code on a NUCLEO-F401RE
//! driving a cart (encoder in, PWM + direction out). `my_pd.rs` is your PD as it is;
//! `board.rs` is the board (in place of the minimal adapter's simulated `robot.rs`).
//!
//! The operator presses the user button to start each episode, and again to stop one. An
//! episode also stops, with the motor off, when the cart leaves its safe range; between
//! episodes the bare PD brings the cart back to the start pose. See docs/porting.md.
#![no_std]
#![no_main]

mod board; // the board (here a NUCLEO-F401RE driving a cart)
mod my_pd; // your PD, as it is

use board::{Board, Led};
use ctrl_adapt::{
    Vector,
    controller::{AdapterBuilder, CorrectedAdapter, Mode, Nominal},
};
use rand_xoshiro::Xoshiro128PlusPlus;

const EPISODES: u32 = 40; // learning episodes, then the best correction is deployed
const SEED: u32 = 0x5EED; // this device's seed (one per robot if several learn)

#[cortex_m_rt::entry]
fn main() -> ! {
    let mut board = Board::take();
    let mut pd = my_pd::MyPd::default();
    let nominal = move |s: &Vector<2>, _time: f32| Vector::from([pd.update(s[0], board::DT)]);
    // A correction of up to ±0.3 duty, whole at 5 cm of error or at 0.2 m/s; the command
    // is a duty, so the corrected action is limited to ±1.
    let builder = AdapterBuilder::<1, 2, 2>::new(board::DT, [0.3], [0.05, 0.2]).output_limit([1.0]);
    let Ok(mut adapter) = builder.learning_episodes(EPISODES).build(nominal) else {
        board.halt("invalid configuration")
    };
    let mut armed = true;
    let mut episode: u32 = 0;
    loop {
        return_to_start(&mut board, &mut adapter, armed);
        board.take_overruns(); // count the episode's own
        // θ of this episode: the optimizer's next candidate; after EPISODES, the best one.
        // (Should it fail, no episode runs and `control` gives the bare PD.)
        if let Err(e) = adapter.begin_seeded_episode::<Xoshiro128PlusPlus>(SEED) {
            defmt::warn!("episode {}: not started ({})", episode, e);
        }
        board.show(if adapter.mode() == Mode::Learn {
            Led::On
        } else {
            Led::SlowBlink
        });
        let mut fault = None;
        for _ in 0..board::TICKS {
            let state = board.read_state(board::SETPOINT); // [error, velocity]
            fault = board.fault();
            if fault.is_some() {
                break;
            }
            let u = adapter.control(&state, &Vector::from([state[0]])); // cost: ∫ error² dt
            board.write_command(u[0]);
        }
        // A stopped episode is told the failure cost: the optimizer learns to avoid it.
        let report = if let Some(fault) = fault {
            board.stop_motor();
            defmt::warn!("episode {}: aborted ({})", episode, fault);
            adapter.abort_episode()
        } else {
            adapter.end_episode()
        };
        if let Ok(report) = report {
            let overruns = board.take_overruns();
            defmt::info!(
                "episode {}: cost {}, {} overruns",
                episode,
                report.cost,
                overruns
            );
        }
        armed = fault.is_none();
        episode = episode.wrapping_add(1);
    }
}

/// Between episodes: back to the start pose under the bare PD (outside an episode,
/// `control` runs the nominal law and records nothing), held there until a press of the
/// button starts the next episode.
///
/// After an aborted episode (`armed` false), or whenever the cart is outside its safe range,
/// the motor stays off until the operator has checked the rig and pressed the button.
fn return_to_start<N: Nominal<2, 1>>(
    board: &mut Board,
    adapter: &mut CorrectedAdapter<N, 1, 2, 2>,
    mut armed: bool,
) {
    loop {
        let state = board.read_state(board::START);
        let pressed = board.pressed();
        if !armed || board.outside_safe_range() {
            board.stop_motor();
            board.show(Led::FastBlink);
            // A press inside the safe range re-arms; the next one starts the episode.
            armed = pressed && !board.outside_safe_range();
            continue;
        }
        board.show(Led::Off);
        let u = adapter.control(&state, &Vector::from([state[0]]));
        board.write_command(u[0]);
        if pressed && board.at_rest(board::START) {
            return;
        }
    }
}
