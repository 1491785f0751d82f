//! The verdict of `evcal calibrate`: a good run's console is short and ends with it, the
//! exit status and the JSON result say the same, `-v` adds the diagnostics, and `--help`
//! states the thresholds the verdict uses (issue 44, items 3 and 4).

use evcal_host::calib::{synthetic_views, Intrinsics};
use evcal_host::input::detections::{CenterRecord, WindowRecord};
use evcal_host::pipeline::{
    GOOD_CENTRE_PX, GOOD_CORNER_PX, GOOD_COVERAGE, GOOD_FOCAL_RELATIVE, GOOD_PROJECTION_PX, GOOD_RMS_PX, GOOD_VIEWS,
};
use std::path::Path;
use std::process::Command;

/// A DAVIS346-like camera with barrel distortion.
const LENS: Intrinsics =
    Intrinsics { fx: 352.4, fy: 351.1, cx: 171.3, cy: 128.6, k1: -0.31, k2: 0.12, p1: 0.0, p2: 0.0, k3: 0.0 };

/// `n` views of the 4x11 grid (24 mm) from poses spread over the sensor, 0.03 px of noise,
/// one window each 33 ms, as detections.
fn detections(path: &Path, n: usize) {
    let lines: Vec<String> = synthetic_views(&LENS, n, 0.03, 11)
        .iter()
        .enumerate()
        .map(|(seq, v)| {
            let centers = v
                .image
                .iter()
                .map(|p| CenterRecord { u: p[0] as f32, v: p[1] as f32, r: 4.0, spread: 0.3, n: 60, converged: true })
                .collect();
            let t_ref_us = 1_000_000 + 33_333 * seq as u64;
            let w =
                WindowRecord { seq: seq as u32, t_ref_us, events: 8000, noise: 10, centers, sensor: Some([346, 260]) };
            serde_json::to_string(&w).unwrap()
        })
        .collect();
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

/// `evcal calibrate` on `det` (no step that follows a motion: the views are poses at
/// random) into `out`: (status, stdout, stderr, the JSON result).
fn calibrate(det: &Path, out: &Path, extra: &[&str]) -> (Option<i32>, String, String, serde_json::Value) {
    let o = Command::new(env!("CARGO_BIN_EXE_evcal"))
        .args(["calibrate", det.to_str().unwrap(), "--pattern", "4x11", "--spacing", "0.024"])
        .args(["--no-smoothing", "--no-edge-shift", "--no-tracking", "--out", out.to_str().unwrap()])
        .args(extra)
        .output()
        .unwrap();
    let json = std::fs::read(out.join("calibration.json")).unwrap_or_default();
    let v = serde_json::from_slice(&json).unwrap_or_default();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        v,
    )
}

#[test]
fn a_good_run_says_little_and_ends_with_its_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let det = dir.path().join("det.jsonl");
    detections(&det, 40);
    let (code, out, err, json) = calibrate(&det, &dir.path().join("o"), &[]);
    assert_eq!((code, json["verdict"].as_str()), (Some(0), Some("good")), "{out}{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines.len() <= 25, "{} lines:\n{out}", lines.len());
    assert_eq!(lines.last(), Some(&"verdict: good"), "{out}");
    assert!(json["verdict_actions"].as_array().is_some_and(Vec::is_empty), "{json}");
    // One count of views on the console, as in the file.
    let used = json["views_used"].as_u64().unwrap();
    assert!(out.contains(&format!("views: {used} solved on")), "{out}");
    // The diagnostics wait for -v.
    assert!(!out.contains("σ: ") && !out.contains("|"), "{out}");
    let (code, verbose, _, _) = calibrate(&det, &dir.path().join("v"), &["-v"]);
    assert_eq!(code, Some(0));
    assert!(verbose.contains("  σ: ") && verbose.lines().count() > lines.len() + 5, "{verbose}");
    assert_eq!(verbose.lines().last(), Some("verdict: good"));
}

#[test]
fn a_usable_run_exits_4_with_its_actions_and_writes_a_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let det = dir.path().join("det.jsonl");
    // Fewer views than the verdict asks for.
    detections(&det, GOOD_VIEWS - 3);
    let out_dir = dir.path().join("o");
    let (code, out, err, json) = calibrate(&det, &out_dir, &[]);
    assert_eq!((code, json["verdict"].as_str()), (Some(4), Some("usable")), "{out}{err}");
    let last = out.lines().last().unwrap_or_default();
    assert!(last.starts_with("verdict: usable, but ") && last.contains("record more views"), "{out}");
    let actions = json["verdict_actions"].as_array().unwrap();
    assert!((1..=3).contains(&actions.len()) && last.contains(actions[0].as_str().unwrap()), "{json}");
    // A calibration, under the names a program looks for.
    assert!(out_dir.join("opencv.yaml").is_file() && !out_dir.join("opencv.failed.yaml").exists());
}

#[test]
fn help_states_the_verdicts_thresholds() {
    let o = Command::new(env!("CARGO_BIN_EXE_evcal")).args(["calibrate", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&o.stdout);
    for (what, text) in [
        ("focal length", format!("fx, fy within {} %", 100.0 * GOOD_FOCAL_RELATIVE)),
        ("principal point", format!("cx, cy within {GOOD_CENTRE_PX} px")),
        ("distortion", format!("corner by over {GOOD_CORNER_PX} px")),
        ("projection", format!("projection σ within {GOOD_PROJECTION_PX} px over 95 %")),
        ("coverage", format!("at least {:.0} % of the sensor", 100.0 * GOOD_COVERAGE)),
        ("views", format!("{GOOD_VIEWS} views")),
        ("residuals", format!("within {GOOD_RMS_PX} px")),
    ] {
        let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(flat.contains(&text), "--help does not state the {what} threshold ({text}):\n{help}");
    }
    for status in ["verdict: good (0)", "verdict: usable, but ... (4)", "verdict: not a calibration (3)"] {
        assert!(help.split_whitespace().collect::<Vec<_>>().join(" ").contains(status), "{status}:\n{help}");
    }
}
