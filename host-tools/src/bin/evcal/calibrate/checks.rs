//! What `evcal calibrate` checks of what it read before it solves: the sensor the detections
//! say, and a pattern given with its rows and columns the other way round.

use anyhow::{bail, Result};
use evcal_core::event::SensorSize;
use evcal_host::{
    input::detections::WindowRecord,
    pipeline::{views_from_windows, Setup},
    views::grid::Pattern,
};
use std::path::Path;

/// The sensor the detections `windows` were made on: what their lines say (each the same),
/// or `given` (`--sensor`); an error when they disagree or neither says.
pub fn detections_sensor(windows: &[WindowRecord], given: Option<SensorSize>, input: &Path) -> Result<SensorSize> {
    let mut stated: Option<(u32, [u16; 2])> = None;
    for w in windows {
        match (w.sensor, stated) {
            (Some(s), None) => stated = Some((w.seq, s)),
            (Some(s), Some((seq, first))) if s != first => bail!(
                "{}: window {} says a {}x{} sensor, window {seq} a {}x{}: detections of two cameras in one file",
                input.display(),
                w.seq,
                s[0],
                s[1],
                first[0],
                first[1]
            ),
            _ => {}
        }
    }
    let stated = stated.map(|(_, [width, height])| SensorSize { width, height });
    match (given, stated) {
        (Some(g), Some(s)) if g != s => bail!(
            "{}: the detections were made on a {}x{} sensor, and --sensor says {}x{}: leave --sensor out, or detect again with the size you mean",
            input.display(),
            s.width,
            s.height,
            g.width,
            g.height
        ),
        (Some(g), _) => Ok(g),
        (None, Some(s)) => Ok(s),
        (None, None) => bail!(
            "{}: detections do not say the sensor size (written before evcal wrote it on every line); give --sensor WxH (e.g. 346x260) or davis346 / dvxplorer",
            input.display()
        ),
    }
}

/// Windows [`transposed_finds`] looks at: enough to find a grid that is in view a tenth of
/// the time, few enough to cost a second or two on a run that failed anyway.
const TRANSPOSED_WINDOWS: usize = 120;

/// When `setup`'s pattern found no grid: in how many of up to [`TRANSPOSED_WINDOWS`] of
/// `windows` (evenly spread) the pattern with rows and columns swapped is found, and how many
/// were tried, if in any; `None` for a square pattern, or one that cannot be swapped.
pub fn transposed_finds(windows: &[WindowRecord], setup: &Setup) -> Option<(usize, usize)> {
    let p = setup.pattern;
    if p.rows == p.cols {
        return None;
    }
    let swapped = Pattern::new(p.cols, p.rows, p.spacing).ok()?;
    let step = windows.len().div_ceil(TRANSPOSED_WINDOWS).max(1);
    let sample: Vec<WindowRecord> = windows.iter().step_by(step).cloned().collect();
    // Each window alone: the pattern is the question, not how windows follow one another.
    let setup = Setup { pattern: swapped, track: None, ..setup.clone() };
    let views = views_from_windows(&sample, &setup, &|_| {});
    (views.stats.found > 0).then_some((views.stats.found, sample.len()))
}
