//! The three YAML layouts: OpenCV's `cv::FileStorage`, ROS's `camera_info` (as
//! `camera_calibration_parsers` writes it) and Kalibr's camchain.

use crate::calib::{k3_displacement_px, optimal_new_camera_matrix, Calibration, Intrinsics, K3_NEGLIGIBLE_PX};
use std::fmt::Write;

/// A number as every reader here takes it for the same `f64`: Rust's shortest round-trip
/// digits, with a decimal point always (YAML 1.1, hence PyYAML and Kalibr, reads `350` as an
/// integer and `1e-07` as a string) and a signed exponent for very small or large values.
fn num(x: f64) -> String {
    if !x.is_finite() {
        // YAML's spellings, which OpenCV's parser also knows.
        return if x.is_nan() {
            ".nan".into()
        } else if x > 0.0 {
            ".inf".into()
        } else {
            "-.inf".into()
        };
    }
    let a = x.abs();
    if a == 0.0 || (1e-4..1e15).contains(&a) {
        let s = format!("{x}");
        return if s.contains('.') { s } else { s + ".0" };
    }
    let s = format!("{x:e}");
    let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
    let mantissa = if mantissa.contains('.') { mantissa.to_string() } else { format!("{mantissa}.0") };
    let exponent = if exponent.starts_with('-') { exponent.to_string() } else { format!("+{exponent}") };
    format!("{mantissa}e{exponent}")
}

/// A flow sequence of numbers.
fn list(xs: &[f64]) -> String {
    let items: Vec<String> = xs.iter().map(|&x| num(x)).collect();
    format!("[{}]", items.join(", "))
}

/// A YAML scalar string: plain when it is made of characters no reader takes for syntax,
/// otherwise double-quoted with JSON's escapes (a subset of YAML's).
fn string(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars().all(|c| c.is_ascii_alphanumeric() || "_/.-".contains(c))
        && !s.starts_with(['-', '.'])
        // Words YAML 1.1 reads as something else than a string.
        && !["true", "false", "yes", "no", "on", "off", "null", "y", "n"].contains(&s.to_ascii_lowercase().as_str())
        && s.parse::<f64>().is_err();
    if plain {
        s.to_string()
    } else {
        serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
    }
}

fn camera_matrix(k: &Intrinsics) -> [f64; 9] {
    [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]
}

/// The calibration in `cv::FileStorage`'s YAML layout, as OpenCV's calibration sample writes
/// it: `image_width`, `image_height`, `camera_matrix` (3×3) and `distortion_coefficients`
/// (1×5: k1, k2, p1, p2, k3) as `!!opencv-matrix`, `avg_reprojection_error` (the RMS, px).
/// `calibration_time`, when given, goes first as a quoted string.
pub fn opencv_yaml(cal: &Calibration, calibration_time: Option<&str>) -> String {
    let k = &cal.intrinsics;
    // OpenCV's own parser insists on this exact first line.
    let mut s = String::from("%YAML:1.0\n---\n");
    if let Some(t) = calibration_time {
        // Always quoted: a time reads as a number or a date in YAML otherwise.
        let _ = writeln!(s, "calibration_time: {}", serde_json::to_string(t).unwrap_or_else(|_| "\"\"".into()));
    }
    let _ = writeln!(s, "image_width: {}", cal.image_size[0]);
    let _ = writeln!(s, "image_height: {}", cal.image_size[1]);
    let matrix = |s: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]| {
        let _ = writeln!(s, "{name}: !!opencv-matrix");
        let _ = writeln!(s, "   rows: {rows}");
        let _ = writeln!(s, "   cols: {cols}");
        let _ = writeln!(s, "   dt: d");
        let _ = writeln!(s, "   data: {}", list(data));
    };
    matrix(&mut s, "camera_matrix", 3, 3, &camera_matrix(k));
    matrix(&mut s, "distortion_coefficients", 1, 5, &k.distortion());
    let _ = writeln!(s, "avg_reprojection_error: {}", num(cal.rms_px));
    s
}

/// The calibration as a ROS `sensor_msgs/CameraInfo` YAML in `camera_calibration_parsers`'
/// layout: plumb_bob distortion (k1, k2, p1, p2, k3), identity rectification and the
/// projection of a monocular camera as ROS's `camera_calibration` writes it: the undistorted
/// image's camera matrix from OpenCV's `getOptimalNewCameraMatrix` with `alpha = 0`
/// ([`optimal_new_camera_matrix`]), so that `image_proc`'s rectified image has no invalid
/// pixel.
pub fn camera_info_yaml(cal: &Calibration, camera_name: &str) -> String {
    let k = &cal.intrinsics;
    let mut s = String::new();
    let _ = writeln!(s, "image_width: {}", cal.image_size[0]);
    let _ = writeln!(s, "image_height: {}", cal.image_size[1]);
    let _ = writeln!(s, "camera_name: {}", string(camera_name));
    let matrix = |s: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]| {
        let _ = writeln!(s, "{name}:");
        let _ = writeln!(s, "  rows: {rows}");
        let _ = writeln!(s, "  cols: {cols}");
        let _ = writeln!(s, "  data: {}", list(data));
    };
    matrix(&mut s, "camera_matrix", 3, 3, &camera_matrix(k));
    let _ = writeln!(s, "distortion_model: plumb_bob");
    matrix(&mut s, "distortion_coefficients", 1, 5, &k.distortion());
    matrix(&mut s, "rectification_matrix", 3, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    let m = optimal_new_camera_matrix(k, cal.image_size);
    let p = [m[0], 0.0, m[2], 0.0, 0.0, m[4], m[5], 0.0, 0.0, 0.0, 1.0, 0.0];
    matrix(&mut s, "projection_matrix", 3, 4, &p);
    s
}

/// The calibration as a Kalibr camchain with one camera, `cam0`: pinhole, radtan
/// (k1, k2, p1, p2), the resolution and the ROS topic. Returns the YAML and the warnings:
/// one when k3 is not negligible ([`k3_displacement_px`] above [`K3_NEGLIGIBLE_PX`]), since
/// radtan cannot carry it and the camchain is then not the camera that was calibrated.
pub fn kalibr_camchain_yaml(cal: &Calibration, rostopic: &str) -> (String, Vec<String>) {
    let k = &cal.intrinsics;
    let mut s = String::from("cam0:\n");
    let _ = writeln!(s, "  camera_model: pinhole");
    let _ = writeln!(s, "  intrinsics: {}", list(&[k.fx, k.fy, k.cx, k.cy]));
    let _ = writeln!(s, "  distortion_model: radtan");
    let _ = writeln!(s, "  distortion_coeffs: {}", list(&[k.k1, k.k2, k.p1, k.p2]));
    let _ = writeln!(s, "  resolution: [{}, {}]", cal.image_size[0], cal.image_size[1]);
    let _ = writeln!(s, "  rostopic: {}", string(rostopic));
    // Kalibr writes it for every camera of a chain; its readers expect it.
    let _ = writeln!(s, "  cam_overlaps: []");
    let mut warnings = Vec::new();
    let d = k3_displacement_px(k, cal.image_size);
    if d > K3_NEGLIGIBLE_PX || d.is_nan() {
        warnings.push(format!(
            "kalibr_camchain.yaml: Kalibr's radtan model has no k3, and k3 = {:.4e} moves the farthest image corner by \
             {d:.3} px (more than {K3_NEGLIGIBLE_PX} px), so the camchain without it is not the calibrated camera; \
             recalibrate with k3 fixed at 0 (`evcal calibrate ... --fix-k3`, or `--kalibr`, which solves the Kalibr \
             export with k3 fixed)",
            k.k3
        ));
    }
    (s, warnings)
}

#[cfg(test)]
pub(super) mod test {
    use super::super::testdata::*;
    use super::*;
    use std::path::Path;
    use std::process::Command;

    #[test]
    fn numbers_read_back_exactly() {
        for x in [
            0.0,
            -0.0,
            1.0,
            350.0,
            352.123456789012,
            -0.3123456789012345,
            1e-7,
            -4.2e-5,
            1e-4,
            0.1 + 0.2,
            6.02e23,
            1e15,
            f64::MIN_POSITIVE,
            f64::MAX,
        ] {
            let s = num(x);
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{x} -> {s}");
            // PyYAML's (YAML 1.1) float: a point in the mantissa, a sign in the exponent.
            let mantissa = s.split('e').next().unwrap();
            assert!(mantissa.contains('.'), "{s}");
            if let Some(e) = s.split('e').nth(1) {
                assert!(e.starts_with(['+', '-']), "{s}");
            }
        }
        assert_eq!(num(350.0), "350.0");
        assert_eq!(num(1e-7), "1.0e-7");
        assert_eq!(num(-4.25e-5), "-4.25e-5");
        assert_eq!(num(f64::NAN), ".nan");
    }

    #[test]
    fn strings_are_quoted_when_needed() {
        assert_eq!(string("dvs"), "dvs");
        assert_eq!(string("/dvs/events"), "/dvs/events");
        assert_eq!(string("my camera: left"), "\"my camera: left\"");
        assert_eq!(string("yes"), "\"yes\"");
        assert_eq!(string("1e3"), "\"1e3\"");
        assert_eq!(string(""), "\"\"");
        assert_eq!(string("a\"b"), "\"a\\\"b\"");
    }

    /// The numbers of the `data: [...]` list that follows `key`.
    fn data_after(text: &str, key: &str) -> Vec<f64> {
        let at = text.find(key).unwrap_or_else(|| panic!("no {key} in\n{text}"));
        let line = text[at..].lines().find(|l| l.trim_start().starts_with("data:")).unwrap();
        let inner = line.split_once('[').unwrap().1.trim_end().trim_end_matches(']');
        inner.split(',').map(|x| x.trim().parse().unwrap()).collect()
    }

    #[test]
    fn layouts_hold_the_calibration() {
        let (_, cal, _, _) = setup(&TRUTH, false);
        let k = cal.intrinsics;
        let cv = opencv_yaml(&cal, Some("Sat Nov 23 07:00:00 2024"));
        assert!(
            cv.starts_with("%YAML:1.0\n---\ncalibration_time: \"Sat Nov 23 07:00:00 2024\"\nimage_width: 346\n"),
            "{cv}"
        );
        assert!(cv.contains("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"), "{cv}");
        assert_eq!(data_after(&cv, "camera_matrix"), camera_matrix(&k));
        assert_eq!(data_after(&cv, "distortion_coefficients"), k.distortion());
        assert!(!opencv_yaml(&cal, None).contains("calibration_time"));

        let ros = camera_info_yaml(&cal, "davis346");
        assert!(ros.starts_with("image_width: 346\nimage_height: 260\ncamera_name: davis346\n"), "{ros}");
        assert!(ros.contains("distortion_model: plumb_bob\n"), "{ros}");
        assert_eq!(data_after(&ros, "camera_matrix"), camera_matrix(&k));
        assert_eq!(data_after(&ros, "distortion_coefficients"), k.distortion());
        assert_eq!(data_after(&ros, "rectification_matrix"), [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let m = optimal_new_camera_matrix(&k, cal.image_size);
        assert_eq!(
            data_after(&ros, "projection_matrix"),
            [m[0], 0.0, m[2], 0.0, 0.0, m[4], m[5], 0.0, 0.0, 0.0, 1.0, 0.0]
        );

        let (kalibr, _) = kalibr_camchain_yaml(&cal, "/dvs/events");
        assert!(kalibr.starts_with("cam0:\n  camera_model: pinhole\n"), "{kalibr}");
        assert!(kalibr.contains("  distortion_model: radtan\n  distortion_coeffs: ["), "{kalibr}");
        assert!(kalibr.contains("  resolution: [346, 260]\n  rostopic: /dvs/events\n"), "{kalibr}");
    }

    #[test]
    fn kalibr_warns_when_k3_matters() {
        let strong = Intrinsics { k3: 0.3, ..TRUTH };
        let (_, cal, _, _) = setup(&strong, false);
        let d = k3_displacement_px(&cal.intrinsics, cal.image_size);
        assert!(d > K3_NEGLIGIBLE_PX, "{d}");
        let (_, w) = kalibr_camchain_yaml(&cal, "/dvs/events");
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("--fix-k3") && w[0].contains("radtan") && w[0].contains(&format!("{d:.3} px")),
            "{}",
            w[0]
        );
        // k3 fixed at 0: nothing to say.
        let (_, cal, _, _) = setup(&strong, true);
        assert_eq!(cal.intrinsics.k3, 0.0);
        assert!(kalibr_camchain_yaml(&cal, "/dvs/events").1.is_empty());
    }

    // ---- independent readers: OpenCV's FileStorage and PyYAML ----

    /// Runs `script` with `python3` on `file`; its stdout. `None` when the user skips the
    /// Python checks (EVCAL_SKIP_PYTHON=1); a failure naming scripts/setup.sh when `module`
    /// is not installed.
    pub(in crate::export) fn python(module: &str, package: &str, script: &str, file: &Path) -> Option<String> {
        if std::env::var("EVCAL_SKIP_PYTHON").is_ok_and(|v| v == "1") {
            eprintln!("\n!!!!!!!! SKIPPED (EVCAL_SKIP_PYTHON=1): reading the export back with Python's {module}\n");
            return None;
        }
        let probe = Command::new("python3").args(["-c", &format!("import {module}")]).output();
        match probe {
            Ok(o) if o.status.success() => {}
            Ok(o) => panic!(
                "Python module {module} ({package}) is missing, and this test reads the export back with it: \
                 run `bash scripts/setup.sh` (or set EVCAL_SKIP_PYTHON=1 to skip). python3 said: {}",
                String::from_utf8_lossy(&o.stderr).trim()
            ),
            Err(e) => {
                panic!("cannot run python3 ({e}): run `bash scripts/setup.sh` (or set EVCAL_SKIP_PYTHON=1 to skip)")
            }
        }
        let out = Command::new("python3").arg("-c").arg(script).arg(file).output().expect("python3 runs");
        assert!(
            out.status.success(),
            "python3 failed on {}:\n{}",
            file.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        Some(String::from_utf8(out.stdout).expect("UTF-8"))
    }

    /// `key value value ...` lines, numbers printed by Python's `repr` (shortest round trip,
    /// read exactly by `str::parse`, unlike a JSON parser's best effort).
    fn parse_lines(out: &str) -> std::collections::HashMap<String, Vec<f64>> {
        out.lines()
            .filter_map(|l| {
                let mut it = l.split_whitespace();
                let key = it.next()?.to_string();
                Some((key, it.map(|x| x.parse().unwrap_or_else(|_| panic!("{l}"))).collect()))
            })
            .collect()
    }

    #[test]
    fn opencv_filestorage_reads_it() {
        let (_, mut cal, _, _) = setup(&TRUTH, false);
        // A coefficient small enough to be written with an exponent.
        cal.intrinsics.p2 = -3.25e-5;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("opencv.yaml");
        std::fs::write(&path, opencv_yaml(&cal, Some("Sat Nov 23 07:00:00 2024"))).unwrap();
        let script = r#"
import sys, cv2
fs = cv2.FileStorage(sys.argv[1], cv2.FILE_STORAGE_READ)
assert fs.isOpened(), "FileStorage did not open the file"
K = fs.getNode("camera_matrix").mat()
D = fs.getNode("distortion_coefficients").mat()
assert K.shape == (3, 3) and K.dtype.name == "float64", (K.shape, K.dtype)
assert D.shape == (1, 5) and D.dtype.name == "float64", (D.shape, D.dtype)
print("size", float(fs.getNode("image_width").real()), float(fs.getNode("image_height").real()))
print("K", *map(repr, K.flatten().tolist()))
print("D", *map(repr, D.flatten().tolist()))
print("err", repr(fs.getNode("avg_reprojection_error").real()))
assert fs.getNode("calibration_time").string() == "Sat Nov 23 07:00:00 2024", fs.getNode("calibration_time").string()
"#;
        let Some(out) = python("cv2", "opencv-python-headless", script, &path) else { return };
        let got = parse_lines(&out);
        let k = cal.intrinsics;
        assert_eq!(got["size"], [346.0, 260.0]);
        assert_eq!(got["K"], camera_matrix(&k));
        assert_eq!(got["D"], k.distortion());
        assert_eq!(got["err"], [cal.rms_px]);
    }

    #[test]
    fn camera_info_projection_is_opencvs_optimal_new_camera_matrix() {
        // ROS's camera_calibration writes P = getOptimalNewCameraMatrix(K, D, size, 0); a
        // strong barrel lens, a mild one with tangential terms, and one with k3.
        let dir = tempfile::tempdir().unwrap();
        for (n, k) in [
            TRUTH,
            Intrinsics { k1: -0.1, k2: 0.02, p1: 4e-4, p2: -3e-4, k3: 0.0, ..TRUTH },
            Intrinsics { k1: -0.28, k2: 0.09, p1: 0.0, p2: 0.0, k3: -0.02, ..TRUTH },
        ]
        .iter()
        .enumerate()
        {
            let path = dir.path().join(format!("k{n}.txt"));
            let mut line = format!("{} {}", 346, 260);
            for v in camera_matrix(k).iter().chain(&k.distortion()) {
                line += &format!(" {v:?}");
            }
            std::fs::write(&path, line).unwrap();
            let script = r#"
import sys, cv2, numpy as np
v = [float(x) for x in open(sys.argv[1]).read().split()]
K = np.array(v[2:11]).reshape(3, 3); D = np.array(v[11:16])
M, _ = cv2.getOptimalNewCameraMatrix(K, D, (int(v[0]), int(v[1])), 0)
print("M", *map(repr, M.flatten().tolist()))
"#;
            let Some(out) = python("cv2", "opencv-python-headless", script, &path) else { return };
            let theirs = &parse_lines(&out)["M"];
            let ours = optimal_new_camera_matrix(k, [346, 260]);
            for (a, b) in ours.iter().zip(theirs) {
                assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "case {n}: ours {ours:?}, OpenCV's {theirs:?}");
            }
        }
    }

    #[test]
    fn pyyaml_reads_camera_info_and_camchain() {
        let (_, mut cal, _, _) = setup(&TRUTH, false);
        // A coefficient small enough to be written with an exponent.
        cal.intrinsics.p2 = -3.25e-5;
        let k = cal.intrinsics;
        let dir = tempfile::tempdir().unwrap();
        let ros = dir.path().join("camera_info.yaml");
        std::fs::write(&ros, camera_info_yaml(&cal, "davis: left")).unwrap();
        // Every number must come back a float (int for the sizes), never a string.
        let script = r#"
import sys, yaml
d = yaml.safe_load(open(sys.argv[1]))
assert d["camera_name"] == "davis: left", d["camera_name"]
assert d["distortion_model"] == "plumb_bob"
assert type(d["image_width"]) is int and type(d["image_height"]) is int
print("size", d["image_width"], d["image_height"])
for m, shape in [("camera_matrix", (3, 3)), ("distortion_coefficients", (1, 5)), ("rectification_matrix", (3, 3)), ("projection_matrix", (3, 4))]:
    assert (d[m]["rows"], d[m]["cols"]) == shape, m
    assert all(type(x) is float for x in d[m]["data"]), d[m]["data"]
    print(m, *map(repr, d[m]["data"]))
"#;
        let Some(out) = python("yaml", "PyYAML", script, &ros) else { return };
        let got = parse_lines(&out);
        assert_eq!(got["size"], [346.0, 260.0]);
        assert_eq!(got["camera_matrix"], camera_matrix(&k));
        assert_eq!(got["distortion_coefficients"], k.distortion());
        assert_eq!(got["rectification_matrix"], [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let m = optimal_new_camera_matrix(&k, cal.image_size);
        assert_eq!(got["projection_matrix"], [m[0], 0.0, m[2], 0.0, 0.0, m[4], m[5], 0.0, 0.0, 0.0, 1.0, 0.0]);

        let chain = dir.path().join("kalibr_camchain.yaml");
        std::fs::write(&chain, kalibr_camchain_yaml(&cal, "/dvs/events").0).unwrap();
        let script = r#"
import sys, yaml
c = yaml.safe_load(open(sys.argv[1]))["cam0"]
assert c["camera_model"] == "pinhole" and c["distortion_model"] == "radtan", c
assert c["rostopic"] == "/dvs/events" and c["resolution"] == [346, 260] and c["cam_overlaps"] == [], c
assert all(type(x) is float for x in c["intrinsics"] + c["distortion_coeffs"]), c
print("intrinsics", *map(repr, c["intrinsics"]))
print("distortion_coeffs", *map(repr, c["distortion_coeffs"]))
"#;
        let Some(out) = python("yaml", "PyYAML", script, &chain) else { return };
        let got = parse_lines(&out);
        assert_eq!(got["intrinsics"], [k.fx, k.fy, k.cx, k.cy]);
        assert_eq!(got["distortion_coeffs"], [k.k1, k.k2, k.p1, k.p2]);
    }
}
