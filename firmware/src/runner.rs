//! The window loop: events in, one detection out per completed window, each window's
//! processing timed by the board's clock (whose window hooks call the benchmark markers,
//! see [`evcal_core::detect::Clock`]).

use crate::{
    boards::{EVENTS_PER_WINDOW, TABLE_CELLS},
    source::{EventSource, SourceError},
};
use evcal_core::{
    config::MAX_CLUSTERS,
    detect::{Clock, Detection, Detector},
    event::{Event, MAX_HELD_EVENTS},
};

/// Events taken from a source per call: large enough that the call overhead does not show,
/// small enough to sit on the stack (16 bytes each).
pub const READ_BATCH: usize = 64;

/// The firmware's detector: the board's window ([`EVENTS_PER_WINDOW`]) and scratch
/// ([`TABLE_CELLS`]), the core's clusters.
pub type FwDetector = Detector<EVENTS_PER_WINDOW, MAX_CLUSTERS, MAX_HELD_EVENTS, TABLE_CELLS>;

/// Feeds events to a detector and processes each window as it completes.
pub struct Runner<'d, K, const N: usize, const C: usize, const H: usize, const CELLS: usize> {
    det: &'d mut Detector<N, C, H, CELLS>,
    clock: K,
    events: u64,
    windows: u64,
    lost: u64,
}

impl<'d, K: Clock, const N: usize, const C: usize, const H: usize, const CELLS: usize> Runner<'d, K, N, C, H, CELLS> {
    /// A runner over `det`, timing stages with `clock`.
    pub fn new(det: &'d mut Detector<N, C, H, CELLS>, clock: K) -> Self {
        Self { det, clock, events: 0, windows: 0, lost: 0 }
    }

    /// Feeds one event; when it completes a window, processes the window and returns its
    /// detection.
    pub fn feed(&mut self, e: Event) -> Option<&Detection<C>> {
        self.events += 1;
        if !self.det.feed(e) {
            return None;
        }
        self.windows += 1;
        let d = self.det.process(&mut self.clock);
        Some(d)
    }

    /// Runs `src` to its end, calling `on_window` with every detection. Returns how the
    /// source ended (`End` for a clean end). A source that has nothing now is polled again.
    pub fn drain(&mut self, src: &mut impl EventSource, mut on_window: impl FnMut(&Detection<C>)) -> SourceError {
        let mut buf = [Event::default(); READ_BATCH];
        loop {
            match src.read_events(&mut buf) {
                Ok(n) => {
                    for e in &buf[..n] {
                        if let Some(d) = self.feed(*e) {
                            on_window(d);
                        }
                    }
                    let lost = src.take_lost();
                    if lost > 0 {
                        self.det.lost();
                        self.lost += lost;
                    }
                }
                Err(e) => {
                    // What the input filter still holds (events after a pause) is windowed too.
                    while self.det.finish() {
                        self.windows += 1;
                        on_window(self.det.process(&mut self.clock));
                    }
                    return e;
                }
            }
        }
    }

    /// Events fed so far.
    pub const fn events(&self) -> u64 {
        self.events
    }

    /// Windows processed so far.
    pub const fn windows(&self) -> u64 {
        self.windows
    }

    /// Events the source lost (a full FIFO), kept out of every window.
    pub const fn lost(&self) -> u64 {
        self.lost
    }

    /// The detector (its input statistics, its configuration).
    pub fn detector(&self) -> &Detector<N, C, H, CELLS> {
        self.det
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::source::SliceSource;
    use evcal_core::{detect::DetectConfig, event::SensorSize, window::WindowConfig};

    /// A clock that advances by one on every reading, and counts the window hooks.
    #[derive(Default)]
    struct Steps {
        t: u32,
        begins: u32,
        ends: u32,
    }

    impl Clock for &mut Steps {
        fn now(&mut self) -> u32 {
            self.t += 1;
            self.t
        }
        fn window_begins(&mut self) {
            self.begins += 1;
        }
        fn window_ends(&mut self) {
            self.ends += 1;
        }
    }

    #[test]
    fn one_detection_per_window_between_the_hooks_and_same_as_push() {
        let sensor = SensorSize::new(64, 48);
        let mut cfg = DetectConfig::new(sensor);
        cfg.window = WindowConfig { events: 100, step_us: 0 };
        // A blob that moves one pixel per window, plus a few stray pixels.
        let evs: Vec<Event> = (0..1050u64)
            .map(|i| {
                let k = (i / 100) as u16;
                let (x, y) = if i % 10 == 9 {
                    ((i * 7 % 64) as u16, (i * 5 % 48) as u16)
                } else {
                    (10 + k + (i % 3) as u16, 20 + (i % 4) as u16)
                };
                Event { t_us: i, x, y, polarity: true }
            })
            .collect();
        let mut det: Box<Detector<128, 8>> = Box::new(Detector::new(cfg));
        let mut clock = Steps::default();
        let mut got = Vec::new();
        let mut r = Runner::new(&mut det, &mut clock);
        let end = r.drain(&mut SliceSource::new(&evs), |d| got.push(d.clone()));
        assert_eq!(end, SourceError::End);
        assert_eq!((r.events(), r.windows()), (1050, 10));
        assert_eq!((clock.begins, clock.ends), (10, 10));
        assert!(got.iter().all(|d| d.stats.cluster_ticks == 1 && d.stats.fit_ticks == 1), "stages timed");

        let mut reference: Box<Detector<128, 8>> = Box::new(Detector::new(cfg));
        let want: Vec<_> = evs.iter().filter_map(|e| reference.push(*e).cloned()).collect();
        assert_eq!(want.len(), 10);
        for (a, b) in got.iter().zip(&want) {
            assert_eq!((a.info, &a.centres), (b.info, &b.centres));
        }
    }

    /// A source that loses events while the detector works: every window the runner makes
    /// is the one a detector makes of the events kept, told of each loss where it fell.
    #[test]
    fn losses_at_the_source_reach_the_detector_in_their_place() {
        use crate::paced::PacedSource;
        use core::cell::Cell;
        let sensor = SensorSize::new(64, 48);
        let mut cfg = DetectConfig::new(sensor);
        cfg.window = WindowConfig { events: 100, step_us: 150 };
        let evs: Vec<Event> = (0..3000u64)
            .map(|i| Event { t_us: i, x: 10 + (i % 5) as u16, y: 20 + (i % 7) as u16, polarity: true })
            .collect();
        // The clock: 1 µs per reading, 90 µs more per window's work (the hooks).
        let clock = Cell::new(0u64);
        struct Busy<'c>(&'c Cell<u64>);
        impl Clock for Busy<'_> {
            fn now(&mut self) -> u32 {
                0
            }
            fn window_ends(&mut self) {
                self.0.set(self.0.get() + 90);
            }
        }
        let mut src: PacedSource<_, _, 16> = PacedSource::new(SliceSource::new(&evs), || {
            clock.set(clock.get() + 1);
            clock.get()
        });
        let mut det: Box<Detector<128, 8>> = Box::new(Detector::new(cfg));
        let mut got = Vec::new();
        let mut r = Runner::new(&mut det, Busy(&clock));
        assert_eq!(r.drain(&mut src, |d| got.push(d.info)), SourceError::End);
        let st = src.stats();
        assert!(st.lost > 100 && st.losses >= 5, "the device is slow enough to lose: {st:?}");
        assert_eq!(r.lost(), st.lost);
        assert!(got.len() >= 5, "{} windows", got.len());
        // The events kept are the events not lost; each window is 100 of them in a row, with
        // no lost event between its first and its last.
        let kept = r.events();
        assert_eq!(kept + st.lost, evs.len() as u64);
        for w in &got {
            assert_eq!(w.t_last_us - w.t_first_us, 99, "window {} holds lost events: {w:?}", w.seq);
        }
    }
}
