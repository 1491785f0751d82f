//! Where the firmware's events come from.
//!
//! Every input is an [`EventSource`]: the host's replay over the UART (the wire protocol's
//! event batches), the emulator's bulk file ([`crate::bulk::BulkSource`]), and a sensor's own
//! byte stream (Prophesee EVT through the core's decoders, or a parallel interface). The
//! window loop ([`crate::runner`]) does not know which one it reads.

use evcal_core::event::Event;

/// Why a source stopped giving events.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SourceError {
    /// The stream ended (end of a file or of a replay).
    End,
    /// The underlying transport failed (a read error of the file or port).
    Io,
    /// The bytes are not in the source's format (bad header, unknown version).
    Format,
    /// The stream ended inside an event: the partial event is lost.
    Truncated,
}

impl core::fmt::Display for SourceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::End => "end of events",
            Self::Io => "read error",
            Self::Format => "not an event stream this source understands",
            Self::Truncated => "event stream ends inside an event",
        })
    }
}

impl core::error::Error for SourceError {}

/// A source of events in time order (the core counts and drops those that are not).
pub trait EventSource {
    /// Writes the next events to the front of `buf` and returns how many. `Ok(0)` means none
    /// is available now (a live source that will have more); `Err(SourceError::End)` means
    /// there will be no more.
    fn read_events(&mut self, buf: &mut [Event]) -> Result<usize, SourceError>;

    /// Events lost since the last call (a full FIFO), told once every event read before
    /// them has been taken and before any read after them: the window loop keeps them out
    /// of every window (`Detector::lost`). A source that loses nothing keeps the default.
    fn take_lost(&mut self) -> u64 {
        0
    }
}

impl<S: EventSource + ?Sized> EventSource for &mut S {
    fn read_events(&mut self, buf: &mut [Event]) -> Result<usize, SourceError> {
        (**self).read_events(buf)
    }

    fn take_lost(&mut self) -> u64 {
        (**self).take_lost()
    }
}

/// Events from a slice in memory (tests, and replays that fit in RAM).
#[derive(Debug, Clone)]
pub struct SliceSource<'a> {
    events: &'a [Event],
}

impl<'a> SliceSource<'a> {
    /// A source that gives `events` in order, then ends.
    pub const fn new(events: &'a [Event]) -> Self {
        Self { events }
    }
}

impl EventSource for SliceSource<'_> {
    fn read_events(&mut self, buf: &mut [Event]) -> Result<usize, SourceError> {
        if self.events.is_empty() {
            return Err(SourceError::End);
        }
        let n = buf.len().min(self.events.len());
        let (now, rest) = self.events.split_at(n);
        buf[..n].copy_from_slice(now);
        self.events = rest;
        Ok(n)
    }
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn slice_source_gives_everything_then_ends() {
        let evs: Vec<Event> = (0..10u64).map(|t| Event { t_us: t, x: 1, y: 2, polarity: t % 2 == 0 }).collect();
        let mut s = SliceSource::new(&evs);
        let mut buf = [Event::default(); 4];
        let mut got = Vec::new();
        loop {
            match s.read_events(&mut buf) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) => {
                    assert_eq!(e, SourceError::End);
                    break;
                }
            }
        }
        assert_eq!(got, evs);
        assert_eq!(s.read_events(&mut buf), Err(SourceError::End));
    }
}
