//! Stack high-water mark: cortex-m-rt's reset handler paints the whole stack before `main`
//! (its `paint-stack` feature, with [`cortex_m_rt::STACK_PAINT_VALUE`]), and the untouched
//! part is measured later, so the RAM figure reported covers the stack as well as the
//! statics.

use core::ptr::{addr_of, read_volatile};
use cortex_m_rt::STACK_PAINT_VALUE;

extern "C" {
    // The board's memory map: the stack runs from `_stack_start` (the top of the CCM) down to
    // `_stack_end` (its bottom); both are what the reset handler paints between. cortex-m-rt's
    // linker script: the statics run from `_ram_start` to `__sheap`.
    static _stack_start: u32;
    static _stack_end: u32;
    static _ram_start: u32;
    static __sheap: u32;
}

fn bounds() -> (usize, usize) {
    // Only the symbols' addresses are taken, never their contents.
    (addr_of!(_stack_end) as usize, addr_of!(_stack_start) as usize)
}

/// The most stack used since boot, in bytes: from the top down to the lowest word that no
/// longer holds the paint.
pub fn high_water() -> usize {
    let (low, top) = bounds();
    let mut a = low;
    // SAFETY: reads within the stack region, word-aligned (cortex-m-rt aligns both ends).
    while a < top && unsafe { read_volatile(a as *const u32) } == STACK_PAINT_VALUE {
        a += 4;
    }
    top - a
}

/// Bytes of RAM the statics take (data, bss, uninit): from the start of RAM to the end of
/// the last of them.
pub fn statics() -> usize {
    // Only the symbols' addresses are taken.
    addr_of!(__sheap) as usize - addr_of!(_ram_start) as usize
}
