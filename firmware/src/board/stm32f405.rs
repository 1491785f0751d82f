//! A real STM32F405/407 board on `stm32f4xx-hal`: 168 MHz from the internal 16 MHz
//! oscillator through the PLL, USART2 on PA2 (TX) / PA3 (RX) at 921 600 baud, a status LED
//! on PD12 (the STM32F4-Discovery's green LED), a sensor's reset line on PB0 and its control
//! bus on I2C1, PB6 (SCL) / PB7 (SDA), at 100 kHz.
//!
//! Flash with `probe-rs run --chip STM32F405RGTx` (see docs/firmware.md). No board is here to
//! test it: it is built in CI, not run. A board wired otherwise changes the pins in [`init`]
//! and the types of [`BoardImpl`]'s fields.
//!
//! The receiver is polled: the protocol's flow control (the host sends an event batch only
//! when the device has asked for one and is waiting for it) keeps bytes from arriving while
//! a window is processed. Bytes lost anyway (a host that ignores it) come back from the HAL
//! as overrun errors, which the device counts, never silently.

use super::{exit, report, Board, SysTickClock, WaitForByte};
use stm32f4xx_hal::{
    gpio::{Output, PushPull, PB0, PD12},
    i2c::{self, I2c},
    pac,
    prelude::*,
    rcc::Config,
    serial::{self, Serial},
};

/// The core clock, 168 MHz: SysTick counts cycles.
pub const CLOCK_HZ: u32 = 168_000_000;
const BAUD: u32 = 921_600;
/// The sensor bus's clock.
const I2C_HZ: u32 = 100_000;

/// The board.
pub struct BoardImpl {
    uart: Serial<pac::USART2>,
    led: PD12<Output<PushPull>>,
    sensor: Option<(PB0<Output<PushPull>>, I2c<pac::I2C1>)>,
    clock: SysTickClock,
}

/// Brings the board up: clocks (HSI, PLL to 168 MHz; AHB /1, APB1 42 MHz, APB2 84 MHz; the
/// HAL sets the flash wait states, prefetch and caches), USART2, the status LED (dark), the
/// sensor's reset line (held low) and bus, SysTick.
pub fn init(cp: cortex_m::Peripherals) -> BoardImpl {
    // `init` runs once, right after the core peripherals were taken: the device peripherals
    // are there to take.
    let Some(dp) = pac::Peripherals::take() else { exit(false) };
    let mut rcc = dp.RCC.freeze(Config::hsi().sysclk(CLOCK_HZ.Hz()).pclk1(42.MHz()).pclk2(84.MHz()));
    if rcc.clocks.sysclk().raw() != CLOCK_HZ {
        report(format_args!("evcal firmware: core clock {} Hz, not {CLOCK_HZ}", rcc.clocks.sysclk().raw()));
        exit(false)
    }
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpiod = dp.GPIOD.split(&mut rcc);
    let config = serial::Config::default().baudrate(BAUD.bps());
    // 921 600 baud is within reach of the 42 MHz APB1 clock (the HAL rejects what is not).
    let Ok(uart) = dp.USART2.serial((gpioa.pa2, gpioa.pa3), config, &mut rcc) else { exit(false) };
    let led = gpiod.pd12.into_push_pull_output();
    let reset = gpiob.pb0.into_push_pull_output();
    // The pins' internal pull-ups (some 40 kΩ) keep a bus with nothing on it idle high: the
    // HAL waits for a free bus without a time limit, so a floating one would stop the boot's
    // bus scan. A sensor's bus still needs its own, stronger pull-ups.
    let (scl, sda) = (gpiob.pb6.internal_pull_up(true), gpiob.pb7.internal_pull_up(true));
    let bus = dp.I2C1.i2c((scl, sda), i2c::Mode::standard(I2C_HZ.Hz()), &mut rcc);
    BoardImpl { uart, led, sensor: Some((reset, bus)), clock: SysTickClock::start(cp.SYST) }
}

impl Board for BoardImpl {
    type Serial = Serial<pac::USART2>;
    type Led = PD12<Output<PushPull>>;
    type SensorReset = PB0<Output<PushPull>>;
    type SensorBus = I2c<pac::I2C1>;

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

impl WaitForByte for Serial<pac::USART2> {
    fn wait_for_byte(&mut self) {
        // Polled (see the module's doc).
    }
}

/// Interrupts this board handles: none (the USART is polled).
pub fn on_interrupt(_irqn: i16) -> bool {
    false
}
