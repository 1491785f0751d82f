//! What `evcal calibrate` (and `evcal demo`) write: the checks of the outputs before any
//! work, the files, their list, and an earlier run's results when a run writes none.

use crate::common::{check_output, outln};
use anyhow::{bail, Result};
use evcal_host::{
    export::{atomic, remove_stale, write_all, Export, Stale, FAILED_FILE_NAMES, FILE_NAMES},
    pipeline::{Outcome, Verdict, Views},
};
use std::path::{Path, PathBuf};

/// Checks that the outputs can be written, before any work: `out` a folder (or nothing yet),
/// its files and `json` neither links nor folders nor one of `inputs`, and `json` not one of
/// the folder's other files.
pub fn check_outputs(out: &Path, json: Option<&Path>, inputs: &[(&str, &Path)]) -> Result<()> {
    if out.exists() && !out.is_dir() {
        bail!("--out {}: exists and is not a folder", out.display());
    }
    if out.is_dir() {
        for name in FILE_NAMES.iter().chain(&FAILED_FILE_NAMES) {
            check_output(&out.join(name), "--out", inputs)?;
        }
    }
    if let Some(j) = json {
        check_output(j, "--json", inputs)?;
        for name in FILE_NAMES[1..].iter().chain(&FAILED_FILE_NAMES) {
            if atomic::same_file(j, &out.join(name)) {
                bail!("--json {}: is --out's {name}, which calibrate writes too; give another name", j.display());
            }
        }
    }
    Ok(())
}

/// After a run that wrote no results: removes the earlier run's in `out` (and at `json`),
/// which would otherwise be taken for this run's, and says so. Files evcal cannot tell it
/// wrote are left, also said.
pub fn say_stale_removed(out: &Path, json: Option<&Path>, quiet: bool) {
    say_stale(&remove_stale(out, json), "as this run gives none", quiet);
}

/// Says what was done with an earlier run's results (`why` they went).
fn say_stale(s: &Stale, why: &str, quiet: bool) {
    let list = |v: &[PathBuf]| v.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ");
    if !s.removed.is_empty() {
        // Said even with --quiet: files went away.
        eprintln!("evcal: removed an earlier run's results, {why}: {}", list(&s.removed));
    }
    if !s.left.is_empty() && !quiet {
        eprintln!("evcal: note: left as they are (not known to be written by evcal): {}", list(&s.left));
    }
    for (p, e) in &s.failed {
        eprintln!("evcal: warning: {}: an earlier run's result, {why}, but it cannot be removed: {e}", p.display());
    }
}

/// Writes every output into `dir`, and the JSON result to `json` too. Done before anything
/// is printed, so that a reader closing standard output early (`| head`) cannot leave the
/// files unwritten or stale from an earlier run.
pub fn export(views: &Views, o: &Outcome, verdict: &Verdict, dir: &Path, json: Option<&Path>) -> Result<Written> {
    let mut e = Export::new(&o.calibration, &o.used, &o.used_origins, &views.timeline);
    let centres = used_centres(views, o);
    e.centres = &centres;
    let events = used_events(views, o);
    e.events = &events;
    e.kalibr_calibration = o.without_k3.as_ref();
    e.edge_shift = o.edge_shift;
    let failure = o.failure.as_ref().map(ToString::to_string);
    e.failure = failure.as_deref();
    e.json_copy = json;
    e.verdict = Some(verdict);
    e.advice = &o.advice;
    e.k3_held = o.k3_held.map(|h| (h.free, h.std));
    let written = write_all(dir, &e)?;
    let why = if o.failure.is_some() {
        "as this run gives no calibration"
    } else {
        "a failed run's, as this run gives a calibration"
    };
    say_stale(&written.stale, why, false);
    // A failed run writes no file under a calibration's name, the --json copy neither.
    let json = json.filter(|_| o.failure.is_none()).map(Path::to_path_buf);
    Ok(Written { files: written, json, without_k3: o.without_k3.is_some() })
}

/// Every centre detected in the window of each view the solve was given (`o.used`), found by
/// its window; a view whose window is not among `views`' gets none.
fn used_centres(views: &Views, o: &Outcome) -> Vec<Vec<[f64; 2]>> {
    let by_window: std::collections::HashMap<u64, &Vec<[f64; 2]>> =
        views.origins.iter().map(|g| g.window_seq).zip(&views.centres).collect();
    o.used_origins.iter().map(|g| by_window.get(&g.window_seq).map_or_else(Vec::new, |c| c.to_vec())).collect()
}

/// The events kept of the window of each view the solve was given (`o.used`), found by its
/// window; empty where that window's were not kept.
fn used_events(views: &Views, o: &Outcome) -> Vec<Vec<[u16; 2]>> {
    let by_window: std::collections::HashMap<u64, &Vec<[u16; 2]>> =
        views.event_frames.iter().map(|f| (u64::from(f.seq), &f.pixels)).collect();
    o.used_origins.iter().map(|g| by_window.get(&g.window_seq).map_or_else(Vec::new, |p| p.to_vec())).collect()
}

/// What [`export`] wrote, to list after the report.
pub struct Written {
    files: evcal_host::export::Written,
    json: Option<PathBuf>,
    without_k3: bool,
}

/// Lists what [`export`] wrote, with its notes, and `more` files the command wrote beside
/// them: one line, the folder named once.
pub fn list_written(w: &Written, more: &[PathBuf]) -> Result<()> {
    if w.without_k3 {
        outln!(
            "note: kalibr_camchain.yaml holds a solve with k3 fixed at 0 (radtan has no k3); the other files hold k3"
        )?;
    }
    for warning in &w.files.warnings {
        outln!("warning: {warning}")?;
    }
    let all: Vec<&PathBuf> = w.files.paths.iter().chain(more).collect();
    let dir = all.first().and_then(|p| p.parent()).map(Path::to_path_buf);
    let in_dir = |p: &PathBuf| dir.as_deref().is_some_and(|d| p.parent() == Some(d));
    let (inside, outside): (Vec<&PathBuf>, Vec<&PathBuf>) = all.into_iter().partition(|p| in_dir(p));
    let names: Vec<String> =
        inside.iter().filter_map(|p| p.file_name()).map(|n| n.to_string_lossy().into_owned()).collect();
    let mut line = match &dir {
        Some(d) if !names.is_empty() => format!("wrote in {}: {}", d.display(), names.join(", ")),
        _ => "wrote:".to_string(),
    };
    for p in outside.iter().copied().chain(&w.json) {
        line += &format!("; {}", p.display());
    }
    outln!("{line}")
}
