//! `evcal collect`: record the detections of a device that has its own sensor.

use crate::common::{check_output, exit_interrupted, output, spinner, stop_on_ctrl_c, LinkArgs};
use crate::ranges;
use anyhow::{Context, Result};
use clap::Args;
use evcal_host::input::link::{
    collect::{collect, CollectLimits, CollectReport},
    Progress,
};
use std::{path::PathBuf, time::Duration};

#[derive(Args)]
pub struct CollectArgs {
    #[command(flatten)]
    pub link: LinkArgs,
    /// Write the JSON lines here instead of standard output (`-`). Written to a temporary
    /// file renamed into place at the end; Ctrl-C and errors keep what arrived.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Stop after this many seconds, 0.001 to a year (default: until Ctrl-C or the link
    /// closes).
    #[arg(long, value_name = "SECONDS", value_parser = ranges::listen, allow_negative_numbers = true)]
    pub seconds: Option<Duration>,
    /// Stop after this many windows (at least 1).
    #[arg(long, value_parser = ranges::windows, allow_negative_numbers = true)]
    pub windows: Option<u64>,
    /// No progress display or summary on standard error.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(a: CollectArgs) -> Result<()> {
    let duration = a.seconds;
    if let Some(o) = &a.out {
        check_output(o, "--out", &[])?;
    }
    let stop = stop_on_ctrl_c();
    let link = a.link.open(stop)?;
    let mut out = output(a.out.as_deref())?;
    let pb = spinner(a.quiet, "collecting");
    let mut write_err: Option<anyhow::Error> = None;
    let result = collect(&link, CollectLimits { duration, windows: a.windows }, stop, &mut |p| match p {
        Progress::Window(w) => {
            if write_err.is_none() {
                write_err = out.line(&w.to_json_line()).err();
                if write_err.is_some() {
                    // Nothing more can be written: stop as Ctrl-C would.
                    stop.store(true, std::sync::atomic::Ordering::Relaxed);
                }
            }
        }
        Progress::Status(r) => pb.set_prefix(status(r)),
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
        eprintln!(
            "evcal: {}; {} bytes received{}{}{}",
            status(&r),
            r.bytes_received,
            if r.windows > 0 {
                format!(" ({:.0} bytes/window)", r.bytes_received as f64 / r.windows as f64)
            } else {
                String::new()
            },
            r.closed.as_ref().map(|c| format!("; link closed: {c}")).unwrap_or_default(),
            if r.interrupted { "; interrupted" } else { "" }
        );
    }
    if r.interrupted {
        exit_interrupted();
    }
    Ok(())
}

fn status(r: &CollectReport) -> String {
    format!(
        "windows {}  centres {}  lost {}  bad frames {}  restarts {}",
        r.windows, r.centres, r.windows_lost, r.frames_bad, r.restarts
    )
}
