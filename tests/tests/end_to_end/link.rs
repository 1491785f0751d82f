//! End to end over the link: a simulated recording replayed into a virtual device (the
//! firmware's protocol loop and capacities, on a thread) must give exactly the JSON lines
//! `evcal detect` gives; damage on the way costs only the damaged frames, and says so.

use evcal_core::{
    detect::DetectConfig,
    event::{Event, SensorSize},
    wire::{emit_core_detection, emit_events, events_that_fit},
};
use evcal_host::{
    eval::simulate,
    input::detections::{self, WindowRecord},
    input::link::{
        fault::{describe, FrameKind, FrameTap},
        replay::{replay, ReplayOptions, ReplayReport, WindowedEvents},
        virtual_device::{self, PipeWriter},
        Link, Progress,
    },
    sim::{Light, SimConfig, Trajectory},
};
use std::{
    collections::BTreeSet,
    io::Write,
    sync::{atomic::AtomicBool, Arc, Mutex},
    time::Duration,
};

/// A short simulated DAVIS346 recording of the 4x11 grid, and the detector's configuration.
fn recording(seconds: f64, light: Light, seed: u64) -> (Vec<Event>, DetectConfig) {
    let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, light, seed).unwrap();
    let (events, _) = simulate(cfg.clone(), seconds);
    (events, DetectConfig::new(SensorSize { width: cfg.camera.width, height: cfg.camera.height }))
}

/// What `evcal detect` prints for these events.
fn detect_lines(events: &[Event], cfg: DetectConfig) -> Vec<String> {
    let mut lines = Vec::new();
    detections::run(events.iter().map(|e| Ok(*e)), cfg, |d| {
        lines.push(WindowRecord::from_detection(d).with_sensor(cfg.sensor).to_json_line())
    })
    .unwrap();
    lines
}

fn quick() -> ReplayOptions {
    ReplayOptions {
        retry_timeout: Duration::from_millis(300),
        hello_timeout: Duration::from_secs(2),
        ..Default::default()
    }
}

/// Replays through a virtual device whose two directions pass through `to_device` and
/// `to_host`; the JSON lines received and the report.
fn replay_lines<D, H>(
    events: &[Event],
    cfg: DetectConfig,
    opts: ReplayOptions,
    to_device: impl FnOnce(PipeWriter) -> D,
    to_host: impl FnOnce(PipeWriter) -> H,
) -> (Vec<WindowRecord>, ReplayReport)
where
    D: Write + Send + 'static,
    H: Write + Send + 'static,
{
    let (mut link, device): (Link, _) = virtual_device::loopback(cfg, virtual_device::options(), to_device, to_host);
    let mut got = Vec::new();
    let report = replay(&mut link, events.iter().map(|e| Ok(*e)), cfg, &opts, &AtomicBool::new(false), &mut |p| {
        if let Progress::Window(w) = p {
            got.push(w.clone());
        }
    })
    .unwrap();
    drop(link);
    device.join();
    (got, report)
}

#[test]
fn replay_through_a_virtual_device_is_byte_identical_to_detect() {
    let (events, cfg) = recording(0.6, Light::Good, 3);
    let expected = detect_lines(&events, cfg);
    assert!(expected.len() >= 15, "{} windows", expected.len());
    let (got, report) = replay_lines(&events, cfg, quick(), |w| w, |w| w);
    let got: Vec<String> = got.iter().map(WindowRecord::to_json_line).collect();
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(&expected) {
        assert_eq!(g, e);
    }
    assert!(report.complete && !report.interrupted);
    assert_eq!((report.windows_lost, report.frames_bad, report.retransmitted), (0, 0, 0));
    // only the events a window holds cross the link: about an eighth
    assert_eq!(report.events_read, events.len() as u64);
    assert_eq!(report.events_sent + report.events_skipped, events.len() as u64);
    assert!(report.events_sent < events.len() as u64 / 4, "{} of {} sent", report.events_sent, events.len());
    let s = report.stats.unwrap();
    assert_eq!((s.events_received, u64::from(s.windows)), (report.events_sent, expected.len() as u64));
    assert_eq!((s.frames_bad, s.frames_discarded), (0, 0));
    assert!(report.centres > 20 * report.windows, "{} centres", report.centres);
}

#[test]
fn replaying_every_event_gives_the_same_lines() {
    let (events, cfg) = recording(0.15, Light::Low, 8);
    let expected = detect_lines(&events, cfg);
    assert!(expected.len() >= 4);
    let all = ReplayOptions { all_events: true, ..quick() };
    let (got, report) = replay_lines(&events, cfg, all, |w| w, |w| w);
    let got: Vec<String> = got.iter().map(WindowRecord::to_json_line).collect();
    assert_eq!(got, expected);
    assert_eq!((report.events_sent, report.events_skipped), (events.len() as u64, 0));
    let s = report.stats.unwrap();
    assert_eq!(s.events_received, events.len() as u64);
    assert_eq!(s.events_accepted + s.out_of_sensor + s.time_backwards, events.len() as u64);
}

/// Damages whole frames chosen by `pick(index, kind)`: flips one bit in the middle, or drops
/// a byte; records the kinds it damaged.
fn damager(
    mut pick: impl FnMut(usize, FrameKind) -> bool + Send + 'static,
    drop_byte: bool,
    log: Arc<Mutex<Vec<FrameKind>>>,
) -> impl FnMut(usize, &mut Vec<u8>) + Send + 'static {
    move |i, f: &mut Vec<u8>| {
        let kind = describe(f);
        if pick(i, kind) {
            let mid = f.len() / 2;
            if drop_byte {
                f.remove(mid);
            } else {
                f[mid] ^= 0x10;
                if f[mid] == 0 {
                    f[mid] = 0x55; // stay inside the frame: a zero would split it
                }
            }
            log.lock().unwrap().push(kind);
        }
    }
}

#[test]
fn damaged_detection_frames_cost_only_their_windows_and_are_reported() {
    let (events, cfg) = recording(0.6, Light::Good, 3);
    let expected = detect_lines(&events, cfg);
    let victims: BTreeSet<u32> = [2u32, 3, 9, 14].into_iter().collect();
    let log = Arc::new(Mutex::new(Vec::new()));
    let v = victims.clone();
    let tap = damager(move |_, k| matches!(k, FrameKind::Detection(s) if v.contains(&s)), false, Arc::clone(&log));
    let (got, report) = replay_lines(&events, cfg, quick(), |w| w, move |w| FrameTap::new(w, tap));
    assert_eq!(log.lock().unwrap().len(), victims.len());
    // exactly the damaged windows are missing; every other line is byte-identical
    let got_seqs: BTreeSet<u32> = got.iter().map(|w| w.seq).collect();
    let all: BTreeSet<u32> = (0..expected.len() as u32).collect();
    assert_eq!(all.difference(&got_seqs).copied().collect::<BTreeSet<_>>(), victims);
    for w in &got {
        assert_eq!(w.to_json_line(), expected[w.seq as usize]);
    }
    assert_eq!(report.windows_lost, victims.len() as u64, "the loss is reported");
    assert_eq!(report.frames_bad, victims.len() as u64);
    assert!(report.complete);
}

#[test]
fn dropped_bytes_in_detection_frames_cost_only_their_windows() {
    let (events, cfg) = recording(0.4, Light::Good, 4);
    let expected = detect_lines(&events, cfg);
    let last = expected.len() as u32 - 1;
    let log = Arc::new(Mutex::new(Vec::new()));
    // the first, a middle and the last window: the last one's loss is known only from the
    // device's final counters
    let tap = damager(
        move |_, k| matches!(k, FrameKind::Detection(s) if s == 0 || s == 5 || s == last),
        true,
        Arc::clone(&log),
    );
    let (got, report) = replay_lines(&events, cfg, quick(), |w| w, move |w| FrameTap::new(w, tap));
    let seqs: Vec<u32> = got.iter().map(|w| w.seq).collect();
    assert!(!seqs.contains(&0) && !seqs.contains(&5) && !seqs.contains(&last));
    assert_eq!(got.len(), expected.len() - 3);
    assert_eq!(report.windows_lost, 3, "{report:?} {seqs:?}");
    for w in &got {
        assert_eq!(w.to_json_line(), expected[w.seq as usize]);
    }
}

#[test]
fn damaged_and_dropped_batches_are_sent_again_and_nothing_is_lost() {
    let (events, cfg) = recording(0.4, Light::Good, 5);
    let expected = detect_lines(&events, cfg);
    let log = Arc::new(Mutex::new(Vec::new()));
    // damage every 7th batch on its first trip (flip), and the End; drop a byte in batch 30
    let mut seen = BTreeSet::new();
    let tap = damager(
        move |_, k| {
            let chosen = matches!(k, FrameKind::Events(s) if s % 7 == 3) || k == FrameKind::End;
            chosen && seen.insert(k)
        },
        false,
        Arc::clone(&log),
    );
    let log2 = Arc::new(Mutex::new(Vec::new()));
    let mut seen2 = BTreeSet::new();
    let tap2 = damager(move |_, k| k == FrameKind::Events(30) && seen2.insert(k), true, Arc::clone(&log2));
    let (got, report) = replay_lines(&events, cfg, quick(), move |w| FrameTap::new(FrameTap::new(w, tap2), tap), |w| w);
    let damaged = log.lock().unwrap().len() + log2.lock().unwrap().len();
    assert!(damaged >= 5, "{damaged} frames damaged");
    let got: Vec<String> = got.iter().map(WindowRecord::to_json_line).collect();
    assert_eq!(got, expected, "a lossless replay despite the damage");
    assert_eq!(report.windows_lost, 0);
    assert!(report.retransmitted >= damaged as u64);
    let s = report.stats.unwrap();
    assert_eq!(s.frames_bad as usize, damaged, "the device counted every damaged frame");
    assert_eq!(s.events_received, report.events_sent, "every event sent arrived exactly once");
}

/// The link's budget, measured on simulated windows: detection frames (what the device
/// sends per window) and event batches (what replay costs per event).
#[test]
fn bytes_per_window_and_per_event() {
    let mut report = Vec::new();
    for (light, seed) in [(Light::Good, 7), (Light::Low, 7)] {
        let (events, cfg) = recording(1.0, light, seed);
        // detection frames exactly as the device encodes them
        let mut det: Box<detections::HostDetector> = Box::new(detections::HostDetector::new(cfg));
        let mut buf = vec![0u8; 4096];
        let (mut windows, mut bytes, mut max, mut centres, mut max_centres) = (0usize, 0usize, 0usize, 0usize, 0usize);
        for e in &events {
            if let Some(d) = det.push(*e) {
                let n = emit_core_detection(d, &mut buf).unwrap();
                windows += 1;
                bytes += n;
                max = max.max(n);
                centres += d.centres.len();
                max_centres = max_centres.max(d.centres.len());
            }
        }
        // event batches at the virtual device's frame limit, for every event and for the
        // events a window holds (what `evcal replay` sends by default)
        let max_frame = evcal_core::wire::device::RX_FRAME + 2;
        let batch_bytes = |ev: &[Event], buf: &mut [u8]| {
            let (mut rest, mut seq, mut bytes) = (ev, 0u32, 0usize);
            while !rest.is_empty() {
                let n = events_that_fit(seq, rest, max_frame);
                bytes += emit_events(seq, &rest[..n], buf).unwrap();
                rest = &rest[n..];
                seq += 1;
            }
            bytes
        };
        let all = batch_bytes(&events, &mut buf);
        let used: Vec<Event> =
            WindowedEvents::new(events.iter().map(|e| Ok(*e)), cfg, false).map(|e| e.unwrap()).collect();
        let sent = batch_bytes(&used, &mut buf);
        let per_event = sent as f64 / used.len() as f64;
        let line = format!(
            "{} light: {windows} windows, {:.1} centres/window (max {max_centres}), detection frame mean {:.0} B, \
             max {max} B ({:.2} B/centre); replay {per_event:.2} B/event, {:.1} kB/window ({} of {} events sent; \
             all events {:.2} B/event), frames <= {max_frame} B",
            light.name(),
            centres as f64 / windows as f64,
            bytes as f64 / windows as f64,
            bytes as f64 / centres.max(1) as f64,
            sent as f64 / windows as f64 / 1e3,
            used.len(),
            events.len(),
            all as f64 / events.len() as f64,
        );
        eprintln!("{line}");
        report.push(line);
        assert!(max <= 1024, "a window's frame is {max} B: over 1 KiB");
        assert!(per_event < 3.5, "{per_event:.2} B/event");
    }
}

/// The host's default window for a DVXplorer (15 000 events) is more than the firmware holds:
/// a replay asking for it as a wish gets the device's 8000-event windows, exactly the lines
/// `evcal detect --events-per-window 8000` prints, and a note; asking for it as a demand (the
/// user's `--events-per-window`) is an error that says what the device holds.
#[test]
fn a_default_window_beyond_the_device_is_cut_to_what_it_holds() {
    let (events, _) = recording(0.4, Light::Good, 3);
    let asked = detections::host_config(SensorSize::DVXPLORER);
    assert_eq!(asked.window.events, 15_000);
    let held = DetectConfig { window: evcal_core::window::WindowConfig { events: 8000, ..asked.window }, ..asked };
    let expected = detect_lines(&events, held);
    let opts = ReplayOptions { window_up_to_device: true, ..quick() };
    let (got, report) = replay_lines(&events, asked, opts, |w| w, |w| w);
    let got: Vec<String> = got.iter().map(WindowRecord::to_json_line).collect();
    assert!(expected.len() >= 10, "{} windows", expected.len());
    assert_eq!(got, expected);
    assert_eq!(report.device.map(|h| h.config.window.events), Some(8000));
    assert!(report.notes.iter().any(|n| n.contains("at most 8000 events per window")), "{:?}", report.notes);

    let (mut link, device): (Link, _) = virtual_device::loopback(asked, virtual_device::options(), |w| w, |w| w);
    let e = replay(&mut link, events.iter().map(|e| Ok(*e)), asked, &quick(), &AtomicBool::new(false), &mut |_| {})
        .unwrap_err();
    drop(link);
    device.join();
    assert!(e.to_string().contains("holds at most 8000 events per window; 15000 were asked"), "{e}");
}
