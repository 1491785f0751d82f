//! QEMU's mps2 boards: `mps2-an386` (Cortex-M4 with FPU, the default) and `mps2-an500`
//! (Cortex-M7, feature `board-mps2-an500`), which QEMU models alike: UART0 a CMSDK APB UART
//! at 0x4000_4000, the FPGA's user LEDs, a CMSDK GPIO and SBCon I2C on the shield header. Each
//! has a minimal hand-written driver here behind the embedded-hal traits the firmware is
//! written against.
//!
//! Run with `-icount shift=0`: each instruction then takes 1 ns of virtual time, and SysTick,
//! on the system clock ([`CLOCK_HZ`]), ticks once every `1e9 / CLOCK_HZ` instructions,
//! deterministically. Semihosting (`-semihosting-config enable=on,target=native`) carries
//! diagnostics, the exit code and, for fast replays, host files.

use super::{Board, SysTickClock, WaitForByte};
use core::convert::Infallible;
use cortex_m_semihosting::debug;
use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource, Operation};
use embedded_hal_nb::nb;

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

/// UART0's receive interrupt on the mps2 boards' NVIC (QEMU's `mps2.c`: RX 0, TX 1).
#[derive(Clone, Copy)]
struct Uart0Rx;

// SAFETY: 0 is the number of UART0's receive interrupt on this board.
unsafe impl cortex_m::interrupt::InterruptNumber for Uart0Rx {
    fn number(self) -> u16 {
        0
    }
}

const UART0: usize = 0x4000_4000;

/// QEMU's mps2-an386: a 25 MHz system clock (SysTick ticks every 40 instructions under
/// `-icount shift=0`).
#[cfg(not(feature = "board-mps2-an500"))]
pub const CLOCK_HZ: u32 = 25_000_000;
/// QEMU's mps2-an500: its system clock (QEMU's `mps2.c`), what SysTick counts.
#[cfg(feature = "board-mps2-an500")]
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
}

impl WaitForByte for CmsdkUart {
    /// Waits for a received byte asleep (WFI) rather than polling. In QEMU this is what makes
    /// the UART fast: a polling vCPU holds the emulator's lock, and the I/O thread then gets
    /// to hand over a byte only now and then (about 12 KB/s); a sleeping one lets it run.
    fn wait_for_byte(&mut self) {
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

impl embedded_hal_nb::serial::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_hal_nb::serial::Read<u8> for CmsdkUart {
    fn read(&mut self) -> nb::Result<u8, Infallible> {
        if self.rx_ready() {
            Ok(self.read_reg(reg::DATA) as u8)
        } else {
            Err(nb::Error::WouldBlock)
        }
    }
}

impl embedded_hal_nb::serial::Write<u8> for CmsdkUart {
    fn write(&mut self, b: u8) -> nb::Result<(), Infallible> {
        // STATE bit 0: the transmit buffer is full.
        if self.read_reg(reg::STATE) & 0b01 != 0 {
            return Err(nb::Error::WouldBlock);
        }
        self.write_reg(reg::DATA, u32::from(b));
        Ok(())
    }

    fn flush(&mut self) -> nb::Result<(), Infallible> {
        // QEMU sends a byte as it is written.
        Ok(())
    }
}

/// The FPGA's user LEDs (FPGAIO `LED0` at 0x4002_8000, bits 0 and 1); QEMU models them
/// (`-d trace:led_*` shows their changes).
const FPGAIO_LED0: usize = 0x4002_8000;

/// One of the FPGA's user LEDs, as an output pin (high: lit).
pub struct FpgaLed {
    mask: u32,
}

impl embedded_hal::digital::ErrorType for FpgaLed {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for FpgaLed {
    fn set_low(&mut self) -> Result<(), Infallible> {
        // SAFETY: LED0 is the FPGAIO's register; each `FpgaLed` owns its own bit (`init`
        // makes one), and the read-modify-write runs in thread mode only.
        unsafe {
            let r = FPGAIO_LED0 as *mut u32;
            core::ptr::write_volatile(r, core::ptr::read_volatile(r) & !self.mask);
        }
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        // SAFETY: as in set_low.
        unsafe {
            let r = FPGAIO_LED0 as *mut u32;
            core::ptr::write_volatile(r, core::ptr::read_volatile(r) | self.mask);
        }
        Ok(())
    }
}

/// GPIO 0 of the AN386 image: a CMSDK AHB GPIO (its pins on the board's expansion
/// headers). QEMU does not model it (the block is an "unimplemented device": writes are
/// dropped), so the reset line below goes nowhere under emulation.
mod gpio {
    pub const BASE: usize = 0x4001_0000;
    pub const DATAOUT: usize = 0x004;
    pub const OUTENSET: usize = 0x010;
}

/// A CMSDK AHB GPIO pin as a push-pull output.
pub struct CmsdkGpioPin {
    base: usize,
    mask: u32,
}

impl CmsdkGpioPin {
    /// # Safety
    /// `base` must be a CMSDK AHB GPIO block, and `pin` (0..16) owned by nothing else.
    unsafe fn output(base: usize, pin: u32, high: bool) -> Self {
        let mut p = Self { base, mask: 1 << pin };
        p.set(high);
        // SAFETY: OUTENSET sets only the bits written.
        unsafe { core::ptr::write_volatile((base + gpio::OUTENSET) as *mut u32, p.mask) };
        p
    }

    fn set(&mut self, high: bool) {
        let r = (self.base + gpio::DATAOUT) as *mut u32;
        // SAFETY: DATAOUT of the block `output` was given; pins of one block are only
        // changed from thread mode.
        unsafe {
            let v = core::ptr::read_volatile(r);
            core::ptr::write_volatile(r, if high { v | self.mask } else { v & !self.mask });
        }
    }
}

impl embedded_hal::digital::ErrorType for CmsdkGpioPin {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for CmsdkGpioPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.set(false);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.set(true);
        Ok(())
    }
}

/// The SBCon two-wire interface of the AN386's shield 1 header (0x4002_A000): I2C driven bit
/// by bit (SCL bit 0, SDA bit 1; write 1s at offset 0 to release a line, at offset 4 to pull
/// it low; reading offset 0 gives the lines' levels). QEMU models it with a bus that
/// `-device` can put I2C devices on (`-device tmp105,address=0x48` lands there).
pub const SBCON_SHIELD1: usize = 0x4002_A000;

/// An I2C master on an SBCon block, at about 100 kHz; waits out a device that holds SCL low
/// (clock stretching) for up to a few milliseconds.
pub struct SbconI2c {
    base: usize,
}

const SCL: u32 = 0b01;
const SDA: u32 = 0b10;
/// Core cycles per quarter of an SCL period: 100 kHz at 25 MHz.
const QUARTER: u32 = CLOCK_HZ / 100_000 / 4;
/// Quarters to wait for a stretched clock before giving up.
const STRETCH_QUARTERS: u32 = 1_000;

impl SbconI2c {
    /// # Safety
    /// `base` must be an SBCon block owned by nothing else.
    unsafe fn new(base: usize) -> Self {
        let i2c = Self { base };
        // Both lines released: the bus idles high.
        i2c.release(SCL | SDA);
        i2c
    }

    fn release(&self, lines: u32) {
        // SAFETY: the block's CONTROLS register (set bits).
        unsafe { core::ptr::write_volatile(self.base as *mut u32, lines) };
    }

    fn pull_low(&self, lines: u32) {
        // SAFETY: the block's CONTROLC register (clear bits).
        unsafe { core::ptr::write_volatile((self.base + 4) as *mut u32, lines) };
    }

    fn levels(&self) -> u32 {
        // SAFETY: the block's CONTROL register (the lines' levels).
        unsafe { core::ptr::read_volatile(self.base as *const u32) }
    }

    fn wait(&self) {
        cortex_m::asm::delay(QUARTER);
    }

    /// Releases SCL and waits until it is high (a device may hold it low).
    fn scl_high(&self) -> Result<(), ErrorKind> {
        self.release(SCL);
        for _ in 0..STRETCH_QUARTERS {
            self.wait();
            if self.levels() & SCL != 0 {
                return Ok(());
            }
        }
        Err(ErrorKind::Bus)
    }

    /// A start, or a repeated start after a transfer (SCL low).
    fn start(&self) -> Result<(), ErrorKind> {
        self.release(SDA);
        self.wait();
        self.scl_high()?;
        if self.levels() & SDA == 0 {
            // Someone else holds the bus.
            return Err(ErrorKind::ArbitrationLoss);
        }
        self.pull_low(SDA);
        self.wait();
        self.pull_low(SCL);
        self.wait();
        Ok(())
    }

    fn stop(&self) {
        self.pull_low(SDA);
        self.wait();
        // A bus held low cannot be stopped cleanly; the next start reports it.
        let _ = self.scl_high();
        self.wait();
        self.release(SDA);
        self.wait();
    }

    /// Clocks one bit out (`true`: released) or in (release and read); returns SDA's level
    /// while SCL was high.
    fn bit(&self, out: bool) -> Result<bool, ErrorKind> {
        if out {
            self.release(SDA);
        } else {
            self.pull_low(SDA);
        }
        self.wait();
        self.scl_high()?;
        let level = self.levels() & SDA != 0;
        self.wait();
        self.pull_low(SCL);
        self.wait();
        Ok(level)
    }

    /// Sends a byte; `true` if the device acknowledged it.
    fn send(&self, byte: u8) -> Result<bool, ErrorKind> {
        for i in (0..8).rev() {
            self.bit(byte & (1 << i) != 0)?;
        }
        Ok(!self.bit(true)?)
    }

    /// Receives a byte and acknowledges it (`ack`) or not (the last byte of a read).
    fn receive(&self, ack: bool) -> Result<u8, ErrorKind> {
        let mut b = 0u8;
        for _ in 0..8 {
            b = (b << 1) | u8::from(self.bit(true)?);
        }
        self.bit(!ack)?;
        Ok(b)
    }

    fn run(&self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        let mut last_read = None;
        let n = ops.len();
        for i in 0..n {
            let read = matches!(ops[i], Operation::Read(_));
            // A start (repeated between operations of different directions), the address
            // and the direction bit.
            if last_read != Some(read) {
                self.start()?;
                if !self.send((address << 1) | u8::from(read))? {
                    return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
                }
            }
            // A read that the next operation continues acknowledges its last byte too.
            let continued = read && i + 1 < n && matches!(ops[i + 1], Operation::Read(_));
            match &mut ops[i] {
                Operation::Write(bytes) => {
                    for &b in bytes.iter() {
                        if !self.send(b)? {
                            return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data));
                        }
                    }
                }
                Operation::Read(buf) => {
                    let len = buf.len();
                    for (j, b) in buf.iter_mut().enumerate() {
                        *b = self.receive(continued || j + 1 < len)?;
                    }
                }
            }
            last_read = Some(read);
        }
        Ok(())
    }
}

impl embedded_hal::i2c::ErrorType for SbconI2c {
    type Error = ErrorKind;
}

impl embedded_hal::i2c::I2c for SbconI2c {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        if ops.is_empty() {
            return Ok(());
        }
        let r = self.run(address & 0x7F, ops);
        self.stop();
        r
    }
}

/// The emulated board.
pub struct BoardImpl {
    uart: CmsdkUart,
    led: FpgaLed,
    sensor: Option<(CmsdkGpioPin, SbconI2c)>,
    clock: SysTickClock,
}

/// The status LED: the FPGA's user LED 0.
const STATUS_LED: u32 = 0;
/// The sensor's reset line: GPIO 0 pin 0.
const SENSOR_RESET_PIN: u32 = 0;

/// Brings the board up: UART0, the status LED (dark), the sensor's reset line (held low)
/// and bus, SysTick.
pub fn init(cp: cortex_m::Peripherals) -> BoardImpl {
    // SAFETY: UART0, GPIO 0 and the SBCon block are used by this board value only, which
    // `init` makes once (it consumes the core peripherals, which exist once).
    let (uart, reset, bus) = unsafe {
        (CmsdkUart::new(UART0), CmsdkGpioPin::output(gpio::BASE, SENSOR_RESET_PIN, false), SbconI2c::new(SBCON_SHIELD1))
    };
    let mut led = FpgaLed { mask: 1 << STATUS_LED };
    let _ = embedded_hal::digital::OutputPin::set_low(&mut led);
    BoardImpl { uart, led, sensor: Some((reset, bus)), clock: SysTickClock::start(cp.SYST) }
}

impl Board for BoardImpl {
    type Serial = CmsdkUart;
    type Led = FpgaLed;
    type SensorReset = CmsdkGpioPin;
    type SensorBus = SbconI2c;

    fn io(&mut self) -> (&mut CmsdkUart, &mut FpgaLed) {
        (&mut self.uart, &mut self.led)
    }

    fn take_sensor(&mut self) -> Option<(CmsdkGpioPin, SbconI2c)> {
        self.sensor.take()
    }

    fn clock(&self) -> SysTickClock {
        self.clock
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
