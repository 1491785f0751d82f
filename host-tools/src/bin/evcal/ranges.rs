//! The numeric options' ranges and their parsers. clap checks every value as it reads the
//! command line, so that a mistake is said before any work, with the range and why, and no
//! value reaches a conversion that cannot take it (`Duration::from_secs_f64(1e300)` panics).

use anyhow::{bail, Result};
use std::{ops::RangeInclusive, time::Duration};

/// A range of an option's values, the unit they are in and why the range ends where it does.
pub struct Range {
    /// The values taken.
    pub values: RangeInclusive<f64>,
    /// What a value is, e.g. "a number of seconds".
    pub what: &'static str,
    /// Why the range ends there (a clause, after a comma), or empty.
    pub why: &'static str,
}

impl Range {
    /// `s` as a number in the range, or what was expected.
    pub fn parse(&self, s: &str) -> Result<f64, String> {
        s.trim().parse::<f64>().map_err(|_| self.expected("not a number")).and_then(|v| self.check(v))
    }

    /// `v` if it is in the range, or what was expected.
    pub fn check(&self, v: f64) -> Result<f64, String> {
        if v.is_nan() {
            Err(self.expected("not a number"))
        } else if v.is_infinite() {
            Err(self.expected("not a finite number"))
        } else if !self.values.contains(&v) {
            Err(self.expected("out of range"))
        } else {
            Ok(v)
        }
    }

    fn expected(&self, fault: &str) -> String {
        let (lo, hi) = (self.values.start(), self.values.end());
        format!("{fault}: expected {} from {lo} to {hi}{}", self.what, self.why)
    }
}

/// A range of a count's values (whole numbers), what they count and why the range ends
/// where it does.
pub struct Count {
    /// The values taken.
    pub values: RangeInclusive<u64>,
    /// What is counted, e.g. "views".
    pub what: &'static str,
    /// Why the range ends there (a clause, after a comma), or empty.
    pub why: &'static str,
}

impl Count {
    /// `s` as a whole number in the range, or what was expected.
    pub fn parse(&self, s: &str) -> Result<u64, String> {
        let (lo, hi) = (*self.values.start(), *self.values.end());
        let range = if hi == u64::MAX { format!("at least {lo}") } else { format!("from {lo} to {hi}") };
        let expected = format!("expected a whole number of {} {range}{}", self.what, self.why);
        match s.trim().parse::<u64>() {
            Ok(v) if self.values.contains(&v) => Ok(v),
            Ok(_) => Err(format!("out of range: {expected}")),
            Err(e) if *e.kind() == std::num::IntErrorKind::PosOverflow => Err(format!("too large: {expected}")),
            Err(_) => Err(format!("not a whole number: {expected}")),
        }
    }
}

/// `v` for a message: as typed when short, else in exponent form (1e-300 is not three
/// hundred digits).
pub fn number(v: f64) -> String {
    let plain = v.to_string();
    if plain.len() <= 12 {
        plain
    } else {
        format!("{v:e}")
    }
}

/// The longest wait any option takes, seconds: a year. Longer is a slip of the keyboard, and
/// a `Duration` holds no more than 2^64 s anyway.
pub const MAX_WAIT_S: f64 = 365.0 * 86_400.0;

/// Waits that may be 0 (`--connect-timeout`: one attempt; `--hello-timeout`: do not wait).
pub const WAIT: Range =
    Range { values: 0.0..=MAX_WAIT_S, what: "a number of seconds", why: " (a year; longer is a slip)" };

/// Seconds to wait; see [`WAIT`].
pub fn wait(s: &str) -> Result<Duration, String> {
    to_duration(WAIT.parse(s)?)
}

/// `collect --seconds`: how long to listen.
pub const LISTEN: Range = Range {
    values: 0.001..=MAX_WAIT_S,
    what: "a number of seconds",
    why: " (a year; leave the option out to listen until Ctrl-C)",
};

/// Seconds to listen; see [`LISTEN`].
pub fn listen(s: &str) -> Result<Duration, String> {
    to_duration(LISTEN.parse(s)?)
}

/// `device --idle-timeout`: how long a silent host keeps the device.
pub const IDLE: Range = Range { values: 0.1..=MAX_WAIT_S, what: "a number of seconds", why: " (a year)" };

/// Seconds a host may stay silent; see [`IDLE`].
pub fn idle(s: &str) -> Result<Duration, String> {
    to_duration(IDLE.parse(s)?)
}

fn to_duration(s: f64) -> Result<Duration, String> {
    // -0 is in a range from 0; as a Duration it is 0.
    Duration::try_from_secs_f64(s.abs()).map_err(|e| format!("{s} s: {e}"))
}

/// `--step-ms`: event time between window ticks.
pub const STEP_MS: Range = Range {
    values: 0.0..=60_000.0,
    what: "milliseconds",
    why: " (0: windows back to back; the paper's 33; a step over a minute leaves a recording a handful of windows)",
};

/// Milliseconds between window ticks; see [`STEP_MS`].
pub fn step_ms(s: &str) -> Result<f64, String> {
    STEP_MS.parse(s)
}

/// `--eps`: DBSCAN's radius, normalised by the sensor size.
pub const EPS: Range = Range {
    values: 0.0001..=0.5,
    what: "a fraction of the sensor's size",
    why: " (the paper's 0.015; under 0.0001, a tenth of a pixel on a 1280-pixel sensor, no two events are neighbours; at 0.5 a window is one cluster)",
};

/// DBSCAN's radius; see [`EPS`].
pub fn eps(s: &str) -> Result<f32, String> {
    EPS.parse(s).map(|v| v as f32)
}

/// `--eps-t`: ST-DBSCAN's time radius, a fraction of the window's duration.
pub const EPS_T: Range = Range {
    values: 0.0001..=1.0,
    what: "a fraction of the window's duration",
    why: " (at 1 every event of a window is near in time)",
};

/// ST-DBSCAN's time radius; see [`EPS_T`].
pub fn eps_t(s: &str) -> Result<f32, String> {
    EPS_T.parse(s).map(|v| v as f32)
}

/// `--min-change-px`: how far a view must move from a kept one.
pub const MIN_CHANGE_PX: Range = Range {
    values: 0.0..=2000.0,
    what: "pixels",
    why: " (past any sensor's diagonal, 1469 px on 1280x720, every view but the first would be left out)",
};

/// Pixels a view must move; see [`MIN_CHANGE_PX`].
pub fn min_change_px(s: &str) -> Result<f64, String> {
    MIN_CHANGE_PX.parse(s)
}

/// Seconds simulated (`simulate`, `demo`). Every event of a `simulate` is held in memory.
pub const SIM_SECONDS: Range = Range { values: 0.001..=3600.0, what: "a number of seconds", why: " (an hour)" };

/// Seconds to simulate; see [`SIM_SECONDS`].
pub fn sim_seconds(s: &str) -> Result<f64, String> {
    SIM_SECONDS.parse(s)
}

/// `--threshold`: the contrast threshold, log intensity.
pub const THRESHOLD: Range = Range {
    values: 0.01..=5.0,
    what: "log-intensity units",
    why: " (real pixels: 0.1 to 0.5; under 0.01 every flicker fires, over 5, a change of 148 times, nothing does)",
};

/// The contrast threshold; see [`THRESHOLD`].
pub fn threshold(s: &str) -> Result<f64, String> {
    THRESHOLD.parse(s)
}

/// `--mismatch`: the thresholds' spread from pixel to pixel, log intensity.
pub const MISMATCH: Range =
    Range { values: 0.0..=1.0, what: "log-intensity units", why: " (real pixels: 0.02 to 0.05)" };

/// The thresholds' spread; see [`MISMATCH`].
pub fn mismatch(s: &str) -> Result<f64, String> {
    MISMATCH.parse(s)
}

/// `--leak-hz`: leak events per pixel and second.
pub const LEAK_HZ: Range = Range {
    values: 0.0..=100.0,
    what: "Hz",
    why: " (real pixels: about 0.1; at 100 the leak outnumbers a board's events many times)",
};

/// The leak rate; see [`LEAK_HZ`].
pub fn leak_hz(s: &str) -> Result<f64, String> {
    LEAK_HZ.parse(s)
}

/// `--shot-noise-hz`: shot-noise events per pixel and second, in darkness.
pub const SHOT_NOISE_HZ: Range = Range {
    values: 0.0..=1000.0,
    what: "Hz",
    why: " (real pixels in dim light: about 1; at 1000 noise drowns any board)",
};

/// The shot-noise rate; see [`SHOT_NOISE_HZ`].
pub fn shot_noise_hz(s: &str) -> Result<f64, String> {
    SHOT_NOISE_HZ.parse(s)
}

/// `--illumination`: the scene's light, 1 = office light.
pub const ILLUMINATION: Range = Range {
    values: 0.0001..=10_000.0,
    what: "times office light",
    why: " (0.0001: a moonless night; 10000: beyond direct sunlight)",
};

/// The scene's light; see [`ILLUMINATION`].
pub fn illumination(s: &str) -> Result<f64, String> {
    ILLUMINATION.parse(s)
}

/// `--photoreceptor-hz`: the photoreceptor's cutoff in office light on white; "inf" is an
/// unlimited bandwidth.
pub const PHOTORECEPTOR_HZ: Range = Range {
    values: 1.0..=1e6,
    what: "Hz, or inf",
    why: " (real pixels: hundreds of Hz to a few kHz; inf follows the light at once)",
};

/// The photoreceptor's cutoff, `inf` included; see [`PHOTORECEPTOR_HZ`].
pub fn photoreceptor_hz(s: &str) -> Result<f64, String> {
    if matches!(s.trim().to_ascii_lowercase().as_str(), "inf" | "+inf" | "infinity" | "+infinity") {
        return Ok(f64::INFINITY);
    }
    PHOTORECEPTOR_HZ.parse(s)
}

/// `replay --retry-ms`: the most milliseconds a frame waits for its acknowledgement.
pub const RETRY_MS: Count = Count {
    values: 1..=600_000,
    what: "milliseconds",
    why: " (ten minutes: a device that has not acknowledged in that time is not coming back)",
};

/// Milliseconds before frames are sent again; see [`RETRY_MS`].
pub fn retry_ms(s: &str) -> Result<u64, String> {
    RETRY_MS.parse(s)
}

/// `--baud`: serial line rates.
pub const BAUD: Count = Count {
    values: 50..=20_000_000,
    what: "baud",
    why: " (the slowest standard rate to past any USB serial chip's, FT232H: 12000000)",
};

/// The serial line rate; see [`BAUD`].
pub fn baud(s: &str) -> Result<u32, String> {
    BAUD.parse(s).map(|v| v as u32)
}

/// `--min-pts`: DBSCAN's points in a neighbourhood.
pub const MIN_PTS: Count = Count {
    values: 1..=evcal_host::input::detections::HOST_MAX_EVENTS as u64,
    what: "events",
    why: " (the most a window holds)",
};

/// DBSCAN's minimum points; see [`MIN_PTS`].
pub fn min_pts(s: &str) -> Result<u16, String> {
    MIN_PTS.parse(s).map(|v| v as u16)
}

/// `calibrate --max-views`.
pub const MAX_VIEWS: Count = Count {
    values: evcal_host::calib::MIN_VIEWS as u64..=u64::MAX,
    what: "views",
    why: " (the fewest a calibration is solved from)",
};

/// The most views solved from; see [`MAX_VIEWS`].
pub fn max_views(s: &str) -> Result<usize, String> {
    MAX_VIEWS.parse(s).map(|v| usize::try_from(v).unwrap_or(usize::MAX))
}

/// `collect --windows`.
pub const WINDOWS: Count = Count { values: 1..=u64::MAX, what: "windows", why: "" };

/// Windows to collect; see [`WINDOWS`].
pub fn windows(s: &str) -> Result<u64, String> {
    WINDOWS.parse(s)
}

// The target's sizes are checked together, after parsing: the radius's range is the spacing's.

/// The printed boards spacings lie between (metres): a spacing outside is a wrong unit or a
/// typo, and the views it gives fail far from where it was given.
const SPACING_RANGE: std::ops::RangeInclusive<f64> = 0.001..=1.0;

/// Checks `--spacing` for a plausible length in metres.
pub fn check_spacing(spacing: f64) -> Result<()> {
    if !SPACING_RANGE.contains(&spacing) {
        let hint = if (1.0..=1000.0).contains(&spacing) {
            format!(": metres, not millimetres? ({spacing} mm is --spacing {})", spacing * 1e-3)
        } else {
            String::new()
        };
        bail!(
            "--spacing {}: a printed board's circle spacing is {} to {} m{hint}",
            number(spacing),
            SPACING_RANGE.start(),
            SPACING_RANGE.end()
        );
    }
    Ok(())
}

/// The printed circles' radii lie above this share of the spacing: a smaller one is a wrong
/// unit (millimetres for metres: a thousandth) or a typo, and a board of such dots would
/// image them a pixel or two across, too small to fit.
const RADIUS_MIN_SHARE: f64 = 0.05;

/// Checks `--radius` against the spacing: a circle a few pixels across at the least, and
/// below half the diagonal spacing, where neighbouring circles would overlap.
pub fn check_radius(radius: f64, spacing: f64) -> Result<()> {
    let (lo, hi) = (RADIUS_MIN_SHARE * spacing, 0.5 * spacing * std::f64::consts::SQRT_2);
    if !(radius.is_finite() && radius >= lo && radius < hi) {
        let (radius, spacing) = (number(radius), number(spacing));
        bail!(
            "--radius {radius}: with --spacing {spacing} a printed circle's radius is from {lo:.4} m (a twentieth of the spacing; smaller dots image too few pixels across to fit) to below {hi:.4} m (half the diagonal spacing, where neighbours would overlap)"
        );
    }
    Ok(())
}
