//! `evcal ... | head`: when standard output's reader has gone, every command that prints
//! ends quietly with status 0 (no panic from a failed print, no error message), and
//! `calibrate` still writes its files.
//!
//! The pipe's reading end is closed before the command starts, so every write it makes
//! fails with a broken pipe: the outcome does not depend on how fast the reader is.

use evcal_core::{
    event::{Event, SensorSize},
    evt::Encoding,
};
use evcal_host::input::recording::{prophesee::write::write_raw, write_text};
use std::{
    path::Path,
    process::{Command, Stdio},
};

/// Runs `evcal` with standard output a pipe nobody reads from.
fn run_into_closed_pipe(args: &[&str]) -> std::process::Output {
    // The pipe's reading end belongs to a process that has exited (`evcal --version`, which
    // reads nothing): `std::io::pipe` would be shorter but is newer than the MSRV.
    let mut gone = Command::new(env!("CARGO_BIN_EXE_evcal"))
        .arg("--version")
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let writer = gone.stdin.take().unwrap();
    assert!(gone.wait().unwrap().success());
    Command::new(env!("CARGO_BIN_EXE_evcal")).args(args).stdout(Stdio::from(writer)).output().unwrap()
}

fn assert_quiet_success(args: &[&str]) {
    let out = run_into_closed_pipe(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "evcal {args:?} panicked:\n{err}");
    assert!(!err.to_lowercase().contains("broken pipe"), "evcal {args:?}:\n{err}");
    assert!(!err.contains("error"), "evcal {args:?}:\n{err}");
    assert_eq!(out.status.code(), Some(0), "evcal {args:?}:\n{err}");
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn info_and_detect_end_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("rec.raw");
    let events: Vec<Event> = (0..5000u64)
        .map(|i| Event { t_us: i * 400, x: (i % 640) as u16, y: (i % 480) as u16, polarity: i % 4 == 0 })
        .collect();
    write_raw(&raw, Encoding::Evt3, SensorSize::new(640, 480), &events).unwrap();
    assert_quiet_success(&["info", s(&raw)]);
    assert_quiet_success(&["info", "--json", s(&raw)]);

    // Enough events for several windows, each printed as a line.
    let txt = dir.path().join("rec.txt");
    let events: Vec<Event> = (0..20_000u64)
        .map(|i| Event { t_us: i * 20, x: (i * 7 % 346) as u16, y: (i * 13 % 260) as u16, polarity: i % 2 == 0 })
        .collect();
    write_text(&txt, Some(SensorSize::new(346, 260)), &events).unwrap();
    assert_quiet_success(&["detect", s(&txt)]);
    assert_quiet_success(&["detect", "-q", s(&txt)]);
}

#[test]
fn a_damaged_recording_is_still_an_error() {
    // A closed standard output must not hide a real failure.
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("rec.raw");
    let events: Vec<Event> =
        (0..5000u64).map(|i| Event { t_us: i * 400, x: (i % 640) as u16, y: 3, polarity: true }).collect();
    write_raw(&raw, Encoding::Evt3, SensorSize::new(640, 480), &events).unwrap();
    let bytes = std::fs::read(&raw).unwrap();
    std::fs::write(&raw, &bytes[..bytes.len() - 1]).unwrap();
    let out = run_into_closed_pipe(&["info", s(&raw)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("ends inside an EVT 3.0 word"), "{err}");
}

#[test]
fn calibrate_writes_its_files_and_ends_quietly() {
    // Detections as a perfect detector would give them: the true circle centres of a
    // simulated sweep (no event simulation needed).
    let dir = tempfile::tempdir().unwrap();
    let det = dir.path().join("detections.jsonl");
    std::fs::write(&det, crate::true_centre_detections()).unwrap();
    let out_dir = dir.path().join("out");
    assert_quiet_success(&[
        "calibrate",
        s(&det),
        "--sensor",
        "davis346",
        "--pattern",
        "4x11",
        "--spacing",
        "0.024",
        "--out",
        s(&out_dir),
        "-q",
    ]);
    for f in ["calibration.json", "opencv.yaml", "camera_info.yaml", "kalibr_camchain.yaml", "report.png"] {
        assert!(out_dir.join(f).is_file(), "{f} not written");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("calibration.json")).unwrap()).unwrap();
    assert!((v["fx"].as_f64().unwrap() - 355.2).abs() < 1.0, "{}", v["fx"]);
}
