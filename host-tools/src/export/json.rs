//! The JSON result other programs read.
//!
//! Top-level keys, in this order, whose names do not change:
//! `fx fy cx cy k1 k2 p1 p2 k3 rms_px views_used windows detections per_view`; after them,
//! keys that may grow: `image_width image_height mean_view_px median_view_px std_dev
//! sigma_groups sigma_group_s rejected stray_points rms_all_px warnings iterations converged edge_shift circle_radius_m calibration_failed precision_bins verdict verdict_actions k3_held projection_sigma_px`.

use super::RunCounts;
use super::{ExportError, Result};
use crate::calib::{Calibration, Intrinsics, PrecisionBin, ProjectionSigma};
use crate::views::ViewOrigin;
use serde::{Deserialize, Serialize};

/// The JSON result (serialise it with `serde_json`; the field order is the key order).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResultJson {
    /// Focal length along x, px.
    pub fx: f64,
    /// Focal length along y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
    /// Radial distortion, r².
    pub k1: f64,
    /// Radial distortion, r⁴.
    pub k2: f64,
    /// Tangential distortion.
    pub p1: f64,
    /// Tangential distortion.
    pub p2: f64,
    /// Radial distortion, r⁶.
    pub k3: f64,
    /// RMS reprojection error over the points of the views used, strays set aside by the
    /// robust rule left out, px.
    pub rms_px: f64,
    /// Views the calibration used.
    pub views_used: usize,
    /// Detection windows looked at.
    pub windows: u64,
    /// Windows in which the grid was found.
    pub detections: u64,
    /// Every view used, in the solver's order.
    pub per_view: Vec<PerViewJson>,
    /// Image width, px.
    pub image_width: u32,
    /// Image height, px.
    pub image_height: u32,
    /// Mean of the views' RMS errors, px.
    pub mean_view_px: f64,
    /// Median of the views' RMS errors, px.
    pub median_view_px: f64,
    /// One standard deviation of each parameter (0 for a fixed one; `null` for one the
    /// views do not fix at all, read back as infinite).
    #[serde(deserialize_with = "unbounded_as_null")]
    pub std_dev: Intrinsics,
    /// How many groups of views (stretches of the recording, `sigma_group_s` long)
    /// `std_dev` came from, widened for so few (`calib::few_groups_factor`); `null`: each
    /// point's error taken as independent, too few groups to see how the views' errors are
    /// shared.
    #[serde(default)]
    pub sigma_groups: Option<usize>,
    /// How long each of those stretches is, s: half a second, shorter (down to 0.15 s) for
    /// views in fewer half-seconds (`calib::group_seconds`); `null` with `sigma_groups`.
    #[serde(default)]
    pub sigma_group_s: Option<f64>,
    /// Views set aside, and why.
    pub rejected: Vec<RejectedJson>,
    /// Points set aside by the robust rule (beyond 5 σ of all points' errors).
    pub stray_points: usize,
    /// RMS reprojection error over every point of the views used, strays included, px.
    pub rms_all_px: f64,
    /// The solver's warnings, then the exports'.
    pub warnings: Vec<String>,
    /// Levenberg–Marquardt steps of the final solve.
    pub iterations: usize,
    /// Whether the final solve converged.
    pub converged: bool,
    /// How far the detected centres trailed their circles along the motion, and so were
    /// moved forward before the solve (`null`: not measured).
    #[serde(default)]
    pub edge_shift: Option<crate::views::edge_shift::EdgeShift>,
    /// The radius of the board's circles the solve modelled (each detected centre compared
    /// with its circle's outline centre), metres; `null`: centres compared with the
    /// projections of the board points.
    #[serde(default)]
    pub circle_radius_m: Option<f64>,
    /// Why this is no calibration (the views leave a parameter too loose to mean anything);
    /// `null` for a calibration. A program reading the file should check it.
    #[serde(default)]
    pub calibration_failed: Option<String>,
    /// How the solve weighed each centre by the events its fit had, bin by bin from the
    /// fewest events up (`from`: the fewest events in the bin; `weight`: each of its points'
    /// weight, the median square error of all points over the bin's); empty when every
    /// centre weighed alike for want of figures or points, or in a plain solve
    /// (`--no-robust`). All weights equal: centres fitted to more events erred no less.
    #[serde(default)]
    pub precision_bins: Vec<PrecisionBin>,
    /// The run's verdict: `"good"`, `"usable"` or `"not a calibration"`
    /// (`evcal calibrate`'s exit status 0, 4 or 3); `null` when not judged.
    #[serde(default)]
    pub verdict: Option<String>,
    /// What to do about a `"usable"` verdict, the most useful first (at most three).
    #[serde(default)]
    pub verdict_actions: Vec<String>,
    /// k3 was held at 0 because the views do not tell it from 0: what the solve with it free
    /// said; `null` when k3 was solved (or held by `--fix-k3`).
    #[serde(default)]
    pub k3_held: Option<K3HeldJson>,
    /// One standard deviation of where a distant point is seen, px, over the sensor
    /// (`calib::ProjectionSigma`); `null` when it was not computed.
    #[serde(default)]
    pub projection_sigma_px: Option<ProjectionSigmaJson>,
}

/// What the solve with k3 free said, when k3 was held at 0 (`k3_held` in the JSON result).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct K3HeldJson {
    /// k3 with it free.
    pub free: f64,
    /// Its σ there.
    pub std: f64,
}

/// The projection σ in the JSON result: a grid over the sensor, the region the boards
/// covered, and the figures over both. `null` for a σ the views leave unbounded (JSON has
/// no infinity), or for figures over no node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProjectionSigmaJson {
    /// Grid step, px: `values[j][i]` is the σ at pixel (i·step_px, j·step_px).
    pub step_px: u32,
    /// Nodes per row.
    pub columns: usize,
    /// Rows of nodes.
    pub rows: usize,
    /// σ at each node, px, row by row from the top.
    pub values: Vec<Vec<Option<f64>>>,
    /// Whether each node lies within the outline of a board seen in a view used (`values`'
    /// layout); elsewhere the model is extrapolated.
    pub covered: Vec<Vec<bool>>,
    /// The largest σ over the sensor, px.
    pub sensor_worst_px: Option<f64>,
    /// The σ 95 % of the sensor's nodes are at or below, px.
    pub sensor_p95_px: Option<f64>,
    /// The largest σ over the covered nodes, px.
    pub covered_worst_px: Option<f64>,
    /// The σ 95 % of the covered nodes are at or below, px.
    pub covered_p95_px: Option<f64>,
}

impl From<&ProjectionSigma> for ProjectionSigmaJson {
    fn from(s: &ProjectionSigma) -> Self {
        let finite = |x: f64| x.is_finite().then_some(x);
        Self {
            step_px: s.step_px,
            columns: s.columns,
            rows: s.rows,
            values: s.values.iter().map(|r| r.iter().map(|&v| finite(v)).collect()).collect(),
            covered: s.covered.clone(),
            sensor_worst_px: finite(s.sensor.worst_px),
            sensor_p95_px: finite(s.sensor.p95_px),
            covered_worst_px: s.within_points.and_then(|f| finite(f.worst_px)),
            covered_p95_px: s.within_points.and_then(|f| finite(f.p95_px)),
        }
    }
}

/// Reads `std_dev` back: JSON has no infinity, so `serde_json` writes an unbounded σ as
/// `null`; read as infinite, it keeps its meaning (not a σ of zero, nor an error).
fn unbounded_as_null<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Intrinsics, D::Error> {
    #[derive(Deserialize)]
    struct Maybe {
        fx: Option<f64>,
        fy: Option<f64>,
        cx: Option<f64>,
        cy: Option<f64>,
        k1: Option<f64>,
        k2: Option<f64>,
        p1: Option<f64>,
        p2: Option<f64>,
        k3: Option<f64>,
    }
    let m = Maybe::deserialize(d)?;
    let v = [m.fx, m.fy, m.cx, m.cy, m.k1, m.k2, m.p1, m.p2, m.k3].map(|x| x.unwrap_or(f64::INFINITY));
    Ok(Intrinsics::from_array(v))
}

/// One used view in the JSON result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PerViewJson {
    /// Index of the view among those given to the solver.
    pub view: usize,
    /// Sequence number of the window the view comes from.
    pub window_seq: u64,
    /// The window's time, s.
    pub t: f64,
    /// Points of the view.
    pub points: usize,
    /// RMS reprojection error of its points, strays left out, px.
    pub rms_px: f64,
    /// Its points set aside as strays.
    pub strays: usize,
    /// Board → camera rotation (Rodrigues vector, OpenCV's rvec).
    pub rvec: [f64; 3],
    /// Board → camera translation (OpenCV's tvec), metres.
    pub tvec: [f64; 3],
}

/// A view set aside, in the JSON result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RejectedJson {
    /// Index of the view among those given to the solver.
    pub view: usize,
    /// Sequence number of the window the view comes from.
    pub window_seq: Option<u64>,
    /// Why, in words.
    pub reason: String,
}

/// The JSON result of `cal`: `origins` say where each input view came from (indexed like the
/// views given to the solver), `counts` how much of the recording was looked at. An error
/// when a view the calibration used has no origin.
pub fn result_json(cal: &Calibration, origins: &[ViewOrigin], counts: RunCounts) -> Result<ResultJson> {
    let k = &cal.intrinsics;
    let mut per_view = Vec::with_capacity(cal.views.len());
    for v in &cal.views {
        let Some(o) = origins.get(v.view) else {
            return Err(ExportError::Mismatch(format!(
                "view {} was used but has no origin (window): {} origins were given",
                v.view,
                origins.len()
            )));
        };
        per_view.push(PerViewJson {
            view: v.view,
            window_seq: o.window_seq,
            t: o.t_s,
            points: v.points,
            rms_px: v.rms_px,
            strays: v.strays,
            rvec: v.rvec,
            tvec: v.tvec,
        });
    }
    let rejected = cal
        .rejected
        .iter()
        .map(|r| RejectedJson {
            view: r.view,
            window_seq: origins.get(r.view).map(|o| o.window_seq),
            reason: r.reason.clone(),
        })
        .collect();
    Ok(ResultJson {
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        k1: k.k1,
        k2: k.k2,
        p1: k.p1,
        p2: k.p2,
        k3: k.k3,
        rms_px: cal.rms_px,
        views_used: cal.views.len(),
        windows: counts.windows,
        detections: counts.detections,
        per_view,
        image_width: cal.image_size[0],
        image_height: cal.image_size[1],
        mean_view_px: cal.mean_view_px,
        median_view_px: cal.median_view_px,
        std_dev: Intrinsics::from_array(cal.std_dev),
        sigma_groups: cal.sigma_groups,
        sigma_group_s: cal.sigma_group_s.filter(|_| cal.sigma_groups.is_some()),
        rejected,
        stray_points: cal.stray_points,
        rms_all_px: cal.rms_all_px,
        warnings: cal.warnings.clone(),
        iterations: cal.iterations,
        converged: cal.converged,
        edge_shift: None,
        circle_radius_m: cal.circle_radius_m,
        calibration_failed: None,
        precision_bins: cal.precision_bins.clone(),
        verdict: None,
        verdict_actions: Vec::new(),
        k3_held: None,
        projection_sigma_px: None,
    })
}

#[cfg(test)]
mod test {
    use super::super::testdata::*;
    use super::*;
    use crate::calib::{calibrate, synthetic_views, Options};

    /// The keys other programs read, in order.
    const KEYS: [&str; 14] = [
        "fx",
        "fy",
        "cx",
        "cy",
        "k1",
        "k2",
        "p1",
        "p2",
        "k3",
        "rms_px",
        "views_used",
        "windows",
        "detections",
        "per_view",
    ];

    /// The top-level keys of a JSON object in the order written, read off the text (a
    /// `serde_json::Value` sorts them).
    fn top_keys(text: &str) -> Vec<String> {
        let mut keys = Vec::new();
        let (mut depth, mut in_str, mut escaped, mut start) = (0, false, false, 0);
        for (i, c) in text.char_indices() {
            if in_str {
                match c {
                    _ if escaped => escaped = false,
                    '\\' => escaped = true,
                    '"' => {
                        in_str = false;
                        if depth == 1 && text[i + 1..].trim_start().starts_with(':') {
                            keys.push(text[start..i].to_string());
                        }
                    }
                    _ => {}
                }
                continue;
            }
            match c {
                '"' => {
                    in_str = true;
                    start = i + 1;
                }
                '{' | '[' => depth += 1,
                '}' | ']' => depth -= 1,
                _ => {}
            }
        }
        keys
    }

    #[test]
    fn keys_and_round_trip() {
        let (views, cal, origins, _) = setup(&TRUTH, false);
        let counts = RunCounts { windows: 4 * views.len() as u64, detections: views.len() as u64 };
        let json = result_json(&cal, &origins, counts).unwrap();
        let text = serde_json::to_string_pretty(&json).unwrap();
        let keys = top_keys(&text);
        assert_eq!(keys[..KEYS.len()], KEYS, "{text}");
        for extra in [
            "std_dev",
            "sigma_groups",
            "rejected",
            "warnings",
            "image_width",
            "image_height",
            "median_view_px",
            "mean_view_px",
        ] {
            assert!(keys[KEYS.len()..].iter().any(|k| k == extra), "{extra} missing: {keys:?}");
        }

        // Read back with the generic parser, as another program would.
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        let k = cal.intrinsics;
        for (name, want) in ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"].iter().zip(k.to_array()) {
            // serde_json parses floats to within an ulp unless its float_roundtrip feature is on.
            assert!(close(v[name].as_f64().unwrap(), want), "{name}");
        }
        assert!(close(v["rms_px"].as_f64().unwrap(), cal.rms_px));
        assert_eq!(v["views_used"], cal.views.len());
        assert_eq!(v["windows"], counts.windows);
        assert_eq!(v["detections"], counts.detections);
        assert_eq!(v["image_width"], 346);
        assert_eq!(v["std_dev"]["fx"].as_f64().map(|x| close(x, cal.std_dev[0])), Some(true));
        let per_view = v["per_view"].as_array().unwrap();
        assert_eq!(per_view.len(), cal.views.len());
        for (p, r) in per_view.iter().zip(&cal.views) {
            let keys: Vec<&str> = p.as_object().unwrap().keys().map(String::as_str).collect();
            for key in ["view", "window_seq", "t", "points", "rms_px", "rvec", "tvec"] {
                assert!(keys.contains(&key), "{key} missing: {p}");
            }
            assert_eq!(p["view"], r.view);
            assert_eq!(p["window_seq"], origins[r.view].window_seq);
            assert!(close(p["t"].as_f64().unwrap(), origins[r.view].t_s));
            assert_eq!(p["points"], r.points);
            assert!(close(p["tvec"][2].as_f64().unwrap(), r.tvec[2]));
        }

        // And into the struct again.
        let back: ResultJson = serde_json::from_str(&text).unwrap();
        assert_eq!(back.per_view.len(), json.per_view.len());
        assert_eq!(back.views_used, json.views_used);
        assert_eq!(back.rejected, json.rejected);
        assert_eq!(back.warnings, json.warnings);
    }

    #[test]
    fn the_centres_weights_are_written_and_a_file_without_them_reads_as_weighed_alike() {
        let (views, mut cal, origins, _) = setup(&TRUTH, false);
        cal.precision_bins = vec![PrecisionBin { from: 20.0, weight: 0.25 }, PrecisionBin { from: 96.0, weight: 1.5 }];
        let counts = RunCounts { windows: views.len() as u64, detections: views.len() as u64 };
        let text = serde_json::to_string(&result_json(&cal, &origins, counts).unwrap()).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["precision_bins"][1]["from"], 96.0, "{text}");
        assert_eq!(v["precision_bins"][0]["weight"], 0.25, "{text}");
        let back: ResultJson = serde_json::from_str(&text).unwrap();
        assert_eq!(back.precision_bins, cal.precision_bins);

        // A file written before the key existed.
        let mut old: serde_json::Value = serde_json::from_str(&text).unwrap();
        old.as_object_mut().unwrap().remove("precision_bins");
        let back: ResultJson = serde_json::from_value(old).unwrap();
        assert!(back.precision_bins.is_empty());
    }

    #[test]
    fn an_unbounded_sigma_is_written_null_and_read_back_infinite() {
        let views = synthetic_views(&TRUTH, 8, 0.1, 3);
        let mut cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
        cal.std_dev[0] = f64::INFINITY;
        let origins: Vec<ViewOrigin> =
            (0..views.len()).map(|i| ViewOrigin { window_seq: i as u64, t_s: i as f64 }).collect();
        let json = result_json(&cal, &origins, RunCounts { windows: 8, detections: 8 }).unwrap();
        let text = serde_json::to_string(&json).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(v["std_dev"]["fx"].is_null(), "{}", v["std_dev"]);
        assert_eq!(v["std_dev"]["fy"].as_f64(), Some(cal.std_dev[1]));
        let back: ResultJson = serde_json::from_str(&text).unwrap();
        assert_eq!(back.std_dev.fx, f64::INFINITY);
        assert_eq!(back.std_dev.fy, cal.std_dev[1]);
    }

    #[test]
    fn rejected_views_keep_their_reason_and_window() {
        // Three views with too few points: set aside, the others calibrate.
        let mut views = synthetic_views(&TRUTH, 8, 0.1, 3);
        for v in views.iter_mut().step_by(3) {
            v.object.truncate(4);
            v.image.truncate(4);
        }
        let cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
        assert_eq!(cal.rejected.len(), 3);
        let origins: Vec<ViewOrigin> =
            (0..views.len()).map(|i| ViewOrigin { window_seq: 100 + i as u64, t_s: i as f64 }).collect();
        let json = result_json(&cal, &origins, RunCounts::default()).unwrap();
        assert_eq!(json.rejected.iter().map(|r| r.window_seq).collect::<Vec<_>>(), [Some(100), Some(103), Some(106)]);
        assert!(json.rejected.iter().all(|r| r.reason.contains("points")), "{:?}", json.rejected);
        // A used view without an origin is an error naming it.
        let e = result_json(&cal, &origins[..1], RunCounts::default()).unwrap_err().to_string();
        assert!(e.contains("view 1 was used but has no origin"), "{e}");
    }
}
