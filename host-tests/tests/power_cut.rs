//! Learning that survives a power cut: the adapter with its optimizer and the RNG saved to a
//! [`CheckpointStore`] after every episode, on a test NOR flash that loses power after the
//! k-th word written or erased, for every k of every save of a run.

use ctrl_adapt::checkpoint::{CheckpointError, CheckpointStore};
use ctrl_adapt::controller::{
    Adapter, AdapterConfig, CorrectedPd, LinearPolicy, Pd, StateFeatures,
};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::optimizer::{
    Bounds, CemConfig, Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch, DiagonalCem,
    Optimizer, Sracos, SracosConfig, Vector,
};
use ctrl_adapt::record::{self, Persistent, RecordError, Shape};
use embassy_embedded_hal::adapter::BlockingAsync;
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use host_tests::double_integrator::DoubleIntegrator;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

const WORD: usize = 4;
const PAGE: usize = 512;
const SLOT_PAGES: usize = 3;
const FLASH: usize = 2 * SLOT_PAGES * PAGE;
const SLOTS: [core::ops::Range<u32>; 2] = [
    0..(SLOT_PAGES * PAGE) as u32,
    (SLOT_PAGES * PAGE) as u32..FLASH as u32,
];
const ITEM: usize = 128;
const RECORD: usize = 2048;

/// Why the test flash refused an operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FlashError {
    /// The power is off (this operation was the cut one, or came after it).
    PowerCut,
    /// A word written twice without an erase between: a bug in the store.
    NotErased,
    /// Misaligned or out of range.
    Bounds,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::Bounds => NorFlashErrorKind::OutOfBounds,
            _ => NorFlashErrorKind::Other,
        }
    }
}

/// NOR flash in RAM (words of 4 bytes, pages of 512) that counts the words it writes or
/// erases and loses power at the `cut_at`-th: that word is torn (a write leaves its first
/// two bytes programmed, an erase the page erased up to it) and every later operation fails
/// until [`CutFlash::reboot`]. A word may be written once per erase.
#[derive(Clone)]
struct CutFlash {
    data: Vec<u8>,
    ops: u64,
    /// Pages erased, over the flash's life.
    erases: u64,
    cut_at: Option<u64>,
    dead: bool,
    /// Refuse a write to a word not erased (a bug in the store); off, program it as NOR
    /// flash does (1 bits to 0), as over a corrupted erased byte.
    strict: bool,
}

impl CutFlash {
    fn erased() -> Self {
        Self {
            data: vec![0xff; FLASH],
            ops: 0,
            erases: 0,
            cut_at: None,
            dead: false,
            strict: true,
        }
    }

    /// Counts one word operation; false when the power fails at it (or failed before).
    fn power(&mut self) -> bool {
        if self.dead {
            return false;
        }
        self.ops += 1;
        if self.cut_at == Some(self.ops) {
            self.dead = true;
        }
        !self.dead
    }

    /// Power back: no cut planned, the counter at zero.
    fn reboot(&mut self) {
        self.dead = false;
        self.cut_at = None;
        self.ops = 0;
    }

    /// Cuts the power at the `k`-th word operation from now.
    fn cut_after(&mut self, k: u64) {
        self.ops = 0;
        self.cut_at = Some(k);
    }
}

impl ErrorType for CutFlash {
    type Error = FlashError;
}

impl ReadNorFlash for CutFlash {
    const READ_SIZE: usize = WORD;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let at = offset as usize;
        if self.dead {
            return Err(FlashError::PowerCut);
        }
        if !at.is_multiple_of(WORD) || !bytes.len().is_multiple_of(WORD) || at + bytes.len() > FLASH
        {
            return Err(FlashError::Bounds);
        }
        bytes.copy_from_slice(&self.data[at..at + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        FLASH
    }
}

impl NorFlash for CutFlash {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let (from, to) = (from as usize, to as usize);
        if !from.is_multiple_of(PAGE) || !to.is_multiple_of(PAGE) || from > to || to > FLASH {
            return Err(FlashError::Bounds);
        }
        for word in (from..to).step_by(WORD) {
            if !self.power() {
                return Err(FlashError::PowerCut);
            }
            self.data[word..word + WORD].fill(0xff);
        }
        self.erases += ((to - from) / PAGE) as u64;
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let at = offset as usize;
        if !at.is_multiple_of(WORD) || !bytes.len().is_multiple_of(WORD) || at + bytes.len() > FLASH
        {
            return Err(FlashError::Bounds);
        }
        for (i, word) in bytes.chunks(WORD).enumerate() {
            let place = at + i * WORD;
            if self.strict && self.data[place..place + WORD] != [0xff; WORD] {
                return Err(FlashError::NotErased);
            }
            if !self.power() {
                if self.cut_at == Some(self.ops) {
                    // Torn: half the word programmed.
                    self.data[place] &= word[0];
                    self.data[place + 1] &= word[1];
                }
                return Err(FlashError::PowerCut);
            }
            for (d, s) in self.data[place..place + WORD].iter_mut().zip(word) {
                *d &= s;
            }
        }
        Ok(())
    }
}

type Plant = CorrectedPd<1, 2, 2, 2, StateFeatures<2>>;
type Learning<O> = Adapter<O, Plant, QuadraticCost<1>, 2, 2, 1>;

/// What a checkpoint holds: the adapter (optimizer, mode, counters, best θ, controller,
/// shaper), the caller's RNG, which the next candidates are drawn from, and the episodes run.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(bound = "Ad: Serialize + DeserializeOwned")]
struct Learner<Ad> {
    adapter: Ad,
    rng: Xoshiro128PlusPlus,
    episodes: u32,
}

impl<Ad: Persistent> Persistent for Learner<Ad> {
    const SHAPE: Shape = Shape::new(*b"LRNR", &[]).nest(Ad::SHAPE);

    /// The adapter's checks; the RNG and the episode counter can hold any value.
    fn validate(&self) -> Result<(), ctrl_adapt::Error> {
        self.adapter.validate()
    }
}

const DT: f32 = 0.05;
const TICKS: u32 = 40;

fn learner<O: Optimizer<2>>(optimizer: O) -> Learner<Learning<O>> {
    let pd = Pd::<1>::try_new(Vector::repeat(4.0), Vector::repeat(3.6))
        .unwrap()
        .with_limit(Vector::repeat(5.0))
        .unwrap();
    let policy = LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(3.0)).unwrap();
    let config = AdapterConfig {
        dt: DT,
        failure_cost: 100.0,
        max_faulty_ticks: 0,
        learning_episodes: 1000,
    };
    let shaper = QuadraticCost::try_new(Vector::repeat(1.0)).unwrap();
    Learner {
        adapter: Adapter::try_new(
            optimizer,
            CorrectedPd::new(pd, policy),
            shaper,
            config,
            Vector::zeros(),
        )
        .unwrap(),
        rng: Xoshiro128PlusPlus::seed_from_u64(2026),
        episodes: 0,
    }
}

/// One episode on the disturbed double integrator; the θ it ran and the cost told, as bits.
fn episode<O: Optimizer<2>>(l: &mut Learner<Learning<O>>) -> ([u32; 2], u32) {
    let theta = l.adapter.begin_episode(&mut l.rng).unwrap();
    let mut plant = DoubleIntegrator::new(-1.5, f64::from(DT));
    for _ in 0..TICKS {
        let error = (1.0 - plant.position) as f32;
        let state = Vector::from([error, plant.velocity as f32]);
        let u = l.adapter.control(&state, &Vector::repeat(error));
        plant.step(f64::from(u[0]));
    }
    let report = l.adapter.end_episode().unwrap();
    l.episodes += 1;
    (
        [theta[0].to_bits(), theta[1].to_bits()],
        report.told.unwrap().to_bits(),
    )
}

fn bytes<T: Persistent>(value: &T) -> Vec<u8> {
    let mut buf = vec![0u8; 16 * 1024];
    record::save(value, &mut buf).unwrap().to_vec()
}

type Store<'f> = CheckpointStore<BlockingAsync<&'f mut CutFlash>>;

fn store(flash: &mut CutFlash) -> Store<'_> {
    CheckpointStore::try_new(BlockingAsync::new(flash), SLOTS).unwrap()
}

/// Boot: the newest intact checkpoint, or the initial learner on a flash that has none.
fn boot<O>(store: &mut Store<'_>, initial: &Learner<Learning<O>>) -> Learner<Learning<O>>
where
    O: Optimizer<2> + Persistent + Clone,
{
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    store
        .load::<Learner<Learning<O>>>(&mut rec, &mut item)
        .unwrap()
        .unwrap_or_else(|| initial.clone())
}

/// The uninterrupted run: its events, the record after each episode (0: the initial
/// learner), the flash before each save, and the word operations of each save.
struct Reference {
    events: Vec<([u32; 2], u32)>,
    records: Vec<Vec<u8>>,
    images: Vec<CutFlash>,
    ops: Vec<u64>,
    /// Pages erased over the run.
    erases: u64,
}

fn reference<O>(initial: &Learner<Learning<O>>, episodes: usize) -> Reference
where
    O: Optimizer<2> + Persistent + Clone,
{
    let mut flash = CutFlash::erased();
    let mut l = boot(&mut store(&mut flash), initial);
    let mut r = Reference {
        events: Vec::new(),
        records: vec![bytes(&l)],
        images: Vec::new(),
        ops: Vec::new(),
        erases: 0,
    };
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    for _ in 0..episodes {
        r.events.push(episode(&mut l));
        r.records.push(bytes(&l));
        r.images.push(flash.clone());
        flash.ops = 0;
        {
            let mut s = store(&mut flash);
            boot(&mut s, initial);
            let before = s.generation();
            s.save(&l, &mut rec, &mut item).unwrap();
            assert_eq!(s.generation(), Some(before.map_or(1, |g| g + 1)));
        }
        // The boot's reads count nothing; the save's writes and erases are the ops.
        r.ops.push(flash.ops);
    }
    r.erases = flash.erases;
    r
}

/// Continues `l` (which has run `l.episodes`) to `episodes` with a save after each, and
/// checks every event and the final state against the reference.
fn finish<O>(mut l: Learner<Learning<O>>, flash: &mut CutFlash, r: &Reference, episodes: usize)
where
    O: Optimizer<2> + Persistent + Clone,
{
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let mut s = store(flash);
    while (l.episodes as usize) < episodes {
        let at = l.episodes as usize;
        assert_eq!(episode(&mut l), r.events[at], "episode {at}");
        s.save(&l, &mut rec, &mut item).unwrap();
    }
    assert_eq!(bytes(&l), r.records[episodes]);
}

/// Cuts the power at every word operation of every save of a run of `episodes`; after each
/// cut, boot loads the state before or after the interrupted save (bit for bit), and the
/// learning that continues from it ends exactly as the uninterrupted run. Returns the cuts
/// tried and how many booted into the state after the save.
fn cut_everywhere<O>(optimizer: O, episodes: usize) -> (u64, u64, u64, usize)
where
    O: Optimizer<2> + Persistent + Clone,
{
    let initial = learner(optimizer);
    let r = reference(&initial, episodes);
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let (mut cuts, mut after) = (0, 0);
    for save in 0..episodes {
        let state = record::load::<Learner<Learning<O>>>(&r.records[save + 1]).unwrap();
        // k = ops + 1: the cut comes just after the save (its last word is the commit's).
        for k in 1..=r.ops[save] + 1 {
            let mut flash = r.images[save].clone();
            flash.cut_after(k);
            {
                let mut s = store(&mut flash);
                boot(&mut s, &initial);
                let saved = s.save(&state, &mut rec, &mut item);
                assert_eq!(saved.is_ok(), k > r.ops[save], "save {save}, k {k}");
            }
            flash.reboot();
            let booted = boot(&mut store(&mut flash), &initial);
            let found = bytes(&booted);
            if found == r.records[save + 1] {
                after += 1;
            } else {
                assert_eq!(
                    found, r.records[save],
                    "save {save}, cut at word {k}: a mix"
                );
            }
            cuts += 1;
            finish(booted, &mut flash, &r, episodes);
        }
    }
    let largest = r.records.iter().map(Vec::len).max().unwrap_or(0);
    (cuts, after, r.erases, largest)
}

fn bounds() -> Bounds<2> {
    Bounds::uniform(-20.0, 20.0).unwrap()
}

const EPISODES: usize = 12;

fn report(name: &str, (cuts, after, erases, record): (u64, u64, u64, usize)) {
    let saves = after;
    println!(
        "{name}: {cuts} power cuts in {saves} saves ({erases} page erases), {after} booted \
         into the new checkpoint, {} into the one before; largest record {record} bytes",
        cuts - after
    );
    assert!(erases > 0, "the run must cross a garbage collection");
}

/// Checks, for the coordinate search inside the adapter, every power cut of every save: boot
/// finds the state before or after the save, and learning ends as if never cut.
#[test]
fn coordinate_search_survives_every_power_cut() {
    let config = CoordinateConfig {
        initial_step: 2.0,
        ..CoordinateConfig::DEFAULT
    };
    let o = CoordinateSearch::try_new(bounds(), Vector::zeros(), config).unwrap();
    report("coordinate search", cut_everywhere(o, EPISODES));
}

/// As above, for SRACOS.
#[test]
fn sracos_survives_every_power_cut() {
    let o = Sracos::<2>::try_new(bounds(), SracosConfig::DEFAULT).unwrap();
    report("SRACOS", cut_everywhere(o, EPISODES));
}

/// As above, for the diagonal CEM (batches of 4: the run crosses batch updates).
#[test]
fn diagonal_cem_survives_every_power_cut() {
    let o = DiagonalCem::<2, 4, 2>::try_new(bounds(), Vector::zeros(), CemConfig::DEFAULT).unwrap();
    report("diagonal CEM", cut_everywhere(o, EPISODES));
}

/// As above, for CMA-ES (population 4: the run crosses generations).
#[test]
fn cmaes_survives_every_power_cut() {
    let o = Cmaes::<2, 4>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    report("CMA-ES", cut_everywhere(o, EPISODES));
}

/// As above, for ROCK* (a memory of 10 rollouts: the run crosses its first update), over 6
/// episodes: its larger record makes every save cost more words.
#[test]
fn rockstar_survives_every_power_cut() {
    use ctrl_adapt::optimizer::{Rockstar, RockstarConfig};
    let config = RockstarConfig {
        initial_samples: 4,
        ..RockstarConfig::DEFAULT
    };
    let o = Rockstar::<2, 10>::try_new(bounds(), Vector::zeros(), config).unwrap();
    report("ROCK*", cut_everywhere(o, 6));
}

/// Checks: boot on erased flash finds nothing and learning starts fresh; after a run, a
/// corrupted byte anywhere in the flash (each byte in turn, every bit flipped) never panics
/// and boot loads the newest checkpoint, or the one before it when the byte spoilt the
/// newest; never anything else. A save after such a boot succeeds and is the one found next.
/// A checkpoint of other sizes is refused by name, and saving afresh over it works.
#[test]
fn corrupted_bytes_fall_back_to_the_newest_intact_checkpoint() {
    let o = Cmaes::<2, 4>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    let initial = learner(o);
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let mut erased = CutFlash::erased();
    let mut s = store(&mut erased);
    assert!(
        s.load::<Learner<Learning<Cmaes<2, 4>>>>(&mut rec, &mut item)
            .unwrap()
            .is_none()
    );
    assert_eq!(s.generation(), None);

    let r = reference(&initial, EPISODES);
    let mut flash = r.images[EPISODES - 1].clone();
    let last = record::load::<Learner<Learning<Cmaes<2, 4>>>>(&r.records[EPISODES]).unwrap();
    store(&mut flash).save(&last, &mut rec, &mut item).unwrap();
    let (mut newest, mut fallback, mut landed) = (0, 0, 0);
    for at in 0..FLASH {
        let mut bad = flash.clone();
        bad.strict = false;
        bad.data[at] ^= 0xff;
        let mut s = store(&mut bad);
        let booted = boot(&mut s, &initial);
        let found = bytes(&booted);
        if found == r.records[EPISODES] {
            newest += 1;
        } else {
            assert_eq!(found, r.records[EPISODES - 1], "byte {at}");
            fallback += 1;
        }
        let mut next = booted.clone();
        episode(&mut next);
        s.save(&next, &mut rec, &mut item).unwrap();
        // The save may have landed on the corrupted byte (then it is caught and the state
        // booted before is found again).
        let again = bytes(&boot(&mut store(&mut bad), &initial));
        if again != bytes(&next) {
            assert_eq!(again, found, "byte {at}");
            landed += 1;
        }
    }
    println!(
        "corrupted bytes: {newest} kept the newest checkpoint, {fallback} fell back to the one \
         before; the next save landed on the corruption {landed} times"
    );
    assert!(fallback > 0 && newest > 0);
    // An intact checkpoint of other sizes is refused by name, not loaded nor skipped.
    assert_eq!(
        store(&mut flash)
            .load::<Learner<Learning<Cmaes<2, 5>>>>(&mut rec, &mut item)
            .unwrap_err(),
        CheckpointError::Record(RecordError::Shape)
    );
    // Starting afresh with the other sizes: the save goes through and is found next.
    let other =
        learner(Cmaes::<2, 5>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap());
    let mut s = store(&mut flash);
    assert!(
        s.load::<Learner<Learning<Cmaes<2, 5>>>>(&mut rec, &mut item)
            .is_err()
    );
    s.save(&other, &mut rec, &mut item).unwrap();
    let found = store(&mut flash)
        .load::<Learner<Learning<Cmaes<2, 5>>>>(&mut rec, &mut item)
        .unwrap()
        .unwrap();
    assert_eq!(bytes(&found), bytes(&other));
}

/// A NOR flash in RAM with 4 KiB pages (a common internal-flash page) that counts the bytes
/// written and the pages erased, for the size and wear figures.
struct MeteredFlash {
    data: Vec<u8>,
    written: u64,
    erases: u64,
}

const BIG_PAGE: usize = 4096;

impl ErrorType for MeteredFlash {
    type Error = FlashError;
}

impl ReadNorFlash for MeteredFlash {
    const READ_SIZE: usize = WORD;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let at = offset as usize;
        let src = self
            .data
            .get(at..at + bytes.len())
            .ok_or(FlashError::Bounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.data.len()
    }
}

impl NorFlash for MeteredFlash {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = BIG_PAGE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let range = self
            .data
            .get_mut(from as usize..to as usize)
            .ok_or(FlashError::Bounds)?;
        range.fill(0xff);
        self.erases += ((to - from) as usize / BIG_PAGE) as u64;
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let at = offset as usize;
        let dst = self
            .data
            .get_mut(at..at + bytes.len())
            .ok_or(FlashError::Bounds)?;
        if dst.iter().any(|&b| b != 0xff) {
            return Err(FlashError::NotErased);
        }
        dst.copy_from_slice(bytes);
        self.written += bytes.len() as u64;
        Ok(())
    }
}

/// Figures for one optimizer inside the AUV adapter.
struct Figures {
    record: usize,
    written_per_save: f64,
    erases_per_save: f64,
}

/// The AUV adapter (P = 18) with `optimizer`, saved with the RNG after each of `episodes`
/// evaluations of a sphere into a store of two slots of `slot_pages` 4 KiB pages with 1 KiB
/// items; the largest record, the flash bytes written and the pages erased per save. Checks
/// that the last checkpoint loads back bit for bit.
fn measure<O>(mut optimizer: O, episodes: u32, slot_pages: usize) -> Figures
where
    O: Optimizer<{ auv_survey::P }> + Persistent + Clone,
{
    use host_tests::auv_task;
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(5);
    let slot = (slot_pages * BIG_PAGE) as u32;
    let mut flash = MeteredFlash {
        data: vec![0xff; 2 * slot as usize],
        written: 0,
        erases: 0,
    };
    let (mut rec, mut item) = (vec![0u8; 16 * 1024], [0u8; 1024]);
    let mut last = Vec::new();
    let mut record = 0;
    {
        let mut store =
            CheckpointStore::try_new(BlockingAsync::new(&mut flash), [0..slot, slot..2 * slot])
                .unwrap();
        for n in 0..episodes {
            let theta = optimizer.ask(&mut rng).unwrap();
            optimizer.tell(theta.norm_squared()).unwrap();
            let learner = Learner {
                adapter: auv_task::adapter(optimizer.clone(), 1000, Vector::zeros()).unwrap(),
                rng: rng.clone(),
                episodes: n + 1,
            };
            store.save(&learner, &mut rec, &mut item).unwrap();
            last = bytes(&learner);
            record = record.max(last.len());
        }
        let loaded = store
            .load::<Learner<auv_task::AuvAdapter<O>>>(&mut rec, &mut item)
            .unwrap()
            .unwrap();
        assert_eq!(bytes(&loaded), last);
    }
    Figures {
        record,
        written_per_save: flash.written as f64 / f64::from(episodes),
        erases_per_save: flash.erases as f64 / f64::from(episodes),
    }
}

/// Prints the bytes of a checkpoint (the AUV adapter, P = 18, with its optimizer and the
/// RNG) per optimizer, the flash bytes written and the 4 KiB pages erased per save, over 60
/// saves into two slots of 4 pages (ROCK*: 8); checks each last checkpoint loads back.
#[test]
fn checkpoint_sizes_per_optimizer() {
    use ctrl_adapt::optimizer::{
        ControlledRandomSearch, CrsConfig, Rockstar, RockstarConfig, TwoPhase,
    };
    let b = Bounds::<18>::uniform(-1.0, 1.0).unwrap();
    let z = Vector::<18>::zeros();
    let crs = || ControlledRandomSearch::<18, 100>::try_new(b, CrsConfig::DEFAULT).unwrap();
    let rows = [
        (
            "CoordinateSearch<18>",
            measure(
                CoordinateSearch::try_new(b, z, CoordinateConfig::DEFAULT).unwrap(),
                60,
                4,
            ),
        ),
        (
            "Sracos<18>",
            measure(
                Sracos::<18>::try_new(b, SracosConfig::DEFAULT).unwrap(),
                60,
                4,
            ),
        ),
        (
            "DiagonalCem<18, 10, 5>",
            measure(
                DiagonalCem::<18, 10, 5>::try_new(b, z, CemConfig::DEFAULT).unwrap(),
                60,
                4,
            ),
        ),
        (
            "Cmaes<18, 12>",
            measure(
                Cmaes::<18, 12>::try_new(b, z, CmaesConfig::DEFAULT).unwrap(),
                60,
                4,
            ),
        ),
        ("ControlledRandomSearch<18, 100>", measure(crs(), 60, 8)),
        (
            "TwoPhase<ControlledRandomSearch<18, 100>, 18>",
            measure(
                TwoPhase::try_new(crs(), 30, CoordinateConfig::DEFAULT).unwrap(),
                60,
                8,
            ),
        ),
        (
            "Rockstar<18, 90>",
            measure(
                Rockstar::<18, 90>::try_new(b, z, RockstarConfig::DEFAULT).unwrap(),
                60,
                8,
            ),
        ),
    ];
    println!(
        "| optimizer in the AUV adapter | record (B) | flash written per save (B) | 4 KiB page erases per save |"
    );
    println!("| --- | --- | --- | --- |");
    for (name, f) in rows {
        println!(
            "| `{name}` | {} | {:.0} | {:.3} |",
            f.record, f.written_per_save, f.erases_per_save
        );
    }
}
