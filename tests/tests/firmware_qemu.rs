//! The firmware on the emulated board (QEMU mps2-an386, Cortex-M4F), against the host.
//!
//! These boot the real firmware image, so they need `qemu-system-arm` (scripts/setup.sh
//! installs it) and the `thumbv7em-none-eabihf` target; they build the image themselves.
//! Ignored by a plain `cargo test`; scripts/test.sh runs them:
//! `cargo test -p evcal-tests --test firmware_qemu -- --ignored`.

use evcal_core::{detect::DetectConfig, event::SensorSize};
use evcal_host::{
    eval::simulate,
    sim::{Light, SimConfig, Trajectory},
};
use evcal_tests::firmware;
use std::{
    path::PathBuf,
    process::Command,
    time::{Duration, Instant},
};

fn elf() -> PathBuf {
    if let Some(why) = firmware::qemu_missing() {
        panic!("{why}");
    }
    firmware::build_firmware().expect("build the firmware")
}

fn scratch(name: &str) -> PathBuf {
    let d = firmware::target_dir().join("qemu-tests");
    std::fs::create_dir_all(&d).expect("scratch directory");
    d.join(name)
}

/// More than 100 windows of 4000 events of a simulated DAVIS346 recording, replayed from the
/// emulator-only bulk source: every window the device computes equals the host's, bit for
/// bit, and no event goes missing.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn bulk_replay_equals_the_host_core_bit_for_bit() {
    let elf = elf();
    let sim = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, 5).unwrap();
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    let (events, _) = simulate(sim, 0.55);
    let bulk = scratch("bulk-replay.bin");
    firmware::write_bulk(&bulk, sensor, &events).unwrap();
    // Ticks every 5 ms: a window of 4000 events spans about 4.3 ms here, so the windower also
    // skips events between windows, as it does at the paper's 33 ms.
    let step_us = 5_000;
    let mut cfg = DetectConfig::new(sensor);
    cfg.window.step_us = step_us;
    let want = firmware::host_windows(&events, cfg);
    assert!(want.len() >= 100, "the recording has {} windows", want.len());
    assert!(want.iter().map(|w| w.centres.len()).sum::<usize>() > 30 * want.len(), "the windows have centres");

    let t = Instant::now();
    let run = firmware::run_bench(&elf, &bulk, 4000, step_us, None).expect("firmware run");
    eprintln!("{} windows, {} events in QEMU in {:.1} s", run.windows.len(), events.len(), t.elapsed().as_secs_f64());
    assert_eq!(run.windows.len(), want.len(), "windows");
    for (d, h) in run.windows.iter().zip(&want) {
        assert_eq!(d.without_times(), *h, "window {}", h.seq);
        assert!(d.cluster_ticks > 0 && d.fit_ticks > 0, "stages timed by SysTick: {d:?}");
    }
    assert_eq!(run.num("events").unwrap(), events.len() as u64, "every event reached the detector");
    assert_eq!(run.get("end"), Some("End"));
    assert_eq!((run.num("out_of_sensor").unwrap(), run.num("time_backwards").unwrap()), (0, 0));
    assert!(run.num("static_ram").unwrap() + run.num("stack_peak").unwrap() < 128 * 1024, "RAM budget");
}

/// A fault or a panic ends QEMU with a failure status and a message, promptly: a broken
/// firmware can never hang CI.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn faults_and_panics_exit_qemu_with_failure() {
    let elf = elf();
    for (mode, says) in [("fault", "HardFault"), ("panic", "panicked"), ("bench /nonexistent/file", "cannot open")] {
        let t = Instant::now();
        let out = Command::new("bash")
            .arg(firmware::workspace_root().join("scripts/qemu-run.sh"))
            .arg(&elf)
            .args(["-append", mode])
            .env("EVCAL_QEMU_TIMEOUT", "60")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{mode}: {err}");
        assert!(err.contains(says), "{mode}: {err}");
        assert!(t.elapsed() < Duration::from_secs(30), "{mode} took {:?}", t.elapsed());
    }
}
