//! A seeded adversarial driver for the optimizers and the adapter.
//!
//! [`drive`] builds an optimizer on a random box (degenerate ones included: a few ulps wide,
//! subnormal, near ±`f32::MAX`) with a random configuration (any field possibly NaN,
//! infinite, zero, negative or huge) and then mixes, for as many operations as asked: `ask`,
//! a repeated `ask`, `tell` with NaN, ±∞, subnormal, ±`f32::MAX`, plateau and ordinary
//! costs, `tell` without `ask`, and now and then a rebuild. After **every** operation it
//! checks the contract of [`Optimizer`]:
//!
//! * candidates are finite and inside the bounds, a pending candidate is repeated;
//! * a refused call (`tell` without `ask`, a non-finite cost, `ask` on a stopped search)
//!   answers with its error and leaves the whole optimizer unchanged (`Clone` + `PartialEq`);
//! * `evaluations` counts the accepted tells, never beyond `max_evaluations`;
//! * the best cost is the lowest cost told so far (so it never increases), its θ one of the
//!   candidates told that cost; for an optimizer whose costs come from changing conditions
//!   ([`drive_in_conditions`], e.g. `TwoPhase`: a simulator, then the robot), the lowest
//!   told in the current conditions, and until the first cost told in new conditions the
//!   best of the conditions before;
//! * `ask` fails only with [`Error::Stopped`]: when the status is not running, or when a
//!   search finds no new point in its box and stops itself as converged (SRACOS and RACOS on
//!   a box a few f32 steps wide), changing nothing else.
//!
//! [`drive_adapter`] does the same for the [`Adapter`] around a one-axis corrected PD:
//! episodes in every mode, fixed-θ episodes (θ outside the box or NaN included), ticks with
//! NaN, infinite, huge and subnormal states, aborts, mode switches and calls out of order.
//! Every action must be finite and within the PD's limit, its distance from the nominal
//! action within the correction envelope; the faulty ticks counted must be the ticks whose
//! state or corrected action was not finite; a failed episode (aborted, too many faulty
//! ticks, a non-finite cost) must be told the failure cost, any other learning episode its
//! own cost; refused calls change nothing.
//!
//! A violation is returned, not panicked, with the seed and the operation's index, so that
//! a test can also show that the driver catches a planted bug. A panic inside the library
//! propagates (and fails the calling test) with the seed printed first.

use std::fmt;
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};

use ctrl_adapt::controller::{
    Adapter, AdapterConfig, AdapterError, Controller, CorrectedPd, LinearPolicy, Mode, Pd,
    StateFeatures,
};
use ctrl_adapt::cost::Shaper;
use ctrl_adapt::optimizer::{
    Bounds, Error, Generation, InFlight, Optimizer, Status, Ticket, Vector,
};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// The driver's RNG (one stream drives the choices, the boxes and the optimizer's draws).
pub type DriverRng = Xoshiro256PlusPlus;

/// A broken contract: which check, after which operation, of which seed.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// The driver's seed.
    pub seed: u64,
    /// The operation after which the check failed (0-based, over the whole run).
    pub operation: u64,
    /// What was expected and what happened.
    pub message: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "seed {}, operation {}: {}",
            self.seed, self.operation, self.message
        )
    }
}

/// What a run exercised.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Tally {
    /// Operations run (every call on the optimizer or adapter, constructions included).
    pub operations: u64,
    /// Optimizers (or adapters) built and driven.
    pub built: u64,
    /// Boxes or configurations refused at construction.
    pub refused_constructions: u64,
    /// Candidates handed out by `ask` (repeats included).
    pub asks: u64,
    /// Costs accepted.
    pub accepted_tells: u64,
    /// Calls refused with an error (and checked to change nothing).
    pub refused_calls: u64,
    /// Runs that ended with the search stopped (converged or budget spent).
    pub stopped: u64,
    /// Adapter only: faulty ticks counted, and episodes told the failure cost.
    pub faulty_ticks: u64,
    /// Adapter only: failed learning episodes.
    pub failed_episodes: u64,
}

impl fmt::Display for Tally {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} operations, {} built ({} refused at construction), {} asks, {} accepted tells, \
             {} refused calls, {} runs stopped",
            self.operations,
            self.built,
            self.refused_constructions,
            self.asks,
            self.accepted_tells,
            self.refused_calls,
            self.stopped
        )?;
        if self.faulty_ticks + self.failed_episodes > 0 {
            write!(
                f,
                ", {} faulty ticks, {} failed episodes",
                self.faulty_ticks, self.failed_episodes
            )?;
        }
        Ok(())
    }
}

/// A value from the corners of `f32`: NaN, ±∞, ±`f32::MAX`, subnormals, ±0, values near 1
/// and wide-ranging ordinary values; any bit pattern now and then.
pub fn adversarial_f32(rng: &mut impl RngCore) -> f32 {
    match rng.next_u32() % 12 {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::NEG_INFINITY,
        3 => f32::MAX,
        4 => -f32::MAX,
        5 => f32::from_bits(1 + rng.next_u32() % 0x007f_ffff), // a positive subnormal
        6 => -f32::from_bits(1 + rng.next_u32() % 0x007f_ffff),
        7 => 0.0,
        8 => -0.0,
        9 => f32::from_bits(rng.next_u32()), // any pattern, NaN payloads included
        10 => 1.0 + unit(rng) * 1e-6,
        _ => (unit(rng) - 0.5) * 10f32.powi((rng.next_u32() % 16) as i32 - 4),
    }
}

/// An adversarial or ordinary value for a configuration field whose default is `default`:
/// kept three times in four (so that most configurations are valid and get driven), else a
/// corner of `f32` or a scaled default.
pub fn field(rng: &mut impl RngCore, default: f32) -> f32 {
    match rng.next_u32() % 16 {
        0..=11 => default,
        12 => default * (0.1 + 10.0 * unit(rng)),
        13 => -default,
        _ => adversarial_f32(rng),
    }
}

/// A count for a configuration field whose default is `default`: usually kept, else 0, 1,
/// a small number or `u32::MAX`.
pub fn count(rng: &mut impl RngCore, default: u32) -> u32 {
    match rng.next_u32() % 16 {
        0..=11 => default,
        12 => 0,
        13 => 1,
        14 => rng.next_u32() % 8,
        _ => u32::MAX,
    }
}

/// A cap on the work of one call (CRS's redraws, ROCK*'s descent steps): usually
/// `default`, else 0, 1, a small number or 1,000. Not `u32::MAX`: that is a valid setting
/// whose call then runs as long as it was told to, which a driver of a million operations
/// cannot wait for (the caps' documentation says so).
pub fn cap(rng: &mut impl RngCore, default: u32) -> u32 {
    match rng.next_u32() % 16 {
        0..=11 => default,
        12 => 0,
        13 => 1,
        14 => rng.next_u32() % 8,
        _ => 1000,
    }
}

/// A budget: small (so that runs end and restart often), occasionally 0 or unlimited.
pub fn budget(rng: &mut impl RngCore) -> u32 {
    match rng.next_u32() % 20 {
        0 => 0,
        1 => u32::MAX,
        _ => 1 + rng.next_u32() % 300,
    }
}

/// A uniform draw in [0, 1).
fn unit(rng: &mut impl RngCore) -> f32 {
    (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32
}

/// A box with coordinates of every kind: ordinary, a few ulps wide, subnormal, far from the
/// origin, nearly `f32::MAX` wide; and now and then an invalid one (NaN, inverted, empty,
/// overflowing width), which construction must refuse.
pub fn adversarial_bounds<const N: usize>(rng: &mut impl RngCore) -> Result<Bounds<N>, Error> {
    let mut lower = Vector::<N>::zeros();
    let mut upper = Vector::<N>::zeros();
    for i in 0..N {
        let (lo, hi) = match rng.next_u32() % 10 {
            0 => {
                let lo = (unit(rng) - 0.5) * 1e3;
                let ulps = 1 + rng.next_u32() % 4;
                (lo, f32::from_bits(step_up(lo.to_bits(), lo, ulps)))
            }
            1 => (0.0, f32::from_bits(1 + rng.next_u32() % 100)), // subnormal width
            2 => {
                let lo = 1e30 * (unit(rng) + 0.5);
                (lo, lo * 1.001)
            }
            3 => (-f32::MAX / 2.0, f32::MAX / 2.0),
            4 if rng.next_u32().is_multiple_of(8) => (adversarial_f32(rng), adversarial_f32(rng)),
            _ => {
                let lo = (unit(rng) - 0.5) * 20.0;
                (lo, lo + 0.01 + unit(rng) * 20.0)
            }
        };
        lower[i] = lo;
        upper[i] = hi;
    }
    Bounds::try_new(lower, upper)
}

/// The bits of the f32 `ulps` steps above `value` (whose bits are `bits`), towards +∞.
fn step_up(bits: u32, value: f32, ulps: u32) -> u32 {
    if value == 0.0 {
        ulps
    } else if value > 0.0 {
        bits + ulps
    } else {
        bits - ulps
    }
}

/// A point of the box, at a corner, on a face or inside, for starts and fixed θ.
pub fn point_in<const N: usize>(rng: &mut impl RngCore, bounds: &Bounds<N>) -> Vector<N> {
    Vector::from_fn(|i, _| {
        let (lo, hi) = (bounds.lower()[i], bounds.upper()[i]);
        match rng.next_u32() % 4 {
            0 => lo,
            1 => hi,
            _ => (lo + unit(rng) * (hi - lo)).min(hi),
        }
    })
}

/// A cost for the candidate `theta`: adversarial one time in three, a plateau one time in
/// six, else the sphere ‖θ‖² (scaled into range) so that the searches move.
fn adversarial_cost<const N: usize>(
    rng: &mut impl RngCore,
    theta: &Vector<N>,
    plateau: f32,
) -> f32 {
    match rng.next_u32() % 6 {
        0 | 1 => adversarial_f32(rng),
        2 => plateau,
        _ => theta
            .iter()
            .map(|v| (v * 1e-3) * (v * 1e-3))
            .sum::<f32>()
            .min(f32::MAX),
    }
}

/// Whether two states are the same, NaN fields included (`PartialEq` says NaN ≠ NaN: an
/// adapter whose shaper last saw a NaN would never equal its own copy).
fn same<T: PartialEq + fmt::Debug>(a: &T, b: &T) -> bool {
    a == b || format!("{a:?}") == format!("{b:?}")
}

/// Runs `operation` and turns a panic into a printed seed before propagating it.
fn guarded<T>(seed: u64, operation: u64, f: impl FnOnce() -> T) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(value) => value,
        Err(panic) => {
            eprintln!("adversarial driver: panic at seed {seed}, operation {operation}");
            resume_unwind(panic)
        }
    }
}

/// What the driver expects of one optimizer instance.
struct Model<const N: usize> {
    pending: Option<Vector<N>>,
    evaluations: u32,
    /// The lowest cost told and every candidate told exactly that cost.
    lowest: Option<(f32, Vec<Vector<N>>)>,
    /// The conditions the optimizer measures in now, and whether nothing was told in them.
    conditions: u8,
    fresh_conditions: bool,
}

impl<const N: usize> Model<N> {
    fn new() -> Self {
        Self {
            pending: None,
            evaluations: 0,
            lowest: None,
            conditions: 0,
            fresh_conditions: false,
        }
    }
}

/// One construction of the drivers: a box (valid or not), a budget, and what `build`
/// makes of them, counted in `tally`; `None` when either was refused.
fn construct<const N: usize, O>(
    rng: &mut DriverRng,
    seed: u64,
    op: u64,
    tally: &mut Tally,
    build: &mut impl FnMut(&mut DriverRng, Bounds<N>, u32) -> Result<O, Error>,
) -> Option<(Bounds<N>, u32, O)> {
    let built = adversarial_bounds::<N>(rng).and_then(|bounds| {
        let limit = budget(rng);
        guarded(seed, op, || build(rng, bounds, limit)).map(|o| (bounds, limit, o))
    });
    match built {
        Ok(built) => {
            tally.built += 1;
            Some(built)
        }
        Err(_) => {
            tally.refused_constructions += 1;
            None
        }
    }
}

/// Drives optimizers built by `build` (from the driver's RNG, a box, and a budget) for
/// `operations` operations from `seed`, checking the contract after every one (module docs).
/// `budget_of` reads back the budget an optimizer was built with, for the evaluations
/// check.
pub fn drive<const N: usize, O>(
    seed: u64,
    operations: u64,
    build: impl FnMut(&mut DriverRng, Bounds<N>, u32) -> Result<O, Error>,
) -> Result<Tally, Violation>
where
    O: Optimizer<N> + Clone + PartialEq + fmt::Debug,
{
    drive_in_conditions(seed, operations, build, |_| 0)
}

/// [`drive`] for an optimizer whose costs come from changing conditions: `conditions` names
/// the ones it measures in now (e.g. a `TwoPhase`'s phase). When they change, costs told
/// before no longer rank against costs told after: `best` must be the lowest cost told in
/// the new conditions once one is, and until then the best of the conditions before.
pub fn drive_in_conditions<const N: usize, O>(
    seed: u64,
    operations: u64,
    mut build: impl FnMut(&mut DriverRng, Bounds<N>, u32) -> Result<O, Error>,
    conditions: impl Fn(&O) -> u8,
) -> Result<Tally, Violation>
where
    O: Optimizer<N> + Clone + PartialEq + fmt::Debug,
{
    let mut rng = DriverRng::seed_from_u64(seed);
    let mut tally = Tally::default();
    let mut op = 0u64;
    let fail = |op: u64, message: String| Violation {
        seed,
        operation: op,
        message,
    };
    'build: while op < operations {
        // Construction: boxes and configurations, valid or not.
        op += 1;
        tally.operations += 1;
        let Some((bounds, limit, mut o)) = construct(&mut rng, seed, op, &mut tally, &mut build)
        else {
            continue;
        };
        if o.bounds() != &bounds {
            return Err(fail(
                op,
                format!("bounds {:?} became {:?}", bounds, o.bounds()),
            ));
        }
        let mut model = Model::<N>::new();
        model.conditions = conditions(&o);
        let mut plateau = adversarial_cost(&mut rng, &Vector::<N>::zeros(), 1.0);
        if !plateau.is_finite() {
            plateau = 1.0;
        }
        let mut stopped_asks = 0;
        while op < operations {
            op += 1;
            tally.operations += 1;
            let choice = rng.next_u32() % 100;
            if choice == 0 {
                continue 'build; // abandon this one, build another
            }
            if choice < 55 {
                // ask (a repeat when a candidate is pending)
                let before = o.clone();
                let result = guarded(seed, op, || o.ask(&mut rng));
                match result {
                    Ok(theta) => {
                        tally.asks += 1;
                        if !theta.iter().all(|v| v.is_finite()) || !o.bounds().contains(&theta) {
                            return Err(fail(
                                op,
                                format!("candidate {theta:?} outside {:?}", o.bounds()),
                            ));
                        }
                        if let Some(p) = model.pending
                            && p != theta
                        {
                            return Err(fail(
                                op,
                                format!("ask with {p:?} pending returned {theta:?}"),
                            ));
                        }
                        if before.status() != Status::Running && model.pending.is_none() {
                            return Err(fail(
                                op,
                                format!("ask succeeded with status {:?}", before.status()),
                            ));
                        }
                        model.pending = Some(theta);
                    }
                    Err(e) => {
                        tally.refused_calls += 1;
                        if e != Error::Stopped {
                            return Err(fail(op, format!("ask failed with {e:?}")));
                        }
                        if before.status() == Status::Running {
                            // The one documented way: a search that finds no new point in
                            // its box (SRACOS and RACOS on a box a few f32 steps wide, every
                            // point stored) stops itself as converged; nothing else changes.
                            let exhausted = o.status() == Status::Converged
                                && o.evaluations() == before.evaluations()
                                && o.best() == before.best()
                                && model.pending.is_none();
                            if !exhausted {
                                return Err(fail(op, "ask refused while running".into()));
                            }
                        } else if !same(&o, &before) {
                            return Err(fail(op, "a refused ask changed the state".into()));
                        }
                        stopped_asks += 1;
                        if stopped_asks > 3 {
                            tally.stopped += 1;
                            continue 'build;
                        }
                    }
                }
            } else {
                // tell, with or without a candidate pending
                let cost = match model.pending {
                    Some(theta) => adversarial_cost(&mut rng, &theta, plateau),
                    None => adversarial_f32(&mut rng),
                };
                let before = o.clone();
                let result = guarded(seed, op, || o.tell(cost));
                let expected = match model.pending {
                    None => Err(Error::NoPendingAsk),
                    Some(_) if !cost.is_finite() => Err(Error::NonFinite("cost")),
                    Some(_) => Ok(()),
                };
                if result != expected {
                    return Err(fail(
                        op,
                        format!("tell({cost:e}) returned {result:?}, expected {expected:?}"),
                    ));
                }
                if result.is_err() {
                    tally.refused_calls += 1;
                    if !same(&o, &before) {
                        return Err(fail(
                            op,
                            format!("a refused tell({cost:e}) changed the state"),
                        ));
                    }
                } else {
                    tally.accepted_tells += 1;
                    let theta = model.pending.take().unwrap_or_else(Vector::zeros);
                    model.evaluations += 1;
                    match &mut model.lowest {
                        _ if model.fresh_conditions => model.lowest = Some((cost, vec![theta])),
                        Some((c, thetas)) if cost == *c => thetas.push(theta),
                        Some((c, _)) if cost > *c => {}
                        _ => model.lowest = Some((cost, vec![theta])),
                    }
                    model.fresh_conditions = false;
                }
            }
            let now = conditions(&o);
            if now != model.conditions {
                model.conditions = now;
                model.fresh_conditions = true;
            }
            // The state after every operation.
            if o.pending() != model.pending.as_ref() {
                return Err(fail(
                    op,
                    format!("pending {:?}, expected {:?}", o.pending(), model.pending),
                ));
            }
            if o.evaluations() != model.evaluations {
                return Err(fail(
                    op,
                    format!(
                        "{} evaluations, {} accepted",
                        o.evaluations(),
                        model.evaluations
                    ),
                ));
            }
            if model.evaluations > limit {
                return Err(fail(
                    op,
                    format!("{} evaluations over a budget of {limit}", model.evaluations),
                ));
            }
            if model.evaluations == limit && o.status() == Status::Running {
                return Err(fail(
                    op,
                    format!("still running after its budget of {limit}"),
                ));
            }
            match (o.best(), &model.lowest) {
                (None, None) => {}
                (Some(b), Some((c, thetas))) => {
                    if b.cost != *c {
                        return Err(fail(
                            op,
                            format!("best cost {:e}, lowest told {c:e}", b.cost),
                        ));
                    }
                    if !thetas.contains(&b.theta) {
                        return Err(fail(op, format!("best θ {:?} was not told {c:e}", b.theta)));
                    }
                }
                (b, l) => return Err(fail(op, format!("best {b:?}, lowest told {l:?}"))),
            }
        }
    }
    Ok(tally)
}

/// [`drive`] for several candidates in flight: the optimizer built by `build` is wrapped in
/// an [`InFlight`] with room for `C`, and the driver mixes `suggest`, `report` (of an
/// outstanding ticket, a made-up one, a non-finite cost), `cancel`, and the sequential
/// `ask`/`tell` through the wrapper. After every operation it checks:
///
/// * candidates are finite and inside the bounds; a cancelled candidate comes back before a
///   new one; `suggest` returns a candidate exactly when the capacity it announced was > 0,
///   and fails only with `Stopped` (stopped search, or SRACOS's exhausted box) or
///   `CandidatePending` (a sequential `ask` pending);
/// * a refused call (unknown ticket, non-finite cost, `ask`/`tell` with tickets out, ...)
///   answers with its error and changes nothing;
/// * the outstanding tickets are those handed out and neither reported nor cancelled, never
///   more than `max_in_flight`;
/// * `evaluations` never exceeds the budget, and a search at its budget is not running;
/// * whenever the wrapper is idle, `evaluations` counts every accepted cost and, with
///   `strict_best`, the best cost is the lowest of them (TwoPhase changes conditions: then
///   only that the best cost is one of them).
pub fn drive_in_flight<const N: usize, O, const C: usize>(
    seed: u64,
    operations: u64,
    strict_best: bool,
    mut build: impl FnMut(&mut DriverRng, Bounds<N>, u32) -> Result<O, Error>,
) -> Result<Tally, Violation>
where
    O: Generation<N> + Clone + PartialEq + fmt::Debug,
{
    let mut rng = DriverRng::seed_from_u64(seed);
    let mut tally = Tally::default();
    let mut op = 0u64;
    let fail = |op: u64, message: String| Violation {
        seed,
        operation: op,
        message,
    };
    'build: while op < operations {
        op += 1;
        tally.operations += 1;
        let Some((bounds, limit, o)) = construct(&mut rng, seed, op, &mut tally, &mut build) else {
            continue;
        };
        let mut flight = InFlight::<O, N, C>::new(o);
        // Outstanding (ticket, θ), cancelled θs, the sequential pending θ, accepted costs.
        let mut out: Vec<(Ticket, Vector<N>)> = Vec::new();
        let mut cancelled: Vec<Vector<N>> = Vec::new();
        let mut pending: Option<Vector<N>> = None;
        let mut accepted: Vec<f32> = Vec::new();
        let mut plateau = adversarial_cost(&mut rng, &Vector::<N>::zeros(), 1.0);
        if !plateau.is_finite() {
            plateau = 1.0;
        }
        let mut stopped = 0;
        while op < operations {
            op += 1;
            tally.operations += 1;
            let before = flight.clone();
            let choice = rng.next_u32() % 100;
            if choice == 0 {
                continue 'build;
            } else if choice < 40 {
                let capacity = flight.capacity();
                match guarded(seed, op, || flight.suggest(&mut rng)) {
                    Ok(Some((ticket, theta))) => {
                        tally.asks += 1;
                        if !theta.iter().all(|v| v.is_finite()) || !bounds.contains(&theta) {
                            return Err(fail(
                                op,
                                format!("candidate {theta:?} outside {bounds:?}"),
                            ));
                        }
                        if capacity == 0 || out.iter().any(|(t, _)| *t == ticket) {
                            return Err(fail(
                                op,
                                format!("suggest with capacity {capacity} gave {ticket:?}"),
                            ));
                        }
                        if !cancelled.is_empty() {
                            let Some(i) = cancelled.iter().position(|c| *c == theta) else {
                                return Err(fail(
                                    op,
                                    format!(
                                        "a new candidate {theta:?} before the cancelled {cancelled:?}"
                                    ),
                                ));
                            };
                            cancelled.swap_remove(i);
                        }
                        out.push((ticket, theta));
                    }
                    Ok(None) => {
                        if capacity != 0 || !same(&flight, &before) {
                            return Err(fail(
                                op,
                                format!("suggest gave nothing with capacity {capacity}"),
                            ));
                        }
                    }
                    Err(e) => {
                        tally.refused_calls += 1;
                        let expected = match e {
                            Error::CandidatePending => pending.is_some(),
                            Error::Stopped => {
                                before.status() != Status::Running
                                    || (flight.status() == Status::Converged
                                        && flight.evaluations() == before.evaluations())
                            }
                            _ => false,
                        };
                        if !expected {
                            return Err(fail(op, format!("suggest failed with {e:?}")));
                        }
                        if e == Error::Stopped {
                            stopped += 1;
                            if stopped > 3 {
                                tally.stopped += 1;
                                continue 'build;
                            }
                        }
                    }
                }
            } else if choice < 80 {
                // report (mostly an outstanding ticket) or cancel
                let pick = (!out.is_empty() && rng.next_u32() % 8 != 0)
                    .then(|| rng.next_u32() as usize % out.len());
                let ticket = pick.map_or(Ticket::new(rng.next_u32()), |i| out[i].0);
                let known = out.iter().position(|(t, _)| *t == ticket);
                if rng.next_u32() % 10 == 0 {
                    let result = flight.cancel(ticket);
                    match (result, known) {
                        (Ok(()), Some(i)) => cancelled.push(out.swap_remove(i).1),
                        (Err(Error::UnknownTicket), None) if same(&flight, &before) => {
                            tally.refused_calls += 1;
                        }
                        (r, _) => return Err(fail(op, format!("cancel({ticket:?}) gave {r:?}"))),
                    }
                    continue;
                }
                let cost = match known {
                    Some(i) => adversarial_cost(&mut rng, &out[i].1, plateau),
                    None => adversarial_f32(&mut rng),
                };
                let result = guarded(seed, op, || flight.report(ticket, cost));
                let expected = match known {
                    None => Err(Error::UnknownTicket),
                    Some(_) if !cost.is_finite() => Err(Error::NonFinite("cost")),
                    Some(_) => Ok(()),
                };
                if result != expected {
                    return Err(fail(
                        op,
                        format!(
                            "report({ticket:?}, {cost:e}) gave {result:?}, expected {expected:?}"
                        ),
                    ));
                }
                match (result, known) {
                    (Ok(()), Some(i)) => {
                        out.swap_remove(i);
                        accepted.push(cost);
                        tally.accepted_tells += 1;
                    }
                    _ => {
                        tally.refused_calls += 1;
                        if !same(&flight, &before) {
                            return Err(fail(op, "a refused report changed the state".into()));
                        }
                    }
                }
            } else {
                // the sequential calls through the wrapper
                let idle = before.idle();
                if rng.next_u32() % 2 == 0 {
                    match guarded(seed, op, || flight.ask(&mut rng)) {
                        Ok(theta)
                            if idle
                                && bounds.contains(&theta)
                                && pending.is_none_or(|p| p == theta) =>
                        {
                            pending = Some(theta)
                        }
                        Err(Error::InFlight) if !idle && same(&flight, &before) => {
                            tally.refused_calls += 1;
                        }
                        Err(Error::Stopped) if idle => tally.refused_calls += 1,
                        r => return Err(fail(op, format!("ask gave {r:?} (idle: {idle})"))),
                    }
                } else {
                    let cost = adversarial_f32(&mut rng);
                    let result = guarded(seed, op, || flight.tell(cost));
                    let expected = if !idle {
                        Err(Error::InFlight)
                    } else if pending.is_none() {
                        Err(Error::NoPendingAsk)
                    } else if !cost.is_finite() {
                        Err(Error::NonFinite("cost"))
                    } else {
                        Ok(())
                    };
                    if result != expected {
                        return Err(fail(
                            op,
                            format!("tell({cost:e}) gave {result:?}, expected {expected:?}"),
                        ));
                    }
                    if result.is_ok() {
                        pending = None;
                        accepted.push(cost);
                        tally.accepted_tells += 1;
                    } else {
                        tally.refused_calls += 1;
                        if !same(&flight, &before) {
                            return Err(fail(op, "a refused tell changed the state".into()));
                        }
                    }
                }
            }
            // The state after every operation.
            let tickets: Vec<Ticket> = flight.in_flight().collect();
            if tickets.len() != out.len() || out.iter().any(|(t, _)| !tickets.contains(t)) {
                return Err(fail(op, format!("tickets {tickets:?}, expected {out:?}")));
            }
            if tickets.len() > flight.max_in_flight() {
                return Err(fail(
                    op,
                    format!(
                        "{} in flight, at most {}",
                        tickets.len(),
                        flight.max_in_flight()
                    ),
                ));
            }
            let evaluations = flight.evaluations();
            if evaluations > limit || (evaluations == limit && flight.status() == Status::Running) {
                return Err(fail(
                    op,
                    format!(
                        "{evaluations} evaluations, budget {limit}, {:?}",
                        flight.status()
                    ),
                ));
            }
            if flight.idle() {
                if evaluations as usize != accepted.len() {
                    return Err(fail(
                        op,
                        format!("{evaluations} evaluations, {} accepted", accepted.len()),
                    ));
                }
                let lowest = accepted.iter().copied().reduce(f32::min);
                let best = flight.best().map(|b| b.cost);
                let fine = match (best, lowest) {
                    (None, None) => true,
                    (Some(b), Some(l)) => {
                        if strict_best {
                            b == l
                        } else {
                            accepted.contains(&b)
                        }
                    }
                    _ => false,
                };
                if !fine {
                    return Err(fail(
                        op,
                        format!("best {best:?}, lowest accepted {lowest:?}"),
                    ));
                }
            }
        }
    }
    Ok(tally)
}

/// A shaper whose cost is the last observation (so the driver chooses each episode's cost,
/// NaN and ∞ included); its cost before any observation is 0.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LastObservation(f32);

impl ctrl_adapt::record::Persistent for LastObservation {
    const SHAPE: ctrl_adapt::record::Shape = ctrl_adapt::record::Shape::new(*b"LAST", &[]);

    /// Any observation is one (NaN included: the shaper reports it as the cost).
    fn validate(&self) -> Result<(), Error> {
        Ok(())
    }
}

impl Shaper for LastObservation {
    type Observation = f32;
    fn reset(&mut self) {
        self.0 = 0.0;
    }
    fn observe(&mut self, observation: &f32, _dt: f32) {
        self.0 = *observation;
    }
    fn cost(&self) -> f32 {
        self.0
    }
    fn skipped(&self) -> u32 {
        0
    }
}

/// The adapter's controller in the driver: one axis, PD limit 2, correction envelope 0.5.
pub type DriverController = CorrectedPd<1, 2, 2, 2, StateFeatures<2>>;

/// The PD's output limit and the correction envelope of [`DriverController`].
pub const ACTION_LIMIT: f32 = 2.0;
/// See [`ACTION_LIMIT`].
pub const ENVELOPE: f32 = 0.5;

fn driver_controller() -> DriverController {
    let pd = Pd::<1>::try_new(Vector::repeat(3.0), Vector::repeat(0.7))
        .and_then(|pd| pd.with_limit(Vector::repeat(ACTION_LIMIT)))
        .expect("valid PD");
    let policy = LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(ENVELOPE))
        .expect("valid policy");
    CorrectedPd::new(pd, policy)
}

/// Drives adapters around optimizers built by `build` (module docs), from `seed`, for
/// `operations` operations.
pub fn drive_adapter<O>(
    seed: u64,
    operations: u64,
    mut build: impl FnMut(&mut DriverRng, Bounds<2>, u32) -> Result<O, Error>,
) -> Result<Tally, Violation>
where
    O: Optimizer<2> + Clone + PartialEq + fmt::Debug,
{
    type A<O> = Adapter<O, DriverController, LastObservation, 2, 2, 1>;
    let mut rng = DriverRng::seed_from_u64(seed);
    let mut tally = Tally::default();
    let mut op = 0u64;
    let fail = |op: u64, message: String| Violation {
        seed,
        operation: op,
        message,
    };
    'build: while op < operations {
        op += 1;
        tally.operations += 1;
        let Ok(bounds) = adversarial_bounds::<2>(&mut rng) else {
            tally.refused_constructions += 1;
            continue;
        };
        let limit = budget(&mut rng);
        let Ok(optimizer) = guarded(seed, op, || build(&mut rng, bounds, limit)) else {
            tally.refused_constructions += 1;
            continue;
        };
        let config = AdapterConfig {
            dt: field(&mut rng, 0.05),
            failure_cost: field(&mut rng, 50.0),
            max_faulty_ticks: count(&mut rng, 3),
            learning_episodes: count(&mut rng, 40),
        };
        let initial = if rng.next_u32().is_multiple_of(8) {
            Vector::from_fn(|_, _| adversarial_f32(&mut rng))
        } else {
            point_in(&mut rng, &bounds)
        };
        let built: Result<A<O>, Error> = guarded(seed, op, || {
            Adapter::try_new(
                optimizer,
                driver_controller(),
                LastObservation(0.0),
                config,
                initial,
            )
        });
        let mut adapter = match built {
            Ok(a) => a,
            Err(_) => {
                if config.validate().is_ok() && bounds.check(&initial, "initial").is_ok() {
                    return Err(fail(op, format!("a valid adapter was refused: {config:?}")));
                }
                tally.refused_constructions += 1;
                continue;
            }
        };
        if config.validate().is_err() {
            return Err(fail(
                op,
                format!("an invalid configuration was accepted: {config:?}"),
            ));
        }
        tally.built += 1;
        // The episode in progress: θ, mode, ticks, faulty ticks, as the driver counts them.
        let mut episode: Option<(Vector<2>, Mode, u32, u32)> = None;
        let mut learned = 0u32;
        let mut controller = driver_controller();
        while op < operations {
            op += 1;
            tally.operations += 1;
            let choice = rng.next_u32() % 100;
            let before = adapter.clone();
            let refused =
                |result: Result<(), AdapterError>, adapter: &A<O>| -> Result<bool, String> {
                    match result {
                        Ok(()) => Ok(false),
                        Err(e) if same(adapter, &before) => {
                            let _ = e;
                            Ok(true)
                        }
                        Err(e) => Err(format!("a refused call ({e:?}) changed the adapter")),
                    }
                };
            if choice == 0 {
                continue 'build;
            } else if choice < 8 {
                // begin an episode
                let mode = adapter.mode();
                let result = guarded(seed, op, || adapter.begin_episode(&mut rng));
                match (result, episode) {
                    (Ok(_), Some(_)) => return Err(fail(op, "began an episode inside one".into())),
                    (Err(e), None) => {
                        return Err(fail(op, format!("begin_episode refused: {e:?}")));
                    }
                    (Ok(theta), None) => {
                        if !adapter.optimizer().bounds().contains(&theta)
                            && adapter.mode() != Mode::Nominal
                        {
                            return Err(fail(op, format!("episode θ {theta:?} outside the box")));
                        }
                        if mode == Mode::Learn
                            && adapter.mode() == Mode::Learn
                            && learned >= config.learning_episodes
                        {
                            return Err(fail(op, "learning past learning_episodes".into()));
                        }
                        let deployed = adapter.optimizer().best().map_or(initial, |b| b.theta);
                        if adapter.mode() == Mode::Deploy && theta != deployed {
                            return Err(fail(op, format!("deployed {theta:?}, best {deployed:?}")));
                        }
                        tally.asks += u64::from(adapter.mode() == Mode::Learn);
                        episode = Some((theta, adapter.mode(), 0, 0));
                    }
                    (Err(_), _) => {
                        tally.refused_calls += 1;
                        if !same(&adapter, &before) {
                            return Err(fail(
                                op,
                                "a refused begin_episode changed the adapter".into(),
                            ));
                        }
                    }
                }
            } else if choice < 10 {
                // a fixed θ, inside the box or not
                let theta = if rng.next_u32().is_multiple_of(3) {
                    Vector::from_fn(|_, _| adversarial_f32(&mut rng))
                } else {
                    point_in(&mut rng, &bounds)
                };
                let result = guarded(seed, op, || adapter.begin_fixed_episode(theta));
                let should = episode.is_none() && bounds.check(&theta, "theta").is_ok();
                match refused(result, &adapter) {
                    Ok(true) if !should => tally.refused_calls += 1,
                    Ok(false) if should => episode = Some((theta, Mode::Deploy, 0, 0)),
                    Ok(r) => {
                        return Err(fail(
                            op,
                            format!(
                                "begin_fixed_episode({theta:?}) refused = {r}, expected {}",
                                !should
                            ),
                        ));
                    }
                    Err(m) => return Err(fail(op, m)),
                }
            } else if choice < 14 {
                // end or abort
                let abort = rng.next_u32().is_multiple_of(3);
                let result = guarded(seed, op, || {
                    if abort {
                        adapter.abort_episode()
                    } else {
                        adapter.end_episode()
                    }
                });
                match (result, episode.take()) {
                    (Err(AdapterError::NoEpisode), None) => {
                        tally.refused_calls += 1;
                        if !same(&adapter, &before) {
                            return Err(fail(op, "a refused end changed the adapter".into()));
                        }
                    }
                    (Ok(report), Some((theta, mode, ticks, faulty))) => {
                        if (report.theta, report.mode, report.ticks, report.faulty_ticks)
                            != (theta, mode, ticks, faulty)
                        {
                            return Err(fail(
                                op,
                                format!(
                                    "report {report:?}, expected θ {theta:?}, {mode:?}, {ticks} ticks, {faulty} faulty"
                                ),
                            ));
                        }
                        let failed =
                            abort || !report.cost.is_finite() || faulty > config.max_faulty_ticks;
                        if report.failed != failed {
                            return Err(fail(
                                op,
                                format!("failed = {}, expected {failed}", report.failed),
                            ));
                        }
                        let told = (mode == Mode::Learn).then_some({
                            if failed {
                                config.failure_cost
                            } else {
                                report.cost
                            }
                        });
                        if report.told != told {
                            return Err(fail(
                                op,
                                format!("told {:?}, expected {told:?}", report.told),
                            ));
                        }
                        if told.is_some() {
                            learned += 1;
                            tally.accepted_tells += 1;
                            tally.failed_episodes += u64::from(failed);
                            if adapter.learning_episodes() != learned {
                                return Err(fail(op, "learning episodes miscounted".into()));
                            }
                        }
                        tally.faulty_ticks += u64::from(faulty);
                    }
                    (r, e) => {
                        return Err(fail(op, format!("end returned {r:?} with episode {e:?}")));
                    }
                }
            } else if choice < 16 {
                let mode =
                    [Mode::Learn, Mode::Deploy, Mode::Nominal][(rng.next_u32() % 3) as usize];
                let result = guarded(seed, op, || adapter.set_mode(mode));
                match refused(result, &adapter) {
                    Ok(true) if episode.is_some() => tally.refused_calls += 1,
                    Ok(false) if episode.is_none() && adapter.mode() == mode => {}
                    Ok(r) => {
                        return Err(fail(
                            op,
                            format!("set_mode refused = {r} with episode {episode:?}"),
                        ));
                    }
                    Err(m) => return Err(fail(op, m)),
                }
            } else {
                // a control tick
                let state = if rng.next_u32().is_multiple_of(4) {
                    Vector::<2>::from_fn(|_, _| adversarial_f32(&mut rng))
                } else {
                    Vector::<2>::from_fn(|_, _| (unit(&mut rng) - 0.5) * 4.0)
                };
                let observation = if rng.next_u32().is_multiple_of(10) {
                    adversarial_f32(&mut rng)
                } else {
                    unit(&mut rng)
                };
                let action = guarded(seed, op, || adapter.control(&state, &observation));
                let u = action[0];
                if !u.is_finite() || u.abs() > ACTION_LIMIT {
                    return Err(fail(op, format!("action {u:e} for state {state:?}")));
                }
                let nominal = controller.nominal(&state, 0.0)[0];
                let corrected = matches!(episode, Some((_, Mode::Learn | Mode::Deploy, _, _)));
                let allowed = if corrected {
                    ENVELOPE * (1.0 + 1e-6)
                } else {
                    0.0
                };
                if nominal.is_finite() && (u - nominal).abs() > allowed {
                    return Err(fail(
                        op,
                        format!(
                            "action {u:e} is {:e} from the nominal {nominal:e}",
                            u - nominal
                        ),
                    ));
                }
                if let Some((theta, mode, ticks, faulty)) = &mut episode {
                    let state_ok = state.iter().all(|v| v.is_finite());
                    let time = *ticks as f32 * config.dt;
                    let proposed = match mode {
                        Mode::Nominal => controller.nominal(&state, time),
                        _ => controller.corrected(theta, &state, time),
                    };
                    if !state_ok || !proposed.iter().all(|v| v.is_finite()) {
                        *faulty += 1;
                    }
                    *ticks += 1;
                }
            }
            if adapter.in_episode() != episode.is_some() {
                return Err(fail(
                    op,
                    "the adapter's episode and the driver's differ".into(),
                ));
            }
        }
    }
    Ok(tally)
}

/// What [`drive_guarded_adapter`] counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GuardTally {
    /// Operations run.
    pub operations: u64,
    /// Guarded adapters built (guard configurations refused are not counted).
    pub built: u64,
    /// Guard configurations refused.
    pub refused_guards: u64,
    /// Episodes ended, and of them tripped by a limit and by the envelope.
    pub episodes: u64,
    /// See [`GuardTally::episodes`].
    pub limit_trips: u64,
    /// See [`GuardTally::episodes`].
    pub envelope_trips: u64,
    /// Records saved and loaded back mid-run.
    pub round_trips: u64,
}

/// The guarded adapter in the driver: two limits, an 8-tick envelope.
type GuardedDriverAdapter<O> =
    Adapter<O, DriverController, LastObservation, 2, 2, 1, ctrl_adapt::controller::Guard<2, 8>>;

/// Drives adapters with a runtime guard (random limits on a state coordinate and on a
/// signal, random hysteresis and margins, NaN and infinities included; one in eight with no
/// margin left at the last tick and margins that overflow f32) around a coordinate
/// search: episodes in every mode, ticks with adversarial states, signals (short ones
/// included) and running costs, aborts, and save/load of the record mid-episode. Checks,
/// besides panic freedom:
///
/// * every action finite, within the PD's limit and the correction envelope of the nominal;
/// * a trip only in a learning or deployed episode, at a tick it ran; from that tick on,
///   every action the nominal action (or the safe action, zero, when that is not finite);
/// * a limit trip exactly at the first tick ending `limit_ticks` consecutive ticks beyond
///   some limit, unless the envelope tripped earlier; an envelope trip exactly at the first
///   tick ending `envelope_ticks` consecutive ticks whose running cost is not at most the
///   guard's threshold (NaN is above), unless a limit trip was due by then; no trip when
///   neither was due; the threshold never NaN; `ticks_beyond_limits` the ticks beyond a
///   limit;
/// * a tripped learning episode told [`tripped_cost`], above the failure cost; the guard's
///   counters the sums of the reports; the record loads back equal.
///
/// [`tripped_cost`]: ctrl_adapt::controller::guard::tripped_cost
pub fn drive_guarded_adapter(seed: u64, operations: u64) -> Result<GuardTally, Violation> {
    use ctrl_adapt::controller::guard::{
        Guard, GuardConfig, Limit, Source, TripReason, tripped_cost,
    };
    use ctrl_adapt::optimizer::{CoordinateConfig, CoordinateSearch};

    let mut rng = DriverRng::seed_from_u64(seed);
    let mut tally = GuardTally::default();
    let mut op = 0u64;
    let fail = |op: u64, message: String| Violation {
        seed,
        operation: op,
        message,
    };
    let bounds = Bounds::<2>::uniform(-1.0, 1.0).expect("valid box");
    'build: while op < operations {
        op += 1;
        tally.operations += 1;
        let limit = |rng: &mut DriverRng, k: u16| {
            let a = field(rng, -1.0);
            let b = field(rng, 1.0);
            Limit {
                source: if k == 0 {
                    Source::State((rng.next_u32() % 3) as u16)
                } else {
                    Source::Signal((rng.next_u32() % 2) as u16)
                },
                low: a.min(b),
                high: if rng.next_u32().is_multiple_of(10) {
                    a
                } else {
                    a.max(b)
                },
            }
        };
        let mut config = GuardConfig {
            limits: [limit(&mut rng, 0), limit(&mut rng, 1)],
            limit_ticks: count(&mut rng, 2).min(5),
            envelope_ticks: count(&mut rng, 2).min(5),
            relative_margin: field(&mut rng, 0.1),
            absolute_margin: field(&mut rng, 0.05),
            margin_taper: field(&mut rng, 0.5),
            tripped_cost_span: field(&mut rng, 10.0),
        };
        if rng.next_u32().is_multiple_of(8) {
            // No margin at the last tick, and margins that overflow f32 on a large
            // envelope (weight 0 times an infinite margin was a NaN threshold).
            const HUGE: [f32; 4] = [10.0, 1e30, f32::MAX, 0.0];
            config.margin_taper = 0.0;
            config.relative_margin = HUGE[(rng.next_u32() % 4) as usize];
            config.absolute_margin = HUGE[(rng.next_u32() % 4) as usize];
        }
        let failure_cost = 50.0;
        let adapter_config = AdapterConfig {
            dt: 0.05,
            failure_cost,
            max_faulty_ticks: 3,
            learning_episodes: 40,
        };
        let search = CoordinateSearch::try_new(
            bounds,
            Vector::zeros(),
            CoordinateConfig {
                max_evaluations: 60,
                ..CoordinateConfig::DEFAULT
            },
        )
        .expect("valid search");
        let built = guarded(seed, op, || {
            let adapter = Adapter::try_new(
                search,
                driver_controller(),
                LastObservation(0.0),
                adapter_config,
                Vector::zeros(),
            )
            .map_err(AdapterError::from)?;
            let guard = Guard::<2, 8>::try_new(config)?;
            adapter.with_guard(guard)
        });
        let fits = config.validate().is_ok()
            && !matches!(config.limits[0].source, Source::State(k) if k >= 2)
            && (failure_cost + config.tripped_cost_span).is_finite()
            && failure_cost + config.tripped_cost_span > failure_cost;
        let mut adapter: GuardedDriverAdapter<_> = match built {
            Ok(a) if fits => a,
            Err(_) if !fits => {
                tally.refused_guards += 1;
                continue;
            }
            Ok(_) => {
                return Err(fail(
                    op,
                    format!("an invalid guard was accepted: {config:?}"),
                ));
            }
            Err(e) => {
                return Err(fail(
                    op,
                    format!("a valid guard was refused ({e:?}): {config:?}"),
                ));
            }
        };
        tally.built += 1;
        let controller = driver_controller();
        // The episode: its mode, and per tick (action, nominal action, beyond a limit, above
        // the envelope's threshold).
        type Ticks = Vec<(f32, f32, bool, bool)>;
        let mut episode: Option<(Mode, Ticks)> = None;
        let (mut limit_trips, mut envelope_trips, mut beyond_total) = (0u32, 0u32, 0u32);
        while op < operations {
            op += 1;
            tally.operations += 1;
            let choice = rng.next_u32() % 100;
            if choice == 0 {
                continue 'build;
            } else if choice < 6 {
                if episode.is_none() {
                    let mode =
                        [Mode::Learn, Mode::Deploy, Mode::Nominal][(rng.next_u32() % 3) as usize];
                    adapter
                        .set_mode(mode)
                        .map_err(|e| fail(op, format!("{e:?}")))?;
                    guarded(seed, op, || adapter.begin_episode(&mut rng))
                        .map_err(|e| fail(op, format!("begin refused: {e:?}")))?;
                    episode = Some((adapter.mode(), Vec::new()));
                }
            } else if choice < 10 {
                let Some((mode, ticks)) = episode.take() else {
                    continue;
                };
                let abort = rng.next_u32().is_multiple_of(4);
                let report = guarded(seed, op, || {
                    if abort {
                        adapter.abort_episode()
                    } else {
                        adapter.end_episode()
                    }
                })
                .map_err(|e| fail(op, format!("end refused: {e:?}")))?;
                tally.episodes += 1;
                let beyond = ticks.iter().filter(|t| t.2).count() as u32;
                beyond_total += beyond;
                if report.ticks_beyond_limits != beyond || report.ticks as usize != ticks.len() {
                    return Err(fail(
                        op,
                        format!("report {report:?}, {beyond} ticks beyond"),
                    ));
                }
                // The first tick ending `limit_ticks` consecutive ticks beyond a limit, and
                // the first ending `envelope_ticks` consecutive ticks above the threshold.
                let mut run = 0;
                let due = ticks.iter().position(|t| {
                    run = if t.2 { run + 1 } else { 0 };
                    run >= config.limit_ticks
                });
                let mut run = 0;
                let envelope_due = ticks.iter().position(|t| {
                    run = if t.3 { run + 1 } else { 0 };
                    run >= config.envelope_ticks
                });
                match report.trip {
                    Some(trip) => {
                        if mode == Mode::Nominal || trip.tick as usize >= ticks.len() {
                            return Err(fail(op, format!("trip {trip:?} in {mode:?}")));
                        }
                        for (t, &(u, nominal, _, _)) in
                            ticks.iter().enumerate().skip(trip.tick as usize)
                        {
                            let expected = if nominal.is_finite() { nominal } else { 0.0 };
                            if u != expected {
                                return Err(fail(
                                    op,
                                    format!("tick {t} after the trip ran {u}, nominal {nominal}"),
                                ));
                            }
                        }
                        match trip.reason {
                            TripReason::Limit(_) => {
                                limit_trips += 1;
                                tally.limit_trips += 1;
                                if due != Some(trip.tick as usize)
                                    || envelope_due.is_some_and(|d| d < trip.tick as usize)
                                {
                                    return Err(fail(
                                        op,
                                        format!(
                                            "limit trip {trip:?}, due {due:?}, an envelope \
                                             trip due {envelope_due:?}"
                                        ),
                                    ));
                                }
                            }
                            TripReason::Envelope => {
                                envelope_trips += 1;
                                tally.envelope_trips += 1;
                                if due.is_some_and(|d| d <= trip.tick as usize) {
                                    return Err(fail(
                                        op,
                                        format!(
                                            "envelope trip {trip:?} after a due limit trip {due:?}"
                                        ),
                                    ));
                                }
                                if envelope_due != Some(trip.tick as usize) {
                                    return Err(fail(
                                        op,
                                        format!("envelope trip {trip:?}, due {envelope_due:?}"),
                                    ));
                                }
                            }
                        }
                        if mode == Mode::Learn {
                            let told = tripped_cost(
                                failure_cost,
                                config.tripped_cost_span,
                                trip.tick,
                                report.ticks,
                            );
                            if report.told != Some(told) || told <= failure_cost {
                                return Err(fail(
                                    op,
                                    format!("told {:?}, expected {told}", report.told),
                                ));
                            }
                        }
                    }
                    None => {
                        if mode != Mode::Nominal && (due.is_some() || envelope_due.is_some()) {
                            return Err(fail(
                                op,
                                format!(
                                    "no trip, a limit trip was due at {due:?}, an envelope \
                                     trip at {envelope_due:?}"
                                ),
                            ));
                        }
                    }
                }
                let c = adapter.guard().counters();
                if (c.limit_trips, c.envelope_trips, c.ticks_beyond_limits)
                    != (limit_trips, envelope_trips, beyond_total)
                {
                    return Err(fail(op, format!("counters {c:?}")));
                }
            } else if choice < 12 {
                let mut buf = vec![0u8; 4096];
                let bytes = ctrl_adapt::record::save(&adapter, &mut buf)
                    .map_err(|e| fail(op, format!("save: {e:?}")))?;
                let back: GuardedDriverAdapter<_> = ctrl_adapt::record::load(bytes)
                    .map_err(|e| fail(op, format!("load: {e:?}")))?;
                if !same(&back, &adapter) {
                    return Err(fail(op, "the record loaded back differs".into()));
                }
                tally.round_trips += 1;
            } else {
                let mut value = || {
                    if rng.next_u32().is_multiple_of(5) {
                        adversarial_f32(&mut rng)
                    } else {
                        (unit(&mut rng) - 0.5) * 4.0
                    }
                };
                let state = Vector::<2>::from_fn(|_, _| value());
                let observation = value();
                let signal = [value(), value()];
                let len = (rng.next_u32() % 3) as usize;
                let signal = &signal[..len];
                // The threshold this tick is checked against (the envelope changes only in
                // bare episodes, which are not checked): never NaN; the running cost (the
                // observation) is above it unless at most it (NaN is above).
                let tick = episode.as_ref().map_or(0, |(_, ticks)| ticks.len() as u32);
                let threshold = adapter.guard().threshold(tick);
                if threshold.is_some_and(f32::is_nan) {
                    return Err(fail(op, format!("a NaN threshold at tick {tick}")));
                }
                let within = threshold.is_none_or(|t| observation <= t);
                let action = guarded(seed, op, || {
                    adapter.control_with_signal(&state, &observation, signal)
                });
                let u = action[0];
                let nominal = controller.clone().nominal(&state, 0.0)[0];
                if !u.is_finite() || u.abs() > ACTION_LIMIT {
                    return Err(fail(op, format!("action {u:e} for state {state:?}")));
                }
                if nominal.is_finite() && (u - nominal).abs() > ENVELOPE * (1.0 + 1e-6) {
                    return Err(fail(
                        op,
                        format!("action {u:e} far from the nominal {nominal:e}"),
                    ));
                }
                if let Some((_, ticks)) = episode.as_mut() {
                    let beyond = config.limits.iter().any(|l| {
                        let v = match l.source {
                            Source::State(k) => state.get(k as usize),
                            Source::Signal(k) => signal.get(k as usize),
                        };
                        !v.is_some_and(|&v| l.low <= v && v <= l.high)
                    });
                    ticks.push((u, nominal, beyond, !within));
                }
            }
        }
    }
    Ok(tally)
}
