//! Footprint benchmark of one control tick (`scripts/footprint` runs it under QEMU with an
//! instruction trace, like `bench`): `Adapter::control` of the AUV adapter (the PD, the
//! 18-weight correction, the envelope checks and the survey reward's bookkeeping) and the
//! policy correction alone (`LinearPolicy::correction`: φ, W·φ and the clamp), each on the
//! 240 states of an AUV episode. The script builds it with both release profiles ("s" and
//! `release-speed`, opt-level 3).
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvAdapter};
use ctrl_adapt::controller::guard::{Guard, GuardConfig, Limit, Source};
use ctrl_adapt::controller::{Adapter, AdapterError, Mode};
use ctrl_adapt::optimizer::unit_f32;
use ctrl_adapt::{CoordinateSearch, Vector};
use ctrl_adapt_firmware::bench::sections;
use ctrl_adapt_firmware::{exit_failure, exit_success, stack};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = auv::P;
/// Measured control ticks: one AUV episode.
const TICKS: u32 = auv::TICKS as u32;

#[cortex_m_rt::entry]
fn main() -> ! {
    for _ in 0..8 {
        sections::empty::measure(|| ());
    }
    if let Err(e) = measure_controller() {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    defmt::info!("footprint: peak stack tick = {=u32}", stack::peak_bytes());
    exit_success()
}

/// One AUV episode of control ticks through the adapter, then the policy correction alone
/// on the same states. θ is a uniform draw from the box (deployed, so every tick runs the
/// corrected law); the states are uniform over errors of ±6 m and velocities of ±0.6 m/s,
/// so the PD and the correction saturate on some axes of some ticks and not on others.
#[inline(never)]
fn measure_controller() -> Result<(), AdapterError> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2);
    let bounds = auv::bounds()?;
    let theta = bounds.sample_uniform(&mut rng);
    let mut adapter: AuvAdapter<CoordinateSearch<N>> = Adapter::try_new(
        auv::coordinate_search(u32::MAX)?,
        auv::controller()?,
        ctrl_adapt::cost::SurveyCost::try_new(auv::RADIUS)?,
        auv::adapter_config(u32::MAX),
        theta,
    )?;
    adapter.set_mode(Mode::Deploy)?;
    adapter.begin_episode(&mut rng)?;
    let state = |rng: &mut Xoshiro128PlusPlus| {
        Vector::<{ auv::S }>::from_fn(|i, _| {
            let range = if i < 3 { 6.0 } else { 0.6 };
            range * (2.0 * unit_f32(rng) - 1.0)
        })
    };
    // The state generator escapes through `black_box`, so the compiler cannot schedule the
    // next state's arithmetic between the markers (it does at opt-level 3 otherwise).
    let next = |rng: &mut Xoshiro128PlusPlus| {
        let x = state(core::hint::black_box(rng));
        core::hint::black_box(x)
    };
    let mut states = Xoshiro128PlusPlus::seed_from_u64(3);
    for _ in 0..TICKS {
        let x = next(&mut states);
        let error = Vector::<3>::new(x[0], x[1], x[2]);
        sections::control::measure(|| adapter.control(&x, &error));
    }
    let report = adapter.end_episode()?;
    defmt::info!(
        "footprint: measured control ticks = {=u32} (cost {=f32})",
        report.ticks,
        report.cost
    );
    measure_guarded(theta, &next)?;
    let policy = *adapter.controller().policy();
    let mut states = Xoshiro128PlusPlus::seed_from_u64(3);
    for _ in 0..TICKS {
        let x = next(&mut states);
        sections::correction::measure(|| policy.correction(&theta, &x, 0.0));
    }
    Ok(())
}

/// The same episode's ticks through the adapter with the runtime guard: 6 limits, one per
/// state coordinate (wide enough that no tick trips them), and the 240-tick envelope learned
/// from one bare episode on the same states (so every tick compares with it).
#[inline(never)]
fn measure_guarded(
    theta: Vector<N>,
    next: &impl Fn(&mut Xoshiro128PlusPlus) -> Vector<{ auv::S }>,
) -> Result<(), AdapterError> {
    let limit = |k: u16| Limit {
        source: Source::State(k),
        low: -100.0,
        high: 100.0,
    };
    let guard = Guard::<6, { auv::TICKS as usize }>::try_new(GuardConfig {
        limits: [limit(0), limit(1), limit(2), limit(3), limit(4), limit(5)],
        relative_margin: 10.0,
        absolute_margin: 10.0,
        tripped_cost_span: 5.0,
        ..GuardConfig::DEFAULT
    })?;
    defmt::info!(
        "footprint: size_of Guard<6, 240> = {=usize}",
        core::mem::size_of_val(&guard)
    );
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2);
    let mut adapter = Adapter::try_new(
        auv::coordinate_search(u32::MAX)?,
        auv::controller()?,
        ctrl_adapt::cost::SurveyCost::try_new(auv::RADIUS)?,
        auv::adapter_config(u32::MAX),
        theta,
    )?
    .with_guard(guard)?;
    for mode in [Mode::Nominal, Mode::Deploy] {
        adapter.set_mode(mode)?;
        adapter.begin_episode(&mut rng)?;
        let mut states = Xoshiro128PlusPlus::seed_from_u64(3);
        for _ in 0..TICKS {
            let x = next(&mut states);
            let error = Vector::<3>::new(x[0], x[1], x[2]);
            if mode == Mode::Deploy {
                sections::guarded_control::measure(|| adapter.control(&x, &error));
            } else {
                adapter.control(&x, &error);
            }
        }
        let report = adapter.end_episode()?;
        defmt::info!(
            "footprint: guarded ticks = {=u32}, tripped = {=bool}",
            report.ticks,
            report.trip.is_some()
        );
    }
    Ok(())
}
