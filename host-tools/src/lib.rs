//! evcal host side: recordings readers, the event-camera simulator and the detection run
//! used by the `evcal` CLI.

#![deny(missing_docs)]

pub mod calib;
pub mod detections;
pub mod eval;
pub mod export;
pub mod link;
pub mod pipeline;
pub mod recording;
pub mod sim;
pub mod views;
