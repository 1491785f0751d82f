//! # evcal-firmware: the parts of the firmware that do not depend on the chip
//!
//! The firmware image (`src/main.rs`, built with `cargo fw` for `thumbv7em-none-eabihf`)
//! brings a board up and runs the detection core of `evcal-core` window by window on events
//! from an [`EventSource`](source::EventSource). What is here compiles on any target, so the
//! host tests it and the host tools use the same code to write what the firmware reads:
//!
//! * [`source`]: the event-source trait every input implements (the emulator's bulk file, a
//!   sensor's EVT byte stream; UART replay arrives through the wire protocol's device loop),
//!   and [`source::SliceSource`] for tests.
//! * [`boards`]: each kind of board's capacity (events per window), and the one built for.
//! * [`bulk`]: the bulk replay format, 8 bytes per event, read by the emulator-only
//!   semihosting source so that CI can replay hundreds of windows faster than QEMU's UART
//!   (about 14 KB/s) carries them.
//! * [`evt`]: a Prophesee sensor's EVT byte stream as an event source (the core's decoders
//!   behind the same trait).
//! * [`paced`]: a recording replayed at the sensor's pace on the device's clock, through a
//!   FIFO of fixed size, losing (and counting) what arrives while it is full.
//! * [`runner`]: the window loop (feed, process between the benchmark markers, hand each
//!   detection on), shared by every mode of the firmware.
//! * [`sensor`]: a sensor's reset line and control bus (embedded-hal `OutputPin` and `I2c`):
//!   reset, bus scan, and a hook for the sensor's own configuration writes.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![deny(missing_docs)]

pub mod boards;
pub mod bulk;
pub mod evt;
pub mod paced;
pub mod runner;
pub mod sensor;
pub mod source;
