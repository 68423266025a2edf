//! Your PD loop made adaptive: the code of the getting-started guide, as a firmware for
//! QEMU's Cortex-M4F. `my_pd.rs` is your PD as it is; `robot.rs` stands for your board
//! (sensor read, actuator write, start pose) and simulates a cart that an unmodelled push
//! keeps off its setpoint.
#![no_std]
#![no_main]

mod my_pd; // your PD, as it is
mod robot; // your board (here a simulated cart)

use ctrl_adapt::{Vector, controller::AdapterBuilder};
use rand_xoshiro::Xoshiro128PlusPlus;

const EPISODES: u32 = 40; // learning episodes, then the best correction is deployed

#[cortex_m_rt::entry]
fn main() -> ! {
    let mut pd = my_pd::MyPd::default();
    let nominal = move |s: &Vector<2>, _time: f32| Vector::from([pd.update(s[0], robot::DT)]);
    // A correction of up to ±3 m/s², whole at 0.1 m of error or at 0.1 m/s.
    let builder = AdapterBuilder::<1, 2, 2>::new(robot::DT, [3.0], [0.1, 0.1]);
    let Ok(mut adapter) = builder.learning_episodes(EPISODES).build(nominal) else {
        robot::stop("invalid configuration")
    };
    let mut robot = robot::Robot::default();
    for episode in 0..=EPISODES {
        robot.go_to_start();
        // θ of this episode: the optimizer's next candidate; after EPISODES, the best one.
        // (Should it fail, no episode runs and `control` gives the bare PD.)
        let _ = adapter.begin_seeded_episode::<Xoshiro128PlusPlus>(0x5EED);
        for _ in 0..robot::TICKS {
            let state = robot.read_state(); // [error, velocity]
            let u = adapter.control(&state, &Vector::from([state[0]])); // cost: ∫ error² dt
            robot.write_command(u[0]);
        }
        if let Ok(report) = adapter.end_episode() {
            defmt::info!("episode {}: cost {}", episode, report.cost);
        }
    }
    robot.finish()
}
