//! Peak stack use by paint and scan.
//!
//! cortex-m-rt's `paint-stack` feature fills the whole stack region, from `_stack_end`
//! (just above `.bss`/`.uninit`) up to `_stack_start` (the initial stack pointer, the end of
//! RAM), with `0xCCCC_CCCC` before `main` runs. The stack grows down from `_stack_start`, so
//! the lowest word that no longer holds the paint marks the deepest point it has reached.
//! A frame that happens to store `0xCCCC_CCCC` at its deepest word would be missed, which
//! can only under-count by that word's frame remainder; in practice the figure is exact to the
//! word.

/// The paint value of cortex-m-rt's `paint-stack` feature.
pub const PAINT: u32 = 0xCCCC_CCCC;

unsafe extern "C" {
    // Linker symbols of cortex-m-rt's link.x; only their addresses are used.
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Bytes of stack used so far (the deepest point since reset).
pub fn peak_bytes() -> u32 {
    let top = (&raw const _stack_start) as usize;
    let bottom = (&raw const _stack_end) as usize;
    let mut addr = bottom;
    while addr < top {
        // SAFETY: `addr` is word-aligned (cortex-m-rt aligns `_stack_end` to 4) and inside
        // the stack region [_stack_end, _stack_start), which is RAM owned by no Rust object
        // below the live stack; a volatile read of it has no side effect.
        let word = unsafe { core::ptr::read_volatile(addr as *const u32) };
        if word != PAINT {
            break;
        }
        addr += 4;
    }
    (top - addr) as u32
}

/// Bytes in the whole stack region (RAM left over after `.data`, `.bss` and `.uninit`).
pub fn region_bytes() -> u32 {
    ((&raw const _stack_start) as usize - (&raw const _stack_end) as usize) as u32
}
