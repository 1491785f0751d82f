//! The benchmark markers: two symbols an external instruction counter breaks on around each
//! window's processing (`firmware/tools/insn_count.c`), and the clock through which the
//! detector calls them, so that they bracket the work however deep the detector sits.

use crate::board::SysTickClock;
use evcal_core::detect::Clock;

/// Marks the start of one window's processing for an external instruction counter (the
/// `qemu-insn-count` plugin breaks on this symbol). Its body differs from [`bench_stop`]'s
/// so that the linker cannot fold the two into one address.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_start() {
    cortex_m::asm::nop();
}

/// Marks the end of one window's processing (see [`bench_start`]).
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_stop() {
    cortex_m::asm::nop();
    cortex_m::asm::nop();
}

/// The board's SysTick clock, calling the `#[no_mangle]` marker functions that the
/// instruction counter breaks on around each window's clustering and fitting.
#[derive(Clone, Copy)]
pub struct MarkedClock(pub SysTickClock);

impl Clock for MarkedClock {
    fn now(&mut self) -> u32 {
        self.0.now()
    }
    fn window_begins(&mut self) {
        bench_start();
    }
    fn window_ends(&mut self) {
        bench_stop();
    }
}
