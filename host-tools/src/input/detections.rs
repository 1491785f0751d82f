//! Running the core over a recording on the host, and the detections' JSON-lines schema.
//!
//! One JSON object per window per line:
//! `{"seq", "t_ref_us", "events", "noise", "centers": [{"u", "v", "r", "spread", "n", "converged"}]}`.
//! Other programs read these names; they do not change.
//!
//! Centres are the wire's fixed-point values (1/1024 px, [`evcal_core::wire::fixed`]) whether
//! they came over a link from a device or from the core run here, so `evcal detect` and a
//! device replaying the same recording print the same bytes.

use crate::input::recording::ReadError;
use evcal_core::{
    config::MAX_CLUSTERS,
    detect::{DetectConfig, Detection, Detector},
    event::{Event, InputStats, SensorSize},
    window::{disc_events_per_window as core_disc_events_per_window, ring_events_per_window},
    wire::{DetectionFrame, DetectionHeader, WireCentre},
};
use serde::{Deserialize, Serialize};

/// Most events per window the host's detector holds (the firmware's is
/// [`MAX_EVENTS_PER_WINDOW`](evcal_core::config::MAX_EVENTS_PER_WINDOW)). Results do not
/// depend on it: only the number of clusters shapes them, and that matches the firmware's.
pub const HOST_MAX_EVENTS: usize = 32_000;
// Every sensor's default window fits.
const _: () = assert!(evcal_core::window::LARGEST_WINDOW <= HOST_MAX_EVENTS);

/// Events the host's input filter can hold while the events after a far step in time say
/// whether it was real (the firmware's is [`MAX_HELD_EVENTS`](evcal_core::event::MAX_HELD_EVENTS)):
/// half of them decide, so a stray EVT 2.0 `TIME_HIGH` (whose 64 µs period holds 256 events
/// at 4 M events/s) is dropped with its events. Results of a recording with no stray time do
/// not depend on it.
pub const HOST_HELD_EVENTS: usize = 512;

/// The host's default events per window for a sensor of `sensor`'s size: the core's rule,
/// [`ring_events_per_window`] (8000 on a DAVIS346, scaled by the sensor's linear size), the
/// same a device boots with, so that its detections and the host's are the same bytes.
pub fn default_events_per_window(sensor: SensorSize) -> usize {
    ring_events_per_window(sensor)
}

/// The host's default events per window where circles are fitted as filled discs
/// (`FitConfig::filled_discs`): the core's rule, [`core_disc_events_per_window`] (8000 on a
/// DAVIS346, scaled by the sensor's area).
pub fn disc_events_per_window(sensor: SensorSize) -> usize {
    core_disc_events_per_window(sensor)
}

/// The host's default events per window on `sensor`: [`disc_events_per_window`] when
/// `filled_discs`, else [`default_events_per_window`].
pub fn window_events_for(sensor: SensorSize, filled_discs: bool) -> usize {
    evcal_core::window::events_per_window(sensor, filled_discs)
}

/// The core's defaults for a sensor of `sensor`'s size with the host's window size
/// ([`default_events_per_window`]): what `evcal detect` and `calibrate` run without options,
/// and what a device boots with ([`DetectConfig::for_sensor`]).
pub fn host_config(sensor: SensorSize) -> DetectConfig {
    DetectConfig::for_sensor(sensor)
}

/// [`host_config`] fitting filled discs where no ring fits, in windows of
/// [`disc_events_per_window`]: what `evcal calibrate` detects again when the rings give no
/// calibration ([`DetectConfig::discs_for_sensor`]).
pub fn host_disc_config(sensor: SensorSize) -> DetectConfig {
    DetectConfig::discs_for_sensor(sensor)
}

/// The detector the host runs: the firmware's clusters, a larger window and input hold.
pub type HostDetector = Detector<HOST_MAX_EVENTS, MAX_CLUSTERS, HOST_HELD_EVENTS>;

/// One circle centre as written to and read from detections files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CenterRecord {
    /// Centre column at the window's t_ref, px.
    pub u: f32,
    /// Centre row at the window's t_ref, px.
    pub v: f32,
    /// Radius, px.
    pub r: f32,
    /// Weighted RMS distance of the cluster's events from the circle, px.
    pub spread: f32,
    /// Events in the cluster.
    pub n: u16,
    /// Whether the fit converged.
    pub converged: bool,
}

/// One window's detections, one line of a detections file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WindowRecord {
    /// Window sequence number.
    pub seq: u32,
    /// Reference time of the window (the middle of its events' span, where its centres are given), µs.
    pub t_ref_us: u64,
    /// Events in the window.
    pub events: u16,
    /// Events left as noise by the clustering.
    pub noise: u16,
    /// The circle centres found.
    pub centers: Vec<CenterRecord>,
    /// The sensor's size, `[width, height]`, as the writer knew it (`evcal detect`, `replay`,
    /// `collect` and `demo` write it on every line, so that `calibrate` needs no `--sensor`
    /// and a line cut from its file still says it); absent from older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<[u16; 2]>,
}

impl CenterRecord {
    /// The record of a centre as it crossed (or would cross) the link.
    pub fn from_wire(c: &WireCentre) -> Self {
        Self { u: c.u_px(), v: c.v_px(), r: c.r_px(), spread: c.spread_px(), n: c.n, converged: c.converged }
    }
}

impl WindowRecord {
    /// The record of a window's counts and centres in their wire form.
    pub fn from_wire(h: &DetectionHeader, centres: impl Iterator<Item = WireCentre>) -> Self {
        Self {
            seq: h.seq,
            t_ref_us: h.t_ref_us,
            events: h.events,
            noise: h.noise,
            centers: centres.map(|c| CenterRecord::from_wire(&c)).collect(),
            sensor: None,
        }
    }

    /// The record saying the sensor's size.
    pub fn with_sensor(self, sensor: SensorSize) -> Self {
        Self { sensor: Some([sensor.width, sensor.height]), ..self }
    }

    /// The record of a detection received from a device.
    pub fn from_frame(d: &DetectionFrame<'_>) -> Self {
        Self::from_wire(&d.header, d.centres())
    }

    /// The record of a core detection, quantised exactly as the device's encoder does.
    pub fn from_detection<const C: usize>(d: &Detection<C>) -> Self {
        Self::from_wire(&DetectionHeader::from_detection(d), d.centres.iter().map(WireCentre::from_centre))
    }

    /// The record as one JSON line (no newline).
    pub fn to_json_line(&self) -> String {
        // Serialising plain numbers and strings cannot fail.
        serde_json::to_string(self).unwrap_or_default()
    }
}

/// A detections file that cannot be read.
#[derive(Debug)]
pub enum ReadDetectionsError {
    /// The file could not be read.
    Io(std::io::Error),
    /// A line is not a window record.
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
    /// A window out of order: repeated, earlier than the one before, or at the same time.
    Order {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
    /// A window that lists one centre twice.
    Repeated {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
}

impl std::fmt::Display for ReadDetectionsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadDetectionsError::Io(e) => write!(f, "{e}"),
            ReadDetectionsError::Line { line, message } => write!(
                f,
                "line {line}: not a window record ({message}); expected one JSON object per line with \"seq\", \"t_ref_us\", \"events\", \"noise\", \"centers\", as `evcal detect` writes"
            ),
            ReadDetectionsError::Order { line, message } => write!(
                f,
                "line {line}: {message}; evcal writes windows in order (files joined or edited? sort them by seq, drop repeats)"
            ),
            ReadDetectionsError::Repeated { line, message } => write!(
                f,
                "line {line}: {message}; the detector lists each circle it finds once (an edited or corrupt file?), and the grid cannot be matched to repeated centres"
            ),
        }
    }
}

impl std::error::Error for ReadDetectionsError {}

/// The longest line of a detections file read: a window of the most clusters is a few kB.
pub const MAX_DETECTIONS_LINE: usize = 1 << 20;

/// Reads a detections file (JSON lines, as `evcal detect`, `replay` and `collect` write it).
/// Blank lines are skipped; any other line that is not a window record is an error naming
/// the line, so nothing is dropped silently. Lines are at most [`MAX_DETECTIONS_LINE`]
/// bytes. [`read_jsonl_in_order`] also checks the windows' order, as a calibration needs.
pub fn read_jsonl(input: impl std::io::BufRead) -> Result<Vec<WindowRecord>, ReadDetectionsError> {
    Ok(parse_jsonl(input)?.into_iter().map(|(_, w)| w).collect())
}

/// [`read_jsonl`], and the windows must come in order, each with a larger `seq` and a
/// `t_ref_us` no earlier than the one before, not all at one time: a file in reverse, with
/// repeated windows or with one time for all (which calibrate worse, silently) is refused,
/// not sorted, so that whatever made it can be fixed. A window that lists a centre twice is
/// refused too (the grid finder would blame the pattern).
pub fn read_jsonl_in_order(input: impl std::io::BufRead) -> Result<Vec<WindowRecord>, ReadDetectionsError> {
    let windows = parse_jsonl(input)?;
    for (line, w) in &windows {
        let mut at: Vec<(u32, u32)> = w.centers.iter().map(|c| (c.u.to_bits(), c.v.to_bits())).collect();
        at.sort_unstable();
        if let Some(pair) = at.windows(2).find(|p| p[0] == p[1]) {
            let times = at.iter().filter(|&&c| c == pair[0]).count();
            return Err(ReadDetectionsError::Repeated {
                line: *line,
                message: format!(
                    "window {} lists the centre ({}, {}) {times} times",
                    w.seq,
                    f32::from_bits(pair[0].0),
                    f32::from_bits(pair[0].1)
                ),
            });
        }
    }
    for pair in windows.windows(2) {
        let ((_, prev), (line, r)) = (&pair[0], &pair[1]);
        let order = |message: String| ReadDetectionsError::Order { line: *line, message };
        if r.seq == prev.seq {
            return Err(order(format!("window {} again (a repeated window)", r.seq)));
        }
        if r.seq < prev.seq {
            return Err(order(format!("window {} after window {} (out of order)", r.seq, prev.seq)));
        }
        if r.t_ref_us < prev.t_ref_us {
            return Err(order(format!(
                "window {} at {} µs, before window {} at {} µs (times out of order)",
                r.seq, r.t_ref_us, prev.seq, prev.t_ref_us
            )));
        }
    }
    // Two windows may share a time (events of one timestamp, `--step-ms 0`); all of them
    // cannot: the times were lost.
    if let (Some((_, first)), Some((line, last))) = (windows.first(), windows.last()) {
        if windows.len() > 1 && first.t_ref_us == last.t_ref_us {
            return Err(ReadDetectionsError::Order {
                line: *line,
                message: format!(
                    "all {} windows at the same time ({} µs: times all alike)",
                    windows.len(),
                    first.t_ref_us
                ),
            });
        }
    }
    Ok(windows.into_iter().map(|(_, w)| w).collect())
}

/// The window records of a detections file, each with its line number.
fn parse_jsonl(mut input: impl std::io::BufRead) -> Result<Vec<(usize, WindowRecord)>, ReadDetectionsError> {
    use std::io::{BufRead, Read};
    let mut out = Vec::new();
    let mut line = Vec::new();
    let mut i = 0usize;
    loop {
        line.clear();
        let n = (&mut input)
            .take(MAX_DETECTIONS_LINE as u64 + 1)
            .read_until(b'\n', &mut line)
            .map_err(ReadDetectionsError::Io)?;
        if n == 0 {
            break;
        }
        i += 1;
        if line.len() > MAX_DETECTIONS_LINE {
            return Err(ReadDetectionsError::Line {
                line: i,
                message: format!(
                    "longer than {MAX_DETECTIONS_LINE} bytes; it starts \"{}\"",
                    crate::input::recording::quote(&line, 40)
                ),
            });
        }
        let mut text = std::str::from_utf8(&line).map_err(|e| ReadDetectionsError::Line {
            line: i,
            message: format!(
                "not UTF-8 at byte {}; it starts \"{}\"",
                e.valid_up_to() + 1,
                crate::input::recording::quote(&line, 40)
            ),
        })?;
        if i == 1 {
            text = text.strip_prefix('\u{feff}').unwrap_or(text);
        }
        if text.trim().is_empty() {
            continue;
        }
        let r: WindowRecord = serde_json::from_str(text).map_err(|e| ReadDetectionsError::Line {
            line: i,
            message: format!("{e}; it starts \"{}\"", crate::input::recording::quote(text.trim().as_bytes(), 40)),
        })?;
        out.push((i, r));
    }
    Ok(out)
}

/// Totals of one run over a recording.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RunSummary {
    /// Events read from the recording.
    pub events_read: u64,
    /// Windows completed.
    pub windows: u64,
    /// Centres found, over all windows.
    pub centres: u64,
    /// Events of the last, incomplete window (not processed).
    pub events_in_last_partial_window: u64,
    /// Clusters dropped for lack of capacity, over all windows.
    pub dropped_clusters: u64,
    /// Ticks skipped because a window was still filling.
    pub ticks_skipped: u64,
    /// Out-of-sensor events dropped.
    pub out_of_sensor: u64,
    /// Events dropped because time went backwards.
    pub time_backwards: u64,
    /// Events dropped as stray times: far ahead of the events around them (see
    /// [`InputFilter`](evcal_core::event::InputFilter)).
    pub time_jumps: u64,
    /// The largest step ahead, µs, of a time dropped as stray.
    pub largest_jump_us: u64,
}

/// Runs the core over `events`, calling `on_window` with each completed window. Stops at the
/// first read error and returns it (the windows of the events before it have been delivered).
pub fn run(
    events: impl Iterator<Item = Result<Event, ReadError>>,
    cfg: DetectConfig,
    mut on_window: impl FnMut(&Detection<MAX_CLUSTERS>),
) -> Result<RunSummary, ReadError> {
    let mut det: Box<HostDetector> = Box::new(HostDetector::new(cfg));
    let mut s = RunSummary::default();
    let mut window = |s: &mut RunSummary, d: &Detection<MAX_CLUSTERS>| {
        s.windows += 1;
        s.centres += d.centres.len() as u64;
        s.dropped_clusters += u64::from(d.stats.dropped_clusters);
        s.ticks_skipped += u64::from(d.stats.ticks_skipped);
        on_window(d);
    };
    let mut failed = None;
    for e in events {
        let e = match e {
            Ok(e) => e,
            Err(err) => {
                failed = Some(err);
                break;
            }
        };
        s.events_read += 1;
        if let Some(d) = det.push(e) {
            window(&mut s, d);
        }
    }
    // The events the input filter still holds (after a pause) before the end or the error.
    while let Some(d) = det.end() {
        window(&mut s, d);
    }
    if let Some(err) = failed {
        return Err(err);
    }
    let input: InputStats = det.input_stats();
    s.out_of_sensor = input.out_of_sensor;
    s.time_backwards = input.time_backwards;
    s.time_jumps = input.time_jumps;
    s.largest_jump_us = input.largest_jump_us;
    s.events_in_last_partial_window = det.pending() as u64;
    Ok(s)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn the_host_runs_the_devices_defaults() {
        for sensor in [SensorSize::DAVIS346, SensorSize::DVXPLORER, SensorSize::new(320, 320)] {
            assert_eq!(host_config(sensor), DetectConfig::for_sensor(sensor));
            assert_eq!(host_disc_config(sensor), DetectConfig::discs_for_sensor(sensor));
            for discs in [false, true] {
                assert_eq!(window_events_for(sensor, discs), evcal_core::window::events_per_window(sensor, discs));
            }
        }
        // The paper's detector but for the window.
        let paper = DetectConfig::new(SensorSize::DAVIS346);
        let host = host_config(SensorSize::DAVIS346);
        assert_eq!((paper.window.events, host.window.events), (4000, 8000));
        assert_eq!(DetectConfig { window: paper.window, ..host }, paper);
    }

    #[test]
    fn json_lines_round_trip_and_bad_lines_are_named() {
        let w = WindowRecord {
            seq: 3,
            t_ref_us: 12_345,
            events: 4000,
            noise: 120,
            centers: vec![CenterRecord { u: 10.5, v: 20.25, r: 6.0, spread: 0.3, n: 55, converged: true }],
            sensor: Some([346, 260]),
        };
        let text = format!("{}\n\n{}\n", w.to_json_line(), w.to_json_line());
        assert_eq!(read_jsonl(text.as_bytes()).unwrap(), vec![w.clone(), w.clone()]);
        let bad = format!("{}\n{{\"seq\": 1}}\n", w.to_json_line());
        let e = read_jsonl(bad.as_bytes()).unwrap_err();
        assert!(matches!(e, ReadDetectionsError::Line { line: 2, .. }), "{e}");
        assert!(e.to_string().starts_with("line 2: not a window record"), "{e}");
        assert_eq!(read_jsonl(&b""[..]).unwrap(), vec![]);
    }

    #[test]
    fn a_centre_listed_twice_is_refused() {
        let c = CenterRecord { u: 10.5, v: 20.25, r: 6.0, spread: 0.3, n: 55, converged: true };
        let other = CenterRecord { u: 30.0, ..c };
        let w = |seq, centers| WindowRecord {
            seq,
            t_ref_us: 100 * u64::from(seq),
            events: 4000,
            noise: 0,
            centers,
            sensor: None,
        };
        let text = format!("{}\n{}\n", w(1, vec![c, other]).to_json_line(), w(2, vec![c, other, c]).to_json_line());
        let e = read_jsonl_in_order(text.as_bytes()).unwrap_err();
        assert!(matches!(e, ReadDetectionsError::Repeated { line: 2, .. }), "{e}");
        assert!(e.to_string().contains("window 2 lists the centre (10.5, 20.25) 2 times"), "{e}");
        // the same centre in two windows is no repeat
        let text = format!("{}\n{}\n", w(1, vec![c]).to_json_line(), w(2, vec![c]).to_json_line());
        assert_eq!(read_jsonl_in_order(text.as_bytes()).unwrap().len(), 2);
    }
}
