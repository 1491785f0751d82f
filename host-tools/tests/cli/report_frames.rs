//! The report's windows drawn on their events (issue 44, item 5): `evcal calibrate` on a
//! recording keeps a few windows' events while it detects, and the report draws them in grey
//! under the numbered grid.

use evcal_host::{
    eval::simulate,
    export::REPORT_SIZE,
    input::recording::write_ecalib_h5,
    sim::{Light, SimConfig, Trajectory},
};
use std::process::Command;

/// The grey of a pixel one event fell on in a window of the report.
const ONE_EVENT: [u8; 3] = [205, 205, 205];

/// The rings round centres outside the grid (the wall's circles, the board's edge).
const RED: [u8; 3] = [214, 39, 40];

/// Rows at the bottom of the report that the strip of windows fills.
const STRIP_ROWS: u32 = 250;

#[test]
fn a_recording_s_report_draws_its_windows_events() {
    let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, 5).unwrap();
    let spacing = cfg.board.spacing.to_string();
    // A few views: enough for a solve, calibration or not, and a report either way.
    let (events, _) = simulate(cfg, 0.15);
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("short.h5");
    write_ecalib_h5(&rec, &events).unwrap();
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_evcal"))
        .arg("calibrate")
        .arg(&rec)
        .args(["--sensor", "davis346", "--pattern", "4x11", "--spacing", &spacing, "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    let report = ["report.png", "report.failed.png"].iter().map(|n| out.join(n)).find(|p| p.is_file());
    let report = report.unwrap_or_else(|| panic!("no report: {stderr}"));
    let bytes = std::fs::read(&report).unwrap();
    let mut reader = png::Decoder::new(&bytes[..]).read_info().unwrap();
    let mut px = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut px).unwrap();
    assert_eq!((info.width, info.height), REPORT_SIZE);
    let n = info.color_type.samples();
    let (w, h) = REPORT_SIZE;
    let row = |y: u32| &px[(y * w) as usize * n..((y + 1) * w) as usize * n];
    let count =
        |c: [u8; 3]| -> usize { (h - STRIP_ROWS..h).map(|y| row(y).chunks(n).filter(|p| p[..3] == c).count()).sum() };
    // Four windows of 8000 events over a few thousand pixels each.
    let grey = count(ONE_EVENT);
    assert!(grey >= 2000, "{grey} pixels of single events in the strip of {}", report.display());
    // The centres the detector found beside the grid's, ringed.
    let red = count(RED);
    assert!(red >= 10, "{red} pixels of rings round centres in the strip of {}", report.display());
}
