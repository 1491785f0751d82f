//! Text recordings: one event per line, `t x y p`, `t` in seconds (RPG layout).
//!
//! Lines starting with `#` or `%` are comments. A first data line of exactly two integers
//! is read as the sensor size `width height` (some datasets write one). Seconds are parsed
//! as exact decimals, so `12.000001` is 12 000 001 µs, not whatever a float rounds it to.
//!
//! Times are seconds unless the caller gives a unit; a file whose first nonzero time is an
//! integer (no decimal point) holds ticks, taken as µs (ns from 1e17, Unix time in ns), and
//! a note says so. A line is at most [`MAX_LINE`] bytes: a longer one (a binary file, a
//! stream of NUL bytes) ends the read with an error quoting its start, in constant memory.

use super::{
    bytes::{quote, Input},
    types::{EventSource, Position, ReadError, TimeUnit},
};
use evcal_core::event::{Event, SensorSize};
use std::{
    fs::File,
    io::{BufRead, BufReader, BufWriter, Read, Write},
    path::{Path, PathBuf},
};

/// The longest line read: an event line is some 30 bytes, a comment rarely a few hundred.
pub const MAX_LINE: usize = 4096;

/// Bytes of a bad line quoted in a message.
const QUOTE: usize = 40;

/// How times are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Times {
    /// Not decided yet: every time so far was zero.
    Undecided,
    /// Given by the caller.
    Given(TimeUnit),
    /// Decimal seconds, the layout's convention.
    Seconds,
    /// Integer ticks of a unit guessed from the first nonzero time.
    Ticks(TimeUnit),
}

/// Streaming reader of text recordings.
pub struct TextReader {
    path: PathBuf,
    lines: BufReader<Box<dyn Read>>,
    line_no: u64,
    bytes: u64,
    line: Vec<u8>,
    sensor: Option<SensorSize>,
    times: Times,
    notes: Vec<String>,
    /// A data line read while looking for the header, not yet returned.
    held: Option<Result<Event, ReadError>>,
    failed: bool,
}

impl TextReader {
    /// Opens `path` and reads its optional sensor-size header; times in seconds unless the
    /// file's integers say otherwise.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let f = File::open(path).map_err(|e| ReadError::io(path, e))?;
        Self::from_reader(path, Box::new(f), None)
    }

    /// Reads a text recording from `r`, named `name` in messages, with times in `unit` if
    /// given (decimals allowed in any unit).
    pub fn from_reader(name: &Path, r: Box<dyn Read>, unit: Option<TimeUnit>) -> Result<Self, ReadError> {
        let mut r = Self {
            path: name.to_path_buf(),
            lines: BufReader::with_capacity(1 << 16, r),
            line_no: 0,
            bytes: 0,
            line: Vec::new(),
            sensor: None,
            times: unit.map_or(Times::Undecided, Times::Given),
            notes: Vec::new(),
            held: None,
            failed: false,
        };
        if let Some(line) = r.next_data_line() {
            let line = line?;
            let fields: Vec<&str> = line.split_whitespace().collect();
            if fields.len() == 2 {
                let w = fields[0].parse::<u16>();
                let h = fields[1].parse::<u16>();
                match (w, h) {
                    (Ok(w), Ok(h)) if w > 0 && h > 0 => r.sensor = Some(SensorSize::new(w, h)),
                    _ => {
                        return Err(ReadError::new(
                            name,
                            Position::Line(r.line_no),
                            format!(
                                "expected 't x y p' or a 'width height' header, found \"{}\"",
                                quote(line.as_bytes(), QUOTE)
                            ),
                        ))
                    }
                }
            } else {
                r.held = Some(r.parse_event(&line));
            }
        }
        Ok(r)
    }

    /// The sensor size from the header, if the file has one.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    fn error(&self, line: u64, m: impl Into<String>) -> ReadError {
        ReadError::new(&self.path, Position::Line(line), m)
    }

    /// Reads one line into `self.line` (without its end), at most [`MAX_LINE`] bytes;
    /// `Ok(false)` at the end of the input.
    fn read_line(&mut self) -> Result<bool, ReadError> {
        self.line.clear();
        let at = self.line_no + 1;
        let mut any = false;
        loop {
            let buf = match self.lines.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(self.error(at, e.to_string())),
            };
            if buf.is_empty() {
                break;
            }
            any = true;
            let (take, end) = match buf.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (buf.len(), false),
            };
            let room = MAX_LINE + 1 - self.line.len();
            self.line.extend_from_slice(&buf[..take.min(room)]);
            self.lines.consume(take);
            self.bytes += take as u64;
            if self.line.len() > MAX_LINE {
                return Err(self.error(
                    at,
                    format!(
                        "a line longer than {MAX_LINE} bytes (it starts \"{}\"): not a text recording of one event a line?",
                        quote(&self.line, QUOTE)
                    ),
                ));
            }
            if end {
                break;
            }
        }
        if !any {
            return Ok(false);
        }
        self.line_no += 1;
        while self.line.last().is_some_and(|&b| b == b'\n' || b == b'\r') {
            self.line.pop();
        }
        Ok(true)
    }

    fn next_data_line(&mut self) -> Option<Result<String, ReadError>> {
        loop {
            match self.read_line() {
                Ok(false) => return None,
                Ok(true) => {}
                Err(e) => return Some(Err(e)),
            }
            let mut bytes = &self.line[..];
            if self.line_no == 1 {
                if let Some(b) = bytes.strip_prefix("\u{feff}".as_bytes()) {
                    bytes = b;
                    self.notes
                        .push(format!("{}: a UTF-8 byte-order mark at the start was skipped", self.path.display()));
                }
            }
            let t = match std::str::from_utf8(bytes) {
                Ok(t) => t.trim(),
                Err(e) => {
                    return Some(Err(self.error(
                        self.line_no,
                        format!(
                            "not UTF-8 text (byte {} of the line; it starts \"{}\"): is this a binary recording with the wrong extension?",
                            e.valid_up_to() + 1,
                            quote(bytes, QUOTE)
                        ),
                    )))
                }
            };
            if let Some(i) = bytes.iter().position(|&b| b == 0) {
                return Some(Err(self.error(
                    self.line_no,
                    format!(
                        "a NUL byte at column {} (the line starts \"{}\"): binary data, not a text recording",
                        i + 1,
                        quote(bytes, QUOTE)
                    ),
                )));
            }
            if t.is_empty() || t.starts_with('#') || t.starts_with('%') {
                continue;
            }
            return Some(Ok(t.to_string()));
        }
    }

    fn parse_event(&mut self, line: &str) -> Result<Event, ReadError> {
        let line_no = self.line_no;
        let q = || quote(line.as_bytes(), QUOTE);
        let mut it = line.split_whitespace();
        let (Some(t), Some(x), Some(y), Some(p)) = (it.next(), it.next(), it.next(), it.next()) else {
            let hint = if line.starts_with('{') { " (detections? they are read from a .jsonl file)" } else { "" };
            return Err(self.error(line_no, format!("expected 4 fields 't x y p', found \"{}\"{hint}", q())));
        };
        if it.next().is_some() {
            return Err(self.error(line_no, format!("expected 4 fields 't x y p', found more: \"{}\"", q())));
        }
        let t_us = self.time(t).map_err(|m| self.error(line_no, m))?;
        let bad = |m: String| self.error(line_no, m);
        let x: u16 = x
            .parse()
            .map_err(|_| bad(format!("bad x '{}' (an integer pixel column 0..65535)", quote(x.as_bytes(), QUOTE))))?;
        let y: u16 = y
            .parse()
            .map_err(|_| bad(format!("bad y '{}' (an integer pixel row 0..65535)", quote(y.as_bytes(), QUOTE))))?;
        let polarity = match p {
            "1" | "+1" | "true" => true,
            "0" | "-1" | "false" => false,
            _ => return Err(bad(format!("bad polarity '{}' (1/0 or 1/-1)", quote(p.as_bytes(), QUOTE)))),
        };
        Ok(Event { t_us, x, y, polarity })
    }

    /// The time `t` in µs, deciding the unit at the first nonzero time.
    fn time(&mut self, t: &str) -> Result<u64, String> {
        let bad = || format!("bad timestamp '{}' (seconds, e.g. 0.001234)", quote(t.as_bytes(), QUOTE));
        let integer = !t.is_empty() && t.trim_start_matches('+').bytes().all(|b| b.is_ascii_digit());
        if self.times == Times::Undecided {
            if integer && t.trim_start_matches('+').bytes().all(|b| b == b'0') {
                return Ok(0);
            }
            if integer {
                let v: u128 = t.trim_start_matches('+').parse().map_err(|_| bad())?;
                let unit = if v >= 100_000_000_000_000_000 { TimeUnit::Nanoseconds } else { TimeUnit::Microseconds };
                self.times = Times::Ticks(unit);
                self.notes.push(format!(
                    "{}: the times are integers (the first nonzero one, line {}, is {t}): taken as {} ticks, not seconds; set --time-unit to override",
                    self.path.display(),
                    self.line_no,
                    unit.name()
                ));
            } else {
                self.times = Times::Seconds;
            }
        }
        match self.times {
            Times::Given(u) => to_us(t, u).ok_or_else(|| {
                format!("bad timestamp '{}' (a non-negative number of {})", quote(t.as_bytes(), QUOTE), u.name())
            }),
            Times::Ticks(u) if !integer => Err(format!(
                "timestamp '{}' is not an integer, but the times before it were (taken as {} ticks): mixed units? set --time-unit",
                quote(t.as_bytes(), QUOTE),
                u.name()
            )),
            Times::Ticks(u) => to_us(t, u).ok_or_else(bad),
            Times::Seconds | Times::Undecided => seconds_to_us(t).ok_or_else(bad),
        }
    }
}

impl EventSource for TextReader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.failed {
            return None;
        }
        let r = if let Some(h) = self.held.take() {
            h
        } else {
            match self.next_data_line()? {
                Ok(line) => self.parse_event(&line),
                Err(e) => Err(e),
            }
        };
        // After an error the reader stops: a caller that goes on would see a shifted stream.
        self.failed = r.is_err();
        Some(r)
    }

    fn progress_bytes(&self) -> u64 {
        self.bytes
    }

    fn notes(&self) -> Vec<String> {
        self.notes.clone()
    }
}

/// Opens a text recording on an input whose head was peeked.
pub(crate) fn from_input(input: Input, unit: Option<TimeUnit>) -> Result<TextReader, ReadError> {
    let name = input.name.clone();
    TextReader::from_reader(&name, Box::new(input.into_reader()), unit)
}

/// Seconds as a decimal string to whole microseconds, rounding half up; exact for plain
/// decimals, through f64 for exponent forms. `None` for negative, non-finite or huge values.
fn seconds_to_us(s: &str) -> Option<u64> {
    to_us(s, TimeUnit::Seconds)
}

/// A decimal number of `unit` to whole microseconds, rounding half up (on the first digit
/// past the µs, as a hand would); exact for plain decimals, through f64 for exponent forms.
fn to_us(s: &str, unit: TimeUnit) -> Option<u64> {
    let e: i32 = match unit {
        TimeUnit::Seconds => 6,
        TimeUnit::Milliseconds => 3,
        TimeUnit::Microseconds => 0,
        TimeUnit::Nanoseconds => -3,
    };
    if s.contains(['e', 'E']) {
        let v: f64 = s.parse().ok()?;
        let us = v * 10f64.powi(e);
        return (0.0..1.8e19).contains(&us).then(|| us.round() as u64);
    }
    let s = s.strip_prefix('+').unwrap_or(s);
    let (int, frac) = s.split_once('.').unwrap_or((s, ""));
    if (int.is_empty() && frac.is_empty())
        || !int.bytes().all(|b| b.is_ascii_digit())
        || !frac.bytes().all(|b| b.is_ascii_digit())
    {
        return None;
    }
    let int = int.trim_start_matches('0');
    if int.len() > 24 {
        return None;
    }
    // Digits past the first one below a µs cannot change the rounding.
    let keep = &frac[..frac.len().min((e + 1).max(0) as usize)];
    let mut n: u128 = 0;
    for b in int.bytes().chain(keep.bytes()) {
        n = n * 10 + u128::from(b - b'0');
    }
    let d = e - keep.len() as i32;
    let us = if d >= 0 {
        n * 10u128.pow(d as u32)
    } else {
        let div = 10u128.pow((-d) as u32);
        (n + div / 2) / div
    };
    u64::try_from(us).ok()
}

/// Writes events as a text recording (`t x y p`, t in seconds with 6 decimals), with a
/// `width height` header line when `sensor` is given; through a temporary file renamed over
/// `path` ([`crate::export::atomic`]), so that a failure leaves `path` as it was.
pub fn write_text(path: &Path, sensor: Option<SensorSize>, events: &[Event]) -> std::io::Result<()> {
    let mut w = TextWriter::create(path, sensor)?;
    w.write(events)?;
    w.finish()
}

/// Writes a text recording as [`write_text`] does, the events as they come.
pub struct TextWriter(BufWriter<crate::export::atomic::AtomicFile>);

impl TextWriter {
    /// Starts `path` (replacing it at [`TextWriter::finish`], through a temporary file beside
    /// it) and writes the `width height` header if `sensor` is given.
    pub fn create(path: &Path, sensor: Option<SensorSize>) -> std::io::Result<Self> {
        let f = crate::export::atomic::AtomicFile::create(path).map_err(std::io::Error::other)?;
        let mut w = BufWriter::with_capacity(1 << 16, f);
        if let Some(s) = sensor {
            writeln!(w, "{} {}", s.width, s.height)?;
        }
        Ok(Self(w))
    }

    /// Appends `events`.
    pub fn write(&mut self, events: &[Event]) -> std::io::Result<()> {
        for e in events {
            let (s, us) = (e.t_us / 1_000_000, e.t_us % 1_000_000);
            writeln!(self.0, "{s}.{us:06} {} {} {}", e.x, e.y, u8::from(e.polarity))?;
        }
        Ok(())
    }

    /// Writes what is buffered and puts the file in place; dropped before, the file is left
    /// as it was.
    pub fn finish(self) -> std::io::Result<()> {
        let f = self.0.into_inner().map_err(|e| e.into_error())?;
        f.commit().map_err(std::io::Error::other)
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::input::recording::Recording;

    #[test]
    fn seconds_are_exact() {
        assert_eq!(seconds_to_us("12.000001"), Some(12_000_001));
        assert_eq!(seconds_to_us("0.0000015"), Some(2));
        assert_eq!(seconds_to_us("0.0000014999"), Some(1));
        assert_eq!(seconds_to_us(".5"), Some(500_000));
        assert_eq!(seconds_to_us("3"), Some(3_000_000));
        assert_eq!(seconds_to_us("1.5e-3"), Some(1500));
        assert_eq!(seconds_to_us("5000.123456789"), Some(5_000_123_457));
        for bad in ["-1", "abc", "1.2.3", "", ".", "nan", "1e300"] {
            assert_eq!(seconds_to_us(bad), None, "{bad}");
        }
    }

    #[test]
    fn round_trip_with_header_and_comments() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.txt");
        let events: Vec<Event> = (0..1000u64)
            .map(|i| Event {
                t_us: i * 37 + 5_000_000_000,
                x: (i % 346) as u16,
                y: (i % 260) as u16,
                polarity: i % 3 == 0,
            })
            .collect();
        write_text(&p, Some(SensorSize::DAVIS346), &events).unwrap();
        let rec = Recording::open(&p).unwrap();
        assert_eq!(rec.sensor, Some(SensorSize::DAVIS346));
        let back: Vec<Event> = rec.map(Result::unwrap).collect();
        assert_eq!(back, events);

        std::fs::write(&p, "# comment\n% another\n\n0.5 1 2 -1\n0.6 3 4 1\n").unwrap();
        let rec = Recording::open(&p).unwrap();
        assert_eq!(rec.sensor, None);
        let back: Vec<Event> = rec.map(Result::unwrap).collect();
        assert_eq!(back.len(), 2);
        assert_eq!(back[0], Event { t_us: 500_000, x: 1, y: 2, polarity: false });
    }

    #[test]
    fn bad_lines_name_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.txt");
        for (content, line, what) in [
            ("0.1 1 2 1\n0.2 1 2\n", 2, "4 fields"),
            ("0.1 1 2 1\n0.2 70000 2 1\n", 2, "bad x"),
            ("0.1 1 2 1\n\n0.2 1 -3 1\n", 3, "bad y"),
            ("0.1 1 2 7\n", 1, "polarity"),
            ("abc 1 2 1\n", 1, "timestamp"),
            ("346 x\n", 1, "header"),
        ] {
            std::fs::write(&p, content).unwrap();
            let err = match Recording::open(&p) {
                Err(e) => e,
                Ok(rec) => rec.filter_map(Result::err).next().expect("an error"),
            };
            assert_eq!(err.at, Position::Line(line), "{content:?}");
            let msg = err.to_string();
            assert!(msg.contains("bad.txt") && msg.contains(what), "{msg}");
        }
        std::fs::write(&p, [0xffu8, 0xfe, 0x00, 0x10, b'\n']).unwrap();
        let r = Recording::open(&p);
        let msg = match r {
            Err(e) => e.to_string(),
            Ok(rec) => rec.filter_map(Result::err).next().unwrap().to_string(),
        };
        assert!(msg.contains("UTF-8"), "{msg}");
    }

    #[test]
    fn empty_file_gives_no_events() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("empty.txt");
        std::fs::write(&p, "").unwrap();
        assert_eq!(Recording::open(&p).unwrap().count(), 0);
    }
}
