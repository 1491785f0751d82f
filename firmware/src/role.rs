//! The one big static memory the firmware runs in, and the role it is given: the protocol's
//! device or the benchmark's detector. Whichever mode runs takes it, once; the other mode's
//! value is never made, so RAM holds one detector's worth, not two.

use crate::board;
use evcal_core::{
    detect::DetectConfig,
    event::SensorSize,
    wire::{Device, DeviceOptions},
};
#[cfg(not(feature = "board-stm32f405"))]
use evcal_firmware::runner::FwDetector;
use static_cell::StaticCell;

/// The configuration the device boots with, until a host sends its own: the core's
/// defaults for a DAVIS346.
const BOOT_CONFIG: DetectConfig = DetectConfig::for_sensor(SensorSize::DAVIS346);

/// How the device behaves on the link: credit for two frames (one being fed, one waiting in
/// the UART or the host), stats every 16 windows, stage times in SysTick ticks.
const OPTIONS: DeviceOptions = DeviceOptions { window: 2, stats_every: 16, clock_hz: board::CLOCK_HZ };

/// The protocol's device with the core's default capacities and buffers.
pub type FwDevice = Device;

/// What the big static memory holds: one detector's worth (some 100 KB of window buffer,
/// clusterer and scratch for the host's 8000-event windows), used by whichever mode runs.
#[allow(clippy::large_enum_variant)] // the variants share one memory on purpose
enum Role {
    Protocol(FwDevice),
    #[cfg(not(feature = "board-stm32f405"))]
    Bench(FwDetector),
}

// The images a role starts from, built at compile time. Writing one into the static copies
// it from flash; building the value at run time would put a temporary of the same size on
// the stack first (measured: a 37 KB stack peak), RAM the budget would have to hold too.
const PROTOCOL_IMAGE: Role = Role::Protocol(FwDevice::new(BOOT_CONFIG, OPTIONS));
#[cfg(not(feature = "board-stm32f405"))]
const BENCH_IMAGE: Role = Role::Bench(FwDetector::new(BOOT_CONFIG));

static ROLE: StaticCell<Role> = StaticCell::new();

/// The static memory, once. Written in place (`try_uninit`, then `write`): the image goes
/// from flash into the static without a copy on the stack (`StaticCell::init(image)` takes
/// it by value, which may pass through one).
fn role(image: Role) -> Option<&'static mut Role> {
    Some(ROLE.try_uninit()?.write(image))
}

/// The detector for the benchmark, configured with `cfg`; `None` if the memory is taken.
#[cfg(not(feature = "board-stm32f405"))]
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
        #[cfg(not(feature = "board-stm32f405"))]
        Role::Bench(_) => None,
    }
}
