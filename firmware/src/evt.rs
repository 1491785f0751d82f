//! A Prophesee sensor's raw byte stream (EVT 2.0, 2.1 or 3.0) as an event source: bytes from
//! any `embedded_io::Read` (a sensor's parallel or SPI interface, a serial port, a file),
//! decoded by the core's streaming decoders.

use crate::source::{EventSource, SourceError};
use evcal_core::{
    event::Event,
    evt::{DecodeStats, Decoder, Encoding},
};

/// Bytes read from the transport at a time.
pub const EVT_CHUNK: usize = 512;

/// Events from an EVT byte stream.
pub struct EvtSource<R> {
    reader: R,
    decoder: Decoder,
    buf: [u8; EVT_CHUNK],
    start: usize,
    end: usize,
    eof: bool,
    truncated_reported: bool,
}

impl<R: embedded_io::Read> EvtSource<R> {
    /// A source reading `encoding` from `reader`, from the start of a stream (after a RAW
    /// file's `%` header, if any).
    pub fn new(reader: R, encoding: Encoding) -> Self {
        Self {
            reader,
            decoder: Decoder::new(encoding),
            buf: [0; EVT_CHUNK],
            start: 0,
            end: 0,
            eof: false,
            truncated_reported: false,
        }
    }

    /// What the decoder has seen, dropped and skipped (for the device's statistics).
    pub fn stats(&self) -> &DecodeStats {
        self.decoder.stats()
    }
}

impl<R: embedded_io::Read> EventSource for EvtSource<R> {
    fn read_events(&mut self, out: &mut [Event]) -> Result<usize, SourceError> {
        if out.is_empty() {
            return Ok(0);
        }
        loop {
            let d = self.decoder.decode(&self.buf[self.start..self.end], out);
            self.start += d.consumed;
            if d.events > 0 {
                return Ok(d.events);
            }
            if self.start < self.end {
                // The decoder only stops short of its input when `out` is full; were it ever
                // to take nothing and give nothing, stop rather than spin.
                if d.consumed == 0 {
                    return Err(SourceError::Format);
                }
                continue;
            }
            if self.eof {
                if self.decoder.pending_bytes() > 0 && !self.truncated_reported {
                    self.truncated_reported = true;
                    return Err(SourceError::Truncated);
                }
                return Err(SourceError::End);
            }
            match self.reader.read(&mut self.buf) {
                Ok(0) => self.eof = true,
                Ok(n) => (self.start, self.end) = (0, n),
                Err(_) => return Err(SourceError::Io),
            }
        }
    }
}

#[cfg(test)]
mod test {
    use super::*;

    /// EVT 3.0 words: TIME_HIGH, then per event TIME_LOW, ADDR_Y, ADDR_X.
    fn evt3(events: &[(u16, u16, u16, bool)]) -> Vec<u8> {
        let mut w: Vec<u16> = vec![0x8000 | 1];
        for &(t, x, y, p) in events {
            w.push(0x6000 | t);
            w.push(y & 0x7FF);
            w.push(0x2000 | (u16::from(p) << 11) | (x & 0x7FF));
        }
        w.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn decodes_a_stream_in_any_read_and_batch_size() {
        let evs: Vec<(u16, u16, u16, bool)> = (0..300).map(|i| (i * 3, i % 640, (i * 7) % 480, i % 2 == 0)).collect();
        let bytes = evt3(&evs);
        let want: Vec<Event> =
            evs.iter().map(|&(t, x, y, p)| Event { t_us: 4096 + u64::from(t), x, y, polarity: p }).collect();
        for batch in [1, 7, 64, 1000] {
            let mut s = EvtSource::new(&bytes[..], Encoding::Evt3);
            let mut out = vec![Event::default(); batch];
            let mut got = Vec::new();
            let end = loop {
                match s.read_events(&mut out) {
                    Ok(n) => got.extend_from_slice(&out[..n]),
                    Err(e) => break e,
                }
            };
            assert_eq!(end, SourceError::End);
            assert_eq!(got, want, "batch {batch}");
            assert_eq!(s.stats().events, 300);
        }
    }

    #[test]
    fn a_stream_cut_inside_a_word_is_reported() {
        let bytes = evt3(&[(5, 3, 7, true), (6, 4, 7, false)]);
        let mut s = EvtSource::new(&bytes[..bytes.len() - 1], Encoding::Evt3);
        let mut out = [Event::default(); 8];
        assert_eq!(s.read_events(&mut out), Ok(1));
        assert_eq!(s.read_events(&mut out), Err(SourceError::Truncated));
        assert_eq!(s.read_events(&mut out), Err(SourceError::End));
    }
}
