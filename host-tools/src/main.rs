//! `evcal`: calibrate event cameras from an asymmetric circle grid.

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use evcal_core::{
    cluster::ClusterConfig,
    detect::DetectConfig,
    event::SensorSize,
    fit::{FitConfig, FitMethod},
    window::WindowConfig,
};
use evcal_host::{
    detections::{self, WindowRecord},
    recording::{guess_sensor, parse_sensor, Recording},
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
