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

/// The detector's scratch on a Cortex-M4F board: the core's default, 8192 cells (16 KiB),
/// the column tables of a DAVIS346's or a GenX320's neighbourhoods.
pub const M4F_TABLE_CELLS: usize = evcal_core::cluster::TABLE_CELLS;

/// The detector's scratch on a Cortex-M7 board: 65 536 cells (128 KiB of the H743's 512 KiB),
/// room for the column tables of a 1280x720 sensor's neighbourhoods (some 41 000 cells; a
/// 640x480 sensor's some 14 500), which the clustering otherwise replaces by cursors walking
/// the rows, to the same result at four to six times the cost an event (docs/firmware.md,
/// "Performance").
pub const M7_TABLE_CELLS: usize = evcal_core::cluster::MAX_TABLE_CELLS;

/// The detector's scratch on the board this firmware is built for.
#[cfg(any(feature = "board-mps2-an500", feature = "board-stm32h743"))]
pub const TABLE_CELLS: usize = M7_TABLE_CELLS;
/// The detector's scratch on the board this firmware is built for.
#[cfg(not(any(feature = "board-mps2-an500", feature = "board-stm32h743")))]
pub const TABLE_CELLS: usize = M4F_TABLE_CELLS;
