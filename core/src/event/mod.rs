//! Events: the type every stage consumes, wrap-safe timestamps and input validation.
//!
//! Timestamps are integer microseconds in a `u64`, so recordings longer than the 32-bit
//! microsecond wrap (71.6 minutes) keep a monotonic time axis. Sources that deliver 32-bit
//! timestamps extend them with [`TimeUnwrapper`].

mod filter;

pub use filter::{InputFilter, InputStats, MAX_HELD_EVENTS, MAX_STEP_US};

/// One event: a pixel whose log intensity changed by more than the contrast threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Event {
    /// Timestamp in microseconds.
    pub t_us: u64,
    /// Column, 0 = leftmost pixel.
    pub x: u16,
    /// Row, 0 = top pixel.
    pub y: u16,
    /// `true` for an increase of brightness (ON), `false` for a decrease (OFF).
    pub polarity: bool,
}

/// Sensor size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorSize {
    /// Width in pixels (number of columns).
    pub width: u16,
    /// Height in pixels (number of rows).
    pub height: u16,
}

impl SensorSize {
    /// The iniVation DAVIS346: 346 x 260.
    pub const DAVIS346: Self = Self::new(346, 260);
    /// The iniVation DVXplorer: 640 x 480.
    pub const DVXPLORER: Self = Self::new(640, 480);

    /// A sensor of `width` x `height` pixels.
    pub const fn new(width: u16, height: u16) -> Self {
        Self { width, height }
    }

    /// Whether pixel (`x`, `y`) lies on the sensor.
    pub const fn contains(&self, x: u16, y: u16) -> bool {
        x < self.width && y < self.height
    }
}

/// Extends 32-bit wrapping microsecond timestamps to 64 bits.
///
/// A timestamp that is smaller than the previous one by more than half the 32-bit range is
/// taken as a wrap; a small step back is passed through unchanged (as a step back in time),
/// so that [`InputFilter`] counts it rather than the unwrapper inventing a 71-minute jump.
#[derive(Debug, Clone, Copy, Default)]
pub struct TimeUnwrapper {
    high: u64,
    last: Option<u32>,
}

impl TimeUnwrapper {
    /// A new unwrapper; the first timestamp is taken as it is.
    pub const fn new() -> Self {
        Self { high: 0, last: None }
    }

    /// The 64-bit time of the 32-bit timestamp `t`.
    pub fn extend(&mut self, t: u32) -> u64 {
        if let Some(last) = self.last {
            if t < last && last - t > u32::MAX / 2 {
                self.high += 1 << 32;
            } else if t > last && t - last > u32::MAX / 2 && self.high > 0 {
                // A late event from before the last wrap: report it in the previous epoch.
                return (self.high - (1 << 32)) | u64::from(t);
            }
        }
        self.last = Some(t);
        self.high | u64::from(t)
    }

    /// The 64-bit time of `t` taken as it is, in the current epoch, even where
    /// [`extend`](Self::extend) would see a wrap: for a source that knows the time before
    /// was a stray (it had itself jumped ahead by more than half the range), so that the
    /// step back is no wrap but the stream going on; the input filter then drops the stray.
    pub fn take_as_is(&mut self, t: u32) -> u64 {
        self.last = Some(t);
        self.high | u64::from(t)
    }
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn unwrapper_extends_across_wraps() {
        let mut u = TimeUnwrapper::new();
        assert_eq!(u.extend(10), 10);
        assert_eq!(u.extend(u32::MAX - 5), u64::from(u32::MAX - 5));
        assert_eq!(u.extend(3), (1u64 << 32) + 3);
        assert_eq!(u.extend(1 << 31), (1u64 << 32) + (1 << 31));
        assert_eq!(u.extend(u32::MAX), (1u64 << 32) + u64::from(u32::MAX));
        assert_eq!(u.extend(7), (2u64 << 32) + 7);
        // a late event from just before the last wrap stays in the previous epoch
        assert_eq!(u.extend(u32::MAX - 1), (1u64 << 32) + u64::from(u32::MAX - 1));
    }

    #[test]
    fn unwrapper_takes_a_time_as_it_is_when_told() {
        let mut u = TimeUnwrapper::new();
        assert_eq!(u.extend(1000), 1000);
        // A stray far ahead, then the stream going on: no wrap.
        assert_eq!(u.extend(3_600_000_000), 3_600_000_000);
        assert_eq!(u.take_as_is(1010), 1010);
        assert_eq!(u.extend(1020), 1020);
    }

    #[test]
    fn unwrapper_passes_small_steps_back() {
        let mut u = TimeUnwrapper::new();
        assert_eq!(u.extend(1000), 1000);
        assert_eq!(u.extend(990), 990);
    }
}
