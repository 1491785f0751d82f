//! Recordings: reading event files of the common formats as a stream of core events.
//!
//! Every reader streams (constant memory, whatever the file size) and reports a bad record
//! with the file and the line or offset where it is, never a panic. The format is chosen by
//! content and extension ([`Format::detect`]), from bytes peeked into a buffer that the
//! reader then consumes, so a pipe or standard input (`-`) loses nothing.

mod aedat4;
mod aedat4info;
mod bag;
mod bagrecords;
mod bytes;
mod codec;
mod flatbuf;
mod hdf5;
pub mod prophesee;
mod text;
mod types;

pub use aedat4::{Aedat4Reader, Compression as Aedat4Compression, StreamInfo as Aedat4Stream};
pub use bag::{BagReader, BagTopic, DEFAULT_TOPIC as BAG_DEFAULT_TOPIC};
pub use bytes::{quote, remove_spools, Spool, SPOOL_MAX_BYTES, STDIN_NAME};
pub use hdf5::{write_ecalib_h5, EcalibH5Writer, H5ColumnsReader, H5Reader};
pub use text::{write_text, TextReader, TextWriter, MAX_LINE};
pub use types::{Format, OpenOptions, Position, ReadError, TimeUnit};

use bytes::{Input, TeeHandle};
use evcal_core::event::{Event, SensorSize};
use std::{
    path::{Path, PathBuf},
    rc::Rc,
};
use types::EventSource;

impl Format {
    /// Chooses the format of `path` by its first bytes (the HDF5 signature, AEDAT4's
    /// `#!AER-DAT4.0`, `#ROSBAG V`, a Prophesee `%` header), falling back on the extension.
    /// A stream (`-`, a pipe) is consumed: open it with [`Recording::open`] instead.
    pub fn detect(path: &Path) -> Result<Self, ReadError> {
        let mut input = Input::open(path)?;
        match sniff(&mut input, path)? {
            Sniffed::Ready(f) => Ok(f),
            Sniffed::Hdf5 => {
                let tmp;
                let p = match &input.path {
                    Some(p) => p.as_path(),
                    None => {
                        tmp = input.spool()?;
                        &*tmp
                    }
                };
                Ok(hdf5::layout(p).unwrap_or(Format::EcalibH5))
            }
        }
    }
}

/// What the first bytes say.
enum Sniffed {
    Ready(Format),
    /// HDF5: which layout needs the file itself (random access).
    Hdf5,
}

/// The format by the input's first bytes (peeked, kept for the reader), else by the
/// extension of `path`.
fn sniff(input: &mut Input, path: &Path) -> Result<Sniffed, ReadError> {
    let head = input.peek(16)?;
    if head.starts_with(b"\x89HDF\r\n\x1a\n") {
        return Ok(Sniffed::Hdf5);
    }
    // AEDAT 2 and 3 too: the AEDAT4 reader says they are not supported.
    if head.starts_with(b"#!AER-DAT") {
        return Ok(Sniffed::Ready(Format::Aedat4));
    }
    if head.starts_with(b"#ROSBAG V") {
        return Ok(Sniffed::Ready(Format::RosBag));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if head.starts_with(b"%") || matches!(ext.as_deref(), Some("raw" | "dat")) {
        prophesee::peek_header(input)?;
        if let Some(f) = prophesee::sniff(&input.name, &input.head, ext.as_deref())? {
            return Ok(Sniffed::Ready(f));
        }
    }
    Ok(match ext.as_deref() {
        Some("h5" | "hdf5") => Sniffed::Hdf5,
        Some("aedat4") => Sniffed::Ready(Format::Aedat4),
        Some("bag") => Sniffed::Ready(Format::RosBag),
        _ => Sniffed::Ready(Format::Text),
    })
}

/// A reader of a temporary copy, whose messages name the stream the copy is of.
struct Renamed {
    inner: Box<dyn EventSource>,
    from: PathBuf,
    to: PathBuf,
    note: Option<String>,
}

impl EventSource for Renamed {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        self.inner.next_event().map(|r| r.map_err(|e| e.renamed(&self.from, &self.to)))
    }

    fn progress_bytes(&self) -> u64 {
        self.inner.progress_bytes()
    }

    fn notes(&self) -> Vec<String> {
        let (from, to) = (self.from.display().to_string(), self.to.display().to_string());
        self.note.iter().cloned().chain(self.inner.notes().into_iter().map(|n| n.replace(&from, &to))).collect()
    }
}

/// An open recording: an iterator of events plus what the file says about itself.
pub struct Recording {
    /// The format.
    pub format: Format,
    /// Sensor size, when the file states it.
    pub sensor: Option<SensorSize>,
    /// Total events, when known without reading them all.
    pub len: Option<u64>,
    /// Bytes in the file, for progress (0 for a stream).
    pub file_bytes: u64,
    events: Box<dyn EventSource>,
    origin: Origin,
    opts: OpenOptions,
}

/// How to read a recording again.
#[derive(Clone)]
enum Origin {
    /// A file: open it again.
    File(PathBuf),
    /// A stream copied to a temporary file first (a format that needs random access).
    Spooled(PathBuf, Rc<bytes::Spool>),
    /// A stream read through a copy.
    Tee(PathBuf, TeeHandle),
    /// A stream, not kept.
    Stream(PathBuf),
}

impl Recording {
    /// Opens `path` with the default [`OpenOptions`], choosing the reader by [`Format::detect`].
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        Self::open_with(path, &OpenOptions::default())
    }

    /// Opens `path` (`-`: standard input), choosing the reader by [`Format::detect`]. A
    /// stream is read as it comes, except in the formats that need random access (HDF5,
    /// AEDAT4, ROS bag), which copy it to a temporary file first (a note says so).
    pub fn open_with(path: &Path, opts: &OpenOptions) -> Result<Self, ReadError> {
        Self::from_input(Input::open(path)?, path, opts)
    }

    /// Reads a recording from the stream `r`, named `name` in messages (its extension counts
    /// as a file's would), as [`Recording::open_with`] reads a pipe.
    pub fn from_reader(name: &Path, r: Box<dyn std::io::Read>, opts: &OpenOptions) -> Result<Self, ReadError> {
        Self::from_input(Input::stream(name, r), name, opts)
    }

    fn from_input(mut input: Input, path: &Path, opts: &OpenOptions) -> Result<Self, ReadError> {
        let sniffed = sniff(&mut input, path)?;
        let name = input.name.clone();
        let file_bytes = input.len.unwrap_or(0);
        let needs_file = match sniffed {
            Sniffed::Hdf5 => true,
            Sniffed::Ready(f) => matches!(f, Format::Aedat4 | Format::RosBag),
        };
        if needs_file {
            return match input.path.clone() {
                Some(p) => Self::open_file(&p, &name, sniffed, opts, Origin::File(p.clone()), file_bytes, None),
                None => {
                    let tmp = Rc::new(input.spool()?);
                    let bytes = std::fs::metadata(&*tmp).map(|m| m.len()).unwrap_or(0);
                    let note = format!(
                        "{}: a stream: copied to a temporary file first ({bytes} bytes; this format needs random access)",
                        name.display()
                    );
                    let origin = Origin::Spooled(name.clone(), Rc::clone(&tmp));
                    Self::open_file(&tmp, &name, sniffed, opts, origin, bytes, Some(note))
                }
            };
        }
        let Sniffed::Ready(format) = sniffed else { unreachable!("HDF5 needs a file") };
        time_unit_applies(format, opts.time_unit).map_err(|m| ReadError::new(&name, Position::File, m))?;
        let origin = match (&input.path, opts.rewindable) {
            (Some(p), _) => Origin::File(p.clone()),
            (None, false) => Origin::Stream(name.clone()),
            (None, true) => {
                let tee = TeeHandle::new(&input.head, std::mem::replace(&mut input.rest, Box::new(std::io::empty())))
                    .map_err(|e| {
                    ReadError::new(&name, Position::File, format!("cannot keep a copy in a temporary file: {e}"))
                })?;
                input.rest = Box::new(tee.clone());
                Origin::Tee(name.clone(), tee)
            }
        };
        let (sensor, len, events): (_, _, Box<dyn EventSource>) = match format {
            Format::Text => {
                let r = text::from_input(input, opts.time_unit)?;
                (r.sensor(), None, Box::new(r))
            }
            Format::PropheseeRaw(enc) => {
                let r = prophesee::RawReader::from_input(input, enc)?;
                (r.sensor(), None, Box::new(r))
            }
            Format::PropheseeDat => {
                let r = prophesee::DatReader::from_input(input)?;
                (r.sensor(), r.len(), Box::new(r))
            }
            _ => unreachable!("the formats that need a file are opened above"),
        };
        Ok(Self { format, sensor, len, file_bytes, events, origin, opts: opts.clone() })
    }

    /// Opens a format that needs random access from the file `file`, named `name` in
    /// messages.
    fn open_file(
        file: &Path,
        name: &Path,
        sniffed: Sniffed,
        opts: &OpenOptions,
        origin: Origin,
        file_bytes: u64,
        note: Option<String>,
    ) -> Result<Self, ReadError> {
        let format = match sniffed {
            Sniffed::Hdf5 => hdf5::layout(file).unwrap_or(Format::EcalibH5),
            Sniffed::Ready(f) => f,
        };
        let rename = |e: ReadError| e.renamed(file, name);
        time_unit_applies(format, opts.time_unit).map_err(|m| ReadError::new(name, Position::File, m))?;
        let (sensor, len, events): (_, _, Box<dyn EventSource>) = match format {
            Format::EcalibH5 => {
                let r = H5Reader::open(file).map_err(rename)?;
                (r.sensor(), Some(r.len()), Box::new(r))
            }
            Format::Aedat4 => {
                let r = Aedat4Reader::open(file, opts.topic.as_deref()).map_err(rename)?;
                (r.sensor(), r.len(), Box::new(r))
            }
            Format::RosBag => {
                let r = BagReader::open(file, opts.topic.as_deref()).map_err(rename)?;
                (r.sensor(), None, Box::new(r))
            }
            Format::EventsGroupH5 | Format::RootColumnsH5 => {
                let r = H5ColumnsReader::open(file, format, opts.time_unit).map_err(rename)?;
                (r.sensor(), Some(r.len()), Box::new(r))
            }
            _ => unreachable!("only the formats that need a file"),
        };
        let events: Box<dyn EventSource> = if file == name {
            events
        } else {
            Box::new(Renamed { inner: events, from: file.to_path_buf(), to: name.to_path_buf(), note })
        };
        Ok(Self { format, sensor, len, file_bytes, events, origin, opts: opts.clone() })
    }

    /// The same recording from its start, for a second pass: a file is opened again, a
    /// stream read from the copy kept of it (the rest of the stream is copied first). A
    /// stream opened without [`OpenOptions::rewindable`] cannot be read again: an error.
    pub fn rewind(&self) -> Result<Recording, ReadError> {
        match &self.origin {
            Origin::File(p) => Self::open_with(p, &self.opts),
            Origin::Spooled(name, tmp) => {
                let sniffed = match self.format {
                    Format::EcalibH5 | Format::EventsGroupH5 | Format::RootColumnsH5 => Sniffed::Hdf5,
                    f => Sniffed::Ready(f),
                };
                let origin = self.origin.clone();
                Self::open_file(tmp, name, sniffed, &self.opts, origin, self.file_bytes, None)
            }
            Origin::Tee(name, tee) => {
                let f = tee.finish().map_err(|e| {
                    ReadError::new(name, Position::File, format!("cannot read the copy kept of the stream: {e}"))
                })?;
                let input = Input::from_file(name, None, f)?;
                let mut r = Self::from_input(input, name, &OpenOptions { rewindable: false, ..self.opts.clone() })?;
                r.origin = self.origin.clone();
                Ok(r)
            }
            Origin::Stream(name) => Err(ReadError::new(
                name,
                Position::File,
                "a stream cannot be read a second time (it was opened without keeping a copy)",
            )),
        }
    }

    /// The name of the recording in messages: its path, or [`STDIN_NAME`].
    pub fn name(&self) -> &Path {
        match &self.origin {
            Origin::File(p) | Origin::Spooled(p, _) | Origin::Tee(p, _) | Origin::Stream(p) => p,
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

/// Whether a time unit given by the user (`--time-unit`) can apply to `format`: an error for
/// a format whose times have a unit of their own that differs (it would be ignored, and the
/// user believe it was used).
fn time_unit_applies(format: Format, unit: Option<TimeUnit>) -> Result<(), String> {
    let Some(unit) = unit else { return Ok(()) };
    let (own, why) = match format {
        Format::Text | Format::EventsGroupH5 | Format::RootColumnsH5 => return Ok(()),
        Format::Aedat4 => (Some(TimeUnit::Microseconds), "AEDAT4 timestamps are µs by the format"),
        Format::PropheseeRaw(_) | Format::PropheseeDat => {
            (Some(TimeUnit::Microseconds), "Prophesee timestamps are µs by the format")
        }
        Format::EcalibH5 => (Some(TimeUnit::Seconds), "E-Calib's events_data holds seconds by the format"),
        Format::RosBag => (None, "ROS times are seconds and nanoseconds by the format"),
    };
    if own == Some(unit) {
        return Ok(());
    }
    Err(format!(
        "--time-unit {} does not apply to this file: {why} (--time-unit is for text recordings and HDF5 columns)",
        unit.name()
    ))
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
    let q = quote(s.as_bytes(), 40);
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| {
        format!("'{q}' is not a sensor size: use WxH (e.g. 346x260) or davis346 / dvxplorer / imx636 / genx320")
    })?;
    let w: u16 = w.trim().parse().map_err(|_| format!("bad sensor width in '{q}' (1 to 65535)"))?;
    let h: u16 = h.trim().parse().map_err(|_| format!("bad sensor height in '{q}' (1 to 65535)"))?;
    if w == 0 || h == 0 {
        return Err(format!("sensor size '{q}' must be at least 1x1"));
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
