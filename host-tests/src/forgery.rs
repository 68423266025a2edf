//! Forged records: a real record taken mid-run, with one byte (or four) overwritten and its
//! checksum recomputed, so that only the library's validation of decoded state stands
//! between the forgery and the plant.
//!
//! [`sweep`] overwrites every byte before the checksum in turn with each of
//! [`BYTE_PATTERNS`] (and `+1`), and every run of four bytes with each of [`F32_PATTERNS`]
//! (NaN and ±∞), loads the result and tallies how it was refused, by error and field. A
//! forgery that loads is handed to a runner: [`run_optimizer`] asks and tells up to a given
//! number of steps, checking that every candidate is finite and inside the box and that the
//! best stays there; [`run_adapter`] runs episodes of control ticks, checking that every
//! learning or deployed θ lies in the optimizer's box and every action is finite, within
//! the PD's limit and within the correction envelope of the nominal action (with a runtime
//! guard and a plant model too); [`run_model_based`] proposes and tells with the
//! model-based learner, checking every proposal, the trust region and the best;
//! [`run_rls_model`] fits ticks (non-finite and huge ones among them) to a plant model,
//! checking that it stays a valid state. Broken checks and panics are counted, the first
//! one kept with the byte and the pattern.

use std::collections::BTreeMap;
use std::fmt;
use std::panic::{AssertUnwindSafe, catch_unwind};

use ctrl_adapt::controller::guard::Supervisor;
use ctrl_adapt::controller::{Adapter, Controller, Mode, Unguarded};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::model::{Affine, ModelBased, RlsModel, TickModel, Unmodelled};
use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Error, Optimizer, Vector};
use ctrl_adapt::record::{self, Persistent};
use rand_core::{RngCore, SeedableRng};

use crate::adversarial::{DriverController, DriverRng};

/// Single bytes written over each byte of a record (besides the byte plus one).
pub const BYTE_PATTERNS: [u8; 3] = [0x00, 0xff, 0x7f];

/// `f32` values written, little-endian, over each run of four bytes of a record.
pub const F32_PATTERNS: [f32; 3] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];

/// The checksum of records: CRC-32/ISCSI over everything before it, little-endian.
const CHECKSUM: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// What a sweep did with the forgeries of one record.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Forgeries {
    /// Records forged (variants equal to the original record are skipped).
    pub forged: u64,
    /// Forgeries that loaded and were run.
    pub loaded: u64,
    /// Steps (ask/tell pairs, or control ticks) the loaded forgeries ran.
    pub steps: u64,
    /// Loaded forgeries whose run broke a check or panicked.
    pub violations: u64,
    /// The first of them: the byte, the pattern and what happened.
    pub first_violation: Option<String>,
    /// Forgeries refused, by the error `load` returned (the field named, for a state that
    /// decoded but was invalid).
    pub rejected: BTreeMap<String, u64>,
}

impl Forgeries {
    /// Forgeries refused as decodable but invalid states ([`record::RecordError::Invalid`]).
    pub fn invalid(&self) -> u64 {
        self.rejected
            .iter()
            .filter(|(e, _)| e.starts_with("Invalid"))
            .map(|(_, n)| n)
            .sum()
    }
}

impl fmt::Display for Forgeries {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rejected: u64 = self.rejected.values().sum();
        write!(
            f,
            "{} forged, {} loaded ({} steps run, {} broke a check), {} rejected ({} as invalid \
             states)",
            self.forged,
            self.loaded,
            self.steps,
            self.violations,
            rejected,
            self.invalid()
        )?;
        if let Some(first) = &self.first_violation {
            write!(f, "\n    first broken check: {first}")?;
        }
        for (error, n) in &self.rejected {
            write!(f, "\n    {n:>6}  {error}")?;
        }
        Ok(())
    }
}

/// `record` with `bytes` written at `at` and the checksum recomputed; `None` when that
/// changes nothing.
fn forged(record: &[u8], at: usize, bytes: &[u8]) -> Option<Vec<u8>> {
    let end = record.len().checked_sub(4)?;
    let slot = record
        .get(at..at + bytes.len())
        .filter(|_| at + bytes.len() <= end)?;
    if slot == bytes {
        return None;
    }
    let mut forged = record.to_vec();
    forged[at..at + bytes.len()].copy_from_slice(bytes);
    let checksum = CHECKSUM.checksum(&forged[..end]).to_le_bytes();
    forged[end..].copy_from_slice(&checksum);
    Some(forged)
}

/// Every forgery of `record` (module docs) loaded as `T`; each one that loads is handed to
/// `run` with an RNG seeded from the forgery's index, which returns the steps it ran or the
/// check it saw broken. Broken checks and panics (in `load` or in `run`) are counted, the
/// first one kept with the byte and the pattern.
pub fn sweep<T: Persistent>(
    record: &[u8],
    mut run: impl FnMut(T, &mut DriverRng) -> Result<u64, String>,
) -> Forgeries {
    let end = record.len().saturating_sub(4);
    let mut tally = Forgeries::default();
    let mut index = 0u64;
    for at in 0..end {
        let byte = record[at];
        let singles = BYTE_PATTERNS.into_iter().chain([byte.wrapping_add(1)]);
        let mut patterns: Vec<Vec<u8>> = singles.map(|b| vec![b]).collect();
        patterns.extend(F32_PATTERNS.iter().map(|v| v.to_le_bytes().to_vec()));
        for pattern in patterns {
            let Some(bad) = forged(record, at, &pattern) else {
                continue;
            };
            index += 1;
            tally.forged += 1;
            let outcome = match catch_unwind(|| record::load::<T>(&bad)) {
                Err(_) => Err("load panicked".to_string()),
                Ok(Err(e)) => {
                    *tally.rejected.entry(format!("{e:?}")).or_default() += 1;
                    Ok(0)
                }
                Ok(Ok(value)) => {
                    tally.loaded += 1;
                    let mut rng = DriverRng::seed_from_u64(index);
                    catch_unwind(AssertUnwindSafe(|| run(value, &mut rng)))
                        .unwrap_or_else(|_| Err("panicked while running".to_string()))
                }
            };
            match outcome {
                Ok(steps) => tally.steps += steps,
                Err(e) => {
                    tally.violations += 1;
                    tally.first_violation.get_or_insert_with(|| {
                        format!("byte {at} of {end} overwritten with {pattern:02x?}: {e}")
                    });
                }
            }
        }
    }
    tally
}

/// A uniform draw in [0, 1).
fn unit(rng: &mut impl RngCore) -> f32 {
    (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32
}

/// A noisy shifted sphere, ‖θ − 0.3‖² + U(0, 0.01), finite for any finite θ.
fn sphere<const N: usize>(theta: &Vector<N>, rng: &mut impl RngCore) -> f32 {
    let cost = (theta - Vector::repeat(0.3)).norm_squared() + 0.01 * unit(rng);
    cost.min(f32::MAX)
}

/// Up to `steps` asks and tells of `o` on `sphere`, until it stops; every candidate must
/// be finite and inside the box, be the pending one, and be told without an error, and the
/// best must stay finite and inside the box. Returns the steps run.
pub fn run_optimizer<const N: usize, O: Optimizer<N>>(
    mut o: O,
    rng: &mut DriverRng,
    steps: u64,
) -> Result<u64, String> {
    for step in 0..steps {
        let theta = match o.ask(rng) {
            Ok(theta) => theta,
            Err(Error::Stopped) => return Ok(step),
            Err(e) => return Err(format!("ask {step}: {e}")),
        };
        let bounds = *o.bounds();
        if bounds.check(&theta, "theta").is_err() || o.pending() != Some(&theta) {
            return Err(format!("ask {step}: θ {theta:?} in the box {bounds:?}?"));
        }
        o.tell(sphere(&theta, rng))
            .map_err(|e| format!("tell {step}: {e}"))?;
        if let Some(best) = o.best()
            && (bounds.check(&best.theta, "best").is_err() || !best.cost.is_finite())
        {
            return Err(format!("tell {step}: best {best:?} in the box {bounds:?}?"));
        }
    }
    Ok(steps)
}

/// The adapter the forgeries of [`run_adapter`] hold: the adversarial driver's controller
/// (one axis, PD limit 2, correction envelope 0.5) and a quadratic cost, with the guard `G`
/// and the plant model `M` (none by default).
pub type ForgedAdapter<O, G = Unguarded, M = Unmodelled> =
    Adapter<O, DriverController, QuadraticCost<1>, 2, 2, 1, G, M>;

/// `episodes` episodes of `ticks` control ticks of `adapter` (a running episode is ended
/// first), on states drawn in [−2, 2]²: every θ it begins in [`Mode::Learn`] or
/// [`Mode::Deploy`] must be finite and inside the optimizer's box; every action finite,
/// within the PD's limit, and within the correction envelope of the nominal action;
/// beginning and ending episodes must not fail. Returns the ticks run.
pub fn run_adapter<O: Optimizer<2>, G: Supervisor<2>, M: TickModel<2, 1>>(
    mut adapter: ForgedAdapter<O, G, M>,
    rng: &mut DriverRng,
    episodes: u64,
    ticks: u64,
) -> Result<u64, String> {
    if adapter.in_episode() {
        adapter
            .end_episode()
            .map_err(|e| format!("ending the saved episode: {e}"))?;
    }
    for episode in 0..episodes {
        let theta = adapter
            .begin_episode(rng)
            .map_err(|e| format!("episode {episode}: {e}"))?;
        let bounds = *adapter.optimizer().bounds();
        if adapter.mode() != Mode::Nominal && bounds.check(&theta, "theta").is_err() {
            return Err(format!("episode {episode}: θ {theta:?} in {bounds:?}?"));
        }
        let mut controller = *adapter.controller();
        let limit = controller.pd().limit()[0];
        let envelope = match adapter.mode() {
            Mode::Nominal => 0.0,
            _ => controller.policy().envelope()[0] * (1.0 + 1e-6),
        };
        for tick in 0..ticks {
            let state = Vector::<2>::from_fn(|_, _| (unit(rng) - 0.5) * 4.0);
            let u = adapter.control(&state, &Vector::from([state[0]]))[0];
            let nominal = controller.nominal(&state, 0.0)[0];
            if !u.is_finite() || u.abs() > limit || (u - nominal).abs() > envelope {
                return Err(format!(
                    "episode {episode}, tick {tick}: action {u:e} (nominal {nominal:e}, \
                     limit {limit:e}, envelope {envelope:e})"
                ));
            }
        }
        adapter
            .end_episode()
            .map_err(|e| format!("episode {episode}: {e}"))?;
    }
    Ok(episodes * ticks)
}

/// `value` saved as a record.
fn save<T: Persistent>(value: &T) -> Result<Vec<u8>, String> {
    let mut buf = vec![0u8; 1 << 16];
    record::save(value, &mut buf)
        .map(|bytes| bytes.to_vec())
        .map_err(|e| format!("save: {e}"))
}

/// `value`'s record, after checking that it loads back (validation accepts every state a
/// real run reaches) into a value whose record is the same.
fn round_trip<T: Persistent>(value: &T, when: &str) -> Result<Vec<u8>, String> {
    let bytes = save(value)?;
    let loaded: T = record::load(&bytes).map_err(|e| format!("{when}: refused: {e}"))?;
    if save(&loaded)? != bytes {
        return Err(format!("{when}: loaded as another state"));
    }
    Ok(bytes)
}

/// The record of `o` after `steps` asks and tells on `sphere` and one more ask (so that
/// a candidate is pending); every state on the way, after each ask and each tell, must load
/// back as itself.
pub fn mid_run<const N: usize, O: Optimizer<N> + Persistent>(
    mut o: O,
    steps: usize,
) -> Result<Vec<u8>, String> {
    let mut rng = DriverRng::seed_from_u64(0);
    round_trip(&o, "fresh")?;
    for step in 0..=steps {
        let theta = o.ask(&mut rng).map_err(|e| format!("ask {step}: {e}"))?;
        let bytes = round_trip(&o, &format!("after ask {step}"))?;
        if step == steps {
            return Ok(bytes);
        }
        o.tell(sphere(&theta, &mut rng))
            .map_err(|e| format!("tell {step}: {e}"))?;
        round_trip(&o, &format!("after tell {step}"))?;
    }
    Err("no step".to_string())
}

/// The record of `adapter` after `episodes` episodes of three ticks, within a fourth after
/// its first tick; every state on the way must load back as itself.
pub fn adapter_mid_run<O, G, M>(
    mut adapter: ForgedAdapter<O, G, M>,
    episodes: usize,
) -> Result<Vec<u8>, String>
where
    O: Optimizer<2> + Persistent,
    G: Supervisor<2> + Persistent,
    M: TickModel<2, 1> + Persistent,
{
    let mut rng = DriverRng::seed_from_u64(0);
    round_trip(&adapter, "fresh")?;
    for episode in 0..=episodes {
        adapter
            .begin_episode(&mut rng)
            .map_err(|e| format!("episode {episode}: {e}"))?;
        for tick in 0..3 {
            let state = Vector::<2>::from_fn(|_, _| (unit(&mut rng) - 0.5) * 4.0);
            adapter.control(&state, &Vector::from([state[0]]));
            let bytes = round_trip(&adapter, &format!("episode {episode}, tick {tick}"))?;
            if episode == episodes {
                return Ok(bytes);
            }
        }
        adapter
            .end_episode()
            .map_err(|e| format!("episode {episode}: {e}"))?;
        round_trip(&adapter, &format!("after episode {episode}"))?;
    }
    Err("no episode".to_string())
}

/// The learner the forgeries of [`run_model_based`] hold: the model-based learner over two
/// weights, with a coordinate search as its fallback.
pub type ForgedModelBased = ModelBased<CoordinateSearch<2>, 2>;

/// The inner search of [`run_model_based`]'s proposals: a coordinate search from the trust
/// region's centre.
fn inner_search(bounds: Bounds<2>, start: Vector<2>) -> Result<CoordinateSearch<2>, Error> {
    CoordinateSearch::try_new(bounds, start, CoordinateConfig::DEFAULT)
}

/// A plant model's prediction of [`sphere`], off by a shift of 0.05, and now and then an
/// error (a diverging imagined episode) or a non-finite value.
fn model_of_sphere(theta: &Vector<2>, rng: &mut impl RngCore) -> Result<f32, Error> {
    match rng.next_u32() % 64 {
        0 => Err(Error::NonFinite("prediction")),
        1 => Ok(f32::NAN),
        2 => Ok(f32::INFINITY),
        _ => Ok((theta - Vector::repeat(0.25)).norm_squared()),
    }
}

/// One proposal and its real episode (on [`sphere`]); every third step, when nothing is
/// pending, also an exploration episode of the caller's own ([`ModelBased::record`]).
/// Checks the proposal (finite, in the box, the pending one), the trust radius (within the
/// configured range), the measured prediction error (finite, ≥ 0), the restart's counts
/// (the stall count below `restart_after` when set, the restarts at most the episodes) and
/// the best (finite, in the box, never worse). `Ok(false)` when the fallback is spent.
fn model_based_step(
    learner: &mut ForgedModelBased,
    rng: &mut DriverRng,
    step: u64,
) -> Result<bool, String> {
    let bounds = *learner.fallback().bounds();
    let before = learner.best().map_or(f32::INFINITY, |b| b.cost);
    if step % 3 == 2 && learner.pending().is_none() {
        let theta = Vector::<2>::from_fn(|_, _| unit(rng) * 2.0 - 1.0);
        let theta = bounds.clamp(&theta);
        learner
            .record(theta, sphere(&theta, rng))
            .map_err(|e| format!("record {step}: {e}"))?;
    }
    let mut model_rng = DriverRng::seed_from_u64(step);
    let proposal = match learner.propose(rng, inner_search, |theta| {
        model_of_sphere(theta, &mut model_rng)
    }) {
        Ok(p) => p,
        Err(Error::Stopped) => return Ok(false),
        Err(e) => return Err(format!("propose {step}: {e}")),
    };
    let theta = proposal.theta;
    if bounds.check(&theta, "theta").is_err() || learner.pending().map(|p| p.theta) != Some(theta) {
        return Err(format!(
            "propose {step}: θ {theta:?} in the box {bounds:?}?"
        ));
    }
    learner
        .tell(sphere(&theta, rng))
        .map_err(|e| format!("tell {step}: {e}"))?;
    let config = learner.config();
    let radius = learner.radius();
    if !(radius >= config.min_radius && radius <= config.max_radius) {
        return Err(format!("tell {step}: radius {radius:e} outside its range"));
    }
    let error = learner.prediction_error();
    if !(error.is_finite() && error >= 0.0) {
        return Err(format!("tell {step}: prediction error {error:e}"));
    }
    let (stalled, restarts) = (learner.stalled(), learner.restarts());
    let restart = config.restart_after;
    if (restart > 0 && stalled >= restart) || restarts > learner.evaluations() {
        return Err(format!(
            "tell {step}: stalled {stalled}, restarts {restarts} (restart after {restart})"
        ));
    }
    match learner.best() {
        Some(best)
            if bounds.check(&best.theta, "best").is_err()
                || !best.cost.is_finite()
                || best.cost > before =>
        {
            Err(format!("tell {step}: best {best:?} (before {before:e})"))
        }
        None => Err(format!("tell {step}: no best after a real episode")),
        Some(_) => Ok(true),
    }
}

/// Up to `steps` proposals of `learner` and their real episodes on a noisy shifted sphere
/// (‖θ − 0.3‖² + U(0, 0.01)), the model's predictions off by a shift and sometimes failing
/// or not finite, with an exploration episode of the caller's own now and then. Every
/// proposal must be finite, in the box and the pending one; the trust radius within its
/// configured range; the measured prediction error finite and ≥ 0; the restart's counts
/// within theirs; the best finite, in the box and never worse. A proposal pending in the
/// record is told first. Returns the steps
/// run.
pub fn run_model_based(
    mut learner: ForgedModelBased,
    rng: &mut DriverRng,
    steps: u64,
) -> Result<u64, String> {
    for step in 0..steps {
        if !model_based_step(&mut learner, rng, step)? {
            return Ok(step);
        }
    }
    Ok(steps)
}

/// The record of `learner` after a reference cost and `steps` proposals with their real
/// episodes, then one more proposal (so that one is pending); every state on the way must
/// load back as itself.
pub fn model_based_mid_run(mut learner: ForgedModelBased, steps: u64) -> Result<Vec<u8>, String> {
    let mut rng = DriverRng::seed_from_u64(0);
    round_trip(&learner, "fresh")?;
    learner
        .set_reference(sphere(&Vector::<2>::zeros(), &mut rng))
        .map_err(|e| format!("reference: {e}"))?;
    for step in 0..steps {
        if !model_based_step(&mut learner, &mut rng, step)? {
            return Err(format!("the fallback stopped after {step} steps"));
        }
        round_trip(&learner, &format!("after step {step}"))?;
    }
    let mut model_rng = DriverRng::seed_from_u64(steps);
    learner
        .propose(&mut rng, inner_search, |theta| {
            model_of_sphere(theta, &mut model_rng)
        })
        .map_err(|e| format!("the last proposal: {e}"))?;
    round_trip(&learner, "with a proposal pending")
}

/// The plant model the forgeries of [`run_rls_model`] hold: two states, one command, the
/// affine regressors.
pub type ForgedRlsModel = RlsModel<2, 1, 4>;

/// How [`plant_tick`] draws its command: uniformly in [−2, 2], a square wave of ±1 switched
/// every 1,000 ticks, or a constant 0.3 with a 10⁻⁶ wobble (the two that lost the plain
/// form's positive definiteness under forgetting).
#[derive(Clone, Copy)]
enum Command {
    Random,
    Square,
    NearlyConstant,
}

impl Command {
    fn draw(rng: &mut impl RngCore) -> Self {
        match rng.next_u32() % 3 {
            0 => Self::Random,
            1 => Self::Square,
            _ => Self::NearlyConstant,
        }
    }

    fn at(self, tick: u64, rng: &mut impl RngCore) -> f32 {
        match self {
            Self::Random => (unit(rng) - 0.5) * 4.0,
            Self::Square if (tick / 1000).is_multiple_of(2) => 1.0,
            Self::Square => -1.0,
            Self::NearlyConstant => 0.3 + 1e-6 * (unit(rng) - 0.5),
        }
    }
}

/// A damped linear plant x' = A·x + B·u + c with a little noise under `command`; one tick in
/// 50 non-finite and one in 50 huge (about 10³⁰). The last value says whether the tick is an
/// ordinary one (finite and of ordinary size), which no model may refuse.
fn plant_tick(
    x: &Vector<2>,
    command: Command,
    tick: u64,
    rng: &mut impl RngCore,
) -> (Vector<2>, Vector<1>, Vector<2>, bool) {
    let u = Vector::<1>::new(command.at(tick, rng));
    let next = Vector::<2>::new(
        0.9 * x[0] + 0.1 * x[1] + 0.01 * (unit(rng) - 0.5),
        -0.2 * x[0] + 0.8 * x[1] + 0.5 * u[0] + 0.1 + 0.01 * (unit(rng) - 0.5),
    );
    match rng.next_u32() % 50 {
        0 => (*x, u, Vector::repeat(f32::NAN), false),
        1 => (*x * 1e30, u, next, false),
        _ => (*x, u, next, true),
    }
}

/// Whether `model`'s prediction or leverage at (`state`, `command`) lies beyond 10³⁰: a
/// state the forgery made (the plant's own ticks are of order 10).
fn extreme(model: &ForgedRlsModel, state: &Vector<2>, command: &Vector<1>) -> bool {
    let (next, leverage) = model.predict_with_leverage(&Affine, state, command);
    !(next.iter().all(|v| v.abs() <= 1e30) && leverage <= 1e30)
}

/// `ticks` ticks of a damped linear plant with two states and one command fitted by
/// `model` (one tick in 50 non-finite, one in 50 huge; the command random, a square wave or
/// nearly constant, drawn per run), from a random state (the plant's state reset when it
/// leaves [−10, 10]²): an ordinary tick must be fitted (unless the forged state's own
/// prediction or leverage for it is beyond 10³⁰), the others refused as non-finite or as an
/// overflow, every state valid; no prediction may panic. Returns the ticks run.
pub fn run_rls_model(
    mut model: ForgedRlsModel,
    rng: &mut DriverRng,
    ticks: u64,
) -> Result<u64, String> {
    let mut x = Vector::<2>::from_fn(|_, _| (unit(rng) - 0.5) * 4.0);
    let command = Command::draw(rng);
    for tick in 0..ticks {
        let (state, command, next, ordinary) = plant_tick(&x, command, tick, rng);
        let _ = model.predict(&Affine, &state, &command);
        match model.update(&Affine, &state, &command, &next) {
            Ok(_) => {}
            // A forged state may hold values near f32's range (a weight of 10³⁸, a variance
            // bound of 10³⁸): its prediction or leverage for an ordinary tick is then beyond
            // f32's reach too, and the refusal is right. Otherwise it is a defect.
            Err(e) if ordinary && !extreme(&model, &state, &command) => {
                return Err(format!(
                    "tick {tick}: an ordinary tick refused: {e}: {model:?}"
                ));
            }
            Err(Error::NonFinite(_) | Error::Overflow(_)) => {}
            Err(e) => return Err(format!("tick {tick}: {e}")),
        }
        model
            .validate()
            .map_err(|e| format!("tick {tick}: the fitted model is invalid: {e}"))?;
        x = if next.iter().all(|v| v.is_finite() && v.abs() <= 10.0) {
            next
        } else {
            Vector::from_fn(|_, _| (unit(rng) - 0.5) * 4.0)
        };
    }
    Ok(ticks)
}

/// The record of `model` after `ticks` ticks of [`run_rls_model`]'s plant; every state on
/// the way must load back as itself.
pub fn rls_model_mid_run(mut model: ForgedRlsModel, ticks: u64) -> Result<Vec<u8>, String> {
    let mut rng = DriverRng::seed_from_u64(0);
    round_trip(&model, "fresh")?;
    let mut x = Vector::<2>::zeros();
    let command = Command::draw(&mut rng);
    for tick in 0..ticks {
        let (state, command, next, _) = plant_tick(&x, command, tick, &mut rng);
        let _ = model.update(&Affine, &state, &command, &next);
        round_trip(&model, &format!("after tick {tick}"))?;
        if next.iter().all(|v| v.is_finite() && v.abs() <= 10.0) {
            x = next;
        }
    }
    round_trip(&model, "at the end")
}
