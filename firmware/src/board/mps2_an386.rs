//! QEMU's `mps2-an386`: Cortex-M4 with FPU, UART0 a CMSDK APB UART at 0x4000_4000.
//!
//! Run with `-icount shift=0`: each instruction then takes 1 ns of virtual time, and SysTick,
//! on the 25 MHz system clock, ticks once every 40 instructions, deterministically.
//! Semihosting (`-semihosting-config enable=on,target=native`) carries diagnostics, the exit
//! code and, for fast replays, host files.

use super::{Board, SysTickClock};
use core::convert::Infallible;
use cortex_m_semihosting::debug;

/// The CMSDK APB UART's registers, as offsets from its base.
mod reg {
    pub const DATA: usize = 0x00;
    /// bit 0: TX buffer full; bit 1: RX buffer full.
    pub const STATE: usize = 0x04;
    /// bit 0: TX enable; bit 1: RX enable.
    pub const CTRL: usize = 0x08;
    pub const BAUDDIV: usize = 0x10;
}

const UART0: usize = 0x4000_4000;

/// The CMSDK APB UART.
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// # Safety
    /// `base` must be a CMSDK UART's register block, owned by nothing else.
    unsafe fn new(base: usize) -> Self {
        let u = Self { base };
        // QEMU ignores the rate, but a divider of at least 16 is required for the UART to run.
        u.write_reg(reg::BAUDDIV, 16);
        u.write_reg(reg::CTRL, 0b11);
        u
    }

    fn read_reg(&self, off: usize) -> u32 {
        // SAFETY: an aligned register of the block `new` was given.
        unsafe { core::ptr::read_volatile((self.base + off) as *const u32) }
    }

    fn write_reg(&self, off: usize, v: u32) {
        // SAFETY: as in read_reg.
        unsafe { core::ptr::write_volatile((self.base + off) as *mut u32, v) }
    }

    fn rx_ready(&self) -> bool {
        self.read_reg(reg::STATE) & 0b10 != 0
    }
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_io::Read for CmsdkUart {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        while !self.rx_ready() {}
        let mut n = 0;
        while n < buf.len() && self.rx_ready() {
            buf[n] = self.read_reg(reg::DATA) as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::ReadReady for CmsdkUart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.rx_ready())
    }
}

impl embedded_io::Write for CmsdkUart {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        for &b in buf {
            while self.read_reg(reg::STATE) & 0b01 != 0 {}
            self.write_reg(reg::DATA, u32::from(b));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// The emulated board.
pub struct BoardImpl {
    uart: CmsdkUart,
    clock: SysTickClock,
}

/// Brings the board up: UART0, SysTick.
pub fn init(cp: cortex_m::Peripherals) -> BoardImpl {
    // SAFETY: UART0 is used by this board value only, which `init` makes once (it consumes
    // the core peripherals, which exist once).
    let uart = unsafe { CmsdkUart::new(UART0) };
    BoardImpl { uart, clock: SysTickClock::start(cp.SYST) }
}

impl Board for BoardImpl {
    type Serial = CmsdkUart;

    fn serial(&mut self) -> &mut CmsdkUart {
        &mut self.uart
    }

    fn clock(&self) -> SysTickClock {
        self.clock
    }

    fn clock_hz(&self) -> u32 {
        // QEMU's mps2 boards: a 25 MHz system clock (SysTick ticks every 40 instructions
        // under -icount shift=0).
        25_000_000
    }

    fn serial_overruns(&self) -> u32 {
        // QEMU holds input back while the one-byte receive buffer is full.
        0
    }
}

/// Ends QEMU with exit status 0 (`ok`) or 1 through semihosting.
pub fn exit(ok: bool) -> ! {
    loop {
        debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    }
}

/// Prints a line on the emulator's standard error (semihosting), for diagnostics that must
/// reach the person running it (faults, usage errors) whether or not defmt is built in.
pub fn report(args: core::fmt::Arguments) {
    use core::fmt::Write;
    if let Ok(mut err) = cortex_m_semihosting::hio::hstderr() {
        let _ = err.write_fmt(args);
        let _ = err.write_str("\n");
    }
}
