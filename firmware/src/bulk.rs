//! The bulk replay format: a recording as a flat file the firmware reads fast.
//!
//! QEMU's emulated UART carries about 14 KB/s into the device, and a simulated DAVIS346
//! fires close to a million events per second, so replaying many windows over the UART would
//! take CI far too long. Under the emulator the firmware can instead read the events from a
//! host file through semihosting, while the UART still carries the protocol. This is that
//! file's format; it only exists between a host and an emulated board.
//!
//! ```text
//! header  16 bytes  "EVCALBK1", width u16, height u16, 0u32        (little-endian)
//! event    8 bytes  t u32 (µs, low 32 bits), x u16, y u16 | polarity << 15
//! ```
//!
//! Times are stored modulo 2^32 µs and extended again on reading ([`TimeUnwrapper`]), so
//! recordings longer than 71 minutes replay correctly as long as consecutive events are less
//! than 35 minutes apart.

use crate::source::{EventSource, SourceError};
use evcal_core::event::{Event, SensorSize, TimeUnwrapper};

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"EVCALBK1";
/// Header length in bytes.
pub const HEADER_LEN: usize = 16;
/// Bytes per event.
pub const EVENT_LEN: usize = 8;
/// Bytes [`BulkSource`] reads at a time: 256 events. Larger reads save semihosting calls
/// (each costs a trap into the emulator) at the price of RAM.
pub const BULK_CHUNK: usize = 2048;
/// Rows beyond this do not fit beside the polarity bit.
pub const MAX_ROWS: u16 = 1 << 15;

/// The header of a bulk file for a sensor of the given size.
pub fn encode_header(sensor: SensorSize) -> [u8; HEADER_LEN] {
    let mut h = [0u8; HEADER_LEN];
    h[..8].copy_from_slice(&MAGIC);
    h[8..10].copy_from_slice(&sensor.width.to_le_bytes());
    h[10..12].copy_from_slice(&sensor.height.to_le_bytes());
    h
}

/// Reads a header: the sensor size, or `None` if these are not the bytes of a bulk file.
pub fn decode_header(h: &[u8; HEADER_LEN]) -> Option<SensorSize> {
    if h[..8] != MAGIC || h[12..16] != [0; 4] {
        return None;
    }
    let width = u16::from_le_bytes([h[8], h[9]]);
    let height = u16::from_le_bytes([h[10], h[11]]);
    (height <= MAX_ROWS).then_some(SensorSize { width, height })
}

/// One event's record. Rows at or above [`MAX_ROWS`] cannot be stored (no sensor has them):
/// `None`.
pub fn encode_event(e: &Event) -> Option<[u8; EVENT_LEN]> {
    if e.y >= MAX_ROWS {
        return None;
    }
    let mut r = [0u8; EVENT_LEN];
    // Stored modulo 2^32 on purpose: the reader extends it again.
    r[..4].copy_from_slice(&(e.t_us as u32).to_le_bytes());
    r[4..6].copy_from_slice(&e.x.to_le_bytes());
    r[6..8].copy_from_slice(&(e.y | (u16::from(e.polarity) << 15)).to_le_bytes());
    Some(r)
}

fn decode_event(r: &[u8], unwrap: &mut TimeUnwrapper) -> Event {
    let w = |i: usize| u16::from_le_bytes([r[i], r[i + 1]]);
    let t = u32::from_le_bytes([r[0], r[1], r[2], r[3]]);
    let yp = w(6);
    Event { t_us: unwrap.extend(t), x: w(4), y: yp & 0x7FFF, polarity: yp & 0x8000 != 0 }
}

/// Events from a bulk file, read through any `embedded_io::Read` (a semihosting file on the
/// emulator; a byte slice in tests).
pub struct BulkSource<R> {
    reader: R,
    sensor: SensorSize,
    unwrap: TimeUnwrapper,
    buf: [u8; BULK_CHUNK],
    start: usize,
    end: usize,
    eof: bool,
    truncated_reported: bool,
}

impl<R: embedded_io::Read> BulkSource<R> {
    /// Reads the header. `Format` if the bytes are not a bulk file, `Io` on a read error.
    pub fn open(mut reader: R) -> Result<Self, SourceError> {
        let mut h = [0u8; HEADER_LEN];
        let mut got = 0;
        while got < HEADER_LEN {
            match reader.read(&mut h[got..]) {
                Ok(0) => return Err(SourceError::Format),
                Ok(n) => got += n,
                Err(_) => return Err(SourceError::Io),
            }
        }
        let sensor = decode_header(&h).ok_or(SourceError::Format)?;
        Ok(Self {
            reader,
            sensor,
            unwrap: TimeUnwrapper::new(),
            buf: [0; BULK_CHUNK],
            start: 0,
            end: 0,
            eof: false,
            truncated_reported: false,
        })
    }

    /// The sensor size the file states.
    pub const fn sensor(&self) -> SensorSize {
        self.sensor
    }

    /// Tops the buffer up until it holds a whole event or the file ends.
    fn fill(&mut self) -> Result<(), SourceError> {
        if self.end - self.start >= EVENT_LEN || self.eof {
            return Ok(());
        }
        self.buf.copy_within(self.start..self.end, 0);
        self.end -= self.start;
        self.start = 0;
        while self.end < EVENT_LEN && !self.eof {
            match self.reader.read(&mut self.buf[self.end..]) {
                Ok(0) => self.eof = true,
                Ok(n) => self.end += n,
                Err(_) => return Err(SourceError::Io),
            }
        }
        Ok(())
    }
}

impl<R: embedded_io::Read> EventSource for BulkSource<R> {
    fn read_events(&mut self, out: &mut [Event]) -> Result<usize, SourceError> {
        self.fill()?;
        let avail = (self.end - self.start) / EVENT_LEN;
        if avail == 0 {
            // Fewer than EVENT_LEN bytes left and the file has ended.
            if self.end > self.start && !self.truncated_reported {
                self.truncated_reported = true;
                return Err(SourceError::Truncated);
            }
            return Err(SourceError::End);
        }
        let n = avail.min(out.len());
        let bytes = &self.buf[self.start..self.start + n * EVENT_LEN];
        for (e, r) in out.iter_mut().zip(bytes.chunks_exact(EVENT_LEN)) {
            *e = decode_event(r, &mut self.unwrap);
        }
        self.start += n * EVENT_LEN;
        Ok(n)
    }
}

#[cfg(test)]
mod test {
    use super::*;

    fn file(sensor: SensorSize, events: &[Event]) -> Vec<u8> {
        let mut f = encode_header(sensor).to_vec();
        for e in events {
            f.extend_from_slice(&encode_event(e).unwrap());
        }
        f
    }

    fn read_all<R: embedded_io::Read>(src: &mut BulkSource<R>, chunk: usize) -> (Vec<Event>, SourceError) {
        let mut out = Vec::new();
        let mut buf = vec![Event::default(); chunk];
        loop {
            match src.read_events(&mut buf) {
                Ok(n) => out.extend_from_slice(&buf[..n]),
                Err(e) => return (out, e),
            }
        }
    }

    /// A reader that hands out at most `step` bytes per call, as a serial port or a slow
    /// file would.
    struct Trickle<'a> {
        bytes: &'a [u8],
        step: usize,
    }

    impl embedded_io::ErrorType for Trickle<'_> {
        type Error = core::convert::Infallible;
    }

    impl embedded_io::Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
            let n = buf.len().min(self.step).min(self.bytes.len());
            buf[..n].copy_from_slice(&self.bytes[..n]);
            self.bytes = &self.bytes[n..];
            Ok(n)
        }
    }

    fn events(n: u64) -> Vec<Event> {
        // Times cross the 32-bit wrap twice; rows up to the largest storable.
        (0..n)
            .map(|i| Event {
                t_us: i * 1_500_000_000,
                x: (i * 37 % 1280) as u16,
                y: if i == 3 { MAX_ROWS - 1 } else { (i * 11 % 720) as u16 },
                polarity: i % 3 == 0,
            })
            .collect()
    }

    #[test]
    fn round_trip_across_time_wraps_and_read_sizes() {
        let evs = events(700);
        let f = file(SensorSize::new(1280, 720), &evs);
        for (step, chunk) in [(f.len(), 1000), (1, 7), (13, 256), (BULK_CHUNK + 3, 1)] {
            let mut s = BulkSource::open(Trickle { bytes: &f, step }).unwrap();
            assert_eq!(s.sensor(), SensorSize::new(1280, 720));
            let (got, end) = read_all(&mut s, chunk);
            assert_eq!(end, SourceError::End);
            assert_eq!(got, evs, "step {step} chunk {chunk}");
        }
    }

    #[test]
    fn truncated_tail_is_reported_once_then_end() {
        let evs = events(5);
        let mut f = file(SensorSize::DAVIS346, &evs);
        f.truncate(f.len() - 3);
        let mut s = BulkSource::open(&f[..]).unwrap();
        let (got, err) = read_all(&mut s, 64);
        assert_eq!((got.as_slice(), err), (&evs[..4], SourceError::Truncated));
        assert_eq!(s.read_events(&mut [Event::default(); 4]), Err(SourceError::End));
    }

    #[test]
    fn foreign_or_short_headers_are_rejected() {
        let good = encode_header(SensorSize::DAVIS346);
        assert!(BulkSource::open(&good[..]).is_ok());
        assert_eq!(BulkSource::open(&good[..10]).err(), Some(SourceError::Format));
        for i in 0..HEADER_LEN {
            let mut h = good;
            h[i] ^= if i == 11 { 0x80 } else { 0x01 };
            // Every byte but the sensor size's low bytes is checked.
            let accepted = BulkSource::open(&h[..]).is_ok();
            assert_eq!(accepted, (8..=10).contains(&i), "byte {i}");
        }
    }

    #[test]
    fn rows_that_collide_with_polarity_are_refused() {
        assert!(encode_event(&Event { t_us: 0, x: 0, y: MAX_ROWS, polarity: false }).is_none());
    }
}
