//! A NOR flash in RAM for the checkpoint tests: 4-byte words, pages of `PAGE` bytes, one of
//! three [`Programming`] rules, and a power cut at the k-th word written or erased.
//!
//! Real parts differ in what a second program of a word does, and a checkpoint store must
//! survive each:
//!
//! | rule | a word programmed again (no erase between) | parts |
//! | --- | --- | --- |
//! | [`Programming::WriteOnce`] | refused, whatever the data (the word's ECC is written) | STM32H7-class |
//! | [`Programming::And`] | accepted: the new bits are ANDed in (1 → 0 only) | nRF52 NVMC |
//! | [`Programming::RewritableZeros`] | accepted only when the new data is all zeros | STM32L4/G4-class |
//!
//! A power cut tears the word being written (its first [`CutFlash::tear_bytes`] bytes are
//! programmed, and the word counts as programmed) or the page being erased (erased up to the
//! word), and every later operation fails until [`CutFlash::reboot`]. The flash can start
//! erased, or hold any image (another firmware's leftovers, a stray word): a word that is not
//! all `0xFF` counts as programmed.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// The flash's write (and read) unit.
pub const WORD: usize = 4;

/// What the flash does with a second program of a word (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Programming {
    /// A word can be programmed once per erase; a second program fails, even when the first
    /// was cut before any bit changed.
    WriteOnce,
    /// A program ANDs its bits into the word, any number of times, and never fails.
    And,
    /// A programmed word can be programmed again with zeros only; other data fails.
    RewritableZeros,
}

impl Programming {
    /// The three rules.
    pub const ALL: [Self; 3] = [Self::WriteOnce, Self::And, Self::RewritableZeros];

    /// The rule's name, for test output.
    pub fn name(self) -> &'static str {
        match self {
            Self::WriteOnce => "write-once words",
            Self::And => "AND-programming",
            Self::RewritableZeros => "re-writable zeros",
        }
    }
}

/// Why the flash refused an operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashError {
    /// The power is off (this operation was the cut one, or came after it).
    PowerCut,
    /// A program of a word the rule does not let be programmed again.
    Refused,
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

/// The test flash (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct CutFlash<const PAGE: usize> {
    /// The flash's bytes.
    pub data: Vec<u8>,
    /// Which words have been programmed since their last erase.
    programmed: Vec<bool>,
    /// What a second program of a word does.
    pub rule: Programming,
    /// Bytes of a torn word that get programmed (0 to [`WORD`]).
    pub tear_bytes: usize,
    /// Words written or erased since the last [`cut_after`](Self::cut_after) or reboot.
    pub ops: u64,
    /// Pages erased, over the flash's life.
    pub erases: u64,
    /// Bytes programmed, over the flash's life.
    pub written: u64,
    cut_at: Option<u64>,
    dead: bool,
}

impl<const PAGE: usize> CutFlash<PAGE> {
    /// An erased flash of `len` bytes (a whole number of pages) under `rule`; a torn word
    /// gets half its bytes programmed.
    pub fn erased(len: usize, rule: Programming) -> Self {
        Self::with_image(vec![0xff; len], rule)
    }

    /// A flash that holds `image` (a whole number of pages): every word not all `0xFF`
    /// counts as programmed.
    pub fn with_image(image: Vec<u8>, rule: Programming) -> Self {
        assert!(image.len().is_multiple_of(PAGE), "a whole number of pages");
        let programmed = image
            .chunks(WORD)
            .map(|w| w.iter().any(|&b| b != 0xff))
            .collect();
        Self {
            data: image,
            programmed,
            rule,
            tear_bytes: WORD / 2,
            ops: 0,
            erases: 0,
            written: 0,
            cut_at: None,
            dead: false,
        }
    }

    /// Programs `word` at byte `at` outside the store (a stray write), as the rule would.
    pub fn poke(&mut self, at: usize, word: [u8; WORD]) {
        for (d, s) in self.data[at..at + WORD].iter_mut().zip(word) {
            *d &= s;
        }
        self.programmed[at / WORD] = true;
    }

    /// Flips the bits of `mask` in the byte at `at` outside the store (a corrupted byte);
    /// its word counts as programmed unless it reads erased.
    pub fn corrupt(&mut self, at: usize, mask: u8) {
        self.data[at] ^= mask;
        let word = at / WORD * WORD;
        self.programmed[at / WORD] |= self.data[word..word + WORD] != [0xff; WORD];
    }

    /// Counts one word operation: `Some(true)` when it completes, `Some(false)` when the
    /// power fails during it (it is torn), `None` when the power was already off.
    fn power(&mut self) -> Option<bool> {
        if self.dead {
            return None;
        }
        self.ops += 1;
        self.dead = self.cut_at == Some(self.ops);
        Some(!self.dead)
    }

    /// Power back: no cut planned, the counter at zero.
    pub fn reboot(&mut self) {
        self.dead = false;
        self.cut_at = None;
        self.ops = 0;
    }

    /// Cuts the power at the `k`-th word operation from now.
    pub fn cut_after(&mut self, k: u64) {
        self.ops = 0;
        self.cut_at = Some(k);
    }

    fn aligned(&self, at: usize, len: usize, unit: usize) -> bool {
        at.is_multiple_of(unit) && len.is_multiple_of(unit) && at + len <= self.data.len()
    }
}

impl<const PAGE: usize> ErrorType for CutFlash<PAGE> {
    type Error = FlashError;
}

impl<const PAGE: usize> ReadNorFlash for CutFlash<PAGE> {
    const READ_SIZE: usize = WORD;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let at = offset as usize;
        if self.dead {
            return Err(FlashError::PowerCut);
        }
        if !self.aligned(at, bytes.len(), WORD) {
            return Err(FlashError::Bounds);
        }
        bytes.copy_from_slice(&self.data[at..at + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.data.len()
    }
}

impl<const PAGE: usize> NorFlash for CutFlash<PAGE> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let (from, to) = (from as usize, to as usize);
        if from > to || !self.aligned(from, to - from, PAGE) {
            return Err(FlashError::Bounds);
        }
        for word in (from..to).step_by(WORD) {
            if self.power() != Some(true) {
                return Err(FlashError::PowerCut);
            }
            self.data[word..word + WORD].fill(0xff);
            self.programmed[word / WORD] = false;
        }
        self.erases += ((to - from) / PAGE) as u64;
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let at = offset as usize;
        if !self.aligned(at, bytes.len(), WORD) {
            return Err(FlashError::Bounds);
        }
        for (i, word) in bytes.chunks(WORD).enumerate() {
            let place = at + i * WORD;
            let again = self.programmed[place / WORD];
            let refused = match self.rule {
                Programming::WriteOnce => again,
                Programming::And => false,
                Programming::RewritableZeros => again && word.iter().any(|&b| b != 0),
            };
            if refused {
                return Err(FlashError::Refused);
            }
            let Some(complete) = self.power() else {
                return Err(FlashError::PowerCut);
            };
            let programmed = if complete {
                WORD
            } else {
                self.tear_bytes.min(WORD)
            };
            for (d, s) in self.data[place..place + programmed].iter_mut().zip(word) {
                *d &= s;
            }
            self.programmed[place / WORD] = true;
            self.written += programmed as u64;
            if !complete {
                return Err(FlashError::PowerCut);
            }
        }
        Ok(())
    }
}
