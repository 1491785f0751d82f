//! The evcal firmware: the detection core on a Cortex-M4F or Cortex-M7 beside the event
//! camera.
//!
//! Built for `thumbv7em-none-eabihf` with `cargo fw` (the Cortex-M4F boards) or
//! `scripts/firmware-build.sh m7|stm32h743` (the Cortex-M7 boards); `cargo fw-run` boots the
//! M4F image in QEMU. On the host this file is a stub that says so (the workspace builds
//! every member there).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "evcal-firmware runs on a Cortex-M4F or Cortex-M7: build it with `cargo fw` \
         (cargo build -p evcal-firmware --target thumbv7em-none-eabihf --profile firmware) \
         and boot it in QEMU with `cargo fw-run`; the Cortex-M7 images with \
         `bash scripts/firmware-build.sh m7|stm32h743`"
    );
    std::process::exit(2);
}

// Logging: defmt with the `defmt` feature, nothing without (the arguments are still
// borrowed, so they are type-checked and count as used, but not formatted). Must come before
// the modules that log.
#[cfg(target_os = "none")]
macro_rules! log_info {
    ($fmt:literal $(, $arg:expr)* $(,)?) => {{
        #[cfg(feature = "defmt")]
        defmt::info!($fmt $(, $arg)*);
        #[cfg(not(feature = "defmt"))]
        {
            $(let _ = &$arg;)*
        }
    }};
}

#[cfg(all(target_os = "none", emulated))]
mod bench;
#[cfg(target_os = "none")]
mod board;
#[cfg(target_os = "none")]
mod device;
#[cfg(all(target_os = "none", emulated))]
mod hostfs;
#[cfg(target_os = "none")]
mod markers;
#[cfg(target_os = "none")]
mod role;
#[cfg(all(target_os = "none", emulated))]
mod stack;

#[cfg(all(target_os = "none", feature = "defmt", not(emulated)))]
use defmt_rtt as _;
#[cfg(all(target_os = "none", feature = "defmt", emulated))]
use defmt_semihosting as _;

#[cfg(target_os = "none")]
#[cortex_m_rt::entry]
fn main() -> ! {
    // cortex-m-rt painted the stack before `main` (its `paint-stack` feature): the benchmark
    // reports the high-water mark (`stack`, emulator only).
    // `take` succeeds exactly once, and this is the first call.
    let Some(cp) = cortex_m::Peripherals::take() else { board::exit(false) };
    let board = board::init(cp);
    log_info!("evcal firmware up: core clock {=u32} Hz", board::CLOCK_HZ);
    let ok = device::run(board);
    board::exit(ok)
}

#[cfg(target_os = "none")]
#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    board::report(format_args!("evcal firmware: HardFault at pc {:#010x}, lr {:#010x}", ef.pc(), ef.lr()));
    board::exit(false)
}

/// Interrupts the board does not handle itself are faults.
#[cfg(target_os = "none")]
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    if !board::on_interrupt(irqn) {
        board::report(format_args!("evcal firmware: unexpected interrupt {irqn}"));
        board::exit(false)
    }
}

#[cfg(target_os = "none")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    board::report(format_args!("evcal firmware: {info}"));
    board::exit(false)
}
