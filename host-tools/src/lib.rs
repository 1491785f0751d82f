//! evcal host side: recordings readers, the event-camera simulator and the detection run
//! used by the `evcal` CLI.

#![deny(missing_docs)]
// Only the HDF5 modules that call its C library directly may use `unsafe` (allowed by name in
// `input::recording::hdf5`).
#![deny(unsafe_code)]

pub mod calib;
pub mod eval;
pub mod export;
pub mod input;
pub mod pipeline;
pub mod sim;
mod stats;
pub mod views;
