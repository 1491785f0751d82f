//! Outputs that would clobber something (issue 46, items 3 and 4): an output that is an
//! input, a link planted at an output's name, a truth.json of another recording, an earlier
//! run's results left looking like this run's. Refused before any work, or removed, with
//! every file that is not evcal's to replace left byte for byte.

use super::{evcal, fixture, s};
use evcal_host::{
    calib::{calibrate, synthetic_views, Intrinsics, Options},
    export::{write_all, Export},
    views::{ViewOrigin, WindowSample},
};
use std::path::Path;

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    v.sort();
    v
}

/// A copy of the text fixture at `dir/name`, and its bytes.
fn recording(dir: &Path, name: &str) -> (std::path::PathBuf, Vec<u8>) {
    let p = dir.join(name);
    std::fs::copy(fixture("events.txt"), &p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    (p, bytes)
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, bytes) = recording(dir.path(), "same.txt");
    // The same name, another spelling of it, and a hard link to it.
    let hard = dir.path().join("hard.txt");
    std::fs::hard_link(&rec, &hard).unwrap();
    for out in [rec.clone(), dir.path().join(".").join("same.txt"), hard] {
        let (code, _, err) = evcal(&["detect", s(&rec), "-o", s(&out)]);
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains("same file as the recording") && err.contains("same.txt"), "{err}");
        assert!(!err.contains("windows:"), "refused before any work: {err}");
        assert_eq!(std::fs::read(&rec).unwrap(), bytes);
    }
    // replay: before connecting (nothing listens on port 9 of this machine).
    let (code, _, err) = evcal(&["replay", s(&rec), "--port", "tcp:127.0.0.1:9", "--out", s(&rec)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("same file as the recording") && !err.contains("connect"), "{err}");
    assert_eq!(std::fs::read(&rec).unwrap(), bytes);
    // calibrate's --json, and --out holding the input.
    let det = dir.path().join("same.jsonl");
    let lines = br#"{"seq":0,"t_ref_us":100,"events":4000,"noise":10,"centers":[]}
"#;
    std::fs::write(&det, lines).unwrap();
    let cal = ["--sensor", "346x260", "--pattern", "4x11", "--spacing", "0.024"];
    let (code, _, err) =
        evcal(&[&["calibrate", s(&det), "--json", s(&det), "--out", s(&dir.path().join("o"))][..], &cal].concat());
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--json") && err.contains("same file as the input") && err.contains("same.jsonl"), "{err}");
    assert_eq!(std::fs::read(&det).unwrap(), lines);
    let cal_json = dir.path().join("calibration.json");
    std::fs::write(&cal_json, lines).unwrap();
    let (code, _, err) = evcal(&[&["calibrate", s(&cal_json), "--out", s(dir.path())][..], &cal].concat());
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--out") && err.contains("same file as the input"), "{err}");
    assert_eq!(std::fs::read(&cal_json).unwrap(), lines);
    // The input on standard input, redirected from the output's file.
    let o = super::evcal_command()
        .args(["detect", "-", "--sensor", "346x260", "-o", s(&rec)])
        .stdin(std::fs::File::open(&rec).unwrap())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("same file as the recording -"), "{err}");
    assert_eq!(std::fs::read(&rec).unwrap(), bytes);
}

#[cfg(unix)]
#[test]
fn an_output_that_is_a_link_is_refused_and_its_target_kept() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, _) = recording(dir.path(), "rec.txt");
    let victim = dir.path().join("victim");
    std::fs::write(&victim, "precious").unwrap();
    let link = dir.path().join("link.jsonl");
    std::os::unix::fs::symlink(&victim, &link).unwrap();
    let (code, _, err) = evcal(&["detect", s(&rec), "-o", s(&link)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("link.jsonl") && err.contains("symbolic link") && err.contains("victim"), "{err}");
    // Planted as calibration.json in --out (a shared /tmp).
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::os::unix::fs::symlink(&victim, out.join("calibration.json")).unwrap();
    let (code, _, err) =
        evcal(&["calibrate", s(&rec), "--pattern", "4x11", "--spacing", "0.024", "--out", s(&out), "--quiet"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("calibration.json") && err.contains("symbolic link"), "{err}");
    assert!(!err.contains("windows:"), "refused before any work: {err}");
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    assert_eq!(names(&out), ["calibration.json"]);
    // A folder is no file either.
    let (code, _, err) = evcal(&["detect", s(&rec), "-o", s(&out)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is a directory"), "{err}");
}

#[test]
fn outputs_are_replaced_whole_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, _) = recording(dir.path(), "rec.txt");
    let out = dir.path().join("det.jsonl");
    std::fs::write(&out, "earlier\n").unwrap();
    let (code, _, err) = evcal(&["detect", s(&rec), "--events-per-window", "500", "-o", s(&out), "--quiet"]);
    assert_eq!(code, Some(0), "{err}");
    let whole = std::fs::read_to_string(&out).unwrap();
    assert!(whole.lines().count() > 1 && whole.lines().all(|l| l.starts_with("{\"seq\"")), "{whole}");
    assert_eq!(names(dir.path()), ["det.jsonl", "rec.txt"], "no temporary file left");
    // A recording that breaks off after its first windows: the earlier file stays whole.
    let mut broken = std::fs::read_to_string(&rec).unwrap();
    broken.push_str("not an event\n");
    std::fs::write(&rec, broken).unwrap();
    let (code, _, err) = evcal(&["detect", s(&rec), "--events-per-window", "500", "-o", s(&out), "--quiet"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("det.jsonl not written (left as it was)"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), whole);
    assert_eq!(names(dir.path()), ["det.jsonl", "rec.txt"], "no temporary file left");
}

#[test]
fn simulate_keeps_a_truth_json_that_is_not_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let sim = |out: &Path, extra: &[&str]| {
        evcal(&[&["simulate", "--seconds", "0.05", "--quiet", "-o", s(out)][..], extra].concat())
    };
    // The recording where its own truth goes.
    let truth = dir.path().join("truth.json");
    let (code, _, err) = sim(&truth, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is where the truth goes") && err.contains("--truth"), "{err}");
    assert!(!truth.exists());
    // Another program's truth.json beside the recording.
    let foreign = br#"{"K": {"fx": 355.0}, "frames30": {"frames": []}}"#;
    std::fs::write(&truth, foreign).unwrap();
    let rec = dir.path().join("rec.txt");
    let (code, _, err) = sim(&rec, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("truth.json: is not the truth of a recording evcal simulated") && err.contains("--truth"),
        "{err}"
    );
    assert_eq!(std::fs::read(&truth).unwrap(), foreign);
    assert!(!rec.exists(), "refused before any work");
    // Elsewhere, with --truth: and again, which replaces its own.
    let sub = dir.path().join("sub");
    for _ in 0..2 {
        let (code, _, err) = sim(&sub.join("rec.txt"), &[]);
        assert_eq!(code, Some(0), "{err}");
    }
    let own: serde_json::Value = serde_json::from_slice(&std::fs::read(sub.join("truth.json")).unwrap()).unwrap();
    assert_eq!(own["recording"], "rec.txt");
    assert!(own["windows"].is_array() && own["camera"].is_object());
    let (code, _, err) = sim(&rec, &["--truth", s(&dir.path().join("rec-truth.json"))]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(std::fs::read(&truth).unwrap(), foreign);
    // Another recording into the folder whose truth.json is rec.txt's.
    let (code, _, err) = sim(&sub.join("other.txt"), &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("holds the truth of another recording, rec.txt"), "{err}");
    assert_eq!(names(&sub), ["rec.txt", "truth.json"]);
}

/// An earlier run's results in `dir`, as evcal writes them, from a synthetic calibration.
fn earlier_results(dir: &Path) {
    let truth =
        Intrinsics { fx: 352.5, fy: 351.25, cx: 171.3, cy: 128.7, k1: -0.31, k2: 0.11, p1: 4e-4, p2: -3e-4, k3: 0.0 };
    let views = synthetic_views(&truth, 8, 0.15, 3);
    let cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
    let origins: Vec<ViewOrigin> =
        (0..views.len()).map(|i| ViewOrigin { window_seq: i as u64, t_s: i as f64 * 0.1 }).collect();
    let timeline: Vec<WindowSample> =
        (0..views.len()).map(|i| WindowSample { t_s: i as f64 * 0.1, centres: 44, grid_found: true }).collect();
    write_all(dir, &Export::new(&cal, &views, &origins, &timeline)).unwrap();
}

#[test]
fn a_failed_calibrate_removes_the_earlier_run_s_results_only() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, _) = recording(dir.path(), "rec.txt");
    let out = dir.path().join("out");
    earlier_results(&out);
    // The user's own files: one under an evcal name.
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let kalibr = b"cam0:\n  camera_model: pinhole\n";
    std::fs::write(out.join("kalibr_camchain.yaml"), kalibr).unwrap();
    let json = dir.path().join("cam0.json");
    std::fs::copy(out.join("calibration.json"), &json).unwrap();
    // The fixture's 2000 events make no view of a 4x11 grid.
    let (code, _, err) = evcal(&[
        "calibrate",
        s(&rec),
        "--pattern",
        "4x11",
        "--spacing",
        "0.024",
        "--out",
        s(&out),
        "--json",
        s(&json),
        "--events-per-window",
        "500",
    ]);
    assert_ne!(code, Some(0), "{err}");
    assert!(err.contains("removed an earlier run's results") && err.contains("calibration.json"), "{err}");
    assert!(err.contains("kalibr_camchain.yaml") && err.contains("left as they are"), "{err}");
    assert_eq!(names(&out), ["kalibr_camchain.yaml", "notes.txt"]);
    assert_eq!(std::fs::read(out.join("kalibr_camchain.yaml")).unwrap(), kalibr);
    assert!(!json.exists());
    // An options error touches nothing.
    earlier_results(&out);
    let (code, _, err) =
        evcal(&["calibrate", s(&rec), "--pattern", "4x11", "--spacing", "0.024", "--out", s(&out), "--eps", "2"]);
    assert_eq!(code, Some(2), "{err}"); // refused as the command line is read
    assert!(!err.contains("removed"), "{err}");
    assert_eq!(names(&out).len(), 6);
}

/// `collect -o` writes into a temporary file, put in place on Ctrl-C with what arrived (here
/// from a device that sends nothing); `detect -o` interrupted leaves its file as it was.
/// Neither leaves a temporary file.
#[cfg(unix)]
#[test]
fn ctrl_c_keeps_what_collect_received_and_leaves_detect_s_file_as_it_was() {
    use std::{process::Stdio, time::Duration};
    let dir = tempfile::tempdir().unwrap();
    let interrupt = |c: &std::process::Child| {
        assert!(std::process::Command::new("kill").args(["-INT", &c.id().to_string()]).status().unwrap().success());
    };
    // Whether a temporary file of `name` is in the folder.
    let temp_of = |name: &str| {
        let prefix = format!(".{name}.");
        std::fs::read_dir(dir.path())
            .unwrap()
            .any(|e| e.unwrap().file_name().into_string().unwrap().starts_with(&prefix))
    };
    let wait_for = |name: &str, c: &mut std::process::Child| {
        let start = std::time::Instant::now();
        while !temp_of(name) && c.try_wait().unwrap().is_none() && start.elapsed() < Duration::from_secs(30) {
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    // A device that accepts the link and says nothing.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let quiet_device = std::thread::spawn(move || listener.accept().map(|(link, _)| link));
    let out = dir.path().join("col.jsonl");
    std::fs::write(&out, "earlier\n").unwrap();
    let mut collect = super::evcal_command()
        .args(["collect", "--port", &format!("tcp:127.0.0.1:{port}"), "-o", s(&out), "-q"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for("col.jsonl", &mut collect);
    // Until the end the earlier file is whole: a write cut short never leaves a torn one.
    assert_eq!(std::fs::read(&out).unwrap(), b"earlier\n");
    interrupt(&collect);
    let o = collect.wait_with_output().unwrap();
    drop(quiet_device.join().unwrap());
    assert_eq!(o.status.code(), Some(130), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&out).unwrap(), b"", "what arrived (nothing) replaces the earlier file");
    // detect: its file as it was.
    let sensor = evcal_core::event::SensorSize::DAVIS346;
    let rec = dir.path().join("long.txt");
    evcal_host::input::recording::write_text(&rec, Some(sensor), &super::events(400_000, sensor, 7)).unwrap();
    let det = dir.path().join("det.jsonl");
    std::fs::write(&det, "earlier\n").unwrap();
    let mut detect = super::evcal_command().args(["detect", s(&rec), "-o", s(&det), "-q"]).spawn().unwrap();
    wait_for("det.jsonl", &mut detect);
    interrupt(&detect);
    let status = detect.wait().unwrap();
    // Finished first on a fast machine: then the file is whole.
    if status.code() == Some(130) {
        assert_eq!(std::fs::read_to_string(&det).unwrap(), "earlier\n");
    } else {
        assert_eq!(status.code(), Some(0));
    }
    assert_eq!(names(dir.path()), ["col.jsonl", "det.jsonl", "long.txt"], "no temporary file left");
}
