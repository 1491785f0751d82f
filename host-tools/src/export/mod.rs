//! What a calibration leaves behind for the user's own stack: OpenCV's `cv::FileStorage`
//! YAML, ROS's `camera_info` YAML, a Kalibr camchain, a JSON result for programs, and a PNG
//! report for people. Before any of that, [`board`] lays out the grid to print.
//!
//! ```no_run
//! use evcal_host::calib::{calibrate, Options, View};
//! use evcal_host::export::{write_all, Export, RunCounts};
//! use evcal_host::views::{ViewOrigin, WindowSample};
//! # fn run(views: Vec<View>, origins: Vec<ViewOrigin>, timeline: Vec<WindowSample>) -> anyhow::Result<()> {
//! let cal = calibrate(&views, [346, 260], &Options::default())?;
//! let export = Export {
//!     counts: RunCounts { windows: timeline.len() as u64, detections: 120 },
//!     ..Export::new(&cal, &views, &origins, &timeline)
//! };
//! let written = write_all(std::path::Path::new("calibration-out"), &export)?;
//! for w in &written.warnings {
//!     eprintln!("warning: {w}");
//! }
//! # Ok(()) }
//! ```
//!
//! The YAML files are written by hand rather than through a YAML library: each consumer
//! (OpenCV's own parser, yaml-cpp in ROS, PyYAML in Kalibr) accepts a different subset of
//! YAML, and the layouts here are the ones those tools write themselves. Every number is
//! written with the shortest digits that read back to the same `f64`.

pub mod atomic;
pub mod board;
mod heatmap;
mod json;
mod report;
mod stale;
mod yaml;

pub use json::{result_json, K3HeldJson, PerViewJson, ProjectionSigmaJson, RejectedJson, ResultJson};
pub use report::{render_report, write_report, Notes, FRAMES, NOTE_LINES, REPORT_SIZE};
pub use stale::{remove_stale, written_by_evcal, Stale, YAML_MARK};
pub use yaml::{camera_info_yaml, kalibr_camchain_yaml, opencv_yaml};

use crate::calib::{Calibration, ProjectionSigma, View, PROJECTION_SIGMA_STEP_PX};
use crate::views::{ViewOrigin, WindowSample};
use std::path::{Path, PathBuf};

/// Why an export could not be written. Every error names the file it concerns, or the
/// mismatch between the calibration and what was handed over with it.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// An output was refused or could not be written ([`atomic`]).
    #[error(transparent)]
    Output(#[from] atomic::OutputError),
    /// A file or directory could not be written.
    #[error("{}: {what}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What could not be done.
        what: &'static str,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// The report could not be drawn.
    #[error("{}: cannot draw the report: {message}", path.display())]
    Report {
        /// The report's file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// A view the calibration used has no origin, or is missing.
    #[error("{0}")]
    Mismatch(String),
    /// The JSON result could not be encoded.
    #[error("the JSON result: {0}")]
    Json(#[from] serde_json::Error),
}

impl From<crate::views::MissingView> for ExportError {
    fn from(e: crate::views::MissingView) -> Self {
        Self::Mismatch(e.to_string())
    }
}

/// The exports' results.
pub type Result<T, E = ExportError> = std::result::Result<T, E>;

/// An I/O error about `path`.
fn io_at(path: &Path, what: &'static str) -> impl FnOnce(std::io::Error) -> ExportError {
    let path = path.to_path_buf();
    move |source| ExportError::Io { path, what, source }
}

/// How much of the recording became views: the JSON result's `windows` and `detections`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RunCounts {
    /// Detection windows looked at.
    pub windows: u64,
    /// Windows in which the grid was found.
    pub detections: u64,
}

/// Everything [`write_all`] writes from. [`Export::new`] fills in the defaults; set the
/// other fields with struct update syntax.
#[derive(Debug, Clone, Copy)]
pub struct Export<'a> {
    /// The calibration written to the JSON, OpenCV and ROS files and drawn in the report.
    pub calibration: &'a Calibration,
    /// The calibration the Kalibr camchain is written from, when it differs: Kalibr's radtan
    /// model has no k3, so a solve with k3 fixed at 0 fits it exactly. `None`: `calibration`.
    pub kalibr_calibration: Option<&'a Calibration>,
    /// The views calibrated from, in the order given to the solver.
    pub views: &'a [View],
    /// Where each view came from, indexed like `views`.
    pub origins: &'a [ViewOrigin],
    /// Every detection window, for the report's timeline.
    pub timeline: &'a [WindowSample],
    /// Every circle centre detected in each view's window, indexed like `views`, for the
    /// report's windows ([`Notes::centres`]). Empty: the grid drawn alone.
    pub centres: &'a [Vec<[f64; 2]>],
    /// The events of each view's window as pixels, indexed like `views`, for the report's
    /// windows ([`Notes::events`]). Empty, or an empty list: not kept.
    pub events: &'a [Vec<[u16; 2]>],
    /// Windows looked at and grids found.
    pub counts: RunCounts,
    /// `camera_name` of the ROS file.
    pub camera_name: &'a str,
    /// `rostopic` of the Kalibr camchain.
    pub rostopic: &'a str,
    /// `calibration_time` of the OpenCV file, as the user wants it shown (OpenCV's sample
    /// writes `asctime`'s form); `None` leaves the entry out.
    pub calibration_time: Option<&'a str>,
    /// The shift taken out of the centres before the solve, for the JSON result.
    pub edge_shift: Option<crate::views::edge_shift::EdgeShift>,
    /// Why the result is no calibration ([`crate::pipeline::loose_params`]): then the files are
    /// [`FAILED_FILE_NAMES`], none a program would load as a calibration (the JSON under
    /// another name with its `calibration_failed`, each YAML file's entries commented out
    /// below `calibration_failed`, so no `camera_matrix`; the report stamped), and
    /// `json_copy` is not written.
    pub failure: Option<&'a str>,
    /// The run's verdict ([`crate::pipeline::Verdict`]): in the JSON result's `verdict` and
    /// `verdict_actions`, and on the report. `None` leaves them out (`null`).
    pub verdict: Option<&'a crate::pipeline::Verdict>,
    /// What the run advises beside the solver's warnings (coverage, tilt, views), drawn on
    /// the report with them.
    pub advice: &'a [String],
    /// k3 held at 0 because the views do not demand it: what the solve with it free said
    /// (value, σ), for the JSON result's `k3_held`.
    pub k3_held: Option<(f64, f64)>,
    /// Another file to write the JSON result to (`evcal calibrate --json`), with the others:
    /// all are in place or none is replaced. Nothing more when it is the folder's own
    /// `calibration.json`; nothing at all for a failed run (see `failure`).
    pub json_copy: Option<&'a Path>,
}

impl<'a> Export<'a> {
    /// An export of `calibration` made from `views`, with the counts taken from the timeline,
    /// camera name `dvs`, topic `/dvs/events` (the names of the rpg_dvs_ros driver) and no
    /// calibration time.
    pub fn new(
        calibration: &'a Calibration,
        views: &'a [View],
        origins: &'a [ViewOrigin],
        timeline: &'a [WindowSample],
    ) -> Self {
        Self {
            calibration,
            kalibr_calibration: None,
            views,
            origins,
            timeline,
            centres: &[],
            events: &[],
            counts: RunCounts {
                windows: timeline.len() as u64,
                detections: timeline.iter().filter(|w| w.grid_found).count() as u64,
            },
            camera_name: "dvs",
            rostopic: "/dvs/events",
            calibration_time: None,
            edge_shift: None,
            failure: None,
            verdict: None,
            advice: &[],
            k3_held: None,
            json_copy: None,
        }
    }
}

/// What [`write_all`] did.
#[derive(Debug, Default)]
pub struct Written {
    /// The files written, in the order of [`FILE_NAMES`] (or [`FAILED_FILE_NAMES`]).
    pub paths: Vec<PathBuf>,
    /// What the user should know about the exports (also in the JSON's `warnings`).
    pub warnings: Vec<String>,
    /// The other outcome's files an earlier run left in the folder (a calibration's beside
    /// a failed run's, or the reverse), removed so that none is taken for this run's; and
    /// those that were left (see [`remove_stale`]).
    pub stale: Stale,
}

/// The files [`write_all`] writes for a calibration, in order: JSON result, OpenCV YAML, ROS
/// `camera_info`, Kalibr camchain, report.
pub const FILE_NAMES: [&str; 5] =
    ["calibration.json", "opencv.yaml", "camera_info.yaml", "kalibr_camchain.yaml", "report.png"];

/// The files [`write_all`] writes for a result that is no calibration, in the order of
/// [`FILE_NAMES`]: named so that no program looking for a calibration's file finds one.
pub const FAILED_FILE_NAMES: [&str; 5] = [
    "calibration.failed.json",
    "opencv.failed.yaml",
    "camera_info.failed.yaml",
    "kalibr_camchain.failed.yaml",
    "report.failed.png",
];

/// The files [`write_all`] writes for a calibration (`failed` false) or for a result that is
/// none.
pub const fn file_names(failed: bool) -> [&'static str; 5] {
    if failed {
        FAILED_FILE_NAMES
    } else {
        FILE_NAMES
    }
}

/// Writes every export into `dir` (made if missing) under the names of [`FILE_NAMES`];
/// returns the paths and the warnings. Every error names the file it concerns.
///
/// Each file is written to a temporary file beside it first and all are renamed into place
/// at the end ([`atomic`]): a failure (a report that cannot be drawn, a full disk) replaces
/// none of an earlier run's files. A link at one of the names is replaced, not followed.
/// Each YAML file ends with [`YAML_MARK`] and the report names evcal as its software, so
/// that [`remove_stale`] can tell evcal's files from others.
pub fn write_all(dir: &Path, export: &Export<'_>) -> Result<Written> {
    std::fs::create_dir_all(dir).map_err(io_at(dir, "cannot create the directory"))?;
    let cal = export.calibration;
    let kalibr_cal = export.kalibr_calibration.unwrap_or(cal);
    // Warnings first, so that the JSON carries them too.
    let (kalibr, warnings) = kalibr_camchain_yaml(kalibr_cal, export.rostopic);
    let mut json = result_json(cal, export.origins, export.counts)?;
    json.edge_shift = export.edge_shift;
    json.calibration_failed = export.failure.map(str::to_owned);
    if let Some(v) = export.verdict {
        json.verdict = Some(v.grade().to_owned());
        json.verdict_actions = v.actions().to_vec();
    }
    json.k3_held = export.k3_held.map(|(free, std)| json::K3HeldJson { free, std });
    json.warnings.extend(warnings.iter().cloned());
    json.projection_sigma_px =
        ProjectionSigma::of(cal, export.views, PROJECTION_SIGMA_STEP_PX).as_ref().map(ProjectionSigmaJson::from);
    let json = serde_json::to_string_pretty(&json)? + "\n";

    let path = |name: &str| dir.join(name);
    let names = file_names(export.failure.is_some());
    let mut written = Written { paths: Vec::with_capacity(names.len()), warnings, stale: Stale::default() };
    let mut texts =
        [json, opencv_yaml(cal, export.calibration_time), camera_info_yaml(cal, export.camera_name), kalibr];
    if let Some(why) = export.failure {
        for t in &mut texts[1..] {
            *t = not_a_calibration(t, why);
        }
    }
    for t in &mut texts[1..] {
        t.push_str(&yaml_mark());
    }
    let report = path(names[4]);
    let verdict = export.verdict.map(ToString::to_string);
    let all_warnings: Vec<String> =
        cal.warnings.iter().chain(&written.warnings).chain(export.advice).cloned().collect();
    let notes = Notes {
        failure: export.failure,
        verdict: verdict.as_deref(),
        warnings: &all_warnings,
        centres: export.centres,
        events: export.events,
    };
    let png = render_report(&report, cal, export.views, export.origins, export.timeline, &notes)?;
    let mut contents: Vec<(PathBuf, &[u8])> =
        names.iter().map(|n| path(n)).zip(texts.iter().map(|t| t.as_bytes())).collect();
    contents.push((report, &png));
    // Every file written before any is put in place.
    let mut staged = Vec::with_capacity(contents.len() + 1);
    let copy = export.json_copy.filter(|j| export.failure.is_none() && !atomic::same_file(j, &contents[0].0));
    for (p, bytes) in contents.iter().map(|(p, b)| (p.as_path(), *b)).chain(copy.map(|j| (j, texts[0].as_bytes()))) {
        let mut f = atomic::AtomicFile::create(p)?;
        std::io::Write::write_all(&mut f, bytes).map_err(io_at(p, "cannot write"))?;
        staged.push(f);
    }
    for f in staged {
        f.commit()?;
    }
    written.paths.extend(contents.into_iter().map(|(p, _)| p));
    // The other outcome's files, and for a failed run the `--json` copy, are an earlier
    // run's: a program would take a calibration's for this run's.
    let other = file_names(export.failure.is_none());
    let stale_copy = export.json_copy.filter(|_| export.failure.is_some());
    written.stale = stale::remove_named(dir, &other, stale_copy);
    Ok(written)
}

/// The line that ends each YAML file evcal writes: `# written by evcal VERSION`.
fn yaml_mark() -> String {
    format!("{YAML_MARK} {}\n", env!("CARGO_PKG_VERSION"))
}

/// `yaml` as a failed run writes it: OpenCV's directive and document start as they are
/// (they must come first), then why it is no calibration, as a comment and as the entry
/// `calibration_failed`, then every other line commented out. A reader finds no
/// `camera_matrix` (nor `K`, nor `intrinsics`), and a person still reads the estimate.
fn not_a_calibration(yaml: &str, why: &str) -> String {
    let why = why.replace('\n', " ");
    let mut out = String::with_capacity(yaml.len() + why.len() + 64);
    let mut lines = yaml.lines().peekable();
    while let Some(l) = lines.next_if(|l| l.starts_with("%YAML") || *l == "---") {
        out.push_str(l);
        out.push('\n');
    }
    // A JSON string is a YAML double-quoted scalar, escapes and all.
    let quoted = serde_json::to_string(&why).unwrap_or_else(|_| "\"\"".into());
    out.push_str(&format!("# NOT A CALIBRATION: {why}\ncalibration_failed: {quoted}\n"));
    for l in lines {
        out.push_str("# ");
        out.push_str(l);
        out.push('\n');
    }
    out
}

#[cfg(test)]
pub(crate) mod testdata {
    //! Calibrations for the tests, made by the solver from synthetic views.

    use super::*;
    use crate::calib::{calibrate, synthetic_views, Intrinsics, Options};

    pub const TRUTH: Intrinsics =
        Intrinsics { fx: 352.5, fy: 351.25, cx: 171.3, cy: 128.7, k1: -0.31, k2: 0.11, p1: 4e-4, p2: -3e-4, k3: 0.0 };

    /// Views, a calibration from them (k3 free or fixed), origins and a timeline.
    pub fn setup(truth: &Intrinsics, fix_k3: bool) -> (Vec<View>, Calibration, Vec<ViewOrigin>, Vec<WindowSample>) {
        let views = synthetic_views(truth, 14, 0.15, 11);
        let cal = calibrate(&views, [346, 260], &Options { fix_k3, ..Options::default() }).expect("calibration");
        // One view every fourth window, 10 ms apart, as a recording's detections would give.
        let origins: Vec<ViewOrigin> = (0..views.len())
            .map(|i| ViewOrigin { window_seq: 4 * i as u64 + 2, t_s: (4 * i + 2) as f64 * 0.01 })
            .collect();
        let timeline = (0..4 * views.len())
            .map(|w| WindowSample { t_s: w as f64 * 0.01, centres: 30 + (w * 7) % 15, grid_found: w % 4 == 2 })
            .collect();
        (views, cal, origins, timeline)
    }
}

#[cfg(test)]
mod test {
    use super::testdata::*;
    use super::*;

    #[test]
    fn write_all_writes_every_file() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new/sub");
        let export = Export {
            calibration_time: Some("Sat Nov 23 07:00:00 2024"),
            ..Export::new(&cal, &views, &origins, &timeline)
        };
        let written = write_all(&out, &export).unwrap();
        let want: Vec<PathBuf> = FILE_NAMES.iter().map(|n| out.join(n)).collect();
        assert_eq!(written.paths, want);
        for p in &written.paths {
            assert!(std::fs::metadata(p).unwrap().len() > 100, "{}", p.display());
        }
        // The JSON carries the export's warnings after the solver's.
        let json: ResultJson = serde_json::from_slice(&std::fs::read(&want[0]).unwrap()).unwrap();
        assert_eq!(json.warnings[cal.warnings.len()..], written.warnings[..]);
        // And the projection σ over the sensor, its grid as the calibration gives it.
        let sigma = ProjectionSigma::of(&cal, &views, PROJECTION_SIGMA_STEP_PX).expect("a projection σ");
        let got = json.projection_sigma_px.as_ref().expect("projection_sigma_px");
        assert_eq!((got.step_px, got.columns, got.rows), (8, 44, 33));
        // serde_json reads a float back to within a unit of its last digit.
        let want = ProjectionSigmaJson::from(&sigma);
        assert_eq!(got.covered, want.covered);
        for (g, w) in got.values.iter().flatten().zip(want.values.iter().flatten()) {
            assert!(g.zip(*w).is_some_and(|(g, w)| w > 0.0 && (g / w - 1.0).abs() < 1e-14), "{g:?} {w:?}");
        }
        let (covered, sensor) = (got.covered_p95_px.expect("covered"), got.sensor_worst_px.expect("sensor"));
        assert!((covered / want.covered_p95_px.expect("covered") - 1.0).abs() < 1e-14);
        assert!(covered < sensor && got.covered.iter().flatten().any(|&c| c), "{covered} {sensor}");
        assert_eq!(json.windows, timeline.len() as u64);
        assert_eq!(json.detections, views.len() as u64);
    }

    /// A failed run's files: named apart, none a program would load as a calibration
    /// (OpenCV's FileStorage finds no `camera_matrix`, PyYAML no `K` nor `cam0`), each saying
    /// why; an earlier run's calibration and its `--json` copy removed, and the failed run's
    /// files removed in turn by a calibration.
    #[test]
    fn a_failed_run_writes_no_file_a_program_loads_as_a_calibration() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let copy = dir.path().join("cam0.json");
        let good = Export { json_copy: Some(&copy), ..Export::new(&cal, &views, &origins, &timeline) };
        write_all(dir.path(), &good).unwrap();
        let why = "the views do not fix the camera: fx ±127.0 % (1σ), \"quoted\"";
        let failed = Export { failure: Some(why), ..good };
        let written = write_all(dir.path(), &failed).unwrap();
        let sorted = |names: &[&str]| {
            let mut v: Vec<String> = names.iter().map(|n| n.to_string()).collect();
            v.sort();
            v
        };
        let in_folder = || {
            let mut v: Vec<String> =
                std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
            v.sort();
            v
        };
        assert_eq!(written.paths, FAILED_FILE_NAMES.iter().map(|n| dir.path().join(n)).collect::<Vec<_>>());
        assert_eq!(in_folder(), sorted(&FAILED_FILE_NAMES));
        assert_eq!(written.stale.removed.len(), FILE_NAMES.len() + 1, "{:?}", written.stale);
        let json: ResultJson = serde_json::from_slice(&std::fs::read(&written.paths[0]).unwrap()).unwrap();
        assert_eq!(json.calibration_failed.as_deref(), Some(why));
        for p in &written.paths {
            assert!(written_by_evcal(p), "{}", p.display());
        }
        for p in &written.paths[1..4] {
            let text = std::fs::read_to_string(p).unwrap();
            assert!(text.contains(&format!("# NOT A CALIBRATION: {why}\n")), "{}: {text}", p.display());
            // Only the directive, the document start and `calibration_failed` are entries.
            for l in text.lines().filter(|l| !l.starts_with('#')) {
                assert!(
                    l.starts_with("%YAML") || l == "---" || l.starts_with("calibration_failed: "),
                    "{}: {l}",
                    p.display()
                );
            }
        }
        let cv = "import cv2, sys\nfs = cv2.FileStorage(sys.argv[1], cv2.FILE_STORAGE_READ)\nprint(fs.getNode('camera_matrix').empty(), fs.getNode('calibration_failed').string())";
        if let Some(out) = yaml::test::python("cv2", "opencv-python-headless", cv, &written.paths[1]) {
            assert_eq!(out.trim(), format!("True {why}"));
        }
        let py = "import yaml, sys\nd = yaml.safe_load(open(sys.argv[1]))\nprint(sorted(d))";
        for p in &written.paths[2..4] {
            if let Some(out) = yaml::test::python("yaml", "PyYAML", py, p) {
                assert_eq!(out.trim(), "['calibration_failed']", "{}", p.display());
            }
        }
        // A calibration then: the failed run's files go.
        let written = write_all(dir.path(), &Export::new(&cal, &views, &origins, &timeline)).unwrap();
        assert_eq!(in_folder(), sorted(&FILE_NAMES));
        assert_eq!(written.stale.removed.len(), FAILED_FILE_NAMES.len());
        let json: ResultJson = serde_json::from_slice(&std::fs::read(&written.paths[0]).unwrap()).unwrap();
        assert_eq!(json.calibration_failed, None);
        assert!(!std::fs::read_to_string(&written.paths[1]).unwrap().contains("NOT A CALIBRATION"));
    }

    #[test]
    fn write_all_errors_name_the_path() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        // The directory to write into is a file.
        let blocker = dir.path().join("taken");
        std::fs::write(&blocker, b"x").unwrap();
        let e = format!("{:#}", write_all(&blocker, &Export::new(&cal, &views, &origins, &timeline)).unwrap_err());
        assert!(e.contains("taken"), "{e}");
        // One of the files is a directory: none is put in place, and no temporary file is
        // left behind.
        let out = dir.path().join("out");
        std::fs::create_dir_all(out.join("camera_info.yaml")).unwrap();
        std::fs::write(out.join("calibration.json"), "earlier").unwrap();
        let e = format!("{:#}", write_all(&out, &Export::new(&cal, &views, &origins, &timeline)).unwrap_err());
        assert!(e.contains("camera_info.yaml"), "{e}");
        let mut names: Vec<String> =
            std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        names.sort();
        assert_eq!(names, ["calibration.json", "camera_info.yaml"]);
        assert_eq!(std::fs::read(out.join("calibration.json")).unwrap(), b"earlier");
        // Origins missing for the views used.
        let e =
            format!("{:#}", write_all(dir.path(), &Export::new(&cal, &views, &origins[..3], &timeline)).unwrap_err());
        assert!(e.contains("origin"), "{e}");
    }
}
