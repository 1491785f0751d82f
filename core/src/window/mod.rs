//! The windower: cuts the event stream into windows of the first N events at or after each
//! tick of event time.
//!
//! Ticks fall every `step_us` of event time from the first event on. A window starts at the
//! first event at or after a tick and holds the next `events` events. Each event is stored
//! relative to the window's first event, in 8 bytes.
//!
//! The window's reference time `t_ref`, at which its circle centres are given, is the middle
//! of its span: `(t_first + t_last) / 2`. The paper takes the first event (any instant works
//! as long as all circles of a window share it), but a centre is estimated best near the
//! mean time of its own events, and a window's events are spread evenly over its span: at
//! the first event every centre would be extrapolated half a window back along a velocity
//! fitted from a fraction of a pixel of motion, which doubles its error in simulation.
//!
//! With one buffer of fixed size, a window is never shared by two ticks: ticks that fall
//! while a window is still filling (slow scenes, where N events take longer than a step)
//! are skipped and counted in [`WindowInfo::ticks_skipped`]. The offline reference code
//! would emit an overlapping window there instead.
//!
//! Events lost before they reach the windower (a device whose input FIFO overran while it
//! worked on a window: [`Windower::lost`]) are never inside a window: a window filling when
//! they were lost is dropped, and the next one starts at the first tick after the first event
//! that follows the loss (the lost events' times are unknown, and any of them may lie up to
//! that event). A window is the first N events at or after its tick, or it is not made.

mod size;

pub use size::{
    disc_events_per_window, events_per_window, ring_events_per_window, EVENTS_PER_WINDOW_STEP, LARGEST_WINDOW,
    REFERENCE_EVENTS_PER_WINDOW, REFERENCE_SENSOR,
};

use crate::event::Event;

/// An event inside a window: pixel, and time since the window's reference time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowEvent {
    /// Column.
    pub x: u16,
    /// Row.
    pub y: u16,
    /// Microseconds since the window's first event (saturates at `u32::MAX`, 71 minutes).
    pub dt_us: u32,
}

/// How windows are cut.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowConfig {
    /// Events per window; at least 1, at most the windower's capacity (clamped).
    pub events: usize,
    /// Microseconds between ticks; 0 means back-to-back windows.
    pub step_us: u64,
}

impl Default for WindowConfig {
    fn default() -> Self {
        Self { events: crate::config::DEFAULT_EVENTS_PER_WINDOW, step_us: crate::config::DEFAULT_STEP_US }
    }
}

/// What is known of a completed window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowInfo {
    /// Sequence number of the window, from 0.
    pub seq: u32,
    /// Time of the window's first event, in microseconds.
    pub t_first_us: u64,
    /// The window's reference time, at which its centres are given: the middle of its span,
    /// `t_first_us + (t_last_us - t_first_us) / 2` (rounded down), in microseconds.
    pub t_ref_us: u64,
    /// Time of the window's last event, in microseconds.
    pub t_last_us: u64,
    /// Ticks that started no window since the previous one: they fell inside it while it
    /// filled, or events were lost around them ([`Windower::lost`]).
    pub ticks_skipped: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// No event seen yet.
    Start,
    /// Waiting for the first event at or after tick `k`.
    Waiting { k: u64, skipped: u32 },
    /// Filling the window of tick `k`.
    Filling { k: u64, skipped: u32 },
    /// The window is complete and handed out; the next push starts a new search.
    Full { k: u64 },
}

/// Cuts an event stream into windows of at most `N` events, in inline storage.
///
/// ```
/// use evcal_core::{event::Event, window::{Windower, WindowConfig}};
/// let mut w: Windower<4> = Windower::new(WindowConfig { events: 3, step_us: 100 });
/// let mut done = None;
/// for t in [0u64, 10, 20, 30, 150, 160, 170] {
///     if let Some(info) = w.push(Event { t_us: t, x: 1, y: 2, polarity: true }) {
///         done = Some((info, w.events().len()));
///     }
/// }
/// let (info, len) = done.unwrap();
/// assert_eq!((info.seq, info.t_first_us, info.t_ref_us, info.t_last_us, len), (1, 150, 160, 170, 3));
/// ```
#[derive(Debug, Clone)]
pub struct Windower<const N: usize> {
    cfg: WindowConfig,
    buf: [WindowEvent; N],
    len: usize,
    t0: u64,
    t_first: u64,
    t_last: u64,
    seq: u32,
    state: State,
    /// Events were lost since the last event pushed: the next window's tick must come after
    /// the first event pushed.
    lost: bool,
}

impl<const N: usize> Windower<N> {
    /// A windower that cuts windows as `cfg` says (events clamped to 1..=N).
    pub const fn new(cfg: WindowConfig) -> Self {
        Self {
            cfg: Self::clamped(cfg),
            buf: [WindowEvent { x: 0, y: 0, dt_us: 0 }; N],
            len: 0,
            t0: 0,
            t_first: 0,
            t_last: 0,
            seq: 0,
            state: State::Start,
            lost: false,
        }
    }

    const fn clamped(cfg: WindowConfig) -> WindowConfig {
        let events = if cfg.events == 0 {
            1
        } else if cfg.events > N {
            N
        } else {
            cfg.events
        };
        WindowConfig { events, step_us: cfg.step_us }
    }

    /// Starts over as `new(cfg)` would, in place: the event buffer (8 bytes per event, tens
    /// of kilobytes) is neither rebuilt nor copied, which matters where it lives in a
    /// `static` and the stack is small.
    pub fn reconfigure(&mut self, cfg: WindowConfig) {
        self.cfg = Self::clamped(cfg);
        self.len = 0;
        self.t0 = 0;
        self.t_first = 0;
        self.t_last = 0;
        self.seq = 0;
        self.state = State::Start;
        self.lost = false;
    }

    /// Events were lost between the last event pushed and the next (an input FIFO that
    /// overran, counted by the caller). A window filling now is dropped (its tick counts as
    /// skipped), and the next window starts at the first tick strictly after the next event
    /// pushed, so that no window holds the place of lost events. Returns whether a window
    /// was dropped.
    pub fn lost(&mut self) -> bool {
        match self.state {
            // Nothing is known of the times yet: the first event pushed starts the ticks.
            State::Start => false,
            State::Filling { k, skipped } => {
                self.len = 0;
                self.lost = true;
                self.state = State::Waiting { k: k.saturating_add(1), skipped: skipped.saturating_add(1) };
                true
            }
            State::Waiting { .. } | State::Full { .. } => {
                self.lost = true;
                false
            }
        }
    }

    /// The configuration in force (after clamping).
    pub const fn config(&self) -> WindowConfig {
        self.cfg
    }

    /// Index of the last tick at or before `t`.
    fn tick_at(&self, t: u64) -> u64 {
        (t - self.t0).checked_div(self.cfg.step_us).unwrap_or(0)
    }

    fn tick_time(&self, k: u64) -> u64 {
        self.t0.saturating_add(k.saturating_mul(self.cfg.step_us))
    }

    /// Feeds one event (time must not go backwards: filter with
    /// [`InputFilter`](crate::event::InputFilter) first; an event earlier than the last is
    /// ignored). Returns the window's info when this event completes a window; the window's
    /// events are then in [`events`](Self::events) / [`events_mut`](Self::events_mut) until
    /// the next push.
    pub fn push(&mut self, e: Event) -> Option<WindowInfo> {
        if self.state != State::Start && e.t_us < self.t_last {
            return None;
        }
        match self.state {
            State::Start => {
                self.t0 = e.t_us;
                self.begin(e, 0, 0)
            }
            // Back-to-back windows (no ticks) start at the first event after a loss.
            State::Waiting { k, skipped } if self.lost && self.cfg.step_us != 0 => {
                self.lost = false;
                // The lost events may reach up to this one: the ticks up to its time pass
                // without a window, and it is not the first event of the next.
                let next = self.tick_at(e.t_us).saturating_add(1).max(k);
                let skipped = skipped.saturating_add(next.saturating_sub(k).min(u64::from(u32::MAX)) as u32);
                self.state = State::Waiting { k: next, skipped };
                self.t_last = e.t_us;
                None
            }
            State::Waiting { k, skipped } => {
                self.lost = false;
                if e.t_us < self.tick_time(k) {
                    self.t_last = e.t_us;
                    return None;
                }
                // After a gap, the window belongs to the last tick the event is at or after.
                let k = self.tick_at(e.t_us).max(k);
                self.begin(e, k, skipped)
            }
            State::Filling { k, skipped } => {
                self.append(e);
                if self.len >= self.cfg.events {
                    self.state = State::Full { k };
                    return Some(WindowInfo {
                        seq: self.seq,
                        t_first_us: self.t_first,
                        t_ref_us: self.t_first + (self.t_last - self.t_first) / 2,
                        t_last_us: self.t_last,
                        ticks_skipped: skipped,
                    });
                }
                let _ = k;
                None
            }
            State::Full { k } => {
                self.seq = self.seq.wrapping_add(1);
                // The next tick strictly after the full window's last event; ticks before it
                // fell inside the window.
                let next = if self.cfg.step_us == 0 { k } else { self.tick_at(self.t_last) + 1 };
                let skipped = next.saturating_sub(k + 1).min(u64::from(u32::MAX)) as u32;
                self.len = 0;
                self.state = State::Waiting { k: next, skipped };
                self.push(e)
            }
        }
    }

    fn begin(&mut self, e: Event, k: u64, skipped: u32) -> Option<WindowInfo> {
        self.t_first = e.t_us;
        self.len = 0;
        self.state = State::Filling { k, skipped };
        // Appending through the Filling arm also handles a window of one event.
        self.push(e)
    }

    fn append(&mut self, e: Event) {
        let dt = e.t_us - self.t_first;
        if self.len < N {
            self.buf[self.len] = WindowEvent { x: e.x, y: e.y, dt_us: dt.min(u64::from(u32::MAX)) as u32 };
            self.len += 1;
        }
        self.t_last = e.t_us;
    }

    /// Events of the window just completed (empty while a window fills).
    pub fn events(&self) -> &[WindowEvent] {
        match self.state {
            State::Full { .. } => &self.buf[..self.len],
            _ => &[],
        }
    }

    /// The completed window's events, for in-place processing (clustering reorders them).
    pub fn events_mut(&mut self) -> &mut [WindowEvent] {
        match self.state {
            State::Full { .. } => &mut self.buf[..self.len],
            _ => &mut [],
        }
    }

    /// Events held by the window that is still filling (dropped at the end of a stream).
    pub fn pending(&self) -> usize {
        match self.state {
            State::Filling { .. } => self.len,
            _ => 0,
        }
    }
}

#[cfg(test)]
mod test {
    use super::*;

    fn ev(t: u64) -> Event {
        Event { t_us: t, x: (t % 300) as u16, y: 7, polarity: false }
    }

    fn run<const N: usize>(cfg: WindowConfig, ts: &[u64]) -> std::vec::Vec<(WindowInfo, std::vec::Vec<WindowEvent>)> {
        let mut w: Windower<N> = Windower::new(cfg);
        let mut out = std::vec::Vec::new();
        for &t in ts {
            if let Some(info) = w.push(ev(t)) {
                out.push((info, w.events().to_vec()));
            }
        }
        out
    }

    #[test]
    fn first_n_events_at_or_after_each_tick() {
        // ticks at 0, 100, 200, 300
        let ts = [0, 10, 20, 30, 40, 99, 100, 101, 102, 250, 300, 301, 302];
        let w = run::<8>(WindowConfig { events: 3, step_us: 100 }, &ts);
        let refs: std::vec::Vec<_> = w.iter().map(|(i, _)| (i.seq, i.t_first_us, i.t_last_us)).collect();
        assert_eq!(refs, [(0, 0, 20), (1, 100, 102), (2, 250, 301)]);
        let mids: std::vec::Vec<_> = w.iter().map(|(i, _)| i.t_ref_us).collect();
        assert_eq!(mids, [10, 101, 275]);
        // the window at 250 belongs to tick 200 (first event at or after it); 300 then fell
        // inside it and was skipped
        assert_eq!(w[2].0.ticks_skipped, 0);
        let dts: std::vec::Vec<u32> = w[1].1.iter().map(|e| e.dt_us).collect();
        assert_eq!(dts, [0, 1, 2]);
    }

    #[test]
    fn ticks_inside_a_filling_window_are_skipped_and_counted() {
        // 3 events per window, but they span 0..=250 with ticks every 100
        let ts = [0, 120, 250, 260, 290, 301, 302, 303];
        let w = run::<4>(WindowConfig { events: 3, step_us: 100 }, &ts);
        assert_eq!(w.len(), 2);
        assert_eq!(w[1].0.t_first_us, 301);
        assert_eq!(w[1].0.ticks_skipped, 2, "ticks 100 and 200 fell inside window 0");
    }

    #[test]
    fn back_to_back_when_step_is_zero() {
        let ts: std::vec::Vec<u64> = (0..10).collect();
        let w = run::<4>(WindowConfig { events: 2, step_us: 0 }, &ts);
        assert_eq!(w.len(), 5);
        assert_eq!(w[4].0.t_first_us, 8);
    }

    #[test]
    fn events_clamped_to_capacity_and_backwards_time_ignored() {
        let w = run::<2>(WindowConfig { events: 10, step_us: 0 }, &[5, 6, 4, 7, 8]);
        assert_eq!(w.len(), 2);
        assert_eq!(w[0].1.len(), 2);
    }

    /// Runs `ts`, calling `lost` before each time in `losses`.
    fn run_with_losses(cfg: WindowConfig, ts: &[u64], losses: &[u64]) -> std::vec::Vec<WindowInfo> {
        let mut w: Windower<8> = Windower::new(cfg);
        let mut out = std::vec::Vec::new();
        for &t in ts {
            if losses.contains(&t) {
                w.lost();
            }
            if let Some(info) = w.push(ev(t)) {
                out.push(info);
            }
        }
        out
    }

    #[test]
    fn a_loss_while_a_window_fills_drops_it_and_the_next_tick_after_the_gap_starts_one() {
        let cfg = WindowConfig { events: 3, step_us: 100 };
        // Events lost between 110 and 120, while tick 100's window fills: it is dropped; the
        // first event after the loss (120) may follow lost ones, so tick 200 starts the next.
        let ts = [0, 10, 20, 100, 110, 120, 130, 205, 210, 220, 300, 301, 302];
        let w = run_with_losses(cfg, &ts, &[120]);
        let firsts: std::vec::Vec<_> = w.iter().map(|i| (i.seq, i.t_first_us, i.ticks_skipped)).collect();
        assert_eq!(firsts, [(0, 0, 0), (1, 205, 1), (2, 300, 0)]);
        // Without the loss, tick 100's window is made.
        let w = run_with_losses(cfg, &ts, &[]);
        assert_eq!(w[1].t_first_us, 100);
    }

    #[test]
    fn a_loss_between_windows_moves_the_next_window_past_the_gap() {
        let cfg = WindowConfig { events: 2, step_us: 100 };
        // Lost before 150 (after window 0 completed, tick 100 not yet met): the lost events
        // may lie between tick 100 and 150, so 150 does not start tick 100's window.
        let w = run_with_losses(cfg, &[0, 1, 150, 160, 210, 220], &[150]);
        let firsts: std::vec::Vec<_> = w.iter().map(|i| (i.t_first_us, i.ticks_skipped)).collect();
        assert_eq!(firsts, [(0, 0), (210, 1)]);
        // Lost before 50, all before tick 100: tick 100's window is made as usual.
        let w = run_with_losses(cfg, &[0, 1, 50, 100, 110], &[50]);
        let firsts: std::vec::Vec<_> = w.iter().map(|i| (i.t_first_us, i.ticks_skipped)).collect();
        assert_eq!(firsts, [(0, 0), (100, 0)]);
        // A loss before the first event changes nothing; back to back, the next window starts
        // at the next event.
        assert_eq!(run_with_losses(cfg, &[0, 1, 100, 101], &[0]).len(), 2);
        let w = run_with_losses(WindowConfig { events: 2, step_us: 0 }, &[0, 1, 2, 3, 4, 5], &[3]);
        let firsts: std::vec::Vec<_> = w.iter().map(|i| i.t_first_us).collect();
        assert_eq!(firsts, [0, 3]);
    }

    proptest::proptest! {
        /// No window holds the place of lost events: a window is its `events` events in a row,
        /// with no loss between them, and every loss before it lies before its tick (the lost
        /// events reach up to the event after the loss, whose time must be before the tick).
        #[test]
        fn no_window_spans_a_loss(
            gaps in proptest::collection::vec(0u64..60, 1..300),
            lossy in proptest::collection::vec(proptest::bool::weighted(0.05), 300),
            events in 1usize..6,
            step in 0u64..200,
        ) {
            let mut t = 0;
            let ts: std::vec::Vec<u64> = gaps.iter().map(|g| { t += g; t }).collect();
            let mut w: Windower<8> = Windower::new(WindowConfig { events, step_us: step });
            let mut last_loss: Option<usize> = None;
            let mut windows = 0;
            for (i, &ti) in ts.iter().enumerate() {
                if lossy[i] {
                    w.lost();
                    last_loss = Some(i);
                }
                let Some(info) = w.push(ev(ti)) else { continue };
                windows += 1;
                let first = i + 1 - events;
                proptest::prop_assert_eq!(info.t_first_us, ts[first]);
                let inside = lossy[first + 1..=i].iter().position(|&l| l);
                proptest::prop_assert!(inside.is_none(), "a loss inside the window {}..={}: {:?}", first, i, inside);
                // A loss before the first event of all changes nothing (it starts the ticks).
                if let Some(l) = last_loss.filter(|&l| l > 0 && step > 0) {
                    let tick = ts[first] - (ts[first] - ts[0]) % step;
                    proptest::prop_assert!(ts[l] < tick, "a loss before event {} (t {}) reaches the window of tick {}", l, ts[l], tick);
                }
            }
            // Without losses, as many windows as ever: the property is not met by making none.
            if !lossy.iter().take(ts.len()).any(|&l| l) && ts.len() >= events {
                proptest::prop_assert!(windows >= 1);
            }
        }
    }

    #[test]
    fn huge_gaps_and_times_do_not_overflow() {
        let ts = [0, u64::MAX / 2, u64::MAX / 2 + 1, u64::MAX - 1, u64::MAX];
        let w = run::<2>(WindowConfig { events: 2, step_us: 1 }, &ts);
        assert_eq!(w.len(), 2);
        let w = run::<2>(WindowConfig { events: 2, step_us: u64::MAX }, &ts);
        assert_eq!(w.len(), 1);
    }
}
