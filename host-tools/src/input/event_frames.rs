//! A bounded, even sample of detection windows' events, kept while a recording is detected so
//! that the report can draw a few windows' events under their grids once the views are known
//! ([`crate::export::Notes::events`]).
//!
//! Which windows the solve will use is known only at the end, and a recording may run for
//! hours: the sampler keeps every k-th window (by sequence number), doubling k whenever more
//! than [`MAX_EVENT_FRAMES`] are kept, so that those kept stay spread evenly over the run
//! whatever its length.

use evcal_core::event::{Event, MAX_HELD_EVENTS};
use std::collections::VecDeque;

/// The most windows whose events are kept: a DAVIS346 window of 8000 events is 32 kB of
/// pixels, so at most half a megabyte.
pub const MAX_EVENT_FRAMES: usize = 16;

/// One window's events, as pixels.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct EventFrame {
    /// The window's sequence number ([`evcal_core::window::WindowInfo::seq`]).
    pub seq: u32,
    /// Each event's pixel, `[column, row]`, in the order read.
    pub pixels: Vec<[u16; 2]>,
}

/// Feed it every event read ([`FrameSampler::event`]) and every window the core completes
/// ([`FrameSampler::window`]); [`FrameSampler::into_frames`] gives the windows kept.
#[derive(Debug)]
pub struct FrameSampler {
    /// Keep windows whose sequence number is a multiple of this.
    every: u32,
    frames: Vec<EventFrame>,
    /// The latest events read: a window completes when its last event leaves the core's input
    /// filter, which may hold up to [`MAX_HELD_EVENTS`] read after it.
    recent: VecDeque<(u64, [u16; 2])>,
    recent_cap: usize,
}

impl FrameSampler {
    /// A sampler for windows of `window_events` events. The events of a window are those read
    /// between its first and last event's times among the last `2 × window_events +
    /// MAX_HELD_EVENTS` read: events the core dropped (off the sensor, back in time) are
    /// among them, so twice the window leaves room for them.
    pub fn new(window_events: usize) -> Self {
        let recent_cap = 2 * window_events.max(1) + MAX_HELD_EVENTS;
        Self { every: 1, frames: Vec::new(), recent: VecDeque::with_capacity(recent_cap), recent_cap }
    }

    /// An event read from the recording.
    pub fn event(&mut self, e: &Event) {
        if self.recent.len() == self.recent_cap {
            self.recent.pop_front();
        }
        self.recent.push_back((e.t_us, [e.x, e.y]));
    }

    /// Whether window `seq` is to be kept now.
    pub fn wants(&self, seq: u32) -> bool {
        seq % self.every == 0
    }

    /// A window the core completed: number `seq`, its first and last event's times.
    pub fn window(&mut self, seq: u32, t_first_us: u64, t_last_us: u64) {
        if !self.wants(seq) {
            return;
        }
        let pixels =
            self.recent.iter().filter(|(t, _)| (t_first_us..=t_last_us).contains(t)).map(|&(_, p)| p).collect();
        self.frames.push(EventFrame { seq, pixels });
        if self.frames.len() > MAX_EVENT_FRAMES {
            self.every = self.every.saturating_mul(2);
            let every = self.every;
            self.frames.retain(|f| f.seq % every == 0);
        }
    }

    /// The windows kept, in the order completed.
    pub fn into_frames(self) -> Vec<EventFrame> {
        self.frames
    }
}

#[cfg(test)]
mod test {
    use super::*;

    fn ev(t_us: u64, x: u16) -> Event {
        Event { t_us, x, y: 7, polarity: true }
    }

    /// However long the run, at most the cap is kept, evenly spread from its start to its end.
    #[test]
    fn keeps_at_most_its_cap_spread_over_the_run() {
        for windows in [1u32, 5, 16, 17, 100, 1000, 12_345] {
            let mut s = FrameSampler::new(4);
            for seq in 0..windows {
                s.window(seq, 0, 0);
            }
            let seqs: Vec<u32> = s.into_frames().iter().map(|f| f.seq).collect();
            assert!(!seqs.is_empty() && seqs.len() <= MAX_EVENT_FRAMES, "{windows}: {seqs:?}");
            assert_eq!(seqs[0], 0);
            // Equal steps, and the last kept within one step of the end.
            let step = seqs.get(1).map_or(1, |s| s - seqs[0]);
            assert!(seqs.windows(2).all(|p| p[1] - p[0] == step), "{windows}: {seqs:?}");
            assert!(windows - 1 - seqs[seqs.len() - 1] < step, "{windows}: {seqs:?}");
            if windows >= MAX_EVENT_FRAMES as u32 {
                assert!(seqs.len() > MAX_EVENT_FRAMES / 2, "{windows}: {seqs:?}");
            }
        }
    }

    /// A window's events are those read between its first and last event's times.
    #[test]
    fn a_window_holds_the_events_of_its_span() {
        let mut s = FrameSampler::new(3);
        for (t, x) in [(10, 1), (20, 2), (30, 3), (40, 4), (50, 5)] {
            s.event(&ev(t, x));
        }
        s.window(0, 20, 40);
        for t in 60..100 {
            s.event(&ev(t, 9));
        }
        // Older than the events remembered (2 × 3 + the filter's hold): none left.
        s.window(2, 10, 50);
        let f = s.into_frames();
        assert_eq!(f[0], EventFrame { seq: 0, pixels: vec![[2, 7], [3, 7], [4, 7]] });
        assert_eq!(f[1], EventFrame { seq: 2, pixels: vec![] });
    }
}
