//! The host's run of the core on seeded simulations against the golden hashes that the
//! firmware's output under QEMU is also checked against (`tests/tests/end_to_end/firmware_qemu.rs`;
//! `evcal detect` itself: `host-tools/tests/cli/golden_detect.rs`). See `tests/src/golden.rs`.

use evcal_core::{detect::DetectConfig, event::SensorSize};
use evcal_host::{
    eval::simulate,
    input::detections::{self, WindowRecord},
    sim::{Light, SimConfig, Trajectory},
};
use evcal_tests::{firmware, golden};

fn simulation(seed: u64, seconds: f64) -> (Vec<evcal_core::event::Event>, SensorSize) {
    let sim = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, seed).unwrap();
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    (simulate(sim, seconds).0, sensor)
}

/// The library's path to `evcal detect`'s output (the core over simulated events, JSON
/// lines) gives the bytes the CLI gives from its text recording.
#[test]
fn detections_of_the_seeded_simulation_are_pinned() {
    let (events, sensor) = simulation(golden::DETECT_SEED, golden::DETECT_SECONDS);
    // The device's window (the host's default is longer): the same bytes the firmware's
    // replay writes.
    let mut cfg = detections::host_config(sensor);
    cfg.window.events = evcal_core::config::DEFAULT_EVENTS_PER_WINDOW;
    cfg.window.step_us = golden::DETECT_STEP_MS * 1000;
    let mut jsonl = String::new();
    let summary = detections::run(events.into_iter().map(Ok), cfg, |d| {
        jsonl.push_str(&WindowRecord::from_detection(d).with_sensor(sensor).to_json_line());
        jsonl.push('\n');
    })
    .unwrap();
    assert_eq!(summary.windows, 101, "windows");
    golden::assert_pinned("DETECT_JSONL", "the host's core, as JSON lines", jsonl.as_bytes(), golden::DETECT_JSONL);
}

/// The host's run of the core written as the firmware's benchmark mode writes its windows.
#[test]
fn bench_lines_of_the_seeded_simulation_are_pinned() {
    let (events, sensor) = simulation(golden::BENCH_SEED, golden::BENCH_SECONDS);
    let mut cfg = DetectConfig::new(sensor);
    cfg.window.step_us = golden::BENCH_STEP_US;
    let windows = firmware::host_windows(&events, cfg);
    assert!(windows.len() >= 100, "{} windows", windows.len());
    let lines: String = windows.iter().map(firmware::BenchWindow::line).collect();
    golden::assert_pinned("BENCH_LINES", "the host's core, as bench lines", lines.as_bytes(), golden::BENCH_LINES);
}
