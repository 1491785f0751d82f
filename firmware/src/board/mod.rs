//! The board layer: what the application needs of a board, through the embedded ecosystem's
//! traits, so that the emulated board and real boards are interchangeable.
//!
//! A board provides a serial port (`embedded_hal_nb::serial`: any HAL's UART plugs in), a
//! status LED and a sensor's reset line (`embedded_hal::digital::OutputPin`), a sensor's
//! control bus (`embedded_hal::i2c::I2c`), a free-running core-clock tick counter for
//! per-stage timing, a way to report a fatal error, and a way to end the program. The board
//! is chosen at build time: QEMU's `mps2-an386` (Cortex-M4F; its drivers hand-written,
//! minimal) by default, `mps2-an500` (Cortex-M7, the same drivers) with `board-mps2-an500`, a
//! real STM32F405/407 (on `stm32f4xx-hal`) with `board-stm32f405`, a real STM32H743 (on
//! `embassy-stm32`) with `board-stm32h743`.

#[cfg(emulated)]
mod mps2;
#[cfg(emulated)]
pub use mps2::{exit, init, on_interrupt, report, CLOCK_HZ};

#[cfg(feature = "board-stm32f405")]
mod stm32f405;
#[cfg(feature = "board-stm32f405")]
pub use stm32f405::{init, on_interrupt, CLOCK_HZ};

#[cfg(feature = "board-stm32h743")]
mod stm32h743;
#[cfg(feature = "board-stm32h743")]
pub use stm32h743::{init, on_interrupt, CLOCK_HZ};

#[cfg(not(emulated))]
mod probe;
#[cfg(not(emulated))]
pub use probe::{exit, report};

mod systick;
pub use systick::SysTickClock;

use embedded_hal::{digital::OutputPin, i2c::I2c};
use embedded_hal_nb::serial;

/// What the application needs of a board. Each board also exports `CLOCK_HZ` (what one
/// tick of its clock is), `init`, `report`, `exit` and `on_interrupt`.
pub trait Board {
    /// The serial link to the host. A receive error (an overrun, a framing or noise error)
    /// counts as a byte lost.
    type Serial: serial::Read<u8> + serial::Write<u8> + WaitForByte;
    /// The status LED: lit while the device works on a window.
    type Led: OutputPin;
    /// A sensor's reset line (active low).
    type SensorReset: OutputPin;
    /// A sensor's control bus.
    type SensorBus: I2c;

    /// The serial link and the status LED (the device loop holds both at once).
    fn io(&mut self) -> (&mut Self::Serial, &mut Self::Led);
    /// The sensor's reset line and control bus, handed over once (`None` after).
    fn take_sensor(&mut self) -> Option<(Self::SensorReset, Self::SensorBus)>;
    /// The core-clock tick counter (SysTick), for per-stage timing.
    fn clock(&self) -> SysTickClock;
}

/// How a serial port waits for a byte when it has none and the device nothing else to do.
pub trait WaitForByte {
    /// Returns when a byte may have arrived: asleep until the receive interrupt (the
    /// emulated board), or at once (a board that polls).
    fn wait_for_byte(&mut self);
}

/// Delays by spinning the core for the equivalent number of clock cycles (at least as long
/// as asked; longer if interrupts come). SysTick is the tick counter's, so delays do not use
/// it.
pub struct CycleDelay;

impl embedded_hal::delay::DelayNs for CycleDelay {
    fn delay_ns(&mut self, ns: u32) {
        // Cycles = ns × f / 1e9, rounded up, in 64 bits.
        let cycles = (u64::from(ns) * u64::from(CLOCK_HZ)).div_ceil(1_000_000_000);
        cortex_m::asm::delay(u32::try_from(cycles).unwrap_or(u32::MAX));
    }
}
