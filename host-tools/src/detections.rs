//! Running the core over a recording on the host, and the detections' JSON-lines schema.
//!
//! One JSON object per window per line:
//! `{"seq", "t_ref_us", "events", "noise", "centers": [{"u", "v", "r", "spread", "n", "converged"}]}`.
//! Other programs read these names; they do not change.
//!
//! Centres are the wire's fixed-point values (1/1024 px, [`evcal_core::wire::fixed`]) whether
//! they came over a link from a device or from the core run here, so `evcal detect` and a
//! device replaying the same recording print the same bytes.

use crate::recording::ReadError;
use evcal_core::{
    config::MAX_CLUSTERS,
    detect::{DetectConfig, Detection, Detector},
    event::{Event, InputStats},
    wire::{DetectionFrame, DetectionHeader, WireCentre},
};
use serde::{Deserialize, Serialize};

/// Most events per window the host's detector holds (the firmware's is
/// [`MAX_EVENTS_PER_WINDOW`](evcal_core::config::MAX_EVENTS_PER_WINDOW)). Results do not
/// depend on it: only the number of clusters shapes them, and that matches the firmware's.
pub const HOST_MAX_EVENTS: usize = 32_000;

/// The detector the host runs: the firmware's clusters, a larger window.
pub type HostDetector = Detector<HOST_MAX_EVENTS, MAX_CLUSTERS>;

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
        }
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
}

impl std::fmt::Display for ReadDetectionsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadDetectionsError::Io(e) => write!(f, "{e}"),
            ReadDetectionsError::Line { line, message } => write!(
                f,
                "line {line}: not a window record ({message}); expected one JSON object per line with \"seq\", \"t_ref_us\", \"events\", \"noise\", \"centers\", as `evcal detect` writes"
            ),
        }
    }
}

impl std::error::Error for ReadDetectionsError {}

/// Reads a detections file (JSON lines, as `evcal detect`, `replay` and `collect` write it).
/// Blank lines are skipped; any other line that is not a window record is an error naming
/// the line, so nothing is dropped silently.
pub fn read_jsonl(input: impl std::io::BufRead) -> Result<Vec<WindowRecord>, ReadDetectionsError> {
    let mut out = Vec::new();
    for (i, line) in input.lines().enumerate() {
        let line = line.map_err(ReadDetectionsError::Io)?;
        if line.trim().is_empty() {
            continue;
        }
        let r: WindowRecord = serde_json::from_str(&line)
            .map_err(|e| ReadDetectionsError::Line { line: i + 1, message: e.to_string() })?;
        out.push(r);
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
}

/// Runs the core over `events`, calling `on_window` with each completed window. Stops at the
/// first read error and returns it (the windows before it have been delivered).
pub fn run(
    events: impl Iterator<Item = Result<Event, ReadError>>,
    cfg: DetectConfig,
    mut on_window: impl FnMut(&Detection<MAX_CLUSTERS>),
) -> Result<RunSummary, ReadError> {
    let mut det: Box<HostDetector> = Box::new(HostDetector::new(cfg));
    let mut s = RunSummary::default();
    for e in events {
        let e = e?;
        s.events_read += 1;
        if let Some(d) = det.push(e) {
            s.windows += 1;
            s.centres += d.centres.len() as u64;
            s.dropped_clusters += u64::from(d.stats.dropped_clusters);
            s.ticks_skipped += u64::from(d.stats.ticks_skipped);
            on_window(d);
        }
    }
    let input: InputStats = det.input_stats();
    s.out_of_sensor = input.out_of_sensor;
    s.time_backwards = input.time_backwards;
    s.events_in_last_partial_window = det.pending() as u64;
    Ok(s)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn json_lines_round_trip_and_bad_lines_are_named() {
        let w = WindowRecord {
            seq: 3,
            t_ref_us: 12_345,
            events: 4000,
            noise: 120,
            centers: vec![CenterRecord { u: 10.5, v: 20.25, r: 6.0, spread: 0.3, n: 55, converged: true }],
        };
        let text = format!("{}\n\n{}\n", w.to_json_line(), w.to_json_line());
        assert_eq!(read_jsonl(text.as_bytes()).unwrap(), vec![w.clone(), w.clone()]);
        let bad = format!("{}\n{{\"seq\": 1}}\n", w.to_json_line());
        let e = read_jsonl(bad.as_bytes()).unwrap_err();
        assert!(matches!(e, ReadDetectionsError::Line { line: 2, .. }), "{e}");
        assert!(e.to_string().starts_with("line 2: not a window record"), "{e}");
        assert_eq!(read_jsonl(&b""[..]).unwrap(), vec![]);
    }
}
