//! `evcal collect`: record the detections of a device that has its own sensor.

use crate::common::{check_output, output, spinner, stop_on_ctrl_c, LinkArgs};
use anyhow::{bail, Context, Result};
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
    /// Stop after this many seconds (default: until Ctrl-C or the link closes).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Stop after this many windows.
    #[arg(long)]
    pub windows: Option<u64>,
    /// No progress display or summary on standard error.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(a: CollectArgs) -> Result<()> {
    let duration = match a.seconds {
        Some(s) if !(s.is_finite() && s > 0.0) => bail!("--seconds must be a positive number"),
        Some(s) => Some(Duration::from_secs_f64(s)),
        None => None,
    };
    if let Some(o) = &a.out {
        check_output(o, "--out", &[])?;
    }
    let stop = stop_on_ctrl_c();
    let link = a.link.open()?;
    let mut out = output(a.out.as_deref())?;
    let pb = spinner(a.quiet, "collecting");
    let mut write_err: Option<anyhow::Error> = None;
    let result = collect(&link, CollectLimits { duration, windows: a.windows }, &stop, &mut |p| match p {
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
        std::process::exit(130);
    }
    Ok(())
}

fn status(r: &CollectReport) -> String {
    format!(
        "windows {}  centres {}  lost {}  bad frames {}  restarts {}",
        r.windows, r.centres, r.windows_lost, r.frames_bad, r.restarts
    )
}
