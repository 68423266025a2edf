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
//! the PD's limit and within the correction envelope of the nominal action. Broken checks
//! and panics are counted, the first one kept with the byte and the pattern.

use std::collections::BTreeMap;
use std::fmt;
use std::panic::{AssertUnwindSafe, catch_unwind};

use ctrl_adapt::controller::{Adapter, Controller, Mode};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::optimizer::{Error, Optimizer, Vector};
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
/// (one axis, PD limit 2, correction envelope 0.5) and a quadratic cost.
pub type ForgedAdapter<O> = Adapter<O, DriverController, QuadraticCost<1>, 2, 2, 1>;

/// `episodes` episodes of `ticks` control ticks of `adapter` (a running episode is ended
/// first), on states drawn in [−2, 2]²: every θ it begins in [`Mode::Learn`] or
/// [`Mode::Deploy`] must be finite and inside the optimizer's box; every action finite,
/// within the PD's limit, and within the correction envelope of the nominal action;
/// beginning and ending episodes must not fail. Returns the ticks run.
pub fn run_adapter<O: Optimizer<2>>(
    mut adapter: ForgedAdapter<O>,
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
pub fn adapter_mid_run<O: Optimizer<2> + Persistent>(
    mut adapter: ForgedAdapter<O>,
    episodes: usize,
) -> Result<Vec<u8>, String> {
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
