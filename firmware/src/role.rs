//! The one big static memory the firmware runs in, and the role it is given: the protocol's
//! device or the benchmark's detector. Whichever mode runs takes it, once; the other mode's
//! value is never made, so RAM holds one detector's worth, not two.

use crate::board;
use evcal_core::{
    config::MAX_CLUSTERS,
    detect::DetectConfig,
    event::SensorSize,
    wire::{
        device::{RX_FRAME, TX_FRAME},
        Device, DeviceOptions,
    },
};
use evcal_firmware::boards::{EVENTS_PER_WINDOW, TABLE_CELLS};
#[cfg(emulated)]
use evcal_firmware::runner::FwDetector;
use static_cell::StaticCell;

/// The configuration the device boots with, until a host sends its own: the core's
/// defaults for a DAVIS346.
const BOOT_CONFIG: DetectConfig = DetectConfig::for_sensor(SensorSize::DAVIS346);

/// How the device behaves on the link: credit for two frames (one being fed, one waiting in
/// the UART or the host), stats every 16 windows, stage times in SysTick ticks.
const OPTIONS: DeviceOptions = DeviceOptions { window: 2, stats_every: 16, clock_hz: board::CLOCK_HZ };

/// The protocol's device: the board's window and scratch (`boards::EVENTS_PER_WINDOW`,
/// `boards::TABLE_CELLS`), the core's clusters and buffers.
pub type FwDevice = Device<EVENTS_PER_WINDOW, MAX_CLUSTERS, RX_FRAME, TX_FRAME, TABLE_CELLS>;

/// What the big static memory holds: one detector's worth (window buffer, clusterer and
/// scratch: some 100 KB for the M4F's 8000-event windows, 400 KB for the M7's 32 000), used
/// by whichever mode runs.
#[allow(clippy::large_enum_variant)] // the variants share one memory on purpose
enum Role {
    Protocol(FwDevice),
    #[cfg(emulated)]
    Bench(FwDetector),
}

// The images a role starts from, built at compile time. Writing one into the static copies
// it from flash; building the value at run time would put a temporary of the same size on
// the stack first (measured: a 37 KB stack peak), RAM the budget would have to hold too.
const PROTOCOL_IMAGE: Role = Role::Protocol(FwDevice::new(BOOT_CONFIG, OPTIONS));
#[cfg(emulated)]
const BENCH_IMAGE: Role = Role::Bench(FwDetector::new(BOOT_CONFIG));

static ROLE: StaticCell<Role> = StaticCell::new();

/// The static memory, once. Written in place (`try_uninit`, then `write`): the image goes
/// from flash into the static without a copy on the stack (`StaticCell::init(image)` takes
/// it by value, which may pass through one).
fn role(image: Role) -> Option<&'static mut Role> {
    Some(ROLE.try_uninit()?.write(image))
}

/// The detector for the benchmark, configured with `cfg`; `None` if the memory is taken.
#[cfg(emulated)]
pub fn bench_detector(cfg: DetectConfig) -> Option<&'static mut FwDetector> {
    match role(BENCH_IMAGE)? {
        Role::Bench(d) => {
            d.reconfigure(cfg);
            Some(d)
        }
        Role::Protocol(_) => None,
    }
}

/// The protocol's device in its boot configuration; `None` if the memory is taken.
pub fn protocol_device() -> Option<&'static mut FwDevice> {
    match role(PROTOCOL_IMAGE)? {
        Role::Protocol(d) => Some(d),
        #[cfg(emulated)]
        Role::Bench(_) => None,
    }
}
