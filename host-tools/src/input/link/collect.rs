//! Recording the detections of a device that has its own sensor: the host only listens.

use super::Result;
use super::{Incoming, Link, Progress, Seen, WindowSeq};
use evcal_core::wire::{Hello, Stats};
use std::{
    sync::atomic::{AtomicBool, Ordering},
    time::{Duration, Instant},
};

/// When to stop listening (besides Ctrl-C and the link closing).
#[derive(Debug, Clone, Copy, Default)]
pub struct CollectLimits {
    /// After this long.
    pub duration: Option<Duration>,
    /// After this many windows.
    pub windows: Option<u64>,
}

/// What was heard.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CollectReport {
    /// The device's latest Hello.
    pub device: Option<Hello>,
    /// Windows whose detections arrived.
    pub windows: u64,
    /// Centres in them.
    pub centres: u64,
    /// Windows whose detections never arrived (gaps in the window numbers).
    pub windows_lost: u64,
    /// Frames that arrived damaged.
    pub frames_bad: u64,
    /// Times the device started a new stream (window numbers went back, or a boot Hello).
    pub restarts: u64,
    /// Bytes received.
    pub bytes_received: u64,
    /// The device's latest counters.
    pub stats: Option<Stats>,
    /// Stopped by the caller (Ctrl-C).
    pub interrupted: bool,
    /// The link closed (and why, if known).
    pub closed: Option<String>,
}

/// Listens on `link` until `stop` is set, a limit is reached or the link closes.
pub fn collect(
    link: &Link,
    limits: CollectLimits,
    stop: &AtomicBool,
    on: &mut dyn FnMut(Progress<'_, CollectReport>),
) -> Result<CollectReport> {
    let started = Instant::now();
    let mut report = CollectReport::default();
    let mut seq = WindowSeq::default();
    let mut last_status = Instant::now();
    loop {
        if stop.load(Ordering::Relaxed) {
            report.interrupted = true;
            break;
        }
        if limits.duration.is_some_and(|d| started.elapsed() >= d)
            || limits.windows.is_some_and(|w| report.windows >= w)
        {
            break;
        }
        match link.recv(Duration::from_millis(50)) {
            Some(Incoming::Window(w)) => {
                match seq.see(w.seq) {
                    Seen::InOrder => {}
                    Seen::AfterLoss(n) => report.windows_lost += u64::from(n),
                    Seen::Restart => report.restarts += 1,
                }
                report.windows += 1;
                report.centres += w.centers.len() as u64;
                on(Progress::Window(&w));
            }
            Some(Incoming::Hello(h)) => {
                if report.device.is_some() {
                    report.restarts += 1;
                }
                seq = WindowSeq::default();
                report.device = Some(h);
            }
            Some(Incoming::Stats(s)) => report.stats = Some(s),
            Some(Incoming::Bad(_)) => report.frames_bad += 1,
            Some(Incoming::Ack(_)) | None => {}
            Some(Incoming::Closed(why)) => {
                let why = why.unwrap_or_else(|| "end of input".into());
                report.closed = Some(if link.traffic().1 == 0 {
                    // As `evcal device` closes a second host's connection.
                    format!("{why}, before the device said a word: the device is busy with another host (it serves one at a time), or it is shutting down")
                } else {
                    why
                });
                break;
            }
        }
        if last_status.elapsed() >= Duration::from_millis(100) {
            report.bytes_received = link.traffic().1;
            on(Progress::Status(&report));
            last_status = Instant::now();
        }
    }
    report.bytes_received = link.traffic().1;
    Ok(report)
}
