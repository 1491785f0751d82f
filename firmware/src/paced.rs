//! A recording replayed at the sensor's own pace, for the emulator: each event arrives at its
//! time in the recording, on the device's clock, into a FIFO of fixed size, as a sensor's
//! events reach a microcontroller through its interface (a DMA ring). What arrives while the
//! FIFO is full is lost and counted, and the loss is told to the window loop
//! ([`EventSource::take_lost`]) at its place in the stream, so that no window holds it
//! (`evcal_core::window::Windower::lost`).
//!
//! The device's time is its clock's (on the emulator, instructions under `-icount shift=0`,
//! turned into time by the board's clock and cycles per instruction): the core's work on a
//! window takes what it takes, and the events that arrive meanwhile wait in the FIFO or are
//! lost. While the device has nothing to do (the FIFO empty), it waits for the next event:
//! the time it would sleep is skipped, not spent polling. The source's own work (reading and
//! decoding the recording, the FIFO's bookkeeping, which a sensor's interface and its DMA do
//! without the core) is left out of the device's time: what is paced is the core's, from the
//! input filter on. A sensor's format costs the core its decoding on top (the EVT decoders'
//! cost per event, docs/firmware.md).

use crate::source::{EventSource, SourceError};
use evcal_core::event::Event;

/// Events the FIFO of [`PacedSource`] holds: 256, the events of a 1 KiB DMA ring of EVT 2.0
/// words (4 bytes each), a few hundred microseconds of a busy sensor.
pub const FIFO_EVENTS: usize = 256;

/// Events read from the recording at a time (arrivals are taken one by one from them).
const STAGE: usize = 32;

/// A source that gives `inner`'s events as they arrive at the recording's pace on the
/// device's clock `now_us` (microseconds, any origin, never going back), through a FIFO of
/// `F` events. A loss is told once every event before it has been read.
pub struct PacedSource<S, T, const F: usize = FIFO_EVENTS> {
    inner: S,
    now_us: T,
    fifo: [Event; F],
    head: usize,
    len: usize,
    stage: [Event; STAGE],
    staged: usize,
    next_staged: usize,
    inner_end: Option<SourceError>,
    /// Device time at which the recording's time `t_first` arrives; moved on while the
    /// device waits with nothing to do.
    origin: Option<(u64, u64)>,
    /// Events in the FIFO before a loss, while one waits to be told.
    boundary: Option<usize>,
    lost_pending: u64,
    lost_ready: u64,
    /// Clock time spent in this source, left out of the device's time.
    excluded: u64,
    stats: PacedStats,
}

/// What a [`PacedSource`] counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PacedStats {
    /// Events that arrived (kept or lost).
    pub arrived: u64,
    /// Events lost: they arrived while the FIFO was full (or while a loss before them was
    /// still to be told).
    pub lost: u64,
    /// Separate losses (runs of lost events).
    pub losses: u64,
    /// Microseconds the device waited for events with the FIFO empty.
    pub idle_us: u64,
    /// The most events the FIFO held.
    pub fifo_peak: usize,
}

impl<S: EventSource, T: FnMut() -> u64, const F: usize> PacedSource<S, T, F> {
    /// `inner`'s events at their pace on the clock `now_us`.
    pub fn new(inner: S, now_us: T) -> Self {
        Self {
            inner,
            now_us,
            fifo: [Event::default(); F],
            head: 0,
            len: 0,
            stage: [Event::default(); STAGE],
            staged: 0,
            next_staged: 0,
            inner_end: None,
            origin: None,
            boundary: None,
            lost_pending: 0,
            lost_ready: 0,
            excluded: 0,
            stats: PacedStats::default(),
        }
    }

    /// What was counted so far.
    pub const fn stats(&self) -> PacedStats {
        self.stats
    }

    /// The recording's next event, without taking it.
    fn peek(&mut self) -> Option<Event> {
        while self.next_staged == self.staged && self.inner_end.is_none() {
            match self.inner.read_events(&mut self.stage) {
                Ok(n) => {
                    self.staged = n.min(STAGE);
                    self.next_staged = 0;
                }
                Err(e) => self.inner_end = Some(e),
            }
        }
        self.stage.get(self.next_staged).filter(|_| self.next_staged < self.staged).copied()
    }

    /// When `e` arrives, on the device's clock.
    fn arrival(&mut self, e: &Event, now: u64) -> u64 {
        let (device, recording) = *self.origin.get_or_insert((now, e.t_us));
        device.saturating_add(e.t_us.saturating_sub(recording))
    }

    /// Takes every event that has arrived by `now` into the FIFO, or loses it.
    fn admit(&mut self, now: u64) {
        while let Some(e) = self.peek() {
            if self.arrival(&e, now) > now {
                break;
            }
            self.next_staged += 1;
            self.stats.arrived += 1;
            if self.boundary.is_none() && self.len < F {
                self.fifo[(self.head + self.len) % F] = e;
                self.len += 1;
                self.stats.fifo_peak = self.stats.fifo_peak.max(self.len);
            } else {
                if self.boundary.is_none() {
                    self.boundary = Some(self.len);
                    self.stats.losses += 1;
                }
                self.lost_pending += 1;
                self.stats.lost += 1;
            }
        }
    }
}

impl<S: EventSource, T: FnMut() -> u64, const F: usize> EventSource for PacedSource<S, T, F> {
    fn read_events(&mut self, buf: &mut [Event]) -> Result<usize, SourceError> {
        let entered = (self.now_us)();
        let r = self.read_at(entered.saturating_sub(self.excluded), buf);
        self.excluded = self.excluded.saturating_add((self.now_us)().saturating_sub(entered));
        r
    }

    fn take_lost(&mut self) -> u64 {
        core::mem::take(&mut self.lost_ready)
    }
}

impl<S: EventSource, T: FnMut() -> u64, const F: usize> PacedSource<S, T, F> {
    /// [`EventSource::read_events`] at the device's time `now`.
    fn read_at(&mut self, now: u64, buf: &mut [Event]) -> Result<usize, SourceError> {
        self.admit(now);
        if self.boundary == Some(0) {
            // Every event before the loss was read: the loss is told before any after it.
            self.lost_ready += core::mem::take(&mut self.lost_pending);
            self.boundary = None;
            return Ok(0);
        }
        if self.len == 0 {
            let Some(e) = self.peek() else {
                return Err(self.inner_end.unwrap_or(SourceError::End));
            };
            // Nothing to do until the next event: the device sleeps until it arrives.
            let wait = self.arrival(&e, now).saturating_sub(now);
            self.stats.idle_us += wait;
            if let Some((device, _)) = self.origin.as_mut() {
                *device = device.saturating_sub(wait);
            }
            self.admit(now);
        }
        let n = buf.len().min(self.len).min(self.boundary.unwrap_or(usize::MAX));
        for slot in buf.iter_mut().take(n) {
            *slot = self.fifo[self.head];
            self.head = (self.head + 1) % F;
        }
        self.len -= n;
        if let Some(b) = self.boundary.as_mut() {
            *b -= n;
        }
        Ok(n)
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::source::SliceSource;
    use core::cell::Cell;

    fn events(times: &[u64]) -> Vec<Event> {
        times.iter().enumerate().map(|(i, &t)| Event { t_us: t, x: i as u16, y: 0, polarity: true }).collect()
    }

    /// Reads `src` to its end, the clock advancing by `cost` µs per event read; returns the
    /// events read, with `None` where a loss was told.
    fn drain<const F: usize>(evs: &[Event], cost: u64, busy: &[(usize, u64)]) -> (Vec<Option<Event>>, PacedStats) {
        let clock = Cell::new(1000u64);
        let mut src: PacedSource<_, _, F> = PacedSource::new(SliceSource::new(evs), || clock.get());
        let mut out = Vec::new();
        let mut buf = [Event::default(); 4];
        let mut read = 0;
        loop {
            match src.read_events(&mut buf) {
                Ok(n) => {
                    for e in &buf[..n] {
                        out.push(Some(*e));
                        read += 1;
                        clock.set(clock.get() + cost);
                        if let Some(&(_, t)) = busy.iter().find(|(at, _)| *at == read) {
                            clock.set(clock.get() + t);
                        }
                    }
                }
                Err(e) => {
                    assert_eq!(e, SourceError::End);
                    break;
                }
            }
            if src.take_lost() > 0 {
                out.push(None);
            }
        }
        (out, src.stats())
    }

    #[test]
    fn a_device_that_keeps_up_loses_nothing_and_waits_between_events() {
        let evs = events(&(0..100).map(|i| i * 10).collect::<Vec<_>>());
        let (out, st) = drain::<8>(&evs, 3, &[]);
        assert_eq!(out, evs.iter().map(|e| Some(*e)).collect::<Vec<_>>());
        assert_eq!((st.arrived, st.lost, st.losses), (100, 0, 0));
        // 10 µs between events, 3 spent on each: about 7 waited.
        assert!(st.idle_us >= 99 * 6 && st.idle_us <= 99 * 8, "{st:?}");
    }

    #[test]
    fn what_arrives_while_the_fifo_is_full_is_lost_and_told_in_its_place() {
        // An event every µs; after the 10th event read the device is busy for 40 µs, while
        // 40 events arrive into a FIFO of 8.
        let evs = events(&(0..100).collect::<Vec<_>>());
        let (out, st) = drain::<8>(&evs, 1, &[(10, 40)]);
        let gap = out.iter().position(Option::is_none).expect("a loss told");
        assert_eq!(out.iter().filter(|e| e.is_none()).count(), 1);
        let kept: Vec<Event> = out.iter().flatten().copied().collect();
        assert_eq!(kept.len() as u64 + st.lost, 100, "every event read or counted lost");
        // Before the loss: the events in order with none missing; after it: in order.
        let before: Vec<u64> = out[..gap].iter().flatten().map(|e| e.t_us).collect();
        assert_eq!(before, (0..before.len() as u64).collect::<Vec<_>>());
        let after = out[gap + 1].expect("events after the loss").t_us;
        assert_eq!(after, before.len() as u64 + st.lost, "the lost events are exactly those between");
        assert_eq!(st.losses, 1);
        assert_eq!(st.fifo_peak, 8);
        assert!(st.lost >= 30, "{st:?}");
    }

    #[test]
    fn a_slow_device_loses_again_and_again_and_counts_every_event() {
        let evs = events(&(0..1000).collect::<Vec<_>>());
        let (out, st) = drain::<16>(&evs, 3, &[]);
        let kept = out.iter().flatten().count() as u64;
        assert_eq!(kept + st.lost, 1000);
        assert!(st.losses >= 10 && st.lost > 500, "{st:?}");
        assert_eq!(out.iter().filter(|e| e.is_none()).count() as u64, st.losses);
        let times: Vec<u64> = out.iter().flatten().map(|e| e.t_us).collect();
        assert!(times.windows(2).all(|w| w[0] < w[1]), "kept in order");
    }
}
