//! The smallest complete ctrl-adapt firmware, to copy into a project: a PD position loop on
//! a 1-D double integrator that an unmodelled constant push (−1.5 m/s²) keeps off its
//! setpoint, made adaptive by a two-parameter linear correction that a coordinate search
//! tunes over 40 episodes of 10 s; then the best correction is deployed.
//!
//! The plant is simulated on the microcontroller itself ([`Plant`]): on a robot, its three
//! methods are your sensor read, your actuator write and your start-pose routine, and the
//! tick loop waits for your control timer. Everything else stays as it is.
//!
//! Run it on QEMU's Cortex-M4F (`bash scripts/firmware-ci` installs QEMU, the target and
//! defmt-print): `cargo run --release` in this directory. It exits with success when the
//! deployed correction's cost is below 35 % of the bare PD's.
#![no_std]
#![no_main]

use cortex_m as _; // its critical-section implementation (single core), used by the logger
use ctrl_adapt::controller::{
    Adapter, AdapterConfig, CorrectedPd, IdentityFeatures, LinearPolicy, Pd,
};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Error, Vector};
use defmt_semihosting as _; // the defmt logger: semihosting stdout (defmt-rtt on a board)
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The corrected PD: 1 action, 2 state values [error, velocity], 2 features (the state
/// itself), 2 parameters (the correction's gains).
type Controller = CorrectedPd<1, 2, 2, 2, IdentityFeatures>;
/// The adapter: optimizer, controller, cost shaper; P = 2 parameters, S = 2, A = 1.
type MyAdapter = Adapter<CoordinateSearch<2>, Controller, QuadraticCost<1>, 2, 2, 1>;

/// Control period (s): a 50 Hz loop.
const DT: f32 = 0.02;
/// Ticks per episode: 10 s.
const TICKS: u32 = 500;
/// Learning episodes, after which the adapter deploys the best correction found.
const LEARNING: u32 = 40;

/// Builds the adapter once, at start-up. Every size is in the type: `size_of::<MyAdapter>()`
/// is all the RAM learning will ever use.
fn build_adapter() -> Result<MyAdapter, Error> {
    // The firmware's PD: acceleration from [error, velocity], limited to ±5 m/s².
    let pd = Pd::<1>::try_new(Vector::repeat(4.0), Vector::repeat(3.6))?
        .with_limit(Vector::repeat(5.0))?;
    // The correction c = clamp(W·[error, velocity]), |c| ≤ 3 m/s².
    let policy = LinearPolicy::try_new(IdentityFeatures, Vector::repeat(3.0))?;
    let controller: Controller = CorrectedPd::new(pd, policy);
    // W ∈ [−20, 20]², searched from the zero correction (the bare PD).
    let search = CoordinateSearch::try_new(
        Bounds::uniform(-20.0, 20.0)?,
        Vector::zeros(),
        CoordinateConfig {
            initial_step: 2.0,
            tolerance: 1e-3,
            ..CoordinateConfig::DEFAULT
        },
    )?;
    let config = AdapterConfig {
        dt: DT,
        failure_cost: 100.0, // told for a failed episode: worse than any real one
        max_faulty_ticks: 0, // one non-finite state fails the episode
        learning_episodes: LEARNING, // then deploy the best θ
    };
    let shaper = QuadraticCost::<1>::try_new(Vector::repeat(1.0))?; // ∫ error² dt
    Adapter::try_new(search, controller, shaper, config, Vector::zeros())
}

/// Stand-in for the robot: a unit mass at `x` (m) moving at `v` (m/s), commanded in
/// acceleration, with a constant push the PD was not designed for; the setpoint is 1 m.
struct Plant {
    x: f32,
    v: f32,
}

impl Plant {
    /// Your start-pose routine: back at rest at 0.
    fn reset(&mut self) {
        (self.x, self.v) = (0.0, 0.0);
    }

    /// Your sensor read: the policy's state [setpoint − position, velocity].
    fn read_state(&self) -> Vector<2> {
        Vector::from([1.0 - self.x, self.v])
    }

    /// Your actuator write: one control period of the commanded acceleration.
    fn write_command(&mut self, u: &Vector<1>) {
        self.v += (u[0] - 1.5) * DT; // −1.5 m/s²: the unmodelled push
        self.x += self.v * DT;
    }

    /// Your watchdog: the robot left its safe region.
    fn tripped(&self) -> bool {
        !(-5.0..=5.0).contains(&self.x)
    }
}

#[cortex_m_rt::entry]
fn main() -> ! {
    let Ok(mut adapter) = build_adapter() else {
        // A configuration error: never start learning (a robot would run its bare PD).
        defmt::error!("invalid adapter configuration");
        semihosting::process::exit(1)
    };
    defmt::info!(
        "size_of the adapter: {=usize} bytes",
        core::mem::size_of::<MyAdapter>()
    );
    // The optimizers draw from the RNG you pass; seed it from a hardware RNG or a constant.
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let mut plant = Plant { x: 0.0, v: 0.0 };
    let (mut bare, mut deployed) = (f32::NAN, f32::NAN);

    for episode in 0..=LEARNING {
        plant.reset();
        // Learn: the optimizer's next θ. After the budget: the best θ so far (Deploy).
        if let Err(e) = adapter.begin_episode(&mut rng) {
            defmt::error!("no episode: {}", e); // `control` then runs the bare PD
        }
        for _ in 0..TICKS {
            // On a robot: wait for the control timer here.
            let state = plant.read_state();
            // Never fails: a non-finite state gets the nominal PD (a faulty tick).
            let u = adapter.control(&state, &Vector::repeat(state[0]));
            plant.write_command(&u);
            if plant.tripped() {
                let _ = adapter.abort_episode(); // told the failure cost
                break;
            }
        }
        if adapter.in_episode() {
            // Scores the episode and tells the optimizer its cost.
            match adapter.end_episode() {
                Ok(report) => {
                    defmt::info!(
                        "episode {=u32} ({}): cost {=f32}, W = {}",
                        episode,
                        report.mode,
                        report.cost,
                        report.theta.as_slice()
                    );
                    if episode == 0 {
                        bare = report.cost; // θ = 0: the bare PD
                    }
                    deployed = report.cost;
                }
                Err(e) => defmt::error!("episode {=u32} not scored: {}", episode, e),
            }
        }
    }

    defmt::info!("bare PD cost {=f32}, deployed cost {=f32}", bare, deployed);
    if deployed < 0.35 * bare {
        semihosting::process::exit(0)
    } else {
        semihosting::process::exit(1)
    }
}

/// A panic ends the emulation with a failure code (on a board: reset, or fall back to the
/// bare controller). The library itself never panics on any input.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    semihosting::process::exit(1)
}
