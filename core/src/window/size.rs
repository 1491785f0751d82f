//! How many events a window holds on a sensor: one rule for the host and the device, so
//! that a device's detections and `evcal detect`'s on the same recording are the same bytes.
//!
//! The rule is integer arithmetic in a `const fn`: a device's detector is a `static`
//! configured at compile time, and the host must get the same number on every platform.

use crate::event::SensorSize;

/// The sensor the window sizes are scaled from: the E-Calib paper's DAVIS346.
pub const REFERENCE_SENSOR: SensorSize = SensorSize::DAVIS346;

/// Events per window on the [`REFERENCE_SENSOR`]: twice the paper's 4000
/// ([`DEFAULT_EVENTS_PER_WINDOW`](crate::config::DEFAULT_EVENTS_PER_WINDOW)).
///
/// Why longer than the paper's: a window of 4000 events lasts 4–9 ms on a DAVIS346 watching
/// a hand-held board, while a dim pixel answers 15–20 ms late and its OFF events trail the
/// edge for tens of milliseconds. A window shorter than that response holds a different
/// part of each circle's trailing events depending on how fast the circle moves, and the
/// centres then differ from circle to circle by more than any pose explains. Twice the
/// events halve that and double each circle's events. Measured: on the recordings of an
/// independent pixel emulator the dim cone's cx came from +2.24 to +0.26 px, and every
/// reprojection RMS fell by a third or more; on the simulator's physics sweep every RMS fell
/// by 38–47 % (docs/accuracy.md, "Windows twice the paper's on the host"). Much longer
/// windows are not better: a window's circle moves in a straight line in the fit, and on a
/// curving path its centre then sits inside the curve by the acceleration times the
/// window's duration squared over 24.
pub const REFERENCE_EVENTS_PER_WINDOW: usize = 2 * crate::config::DEFAULT_EVENTS_PER_WINDOW;

/// Window sizes of [`ring_events_per_window`] and [`disc_events_per_window`] are multiples
/// of this many events.
pub const EVENTS_PER_WINDOW_STEP: usize = 500;

/// The largest window either rule gives (a 1280x720 sensor's filled discs).
pub const LARGEST_WINDOW: usize = 32_000;

/// The reference sensor's pixels, and the reference window in steps.
const REFERENCE_PIXELS: u64 = REFERENCE_SENSOR.width as u64 * REFERENCE_SENSOR.height as u64;
const REFERENCE_STEPS: u64 = (REFERENCE_EVENTS_PER_WINDOW / EVENTS_PER_WINDOW_STEP) as u64;
const _: () = assert!(REFERENCE_EVENTS_PER_WINDOW % EVENTS_PER_WINDOW_STEP == 0);

/// Events per window for circles fitted as rings on a sensor of `sensor`'s size:
/// [`REFERENCE_EVENTS_PER_WINDOW`] (8000) on a DAVIS346, scaled by the sensor's linear size,
/// `8000 · √(W·H / (346·260))`, rounded to the nearest multiple of
/// [`EVENTS_PER_WINDOW_STEP`] and kept within one step to [`LARGEST_WINDOW`]: 8500 on a
/// 320x320 GenX320, 15 000 on 640x480, 25 500 on 1280x720.
///
/// Why linear: the board's circles span a number of pixels proportional to the sensor's
/// linear size (the board framed alike), and so does the distance they travel in a second;
/// the event rate grows with both, as the area. A window of a fixed number of events is
/// then shorter on a larger sensor, its edges sweep fewer pixels and each circle's events
/// are spread thinner along an outline of more pixels: both come back to the DAVIS346's
/// with a window proportional to the linear size. The square root of the pixel count is
/// that size for any aspect ratio. Measured on simulated 4x11 cones in good light
/// (`tests/examples/window_sizes.rs`): docs/accuracy.md, "Windows sized to the sensor".
///
/// ```
/// use evcal_core::{event::SensorSize, window::ring_events_per_window};
/// assert_eq!(ring_events_per_window(SensorSize::DAVIS346), 8000);
/// assert_eq!(ring_events_per_window(SensorSize::new(320, 320)), 8500);
/// assert_eq!(ring_events_per_window(SensorSize::new(1280, 720)), 25_500);
/// ```
pub const fn ring_events_per_window(sensor: SensorSize) -> usize {
    // steps = round(k·√(A/A0)), k the reference steps: the largest s with
    // (2s − 1)² · A0 ≤ 4k² · A, in integers. No tie can fall between the two roundings:
    // (2s − 1)² · A0 has A0's three factors of two, 4k² · A at least ten.
    let scaled = 4 * REFERENCE_STEPS * REFERENCE_STEPS * pixels(sensor);
    let odd = isqrt(scaled / REFERENCE_PIXELS);
    let odd = if odd % 2 == 0 { odd.saturating_sub(1) } else { odd };
    in_range(odd.div_ceil(2))
}

/// Events per window where circles are fitted as filled discs (`FitConfig::filled_discs`):
/// [`REFERENCE_EVENTS_PER_WINDOW`] (8000) on a DAVIS346, scaled by the sensor's area,
/// `8000 · W·H / (346·260)`, rounded to a multiple of [`EVENTS_PER_WINDOW_STEP`] and kept
/// within one step to [`LARGEST_WINDOW`]: 27 500 on 640x480, 32 000 on 1280x720.
///
/// Why the area: filled discs are the mark of slow pixels (a dark circle's pixels go on
/// firing long after its edge passed), and what a slow pixel asks of a window is time, not
/// pixels of motion. The event rate grows with the sensor's area, so the area keeps the
/// DAVIS346's window duration, where the linear law makes a larger sensor's windows
/// shorter (a 640x480 window 0.54 times a DAVIS346's). Measured on a simulated DVXplorer's
/// dim cone (docs/notes/sweep.md, "Filled discs in windows of the DAVIS346's duration"):
/// over seeds 5–8, fx +0.181, +0.368, +0.077, +0.258 % in windows of the linear law,
/// +0.004, +0.146, +0.005, +0.142 % in windows of the area law.
///
/// ```
/// use evcal_core::{event::SensorSize, window::disc_events_per_window};
/// assert_eq!(disc_events_per_window(SensorSize::DAVIS346), 8000);
/// assert_eq!(disc_events_per_window(SensorSize::DVXPLORER), 27_500);
/// ```
pub const fn disc_events_per_window(sensor: SensorSize) -> usize {
    // round(k · A / A0), ties up.
    in_range((2 * REFERENCE_STEPS * pixels(sensor) + REFERENCE_PIXELS) / (2 * REFERENCE_PIXELS))
}

/// The window for `sensor`: [`disc_events_per_window`] when circles are fitted as filled
/// discs, else [`ring_events_per_window`].
pub const fn events_per_window(sensor: SensorSize, filled_discs: bool) -> usize {
    if filled_discs {
        disc_events_per_window(sensor)
    } else {
        ring_events_per_window(sensor)
    }
}

const fn pixels(sensor: SensorSize) -> u64 {
    sensor.width as u64 * sensor.height as u64
}

/// `steps` steps of events, at least one step and at most [`LARGEST_WINDOW`].
const fn in_range(steps: u64) -> usize {
    let most = (LARGEST_WINDOW / EVENTS_PER_WINDOW_STEP) as u64;
    let steps = if steps < 1 {
        1
    } else if steps > most {
        most
    } else {
        steps
    };
    steps as usize * EVENTS_PER_WINDOW_STEP
}

/// ⌊√n⌋ by Newton's iteration from above (every value here is below 2⁴⁴).
const fn isqrt(n: u64) -> u64 {
    if n < 2 {
        return n;
    }
    let mut x = n;
    let mut y = x.div_ceil(2);
    while y < x {
        x = y;
        y = (x + n / x) / 2;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule as it was first written, in floating point.
    fn by_float(sensor: SensorSize, power: f64) -> usize {
        let ratio = pixels(sensor) as f64 / REFERENCE_PIXELS as f64;
        let events = REFERENCE_EVENTS_PER_WINDOW as f64 * libm::pow(ratio, power);
        let steps = libm::round(events / EVENTS_PER_WINDOW_STEP as f64).max(1.0) as usize;
        (steps * EVENTS_PER_WINDOW_STEP).min(LARGEST_WINDOW)
    }

    #[test]
    fn integers_agree_with_the_floating_point_rule_on_every_sensor_size() {
        for width in (1..=2048u16).step_by(7).chain([320, 346, 640, 1280]) {
            for height in (1..=1536u16).step_by(5).chain([240, 260, 320, 480, 720]) {
                let s = SensorSize::new(width, height);
                assert_eq!(ring_events_per_window(s), by_float(s, 0.5), "{width}x{height}");
                assert_eq!(disc_events_per_window(s), by_float(s, 1.0), "{width}x{height}");
            }
        }
    }

    #[test]
    fn the_sensors_evcal_knows() {
        let cases = [
            ((346, 260), 8000, 8000),
            ((320, 320), 8500, 9000),
            ((640, 480), 15_000, 27_500),
            ((1280, 720), 25_500, 32_000),
        ];
        for ((w, h), ring, disc) in cases {
            let s = SensorSize::new(w, h);
            assert_eq!((ring_events_per_window(s), disc_events_per_window(s)), (ring, disc), "{w}x{h}");
        }
        // Linear: twice the width and height, twice the events (a DAVIS240: 5549 -> 5500).
        assert_eq!(ring_events_per_window(SensorSize::new(692, 520)), 16_000);
        assert_eq!(ring_events_per_window(SensorSize::new(240, 180)), 5500);
        // Quadratic: half the width and height, a quarter of the events.
        assert_eq!(disc_events_per_window(SensorSize::new(173, 130)), 2000);
        assert_eq!(ring_events_per_window(SensorSize::new(1, 1)), EVENTS_PER_WINDOW_STEP);
        assert_eq!(ring_events_per_window(SensorSize::new(u16::MAX, u16::MAX)), LARGEST_WINDOW);
    }

    #[test]
    fn isqrt_is_the_floor_of_the_root() {
        for n in (0..100_000u64).chain([(1 << 44) - 1, 1 << 44, u32::MAX as u64 * 4096]) {
            let r = isqrt(n);
            assert!(r * r <= n && (r + 1) * (r + 1) > n, "{n}: {r}");
        }
    }
}
