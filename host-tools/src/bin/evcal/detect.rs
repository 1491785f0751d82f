//! `evcal detect`: the detection core over a recording, one JSON line per window.

use crate::common::{
    check_output, no_window_error, output, outside_warning, progress_bar, resolve_sensor, time_order_warnings,
    with_position, CoreArgs, ReadArgs,
};
use anyhow::{Context, Result};
use clap::Args;
use evcal_host::input::detections::{self, WindowRecord};
use std::{cell::Cell, path::PathBuf};

#[derive(Args)]
pub struct DetectArgs {
    /// The recording: text (`t x y p`, t in seconds), AEDAT4, ROS1 bag (dvs_msgs/EventArray)
    /// or HDF5 (E-Calib's `events_data`, `events/{x,y,t,p}`, e2calib's root `x, y, p, t`);
    /// `-` for standard input.
    pub recording: PathBuf,
    #[command(flatten)]
    pub read: ReadArgs,
    #[command(flatten)]
    pub core: CoreArgs,
    /// Write the JSON lines here instead of standard output (`-`). The file is replaced
    /// only by a complete run: an error or Ctrl-C leaves it as it was.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// No progress bar or summary on standard error.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(a: DetectArgs) -> Result<()> {
    if let Some(o) = &a.out {
        check_output(o, "--out", &[("the recording", &a.recording)])?;
    }
    let rec = a.read.open(&a.recording, a.quiet, a.core.sensor.is_none())?;
    let notes_at_open = rec.notes();
    let (sensor, rec) = resolve_sensor(a.core.sensor.as_deref(), rec, a.quiet)?;
    let cfg = a.core.config(sensor)?;
    if !a.quiet {
        eprintln!("evcal: {}", a.core.window_line(&cfg));
    }
    let mut out = output(a.out.as_deref())?;
    let pb = progress_bar(rec.file_bytes, a.quiet, "detecting");
    let mut write_err: Option<anyhow::Error> = None;
    // Set with `write_err`: ends the events early, as nothing more can be written.
    let failed = Cell::new(false);
    let mut rec = rec;
    // The progress position is read off the reader between events.
    let progress = Cell::new(0u64);
    let events = with_position(&mut rec, 65_536, &progress).take_while(|_| !failed.get());
    let summary = detections::run(events, cfg, |d| {
        pb.set_position(progress.get());
        pb.set_prefix(format!("windows {}", d.info.seq + 1));
        if write_err.is_none() {
            if let Err(e) = out.line(&WindowRecord::from_detection(d).with_sensor(sensor).to_json_line()) {
                write_err = Some(e);
                failed.set(true);
            }
        }
    });
    pb.finish_and_clear();
    if let Some(e) = write_err {
        return Err(e.context("writing detections"));
    }
    // A read error leaves the file as it was: detections of part of a recording are not
    // to be taken for all of it (standard output still gets them as they come).
    match &summary {
        Ok(_) => out.finish().context("writing detections")?,
        Err(_) => {
            drop(out);
            if let Some(o) = a.out.as_deref().filter(|o| o.as_os_str() != "-") {
                eprintln!("evcal: note: {} not written (left as it was)", o.display());
            }
        }
    }
    if !a.quiet {
        // What the reader noticed while reading (the notes of opening were printed then).
        for n in rec.notes().iter().filter(|n| !notes_at_open.contains(n)) {
            eprintln!("evcal: note: {n}");
        }
    }
    let s = summary?;
    if !a.quiet {
        eprintln!(
            "evcal: {} events, {} windows, {} centres; dropped: {} outside the sensor, {} back in time, {} stray times far ahead, {} clusters over capacity; {} events of an unfinished last window left out",
            s.events_read, s.windows, s.centres, s.out_of_sensor, s.time_backwards, s.time_jumps, s.dropped_clusters, s.events_in_last_partial_window
        );
    }
    if let Some(w) = outside_warning(s.out_of_sensor, s.events_read, sensor) {
        eprintln!("evcal: warning: {}: {w}", rec.name().display());
    }
    for w in time_order_warnings(&s) {
        eprintln!("evcal: warning: {}: {w}", rec.name().display());
    }
    if s.windows == 0 {
        // The (empty) output is written; the run still failed to detect anything.
        return Err(no_window_error(rec.name(), &s, &cfg));
    }
    Ok(())
}
