//! The board layer: what the application needs of a board, so that the emulated board and
//! real boards are interchangeable.
//!
//! A board provides a serial port (through `embedded-io` traits, so any HAL's UART plugs
//! in), a free-running core-clock tick counter for per-stage timing, a way to report a fatal
//! error, and a way to end the program. The board is chosen at build time: the emulated
//! `mps2-an386` by default, a real STM32F405/407 with the `board-stm32f405` feature.

#[cfg(not(feature = "board-stm32f405"))]
mod mps2_an386;
#[cfg(not(feature = "board-stm32f405"))]
pub use mps2_an386::{exit, init, on_interrupt, report, BoardImpl, CLOCK_HZ};

#[cfg(feature = "board-stm32f405")]
mod stm32f405;
#[cfg(feature = "board-stm32f405")]
pub use stm32f405::{exit, init, on_interrupt, report, BoardImpl, CLOCK_HZ};

mod systick;
pub use systick::SysTickClock;

/// What the application needs of a board. Each board also exports `CLOCK_HZ` (what one
/// tick of its clock is), `init`, `report`, `exit` and `on_interrupt`.
pub trait Board {
    /// The serial link to the host.
    type Serial: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write;
    /// The serial link.
    fn serial(&mut self) -> &mut Self::Serial;
    /// The core-clock tick counter (SysTick), for per-stage timing.
    fn clock(&self) -> SysTickClock;
    /// Bytes the serial receiver lost because they arrived before the previous one was read
    /// (hardware overruns; 0 where the link cannot overrun, as in QEMU).
    fn serial_overruns(&self) -> u32;
}
