//! Peak stack use by paint and scan.
//!
//! cortex-m-rt's `paint-stack` feature fills the whole stack region, from `_stack_end`
//! (just above `.bss`/`.uninit`) up to `_stack_start` (the initial stack pointer, the end of
//! RAM), with `0xCCCC_CCCC` before `main` runs. The stack grows down from `_stack_start`, so
//! the lowest word that no longer holds the paint marks the deepest point it has reached.
//! A frame that happens to store `0xCCCC_CCCC` at its deepest word would be missed, which
//! can only under-count by that word's frame remainder; in practice the figure is exact to the
//! word. [`measure`] paints again below the current frame, to measure one call's stack.

/// The paint value of cortex-m-rt's `paint-stack` feature.
pub const PAINT: u32 = 0xCCCC_CCCC;

unsafe extern "C" {
    // Linker symbols of cortex-m-rt's link.x; only their addresses are used.
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Bytes of stack used so far (the deepest point since reset, or since the last
/// [`measure`], which paints again).
pub fn peak_bytes() -> u32 {
    ((&raw const _stack_start) as usize - deepest_used()) as u32
}

/// Runs `f` and returns its result with the stack it used below the caller's frame, in
/// bytes: the free stack below the current stack pointer is painted again, `f` runs, and the
/// scan finds the deepest word it scrubbed. Its frame, its callees' and anything they keep
/// on the stack (an optimizer built inside `f`) are counted; the caller's frame is not.
///
/// Afterwards [`peak_bytes`] reports the deepest point since this call, not since reset.
#[inline(always)]
pub fn measure<R>(f: impl FnOnce() -> R) -> (R, u32) {
    let caller = cortex_m::register::msp::read() as usize;
    paint_below_here();
    let r = core::hint::black_box(f());
    (r, caller.saturating_sub(deepest_used()) as u32)
}

/// Bytes left unpainted below the stack pointer that [`paint_below_here`] reads: LLVM may
/// read it before the function pushes its own registers (shrink-wrapping), and those pushes
/// must not be painted over. Only a call that uses less stack than this is over-counted.
const PAINT_GUARD: usize = 64;

/// Paints the stack region from `_stack_end` up to [`PAINT_GUARD`] bytes below this
/// function's stack pointer, which is below every live frame. Never inlined, so that the
/// frame it paints under is its own small one, not the caller's.
#[inline(never)]
fn paint_below_here() {
    let below = (cortex_m::register::msp::read() as usize).saturating_sub(PAINT_GUARD);
    let mut addr = (&raw const _stack_end) as usize;
    while addr < below {
        // SAFETY: `addr` is word-aligned (cortex-m-rt aligns `_stack_end` to 4) and inside
        // [_stack_end, SP): stack that no live frame uses (the stack grows down from SP, and
        // the Cortex-M has no red zone below it), owned by no Rust object. With no interrupt
        // enabled nothing else writes there while this loop runs (a fault's exception frame
        // would, and the fault handler ends the run).
        unsafe { core::ptr::write_volatile(addr as *mut u32, PAINT) };
        addr += 4;
    }
}

/// Address of the deepest stack word that no longer holds the paint (`_stack_start` if none
/// was scrubbed).
fn deepest_used() -> usize {
    let top = (&raw const _stack_start) as usize;
    let mut addr = (&raw const _stack_end) as usize;
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
    addr
}

/// Bytes in the whole stack region (RAM left over after `.data`, `.bss` and `.uninit`).
pub fn region_bytes() -> u32 {
    ((&raw const _stack_start) as usize - (&raw const _stack_end) as usize) as u32
}
