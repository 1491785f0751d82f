//! Calibrates recordings of an independent pixel emulator against their ground truth.
//!
//! `cargo run --release -p evcal-tests --example emulator -- DIR...`: each DIR holds
//! `events.h5` and `truth.json` as `../shared/data/independent-emulator/` lays them out
//! (K, distortion, pattern, poses at 30 Hz). Each recording goes through what `evcal
//! calibrate` does with its defaults; one table row per recording: fx, fy error (%), cx, cy
//! error (px), each also in units of the printed σ, the RMS and the views used.
//!
//! `--truth FILE` takes the truth from FILE instead of each DIR's `truth.json`: for a
//! recording of the same motion made by `evcal simulate --poses FILE` (evcal's own pixels
//! on that motion), whose rows and cached detections are then named after its folder.
//!
//! `--detections DIR` reads (or, the first time, writes) each recording's detection windows
//! as `DIR/<name>.jsonl`, so that a rerun skips the detection core. `--diagnose` also solves
//! the same views on the true centres (projected circle centres, and projected ellipse
//! centres) and prints how the detected centres err against the truth. `--no-edge-shift` and
//! `--no-smoothing` switch those steps off, `--fix-k3` holds k3 at 0 and `--free-k3` solves it
//! whatever the views say, as `evcal calibrate`'s flags of the same names do.
//!
//! For experiments on the detection (they bypass `--detections`' cache):
//! `--events-per-window N` and `--step-ms MS` cut the windows as `evcal calibrate`'s options
//! of the same names do; `--trail-filter-ms T` drops every event whose pixel fired the same
//! polarity less than T ms before (a burst or "trail" filter, as some sensors offer on chip:
//! it keeps the onset of each edge's burst and drops the slow settling behind it; this is a
//! measurement, evcal does not filter so). `--span FROM-TO` keeps only the events from FROM to TO
//! seconds after the recording's first: a shorter recording of the same kind, to see whether
//! the printed σ still covers the error when there is less to go on.
//!
//! A row whose σ leaves the camera unfixed (`evcal calibrate` then says the calibration
//! failed, exits with status 3 and marks its files) is named "(no calibration)".

use evcal_core::event::{Event, SensorSize};
use evcal_host::{
    calib::{calibrate, Intrinsics, Options, View},
    input::detections::{self, read_jsonl, WindowRecord},
    input::recording::{ReadError, Recording},
    pipeline::{calibrate_with_disc_fallback, views_from_windows, Chosen, DiscFallback, Outcome, Setup},
};
use nalgebra::{Rotation3, Vector3};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[path = "emulator/diagnose.rs"]
mod diagnose;
#[path = "emulator/images.rs"]
mod images;
#[path = "emulator/mapping.rs"]
mod mapping;

#[derive(Deserialize)]
struct Truth {
    name: String,
    sensor: SensorJson,
    #[serde(rename = "K")]
    k: KJson,
    dist: DistJson,
    pattern: PatternJson,
    frames30: Frames,
}
#[derive(Deserialize)]
struct SensorJson {
    width: u16,
    height: u16,
}
#[derive(Deserialize)]
struct KJson {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}
#[derive(Deserialize)]
struct DistJson {
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
}
#[derive(Deserialize)]
struct PatternJson {
    rows: usize,
    cols: usize,
    spacing_m: f64,
    radius_m: f64,
}
#[derive(Deserialize)]
struct Frames {
    frames: Vec<FrameJson>,
}
#[derive(Deserialize)]
struct FrameJson {
    t: f64,
    rvec: [f64; 3],
    tvec: [f64; 3],
}

impl Truth {
    fn intrinsics(&self) -> Intrinsics {
        let (k, d) = (&self.k, &self.dist);
        Intrinsics { fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy, k1: d.k1, k2: d.k2, p1: d.p1, p2: d.p2, k3: d.k3 }
    }

    /// The pose at `t` seconds: Catmull–Rom through the 30 Hz poses (rvec and tvec
    /// component by component; the motion is smooth at that scale).
    fn pose_at(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let f = &self.frames30.frames;
        let dt = f[1].t - f[0].t;
        let s = ((t - f[0].t) / dt).clamp(0.0, (f.len() - 1) as f64 - 1e-9);
        let i = s.floor() as usize;
        let u = s - i as f64;
        let at = |k: isize| &f[k.clamp(0, f.len() as isize - 1) as usize];
        let i = i as isize;
        let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
        let cr = |a: f64, b: f64, c: f64, d: f64| {
            0.5 * (2.0 * b
                + (-a + c) * u
                + (2.0 * a - 5.0 * b + 4.0 * c - d) * u * u
                + (-a + 3.0 * b - 3.0 * c + d) * u * u * u)
        };
        let r = [0, 1, 2].map(|k| cr(p0.rvec[k], p1.rvec[k], p2.rvec[k], p3.rvec[k]));
        let tv = [0, 1, 2].map(|k| cr(p0.tvec[k], p1.tvec[k], p2.tvec[k], p3.tvec[k]));
        (r, tv)
    }
}

/// How the detection of an experiment differs from `evcal calibrate`'s.
#[derive(Default, Clone, Copy)]
struct Experiment {
    events_per_window: Option<usize>,
    step_ms: Option<f64>,
    trail_filter_ms: Option<f64>,
    span_s: Option<(f64, f64)>,
}

impl Experiment {
    fn any(&self) -> bool {
        self.events_per_window.is_some()
            || self.step_ms.is_some()
            || self.trail_filter_ms.is_some()
            || self.span_s.is_some()
    }
}

/// The events from `from` to `to` seconds after the first event (errors pass through).
fn within(
    events: impl Iterator<Item = Result<Event, ReadError>>,
    (from, to): (f64, f64),
) -> impl Iterator<Item = Result<Event, ReadError>> {
    let mut first = None;
    events.filter(move |e| match e {
        Ok(e) => {
            let t0 = *first.get_or_insert(e.t_us);
            let s = e.t_us.saturating_sub(t0) as f64 * 1e-6;
            (from..to).contains(&s)
        }
        Err(_) => true,
    })
}

/// Drops each event whose pixel fired the same polarity less than `ms` before (any event of
/// it, kept or not, restarts the wait): only the first event of each burst passes.
fn trail_filter(
    events: impl Iterator<Item = Result<Event, ReadError>>,
    sensor: SensorSize,
    ms: f64,
) -> impl Iterator<Item = Result<Event, ReadError>> {
    let width = usize::from(sensor.width);
    let mut last = vec![[i64::MIN / 2; 2]; width * usize::from(sensor.height)];
    let wait_us = (ms * 1e3) as i64;
    events.filter(move |e| {
        let Ok(e) = e else { return true };
        let Some(seen) = last.get_mut(usize::from(e.y) * width + usize::from(e.x)) else { return true };
        let t = e.t_us as i64;
        let keep = t - seen[usize::from(e.polarity)] >= wait_us;
        seen[usize::from(e.polarity)] = t;
        keep
    })
}

/// The core's windows of a recording; with filled discs where no ring fits when
/// `filled_discs` (as `evcal calibrate` detects again when the rings give no calibration).
fn windows_of(
    dir: &Path,
    name: &str,
    cache: Option<&Path>,
    sensor: SensorSize,
    x: Experiment,
    filled_discs: bool,
) -> Vec<WindowRecord> {
    let suffix = if filled_discs { "-filled-discs" } else { "" };
    let file = if x.any() { None } else { cache.map(|c| c.join(format!("{name}{suffix}.jsonl"))) };
    if let Some(w) = file.as_ref().and_then(|f| std::fs::File::open(f).ok()) {
        if let Ok(w) = read_jsonl(std::io::BufReader::new(w)) {
            return w;
        }
    }
    let path = dir.join("events.h5");
    let rec = Recording::open(&path).unwrap_or_else(|e| {
        eprintln!("{}: {e}", path.display());
        std::process::exit(1)
    });
    let mut windows = Vec::new();
    let mut cfg = if filled_discs { detections::host_disc_config(sensor) } else { detections::host_config(sensor) };
    if let Some(n) = x.events_per_window {
        cfg.window.events = n;
    }
    if let Some(ms) = x.step_ms {
        cfg.window.step_us = (ms * 1e3).round() as u64;
    }
    let events: Box<dyn Iterator<Item = Result<Event, ReadError>>> = match x.span_s {
        Some(span) => Box::new(within(rec, span)),
        None => Box::new(rec),
    };
    let events: Box<dyn Iterator<Item = Result<Event, ReadError>>> = match x.trail_filter_ms {
        Some(ms) => Box::new(trail_filter(events, sensor, ms)),
        None => events,
    };
    detections::run(events, cfg, |d| windows.push(WindowRecord::from_detection(d))).unwrap_or_else(|e| {
        eprintln!("{}: {e}", path.display());
        std::process::exit(1)
    });
    if let Some(f) = file {
        let _ = std::fs::create_dir_all(f.parent().unwrap_or(Path::new(".")));
        let text: String = windows.iter().map(|w| w.to_json_line() + "\n").collect();
        let _ = std::fs::write(f, text);
    }
    windows
}

/// fx, fy relative error (%), cx, cy error (px).
fn errors(got: &Intrinsics, truth: &Intrinsics) -> [f64; 4] {
    [
        100.0 * (got.fx - truth.fx) / truth.fx,
        100.0 * (got.fy - truth.fy) / truth.fy,
        got.cx - truth.cx,
        got.cy - truth.cy,
    ]
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut path = |name: &str, what: &str| -> Option<PathBuf> {
        let i = args.iter().position(|a| a == name)?;
        if i + 1 >= args.len() {
            eprintln!("{name} needs {what}");
            std::process::exit(2);
        }
        let p = PathBuf::from(args.remove(i + 1));
        args.remove(i);
        Some(p)
    };
    let (cache, truth_file) = (path("--detections", "a folder"), path("--truth", "a file"));
    let span_s = args.iter().position(|a| a == "--span").map(|i| {
        let span = args.get(i + 1).and_then(|v| {
            let (a, b) = v.split_once('-')?;
            let (a, b) = (a.parse::<f64>().ok()?, b.parse::<f64>().ok()?);
            (a.is_finite() && b.is_finite() && 0.0 <= a && a < b).then_some((a, b))
        });
        let Some(span) = span else {
            eprintln!("--span needs FROM-TO in seconds, FROM < TO (e.g. 0-4)");
            std::process::exit(2);
        };
        args.drain(i..i + 2);
        span
    });
    let mut value = |name: &str| -> Option<f64> {
        let i = args.iter().position(|a| a == name)?;
        let v = args.get(i + 1).and_then(|v| v.parse::<f64>().ok()).filter(|v| v.is_finite() && *v > 0.0);
        let Some(v) = v else {
            eprintln!("{name} needs a positive number");
            std::process::exit(2);
        };
        args.drain(i..i + 2);
        Some(v)
    };
    let experiment = Experiment {
        span_s,
        events_per_window: value("--events-per-window").map(|v| v as usize),
        step_ms: value("--step-ms"),
        trail_filter_ms: value("--trail-filter-ms"),
    };
    let mut flag = |name: &str| args.iter().position(|a| a == name).map(|i| args.remove(i)).is_some();
    let (diagnose, no_edge_shift, no_smoothing) = (flag("--diagnose"), flag("--no-edge-shift"), flag("--no-smoothing"));
    let (fix_k3, free_k3) = (flag("--fix-k3"), flag("--free-k3"));
    if args.is_empty() {
        eprintln!(
            "usage: emulator [--detections DIR] [--truth FILE] [--diagnose] [--no-edge-shift] [--no-smoothing] [--fix-k3 | --free-k3] \
             [--events-per-window N] [--step-ms MS] [--trail-filter-ms T] [--span FROM-TO] RECORDING_DIR..."
        );
        std::process::exit(2);
    }
    println!("| recording | fx error | fy error | cx error | cy error | fx, fy, cx, cy error / σ | RMS | views |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut mappings = Vec::new();
    for dir in args.iter().map(PathBuf::from) {
        let truth_path = truth_file.clone().unwrap_or_else(|| dir.join("truth.json"));
        let mut truth: Truth =
            std::fs::read(&truth_path).ok().and_then(|b| serde_json::from_slice(&b).ok()).unwrap_or_else(|| {
                eprintln!("{}: no readable truth", truth_path.display());
                std::process::exit(1)
            });
        if truth_file.is_some() {
            // Another recording of the same motion: named (and cached) as its folder.
            truth.name = dir.file_name().map_or_else(|| "recording".into(), |n| n.to_string_lossy().into_owned());
        }
        let k = truth.intrinsics();
        let sensor = SensorSize { width: truth.sensor.width, height: truth.sensor.height };
        let mut windows = windows_of(&dir, &truth.name, cache.as_deref(), sensor, experiment, false);
        let pattern =
            evcal_host::views::grid::Pattern::new(truth.pattern.rows, truth.pattern.cols, truth.pattern.spacing_m)
                .expect("a valid pattern");
        let mut setup = Setup::new(pattern, [u32::from(sensor.width), u32::from(sensor.height)]);
        setup.edge_shift = !no_edge_shift;
        setup.calib.fix_k3 = fix_k3;
        setup.k3_only_if_demanded = !free_k3;
        if no_smoothing {
            setup.smooth = None;
        }
        let views = views_from_windows(&windows, &setup, &|_| {});
        // As `evcal calibrate`: filled discs where the rings give no calibration; their
        // windows kept for `--diagnose` should they be taken.
        let mut disc_windows = Vec::new();
        let discs = |_: &_| {
            disc_windows = windows_of(&dir, &truth.name, cache.as_deref(), sensor, experiment, true);
            Ok::<_, std::convert::Infallible>(Some(views_from_windows(&disc_windows, &setup, &|_| {})))
        };
        let Ok(Chosen { views, result, fallback }) = calibrate_with_disc_fallback(views, &setup, discs);
        let mut name = truth.name.clone();
        if matches!(fallback, DiscFallback::Taken { .. }) {
            windows = disc_windows;
            name += " (filled discs)";
        }
        let out = match result {
            Ok(o) => o,
            Err(e) => {
                println!("| {name} | failed: {e} | | | | | | |");
                continue;
            }
        };
        let c = &out.calibration;
        if out.failure.is_some() {
            name += " (no calibration)";
        }
        mappings.push(mapping::row(&name, &mapping::mapping(&k, c, &out.used)));
        let e = errors(&c.intrinsics, &k);
        let sd = [100.0 * c.std_dev[0] / k.fx, 100.0 * c.std_dev[1] / k.fy, c.std_dev[2], c.std_dev[3]];
        let sig: Vec<String> = (0..4).map(|i| format!("{:+.1}", e[i] / sd[i])).collect();
        println!(
            "| {} | {:+.3} % (σ {:.3}) | {:+.3} % | {:+.2} px (σ {:.2}) | {:+.2} px | {} | {:.3} px | {} |",
            name,
            e[0],
            sd[0],
            e[1],
            e[2],
            sd[2],
            e[3],
            sig.join(", "),
            c.rms_px,
            c.views.len()
        );
        if diagnose {
            println!(
                "    circle radius estimated {:.2} mm (true {:.2} mm)",
                1e3 * views.circle_radius_m.unwrap_or(f64::NAN),
                1e3 * truth.pattern.radius_m
            );
            if let Some(s) = out.edge_shift {
                println!("    edge shift {:+.3} px (σ {:.3}, {} points)", s.px, s.std_px, s.points);
            }
            diagnose::diagnose_run(&truth, &k, &windows, &out, &setup);
        }
    }
    println!("\n{}", mapping::header());
    for r in &mappings {
        println!("{r}");
    }
}
