//! `evcal simulate` with a fixed seed, then `evcal detect`: the detections file, byte for
//! byte, against the golden hash that the firmware's output on the same events is also
//! checked against (`tests/src/golden.rs`, `tests/tests/end_to_end/firmware_qemu.rs`).

// The golden constants live with the end-to-end tests; this package cannot depend on theirs.
#[allow(dead_code)]
#[path = "../../../tests/src/golden.rs"]
mod golden;

use std::process::Command;

fn evcal(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_evcal")).args(args).output().unwrap();
    assert!(out.status.success(), "evcal {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn detect_on_a_seeded_simulation_is_pinned() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, jsonl) = (dir.path().join("rec.txt"), dir.path().join("detections.jsonl"));
    let (rec_s, jsonl_s) = (rec.to_str().unwrap(), jsonl.to_str().unwrap());
    let (seed, seconds) = (golden::DETECT_SEED.to_string(), golden::DETECT_SECONDS.to_string());
    evcal(&["simulate", "--seed", &seed, "--seconds", &seconds, "--quiet", "-o", rec_s]);
    let step = golden::DETECT_STEP_MS.to_string();
    // The device's window, which the firmware's replay of the same events uses too.
    let events = evcal_core::config::DEFAULT_EVENTS_PER_WINDOW.to_string();
    evcal(&["detect", rec_s, "--step-ms", &step, "--events-per-window", &events, "--quiet", "-o", jsonl_s]);
    let bytes = std::fs::read(&jsonl).unwrap();
    // Not an empty or truncated file that happens to match: the windows are all there.
    assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 101, "windows in the detections file");
    golden::assert_pinned("DETECT_JSONL", "evcal detect", &bytes, golden::DETECT_JSONL);
}
