//! evcal host side: recordings readers, the event-camera simulator and the detection run
//! used by the `evcal` CLI.

#![deny(missing_docs)]

pub mod calib;
pub mod detections;
pub mod eval;
pub mod export;
pub mod grid;
pub mod link;
pub mod motion;
pub mod pipeline;
pub mod recording;
pub mod select;
pub mod sim;
pub mod smooth;
pub mod track;
pub mod views;
