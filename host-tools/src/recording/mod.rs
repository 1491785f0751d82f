//! Recordings: reading event files of the common formats as a stream of core events.
//!
//! Every reader streams (constant memory, whatever the file size) and reports a bad record
//! with the file and the line or offset where it is, never a panic. The format is chosen by
//! content and extension ([`Format::detect`]).

mod aedat4;
mod bag;
mod codec;
mod flatbuf;
mod h5;
mod h5cols;
pub mod prophesee;
mod text;

pub use aedat4::{Aedat4Reader, Compression as Aedat4Compression, StreamInfo as Aedat4Stream};
pub use bag::{BagReader, BagTopic, DEFAULT_TOPIC as BAG_DEFAULT_TOPIC};
pub use h5::{write_ecalib_h5, H5Reader};
pub use h5cols::{H5ColumnsReader, TimeUnit};
pub use text::{write_text, TextReader};

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
    /// Chooses the format of `path` by its first bytes (the HDF5 signature, AEDAT4's
    /// `#!AER-DAT4.0`, `#ROSBAG V`), falling back on the extension.
    pub fn detect(path: &Path) -> Result<Self, ReadError> {
        use std::io::Read;
        let mut head = Vec::with_capacity(16);
        let f = std::fs::File::open(path).map_err(|e| ReadError::io(path, e))?;
        f.take(16).read_to_end(&mut head).map_err(|e| ReadError::io(path, e))?;
        if head.starts_with(b"\x89HDF\r\n\x1a\n") {
            // Which HDF5 layout, by the datasets; E-Calib's reader lists them if none fits.
            return Ok(h5cols::layout(path).unwrap_or(Format::EcalibH5));
        }
        // AEDAT 2 and 3 too: the AEDAT4 reader says they are not supported.
        if head.starts_with(b"#!AER-DAT") {
            return Ok(Format::Aedat4);
        }
        if head.starts_with(b"#ROSBAG V") {
            return Ok(Format::RosBag);
        }
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if head.starts_with(b"%") || matches!(ext.as_deref(), Some("raw" | "dat")) {
            if let Some(f) = prophesee::sniff(path, ext.as_deref())? {
                return Ok(f);
            }
        }
        match ext.as_deref() {
            Some("h5" | "hdf5") => Ok(Format::EcalibH5),
            Some("aedat4") => Ok(Format::Aedat4),
            Some("bag") => Ok(Format::RosBag),
            _ => Ok(Format::Text),
        }
    }

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
    /// The unit of integer timestamps in HDF5 column layouts, instead of detecting it.
    pub time_unit: Option<TimeUnit>,
}

/// An open recording: an iterator of events plus what the file says about itself.
pub struct Recording {
    /// The format.
    pub format: Format,
    /// Sensor size, when the file states it.
    pub sensor: Option<SensorSize>,
    /// Total events, when known without reading them all.
    pub len: Option<u64>,
    /// Bytes in the file, for progress.
    pub file_bytes: u64,
    events: Box<dyn EventSource>,
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

impl Recording {
    /// Opens `path` with the default [`OpenOptions`], choosing the reader by [`Format::detect`].
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        Self::open_with(path, &OpenOptions::default())
    }

    /// Opens `path`, choosing the reader by [`Format::detect`].
    pub fn open_with(path: &Path, opts: &OpenOptions) -> Result<Self, ReadError> {
        let format = Format::detect(path)?;
        let file_bytes = std::fs::metadata(path).map_err(|e| ReadError::io(path, e))?.len();
        let rec = |sensor, len, events: Box<dyn EventSource>| Self { format, sensor, len, file_bytes, events };
        match format {
            Format::Text => {
                let r = TextReader::open(path)?;
                Ok(rec(r.sensor(), None, Box::new(r)))
            }
            Format::EcalibH5 => {
                let r = H5Reader::open(path)?;
                Ok(rec(None, Some(r.len()), Box::new(r)))
            }
            Format::Aedat4 => {
                let r = Aedat4Reader::open(path, opts.topic.as_deref())?;
                Ok(rec(r.sensor(), r.len(), Box::new(r)))
            }
            Format::RosBag => {
                let r = BagReader::open(path, opts.topic.as_deref())?;
                Ok(rec(r.sensor(), None, Box::new(r)))
            }
            Format::EventsGroupH5 | Format::RootColumnsH5 => {
                let r = H5ColumnsReader::open(path, format, opts.time_unit)?;
                Ok(rec(r.sensor(), Some(r.len()), Box::new(r)))
            }
            Format::PropheseeRaw(enc) => {
                let r = prophesee::RawReader::open(path, enc)?;
                Ok(rec(r.sensor(), None, Box::new(r)))
            }
            Format::PropheseeDat => {
                let r = prophesee::DatReader::open(path)?;
                Ok(rec(r.sensor(), Some(r.len()), Box::new(r)))
            }
        }
    }

    /// Bytes of the file consumed so far (approximate for HDF5), for progress bars.
    pub fn progress_bytes(&self) -> u64 {
        self.events.progress_bytes()
    }

    /// What the reader skipped, dropped or assumed so far (complete once the events are
    /// read), one sentence each: events a file holds but evcal could not use are said here.
    pub fn notes(&self) -> Vec<String> {
        self.events.notes()
    }
}

impl Iterator for Recording {
    type Item = Result<Event, ReadError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.events.next_event()
    }
}

/// Parses a sensor size: `WxH` (e.g. `346x260`) or a preset name (`davis346`, `dvxplorer`,
/// `imx636` or `evk4` for 1280x720, `genx320` for 320x320).
pub fn parse_sensor(s: &str) -> Result<SensorSize, String> {
    match s.to_ascii_lowercase().as_str() {
        "davis346" | "davis" => return Ok(SensorSize::DAVIS346),
        "dvxplorer" | "dvx" => return Ok(SensorSize::DVXPLORER),
        "imx636" | "evk4" => return Ok(SensorSize::new(1280, 720)),
        "genx320" => return Ok(SensorSize::new(320, 320)),
        _ => {}
    }
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| {
        format!("'{s}' is not a sensor size: use WxH (e.g. 346x260) or davis346 / dvxplorer / imx636 / genx320")
    })?;
    let w: u16 = w.trim().parse().map_err(|_| format!("bad sensor width in '{s}'"))?;
    let h: u16 = h.trim().parse().map_err(|_| format!("bad sensor height in '{s}'"))?;
    if w == 0 || h == 0 {
        return Err(format!("sensor size '{s}' must be at least 1x1"));
    }
    Ok(SensorSize::new(w, h))
}

/// The sensor a recording was most likely made with, from the largest coordinates seen:
/// the smallest known sensor that holds them, else their bounding size.
pub fn guess_sensor(max_x: u16, max_y: u16) -> SensorSize {
    const KNOWN: [SensorSize; 6] = [
        SensorSize::new(240, 180),
        SensorSize::new(320, 320),
        SensorSize::DAVIS346,
        SensorSize::DVXPLORER,
        SensorSize::new(1280, 720),
        SensorSize::new(1280, 800),
    ];
    KNOWN
        .into_iter()
        .find(|s| max_x < s.width && max_y < s.height)
        .unwrap_or(SensorSize::new(max_x.saturating_add(1), max_y.saturating_add(1)))
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn sensors_parse() {
        assert_eq!(parse_sensor("346x260"), Ok(SensorSize::DAVIS346));
        assert_eq!(parse_sensor("DVXplorer"), Ok(SensorSize::DVXPLORER));
        assert!(parse_sensor("346").unwrap_err().contains("WxH"));
        assert!(parse_sensor("0x5").is_err());
        assert!(parse_sensor("ax5").is_err());
    }

    #[test]
    fn sensor_guess() {
        assert_eq!(guess_sensor(345, 259), SensorSize::DAVIS346);
        assert_eq!(guess_sensor(400, 100), SensorSize::DVXPLORER);
        assert_eq!(guess_sensor(2000, 10), SensorSize::new(2001, 11));
    }
}
