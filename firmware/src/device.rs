//! What the firmware does once the board is up: the protocol over the UART, or (emulator
//! only, chosen by QEMU's `-append`) the benchmark replay of `crate::bench`.

use crate::board::{self, Board, BoardImpl, SysTickClock};
use core::{
    ptr::addr_of_mut,
    sync::atomic::{AtomicBool, Ordering},
};
use evcal_core::{
    cluster::ClusterConfig,
    config::{
        DEFAULT_EPS, DEFAULT_EVENTS_PER_WINDOW, DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_CLUSTER_EVENTS, DEFAULT_MIN_PTS,
        DEFAULT_STEP_US,
    },
    detect::{Clock, DetectConfig},
    event::SensorSize,
    fit::{FitConfig, FitMethod},
    window::WindowConfig,
};
use evcal_firmware::runner::FwDetector;

/// The board's SysTick clock, calling the `#[no_mangle]` marker functions that the
/// instruction counter breaks on around each window's clustering and fitting.
#[derive(Clone, Copy)]
pub struct MarkedClock(pub SysTickClock);

impl Clock for MarkedClock {
    fn now(&mut self) -> u32 {
        self.0.now()
    }
    fn window_begins(&mut self) {
        crate::bench_start();
    }
    fn window_ends(&mut self) {
        crate::bench_stop();
    }
}

/// The detector's configuration in the static's initial image, replaced before any use:
/// the core's defaults for a DAVIS346.
const BOOT_CONFIG: DetectConfig = DetectConfig {
    sensor: SensorSize::DAVIS346,
    window: WindowConfig { events: DEFAULT_EVENTS_PER_WINDOW, step_us: DEFAULT_STEP_US },
    cluster: ClusterConfig { eps: DEFAULT_EPS, min_pts: DEFAULT_MIN_PTS, eps_t: None },
    fit: FitConfig {
        method: FitMethod::Erwls,
        max_iterations: DEFAULT_MAX_ITERATIONS,
        min_events: DEFAULT_MIN_CLUSTER_EVENTS,
    },
};

/// The detector (some 47 KB) is a static initialised at build time, and reconfigured in
/// place: made at run time it would first be built on the stack and copied (measured: a
/// 37 KB stack peak), and the stack is RAM the budget has to hold too. Its initial image costs
/// flash instead, of which there is plenty.
static mut DETECTOR: FwDetector = FwDetector::new(BOOT_CONFIG);
static DETECTOR_TAKEN: AtomicBool = AtomicBool::new(false);

/// The detector, configured with `cfg`; `None` after the first call.
pub fn detector(cfg: DetectConfig) -> Option<&'static mut FwDetector> {
    if DETECTOR_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: the flag lets one caller through, once: this is the only reference ever made.
    let d = unsafe { &mut *addr_of_mut!(DETECTOR) };
    d.reconfigure(cfg);
    Some(d)
}

/// Runs the firmware; `true` if it ended cleanly.
pub fn run(mut board: BoardImpl) -> bool {
    #[cfg(not(feature = "board-stm32f405"))]
    {
        let mut buf = [0u8; crate::hostfs::CMDLINE_MAX];
        let cmd = crate::hostfs::cmdline(&mut buf);
        if let Some(args) = cmd.strip_prefix("bench") {
            return crate::bench::run(&mut board, args);
        }
        // For the test that faults and panics end QEMU with a failure status.
        if cmd == "fault" {
            cortex_m::asm::udf();
        }
        if cmd == "panic" {
            panic!("as the command line asked");
        }
        if !cmd.is_empty() {
            board::report(format_args!(
                "evcal firmware: unknown command line {cmd:?}; expected `bench FILE [EVENTS [STEP_US]]`, `fault`, `panic` or none"
            ));
            return false;
        }
    }
    protocol(&mut board)
}

/// The UART protocol: hello, configuration, event batches in, detections and stats out.
fn protocol(board: &mut BoardImpl) -> bool {
    let _ = board.serial();
    board::report(format_args!("evcal firmware: the UART protocol is not built in yet"));
    false
}
