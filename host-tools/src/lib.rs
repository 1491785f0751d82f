//! evcal host side: recordings readers, the event-camera simulator and the detection run
//! used by the `evcal` CLI.

#![deny(missing_docs)]

pub mod calib;
pub mod eval;
pub mod export;
pub mod input;
pub mod pipeline;
pub mod sim;
pub mod views;
