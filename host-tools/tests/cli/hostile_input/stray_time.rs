//! One stray timestamp (issue 46): a time far ahead of its neighbours costs the recording
//! that one event, through every reader that can carry it, and is said; a detection with no
//! window fails.

use super::assert_calibrated;
use super::{aedat4_of_events, bag_of_messages, evcal, events, read_all, s};
use evcal_core::{
    detect::DetectConfig,
    event::{Event, SensorSize},
    evt::Encoding,
    window::WindowConfig,
};
use evcal_host::input::{
    detections::{self, RunSummary, WindowRecord},
    recording::{
        prophesee::write::{write_dat, write_raw},
        write_ecalib_h5, write_text, Recording,
    },
};
use std::path::Path;

/// An hour, µs: the stray line `3600.000000 100 100 1`.
const STRAY_US: u64 = 3_600_000_000;

/// The recording with a stray event an hour ahead inserted at a tenth of the way.
fn with_stray(clean: &[Event]) -> Vec<Event> {
    let mut v = clean.to_vec();
    v.insert(clean.len() / 10, Event { t_us: STRAY_US, x: 100, y: 100, polarity: true });
    v
}

/// Small windows, so that the 40 000 events of a test give many.
fn config() -> DetectConfig {
    let mut cfg = DetectConfig::new(SensorSize::DAVIS346);
    cfg.window = WindowConfig { events: 500, step_us: 5_000 };
    cfg
}

/// The detector over a file: every window's JSON line, and the counts.
fn detect(path: &Path) -> (Vec<String>, RunSummary) {
    let rec = Recording::open(path).unwrap_or_else(|e| panic!("{e}"));
    let mut lines = Vec::new();
    let s = detections::run(rec, config(), |d| lines.push(WindowRecord::from_detection(d).to_json_line())).unwrap();
    (lines, s)
}

/// The same windows from the clean and the glitched file of each format, the stray counted.
#[test]
fn a_stray_time_in_any_format_costs_one_event() {
    let dir = tempfile::tempdir().unwrap();
    let clean = events(40_000, SensorSize::DAVIS346, 46);
    let glitched = with_stray(&clean);
    type Writer = fn(&Path, &[Event]);
    let writers: [(&str, Writer); 7] = [
        ("txt", |p, e| write_text(p, Some(SensorSize::DAVIS346), e).unwrap()),
        ("h5", |p, e| write_ecalib_h5(p, e).unwrap()),
        ("raw", |p, e| write_raw(p, Encoding::Evt2, SensorSize::DAVIS346, e).unwrap()),
        ("evt3.raw", |p, e| write_raw(p, Encoding::Evt3, SensorSize::DAVIS346, e).unwrap()),
        ("dat", |p, e| write_dat(p, SensorSize::DAVIS346, e).unwrap()),
        // evcal writes neither: the test's own writers, as ROS's DVS driver and DV lay them
        // out (an EventArray message of 1000 events, packets of 2500)
        ("bag", |p, e| bag_of_messages(p, 346, 260, &e.chunks(1000).collect::<Vec<_>>())),
        ("aedat4", aedat4_of_events),
    ];
    for (ext, write) in writers {
        let (a, b) = (dir.path().join(format!("clean.{ext}")), dir.path().join(format!("stray.{ext}")));
        write(&a, &clean);
        write(&b, &glitched);
        if matches!(ext, "bag" | "aedat4") {
            // the test's own writers: the reader gives back what they wrote, the stray too
            assert!(read_all(Recording::open(&b).unwrap()) == glitched, "{ext}: the events written");
        }
        let (want, s0) = detect(&a);
        let (got, s1) = detect(&b);
        assert!(want.len() >= 70, "{ext}: {} windows", want.len());
        assert_eq!(got, want, "{ext}: the windows of the clean file");
        assert_eq!((s0.time_jumps, s0.time_backwards), (0, 0), "{ext}");
        assert_eq!((s1.time_jumps, s1.time_backwards), (1, 0), "{ext}");
        let ahead = STRAY_US - clean[clean.len() / 10 - 1].t_us;
        if ext == "evt3.raw" {
            // EVT 3.0's clock is 24 bits (16.8 s): the hour ahead arrives modulo that, 8.6 s
            // ahead, more than half the clock (which must not be taken as its wrap).
            assert_eq!(s1.largest_jump_us, ahead % (1 << 24), "{ext}");
        } else {
            assert_eq!(s1.largest_jump_us, ahead, "{ext}");
        }
    }
}

/// A corrupt EVT 2.0 `TIME_HIGH` word: the events up to the next one carry a time far ahead
/// and are dropped, every other event is kept.
#[test]
fn a_stray_evt2_time_high_drops_only_its_events() {
    let dir = tempfile::tempdir().unwrap();
    let clean = events(40_000, SensorSize::DAVIS346, 47);
    let a = dir.path().join("clean.raw");
    write_raw(&a, Encoding::Evt2, SensorSize::DAVIS346, &clean).unwrap();
    let mut bytes = std::fs::read(&a).unwrap();
    // The header's `%` lines end with `% end`; the words follow.
    let start = bytes.windows(6).position(|w| w == b"% end\n").unwrap() + 6;
    let words = (bytes.len() - start) / 4;
    let word = |b: &[u8], k: usize| u32::from_le_bytes(b[start + 4 * k..start + 4 * k + 4].try_into().unwrap());
    // The TIME_HIGH at a tenth of the way, set an hour ahead (its 28 bits are time >> 6).
    let k = (words / 10..words).find(|&k| word(&bytes, k) >> 28 == 0x8).unwrap();
    let high = (word(&bytes, k) & 0x0FFF_FFFF) + (STRAY_US >> 6) as u32;
    bytes[start + 4 * k..start + 4 * k + 4].copy_from_slice(&(0x8000_0000 | (high & 0x0FFF_FFFF)).to_le_bytes());
    let b = dir.path().join("stray.raw");
    std::fs::write(&b, &bytes).unwrap();
    let read = Recording::open(&b).unwrap().map(|e| e.unwrap()).collect::<Vec<_>>();
    assert_eq!(read.len(), clean.len());
    let stray: Vec<bool> = read.iter().map(|e| e.t_us >= STRAY_US).collect();
    let n = stray.iter().filter(|&&s| s).count();
    assert!(n > 0, "the corrupt word gave no stray times");
    let kept: Vec<Event> = clean.iter().zip(&stray).filter(|(_, &s)| !s).map(|(e, _)| *e).collect();
    let c = dir.path().join("kept.txt");
    write_text(&c, Some(SensorSize::DAVIS346), &kept).unwrap();
    let (want, _) = detect(&c);
    let (got, s) = detect(&b);
    assert_eq!(got, want, "the windows of the events the stray word did not touch");
    assert_eq!((s.time_jumps, s.time_backwards), (n as u64, 0));
}

/// The case: a simulated DAVIS346 recording with the line `3600.000000 100 100 1`
/// at a tenth of the way detects the same windows, byte for byte, and calibrates as without
/// it, saying what was dropped and why (the clean run calibrates from its detections, to
/// keep the test quick).
#[test]
fn calibrate_with_a_stray_line_uses_every_view() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("clean.txt");
    let (code, _, err) = evcal(&["simulate", "--seed", "46", "--seconds", "1", "--quiet", "-o", s(&rec)]);
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(&rec).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let first_event = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    let at = first_event + (lines.len() - first_event) / 10;
    let mut glitched = lines[..at].join("\n");
    glitched.push_str("\n3600.000000 100 100 1\n");
    glitched.push_str(&lines[at..].join("\n"));
    glitched.push('\n');
    let stray = dir.path().join("glitch.txt");
    std::fs::write(&stray, glitched).unwrap();
    let said = |err: &str| {
        err.contains("glitch.txt: 1 event dropped: its time was 3599.") && err.contains("s ahead of its neighbours")
    };
    let detect = |input: &Path, out: &str| {
        let jsonl = dir.path().join(out);
        let (code, _, err) = evcal(&["detect", s(input), "-o", s(&jsonl)]);
        assert_eq!(code, Some(0), "{err}");
        (std::fs::read(&jsonl).unwrap(), err)
    };
    let (want, err0) = detect(&rec, "clean.jsonl");
    let (got, err1) = detect(&stray, "glitch.jsonl");
    assert!(!err0.contains("warning") && said(&err1), "{err0}\n{err1}");
    assert!(want.iter().filter(|&&b| b == b'\n').count() >= 25);
    assert!(got == want, "the stray line changed the detections");
    let calibrate = |input: &Path, out: &str| {
        let json = dir.path().join(format!("{out}.json"));
        let (code, _, err) = evcal(&[
            "calibrate",
            s(input),
            "--sensor",
            "346x260",
            "--pattern",
            "4x11",
            "--spacing",
            "0.024",
            "--out",
            s(&dir.path().join(out)),
            "--json",
            s(&json),
        ]);
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_calibrated(code, &v, &err);
        (err, v)
    };
    let (_, clean) = calibrate(&dir.path().join("clean.jsonl"), "clean");
    let (err, glitch) = calibrate(&stray, "glitch");
    assert!(said(&err), "{err}");
    let views = |v: &serde_json::Value| v["views_used"].as_f64().unwrap();
    assert!(views(&clean) >= 15.0, "{clean}");
    assert!((views(&glitch) / views(&clean) - 1.0).abs() <= 0.05, "views: {} vs {}", views(&glitch), views(&clean));
    let fx = |v: &serde_json::Value| v["fx"].as_f64().unwrap();
    assert!((fx(&glitch) / fx(&clean) - 1.0).abs() <= 5e-4, "fx: {} vs {}", fx(&glitch), fx(&clean));
}

/// `detect` that completes no window fails and says why; a first event at 9.3e12 s (a
/// stray) no longer turns the rest into "back in time", and a recording that is all that
/// far on is read as it is.
#[test]
fn detect_fails_on_no_window_and_handles_far_times() {
    let dir = tempfile::tempdir().unwrap();
    let few = dir.path().join("few.txt");
    write_text(&few, Some(SensorSize::DAVIS346), &events(100, SensorSize::DAVIS346, 3)).unwrap();
    let (code, out, err) = evcal(&["detect", s(&few), "--quiet"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(out.is_empty(), "{out}");
    assert!(
        err.contains("few.txt: no detection window: 100 events read") && err.contains("fewer than one window"),
        "{err}"
    );

    let clean = events(40_000, SensorSize::DAVIS346, 5);
    let run = |name: &str, ev: &[Event]| {
        let p = dir.path().join(name);
        write_text(&p, Some(SensorSize::DAVIS346), ev).unwrap();
        let (code, out, err) = evcal(&["detect", s(&p), "--events-per-window", "500", "--step-ms", "5"]);
        assert_eq!(code, Some(0), "{name}: {err}");
        (out.lines().count(), err)
    };
    let (windows, _) = run("clean.txt", &clean);
    assert!(windows >= 70, "{windows}");
    let mut first = clean.clone();
    first.insert(0, Event { t_us: 9_300_000_000_000_000_000, x: 1, y: 1, polarity: true });
    let (w, err) = run("first.txt", &first);
    assert_eq!(w, windows, "{err}");
    assert!(
        err.contains("1 event dropped: its time was 9299999999999.") && err.contains("(a stray timestamp)"),
        "{err}"
    );
    let far: Vec<Event> = clean.iter().map(|e| Event { t_us: e.t_us + 9_300_000_000_000_000_000, ..*e }).collect();
    let (w, err) = run("far.txt", &far);
    assert_eq!(w, windows, "{err}");
    assert!(!err.contains("warning"), "{err}");
}
