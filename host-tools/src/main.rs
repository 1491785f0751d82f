//! `evcal`: calibrate event cameras from an asymmetric circle grid.

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use evcal_core::event::Event;
use evcal_core::{
    cluster::ClusterConfig,
    detect::DetectConfig,
    event::SensorSize,
    fit::{FitConfig, FitMethod},
    window::WindowConfig,
};
use evcal_host::{
    detections::{self, WindowRecord},
    eval::{self, ScoreRules},
    recording::{guess_sensor, parse_sensor, write_ecalib_h5, write_text, Recording},
    sim::{FrameTruth, Light, SimConfig, Simulator, Trajectory},
};
use indicatif::{ProgressBar, ProgressStyle};
use std::{
    io::{BufWriter, Write},
    path::{Path, PathBuf},
};

#[derive(Parser)]
#[command(
    name = "evcal",
    version,
    about = "Calibrate event cameras (DAVIS346, DVXplorer, Prophesee) from raw events on an asymmetric circle grid",
    long_about = "evcal finds the circles of an asymmetric circle grid in raw event-camera data, \
following the E-Calib method: events are cut into windows, clustered per circle (grid-hashed \
DBSCAN), and each circle's slanted cylinder in (x, y, t) is fitted by reweighted least squares \
(eRWLS) to give sub-pixel centres. The same fixed-memory core runs on a microcontroller beside \
the sensor and here on the host.",
    after_help = "Examples:\n  evcal simulate --sensor davis346 --pattern 4x11 --seconds 5 --out rec.txt\n  \
evcal detect rec.txt --sensor 346x260 > detections.jsonl\n  evcal demo"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the detection core over a recording and print one JSON object per window.
    ///
    /// Output lines: {"seq", "t_ref_us", "events", "noise", "centers": [{"u", "v", "r",
    /// "spread", "n", "converged"}]}. Centres are in pixels at the window's reference time
    /// (its first event), with (0,0) the centre of the top-left pixel.
    Detect(DetectArgs),
    /// Simulate an event camera sweeping a circle grid; write the recording and truth.json.
    ///
    /// The recording is text (`t x y p`, first line `W H`) or, for a .h5 name, E-Calib's
    /// HDF5 layout. truth.json, written beside it, holds the camera (K, distortion, size),
    /// the grid, and for every window the detector will cut (same --events-per-window and
    /// --step-ms) the pose and each circle's true image centre at the window's t_ref: the
    /// projected ellipse's centre and the projection of the circle's centre.
    Simulate(SimulateArgs),
    /// The main job on a built-in default: simulate a DAVIS346 sweeping a 4x11 grid, run every
    /// window through the detection core, and score the centres against the truth.
    ///
    /// Writes ./evcal-out/detections.jsonl and ./evcal-out/truth.json. (Grid finding and the
    /// intrinsic solve join this command when they land.)
    Demo(DemoArgs),
}

#[derive(Args)]
struct SimulateArgs {
    /// Sensor preset.
    #[arg(long, default_value = "davis346", value_parser = ["davis346", "dvxplorer"])]
    sensor: String,
    /// Grid preset: 3x7 (34 mm), 3x9 (27 mm) or 4x11 (24 mm).
    #[arg(long, default_value = "4x11", value_parser = ["3x7", "3x9", "4x11"])]
    pattern: String,
    /// Camera motion.
    #[arg(long, value_enum, default_value_t = Trajectory::Cone)]
    trajectory: Trajectory,
    /// Lighting: good, or low (darker, far noisier).
    #[arg(long, value_enum, default_value_t = Light::Good)]
    light: Light,
    /// Simulated seconds.
    #[arg(long, default_value_t = 5.0)]
    seconds: f64,
    /// Seed of every random choice (same seed, same events).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Where to write the recording (.txt or .h5).
    #[arg(long, short)]
    out: PathBuf,
    /// Window cutting used for the truth (match what you pass to `evcal detect`).
    #[arg(long, default_value_t = evcal_core::config::DEFAULT_EVENTS_PER_WINDOW as u32,
          value_parser = clap::value_parser!(u32).range(1..=detections::HOST_MAX_EVENTS as i64))]
    events_per_window: u32,
    /// Milliseconds between window ticks (for the truth).
    #[arg(long, default_value_t = 33.333)]
    step_ms: f64,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct DemoArgs {
    /// Simulated seconds.
    #[arg(long, default_value_t = 3.0)]
    seconds: f64,
    /// Lighting.
    #[arg(long, value_enum, default_value_t = Light::Good)]
    light: Light,
    /// Output folder.
    #[arg(long, default_value = "evcal-out")]
    out: PathBuf,
}

#[derive(Args)]
struct DetectArgs {
    /// The recording: text (`t x y p`, t in seconds) or HDF5 (E-Calib's `events_data`).
    recording: PathBuf,
    #[command(flatten)]
    core: CoreArgs,
    /// Write the JSON lines here instead of standard output.
    #[arg(long, short)]
    out: Option<PathBuf>,
    /// No progress bar or summary on standard error.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args, Clone)]
struct CoreArgs {
    /// Sensor size, WxH (e.g. 346x260) or davis346 / dvxplorer. Default: from the file, else
    /// guessed from the largest coordinates (a note says so).
    #[arg(long)]
    sensor: Option<String>,
    /// Events per window (the paper: 4000; the firmware holds at most 4000).
    #[arg(long, default_value_t = evcal_core::config::DEFAULT_EVENTS_PER_WINDOW as u32,
          value_parser = clap::value_parser!(u32).range(1..=detections::HOST_MAX_EVENTS as i64))]
    events_per_window: u32,
    /// Milliseconds of event time between window ticks (the paper: 33).
    #[arg(long, default_value_t = 33.333)]
    step_ms: f64,
    /// DBSCAN radius, in coordinates normalised by the sensor size.
    #[arg(long, default_value_t = evcal_core::config::DEFAULT_EPS)]
    eps: f32,
    /// DBSCAN minimum points in a neighbourhood (the point included).
    #[arg(long, default_value_t = evcal_core::config::DEFAULT_MIN_PTS)]
    min_pts: u16,
    /// Use ST-DBSCAN: neighbours must also be within this fraction of the window's duration.
    #[arg(long)]
    eps_t: Option<f32>,
    /// Circle fit: erwls (the method), ols or centroid (for comparison).
    #[arg(long, value_enum, default_value_t = Method::Erwls)]
    method: Method,
}

#[derive(Clone, Copy, ValueEnum)]
enum Method {
    Erwls,
    Ols,
    Centroid,
}

impl CoreArgs {
    fn config(&self, sensor: SensorSize) -> Result<DetectConfig> {
        if !(self.step_ms.is_finite() && self.step_ms >= 0.0) {
            bail!("--step-ms must be a non-negative number of milliseconds");
        }
        if !(self.eps.is_finite() && self.eps > 0.0 && self.eps < 1.0) {
            bail!("--eps must be between 0 and 1 (normalised coordinates; the paper uses 0.015)");
        }
        if let Some(t) = self.eps_t {
            if !(t.is_finite() && t > 0.0) {
                bail!("--eps-t must be a positive fraction of the window's duration");
            }
        }
        Ok(DetectConfig {
            sensor,
            window: WindowConfig {
                events: self.events_per_window as usize,
                step_us: (self.step_ms * 1000.0).round() as u64,
            },
            cluster: ClusterConfig { eps: self.eps, min_pts: self.min_pts.max(1), eps_t: self.eps_t },
            fit: FitConfig {
                method: match self.method {
                    Method::Erwls => FitMethod::Erwls,
                    Method::Ols => FitMethod::Ols,
                    Method::Centroid => FitMethod::Centroid,
                },
                ..FitConfig::default()
            },
        })
    }
}

fn main() {
    let cli = Cli::parse();
    let r = match cli.command {
        Command::Detect(a) => detect(a),
        Command::Simulate(a) => simulate(a),
        Command::Demo(a) => demo(a),
    };
    if let Err(e) = r {
        eprintln!("evcal: error: {e:#}");
        std::process::exit(1);
    }
}

/// The sensor size: given, else from the file, else guessed from a pass over the events.
fn resolve_sensor(given: Option<&str>, path: &Path, rec: &Recording, quiet: bool) -> Result<SensorSize> {
    if let Some(s) = given {
        return parse_sensor(s).map_err(anyhow::Error::msg);
    }
    if let Some(s) = rec.sensor {
        return Ok(s);
    }
    let (mut mx, mut my, mut any) = (0u16, 0u16, false);
    for e in Recording::open(path)? {
        let e = e?;
        mx = mx.max(e.x);
        my = my.max(e.y);
        any = true;
    }
    if !any {
        bail!("{}: no events", path.display());
    }
    let s = guess_sensor(mx, my);
    if !quiet {
        eprintln!(
            "evcal: note: {} does not state its sensor size; using {}x{} (largest x {}, y {}); set --sensor WxH to be sure",
            path.display(),
            s.width,
            s.height,
            mx,
            my
        );
    }
    Ok(s)
}

fn progress_bar(len: u64, quiet: bool, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg:12} [{bar:30}] {percent:>3}% {elapsed} eta {eta}  {prefix}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

fn detect(a: DetectArgs) -> Result<()> {
    let rec = Recording::open(&a.recording)?;
    let sensor = resolve_sensor(a.core.sensor.as_deref(), &a.recording, &rec, a.quiet)?;
    let cfg = a.core.config(sensor)?;
    let mut out: Box<dyn Write> = match &a.out {
        Some(p) => Box::new(BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        )),
        None => Box::new(BufWriter::new(std::io::stdout().lock())),
    };
    let pb = progress_bar(rec.file_bytes, a.quiet, "detecting");
    let mut write_err: Option<std::io::Error> = None;
    let mut rec = rec;
    let mut counter = 0u64;
    // The progress position is read off the reader between events.
    let progress = std::cell::Cell::new(0u64);
    let events = std::iter::from_fn(|| {
        let e = rec.next();
        counter += 1;
        if counter % 65_536 == 0 {
            progress.set(rec.progress_bytes());
        }
        e
    });
    let summary = detections::run(events, cfg, |d| {
        pb.set_position(progress.get());
        pb.set_prefix(format!("windows {}", d.info.seq + 1));
        if write_err.is_none() {
            if let Err(e) = writeln!(out, "{}", WindowRecord::from_detection(d).to_json_line()) {
                write_err = Some(e);
            }
        }
    });
    pb.finish_and_clear();
    if let Some(e) = write_err {
        return Err(e).context("writing detections");
    }
    out.flush().context("writing detections")?;
    let s = summary?;
    if !a.quiet {
        eprintln!(
            "evcal: {} events, {} windows, {} centres; dropped: {} outside the sensor, {} back in time, {} clusters over capacity; {} events of an unfinished last window left out",
            s.events_read, s.windows, s.centres, s.out_of_sensor, s.time_backwards, s.dropped_clusters, s.events_in_last_partial_window
        );
    }
    Ok(())
}

/// Simulates with a progress bar; all events in memory.
fn run_simulation(cfg: SimConfig, seconds: f64, quiet: bool) -> Result<(Vec<Event>, Simulator)> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 3600.0) {
        bail!("--seconds must be between 0 and 3600");
    }
    let mut sim = Simulator::new(cfg);
    let pb = progress_bar((seconds * 1000.0) as u64, quiet, "simulating");
    let mut events = Vec::new();
    let mut t = 0.0;
    while t < seconds {
        t = (t + 0.05).min(seconds);
        sim.run_until(t, |b| events.extend_from_slice(b));
        pb.set_position((t * 1000.0) as u64);
        pb.set_prefix(format!("{} events", events.len()));
    }
    pb.finish_and_clear();
    Ok((events, sim))
}

/// The truth of every window the detector cuts from `events`.
fn window_truths(events: &[Event], sim: &Simulator, window: WindowConfig) -> Vec<(u32, FrameTruth)> {
    let mut w: Box<evcal_core::window::Windower<{ detections::HOST_MAX_EVENTS }>> =
        Box::new(evcal_core::window::Windower::new(window));
    events.iter().filter_map(|e| w.push(*e)).map(|info| (info.seq, sim.truth_at(info.t_ref_us))).collect()
}

fn truth_json(sim: &Simulator, windows: &[(u32, FrameTruth)]) -> serde_json::Value {
    let c = sim.config();
    serde_json::json!({
        "camera": c.camera,
        "board": { "rows": c.board.rows, "cols": c.board.cols, "spacing": c.board.spacing, "radius": c.board.radius },
        "trajectory": c.trajectory.name(),
        "light": c.light.name(),
        "seed": c.seed,
        "windows": windows.iter().map(|(seq, t)| serde_json::json!({
            "seq": seq, "t_ref_us": t.t_us, "rvec": t.rvec, "tvec": t.tvec, "circles": t.circles,
        })).collect::<Vec<_>>(),
    })
}

fn write_json(path: &Path, v: &serde_json::Value) -> Result<()> {
    let f = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    serde_json::to_writer(BufWriter::new(f), v).with_context(|| format!("writing {}", path.display()))
}

fn simulate(a: SimulateArgs) -> Result<()> {
    let cfg = SimConfig::preset(&a.sensor, &a.pattern, a.trajectory, a.light, a.seed)
        .ok_or_else(|| anyhow::anyhow!("unknown sensor or pattern preset"))?;
    if !(a.step_ms.is_finite() && a.step_ms >= 0.0) {
        bail!("--step-ms must be a non-negative number of milliseconds");
    }
    let sensor = SensorSize { width: cfg.camera.width, height: cfg.camera.height };
    let (events, sim) = run_simulation(cfg, a.seconds, a.quiet)?;
    let is_h5 = a.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("h5") || e.eq_ignore_ascii_case("hdf5"));
    if is_h5 {
        write_ecalib_h5(&a.out, &events).map_err(anyhow::Error::msg)?;
    } else {
        write_text(&a.out, Some(sensor), &events).with_context(|| format!("writing {}", a.out.display()))?;
    }
    let window = WindowConfig { events: a.events_per_window as usize, step_us: (a.step_ms * 1000.0).round() as u64 };
    let truths = window_truths(&events, &sim, window);
    let truth_path = a.out.parent().unwrap_or(Path::new(".")).join("truth.json");
    write_json(&truth_path, &truth_json(&sim, &truths))?;
    if !a.quiet {
        eprintln!(
            "evcal: {} events over {:.2} s ({} windows) -> {}; truth -> {}",
            events.len(),
            a.seconds,
            truths.len(),
            a.out.display(),
            truth_path.display()
        );
    }
    Ok(())
}

fn demo(a: DemoArgs) -> Result<()> {
    let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, a.light, 1).expect("built-in preset");
    let c = cfg.camera;
    println!("evcal demo: a simulated DAVIS346 ({}x{}) sweeps a 4x11 asymmetric circle grid (24 mm), {} light, cone motion, {:.1} s", c.width, c.height, a.light.name(), a.seconds);
    println!(
        "  true intrinsics: fx {:.2} fy {:.2} cx {:.2} cy {:.2}  k1 {:+.3} k2 {:+.3} p1 {:+.4} p2 {:+.4}",
        c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.p1, c.p2
    );
    let (events, sim) = run_simulation(cfg, a.seconds, false)?;
    println!("  simulated {} events ({:.2} M events/s)", events.len(), events.len() as f64 / a.seconds / 1e6);
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    let det = DetectConfig::new(SensorSize { width: c.width, height: c.height });
    let path = a.out.join("detections.jsonl");
    let mut out =
        BufWriter::new(std::fs::File::create(&path).with_context(|| format!("cannot create {}", path.display()))?);
    let rules = ScoreRules::default();
    let mut scores = Vec::new();
    for method in [FitMethod::Centroid, FitMethod::Ols, FitMethod::Erwls] {
        let mut d = det;
        d.fit.method = method;
        let started = std::time::Instant::now();
        let mut s = eval::Score::default();
        let mut windows = 0u64;
        let mut write_err = None;
        eval::detect_with_truth(&events, &sim, d, |w, t| {
            windows += 1;
            s.add(w, &eval::true_circles(t), &rules);
            if method == FitMethod::Erwls && write_err.is_none() {
                write_err = writeln!(out, "{}", w.to_json_line()).err();
            }
        });
        if let Some(e) = write_err {
            return Err(e).context("writing detections");
        }
        scores.push((method, s, started.elapsed().as_secs_f64() / windows.max(1) as f64));
    }
    out.flush().context("writing detections")?;
    let window = WindowConfig::default();
    write_json(&a.out.join("truth.json"), &truth_json(&sim, &window_truths(&events, &sim, window)))?;
    println!(
        "  detection core, {} windows of {} events (circles wholly in view, radius >= {} px):",
        scores[0].1.windows, window.events, rules.min_radius_px
    );
    println!("    {:<9} {:>8} {:>14} {:>12}", "fit", "found", "centre RMS px", "max px");
    for (m, s, _) in &scores {
        println!(
            "    {:<9} {:>7.1}% {:>14.3} {:>12.2}",
            format!("{m:?}"),
            100.0 * s.found_rate(),
            s.rms_px(),
            s.max_error_px
        );
    }
    println!("  (per-stage core timings: cargo bench -p evcal-host --bench core)");
    println!("  wrote {} and {}", path.display(), a.out.join("truth.json").display());
    Ok(())
}
