//! A 32-bit tick counter from the 24-bit SysTick: the SysTick exception counts wraps.

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::exception;

static WRAPS: AtomicU32 = AtomicU32::new(0);
const RELOAD: u32 = 0x00FF_FFFF;

/// Core-clock ticks from SysTick, extended to 32 bits.
pub struct Ticks {
    syst: SYST,
}

impl Ticks {
    /// Starts SysTick on the core clock, free running, with its wrap interrupt.
    pub fn start(mut syst: SYST) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();
        Self { syst }
    }

    /// Ticks since start (wrapping at 2^32).
    pub fn now(&self) -> u32 {
        loop {
            let w = WRAPS.load(Ordering::Acquire);
            let cur = SYST::get_current();
            // A wrap between the two reads shows as a changed count: read again.
            if WRAPS.load(Ordering::Acquire) == w {
                return (w << 24).wrapping_add(RELOAD - cur);
            }
        }
    }

    /// The SysTick peripheral, for boards that need it back.
    pub fn free(self) -> SYST {
        self.syst
    }
}

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::AcqRel);
}
