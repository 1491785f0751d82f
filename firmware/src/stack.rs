//! Stack high-water mark: the stack region is painted at boot and the untouched part is
//! measured later, so the RAM figure reported covers the stack as well as the statics.

use core::ptr::{addr_of, read_volatile, write_volatile};

const PAINT: u32 = 0x5A5A_A5A5;
/// Bytes under the current stack pointer left unpainted: the painting function's own frame.
const MARGIN: usize = 256;

extern "C" {
    // cortex-m-rt's linker script: the stack runs from `_stack_start` (top of RAM) down to
    // `_stack_end` (the end of the statics).
    static _stack_start: u32;
    static _stack_end: u32;
}

fn bounds() -> (usize, usize) {
    // Only the symbols' addresses are taken, never their contents.
    (addr_of!(_stack_end) as usize, addr_of!(_stack_start) as usize)
}

/// Paints the free stack. Call first thing in `main`.
#[inline(never)]
pub fn paint() {
    let (low, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let mut a = low;
    while a + 4 <= sp.saturating_sub(MARGIN) {
        // SAFETY: [low, sp - MARGIN) is stack that no frame uses yet.
        unsafe { write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
}

/// The most stack used since [`paint`], in bytes.
pub fn high_water() -> usize {
    let (low, top) = bounds();
    let mut a = low;
    // SAFETY: reads within the stack region, word-aligned (cortex-m-rt aligns both ends).
    while a < top && unsafe { read_volatile(a as *const u32) } == PAINT {
        a += 4;
    }
    top - a
}

/// Bytes of RAM the statics take (data, bss, uninit): from the start of RAM to the stack.
pub fn statics() -> usize {
    const RAM_ORIGIN: usize = 0x2000_0000;
    bounds().0 - RAM_ORIGIN
}
