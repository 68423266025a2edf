//! Polled driver for the CMSDK APB UART of the MPS2 boards, with [`embedded_io`] traits, so
//! the PIL code ([`pil_link`]) runs over it exactly as it would over a HAL's UART.
//!
//! Registers (Arm Cortex-M System Design Kit TRM, DDI0479; QEMU `hw/char/cmsdk-apb-uart.c`):
//! `DATA` at +0x00, `STATE` at +0x04 (bit 0 TX buffer full, bit 1 RX buffer full, bits 2–3
//! TX/RX overrun, write 1 to clear), `CTRL` at +0x08 (bit 0 TX enable, bit 1 RX enable),
//! `BAUDDIV` at +0x10 (≥ 16). On QEMU's mps2-an386, UART0 is at 0x4000_4000
//! (`hw/arm/mps2.c`) and is the first `-serial` backend; the emulated line has no baud rate.

use core::ptr::{read_volatile, write_volatile};

/// Base address of UART0 on mps2-an385/an386.
pub const UART0_BASE: usize = 0x4000_4000;

/// UART0's receive interrupt on mps2-an385/an386 (external interrupt 0; TX is 1).
pub const UART0_RX_IRQ: u16 = 0;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const INTSTATUS: usize = 0x0C;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const STATE_RX_OVERRUN: u32 = 1 << 3;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_RX_INT_EN: u32 = 1 << 3;
const INT_RX: u32 = 1 << 1;

/// A received byte was lost because the previous one had not been read (RX overrun).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct Overrun;

impl core::fmt::Display for Overrun {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("UART receive overrun")
    }
}

impl core::error::Error for Overrun {}

impl embedded_io::Error for Overrun {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

/// One CMSDK UART, owned.
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// Takes the UART at `base` and enables its transmitter and receiver with `bauddiv`
    /// (the PCLK divider, at least 16; the emulator ignores the rate).
    ///
    /// # Safety
    /// `base` must be the address of a CMSDK APB UART, and nothing else may access that
    /// UART while the returned value lives (it does unsynchronised register accesses).
    pub unsafe fn new(base: usize, bauddiv: u32) -> Self {
        let uart = Self { base };
        uart.write_reg(BAUDDIV, bauddiv.max(16));
        uart.write_reg(CTRL, CTRL_TX_EN | CTRL_RX_EN);
        uart
    }

    /// Raises the receive interrupt line when a byte arrives (until
    /// [`CmsdkUart::clear_rx_interrupt`]), so a core waiting in `wfi` wakes up for it.
    pub fn enable_rx_interrupt(&mut self) {
        self.write_reg(CTRL, self.read_reg(CTRL) | CTRL_RX_INT_EN);
    }

    /// Lowers the receive interrupt line (write 1 to clear).
    pub fn clear_rx_interrupt(&mut self) {
        self.write_reg(INTSTATUS, INT_RX);
    }

    fn read_reg(&self, offset: usize) -> u32 {
        // SAFETY: `new`'s contract: `base + offset` is a register of a CMSDK UART that this
        // value owns; a volatile 32-bit access is how the device is meant to be accessed.
        unsafe { read_volatile((self.base + offset) as *const u32) }
    }

    fn write_reg(&self, offset: usize, value: u32) {
        // SAFETY: as in `read_reg`.
        unsafe { write_volatile((self.base + offset) as *mut u32, value) }
    }
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Overrun;
}

impl embedded_io::ReadReady for CmsdkUart {
    fn read_ready(&mut self) -> Result<bool, Overrun> {
        Ok(self.read_reg(STATE) & STATE_RX_FULL != 0)
    }
}

impl embedded_io::Read for CmsdkUart {
    /// Blocks until a byte arrives, then returns it (the receiver holds one byte).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Overrun> {
        let Some(first) = buf.first_mut() else {
            return Ok(0);
        };
        loop {
            let state = self.read_reg(STATE);
            if state & STATE_RX_OVERRUN != 0 {
                self.write_reg(STATE, STATE_RX_OVERRUN); // write 1 to clear
                return Err(Overrun);
            }
            if state & STATE_RX_FULL != 0 {
                *first = self.read_reg(DATA) as u8;
                return Ok(1);
            }
        }
    }
}

impl embedded_io::WriteReady for CmsdkUart {
    fn write_ready(&mut self) -> Result<bool, Overrun> {
        Ok(self.read_reg(STATE) & STATE_TX_FULL == 0)
    }
}

impl embedded_io::Write for CmsdkUart {
    /// Blocks until the transmitter has room, then writes as many bytes as it takes.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Overrun> {
        if buf.is_empty() {
            return Ok(0);
        }
        while self.read_reg(STATE) & STATE_TX_FULL != 0 {}
        let mut written = 0;
        for &byte in buf {
            if self.read_reg(STATE) & STATE_TX_FULL != 0 {
                break;
            }
            self.write_reg(DATA, u32::from(byte));
            written += 1;
        }
        Ok(written)
    }

    /// Waits until the transmit buffer has room again (the CMSDK UART has no
    /// "shift register empty" flag).
    fn flush(&mut self) -> Result<(), Overrun> {
        while self.read_reg(STATE) & STATE_TX_FULL != 0 {}
        Ok(())
    }
}
