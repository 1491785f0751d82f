//! Prophesee `.dat` files of CD events: a `% ` header (`% Height`, `% Width`, `% Version 2`),
//! then one byte of event type and one of event size, then records of that size. A CD record
//! (type 12, or type 0 of older files) is 8 bytes: a little-endian u32 timestamp in µs and a
//! u32 with x in bits 0..14, y in bits 14..28 and the polarity in bit 28.

use super::header::{peek_header, Header};
use crate::input::recording::{
    bytes::{read_up_to, Input},
    types::{EventSource, Position, ReadError},
};
use evcal_core::event::{Event, SensorSize, TimeUnwrapper};
use std::{
    io::Read,
    path::{Path, PathBuf},
};

/// Bytes of a CD record.
const RECORD: usize = 8;
/// Records read at a time.
const BATCH: usize = 1 << 15;

/// Streaming reader of Prophesee CD-event `.dat` files.
pub struct DatReader {
    path: PathBuf,
    file: Box<dyn Read>,
    sensor: Option<SensorSize>,
    /// Offset of the first record.
    data_at: u64,
    /// Whole records in the file, when its size is known.
    records: Option<u64>,
    next: u64,
    buf: Vec<u8>,
    buf_at: usize,
    buf_len: usize,
    eof: bool,
    unwrap: TimeUnwrapper,
    last_t: Option<u32>,
    /// The last time jumped ahead of the one before by more than half the 32-bit clock: a
    /// step back as far after it is the stream going on from a stray time, not a wrap.
    jumped: bool,
    /// Such stray times, and the offset of the record after the first.
    strays: u64,
    first_stray_at: u64,
    /// Where the input ended inside a record, and how many of its bytes it held.
    cut: Option<(u64, usize)>,
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
        Self::from_input(Input::open(path)?)
    }

    /// Reads the header from `input`'s first bytes and checks that CD records follow.
    pub(crate) fn from_input(mut input: Input) -> Result<Self, ReadError> {
        let path = input.name.clone();
        peek_header(&mut input)?;
        let head = &input.head;
        let header = Header::parse(head);
        let at = |o: u64, m: String| ReadError::new(&path, Position::Byte(o), m);
        // Prophesee's tools always write a header: without one, nothing tells a .dat from any
        // other bytes (random data reads as plausible events), so it is refused.
        // An empty file holds nothing to misread: no events.
        if header.fields.is_empty() && !head.is_empty() {
            let what = format!("it starts \"{}\"", crate::input::recording::bytes::quote(head, 16));
            return Err(at(
                0,
                format!(
                    "not a Prophesee .dat file: no '% ' header lines (Prophesee's tools write '% Version 2', \
                     '% Width', '% Height' first), but {what}"
                ),
            ));
        }
        let (ev_type, ev_size, data_at) = match head.get(header.len as usize..header.len as usize + 2) {
            _ if head.is_empty() => (12, RECORD as u8, 0),
            Some(&[t, s]) => (t, s, header.len + 2),
            _ => {
                return Err(at(
                    header.len,
                    "the file ends after its header: no event type and size bytes (an empty or truncated .dat)".into(),
                ))
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
        let records = input.len.map(|l| l.saturating_sub(data_at) / RECORD as u64);
        let sensor = header.sensor().map_err(|m| ReadError::new(&path, Position::File, m))?.map(|(s, _)| s);
        let mut file = input.into_reader();
        file.skip_head(data_at as usize);
        Ok(Self {
            path,
            file: Box::new(file),
            sensor,
            data_at,
            records,
            next: 0,
            buf: vec![0; BATCH * RECORD],
            buf_at: 0,
            buf_len: 0,
            eof: false,
            unwrap: TimeUnwrapper::new(),
            last_t: None,
            jumped: false,
            strays: 0,
            first_stray_at: 0,
            cut: None,
            done: false,
        })
    }

    /// The sensor size from the header, if it gives one.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    /// Number of events (whole records) in the file, when its size is known (not a stream).
    pub fn len(&self) -> Option<u64> {
        self.records
    }

    /// Whether the file holds no events (as far as its size tells).
    pub fn is_empty(&self) -> bool {
        self.records == Some(0)
    }

    fn offset(&self) -> u64 {
        self.data_at + self.next * RECORD as u64
    }

    /// Reads the next batch; `Ok(false)` at the end.
    fn fill(&mut self) -> Result<bool, ReadError> {
        let offset = self.offset();
        let n = read_up_to(&mut self.file, &mut self.buf).map_err(|e| {
            ReadError::new(
                &self.path,
                Position::Byte(offset),
                format!("cannot read events: {e} (was the file cut while reading?)"),
            )
        })?;
        self.eof = n < self.buf.len();
        let whole = n - n % RECORD;
        if n % RECORD != 0 {
            let offset = offset + whole as u64;
            // The whole records before the cut are returned first.
            self.buf_len = whole;
            self.buf_at = 0;
            self.cut = Some((offset, n % RECORD));
        } else {
            self.buf_len = n;
            self.buf_at = 0;
        }
        Ok(whole > 0)
    }

    /// Checks a record against the header and the records before it: a file that is not
    /// a CD recording fails here rather than giving plausible garbage.
    fn check(&mut self, t: u32, d: u32) -> Result<(), String> {
        self.check_record(t, d)?;
        self.jumped = self.last_t.is_some_and(|last| t > last && t - last > u32::MAX / 2);
        self.last_t = Some(t);
        Ok(())
    }

    fn check_record(&self, t: u32, d: u32) -> Result<(), String> {
        if d >> 29 != 0 {
            return Err(format!("bad CD record: bits 29..32 are {:#x}, not zero (a polarity is one bit)", d >> 29));
        }
        let (x, y) = (d & 0x3FFF, (d >> 14) & 0x3FFF);
        if let Some(s) = self.sensor {
            if x >= u32::from(s.width) || y >= u32::from(s.height) {
                return Err(format!(
                    "event at x {x}, y {y} outside the {}x{} sensor of the header: corrupt data?",
                    s.width, s.height
                ));
            }
        }
        if let Some(last) = self.last_t {
            // A step back of more than half the clock is its 32-bit wrap; a smaller one is
            // out of order, which Prophesee's tools never write.
            if t < last && last - t <= u32::MAX / 2 {
                return Err(format!("time goes back from {last} to {t} µs: corrupt data, or not a CD recording"));
            }
        }
        Ok(())
    }

    /// The 64-bit time of record time `t`: its 32-bit wrap extended, unless the time before
    /// was a stray far ahead (see `jumped`), which the detector's input filter then drops.
    fn time(&mut self, t: u32) -> u64 {
        let stray_before = self.jumped && self.last_t.is_some_and(|last| t < last && last - t > u32::MAX / 2);
        if stray_before {
            if self.strays == 0 {
                self.first_stray_at = self.offset();
            }
            self.strays += 1;
            return self.unwrap.take_as_is(t);
        }
        self.unwrap.extend(t)
    }
}

impl EventSource for DatReader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.done {
            return None;
        }
        if self.buf_at >= self.buf_len {
            let more = if self.eof { Ok(false) } else { self.fill() };
            match more {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    if let Some((offset, n)) = self.cut.take() {
                        return Some(Err(ReadError::new(
                            &self.path,
                            Position::Byte(offset),
                            format!(
                                "the file ends inside an event record ({n} of {RECORD} bytes): truncated? the {} whole events before it were read",
                                self.next
                            ),
                        )));
                    }
                    return None;
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
        let r = &self.buf[self.buf_at..self.buf_at + RECORD];
        let t = u32::from_le_bytes([r[0], r[1], r[2], r[3]]);
        let d = u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
        // The time is extended before the check moves `last_t` on.
        let t_us = self.time(t);
        if let Err(m) = self.check(t, d) {
            self.done = true;
            return Some(Err(ReadError::new(&self.path, Position::Byte(self.offset()), m)));
        }
        self.buf_at += RECORD;
        self.next += 1;
        Some(Ok(Event { t_us, x: (d & 0x3FFF) as u16, y: ((d >> 14) & 0x3FFF) as u16, polarity: (d >> 28) & 1 == 1 }))
    }

    fn progress_bytes(&self) -> u64 {
        self.offset()
    }

    fn notes(&self) -> Vec<String> {
        if self.strays == 0 {
            return Vec::new();
        }
        vec![format!(
            "{}: byte {}: {} time(s) step back by more than half the 32-bit clock right after a time that jumped ahead as far: taken as stray times (corrupt data?), not as the clock's wrap; the detector drops them",
            self.path.display(),
            self.first_stray_at,
            self.strays
        )]
    }
}
