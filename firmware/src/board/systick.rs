//! A 32-bit tick counter from the 24-bit SysTick: the SysTick exception counts wraps.

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::{syst::SystClkSource, SCB, SYST};
use cortex_m_rt::exception;

static WRAPS: AtomicU32 = AtomicU32::new(0);
const RELOAD: u32 = 0x00FF_FFFF;

/// Core-clock ticks from SysTick, extended to 32 bits. Only [`SysTickClock::start`] makes
/// one, so holding a value means SysTick runs.
#[derive(Debug, Clone, Copy)]
pub struct SysTickClock {
    _started: (),
}

impl SysTickClock {
    /// Starts SysTick on the core clock, free running, with its wrap interrupt. SysTick is
    /// this clock's from now on (the peripheral is consumed).
    pub fn start(mut syst: SYST) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();
        Self { _started: () }
    }

    /// Ticks since start (wrapping at 2^32).
    pub fn now(&self) -> u32 {
        loop {
            let w = WRAPS.load(Ordering::Acquire);
            let p = SCB::is_pendst_pending();
            let cur = SYST::get_current();
            // A wrap whose exception ran between the reads shows as a changed count, one
            // whose exception is still pending (QEMU delivers it at the end of a translated
            // block) as a changed pending bit: read again either way.
            if WRAPS.load(Ordering::Acquire) == w && SCB::is_pendst_pending() == p {
                // Pending before and after: the wrap happened and is not counted yet.
                let w = w.wrapping_add(u32::from(p));
                // The counter runs down from RELOAD: a period is RELOAD + 1 = 2^24 ticks.
                return (w << 24).wrapping_add(RELOAD - cur);
            }
        }
    }
}

impl evcal_core::detect::Clock for SysTickClock {
    fn now(&mut self) -> u32 {
        SysTickClock::now(self)
    }
}

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::AcqRel);
}
