//! The board layer: what the application needs of a board, so that the emulated board and
//! real boards are interchangeable.
//!
//! A board provides a serial port (through `embedded-io` traits, so any HAL's UART plugs
//! in), a free-running tick counter for per-stage timing, and a way to end the program.

#[cfg(all(feature = "board-mps2-an386", feature = "board-stm32f405"))]
compile_error!("choose one board: features board-mps2-an386 and board-stm32f405 exclude each other");

#[cfg(not(feature = "board-stm32f405"))]
mod mps2_an386;
#[cfg(not(feature = "board-stm32f405"))]
pub use mps2_an386::{init, BoardImpl};

#[cfg(feature = "board-stm32f405")]
mod stm32f405;
#[cfg(feature = "board-stm32f405")]
pub use stm32f405::{init, BoardImpl};

mod systick;
pub use systick::Ticks;

/// What the application needs of a board.
pub trait Board {
    /// The serial link to the host.
    type Serial: embedded_io::Read + embedded_io::ReadReady + embedded_io::Write;
    /// The serial link.
    fn serial(&mut self) -> &mut Self::Serial;
    /// Core-clock ticks since start (wrapping), for per-stage timing.
    fn ticks(&self) -> u32;
    /// Core clock in Hz (what one tick is).
    fn clock_hz(&self) -> u32;
    /// Ends the program with a status: under QEMU this is its exit code; on hardware the
    /// board halts (a debugger sees the breakpoint).
    fn exit(&mut self, code: i32) -> !;
}
