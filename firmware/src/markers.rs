//! The benchmark markers: two symbols an external instruction counter breaks on around each
//! window's processing (`firmware/tools/insn_count.c`), and the clock through which the
//! detector calls them, so that they bracket the work however deep the detector sits.

use crate::board::SysTickClock;
use embedded_hal::digital::OutputPin;
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
/// instruction counter breaks on around each window's clustering and fitting, and lighting
/// the status LED while a window is worked on (outside the markers: the LED costs the
/// measured windows nothing).
pub struct MarkedClock<'a, L> {
    ticks: SysTickClock,
    led: &'a mut L,
}

impl<'a, L: OutputPin> MarkedClock<'a, L> {
    /// `ticks`, marking windows with the benchmark markers and `led`.
    pub fn new(ticks: SysTickClock, led: &'a mut L) -> Self {
        Self { ticks, led }
    }
}

impl<L: OutputPin> Clock for MarkedClock<'_, L> {
    fn now(&mut self) -> u32 {
        self.ticks.now()
    }
    fn window_begins(&mut self) {
        // An LED that cannot be driven changes nothing else.
        let _ = self.led.set_high();
        bench_start();
    }
    fn window_ends(&mut self) {
        bench_stop();
        let _ = self.led.set_low();
    }
}
