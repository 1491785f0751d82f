//! Text recordings: one event per line, `t x y p`, `t` in seconds (RPG layout).
//!
//! Lines starting with `#` or `%` are comments. A first data line of exactly two integers
//! is read as the sensor size `width height` (some datasets write one). Seconds are parsed
//! as exact decimals, so `12.000001` is 12 000 001 µs, not whatever a float rounds it to.

use super::{EventSource, Position, ReadError};
use evcal_core::event::{Event, SensorSize};
use std::{
    fs::File,
    io::{BufRead, BufReader, BufWriter, Write},
    path::{Path, PathBuf},
};

/// Streaming reader of text recordings.
pub struct TextReader {
    path: PathBuf,
    lines: BufReader<File>,
    line_no: u64,
    bytes: u64,
    buf: String,
    sensor: Option<SensorSize>,
    /// A data line read while looking for the header, not yet returned.
    held: Option<Result<Event, ReadError>>,
    failed: bool,
}

impl TextReader {
    /// Opens `path` and reads its optional sensor-size header.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let f = File::open(path).map_err(|e| ReadError::io(path, e))?;
        let mut r = Self {
            path: path.to_path_buf(),
            lines: BufReader::with_capacity(1 << 16, f),
            line_no: 0,
            bytes: 0,
            buf: String::new(),
            sensor: None,
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
                            path,
                            Position::Line(r.line_no),
                            format!("expected 't x y p' or a 'width height' header, found '{line}'"),
                        ))
                    }
                }
            } else {
                r.held = Some(parse_event(&line).map_err(|m| ReadError::new(path, Position::Line(r.line_no), m)));
            }
        }
        Ok(r)
    }

    /// The sensor size from the header, if the file has one.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    fn next_data_line(&mut self) -> Option<Result<String, ReadError>> {
        loop {
            self.buf.clear();
            match self.lines.read_line(&mut self.buf) {
                Ok(0) => return None,
                Ok(n) => {
                    self.line_no += 1;
                    self.bytes += n as u64;
                    let t = self.buf.trim();
                    if t.is_empty() || t.starts_with('#') || t.starts_with('%') {
                        continue;
                    }
                    return Some(Ok(t.to_string()));
                }
                Err(e) => {
                    let msg = if e.kind() == std::io::ErrorKind::InvalidData {
                        "not UTF-8 text: is this a binary recording with the wrong extension?".to_string()
                    } else {
                        e.to_string()
                    };
                    return Some(Err(ReadError::new(&self.path, Position::Line(self.line_no + 1), msg)));
                }
            }
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
                Ok(line) => parse_event(&line).map_err(|m| ReadError::new(&self.path, Position::Line(self.line_no), m)),
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
}

fn parse_event(line: &str) -> Result<Event, String> {
    let mut it = line.split_whitespace();
    let (Some(t), Some(x), Some(y), Some(p)) = (it.next(), it.next(), it.next(), it.next()) else {
        return Err(format!("expected 4 fields 't x y p', found '{line}'"));
    };
    if it.next().is_some() {
        return Err(format!("expected 4 fields 't x y p', found more: '{line}'"));
    }
    let t_us = seconds_to_us(t).ok_or_else(|| format!("bad timestamp '{t}' (seconds, e.g. 0.001234)"))?;
    let x: u16 = x.parse().map_err(|_| format!("bad x '{x}' (an integer pixel column 0..65535)"))?;
    let y: u16 = y.parse().map_err(|_| format!("bad y '{y}' (an integer pixel row 0..65535)"))?;
    let polarity = match p {
        "1" | "+1" | "true" => true,
        "0" | "-1" | "false" => false,
        _ => return Err(format!("bad polarity '{p}' (1/0 or 1/-1)")),
    };
    Ok(Event { t_us, x, y, polarity })
}

/// Seconds as a decimal string to whole microseconds, rounding half up; exact for plain
/// decimals, through f64 for exponent forms. `None` for negative, non-finite or huge values.
fn seconds_to_us(s: &str) -> Option<u64> {
    if s.contains(['e', 'E']) {
        let v: f64 = s.parse().ok()?;
        return (0.0..1.8e13).contains(&v).then(|| (v * 1e6).round() as u64);
    }
    let s = s.strip_prefix('+').unwrap_or(s);
    let (int, frac) = s.split_once('.').unwrap_or((s, ""));
    if (int.is_empty() && frac.is_empty())
        || !int.bytes().all(|b| b.is_ascii_digit())
        || !frac.bytes().all(|b| b.is_ascii_digit())
    {
        return None;
    }
    let whole: u64 = if int.is_empty() { 0 } else { int.parse().ok()? };
    let mut micro: u64 = 0;
    for (i, b) in frac.bytes().chain(std::iter::repeat(b'0')).take(6).enumerate() {
        let _ = i;
        micro = micro * 10 + u64::from(b - b'0');
    }
    let round_up = frac.as_bytes().get(6).is_some_and(|&b| b >= b'5');
    whole.checked_mul(1_000_000)?.checked_add(micro + u64::from(round_up))
}

/// Writes events as a text recording (`t x y p`, t in seconds with 6 decimals), with a
/// `width height` header line when `sensor` is given.
pub fn write_text(path: &Path, sensor: Option<SensorSize>, events: &[Event]) -> std::io::Result<()> {
    let mut w = BufWriter::with_capacity(1 << 16, File::create(path)?);
    if let Some(s) = sensor {
        writeln!(w, "{} {}", s.width, s.height)?;
    }
    for e in events {
        writeln!(w, "{}.{:06} {} {} {}", e.t_us / 1_000_000, e.t_us % 1_000_000, e.x, e.y, u8::from(e.polarity))?;
    }
    w.flush()
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::recording::Recording;

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
