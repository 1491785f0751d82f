//! Where windows of centres come from: the first stage on the host.
//!
//! * [`recording`]: event files of the common formats, read as a stream of core events;
//! * [`detections`]: the core run over those events here, and the detections' JSON-lines
//!   schema that a run leaves behind;
//! * [`event_frames`]: a bounded sample of windows' events, for the report's pictures;
//! * [`link`]: the same detections from a device running the core beside its sensor, over a
//!   serial port or TCP (replaying a recording to it, or listening to its own sensor).
//!
//! Everything after this stage sees only [`detections::WindowRecord`]s, whichever way they came.

pub mod detections;
pub mod event_frames;
pub mod link;
pub mod recording;
