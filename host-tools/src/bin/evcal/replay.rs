//! `evcal replay`: stream a recording into a device and collect its detections.

use crate::common::{
    check_output, exit_interrupted, output, progress_bar, resolve_sensor, stop_on_ctrl_c, with_position, CoreArgs,
    LinkArgs, ReadArgs,
};
use crate::ranges;
use anyhow::{bail, Context, Result};
use clap::Args;
use evcal_host::input::link::{
    replay::{replay, ReplayOptions, ReplayReport},
    Progress,
};
use std::{path::PathBuf, time::Duration};

#[derive(Args)]
pub struct ReplayArgs {
    /// The recording, in any format `evcal info` reads (see the README's formats table).
    pub recording: PathBuf,
    #[command(flatten)]
    pub link: LinkArgs,
    #[command(flatten)]
    pub core: CoreArgs,
    #[command(flatten)]
    pub read: ReadArgs,
    /// Write the JSON lines here instead of standard output (`-`). Written to a temporary
    /// file renamed into place at the end; Ctrl-C and errors keep what arrived.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Seconds to wait for the device's Hello before sending the configuration anyway; 0 to
    /// a year.
    #[arg(long, default_value = "3", value_name = "SECONDS", value_parser = ranges::wait,
          allow_negative_numbers = true)]
    pub hello_timeout: Duration,
    /// Milliseconds without an acknowledgement before frames are sent again; 1 to 600000
    /// (ten minutes).
    #[arg(long, default_value_t = 1000, value_name = "MS", value_parser = ranges::retry_ms,
          allow_negative_numbers = true)]
    pub retry_ms: u64,
    /// Send every event. By default only the events the device's windows will hold are sent
    /// (this runs the same input filter and windowing to find them: the device cuts the same
    /// windows), about an eighth of a busy recording.
    #[arg(long)]
    pub all_events: bool,
    /// No progress bar or summary on standard error.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(a: ReplayArgs) -> Result<()> {
    if let Some(o) = &a.out {
        check_output(o, "--out", &[("the recording", &a.recording)])?;
    }
    let rec = a.read.open(&a.recording, a.quiet, a.core.sensor.is_none())?;
    let (sensor, rec) = resolve_sensor(a.core.sensor.as_deref(), rec, a.quiet)?;
    let cfg = a.core.config(sensor)?;
    let opts = ReplayOptions {
        hello_timeout: a.hello_timeout,
        retry_timeout: Duration::from_millis(a.retry_ms),
        all_events: a.all_events,
        // The sensor's default is the host's choice: a device holding fewer (the Cortex-M4F's
        // 8000, on a larger sensor) cuts windows of what it holds. A size the user gave is
        // theirs: an error.
        window_up_to_device: a.core.events_per_window.is_none(),
        ..ReplayOptions::default()
    };
    if !a.quiet {
        let line = a.core.window_line(&cfg);
        if opts.window_up_to_device {
            eprintln!("evcal: {line}, or as many as the device holds");
        } else {
            eprintln!("evcal: {line}");
        }
    }
    let stop = stop_on_ctrl_c();
    let mut link = a.link.open(stop)?;
    let mut out = output(a.out.as_deref())?;
    let pb = progress_bar(rec.file_bytes, a.quiet, "replaying");
    let mut rec = rec;
    let progress = std::cell::Cell::new(0u64);
    let events = with_position(&mut rec, 16_384, &progress);
    let mut write_err: Option<anyhow::Error> = None;
    let result = replay(&mut link, events, cfg, &opts, stop, &mut |p| match p {
        Progress::Window(w) => {
            if write_err.is_none() {
                write_err = out.line(&w.to_json_line()).err();
                if write_err.is_some() {
                    // Nothing more can be written: stop as Ctrl-C would.
                    stop.store(true, std::sync::atomic::Ordering::Relaxed);
                }
            }
        }
        Progress::Status(r) => {
            pb.set_position(progress.get());
            pb.set_prefix(status(r));
        }
    });
    pb.finish_and_clear();
    // Whatever happened, keep what arrived, but for a failed write: the file would end
    // torn, so it is left as it was.
    if let Some(e) = write_err {
        return Err(e.context("writing detections"));
    }
    out.finish().context("writing detections")?;
    let r = result?;
    if !a.quiet {
        summary(&r);
    }
    if let Some(e) = &r.read_error {
        bail!("reading {}: {e} (the events before it were replayed)", a.recording.display());
    }
    if r.interrupted {
        exit_interrupted();
    }
    Ok(())
}

fn status(r: &ReplayReport) -> String {
    format!(
        "windows {}  centres {}  lost {}  bad frames {}  resent {}  {:.0} kB out",
        r.windows,
        r.centres,
        r.windows_lost,
        r.frames_bad,
        r.retransmitted,
        r.bytes_sent as f64 / 1e3
    )
}

/// How many events were read and sent, and why the others were left out.
fn sent_line(r: &ReplayReport) -> String {
    let mut line = format!("{} events read, {} sent", r.events_read, r.events_sent);
    let unused = r.events_skipped.saturating_sub(r.events_out_of_sensor + r.events_time_backwards);
    let why: Vec<String> = [
        (r.events_out_of_sensor, "outside the sensor (dropped)"),
        (r.events_time_backwards, "earlier than the event before (dropped)"),
        (unused, "in no window (--all-events sends them)"),
    ]
    .into_iter()
    .filter(|(n, _)| *n > 0)
    .map(|(n, what)| format!("{n} {what}"))
    .collect();
    if !why.is_empty() {
        line += &format!("; left out: {}", why.join(", "));
    }
    line
}

fn summary(r: &ReplayReport) {
    for n in &r.notes {
        eprintln!("evcal: note: {n}");
    }
    eprintln!("evcal: {}", sent_line(r));
    // Per event and per window only when there were some: 38 bytes of configuration over
    // no event is not a rate.
    let per = |bytes: u64, n: u64, what: &str, digits: usize| {
        if n == 0 {
            format!("{bytes} bytes, no {what}")
        } else {
            format!("{:.digits$} bytes/{what}", bytes as f64 / n as f64)
        }
    };
    eprintln!(
        "evcal: {} events in {} batches ({}, {} frames sent again); {} windows, {} centres received ({}); {} windows lost, {} damaged frames{}",
        r.events_sent,
        r.batches,
        per(r.bytes_sent, r.events_sent, "event", 2),
        r.retransmitted,
        r.windows,
        r.centres,
        per(r.bytes_received, r.windows, "window", 0),
        r.windows_lost,
        r.frames_bad,
        if r.interrupted { "; interrupted" } else { "" }
    );
    let hz = r.device.map_or(0, |h| h.clock_hz);
    if let Some(s) = r.stats.filter(|s| hz > 0 && s.windows > 0) {
        let ms = |ticks: u64| ticks as f64 * 1e3 / f64::from(hz) / f64::from(s.windows);
        eprintln!(
            "evcal: device time per window: input {:.2} ms, clustering {:.2} ms, fitting {:.2} ms, encoding {:.3} ms; {:.0} distance checks",
            ms(s.input_ticks),
            ms(s.cluster_ticks),
            ms(s.fit_ticks),
            ms(s.encode_ticks),
            s.distance_checks as f64 / f64::from(s.windows)
        );
    }
    if let Some(s) = &r.stats {
        eprintln!(
            "evcal: device: {} events received, {} dropped by its input filter, {} lost for lack of buffer; {} windows; {} damaged frames from the host, {} sent again; {} events of an unfinished last window left out",
            s.events_received,
            s.out_of_sensor + s.time_backwards,
            s.events_dropped,
            s.windows,
            s.frames_bad,
            s.frames_discarded,
            s.pending_events
        );
    }
}

#[cfg(test)]
mod test {
    use super::*;

    /// Before: every event left out was said to be one "no window holds", events dropped for
    /// going back in time too.
    #[test]
    fn events_left_out_are_said_with_their_reason() {
        let r = ReplayReport {
            events_read: 100,
            events_sent: 90,
            events_skipped: 10,
            events_out_of_sensor: 1,
            events_time_backwards: 7,
            ..ReplayReport::default()
        };
        assert_eq!(
            sent_line(&r),
            "100 events read, 90 sent; left out: 1 outside the sensor (dropped), 7 earlier than the event before (dropped), 2 in no window (--all-events sends them)"
        );
        let r = ReplayReport { events_read: 5, events_sent: 5, ..ReplayReport::default() };
        assert_eq!(sent_line(&r), "5 events read, 5 sent");
    }
}
