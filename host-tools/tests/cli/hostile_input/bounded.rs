//! Far-off times and crowded windows end within seconds; square pixels held exactly (issue 46,
//! items 2 and 5).

use super::*;

/// Runs evcal for at most `seconds`: (exit code, stdout, stderr). One still running then is
/// killed and the test fails, naming it: a hang must not hold CI up.
fn evcal_within(seconds: f64, args: &[&str]) -> (Option<i32>, String, String) {
    use std::io::Read;
    let mut child = evcal_command().args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = Vec::new();
            let _ = r.read_to_end(&mut s);
            String::from_utf8_lossy(&s).into_owned()
        })
    };
    let out = drain(Box::new(child.stdout.take().unwrap()));
    let err = drain(Box::new(child.stderr.take().unwrap()));
    let started = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return (status.code(), out.join().unwrap(), err.join().unwrap());
        }
        if started.elapsed().as_secs_f64() > seconds {
            let _ = child.kill();
            let _ = child.wait();
            panic!("evcal {args:?} still ran after {seconds} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// The camera of the synthetic detections (a DAVIS346's, with barrel distortion).
const TRUTH: evcal_host::calib::Intrinsics = evcal_host::calib::Intrinsics {
    fx: 352.4,
    fy: 351.1,
    cx: 171.3,
    cy: 128.6,
    k1: -0.31,
    k2: 0.12,
    p1: 0.0,
    p2: 0.0,
    k3: 0.0,
};

/// Writes `n` synthetic views of the 4x11 grid (24 mm) seen by `truth`, one window each 33 ms
/// from 1 s on, then the first views again at the times `far` (µs).
fn synthetic_detections(path: &Path, truth: &evcal_host::calib::Intrinsics, n: usize, far: &[u64]) {
    use evcal_host::input::detections::{CenterRecord, WindowRecord};
    let views = evcal_host::calib::synthetic_views(truth, n, 0.05, 46);
    let times = (0..n as u64).map(|k| 1_000_000 + 33_333 * k).chain(far.iter().copied());
    let lines: Vec<String> = times
        .zip(views.iter().cycle())
        .enumerate()
        .map(|(seq, (t_ref_us, v))| {
            let centers = v
                .image
                .iter()
                .map(|p| CenterRecord { u: p[0] as f32, v: p[1] as f32, r: 4.0, spread: 0.3, n: 60, converged: true })
                .collect();
            let w = WindowRecord { seq: seq as u32, t_ref_us, events: 4000, noise: 10, centers, sensor: None };
            serde_json::to_string(&w).unwrap()
        })
        .collect();
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

/// What `calibrate` takes for the synthetic detections: the views are poses at random, not a
/// motion, so nothing that follows the motion.
fn calibrate_synthetic(det: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = [
        "calibrate",
        s(det),
        "--sensor",
        "346x260",
        "--pattern",
        "4x11",
        "--spacing",
        "0.024",
        "--no-smoothing",
        "--no-edge-shift",
        "--no-tracking",
        "--out",
        s(out),
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    args.extend(extra.iter().map(|a| a.to_string()));
    args
}

#[test]
fn far_off_window_times_end_within_seconds() {
    let dir = tempfile::tempdir().unwrap();
    let truth = TRUTH;
    // 1e14 µs is three years on; 2^63 µs 292 000 years (the walk over stretches took forever).
    for far in [[100_000_000_000_000, 100_000_000_033_333], [1 << 63, (1 << 63) + 33_333]] {
        let det = dir.path().join("far.jsonl");
        synthetic_detections(&det, &truth, 40, &far);
        // -v: how σ was computed, which walks the stretches of time.
        let args = calibrate_synthetic(&det, &dir.path().join("o"), &["-v"]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, out, err) = evcal_within(30.0, &args);
        assert!(matches!(code, Some(0 | 4)), "{far:?}: {out}{err}");
        assert!(out.contains("σ: the larger of each point's own and the scatter of"), "{far:?}: {out}");
    }
}

#[test]
fn a_fixed_aspect_ratio_is_one_in_the_result() {
    let dir = tempfile::tempdir().unwrap();
    let truth = evcal_host::calib::Intrinsics {
        fx: 352.4,
        fy: 352.4,
        cx: 171.3,
        cy: 128.6,
        k1: -0.31,
        k2: 0.12,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
    };
    let det = dir.path().join("square.jsonl");
    synthetic_detections(&det, &truth, 30, &[]);
    let out = dir.path().join("o");
    let args = calibrate_synthetic(&det, &out, &["--fix-aspect-ratio"]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let (code, stdout, err) = evcal_within(60.0, &args);
    assert_eq!(code, Some(0), "{stdout}{err}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("calibration.json")).unwrap()).unwrap();
    let (fx, fy) = (v["fx"].as_f64().unwrap(), v["fy"].as_f64().unwrap());
    assert_eq!(fx.to_bits(), fy.to_bits(), "fx {fx}, fy {fy}");
    // The centres are the circles' projected centres, not their outlines' as the solve models
    // them (a few hundredths of a pixel): fx a little off, whatever the flag.
    assert!((fx / truth.fx - 1.0).abs() < 3e-3, "fx {fx}");
    assert_eq!(v["std_dev"]["fx"], v["std_dev"]["fy"]);
}

#[test]
fn windows_of_thousands_of_centres_are_misses_within_seconds() {
    use evcal_host::input::detections::{CenterRecord, WindowRecord};
    let dir = tempfile::tempdir().unwrap();
    let det = dir.path().join("crowded.jsonl");
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    let lines: Vec<String> = (0..5u32)
        .map(|seq| {
            let centers = (0..9000)
                .map(|_| CenterRecord {
                    u: rng.random_range(0.0..346.0),
                    v: rng.random_range(0.0..260.0),
                    r: 4.0,
                    spread: 0.3,
                    n: 60,
                    converged: true,
                })
                .collect();
            let w = WindowRecord {
                seq,
                t_ref_us: 1_000_000 + 33_333 * u64::from(seq),
                events: 4000,
                noise: 10,
                centers,
                sensor: None,
            };
            serde_json::to_string(&w).unwrap()
        })
        .collect();
    std::fs::write(&det, lines.join("\n")).unwrap();
    let args = calibrate_synthetic(&det, &dir.path().join("o"), &[]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let (code, out, err) = evcal_within(20.0, &args);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(err.contains("crowded.jsonl") && err.contains("5 too many centres (more than 4 per circle"), "{err}");
}

/// Before (issue 44): detections never said their sensor, and `calibrate` asked for
/// `--sensor`. Now each line says it: no `--sensor` is needed, one that disagrees is refused,
/// and so is a file of two cameras.
#[test]
fn detections_say_their_sensor() {
    let dir = tempfile::tempdir().unwrap();
    let truth = TRUTH;
    let plain = dir.path().join("plain.jsonl");
    synthetic_detections(&plain, &truth, 30, &[]);
    let text = std::fs::read_to_string(&plain).unwrap();
    let said = |size: &str, lines: std::ops::Range<usize>| -> String {
        text.lines()
            .enumerate()
            .map(|(k, l)| match lines.contains(&k) {
                true => format!("{},\"sensor\":{size}}}\n", l.strip_suffix('}').unwrap()),
                false => format!("{l}\n"),
            })
            .collect()
    };
    let run = |name: &str, contents: &str, extra: &[&str]| {
        let det = dir.path().join(name);
        std::fs::write(&det, contents).unwrap();
        let out = dir.path().join(format!("{name}.out"));
        let mut args = vec!["calibrate", s(&det), "--pattern", "4x11", "--spacing", "0.024"];
        args.extend(["--no-smoothing", "--no-edge-shift", "--no-tracking", "--out", s(&out)]);
        args.extend(extra);
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        evcal_within(60.0, &args)
    };
    let (code, out, err) = run("said.jsonl", &said("[346,260]", 0..30), &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    // Said on some lines only (an older file with newer lines after it): taken.
    let (code, out, err) = run("some.jsonl", &said("[346,260]", 10..12), &[]);
    assert_eq!(code, Some(0), "{out}{err}");
    let (code, _, err) = run("other.jsonl", &said("[346,260]", 0..30), &["--sensor", "640x480"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("made on a 346x260 sensor, and --sensor says 640x480"), "{err}");
    let (a, b) = (said("[346,260]", 0..30), said("[640,480]", 0..30));
    let two: String = a.lines().take(15).chain(b.lines().skip(15)).map(|l| format!("{l}\n")).collect();
    let (code, _, err) = run("two.jsonl", &two, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("says a 640x480 sensor, window 0 a 346x260"), "{err}");
    let (code, _, err) = run("none.jsonl", &text, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("do not say the sensor size"), "{err}");
}
