//! The reader options on the command line: `evcal detect --topic`, `--time-unit`, and the
//! notes and errors a user sees. The fixtures' 2000 events fill no window of the default
//! size, and `detect` with no window fails: the tests ask for small windows.

use std::process::Command;

fn fixture(name: &str) -> String {
    format!("{}/tests/fixtures/formats/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn evcal(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_evcal")).args(args).output().unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn topic_chooses_the_stream() {
    let bag = fixture("ros_bz2.bag");
    let (ok, _, err) =
        evcal(&["detect", &bag, "--topic", "/right/events", "--events-per-window", "50", "-o", "/dev/null"]);
    assert!(ok, "{err}");
    assert!(err.contains("evcal: 100 events"), "{err}");
    let (ok, _, err) = evcal(&["detect", &bag, "--events-per-window", "500", "-o", "/dev/null"]);
    assert!(ok && err.contains("evcal: 2000 events"), "{err}");
    let (ok, _, err) = evcal(&["detect", &bag, "--topic", "/events"]);
    assert!(!ok);
    assert!(err.contains("no topic '/events'") && err.contains("/dvs/events (dvs_msgs/EventArray)"), "{err}");
    let (ok, _, err) = evcal(&["detect", &fixture("dv_zstd.aedat4"), "--topic", "imu"]);
    assert!(!ok && err.contains("holds no events"), "{err}");
}

#[test]
fn time_unit_and_notes() {
    let h5 = fixture("events_ns.h5");
    let (ok, _, err) = evcal(&["detect", &h5, "--events-per-window", "500", "-o", "/dev/null"]);
    assert!(ok, "{err}");
    assert!(err.contains("evcal: note:") && err.contains("taken as ns"), "{err}");
    let (ok, _, err) =
        evcal(&["detect", &h5, "--time-unit", "ns", "--events-per-window", "500", "-o", "/dev/null", "--quiet"]);
    assert!(ok && err.is_empty(), "{err}");
    let (ok, _, err) = evcal(&["detect", &h5, "--time-unit", "fortnights"]);
    assert!(!ok && err.contains("s, ms, us or ns"), "{err}");
    let (_, help, _) = evcal(&["detect", "--help"]);
    assert!(help.contains("--topic <NAME>") && help.contains("--time-unit <UNIT>"), "{help}");
}

/// The same events in every format give the same detections, byte for byte.
#[test]
fn every_format_detects_the_same() {
    let run = |name: &str| {
        let (ok, out, err) = evcal(&[
            "detect",
            &fixture(name),
            "--quiet",
            "--events-per-window",
            "200",
            "--step-ms",
            "5",
            "--min-pts",
            "3",
        ]);
        assert!(ok, "{name}: {err}");
        out
    };
    let want = run("events.txt");
    // random events: no circles, but every window's time and noise count must agree
    assert!(want.lines().count() >= 5, "{want}");
    for name in
        ["dv_lz4.aedat4", "dv_zstd_high.aedat4", "ros_bz2.bag", "ecalib.h5", "dsec.h5", "events_ns.h5", "e2calib.h5"]
    {
        assert_eq!(run(name), want, "{name}");
    }
}
