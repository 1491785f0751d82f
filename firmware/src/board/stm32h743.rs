//! A real STM32H743 board on `embassy-stm32` (its blocking drivers, through embedded-hal
//! 1.0; `stm32h7xx-hal` 0.16 implements only embedded-hal 0.2): 480 MHz from the internal
//! 64 MHz oscillator through PLL1 (voltage scale 0), USART3 on PD8 (TX) / PD9 (RX) at
//! 921 600 baud (the Nucleo-H743ZI's ST-LINK virtual COM port), a status LED on PB0 (its
//! green LD1), a sensor's reset line on PF12 and its control bus on I2C1, PB8 (SCL) / PB9
//! (SDA), at 100 kHz (the Nucleo-144's Arduino D15/D14).
//!
//! Flash with `probe-rs run --chip STM32H743ZITx` (see docs/firmware.md). No board is here to
//! test it: it is built in CI, not run. A board wired otherwise changes the pins in [`init`].
//!
//! The receiver is polled, as on the STM32F405 (`stm32f405.rs`): the protocol's flow control
//! keeps bytes from arriving while a window is processed, and bytes lost anyway come back
//! from the driver as overrun errors, which the device counts.

use super::{exit, Board, SysTickClock, WaitForByte};
use embassy_stm32::{
    gpio::{Level, Output, Speed},
    i2c::{self, I2c, Master},
    mode::Blocking,
    rcc,
    time::Hertz,
    usart::{self, Uart},
};

/// The core clock, 480 MHz: SysTick counts cycles.
pub const CLOCK_HZ: u32 = 480_000_000;
const BAUD: u32 = 921_600;
/// The sensor bus's clock.
const I2C_HZ: u32 = 100_000;

/// The board.
pub struct BoardImpl {
    uart: Uart<'static, Blocking>,
    led: Output<'static>,
    sensor: Option<(Output<'static>, I2c<'static, Blocking, Master>)>,
    clock: SysTickClock,
}

/// The clock tree: HSI 64 MHz / 4 = 16 MHz × 60 = 960 MHz, / 2 = 480 MHz for the core (PLL1
/// P), which needs voltage scale 0 (the H743's rev V; the HAL sets the flash wait states);
/// AHB 240 MHz, each APB 120 MHz (their most).
fn clocks() -> embassy_stm32::Config {
    let mut config = embassy_stm32::Config::default();
    let r = &mut config.rcc;
    r.hsi = Some(rcc::HSIPrescaler::DIV1);
    r.csi = true;
    r.pll1 = Some(rcc::Pll {
        source: rcc::PllSource::HSI,
        prediv: rcc::PllPreDiv::DIV4,
        mul: rcc::PllMul::MUL60,
        fracn: None,
        divp: Some(rcc::PllDiv::DIV2),
        divq: Some(rcc::PllDiv::DIV8),
        divr: None,
    });
    r.sys = rcc::Sysclk::PLL1_P;
    r.ahb_pre = rcc::AHBPrescaler::DIV2;
    r.apb1_pre = rcc::APBPrescaler::DIV2;
    r.apb2_pre = rcc::APBPrescaler::DIV2;
    r.apb3_pre = rcc::APBPrescaler::DIV2;
    r.apb4_pre = rcc::APBPrescaler::DIV2;
    r.voltage_scale = rcc::VoltageScale::Scale0;
    config
}

/// Brings the board up: caches, clocks ([`clocks`]), USART3, the status LED (dark), the sensor's
/// reset line (held low) and bus, SysTick.
pub fn init(mut cp: cortex_m::Peripherals) -> BoardImpl {
    // The caches: the statics are in the AXI SRAM and the code in flash, both behind the
    // AXI bus, whose wait states the cycles-per-instruction figure (docs/firmware.md) does
    // not include. Nothing here uses DMA, so the data cache needs no maintenance.
    cp.SCB.enable_icache();
    cp.SCB.enable_dcache(&mut cp.CPUID);
    // `init` runs once: embassy takes the device peripherals here, the core ones were taken
    // by the caller.
    let p = embassy_stm32::init(clocks());
    let mut config = usart::Config::default();
    config.baudrate = BAUD;
    let Ok(uart) = Uart::new_blocking(p.USART3, p.PD9, p.PD8, config) else { exit(false) };
    let led = Output::new(p.PB0, Level::Low, Speed::Low);
    let reset = Output::new(p.PF12, Level::Low, Speed::Low);
    let mut bus_config = i2c::Config::default();
    bus_config.frequency = Hertz(I2C_HZ);
    // The pins' internal pull-ups keep a bus with nothing on it idle high (see stm32f405.rs);
    // a sensor's bus still needs its own, stronger ones.
    bus_config.scl_pullup = true;
    bus_config.sda_pullup = true;
    let bus = I2c::new_blocking(p.I2C1, p.PB8, p.PB9, bus_config);
    BoardImpl { uart, led, sensor: Some((reset, bus)), clock: SysTickClock::start(cp.SYST) }
}

impl Board for BoardImpl {
    type Serial = Uart<'static, Blocking>;
    type Led = Output<'static>;
    type SensorReset = Output<'static>;
    type SensorBus = I2c<'static, Blocking, Master>;

    fn io(&mut self) -> (&mut Self::Serial, &mut Self::Led) {
        (&mut self.uart, &mut self.led)
    }

    fn take_sensor(&mut self) -> Option<(Self::SensorReset, Self::SensorBus)> {
        self.sensor.take()
    }

    fn clock(&self) -> SysTickClock {
        self.clock
    }
}

impl WaitForByte for Uart<'static, Blocking> {
    fn wait_for_byte(&mut self) {
        // Polled (see the module's doc).
    }
}

/// Interrupts this board handles: none (the drivers are blocking and polled). embassy's
/// blocking I2C unmasks its event and error interrupts in the NVIC but enables none in the
/// peripheral, so none is raised.
pub fn on_interrupt(_irqn: i16) -> bool {
    false
}
