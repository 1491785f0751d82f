//! What every reader shares: the formats, where a problem is and what it is, the caller's
//! choices, the time units, and the trait a reader implements.
//!
//! A leaf: the dispatcher (`recording/mod.rs`) and every reader import it, and it imports
//! none of them, so no reader depends on the dispatcher that opens it.

use evcal_core::{
    event::{Event, SensorSize},
    evt::{Encoding, Evt21Order},
};
use std::{fmt, path::Path};

/// A recording format evcal reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// One event per line, `t x y p`, `t` in seconds (the RPG event-camera dataset layout).
    Text,
    /// HDF5 with a dataset `events_data` of N x 4 `[x, y, p, t_seconds]` (E-Calib's layout).
    EcalibH5,
    /// Prophesee RAW: a `%` header, then an EVT 2.0 / 2.1 / 3.0 stream.
    PropheseeRaw(Encoding),
    /// Prophesee `.dat` of CD events: a `%` header, then 8-byte records.
    PropheseeDat,
    /// iniVation DV / dv-processing AEDAT 4.0 (the event stream; frames, IMU, triggers skipped).
    Aedat4,
    /// ROS1 bag (format 2.0) with `dvs_msgs/EventArray` messages.
    RosBag,
    /// HDF5 with a group `events` of datasets `x`, `y`, `t`, `p` (DSEC and others).
    EventsGroupH5,
    /// HDF5 with datasets `x`, `y`, `p`, `t` at the root (e2calib).
    RootColumnsH5,
}

impl Format {
    /// The format's name, as `evcal` prints it.
    pub fn name(self) -> &'static str {
        match self {
            Format::Text => "text (t x y p)",
            Format::EcalibH5 => "HDF5 (E-Calib events_data)",
            Format::PropheseeRaw(Encoding::Evt2) => "Prophesee RAW EVT 2.0",
            Format::PropheseeRaw(Encoding::Evt21(Evt21Order::LowHalfFirst)) => "Prophesee RAW EVT 2.1",
            Format::PropheseeRaw(Encoding::Evt21(Evt21Order::HighHalfFirst)) => "Prophesee RAW EVT 2.1 (IMX636 order)",
            Format::PropheseeRaw(Encoding::Evt3) => "Prophesee RAW EVT 3.0",
            Format::PropheseeDat => "Prophesee DAT (CD events)",
            Format::Aedat4 => "AEDAT4 (iniVation DV)",
            Format::RosBag => "ROS1 bag (dvs_msgs/EventArray)",
            Format::EventsGroupH5 => "HDF5 (events/x,y,t,p)",
            Format::RootColumnsH5 => "HDF5 (x,y,p,t at the root: e2calib)",
        }
    }
}

/// Where in a file a problem was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Position {
    /// A line of a text file, from 1.
    Line(u64),
    /// A row of a table (an event index), from 0.
    Row(u64),
    /// A byte offset in a binary file, from 0 (the start of the record or packet at fault).
    Byte(u64),
    /// Nowhere in particular (opening, metadata).
    File,
}

/// A problem reading a recording: the file, where in it, and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadError {
    /// The file.
    pub path: String,
    /// Where in the file.
    pub at: Position,
    /// What is wrong.
    pub message: String,
}

impl ReadError {
    pub(crate) fn new(path: &Path, at: Position, message: impl Into<String>) -> Self {
        Self { path: path.display().to_string(), at, message: message.into() }
    }

    pub(crate) fn io(path: &Path, e: std::io::Error) -> Self {
        Self::new(path, Position::File, e.to_string())
    }

    /// The error with the name `from` (a temporary copy) replaced by `to` (the stream's).
    pub(super) fn renamed(mut self, from: &Path, to: &Path) -> Self {
        let (from, to) = (from.display().to_string(), to.display().to_string());
        if self.path == from {
            self.path.clone_from(&to);
        }
        self.message = self.message.replace(&from, &to);
        self
    }
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.at {
            Position::Line(l) => write!(f, "{}:{}: {}", self.path, l, self.message),
            Position::Row(r) => write!(f, "{}: event {}: {}", self.path, r, self.message),
            Position::Byte(b) => write!(f, "{}: byte {}: {}", self.path, b, self.message),
            Position::File => write!(f, "{}: {}", self.path, self.message),
        }
    }
}

impl std::error::Error for ReadError {}

/// Choices a reader cannot make from the file alone; the defaults suit most files.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct OpenOptions {
    /// The stream to read where a file holds several: a ROS bag topic, an AEDAT4 stream's
    /// name or id. Default: the file's only event stream, else the conventional one
    /// (`/dvs/events`, `events`).
    pub topic: Option<String>,
    /// The unit of timestamps instead of detecting it: of integers in HDF5 column layouts,
    /// of every time in a text recording.
    pub time_unit: Option<TimeUnit>,
    /// Keep what is needed to read a stream a second time ([`Recording::rewind`](super::Recording::rewind)): a copy in
    /// an unlinked temporary file, written as the stream is read (disk, not memory).
    pub rewindable: bool,
}

/// The unit of integer timestamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeUnit {
    /// Seconds.
    Seconds,
    /// Milliseconds.
    Milliseconds,
    /// Microseconds (the event-camera convention).
    Microseconds,
    /// Nanoseconds (ROS time, e2calib).
    Nanoseconds,
}

impl TimeUnit {
    /// Parses `s`, `ms`, `us` (`µs`), `ns` and the spelled-out names.
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "s" | "sec" | "second" | "seconds" => Some(Self::Seconds),
            "ms" | "millisecond" | "milliseconds" => Some(Self::Milliseconds),
            "us" | "µs" | "μs" | "usec" | "microsecond" | "microseconds" => Some(Self::Microseconds),
            "ns" | "nsec" | "nanosecond" | "nanoseconds" => Some(Self::Nanoseconds),
            _ => None,
        }
    }

    /// The short name (`s`, `ms`, `us`, `ns`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Seconds => "s",
            Self::Milliseconds => "ms",
            Self::Microseconds => "us",
            Self::Nanoseconds => "ns",
        }
    }

    /// `v` of this unit in whole µs, rounded to nearest; `None` on overflow.
    pub(crate) fn to_us(self, v: i64) -> Option<i64> {
        match self {
            Self::Seconds => v.checked_mul(1_000_000),
            Self::Milliseconds => v.checked_mul(1000),
            Self::Microseconds => Some(v),
            Self::Nanoseconds => Some(v.div_euclid(1000) + i64::from(v.rem_euclid(1000) >= 500)),
        }
    }
}

/// A streaming reader of one format.
pub(crate) trait EventSource {
    /// The next event, `None` at the end.
    fn next_event(&mut self) -> Option<Result<Event, ReadError>>;
    /// Bytes (or rows, scaled to bytes) consumed so far, for progress.
    fn progress_bytes(&self) -> u64;
    /// What the reader skipped, dropped or assumed so far, one sentence each.
    fn notes(&self) -> Vec<String> {
        Vec::new()
    }
}

/// A sensor size as a file states it: `Ok(None)` for 0 by 0 (a writer that did not know it),
/// else each side must be 1 to 65535 (coordinates are 16-bit); the error says what was
/// stated, to follow "the header " or the like.
pub(crate) fn stated_sensor(width: i128, height: i128) -> Result<Option<SensorSize>, String> {
    if width == 0 && height == 0 {
        return Ok(None);
    }
    match (u16::try_from(width), u16::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok(Some(SensorSize::new(w, h))),
        _ => Err(format!(
            "states a sensor size of {width}x{height}; evcal reads sizes of 1 to {} pixels a side",
            u16::MAX
        )),
    }
}
