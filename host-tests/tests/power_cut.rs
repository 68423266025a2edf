//! Learning that survives a power cut: the adapter with its optimizer and the RNG saved to a
//! [`CheckpointStore`] after every episode, on a test NOR flash ([`CutFlash`]) that loses
//! power after the k-th word written or erased, for every k of every save of a run, under each
//! of three programming rules (write-once words, AND-programming, re-writable zeros); and a
//! flash that starts full of leftover data, or with a stray word in its free space.

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
use host_tests::cut_flash::{CutFlash, Programming, WORD};
use host_tests::double_integrator::DoubleIntegrator;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

const PAGE: usize = 512;
const SLOT_PAGES: usize = 3;
const FLASH: usize = 2 * SLOT_PAGES * PAGE;
const SLOTS: [core::ops::Range<u32>; 2] = [
    0..(SLOT_PAGES * PAGE) as u32,
    (SLOT_PAGES * PAGE) as u32..FLASH as u32,
];
const ITEM: usize = 128;
const RECORD: usize = 2048;

type Flash = CutFlash<PAGE>;

fn erased(rule: Programming) -> Flash {
    CutFlash::erased(FLASH, rule)
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

type Store<'f> = CheckpointStore<BlockingAsync<&'f mut Flash>>;

fn store(flash: &mut Flash) -> Store<'_> {
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
    images: Vec<Flash>,
    ops: Vec<u64>,
    /// Pages erased over the run.
    erases: u64,
}

fn reference<O>(initial: &Learner<Learning<O>>, episodes: usize, rule: Programming) -> Reference
where
    O: Optimizer<2> + Persistent + Clone,
{
    let mut flash = erased(rule);
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
fn finish<O>(mut l: Learner<Learning<O>>, flash: &mut Flash, r: &Reference, episodes: usize)
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

/// What one sweep of power cuts found.
struct Sweep {
    cuts: u64,
    /// Cuts that booted into the state after the interrupted save.
    after: u64,
    /// Pages erased in the uninterrupted run.
    erases: u64,
    /// The largest record of the run (bytes).
    record: usize,
}

/// Cuts the power at every word operation of every save of a run of `episodes` on a flash
/// of `rule` whose torn words get `tear_bytes` bytes programmed; after each cut, boot loads
/// the state before or after the interrupted save (bit for bit), and the learning that
/// continues from it (a save after every episode, each of which must succeed) ends exactly
/// as the uninterrupted run.
fn cut_everywhere<O>(optimizer: O, episodes: usize, rule: Programming, tear_bytes: usize) -> Sweep
where
    O: Optimizer<2> + Persistent + Clone,
{
    let initial = learner(optimizer);
    let r = reference(&initial, episodes, rule);
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let (mut cuts, mut after) = (0, 0);
    for save in 0..episodes {
        let state = record::load::<Learner<Learning<O>>>(&r.records[save + 1]).unwrap();
        // k = ops + 1: the cut comes just after the save (its last word is the commit's).
        for k in 1..=r.ops[save] + 1 {
            let mut flash = r.images[save].clone();
            flash.tear_bytes = tear_bytes;
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
    Sweep {
        cuts,
        after,
        erases: r.erases,
        record: r.records.iter().map(Vec::len).max().unwrap_or(0),
    }
}

fn bounds() -> Bounds<2> {
    Bounds::uniform(-20.0, 20.0).unwrap()
}

const EPISODES: usize = 12;

fn report(name: &str, rule: Programming, tear_bytes: usize, sweep: Sweep) {
    println!(
        "{name}, {}, torn word {tear_bytes} of {WORD} bytes programmed: {} power cuts ({} page \
         erases in the run), {} booted into the new checkpoint, {} into the one before; \
         largest record {} bytes",
        rule.name(),
        sweep.cuts,
        sweep.erases,
        sweep.after,
        sweep.cuts - sweep.after,
        sweep.record,
    );
    assert!(sweep.erases > 0, "the run must cross a garbage collection");
}

/// Every power cut of every save, for one optimizer, on each programming rule and both
/// tears (a torn word with nothing programmed, or half of it).
fn every_rule<O>(name: &str, optimizer: O, episodes: usize)
where
    O: Optimizer<2> + Persistent + Clone,
{
    for rule in Programming::ALL {
        for tear_bytes in [0, WORD / 2] {
            let sweep = cut_everywhere(optimizer.clone(), episodes, rule, tear_bytes);
            report(name, rule, tear_bytes, sweep);
        }
    }
}

/// The sweep on write-once words with half of the torn word programmed, for the optimizers
/// that [`every_rule`] does not sweep.
fn write_once<O>(name: &str, optimizer: O, episodes: usize)
where
    O: Optimizer<2> + Persistent + Clone,
{
    let rule = Programming::WriteOnce;
    report(
        name,
        rule,
        WORD / 2,
        cut_everywhere(optimizer, episodes, rule, WORD / 2),
    );
}

/// Checks, for CMA-ES inside the adapter, every power cut of every save on each programming
/// rule (write-once words, AND-programming, re-writable zeros) and both tears: boot finds
/// the state before or after the save, every later save succeeds, and learning ends as if
/// never cut. On write-once words a torn page marker cannot be written again: the store
/// must erase the slot rather than fail every later save.
#[test]
fn cmaes_survives_every_power_cut_on_each_programming_rule() {
    let o = Cmaes::<2, 4>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    every_rule("CMA-ES", o, EPISODES);
}

/// Checks, for the coordinate search inside the adapter, every power cut of every save on
/// write-once words: boot finds the state before or after the save, and learning ends as if
/// never cut.
#[test]
fn coordinate_search_survives_every_power_cut() {
    let config = CoordinateConfig {
        initial_step: 2.0,
        ..CoordinateConfig::DEFAULT
    };
    let o = CoordinateSearch::try_new(bounds(), Vector::zeros(), config).unwrap();
    write_once("coordinate search", o, EPISODES);
}

/// As above, for SRACOS.
#[test]
fn sracos_survives_every_power_cut() {
    let o = Sracos::<2>::try_new(bounds(), SracosConfig::DEFAULT).unwrap();
    write_once("SRACOS", o, EPISODES);
}

/// As above, for the diagonal CEM (batches of 4: the run crosses batch updates).
#[test]
fn diagonal_cem_survives_every_power_cut() {
    let o = DiagonalCem::<2, 4, 2>::try_new(bounds(), Vector::zeros(), CemConfig::DEFAULT).unwrap();
    write_once("diagonal CEM", o, EPISODES);
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
    write_once("ROCK*", o, 6);
}

/// Checks: boot on erased flash finds nothing and learning starts fresh; after a run, on
/// each programming rule, a corrupted byte anywhere in the flash (each byte in turn, every
/// bit flipped) never panics and boot loads the newest checkpoint, or the one before it when
/// the byte spoilt the newest; never anything else. The next save succeeds and is the one
/// found next, even when it lands on the corrupted byte. A checkpoint of other sizes is
/// refused by name, and saving afresh over it works.
#[test]
fn corrupted_bytes_fall_back_to_the_newest_intact_checkpoint() {
    type Learn = Learner<Learning<Cmaes<2, 4>>>;
    let o = Cmaes::<2, 4>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    let initial = learner(o);
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let mut blank = erased(Programming::WriteOnce);
    let mut s = store(&mut blank);
    assert!(s.load::<Learn>(&mut rec, &mut item).unwrap().is_none());
    assert_eq!(s.generation(), None);

    let mut flash = erased(Programming::WriteOnce);
    for rule in Programming::ALL {
        let r = reference(&initial, EPISODES, rule);
        flash = r.images[EPISODES - 1].clone();
        let last = record::load::<Learn>(&r.records[EPISODES]).unwrap();
        store(&mut flash).save(&last, &mut rec, &mut item).unwrap();
        let (mut newest, mut fallback) = (0, 0);
        for at in 0..FLASH {
            let mut bad = flash.clone();
            bad.corrupt(at, 0xff);
            let mut s = store(&mut bad);
            let booted = boot(&mut s, &initial);
            let found = bytes(&booted);
            if found == r.records[EPISODES] {
                newest += 1;
            } else {
                assert_eq!(found, r.records[EPISODES - 1], "{}, byte {at}", rule.name());
                fallback += 1;
            }
            let mut next = booted.clone();
            episode(&mut next);
            s.save(&next, &mut rec, &mut item).unwrap();
            let again = bytes(&boot(&mut store(&mut bad), &initial));
            assert!(
                again == bytes(&next),
                "{}, byte {at}: boot loaded another state than the one saved",
                rule.name()
            );
        }
        println!(
            "corrupted bytes, {}: {FLASH} bytes flipped in turn; {newest} kept the newest \
             checkpoint, {fallback} fell back to the one before; every next save was found",
            rule.name()
        );
        assert!(fallback > 0 && newest > 0);
    }
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

/// A value whose checks refuse an odd count; [`Lax`] has its shape and no checks, so it
/// writes the intact but invalid records a faulty writer would.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct Strict {
    count: u32,
}

impl Persistent for Strict {
    const SHAPE: Shape = Shape::new(*b"STRC", &[]);

    fn validate(&self) -> Result<(), ctrl_adapt::Error> {
        if self.count.is_multiple_of(2) {
            Ok(())
        } else {
            Err(ctrl_adapt::Error::InvalidParameter("count"))
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct Lax {
    count: u32,
}

impl Persistent for Lax {
    const SHAPE: Shape = Strict::SHAPE;

    fn validate(&self) -> Result<(), ctrl_adapt::Error> {
        Ok(())
    }
}

/// Checks: a save of a value that `load` would refuse returns an error and writes nothing
/// (the previous checkpoint is still the one found); an intact newest checkpoint that fails
/// its checks is passed over for the older one, and `passed_over` says why; with no older
/// one, `load` says why instead of `Ok(None)` (erased flash), and a save afresh then works.
#[test]
fn a_checkpoint_that_cannot_come_back_is_refused_and_said() {
    let invalid = CheckpointError::Record(RecordError::Invalid(
        ctrl_adapt::Error::InvalidParameter("count"),
    ));
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    let mut flash = erased(Programming::WriteOnce);
    let mut s = store(&mut flash);
    s.save(&Strict { count: 2 }, &mut rec, &mut item).unwrap();
    assert_eq!(
        s.save(&Strict { count: 3 }, &mut rec, &mut item),
        Err(invalid)
    );
    let mut s = store(&mut flash);
    assert_eq!(
        s.load::<Strict>(&mut rec, &mut item),
        Ok(Some(Strict { count: 2 }))
    );
    assert_eq!(s.passed_over(), None);

    // A faulty writer's record, newest: the older checkpoint, and why.
    store(&mut flash)
        .save(&Lax { count: 5 }, &mut rec, &mut item)
        .unwrap();
    let mut s = store(&mut flash);
    assert_eq!(
        s.load::<Strict>(&mut rec, &mut item),
        Ok(Some(Strict { count: 2 }))
    );
    assert_eq!(s.passed_over(), Some(invalid));
    // The next save replaces the refused one; the store then loads it without comment.
    s.save(&Strict { count: 4 }, &mut rec, &mut item).unwrap();
    let mut s = store(&mut flash);
    assert_eq!(
        s.load::<Strict>(&mut rec, &mut item),
        Ok(Some(Strict { count: 4 }))
    );
    assert_eq!(s.passed_over(), None);

    // Alone on the flash, the refused checkpoint is an error, not "nothing saved".
    let mut flash = erased(Programming::WriteOnce);
    store(&mut flash)
        .save(&Lax { count: 7 }, &mut rec, &mut item)
        .unwrap();
    let mut s = store(&mut flash);
    assert_eq!(s.load::<Strict>(&mut rec, &mut item), Err(invalid));
    s.save(&Strict { count: 8 }, &mut rec, &mut item).unwrap();
    assert_eq!(
        store(&mut flash).load::<Strict>(&mut rec, &mut item),
        Ok(Some(Strict { count: 8 }))
    );
}

/// Saves `l` after each of `saves` more episodes into `flash`, booting afresh before each
/// save, and checks that every save succeeds and that a fresh boot then loads exactly it.
fn save_and_read_back<O>(
    mut l: Learner<Learning<O>>,
    flash: &mut Flash,
    initial: &Learner<Learning<O>>,
    saves: usize,
    case: &str,
) where
    O: Optimizer<2> + Persistent + Clone,
{
    let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
    for n in 0..saves {
        episode(&mut l);
        let mut s = store(flash);
        let found = s.load::<Learner<Learning<O>>>(&mut rec, &mut item).err();
        assert!(
            matches!(found, None | Some(CheckpointError::Record(_))),
            "{case}, save {n}: boot {found:?}"
        );
        let saved = s.save(&l, &mut rec, &mut item);
        assert_eq!(saved, Ok(()), "{case}, save {n}");
        let back = boot(&mut store(flash), initial);
        assert!(
            bytes(&back) == bytes(&l),
            "{case}, save {n}: boot loaded another state than the one saved"
        );
    }
}

/// Images of the whole flash left by something else: random bytes; random words among
/// erased ones; pages each erased, random, or written part-way (random words, then erased);
/// and another firmware's checkpoints (another optimizer, slots of two pages at other
/// offsets) with a random page after them. Fixed seeds.
fn leftover_images() -> Vec<(String, Vec<u8>)> {
    use rand_core::RngCore;
    let mut images = Vec::new();
    for seed in 0..8u64 {
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
        let mut random = vec![0u8; FLASH];
        rng.fill_bytes(&mut random);
        images.push((format!("random bytes (seed {seed})"), random.clone()));
        let mut words = random.clone();
        for w in words.chunks_mut(WORD) {
            if rng.next_u32() % 2 == 0 {
                w.fill(0xff);
            }
        }
        images.push((format!("random and erased words (seed {seed})"), words));
        let mut pages = random;
        for p in pages.chunks_mut(PAGE) {
            match rng.next_u32() % 3 {
                0 => p.fill(0xff),
                1 => {}
                _ => {
                    let used = (rng.next_u32() as usize % (PAGE / WORD)) * WORD;
                    p[used..].fill(0xff);
                }
            }
        }
        images.push((
            format!("erased, random and part-written pages (seed {seed})"),
            pages,
        ));
    }
    // Another firmware: coordinate search checkpoints in slots of two pages from page 1.
    let mut other = erased(Programming::And);
    {
        let config = CoordinateConfig::DEFAULT;
        let o = CoordinateSearch::try_new(bounds(), Vector::zeros(), config).unwrap();
        let mut l = learner(o);
        let slots = [
            PAGE as u32..3 * PAGE as u32,
            3 * PAGE as u32..5 * PAGE as u32,
        ];
        let mut s = CheckpointStore::try_new(BlockingAsync::new(&mut other), slots).unwrap();
        let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
        for _ in 0..7 {
            episode(&mut l);
            s.save(&l, &mut rec, &mut item).unwrap();
        }
    }
    let mut image = other.data;
    Xoshiro128PlusPlus::seed_from_u64(99).fill_bytes(&mut image[5 * PAGE..]);
    images.push(("another firmware's checkpoints".to_string(), image));
    images
}

/// Checks, on each programming rule, a first boot on a flash full of leftover data (the
/// images of [`leftover_images`]): boot does not fail (nothing found, or another type's
/// checkpoint refused by name), and each of 4 saves after it returns `Ok` and is what a
/// fresh boot loads, bit for bit.
#[test]
fn leftover_data_at_first_boot_is_cleared_not_trusted() {
    let o = Cmaes::<2, 4>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    let initial = learner(o);
    let images = leftover_images();
    for rule in Programming::ALL {
        for (name, image) in &images {
            let mut flash = CutFlash::with_image(image.clone(), rule);
            let case = format!("{}, {name}", rule.name());
            save_and_read_back(initial.clone(), &mut flash, &initial, 4, &case);
        }
        println!(
            "leftover data, {}: {} images at first boot, 4 saves each, every one read back",
            rule.name(),
            images.len()
        );
    }
}

/// Checks, on each programming rule: after a run of 12 saves, a stray word programmed into
/// any erased word of the flash (each in turn) leaves boot on the newest checkpoint or the
/// one before (a stray word on a page's start marker, or where `sequential-storage` reads the
/// next item header, spoils the newest slot's map), never anything else, and
/// each of 3 saves after it returns `Ok` and is what a fresh boot loads, bit for bit.
#[test]
fn a_stray_word_in_free_space_never_loses_a_save() {
    let o = Cmaes::<2, 4>::try_new(bounds(), Vector::zeros(), CmaesConfig::DEFAULT).unwrap();
    let initial = learner(o);
    for rule in Programming::ALL {
        let r = reference(&initial, EPISODES, rule);
        let mut flash = r.images[EPISODES - 1].clone();
        let last = record::load::<Learner<Learning<Cmaes<2, 4>>>>(&r.records[EPISODES]).unwrap();
        let (mut rec, mut item) = ([0u8; RECORD], [0u8; ITEM]);
        store(&mut flash).save(&last, &mut rec, &mut item).unwrap();
        let (mut words, mut newest) = (0, 0);
        for at in (0..FLASH).step_by(WORD) {
            if flash.data[at..at + WORD] != [0xff; WORD] {
                continue;
            }
            let mut stray = flash.clone();
            stray.poke(at, [0x5a, 0xa5, 0x00, 0xff]);
            let booted = boot(&mut store(&mut stray), &initial);
            let found = bytes(&booted);
            if found == r.records[EPISODES] {
                newest += 1;
            } else {
                assert_eq!(found, r.records[EPISODES - 1], "{}, word {at}", rule.name());
            }
            let case = format!("{}, stray word at {at}", rule.name());
            save_and_read_back(booted, &mut stray, &initial, 3, &case);
            words += 1;
        }
        println!(
            "stray word, {}: {words} erased words tried in turn; boot kept the newest \
             checkpoint {newest} times, the one before {} times; 3 saves after each, every \
             one read back",
            rule.name(),
            words - newest
        );
    }
}

/// A common internal-flash page, for the size and wear figures.
const BIG_PAGE: usize = 4096;

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
    let mut flash = CutFlash::<BIG_PAGE>::erased(2 * slot as usize, Programming::WriteOnce);
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
