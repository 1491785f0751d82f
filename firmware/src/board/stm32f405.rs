//! A real STM32F405/407 board: 168 MHz from the internal 16 MHz oscillator through the PLL,
//! USART2 on PA2 (TX) / PA3 (RX), AF7, at 921 600 baud.
//!
//! Raw registers keep this free of a HAL dependency; a HAL's UART (anything implementing
//! `embedded-io`) can replace [`Usart`] as well. Flash with `probe-rs run --chip STM32F405RGTx`
//! (see docs/firmware.md). No board is here to test it: it is built in CI, not run.
//!
//! The receiver is polled: the protocol's flow control (the host sends an event batch only
//! when the device has asked for one and is waiting for it) keeps bytes from arriving while
//! a window is processed. Bytes lost anyway (a host that ignores it) are counted as
//! overruns, never silently.

use super::{Board, SysTickClock};
use core::convert::Infallible;

const RCC: usize = 0x4002_3800;
const FLASH_R: usize = 0x4002_3C00;
const GPIOA: usize = 0x4002_0000;
const USART2: usize = 0x4000_4400;
const BAUD: u32 = 921_600;
const SYSCLK_HZ: u32 = 168_000_000;
const APB1_HZ: u32 = 42_000_000;

fn rd(addr: usize) -> u32 {
    // SAFETY: callers pass register addresses of this chip's peripherals.
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}

fn wr(addr: usize, v: u32) {
    // SAFETY: as in rd.
    unsafe { core::ptr::write_volatile(addr as *mut u32, v) }
}

fn modify(addr: usize, clear: u32, set: u32) {
    wr(addr, (rd(addr) & !clear) | set);
}

/// The core clock, 168 MHz: SysTick counts cycles.
pub const CLOCK_HZ: u32 = SYSCLK_HZ;

/// HSI (16 MHz) -> PLL (M 16, N 336, P 2) -> 168 MHz; AHB /1, APB1 /4 (42 MHz), APB2 /2.
fn clocks() {
    // 5 wait states at 168 MHz and 3.3 V, with prefetch and caches.
    modify(FLASH_R, 0xF, 5 | (1 << 8) | (1 << 9) | (1 << 10));
    // PLLCFGR: M=16, N=336, P=2 (00), source HSI, Q=7.
    wr(RCC + 0x04, 16 | (336 << 6) | (7 << 24));
    modify(RCC, 0, 1 << 24); // PLLON
    while rd(RCC) & (1 << 25) == 0 {}
    // CFGR: HPRE /1, PPRE1 /4 (101), PPRE2 /2 (100), then switch to the PLL.
    modify(RCC + 0x08, (0b111 << 10) | (0b111 << 13) | 0b11, (0b101 << 10) | (0b100 << 13) | 0b10);
    while (rd(RCC + 0x08) >> 2) & 0b11 != 0b10 {}
}

/// USART2, polled.
pub struct Usart {
    overruns: u32,
}

impl Usart {
    fn init() -> Self {
        modify(RCC + 0x30, 0, 1); // GPIOAEN
        modify(RCC + 0x40, 0, 1 << 17); // USART2EN
                                        // PA2, PA3: alternate function 7.
        modify(GPIOA, 0b1111 << 4, 0b1010 << 4);
        modify(GPIOA + 0x20, 0xFF << 8, 0x77 << 8);
        // USARTDIV = f / (16 baud), as mantissa and 4-bit fraction, rounded.
        let div16 = (APB1_HZ + BAUD / 2) / BAUD;
        wr(USART2 + 0x08, div16);
        wr(USART2 + 0x0C, (1 << 13) | (1 << 3) | (1 << 2)); // UE, TE, RE
        Self { overruns: 0 }
    }

    /// Whether a byte waits in the receiver; counts an overrun (ORE, bit 3), which the
    /// following data-register read clears.
    fn rx_ready(&mut self) -> bool {
        let sr = rd(USART2);
        if sr & (1 << 3) != 0 {
            self.overruns = self.overruns.wrapping_add(1);
        }
        sr & (1 << 5) != 0
    }
}

impl embedded_io::ErrorType for Usart {
    type Error = Infallible;
}

impl embedded_io::Read for Usart {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        while !self.rx_ready() {}
        let mut n = 0;
        while n < buf.len() && self.rx_ready() {
            buf[n] = rd(USART2 + 0x04) as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::ReadReady for Usart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.rx_ready())
    }
}

impl embedded_io::Write for Usart {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        for &b in buf {
            while rd(USART2) & (1 << 7) == 0 {}
            wr(USART2 + 0x04, u32::from(b));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while rd(USART2) & (1 << 6) == 0 {}
        Ok(())
    }
}

/// The STM32F405 board.
pub struct BoardImpl {
    uart: Usart,
    clock: SysTickClock,
}

/// Brings the board up: clocks, USART2, SysTick.
pub fn init(cp: cortex_m::Peripherals) -> BoardImpl {
    clocks();
    BoardImpl { uart: Usart::init(), clock: SysTickClock::start(cp.SYST) }
}

impl Board for BoardImpl {
    type Serial = Usart;

    fn serial(&mut self) -> &mut Usart {
        &mut self.uart
    }

    fn clock(&self) -> SysTickClock {
        self.clock
    }

    fn serial_overruns(&self) -> u32 {
        self.uart.overruns
    }
}

/// Interrupts this board handles: none (the USART is polled).
pub fn on_interrupt(_irqn: i16) -> bool {
    false
}

/// Halts: a debugger (probe-rs) sees the breakpoint. `ok` is for the debugger's log.
pub fn exit(ok: bool) -> ! {
    #[cfg(feature = "defmt")]
    defmt::info!("evcal firmware stops (ok: {})", ok);
    let _ = ok;
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Reports a fatal error: over RTT with the `defmt` feature, else nowhere (a real board has
/// no console of its own; the host sees the link go quiet).
pub fn report(args: core::fmt::Arguments) {
    #[cfg(feature = "defmt")]
    defmt::error!("{}", defmt::Display2Format(&args));
    let _ = args;
}
