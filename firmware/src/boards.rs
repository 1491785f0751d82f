//! What each kind of board holds: the most events a window may have on it, the firmware's
//! capacity (the detector's and the protocol device's `N`), chosen with the board at build
//! time. Here, not in the board layer, so that the host (the benchmark, the tests) reads the
//! same figures.

/// Events per window on a Cortex-M4F board (the emulated mps2-an386, an STM32F405): the
/// host's window for a DAVIS346, 8000 events, in the F405's 128 KiB of SRAM beside the link's
/// buffers (the stack has the 64 KiB CCM).
pub const M4F_EVENTS_PER_WINDOW: usize = evcal_core::config::MAX_EVENTS_PER_WINDOW;

/// Events per window on a Cortex-M7 board (the emulated mps2-an500, an STM32H743): 32 000,
/// the largest of the host's default windows (filled discs on a 1280x720 sensor; rings take
/// 8500 on a 320x320 GenX320, 15 000 on 640x480, 25 500 on 1280x720), in the H743's 512 KiB
/// AXI SRAM. Below the clusterer's limit of 32 766 events.
pub const M7_EVENTS_PER_WINDOW: usize = 32_000;

/// Events per window on the board this firmware is built for.
#[cfg(any(feature = "board-mps2-an500", feature = "board-stm32h743"))]
pub const EVENTS_PER_WINDOW: usize = M7_EVENTS_PER_WINDOW;
/// Events per window on the board this firmware is built for.
#[cfg(not(any(feature = "board-mps2-an500", feature = "board-stm32h743")))]
pub const EVENTS_PER_WINDOW: usize = M4F_EVENTS_PER_WINDOW;
