//! # evcal-core
//!
//! The fixed-memory detection core of evcal. It turns a stream of events from an event
//! camera that watches an asymmetric circle grid into per-window lists of sub-pixel circle
//! centres, following the E-Calib method. The same code runs on a Cortex-M4F beside the
//! sensor, inside the host tool, and in the simulation tests, and gives bit-identical
//! centres on all of them.
//!
//! Data flows one way through the modules:
//!
//! ```text
//! event ──▶ window ──▶ cluster ──▶ arc ──▶ fit ──▶ detect (per-window result)
//! ```
//!
//! * [`event`]: the event type (integer microseconds, wrap-safe), input validation.
//! * [`window`]: the windower: the first N events at or after each tick of event time.
//! * [`cluster`]: DBSCAN (and the spatio-temporal variant) over the sorted pixel grid.
//! * [`moments`]: power sums of a cluster and the algebraic circle through them, to join the
//!   crescents of one circle.
//! * [`fit`]: eRWLS slanted-cylinder fit of each cluster, giving a circle centre.
//! * [`detect`]: runs clustering and fitting over one window, in caller-provided memory.
//!
//! Beside the pipeline, [`evt`] decodes the byte streams of Prophesee sensors (EVT 2.0, 2.1,
//! 3.0) into events, streaming and in fixed memory, for the firmware's sensor input and the
//! host's RAW file reader.
//!
//! ## Guarantees
//!
//! * `no_std`, no allocator: every buffer is inline with a const-generic capacity or is
//!   provided by the caller. Every capacity limit is a named constant in [`config`] or a
//!   const generic; overflow is counted in statistics, never fatal.
//! * No panics on any input: malformed events are counted and dropped.
//! * Floating point is `f32` in a fixed order, so results are bit-identical on the host and
//!   on the Cortex-M4F's single-precision FPU. The hot loops use the `math` module's
//!   plain-arithmetic functions, not `libm` (which remains outside them: the wire's rounding,
//!   the clustering's integer square root).
//!
//! ## Features
//!
//! * `defmt`: implement `defmt::Format` on the public types, for firmware logging.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![deny(missing_docs)]

pub mod cluster;
pub mod config;
pub mod detect;
pub mod event;
pub mod evt;
mod extent;
pub mod fit;
mod math;
pub mod moments;
pub mod window;
pub mod wire;
