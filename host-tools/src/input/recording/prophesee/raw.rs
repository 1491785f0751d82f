//! Prophesee RAW files: the `%` header, then the sensor's EVT byte stream, decoded in chunks
//! by `evcal_core::evt` (constant memory whatever the file's size).

use super::header::{peek_header, Header};
use crate::input::recording::{
    bytes::Input,
    types::{EventSource, Position, ReadError},
};
use evcal_core::{
    event::{Event, SensorSize},
    evt::{Decoder, Encoding, Evt21Order},
};
use std::{
    io::Read,
    path::{Path, PathBuf},
};

/// Bytes read from the file at a time.
const READ_BYTES: usize = 1 << 18;
/// Events decoded at a time.
const EVENT_BATCH: usize = 1 << 13;

/// Streaming reader of Prophesee RAW files.
pub struct RawReader {
    path: PathBuf,
    file: Box<dyn Read>,
    header: Header,
    sensor: Option<SensorSize>,
    sensor_from: Option<String>,
    decoder: Decoder,
    buf: Vec<u8>,
    buf_at: usize,
    buf_len: usize,
    events: Vec<Event>,
    ev_at: usize,
    ev_len: usize,
    eof: bool,
    done: bool,
}

impl RawReader {
    /// Opens `path`, reads its header, and decodes its stream as `encoding` (which
    /// `Format::detect` settled from the header and, for EVT 2.1, the stream).
    pub fn open(path: &Path, encoding: Encoding) -> Result<Self, ReadError> {
        Self::from_input(Input::open(path)?, encoding)
    }

    /// Reads the header from `input`'s first bytes, then decodes the rest as `encoding`.
    pub(crate) fn from_input(mut input: Input, encoding: Encoding) -> Result<Self, ReadError> {
        peek_header(&mut input)?;
        let header = Header::parse(&input.head);
        let path = input.name.clone();
        let (sensor, sensor_from) = match header.sensor().map_err(|m| ReadError::new(&path, Position::File, m))? {
            Some((s, from)) => (Some(s), from),
            None => (None, None),
        };
        let mut file = input.into_reader();
        file.skip_head(header.len as usize);
        Ok(Self {
            path,
            file: Box::new(file),
            header,
            sensor,
            sensor_from,
            decoder: Decoder::new(encoding),
            buf: vec![0; READ_BYTES],
            buf_at: 0,
            buf_len: 0,
            events: vec![Event::default(); EVENT_BATCH],
            ev_at: 0,
            ev_len: 0,
            eof: false,
            done: false,
        })
    }

    /// The sensor size from the header, if it gives one.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The decoder (its statistics say what was skipped and dropped).
    pub fn decoder(&self) -> &Decoder {
        &self.decoder
    }

    fn offset(&self) -> u64 {
        self.header.len + self.decoder.stats().bytes
    }

    /// Decodes the next batch into `events`; `Ok(false)` at the end.
    fn refill(&mut self) -> Result<bool, ReadError> {
        loop {
            if self.buf_at < self.buf_len || self.decoder.has_pending_events() {
                let r = self.decoder.decode(&self.buf[self.buf_at..self.buf_len], &mut self.events);
                self.buf_at += r.consumed;
                if r.events > 0 {
                    self.ev_at = 0;
                    self.ev_len = r.events;
                    return Ok(true);
                }
                continue;
            }
            if self.eof {
                let cut = self.decoder.pending_bytes();
                if cut > 0 {
                    let enc = self.decoder.encoding();
                    return Err(ReadError::new(
                        &self.path,
                        Position::Byte(self.offset() - cut as u64),
                        format!(
                            "the file ends inside an {} word ({cut} of {} bytes): truncated? every event before it was read",
                            enc.name(),
                            enc.word_bytes()
                        ),
                    ));
                }
                return Ok(false);
            }
            let n = loop {
                match self.file.read(&mut self.buf) {
                    Ok(n) => break n,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => return Err(ReadError::new(&self.path, Position::Byte(self.offset()), e.to_string())),
                }
            };
            self.buf_at = 0;
            self.buf_len = n;
            self.eof = n == 0;
        }
    }
}

impl EventSource for RawReader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.ev_at >= self.ev_len {
            if self.done {
                return None;
            }
            match self.refill() {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    return None;
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
        let e = self.events[self.ev_at];
        self.ev_at += 1;
        Some(Ok(e))
    }

    fn progress_bytes(&self) -> u64 {
        self.offset()
    }

    fn notes(&self) -> Vec<String> {
        let mut v = Vec::new();
        if let (Some(s), Some(from)) = (self.sensor, &self.sensor_from) {
            v.push(format!("the header states no size: {}x{} is the sensor of its {from}", s.width, s.height));
        }
        if let Encoding::Evt21(order) = self.decoder.encoding() {
            v.push(match order {
                Evt21Order::HighHalfFirst => "EVT 2.1 words with the high half first (IMX636 order)".to_string(),
                Evt21Order::LowHalfFirst => "EVT 2.1 words whole little-endian (GenX320 order)".to_string(),
            });
        }
        let s = self.decoder.stats();
        if s.unsynced > 0 {
            v.push(format!(
                "{} events before the stream's first time/row/vector base were dropped (their time or address is unknown)",
                s.unsynced
            ));
        }
        if s.unknown > 0 {
            v.push(format!(
                "{} words of a reserved type skipped, the first at byte {}: corrupt data or a format evcal does not know",
                s.unknown,
                s.first_unknown_at.map_or(0, |a| a + self.header.len)
            ));
        }
        if s.time_high_steps_back > 0 {
            v.push(format!("time stepped back {} times (TIME_HIGH words out of order)", s.time_high_steps_back));
        }
        if s.time_low_wraps > 0 {
            v.push(format!(
                "{} TIME_HIGH steps inferred from TIME_LOW wrapping (the stream leaves those TIME_HIGH words out)",
                s.time_low_wraps
            ));
        }
        if s.triggers + s.others > 0 {
            v.push(format!("skipped: {} trigger words, {} other non-CD words", s.triggers, s.others));
        }
        if s.time_wraps > 0 {
            v.push(format!("the sensor clock wrapped {} times (unwrapped to 64-bit µs)", s.time_wraps));
        }
        v
    }
}
