//! Prophesee `.dat` files of CD events: a `% ` header (`% Height`, `% Width`, `% Version 2`),
//! then one byte of event type and one of event size, then records of that size. A CD record
//! (type 12, or type 0 of older files) is 8 bytes: a little-endian u32 timestamp in µs and a
//! u32 with x in bits 0..14, y in bits 14..28 and the polarity in bit 28.

use super::{Header, Position, ReadError};
use crate::recording::EventSource;
use evcal_core::event::{Event, SensorSize, TimeUnwrapper};
use std::{
    fs::File,
    io::{Read, Seek, SeekFrom},
    path::{Path, PathBuf},
};

/// Bytes of a CD record.
const RECORD: usize = 8;
/// Records read at a time.
const BATCH: usize = 1 << 15;

/// Streaming reader of Prophesee CD-event `.dat` files.
pub struct DatReader {
    path: PathBuf,
    file: File,
    sensor: Option<SensorSize>,
    /// Offset of the first record.
    data_at: u64,
    records: u64,
    next: u64,
    trailing: u64,
    buf: Vec<u8>,
    buf_at: usize,
    buf_len: usize,
    unwrap: TimeUnwrapper,
    done: bool,
}

/// Names of the `.dat` event types of Prophesee's tools.
fn type_name(t: u8) -> &'static str {
    match t {
        0 => "Event2D",
        12 => "EventCD",
        14 => "EventExtTrigger",
        40 => "EventOpticalFlow",
        _ => "unknown",
    }
}

impl DatReader {
    /// Opens `path`, reads the header and checks that it holds 8-byte CD records.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let (header, head) = Header::read(path)?;
        let file_bytes = std::fs::metadata(path).map_err(|e| ReadError::io(path, e))?.len();
        let at = |o: u64, m: String| ReadError::new(path, Position::Byte(o), m);
        // Prophesee's tools write the type and size bytes after a header; a file without a
        // header is 8-byte 2D events from the first byte.
        let (ev_type, ev_size, data_at) = if header.fields.is_empty() {
            (0, RECORD as u8, 0)
        } else {
            match head.get(header.len as usize..header.len as usize + 2) {
                Some(&[t, s]) => (t, s, header.len + 2),
                _ => {
                    return Err(at(
                        header.len,
                        "the file ends after its header: no event type and size bytes (an empty or truncated .dat)"
                            .into(),
                    ))
                }
            }
        };
        if !matches!(ev_type, 0 | 12) || usize::from(ev_size) != RECORD {
            return Err(at(
                header.len,
                format!(
                    "event type {ev_type} ({}) of {ev_size} bytes: evcal reads .dat files of CD events (type 12 or 0, 8 bytes)",
                    type_name(ev_type)
                ),
            ));
        }
        if let Some(v) = header.get("Version") {
            if !matches!(v.trim(), "1" | "2") {
                return Err(at(0, format!("'% Version {v}': evcal reads .dat versions 1 and 2")));
            }
        }
        let body = file_bytes.saturating_sub(data_at);
        let mut file = File::open(path).map_err(|e| ReadError::io(path, e))?;
        file.seek(SeekFrom::Start(data_at)).map_err(|e| ReadError::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            file,
            sensor: header.sensor().map(|(s, _)| s),
            data_at,
            records: body / RECORD as u64,
            next: 0,
            trailing: body % RECORD as u64,
            buf: vec![0; BATCH * RECORD],
            buf_at: 0,
            buf_len: 0,
            unwrap: TimeUnwrapper::new(),
            done: false,
        })
    }

    /// The sensor size from the header, if it gives one.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    /// Number of events (whole records) in the file.
    pub fn len(&self) -> u64 {
        self.records
    }

    /// Whether the file holds no events.
    pub fn is_empty(&self) -> bool {
        self.records == 0
    }

    fn fill(&mut self) -> Result<(), ReadError> {
        let want = ((self.records - self.next) as usize).min(BATCH) * RECORD;
        let offset = self.data_at + self.next * RECORD as u64;
        self.file.read_exact(&mut self.buf[..want]).map_err(|e| {
            ReadError::new(
                &self.path,
                Position::Byte(offset),
                format!("cannot read events: {e} (was the file cut while reading?)"),
            )
        })?;
        self.buf_at = 0;
        self.buf_len = want;
        Ok(())
    }
}

impl EventSource for DatReader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.done {
            return None;
        }
        if self.buf_at >= self.buf_len {
            if self.next >= self.records {
                self.done = true;
                if self.trailing > 0 {
                    let offset = self.data_at + self.records * RECORD as u64;
                    return Some(Err(ReadError::new(
                        &self.path,
                        Position::Byte(offset),
                        format!(
                            "the file ends inside an event record ({} of {RECORD} bytes): truncated? the {} whole events before it were read",
                            self.trailing, self.records
                        ),
                    )));
                }
                return None;
            }
            if let Err(e) = self.fill() {
                self.done = true;
                return Some(Err(e));
            }
        }
        let r = &self.buf[self.buf_at..self.buf_at + RECORD];
        let t = u32::from_le_bytes([r[0], r[1], r[2], r[3]]);
        let d = u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
        self.buf_at += RECORD;
        self.next += 1;
        Some(Ok(Event {
            t_us: self.unwrap.extend(t),
            x: (d & 0x3FFF) as u16,
            y: ((d >> 14) & 0x3FFF) as u16,
            polarity: (d >> 28) & 1 == 1,
        }))
    }

    fn progress_bytes(&self) -> u64 {
        self.data_at + self.next * RECORD as u64
    }
}
