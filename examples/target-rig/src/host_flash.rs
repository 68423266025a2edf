//! A NOR flash that lives on the host, behind a link: the firmware's flash operations go as
//! requests through two files opened by semihosting (named pipes that the host's PIL harness
//! serves, `cargo run -p host-tests --bin pil -- --persist`), and the host keeps the flash's
//! bytes in a file of its own. The flash so outlives the emulator: QEMU can be killed at any
//! instruction and restarted, and the firmware finds on the "flash" every word the host
//! acknowledged.
//!
//! Requests (firmware → host, on `flash-req`), answers (host → firmware, on `flash-resp`):
//!
//! ```text
//! b'R' offset:u32 len:u32          → len bytes
//! b'W' offset:u32 len:u32 bytes    → status:u8 (0: done)
//! b'E' from:u32   to:u32           → status:u8 (0: done)
//! ```
//!
//! (integers little-endian). The host applies a write as NOR flash does (bits only go from 1
//! to 0) and an erase sets its pages to `0xFF`. Geometry: [`auv_survey::checkpoint`]'s
//! layout, 4-byte words, 2 KiB pages.

use auv_survey::checkpoint::{FLASH_SIZE, PAGE};
use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use semihosting::fs::File;
use semihosting::io::{Read, Write};

/// Why a flash operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum HostFlashError {
    /// Outside the flash.
    OutOfBounds,
    /// Not aligned to the word (write) or page (erase).
    NotAligned,
    /// The link to the host failed, or the host refused the operation.
    Link,
}

impl NorFlashError for HostFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::Link => NorFlashErrorKind::Other,
        }
    }
}

/// The host's flash (see the [module docs](self)).
pub struct HostFlash {
    requests: File,
    answers: File,
}

impl HostFlash {
    /// Opens the two pipes in QEMU's working directory (each open waits for the host's end).
    pub fn open() -> Result<Self, HostFlashError> {
        let requests = File::create(c"flash-req").map_err(|_| HostFlashError::Link)?;
        let answers = File::open(c"flash-resp").map_err(|_| HostFlashError::Link)?;
        Ok(Self { requests, answers })
    }

    fn request(&mut self, op: u8, a: u32, b: u32, data: &[u8]) -> Result<(), HostFlashError> {
        let mut header = [0u8; 9];
        header[0] = op;
        header[1..5].copy_from_slice(&a.to_le_bytes());
        header[5..9].copy_from_slice(&b.to_le_bytes());
        self.requests
            .write_all(&header)
            .and_then(|()| self.requests.write_all(data))
            .map_err(|_| HostFlashError::Link)
    }

    fn status(&mut self) -> Result<(), HostFlashError> {
        let mut status = [0xFF];
        self.answers
            .read_exact(&mut status)
            .map_err(|_| HostFlashError::Link)?;
        if status[0] == 0 {
            Ok(())
        } else {
            Err(HostFlashError::Link)
        }
    }
}

fn check(offset: u32, len: usize, align: u32) -> Result<u32, HostFlashError> {
    let len = u32::try_from(len).map_err(|_| HostFlashError::OutOfBounds)?;
    if offset.checked_add(len).is_none_or(|end| end > FLASH_SIZE) {
        return Err(HostFlashError::OutOfBounds);
    }
    if !offset.is_multiple_of(align) || !len.is_multiple_of(align) {
        return Err(HostFlashError::NotAligned);
    }
    Ok(len)
}

impl ErrorType for HostFlash {
    type Error = HostFlashError;
}

impl ReadNorFlash for HostFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), HostFlashError> {
        let len = check(offset, bytes.len(), 1)?;
        self.request(b'R', offset, len, &[])?;
        self.answers
            .read_exact(bytes)
            .map_err(|_| HostFlashError::Link)
    }

    fn capacity(&self) -> usize {
        FLASH_SIZE as usize
    }
}

impl NorFlash for HostFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), HostFlashError> {
        let len = to.checked_sub(from).ok_or(HostFlashError::OutOfBounds)?;
        check(from, len as usize, PAGE)?;
        self.request(b'E', from, to, &[])?;
        self.status()
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), HostFlashError> {
        let len = check(offset, bytes.len(), 4)?;
        self.request(b'W', offset, len, bytes)?;
        self.status()
    }
}
