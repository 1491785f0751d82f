//! The input filter: pixel on the sensor, time in order, and one stray time not allowed to
//! poison what follows it (how: [`InputFilter`]).

use super::{Event, SensorSize};

/// The step ahead, µs, beyond which an event is held until the events after it confirm its
/// time: a calibration scene (a moving target, and every pixel's background activity) gives
/// events every few microseconds to a millisecond, so 100 ms without one is far beyond any
/// real gap while the target moves, and a longer real pause (a paused recording, a covered
/// lens) still passes once the events after it confirm it.
pub const MAX_STEP_US: u64 = 100_000;

/// Events the device's filter can hold (16 bytes each): half of them decide, so a stray
/// burst of up to 16 events (a `TIME_HIGH` period of 64 µs at 250 k events/s) is dropped.
pub const MAX_HELD_EVENTS: usize = 32;

/// Counts of what [`InputFilter`] accepted and dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InputStats {
    /// Events passed on.
    pub accepted: u64,
    /// Events dropped because their pixel lies outside the sensor.
    pub out_of_sensor: u64,
    /// Events dropped because time went backwards.
    pub time_backwards: u64,
    /// Events dropped as stray times: far ahead of the events before them, while the events
    /// after them went on from before.
    pub time_jumps: u64,
    /// The largest step ahead, µs, of a time dropped as stray (0 when none was).
    pub largest_jump_us: u64,
}

impl InputStats {
    /// All events dropped, for any reason.
    pub const fn dropped(&self) -> u64 {
        self.out_of_sensor + self.time_order()
    }

    /// Events dropped for their time: back in time, or stray.
    pub const fn time_order(&self) -> u64 {
        self.time_backwards + self.time_jumps
    }
}

/// Validates events before they reach the windower: pixel on the sensor, time not going
/// backwards, a stray time held and dropped. Bad events are counted and dropped; nothing
/// panics or allocates.
///
/// Keeping the last accepted time as a high-water mark drops an event earlier than it; but
/// then one event whose time jumps far ahead (a corrupt word, a USB reset, a stray EVT 2.0
/// `TIME_HIGH`) would make every later event "back in time". So an event more than
/// [`MAX_STEP_US`] ahead of the last accepted one is *held*, with the events after it, until
/// they say which time is real: if [`confirm`](InputFilter::CONFIRM) of them go on from the
/// held event's time (at or after it), it was a real pause and everything held is released
/// in order; if as many go on from before it, it was a stray and is dropped
/// ([`InputStats::time_jumps`]). The first event of a stream is held the same way, as
/// nothing vouches for it (the events after it then go on from before it only if they are
/// more than [`MAX_STEP_US`] earlier). When the hold fills first (or the input ends, see
/// [`finish`](InputFilter::finish)) the majority decides, a tie for the held time: a burst of
/// more than half the hold's events at a stray time is taken as real, and the events after
/// it are then dropped as back in time (counted, so a caller can say so).
///
/// Feed it with [`push`](Self::push), which returns the event at once in the usual case,
/// then take what it releases from its hold with [`pop`](Self::pop) until `None`; at the end
/// of the input call [`finish`](Self::finish) and `pop` until `None` again. `H` is the
/// hold's capacity, at least 2.
#[derive(Debug, Clone)]
pub struct InputFilter<const H: usize = MAX_HELD_EVENTS> {
    sensor: SensorSize,
    last_t: Option<u64>,
    stats: InputStats,
    /// Held events, a ring from `start`, `len` of them.
    held: [Event; H],
    start: usize,
    len: usize,
    /// Followers of the oldest held event looked at so far, and how many of them went on
    /// from its time (`ahead`) or from before it (`behind`).
    counted: usize,
    ahead: usize,
    behind: usize,
    /// The input has ended: decide whatever is held.
    finishing: bool,
}

impl<const H: usize> InputFilter<H> {
    const CHECK: () = assert!(H >= 2, "the hold must have room for an event and a follower");

    /// Followers that settle a held event's fate: half the hold, so that the hold fills no
    /// sooner than one side has a majority.
    pub const CONFIRM: usize = H / 2;

    /// A filter for a sensor of the given size.
    pub const fn new(sensor: SensorSize) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Self {
            sensor,
            last_t: None,
            stats: InputStats { accepted: 0, out_of_sensor: 0, time_backwards: 0, time_jumps: 0, largest_jump_us: 0 },
            held: [Event { t_us: 0, x: 0, y: 0, polarity: false }; H],
            start: 0,
            len: 0,
            counted: 0,
            ahead: 0,
            behind: 0,
            finishing: false,
        }
    }

    /// Starts afresh for `sensor`, as [`new`](Self::new) would, in place (no copy of the hold
    /// on a small stack).
    pub fn reset(&mut self, sensor: SensorSize) {
        self.sensor = sensor;
        self.last_t = None;
        self.stats = InputStats::default();
        self.start = 0;
        self.len = 0;
        self.forget_votes();
        self.finishing = false;
    }

    /// Takes one event. Returns it when it passes at once (the usual case: nothing held, on
    /// the sensor, within [`MAX_STEP_US`] after the last accepted event); otherwise it is
    /// dropped or held. Call [`pop`](Self::pop) until `None` after every push: the events it
    /// releases come before any later one.
    #[inline]
    pub fn push(&mut self, e: Event) -> Option<Event> {
        // The usual case inline, the rest out of line: it runs for every event on the device
        // (docs/firmware.md#performance).
        if let (0, Some(last)) = (self.len, self.last_t) {
            if self.sensor.contains(e.x, e.y) && e.t_us >= last && e.t_us - last <= MAX_STEP_US {
                self.finishing = false;
                self.last_t = Some(e.t_us);
                self.stats.accepted += 1;
                return Some(e);
            }
        }
        self.push_held(e)
    }

    /// [`push`](Self::push) for all but the usual case: off the sensor, back in time, far
    /// ahead, or something held.
    #[cold]
    #[inline(never)]
    fn push_held(&mut self, e: Event) -> Option<Event> {
        if !self.sensor.contains(e.x, e.y) {
            self.stats.out_of_sensor += 1;
            return None;
        }
        self.finishing = false;
        if self.len == 0 {
            if let Some(last) = self.last_t {
                if e.t_us < last {
                    self.stats.time_backwards += 1;
                    return None;
                }
                if e.t_us - last <= MAX_STEP_US {
                    self.last_t = Some(e.t_us);
                    self.stats.accepted += 1;
                    return Some(e);
                }
            }
        }
        // A full hold (the caller skipped `pop`): its oldest event is decided now, by the
        // majority of what follows it, to make room.
        let out = if self.len == H { self.take(true) } else { None };
        if self.len < H {
            let at = self.at(self.len);
            self.held[at] = e;
            self.len += 1;
        }
        out
    }

    /// The next event released from the hold, or `None` while what is held waits for more
    /// events to decide (or nothing is held).
    pub fn pop(&mut self) -> Option<Event> {
        self.take(self.finishing)
    }

    /// The input has ended: what is held is decided by the events there are (a held time
    /// with no event after it is kept). Call [`pop`](Self::pop) until `None`. A later push
    /// goes on as before.
    pub fn finish(&mut self) {
        self.finishing = true;
    }

    /// Events held, waiting for a decision or to be popped.
    pub const fn held(&self) -> usize {
        self.len
    }

    /// What has been accepted and dropped so far.
    pub const fn stats(&self) -> InputStats {
        self.stats
    }

    /// The sensor this filter checks against.
    pub const fn sensor(&self) -> SensorSize {
        self.sensor
    }

    /// The ring index of the `k`-th held event (`k < H`).
    fn at(&self, k: usize) -> usize {
        let i = self.start + k;
        if i >= H {
            i - H
        } else {
            i
        }
    }

    fn forget_votes(&mut self) {
        self.counted = 0;
        self.ahead = 0;
        self.behind = 0;
    }

    /// Removes the oldest held event.
    fn remove_first(&mut self) -> Event {
        let e = self.held[self.start];
        self.start = self.at(1);
        self.len -= 1;
        self.forget_votes();
        e
    }

    /// The oldest held event once decided: released (returned), or dropped and the next one
    /// looked at; `None` when nothing is held or the oldest waits (never when `force`).
    fn take(&mut self, force: bool) -> Option<Event> {
        while self.len > 0 {
            let t = self.held[self.start].t_us;
            match self.last_t {
                Some(last) if t < last => {
                    self.remove_first();
                    self.stats.time_backwards += 1;
                    continue;
                }
                Some(last) if t - last <= MAX_STEP_US => return Some(self.release_first()),
                _ => {}
            }
            // Votes of the followers not yet counted (each counted once per held event).
            while self.counted + 1 < self.len {
                self.counted += 1;
                let f = self.held[self.at(self.counted)].t_us;
                if f >= t {
                    self.ahead += 1;
                } else if self.went_on_from_before(t, f) {
                    self.behind += 1;
                }
            }
            let real = if self.ahead >= Self::CONFIRM {
                true
            } else if self.behind >= Self::CONFIRM {
                false
            } else if force || self.len == H {
                self.ahead >= self.behind
            } else {
                return None;
            };
            if real {
                return Some(self.release_first());
            }
            // How far ahead it was: of the last accepted event, or of the first event that
            // went on from before it.
            let before = match self.last_t {
                Some(last) => last,
                None => (1..self.len)
                    .map(|k| self.held[self.at(k)].t_us)
                    .find(|&f| self.went_on_from_before(t, f))
                    .unwrap_or(t),
            };
            self.remove_first();
            self.stats.time_jumps += 1;
            self.stats.largest_jump_us = self.stats.largest_jump_us.max(t - before);
        }
        None
    }

    /// Whether a follower at `f` goes on from before a held time `t`, against it: at or
    /// after the last accepted time, or, when nothing was accepted yet, more than
    /// [`MAX_STEP_US`] before `t` (a stream that merely starts out of order is not a stray
    /// first event but events back in time).
    fn went_on_from_before(&self, t: u64, f: u64) -> bool {
        f < t
            && match self.last_t {
                Some(last) => f >= last,
                None => t - f > MAX_STEP_US,
            }
    }

    fn release_first(&mut self) -> Event {
        let e = self.remove_first();
        self.last_t = Some(e.t_us);
        self.stats.accepted += 1;
        e
    }
}

#[cfg(test)]
mod test;
