//! The firmware on the emulated boards (QEMU mps2-an386, Cortex-M4F; mps2-an500, Cortex-M7),
//! against the host.
//!
//! These boot the real firmware image, so they need `qemu-system-arm` (scripts/setup.sh
//! installs it) and the `thumbv7em-none-eabihf` target; they build the image themselves.
//! Ignored by a plain `cargo test`; scripts/test.sh runs them:
//! `cargo test -p evcal-tests --test end_to_end -- --ignored firmware_qemu::`.

use evcal_core::{
    detect::DetectConfig,
    event::{Event, SensorSize},
};
use evcal_host::{
    eval::{simulate, simulate_windows},
    sim::{Light, SimConfig, Trajectory},
};
use evcal_tests::{
    firmware::{self, Counter, Emulated},
    golden,
    link::{self, Damage, Qemu, Tamper},
};
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

/// A simulated DAVIS346 recording (4x11 grid, cone, good light) and the detector's
/// configuration for it, windows of 4000 events every `step_us`.
fn recording(seed: u64, seconds: f64, step_us: u64) -> (Vec<Event>, DetectConfig) {
    let sim = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, seed).unwrap();
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    let (events, _) = simulate(sim, seconds);
    let mut cfg = DetectConfig::new(sensor);
    cfg.window.step_us = step_us;
    // As `evcal replay` asks a device: filled discs fitted too, so that the device runs that
    // path and must give the host's bits on it.
    cfg.fit.filled_discs = true;
    (events, cfg)
}

fn scratch(name: &str) -> PathBuf {
    let d = firmware::target_dir().join("qemu-tests");
    std::fs::create_dir_all(&d).expect("scratch directory");
    d.join(name)
}

/// More than 100 windows of 4000 events of a simulated DAVIS346 recording, replayed from the
/// emulator-only bulk source: every window the device computes equals the host's, bit for
/// bit, and no event goes missing; the device's windows hash to the golden constant.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn bulk_replay_equals_the_host_core_bit_for_bit() {
    let elf = elf();
    let sim = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, golden::BENCH_SEED).unwrap();
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    let (events, _) = simulate(sim, golden::BENCH_SECONDS);
    let bulk = scratch("bulk-replay.bin");
    firmware::write_bulk(&bulk, sensor, &events).unwrap();
    // Ticks every 5 ms: a window of 4000 events spans about 4.3 ms here, so the windower also
    // skips events between windows, as it does at the paper's 33 ms.
    let step_us = golden::BENCH_STEP_US;
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
    let (ram, stack) = (run.num("static_ram").unwrap(), run.num("stack_peak").unwrap());
    eprintln!("RAM: static {ram} B, stack peak {stack} B");
    // The statics in the SRAM, the stack in the CCM (firmware/boards/*.x).
    assert!(ram <= 128 * 1024 && stack < 64 * 1024, "RAM budget: static {ram} B, stack {stack} B");
    let lines: String = run.windows.iter().map(|w| w.without_times().line()).collect();
    golden::assert_pinned("BENCH_LINES", "the firmware's bench lines", lines.as_bytes(), golden::BENCH_LINES);
}

/// The firmware benchmark's scenario (`scripts/bench-firmware.sh`: 3.5 s of a DAVIS346,
/// 4x11 grid, cone, good light, seed 11; windows of 4000 events every 33.333 ms) with the
/// instructions of each window counted exactly (`-icount shift=0` and the counting plugin):
/// every window within the Cortex-M4F's budget, every window the host's bit for bit.
///
/// Simulated window by window (`eval::simulate_windows`, as `evcal demo` does), to keep CI
/// short: 24 s for this test where the benchmark's continuous simulation took 143 s on 2
/// loaded cores. So its windows are not the benchmark's bit for bit, but cut at the same
/// ticks from the same motion and scene (measured: mean 3.80 M, max 4.26 M instructions per
/// window; the benchmark's: 3.79 M, 4.33 M).
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn benchmark_windows_are_within_the_instruction_budget() {
    let elf = elf();
    let plugin = firmware::build_counter_plugin().expect("the instruction-counting plugin");
    let sim = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, 11).unwrap();
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    let step_us = 33_333;
    let mut cfg = DetectConfig::new(sensor);
    cfg.window.step_us = step_us;
    let (events, _) = simulate_windows(sim, 3.5, cfg.window, |_| {});
    let bulk = scratch("bench.bin");
    firmware::write_bulk(&bulk, sensor, &events).unwrap();
    let want = firmware::host_windows(&events, cfg);
    assert!(want.len() >= 100, "the recording has {} windows", want.len());

    let t = Instant::now();
    let counter = Counter { plugin: &plugin, profile: false };
    let run = firmware::run_bench(&elf, &bulk, 4000, step_us, Some(counter)).expect("firmware run");
    eprintln!("{} windows counted in QEMU in {:.1} s", run.windows.len(), t.elapsed().as_secs_f64());
    assert_eq!(run.windows.len(), want.len(), "windows");
    for (d, h) in run.windows.iter().zip(&want) {
        assert_eq!(d.without_times(), *h, "window {}", h.seq);
    }
    assert_eq!(run.instructions.len(), run.windows.len(), "one counted span per window");
    let budget = firmware::M4F_INSTRUCTIONS_PER_WINDOW;
    let over: Vec<(u32, u64)> =
        run.windows.iter().zip(&run.instructions).filter(|(_, &n)| n > budget).map(|(w, &n)| (w.seq, n)).collect();
    let max = run.instructions.iter().max().copied().unwrap_or(0);
    let mean = run.instructions.iter().sum::<u64>() as f64 / run.instructions.len() as f64;
    eprintln!(
        "instructions per window: mean {:.3} M, max {:.3} M, budget {:.3} M",
        mean / 1e6,
        max as f64 / 1e6,
        budget as f64 / 1e6
    );
    assert!(
        over.is_empty(),
        "{} of {} windows exceed the Cortex-M4F's {budget} instructions (window, instructions): {over:?}; \
         bash scripts/bench-firmware.sh --profile 20 shows where they go",
        over.len(),
        run.windows.len()
    );
}

/// The Cortex-M7 runs a GenX320's and a DVXplorer's windows within its budget (the host's
/// 8500 events on 320x320, 15 000 on 640x480): a simulated cone in good light, windows every
/// 33.3 ms, every window's instructions counted by the plugin, every window the host's bit
/// for bit, none beyond 16.0 M (480 MHz at one cycle an instruction). Measured with `bash
/// scripts/bench-firmware.sh --board m7 --sensor genx320|dvxplorer` over 2 s: GenX320 mean
/// 6.33 M, max 6.86 M; DVXplorer mean 11.4 M, max 12.3 M.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn m7_runs_a_genx320_and_a_dvxplorer_within_the_instruction_budget() {
    if let Some(why) = firmware::qemu_missing() {
        panic!("{why}");
    }
    let elf = firmware::build_firmware_for(Emulated::M7).expect("build the Cortex-M7 firmware");
    let plugin = firmware::build_counter_plugin().expect("the instruction-counting plugin");
    for (preset, events_per_window, seconds) in [("genx320", 8500, 1.0), ("dvxplorer", 15_000, 0.5)] {
        let sim = SimConfig::preset(preset, "4x11", Trajectory::Cone, Light::Good, 11).unwrap();
        let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
        let mut cfg = evcal_host::input::detections::host_config(sensor);
        assert_eq!(cfg.window.events, events_per_window, "the host's window on {preset}");
        cfg.window.step_us = 33_333;
        let (events, _) = simulate_windows(sim, seconds, cfg.window, |_| {});
        let bulk = scratch(&format!("m7-bench-{preset}.bin"));
        firmware::write_bulk(&bulk, sensor, &events).unwrap();
        let want = firmware::host_windows(&events, cfg);
        assert!(want.len() >= 12, "{preset}: the recording has {} windows", want.len());
        let counter = Counter { plugin: &plugin, profile: false };
        let run = firmware::run_bench(&elf, &bulk, cfg.window.events, cfg.window.step_us, Some(counter))
            .expect("firmware run");
        assert_eq!(run.windows.len(), want.len(), "{preset}: windows");
        for (d, h) in run.windows.iter().zip(&want) {
            assert_eq!(d.without_times(), *h, "{preset}: window {}", h.seq);
        }
        assert_eq!(run.instructions.len(), run.windows.len(), "one counted span per window");
        let budget = firmware::M7_INSTRUCTIONS_PER_WINDOW;
        let max = run.instructions.iter().max().copied().unwrap_or(0);
        eprintln!("Cortex-M7, {preset}: {} windows, max {:.3} M instructions", run.windows.len(), max as f64 / 1e6);
        assert!(max <= budget, "{preset}: a window takes {max} instructions, beyond the Cortex-M7's {budget}");
    }
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

/// The emulated board's sensor bus (its bit-banged I2C driver behind embedded-hal's `I2c`):
/// the sensor's bring-up finds exactly the devices QEMU puts on the bus (two of QEMU's own
/// I2C models, standing in for a sensor: any device that acknowledges its address), and none
/// on an empty bus.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn sensor_bus_scan_finds_the_devices_on_the_emulated_bus() {
    let elf = elf();
    let devices: [&[&str]; 2] = [&[], &["-device", "tmp105,address=0x48", "-device", "at24c-eeprom,address=0x50"]];
    for (args, says) in devices.into_iter().zip(["sensor bus: none\n", "sensor bus: 0x48 0x50\n"]) {
        let out = Command::new("bash")
            .arg(firmware::workspace_root().join("scripts/qemu-run.sh"))
            .arg(&elf)
            .args(["-append", "sensor"])
            .args(args)
            .env("EVCAL_QEMU_TIMEOUT", "60")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        assert_eq!(String::from_utf8_lossy(&out.stdout), says, "{args:?}: {err}");
    }
}

/// More than 100 windows of 4000 events replayed through the emulated UART as the wire
/// protocol's event batches (flow-controlled by the device's acknowledgements): the
/// detection frames the device sends are byte for byte the frames the host's run of the core
/// encodes, none is missing, and the device counted every event; written as `evcal replay`
/// writes them, they are the bytes of `evcal detect`'s golden hash.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn uart_replay_equals_the_host_core_byte_for_byte() {
    let elf = elf();
    // Back-to-back windows (step 0): every event sent is used, so the UART carries the
    // least for 100 windows.
    let (events, cfg) = recording(golden::DETECT_SEED, golden::DETECT_SECONDS, golden::DETECT_STEP_MS * 1000);
    let want = link::expected_frames(&events, cfg).unwrap();
    assert!(want.len() >= 100, "{} windows", want.len());

    let t = Instant::now();
    let mut qemu = Qemu::boot(&elf, None, 600).unwrap();
    let got = link::replay(&mut qemu, cfg, &events, Tamper::default(), Duration::from_secs(500)).unwrap();
    let secs = t.elapsed().as_secs_f64();
    eprintln!(
        "UART replay: {} events, {} windows in {secs:.1} s; {} bytes to the device ({:.2} per event, {:.1} KB/s), \
         {} bytes back ({:.0} per window, detections {:.0} per window)",
        events.len(),
        got.detections.len(),
        got.bytes_out,
        got.bytes_out as f64 / events.len() as f64,
        got.bytes_out as f64 / secs / 1e3,
        got.bytes_in,
        got.bytes_in as f64 / want.len() as f64,
        got.detection_bytes as f64 / want.len() as f64,
    );
    assert_eq!(got.detections.len(), want.len(), "windows received");
    for ((s, f), (ws, wf)) in got.detections.iter().zip(&want) {
        assert_eq!(s, ws);
        assert!(f == wf, "window {s}: device frame differs from the host's");
    }
    assert_eq!(got.bad_frames, 0);
    let st = got.final_stats.unwrap();
    assert_eq!(st.events_received, events.len() as u64, "every event reached the device");
    assert_eq!(st.windows as usize, want.len());
    assert_eq!((st.frames_bad, st.frames_discarded, st.rx_overrun), (0, 0, 0));
    // The detections file `evcal replay` would write: the bytes `evcal detect` writes.
    golden::assert_pinned("DETECT_JSONL", "the firmware's detections", got.jsonl.as_bytes(), golden::DETECT_JSONL);
}

/// Damage on the link, both ways. Device to host: three detection frames get a flipped bit,
/// a lost byte and a stray byte; exactly those three windows are missing, every other frame
/// arrives intact, the host's reader counts three bad frames, and the gaps in the window
/// numbers show which were lost. Host to device: three event batches are damaged the same
/// ways on their first transmission; the device drops and reports them (and discards the
/// frames that follow until the repeat), asks for them again, and the replay stays lossless.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn damaged_frames_cost_only_themselves_and_are_reported() {
    let elf = elf();
    let (events, cfg) = recording(8, 0.06, 0);
    let want = link::expected_frames(&events, cfg).unwrap();
    assert!(want.len() >= 12, "{} windows", want.len());
    let tamper = Tamper {
        detections: vec![(2, Damage::FlipBit), (5, Damage::DropByte), (9, Damage::InsertByte)],
        batches: vec![(3, Damage::FlipBit), (40, Damage::DropByte), (41, Damage::InsertByte)],
    };
    let mut qemu = Qemu::boot(&elf, None, 300).unwrap();
    let got = link::replay(&mut qemu, cfg, &events, tamper, Duration::from_secs(240)).unwrap();

    let lost: std::collections::BTreeSet<u32> = [2, 5, 9].into();
    assert_eq!(got.gaps(), lost, "exactly the damaged windows are missing");
    assert_eq!(got.bad_frames, 3, "the host's reader reports each damaged frame");
    let kept: Vec<_> = want.iter().filter(|(s, _)| !lost.contains(s)).collect();
    assert_eq!(got.detections.len(), kept.len());
    for ((s, f), (ws, wf)) in got.detections.iter().zip(kept) {
        assert_eq!(s, ws);
        assert!(f == wf, "window {s}: device frame differs from the host's");
    }
    let st = got.final_stats.unwrap();
    assert_eq!(st.frames_bad, 3, "the device reports each damaged batch");
    assert!(st.frames_discarded >= 1, "frames after a damaged one are discarded until the repeat");
    assert_eq!(st.events_received, events.len() as u64, "the replay itself lost nothing");
    assert_eq!(st.windows as usize, want.len());
}

/// The protocol with the emulator's bulk source, in the host's own windows: the device boots
/// with the configuration `evcal detect` runs on its sensor (8000 events a window on a
/// DAVIS346), the host configures a session with it over the UART, the events come from a
/// file (windows every 10 ms, so the windower also skips the events between windows, as at
/// the paper's 33 ms), the detection frames come back over the UART, byte for byte the
/// host's.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn bulk_source_through_the_protocol_equals_the_host_core() {
    let elf = elf();
    let (events, paper) = recording(9, 1.4, 10_000);
    let mut cfg = evcal_host::input::detections::host_config(paper.sensor);
    cfg.window.step_us = paper.window.step_us;
    assert_eq!(cfg.window.events, 8000, "the host's window on a DAVIS346");
    let (boot, windows) = bulk_replay_through_the_protocol(&elf, &events, cfg, "protocol-replay.bin");
    assert!(windows >= 100, "{windows} windows");
    let host = evcal_host::input::detections::host_config(cfg.sensor);
    assert_eq!(boot.config, host, "the device boots with what `evcal detect` runs");
    assert!(boot.max_events as usize >= host.window.events, "the device holds the host's window: {boot:?}");
}

/// Replays `events` from a bulk file (`name` in the scratch folder) into the image `elf`
/// through the protocol with `cfg`, and checks that every detection frame is the host's byte
/// for byte and that the device counted every event. Returns the device's boot Hello and the
/// windows.
fn bulk_replay_through_the_protocol(
    elf: &std::path::Path,
    events: &[Event],
    cfg: DetectConfig,
    name: &str,
) -> (evcal_core::wire::Hello, usize) {
    let want = link::expected_frames(events, cfg).unwrap();
    let bulk = scratch(name);
    firmware::write_bulk(&bulk, cfg.sensor, events).unwrap();
    let t = Instant::now();
    let append = format!("replay {}", bulk.display());
    let mut qemu = Qemu::boot(elf, Some(&append), 300).unwrap();
    let got = link::replay(&mut qemu, cfg, &[], Tamper::default(), Duration::from_secs(240)).unwrap();
    eprintln!(
        "bulk source ({}): {} events, {} windows in {:.1} s",
        elf.display(),
        events.len(),
        got.detections.len(),
        t.elapsed().as_secs_f64()
    );
    assert_eq!(got.detections.len(), want.len(), "windows received");
    for ((s, f), (ws, wf)) in got.detections.iter().zip(&want) {
        assert_eq!(s, ws);
        assert!(f == wf, "window {s}: device frame differs from the host's");
    }
    let st = got.final_stats.unwrap();
    assert_eq!(st.events_received, events.len() as u64);
    assert_eq!(st.windows as usize, want.len());
    assert_eq!(st.frames_bad, 0);
    (*got.hellos.first().expect("the device's boot Hello"), want.len())
}

/// Events at the sensor's pace (`-append "bench FILE EVENTS STEP paced 168 125"`: a simulated
/// DAVIS346 at its 1.1 M events/s, arriving on the clock of a 168 MHz Cortex-M4F through the
/// firmware's 256-event FIFO): the device cannot take in every event while it works on a
/// window, so it loses some, counts every one, and keeps them out of every window: each
/// window it makes is the host's on the events it kept, told of each loss in its place.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn events_lost_at_the_sensors_pace_are_counted_and_outside_every_window() {
    let elf = elf();
    let (events, paper) = recording(12, 0.6, 33_333);
    let mut cfg = evcal_host::input::detections::host_config(paper.sensor);
    cfg.window.step_us = paper.window.step_us;
    let bulk = scratch("paced.bin");
    firmware::write_bulk(&bulk, cfg.sensor, &events).unwrap();
    let run = firmware::run_bench_paced(&elf, &bulk, cfg.window.events, cfg.window.step_us, (168.0, 1.25), None)
        .expect("firmware run");
    let count = |k: &str| run.paced.iter().find(|(n, _)| n == k).map(|(_, v)| *v).unwrap();
    let (arrived, lost) = (count("arrived"), count("lost"));
    assert_eq!(arrived, events.len() as u64, "every event arrived");
    assert!(lost > 0 && !run.losses.is_empty(), "the device loses events at this pace: {:?}", run.paced);
    assert_eq!(run.losses.iter().map(|(_, n)| n).sum::<u64>(), lost, "every loss told");
    assert_eq!(run.num("events").unwrap() + lost, arrived, "every event kept or counted lost");
    let want = firmware::host_windows_after_losses(&events, cfg, &run.losses);
    assert!(!want.is_empty(), "windows are made between the losses");
    assert_eq!(run.windows.len(), want.len(), "windows");
    for (d, h) in run.windows.iter().zip(&want) {
        assert_eq!(d.without_times(), *h, "window {}", h.seq);
    }
    // Fewer windows than the host makes of every event: the ones a loss fell in are dropped.
    assert!(want.len() < firmware::host_windows(&events, cfg).len());
}

/// Filled discs on the device: a DVXplorer in dim light with a 300 Hz photoreceptor, whose
/// dark circles fill with their slow pixels' events (`FitConfig::filled_discs`), replayed
/// from a file through the protocol with the flag asked for: every frame the host's, byte
/// for byte, on windows where the disc's fit found circles the ring's did not.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn filled_discs_on_the_device_equal_the_host_core() {
    let elf = elf();
    let mut sim = SimConfig::preset("dvxplorer", "4x11", Trajectory::Cone, Light::Low, 5).unwrap();
    sim.pixel = evcal_host::sim::PixelModel::physical(Light::Low, 300.0);
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    let (events, _) = simulate(sim, 0.25);
    let mut cfg = DetectConfig::new(sensor);
    cfg.window.step_us = 0;
    let rings = link::expected_frames(&events, cfg).unwrap();
    cfg.fit.filled_discs = true;
    let want = link::expected_frames(&events, cfg).unwrap();
    assert!(want.len() >= 40, "{} windows", want.len());
    let changed = want.iter().zip(&rings).filter(|(a, b)| a.1 != b.1).count();
    assert!(changed * 2 >= want.len(), "discs found in only {changed} of {} windows", want.len());
    let bulk = scratch("filled-discs.bin");
    firmware::write_bulk(&bulk, sensor, &events).unwrap();

    let append = format!("replay {}", bulk.display());
    let mut qemu = Qemu::boot(&elf, Some(&append), 300).unwrap();
    let got = link::replay(&mut qemu, cfg, &[], Tamper::default(), Duration::from_secs(240)).unwrap();
    assert_eq!(got.detections.len(), want.len(), "windows received");
    for ((s, f), (ws, wf)) in got.detections.iter().zip(&want) {
        assert_eq!(s, ws);
        assert!(f == wf, "window {s}: device frame differs from the host's");
    }
}

/// The emulated Cortex-M7 (QEMU mps2-an500, memory capped to an STM32H743's) in the host's
/// window for a 640x480 sensor: a short simulated DVXplorer recording (4x11 grid, cone, good
/// light) from the bulk source through the protocol, the session configured with what
/// `evcal detect` runs on that sensor (15 000 events a window, more than a Cortex-M4F board
/// holds); every detection frame is the host's, byte for byte.
#[test]
#[ignore = "boots the firmware in QEMU; scripts/test.sh runs it"]
fn m7_runs_a_640x480_sensor_in_the_hosts_window_equal_to_the_host_core() {
    if let Some(why) = firmware::qemu_missing() {
        panic!("{why}");
    }
    let elf = firmware::build_firmware_for(Emulated::M7).expect("build the Cortex-M7 firmware");
    let sim = SimConfig::preset("dvxplorer", "4x11", Trajectory::Cone, Light::Good, 12).unwrap();
    let sensor = SensorSize { width: sim.camera.width, height: sim.camera.height };
    let (events, _) = simulate(sim, 0.3);
    let mut cfg = evcal_host::input::detections::host_config(sensor);
    // Windows every 10 ms: a window of 15 000 events spans less, so the windower also skips
    // the events between windows, as it does at the paper's 33 ms.
    cfg.window.step_us = 10_000;
    assert_eq!(cfg.window.events, 15_000, "the host's window on a 640x480 sensor");
    assert!(cfg.window.events > Emulated::M4f.capacity(), "a window no Cortex-M4F board holds");
    let (boot, windows) = bulk_replay_through_the_protocol(&elf, &events, cfg, "m7-protocol-replay.bin");
    assert!(windows >= 20, "{windows} windows");
    assert_eq!(boot.max_events as usize, Emulated::M7.capacity(), "the M7's capacity: {boot:?}");
}
