//! `evcal calibrate` states the calibration's uncertainty in pixels (issue 44, item 1): one
//! console line, and the grid with its figures in `calibration.json`.

use std::process::Command;

#[test]
fn calibrate_prints_one_line_of_projection_sigma_and_writes_its_grid() {
    // A perfect detector's centres on 3 s of a simulated cone.
    let dir = tempfile::tempdir().unwrap();
    let det = dir.path().join("detections.jsonl");
    std::fs::write(&det, crate::true_centre_detections()).unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(env!("CARGO_BIN_EXE_evcal"))
        .args(["calibrate", det.to_str().unwrap(), "--sensor", "davis346", "--pattern", "4x11", "--spacing", "0.024"])
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let said: Vec<&str> = stdout.lines().filter(|l| l.starts_with("projection σ")).collect();
    assert_eq!(said.len(), 1, "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("calibration.json")).unwrap()).unwrap();
    let p = &v["projection_sigma_px"];
    assert_eq!(
        (p["step_px"].as_u64(), p["columns"].as_u64(), p["rows"].as_u64()),
        (Some(8), Some(44), Some(33)),
        "{p}"
    );
    let values = p["values"].as_array().unwrap();
    assert_eq!(values.len(), 33);
    assert!(values.iter().all(|r| r.as_array().unwrap().len() == 44));
    // The line says what the file holds.
    let figure = |key: &str| p[key].as_f64().unwrap_or_else(|| panic!("{key}: {p}"));
    let (covered, sensor) = (figure("covered_p95_px"), figure("sensor_worst_px"));
    let px = |x: f64| if x < 0.1 { format!("{x:.3}") } else { format!("{x:.2}") };
    assert!(said[0].contains(&format!("covered p95 {} px", px(covered))), "{}: {p}", said[0]);
    assert!(said[0].contains(&format!("worst {} px (extrapolated", px(sensor))), "{}: {p}", said[0]);
    // Perfect centres fix the camera within the points to a small fraction of a pixel.
    assert!(covered > 0.0 && covered < 0.1 && covered <= sensor, "{p}");
}
