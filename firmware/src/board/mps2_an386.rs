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
    /// Write 1s to clear interrupt bits (bit 1: RX).
    pub const INTCLEAR: usize = 0x0C;
    pub const BAUDDIV: usize = 0x10;
}

/// CTRL: transmitter and receiver on.
const CTRL_ON: u32 = 0b11;
/// CTRL: receive interrupt enable.
const CTRL_RX_IRQ: u32 = 1 << 3;

/// UART0's receive interrupt on the an386's NVIC (QEMU's `mps2.c`: RX 0, TX 1).
#[derive(Clone, Copy)]
struct Uart0Rx;

// SAFETY: 0 is the number of UART0's receive interrupt on this board.
unsafe impl cortex_m::interrupt::InterruptNumber for Uart0Rx {
    fn number(self) -> u16 {
        0
    }
}

const UART0: usize = 0x4000_4000;

/// QEMU's mps2 boards: a 25 MHz system clock (SysTick ticks every 40 instructions under
/// `-icount shift=0`).
pub const CLOCK_HZ: u32 = 25_000_000;

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
        u.write_reg(reg::CTRL, CTRL_ON);
        // SAFETY: the handler (`on_interrupt`) only masks the interrupt again; nothing relies
        // on this interrupt staying masked.
        unsafe { cortex_m::peripheral::NVIC::unmask(Uart0Rx) };
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

    /// Waits for a received byte asleep (WFI) rather than polling. In QEMU this is what makes
    /// the UART fast: a polling vCPU holds the emulator's lock, and the I/O thread then gets
    /// to hand over a byte only now and then (about 12 KB/s); a sleeping one lets it run.
    fn wait_rx(&self) {
        while !self.rx_ready() {
            cortex_m::interrupt::free(|_| {
                // With interrupts masked, a byte arriving after the check still wakes the
                // WFI (a pending interrupt wakes it whatever PRIMASK says), and is taken
                // after `free` unmasks.
                self.write_reg(reg::CTRL, CTRL_ON | CTRL_RX_IRQ);
                if !self.rx_ready() {
                    cortex_m::asm::wfi();
                }
            });
        }
    }
}

/// UART0's receive interrupt: its only job was to end a WFI; mask it until the next wait.
pub fn on_interrupt(irqn: i16) -> bool {
    if irqn != 0 {
        return false;
    }
    // UART0's other user, `CmsdkUart`, only ever writes CTRL whole (no read-modify-write
    // this could tear).
    let uart = CmsdkUart { base: UART0 };
    uart.write_reg(reg::CTRL, CTRL_ON);
    uart.write_reg(reg::INTCLEAR, 0b10);
    true
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_io::Read for CmsdkUart {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        self.wait_rx();
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
