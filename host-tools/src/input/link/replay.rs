//! Replaying a recording into a device (hardware-in-the-loop) and collecting what it finds.
//!
//! The host speaks only after the device's Hello (or after a time-out of silence), starts a
//! session with the detector's configuration, then streams event batches under the
//! device's credit: never more than `window` frames beyond the last acknowledged one, so a
//! device slower than the link is never overrun. Frames the device reports damaged or
//! missing are sent again from the one it expects (go-back-N), as are frames whose
//! acknowledgement does not come within the retry time-out; the replay is lossless on a
//! noisy link. Detections are not repeated by the device: a detection frame damaged on its
//! way here shows as a gap in the window numbers and is counted as lost.

use super::{refuse, LinkError, Result};
use super::{Incoming, Link, Progress, Seen, WindowSeq};
use crate::{
    input::detections::{WindowRecord, HOST_HELD_EVENTS, HOST_MAX_EVENTS},
    input::recording::ReadError,
};
use evcal_core::{
    detect::DetectConfig,
    event::{Event, InputFilter},
    window::Windower,
    wire::{emit_events, events_that_fit, Config, End, Hello, HelloReply, Stats},
};
use std::{
    collections::VecDeque,
    sync::atomic::{AtomicBool, Ordering},
    time::{Duration, Instant},
};

/// Events read ahead of the frame being built (enough to fill any frame).
const READ_AHEAD: usize = 4096;
/// Smallest host frame a device may ask for (a batch needs room for its header).
const MIN_FRAME: u16 = 64;
/// How often the caller hears the counts.
const STATUS_EVERY: Duration = Duration::from_millis(100);

/// How the host behaves on the link.
#[derive(Debug, Clone, Copy)]
pub struct ReplayOptions {
    /// Session number (nonzero, new each run): lets the device tell a repeated Config from a
    /// new session.
    pub session: u32,
    /// How long to wait for the device's Hello before sending the configuration anyway.
    pub hello_timeout: Duration,
    /// How long without an acknowledgement before frames are sent again.
    pub retry_timeout: Duration,
    /// Retries in a row without progress before giving up.
    pub max_retries: u32,
    /// Send every event of the recording, not only those the device's windows will hold.
    pub all_events: bool,
    /// The configuration's events per window is a wish, not a demand: a device that holds
    /// fewer cuts windows of as many as it holds, and the replay goes on with them (a note
    /// says so). Set for the host's default window size, which may exceed a device's; clear,
    /// a device that holds fewer events than asked is an error.
    pub window_up_to_device: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        Self {
            session: new_session(),
            hello_timeout: Duration::from_secs(3),
            retry_timeout: Duration::from_secs(1),
            max_retries: 20,
            all_events: false,
            window_up_to_device: false,
        }
    }
}

/// A nonzero session number from the clock.
pub fn new_session() -> u32 {
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    (t.as_nanos() as u32) | 1
}

/// What happened during a replay.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayReport {
    /// The device's Hello in answer to the configuration.
    pub device: Option<Hello>,
    /// Events read from the recording.
    pub events_read: u64,
    /// Events left out (see [`WindowedEvents`]): outside the sensor, earlier than the event
    /// before, or in no window of the device.
    pub events_skipped: u64,
    /// Of those, the events outside the sensor.
    pub events_out_of_sensor: u64,
    /// Of those, the events earlier than the one before (the device's input filter would
    /// drop them).
    pub events_time_backwards: u64,
    /// Events put into batches and sent.
    pub events_sent: u64,
    /// Batches sent (first transmissions).
    pub batches: u64,
    /// Frames sent again (after a NAK or a time-out).
    pub retransmitted: u64,
    /// Windows whose detections arrived.
    pub windows: u64,
    /// Centres in them.
    pub centres: u64,
    /// Windows whose detections never arrived (damaged on the way).
    pub windows_lost: u64,
    /// Frames from the device that arrived damaged.
    pub frames_bad: u64,
    /// Bytes sent to the device.
    pub bytes_sent: u64,
    /// Bytes received from the device.
    pub bytes_received: u64,
    /// The device's latest counters.
    pub stats: Option<Stats>,
    /// Whether the device's final counters (after the end of the stream) arrived.
    pub complete: bool,
    /// Stopped early by the caller (Ctrl-C).
    pub interrupted: bool,
    /// The recording could not be read to its end: what went wrong (the events before it
    /// were replayed).
    pub read_error: Option<String>,
    /// Things the user should know.
    pub notes: Vec<String>,
}

/// Replays `events` into the device on `link` with the detector configured as `config`.
/// `on` hears every window as it arrives and the counts a few times a second. Returns when
/// the device has acknowledged the end of the stream and sent its final counters, or when
/// `stop` is set; an error when the device misbehaves or stops answering.
pub fn replay(
    link: &mut Link,
    events: impl Iterator<Item = Result<Event, ReadError>>,
    config: DetectConfig,
    opts: &ReplayOptions,
    stop: &AtomicBool,
    on: &mut dyn FnMut(Progress<'_, ReplayReport>),
) -> Result<ReplayReport> {
    let mut report = ReplayReport::default();
    // A session's windows are numbered from 0.
    let mut seq = WindowSeq::starting_at(0);
    let hello = handshake(link, config, opts, stop, &mut report, &mut seq, on)?;
    let Some(hello) = hello else {
        report.interrupted = true;
        return Ok(report);
    };
    // The device's windows, which may hold fewer events than asked (`window_up_to_device`).
    let config = hello.config;
    let mut used = WindowedEvents::new(events, config, opts.all_events);
    let streamed = stream(link, &mut used, &hello, opts, stop, &mut report, &mut seq, on);
    (report.events_read, report.events_skipped) = (used.read, used.skipped);
    (report.events_out_of_sensor, report.events_time_backwards) = (used.out_of_sensor(), used.time_backwards());
    streamed?;
    if let Some(s) = report.stats.filter(|s| s.end_of_stream) {
        let missing = s.windows.saturating_sub(seq.expected());
        report.windows_lost += u64::from(missing);
    }
    (report.bytes_sent, report.bytes_received) = link.traffic();
    on(Progress::Status(&report));
    Ok(report)
}

/// Handles one message that is not flow control; true if it was a window.
fn note(
    m: &Incoming,
    report: &mut ReplayReport,
    seq: &mut WindowSeq,
    on: &mut dyn FnMut(Progress<'_, ReplayReport>),
) -> Result<()> {
    match m {
        Incoming::Window(w) => {
            match seq.see(w.seq) {
                Seen::InOrder => {}
                Seen::AfterLoss(n) => report.windows_lost += u64::from(n),
                Seen::Restart => {
                    refuse!(
                        "window numbers went back (window {} after {}): the device restarted",
                        w.seq,
                        seq.expected()
                    )
                }
            }
            report.windows += 1;
            report.centres += w.centers.len() as u64;
            on(Progress::Window(w));
        }
        Incoming::Stats(s) => report.stats = Some(*s),
        Incoming::Bad(_) => report.frames_bad += 1,
        Incoming::Closed(why) => {
            refuse!("the link closed{}", why.as_ref().map(|w| format!(": {w}")).unwrap_or_default())
        }
        Incoming::Hello(_) | Incoming::Ack(_) => {}
    }
    Ok(())
}

/// Waits for the device to speak, then starts the session; `None` if stopped.
fn handshake(
    link: &mut Link,
    config: DetectConfig,
    opts: &ReplayOptions,
    stop: &AtomicBool,
    report: &mut ReplayReport,
    seq: &mut WindowSeq,
    on: &mut dyn FnMut(Progress<'_, ReplayReport>),
) -> Result<Option<Hello>> {
    let started = Instant::now();
    let mut heard = false;
    while !heard && started.elapsed() < opts.hello_timeout {
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        match link.recv(Duration::from_millis(50)) {
            Some(Incoming::Hello(_)) => heard = true,
            Some(Incoming::Closed(why)) => return Err(closed_before_hello(link, why)),
            // Detections or stats of an earlier session: not ours.
            _ => {}
        }
    }
    if !heard {
        report.notes.push(format!(
            "no Hello from the device within {:.1} s; sent the configuration anyway",
            opts.hello_timeout.as_secs_f64()
        ));
    }
    let mut frame = vec![0u8; 256];
    let n = Config { session: opts.session, config }
        .emit(&mut frame)
        .map_err(|e| LinkError::Device(format!("encoding the configuration: {e}")))?;
    frame.truncate(n);
    for _ in 0..=opts.max_retries {
        link.send(&frame)?;
        let sent = Instant::now();
        while sent.elapsed() < opts.retry_timeout {
            if stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
            let Some(m) = link.recv(Duration::from_millis(50)) else { continue };
            match m {
                Incoming::Hello(h) if h.session == opts.session && h.reply != HelloReply::Boot => {
                    check_hello(&h, &config, opts.window_up_to_device)?;
                    if h.config.window.events != config.window.events {
                        report.notes.push(format!(
                            "the device holds at most {} events per window: its windows hold {}, not the {} asked",
                            h.max_events, h.config.window.events, config.window.events
                        ));
                    }
                    report.device = Some(h);
                    return Ok(Some(h));
                }
                Incoming::Hello(_) => {}
                Incoming::Window(_) | Incoming::Stats(_) => {} // an earlier session's
                Incoming::Closed(why) => return Err(closed_before_hello(link, why)),
                other => note(&other, report, seq, on)?,
            }
        }
    }
    refuse!(
        "the device did not answer the configuration ({} tries, {:.1} s apart)",
        opts.max_retries + 1,
        opts.retry_timeout.as_secs_f64()
    )
}

/// The link closed (`why`, if known) before the device answered. A device that closed it
/// without a byte is serving another host: `evcal device` closes a second connection at
/// once, as a board's one serial line could not take it.
fn closed_before_hello(link: &Link, why: Option<String>) -> LinkError {
    let why = why.map(|w| format!(" ({w})")).unwrap_or_default();
    if link.traffic().1 == 0 {
        LinkError::Device(format!(
            "the device closed the link before it said a word{why}: the device is busy with another host (it serves one at a time), or it is shutting down"
        ))
    } else {
        LinkError::Device(format!("the link closed before the device answered{why}"))
    }
}

/// Whether the device runs the configuration `asked`; with `window_up_to_device`, windows
/// of fewer events than asked are accepted when they are all the device holds.
fn check_hello(h: &Hello, asked: &DetectConfig, window_up_to_device: bool) -> Result<()> {
    if h.reply == HelloReply::Rejected {
        refuse!("the device refused the configuration (a value out of its range): {asked:?}");
    }
    let events = h.config.window.events;
    let clamped = events < asked.window.events && events as u64 == u64::from(h.max_events);
    let asked =
        &if window_up_to_device && clamped { DetectConfig { window: h.config.window, ..*asked } } else { *asked };
    if h.config.window.events != asked.window.events {
        refuse!(
            "the device holds at most {} events per window; {} were asked (use --events-per-window {} or less)",
            h.max_events,
            asked.window.events,
            h.max_events
        );
    }
    if h.config != *asked {
        refuse!("the device runs {:?}, not the configuration asked, {asked:?}", h.config);
    }
    if h.max_frame < MIN_FRAME {
        refuse!("the device accepts frames of only {} bytes; at least {MIN_FRAME} are needed", h.max_frame);
    }
    Ok(())
}

/// Frames sent and not yet acknowledged, by sequence number.
struct Outstanding {
    /// Sequence number of `frames[0]`.
    base: u32,
    /// Next sequence number to transmit (after a rewind, one already in `frames`).
    next: u32,
    frames: VecDeque<Vec<u8>>,
}

impl Outstanding {
    fn in_flight(&self) -> u32 {
        self.next.wrapping_sub(self.base)
    }
}

#[allow(clippy::too_many_arguments)]
fn stream(
    link: &mut Link,
    events: &mut impl Iterator<Item = Result<Event, ReadError>>,
    hello: &Hello,
    opts: &ReplayOptions,
    stop: &AtomicBool,
    report: &mut ReplayReport,
    seq: &mut WindowSeq,
    on: &mut dyn FnMut(Progress<'_, ReplayReport>),
) -> Result<()> {
    let max_frame = usize::from(hello.max_frame);
    let mut window = u32::from(hello.window.max(1));
    let tick = (opts.retry_timeout / 4).clamp(Duration::from_millis(1), Duration::from_millis(50));
    let mut out = Outstanding { base: 0, next: 0, frames: VecDeque::new() };
    let mut pending: Vec<Event> = Vec::with_capacity(READ_AHEAD);
    let mut input_done = false;
    let mut end: Option<(u32, Vec<u8>)> = None;
    let mut end_acked: Option<Instant> = None;
    let mut end_repeats = 0;
    let mut last_progress = Instant::now();
    let mut rewound: Option<(u32, Instant)> = None;
    let mut stalls = 0;
    let mut last_status = Instant::now();
    loop {
        if stop.load(Ordering::Relaxed) {
            report.interrupted = true;
            return Ok(());
        }
        // Send what the credit allows: frames again after a rewind, then new ones.
        while end_acked.is_none() && out.in_flight() < window {
            let idx = out.in_flight() as usize;
            if let Some(f) = out.frames.get(idx) {
                link.send(f)?;
                report.retransmitted += 1;
                out.next = out.next.wrapping_add(1);
                continue;
            }
            if end.is_some() {
                break;
            }
            while !input_done && pending.len() < READ_AHEAD {
                match events.next() {
                    Some(Ok(e)) => pending.push(e),
                    Some(Err(e)) => {
                        report.read_error = Some(e.to_string());
                        input_done = true;
                    }
                    None => input_done = true,
                }
            }
            let mut frame = vec![0u8; max_frame];
            if pending.is_empty() {
                let n = End { seq: out.next }.emit(&mut frame)?;
                frame.truncate(n);
                end = Some((out.next, frame.clone()));
            } else {
                let n = events_that_fit(out.next, &pending, max_frame);
                if n == 0 {
                    refuse!("an event does not fit in the device's {max_frame}-byte frames");
                }
                let len =
                    emit_events(out.next, &pending[..n], &mut frame).map_err(|e| LinkError::Device(e.to_string()))?;
                frame.truncate(len);
                pending.drain(..n);
                report.events_sent += n as u64;
                report.batches += 1;
            }
            link.send(&frame)?;
            out.frames.push_back(frame);
            out.next = out.next.wrapping_add(1);
        }
        // Hear the device.
        if let Some(m) = link.recv(tick) {
            match m {
                Incoming::Ack(a) => {
                    let acked = a.next.wrapping_sub(out.base);
                    if acked > 0 && acked as usize <= out.frames.len() {
                        out.frames.drain(..acked as usize);
                        out.base = a.next;
                        if out.in_flight() > i32::MAX as u32 {
                            // acknowledged past a rewound send position
                            out.next = out.base;
                        }
                        last_progress = Instant::now();
                        stalls = 0;
                    }
                    window = u32::from(a.window.max(1));
                    if a.nak && a.next == out.base && out.next != out.base {
                        // One rewind per NAKed frame: the NAKs of the frames sent after it
                        // ask for the same thing. If the resent frame is damaged again, the
                        // time-out below resends it.
                        let recent =
                            matches!(rewound, Some((k, t)) if k == out.base && t.elapsed() < opts.retry_timeout);
                        if !recent {
                            out.next = out.base;
                            rewound = Some((out.base, Instant::now()));
                        }
                    }
                    if let Some((e, _)) = &end {
                        if out.frames.is_empty() && out.base == e.wrapping_add(1) && end_acked.is_none() {
                            end_acked = Some(Instant::now());
                        }
                    }
                }
                Incoming::Hello(h) if h.reply == HelloReply::Boot => {
                    refuse!("the device restarted during the replay (it said Hello again)")
                }
                other => note(&other, report, seq, on)?,
            }
        }
        if last_status.elapsed() >= STATUS_EVERY {
            (report.bytes_sent, report.bytes_received) = link.traffic();
            on(Progress::Status(report));
            last_status = Instant::now();
        }
        if let Some(t) = end_acked {
            if report.stats.is_some_and(|s| s.end_of_stream) {
                report.complete = true;
                return Ok(());
            }
            // The final Stats precedes the Ack: it was lost. Ask again by repeating End.
            if t.elapsed() >= opts.retry_timeout {
                if end_repeats >= 3 {
                    report.notes.push("the device's final counters never arrived".into());
                    return Ok(());
                }
                if let Some((_, f)) = &end {
                    link.send(f)?;
                }
                end_repeats += 1;
                end_acked = Some(Instant::now());
            }
            continue;
        }
        if !out.frames.is_empty() && last_progress.elapsed() >= opts.retry_timeout {
            stalls += 1;
            if stalls > opts.max_retries {
                refuse!(
                    "the device stopped acknowledging: no progress in {:.1} s",
                    (opts.retry_timeout * stalls).as_secs_f64()
                );
            }
            out.next = out.base;
            rewound = Some((out.base, Instant::now()));
            last_progress = Instant::now();
        }
    }
}

/// The events of a recording that the device will use: those its input filter accepts and
/// its windower puts into a window (the first N events at or after each tick), found by
/// running the same filter and windower here.
///
/// Events between the end of one window and the next tick never reach a window, and a
/// simulated DAVIS346 produces about a million events per second of which the paper's
/// windows (4000 events every 33 ms) hold an eighth: leaving the rest out makes a replay
/// over a 14 KB/s UART eight times faster. The device sees the same first event of every
/// window and the same event times, so it cuts the same windows (the tests compare the
/// JSON lines byte for byte); only its input counters differ, since it never sees what
/// was left out.
pub struct WindowedEvents<I> {
    inner: I,
    /// The host's hold, as `evcal detect`'s, so that a replay drops the strays `detect` drops.
    filter: InputFilter<HOST_HELD_EVENTS>,
    windower: Option<Box<Windower<HOST_MAX_EVENTS>>>,
    /// The read error to pass on once the events before it are out.
    error: Option<ReadError>,
    /// The input has ended (or failed): the filter is releasing what it held.
    ended: bool,
    /// Events passed on.
    sent: u64,
    /// Events read.
    pub read: u64,
    /// Events left out.
    pub skipped: u64,
}

impl<I> WindowedEvents<I> {
    /// Of the events left out, those outside the sensor.
    pub fn out_of_sensor(&self) -> u64 {
        self.filter.stats().out_of_sensor
    }

    /// Of the events left out, those dropped for their time: earlier than the one before, or
    /// a stray far ahead of its neighbours.
    pub fn time_backwards(&self) -> u64 {
        self.filter.stats().time_order()
    }

    /// Filters `inner` for the detector `config` (or passes everything if `all`).
    pub fn new(inner: I, config: DetectConfig, all: bool) -> Self {
        let windower = (!all).then(|| Box::new(Windower::new(config.window)));
        Self {
            inner,
            filter: InputFilter::new(config.sensor),
            windower,
            error: None,
            ended: false,
            sent: 0,
            read: 0,
            skipped: 0,
        }
    }
}

impl<I: Iterator<Item = Result<Event, ReadError>>> Iterator for WindowedEvents<I> {
    type Item = Result<Event, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        let Some(w) = self.windower.as_mut() else {
            let e = self.inner.next()?;
            self.read += u64::from(e.is_ok());
            return Some(e);
        };
        loop {
            // What the filter releases from its hold comes before anything read after it.
            let e = match self.filter.pop() {
                Some(e) => e,
                None if self.ended => {
                    self.skipped = self.read - self.sent;
                    return self.error.take().map(Err);
                }
                None => {
                    let e = match self.inner.next() {
                        Some(Ok(e)) => e,
                        end => {
                            // The events held before an error or the end go out first.
                            self.error = end.and_then(Result::err);
                            self.ended = true;
                            self.filter.finish();
                            continue;
                        }
                    };
                    self.read += 1;
                    match self.filter.push(e) {
                        Some(e) => e,
                        // Held, or dropped.
                        None => continue,
                    }
                }
            };
            let before = w.pending();
            if w.push(e).is_some() || w.pending() > before {
                self.sent += 1;
                self.skipped = self.read - self.sent;
                return Some(Ok(e));
            }
        }
    }
}

/// Replays `events` into a fresh in-process virtual device (the firmware's capacities and
/// loop) and returns every window's record, as `evcal demo` and the tests do.
pub fn replay_virtual(events: &[Event], config: DetectConfig) -> Result<(Vec<WindowRecord>, ReplayReport)> {
    let (mut link, device) = super::virtual_device::loopback(config, super::virtual_device::options(), |w| w, |w| w);
    let mut windows = Vec::new();
    let opts = ReplayOptions { retry_timeout: Duration::from_secs(5), ..ReplayOptions::default() };
    let report = replay(&mut link, events.iter().map(|e| Ok(*e)), config, &opts, &AtomicBool::new(false), &mut |p| {
        if let Progress::Window(w) = p {
            windows.push(w.clone());
        }
    })?;
    drop(link);
    device.join();
    Ok((windows, report))
}

#[cfg(test)]
mod test {
    use super::*;
    use evcal_core::{event::SensorSize, window::WindowConfig};
    use proptest::prelude::*;

    /// The windows (info and events) a device cuts from `events`: its input filter, then its
    /// windower.
    type Cut = (evcal_core::window::WindowInfo, Vec<(u16, u16, u32)>);

    fn windows(events: &[Event], cfg: &DetectConfig) -> Vec<Cut> {
        let mut f: InputFilter = InputFilter::new(cfg.sensor);
        let mut w: Box<Windower<64>> = Box::new(Windower::new(cfg.window));
        let mut out = Vec::new();
        let mut take = |e: Event, out: &mut Vec<Cut>| {
            if let Some(info) = w.push(e) {
                out.push((info, w.events().iter().map(|e| (e.x, e.y, e.dt_us)).collect()));
            }
        };
        for e in events {
            if let Some(e) = f.push(*e) {
                take(e, &mut out);
            }
            while let Some(e) = f.pop() {
                take(e, &mut out);
            }
        }
        f.finish();
        while let Some(e) = f.pop() {
            take(e, &mut out);
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Leaving out the events no window holds changes no window.
        #[test]
        fn windowed_events_cut_the_same_windows(
            steps in proptest::collection::vec((0u64..40, 0u16..24, 0u16..24, 0u8..30), 0..600),
            n in 1usize..40,
            step_us in prop_oneof![Just(0u64), 1u64..300],
        ) {
            let mut t = 1000u64;
            let events: Vec<Event> = steps
                .iter()
                .map(|&(dt, x, y, odd)| {
                    // now and then a step back in time (dropped by the filter)
                    t = if odd == 0 { t.saturating_sub(dt) } else { t + dt };
                    Event { t_us: t, x, y, polarity: odd % 2 == 0 }
                })
                .collect();
            let mut cfg = DetectConfig::new(SensorSize::new(20, 20));
            cfg.window = WindowConfig { events: n, step_us };
            let mut it = WindowedEvents::new(events.iter().map(|e| Ok(*e)), cfg, false);
            let used: Vec<Event> = it.by_ref().map(|e| e.unwrap()).collect();
            prop_assert!(used.len() <= events.len());
            // Each event left out is counted once, under its reason.
            let mut f = InputFilter::<HOST_HELD_EVENTS>::new(cfg.sensor);
            for e in &events {
                let _ = f.push(*e);
                while f.pop().is_some() {}
            }
            f.finish();
            while f.pop().is_some() {}
            prop_assert_eq!((it.out_of_sensor(), it.time_backwards()), (f.stats().out_of_sensor, f.stats().time_order()));
            prop_assert_eq!(it.skipped, events.len() as u64 - used.len() as u64);
            prop_assert_eq!(windows(&used, &cfg), windows(&events, &cfg));
            let all: Vec<Event> =
                WindowedEvents::new(events.iter().map(|e| Ok(*e)), cfg, true).map(|e| e.unwrap()).collect();
            prop_assert_eq!(all, events);
        }
    }

    #[test]
    fn read_errors_pass_through() {
        let cfg = DetectConfig::new(SensorSize::DAVIS346);
        let input = vec![
            Ok(Event { t_us: 0, x: 1, y: 1, polarity: true }),
            Err(ReadError::new(
                std::path::Path::new("rec.txt"),
                crate::input::recording::Position::Line(2),
                "not a number",
            )),
        ];
        let mut w = WindowedEvents::new(input.into_iter(), cfg, false);
        assert!(matches!(w.next(), Some(Ok(_))));
        assert!(matches!(w.next(), Some(Err(_))));
        assert!(w.next().is_none());
        assert_eq!((w.read, w.skipped), (1, 0));
    }
}
