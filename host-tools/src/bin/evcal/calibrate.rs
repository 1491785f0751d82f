//! `evcal calibrate`: from a recording or collected detections to intrinsics and the files
//! users paste into their stack.

use crate::common::{
    no_window_error, outside_warning, progress_bar, resolve_sensor, time_order_warnings, with_position, CoreArgs,
    ReadArgs, StdoutClosed,
};
use crate::ranges;
use anyhow::{bail, Context, Result};
use clap::Args;
use evcal_core::event::SensorSize;
use evcal_host::{
    input::detections::{self, WindowRecord},
    input::event_frames::{EventFrame, FrameSampler},
    input::recording::{parse_sensor, OpenOptions, Recording, STDIN_NAME},
    pipeline::{
        calibrate_views, calibrate_with_disc_fallback, no_calibration, views_from_windows, Chosen, DiscFallback,
        NoCalibration, Outcome, PipelineError, Setup, Verdict, Views,
    },
    views::grid::Pattern,
};
use std::path::{Path, PathBuf};

mod checks;
mod console;
mod files;
use checks::{detections_sensor, transposed_finds};
use console::indent;
pub use console::{finish, report};
pub use files::{check_outputs, export, list_written, say_stale_removed};

#[derive(Args)]
pub struct CalibrateArgs {
    /// A recording (text `t x y p`, AEDAT4, ROS1 bag, HDF5: the detection core runs over it
    /// first) or detections collected earlier (`.jsonl`, as `evcal detect`, `replay` and
    /// `collect` write them). `-`: standard input, read as detections if it starts with '{'.
    pub input: PathBuf,
    #[command(flatten, next_help_heading = "Target (as printed)")]
    pub target: TargetArgs,
    /// Folder for the outputs: calibration.json, opencv.yaml, camera_info.yaml,
    /// kalibr_camchain.yaml, report.png (a result that is no calibration: *.failed.*).
    #[arg(long, default_value = "evcal-out", help_heading = "Output")]
    pub out: PathBuf,
    /// Also write the JSON result here (the same as calibration.json in --out).
    #[arg(long, value_name = "FILE", help_heading = "Output")]
    pub json: Option<PathBuf>,
    /// No progress bars or notes on standard error.
    #[arg(long, short, conflicts_with = "verbose", help_heading = "Output")]
    pub quiet: bool,
    /// Also say how the run got to its result.
    ///
    /// Each view set aside and why, the centres' smoothing and lag, the weights, how σ was
    /// computed, the coverage map and the target's layout.
    #[arg(long, short, help_heading = "Output")]
    pub verbose: bool,
    #[command(flatten, next_help_heading = "Model")]
    pub solve: SolveArgs,
    #[command(flatten, next_help_heading = "Advanced: reading the recording")]
    pub read: ReadArgs,
    #[command(flatten, next_help_heading = "Advanced: detection")]
    pub core: CoreArgs,
    /// Never fit filled discs, not even when the rings alone give no calibration.
    ///
    /// By default a recording whose ring fits give no calibration (no grid, too few views,
    /// a camera the views do not fix) is detected again with filled discs where no ring
    /// fits (see --filled-discs), and the discs' calibration is taken if it is one and its
    /// views fix the focal length within 1 % (a disc's centre may lie a pixel off its
    /// circle's, which a handful of views does not average out); the run says so.
    /// Recordings that calibrate from rings are never fitted with discs.
    #[arg(long, conflicts_with = "filled_discs", help_heading = "Advanced: detection")]
    pub no_filled_discs: bool,
}

/// The target as printed.
#[derive(Args, Clone)]
pub struct TargetArgs {
    /// The asymmetric circle grid, ROWSxCOLS: circles per column x columns.
    ///
    /// E-Calib's and OpenCV's convention; 4x11 is OpenCV's acircles pattern (`evcal target`
    /// draws it). `-v` echoes the layout; compare it with the board.
    #[arg(long, value_name = "ROWSxCOLS")]
    pub pattern: String,
    /// Spacing S in metres (OpenCV's squareSize, Kalibr's spacingMeters).
    ///
    /// Circles in one column are 2·S apart, neighbouring columns S apart (offset by S
    /// vertically). The focal length does not depend on it; the poses do.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    pub spacing: f64,
    /// Radius of the printed circles, metres.
    ///
    /// A circle seen at a slant images as an ellipse whose centre is not the image of the
    /// circle's centre (the nearer half is drawn larger); the solve models where each
    /// outline's centre lies, which takes the radius. Default: estimated from the fitted
    /// radii (a few percent short, which leaves a few thousandths of a pixel). From a
    /// twentieth of --spacing to half the diagonal spacing (0.707 --spacing), where
    /// neighbouring circles would touch.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    pub radius: Option<f64>,
}

/// What the solve may change.
#[derive(Args, Clone)]
pub struct SolveArgs {
    /// Keep k3 at 0 whatever the views say.
    ///
    /// By default k3 is held at 0 unless the views put it at least 3 σ from 0 (they rarely
    /// do: a free k3 mostly bends the model where the points never were), and the run says
    /// which; Kalibr's radtan and ROS's calibrator have no k3 either.
    #[arg(long)]
    pub fix_k3: bool,
    /// Solve k3 whatever the views say (OpenCV's five coefficients), even where they cannot
    /// tell it from 0.
    #[arg(long, conflicts_with = "fix_k3")]
    pub free_k3: bool,
    /// Keep p1 = p2 = 0.
    #[arg(long)]
    pub zero_tangential: bool,
    /// Keep fy/fx at 1 (square pixels).
    ///
    /// One focal length is solved for, and fy = fx exactly, their σ alike.
    #[arg(long)]
    pub fix_aspect_ratio: bool,
    /// Plain least squares, as OpenCV.
    ///
    /// No stray points set aside or down-weighted, no views set aside, every centre weighed
    /// alike (by default each weighs as precise as centres
    /// fitted to as many events prove in the same run).
    #[arg(help_heading = "Advanced: the solve", long)]
    pub no_robust: bool,
    /// Leave out a view whose points moved less than this (RMS, px) from a kept view.
    ///
    /// 0, the default, keeps every window's view: no two windows share an event, so each is
    /// a measurement of its own even where the board barely moved, and keeping them all
    /// tightens a slow motion's σ. Raise it (e.g. 2) only to solve faster. 0 to 2000.
    #[arg(help_heading = "Advanced: the solve", long, default_value_t = 0.0, value_name = "PX", value_parser = ranges::min_change_px,
          allow_negative_numbers = true)]
    pub min_change_px: f64,
    /// Most views solved from (evenly thinned beyond it); at least 3.
    #[arg(help_heading = "Advanced: the solve", long, default_value_t = 500, value_parser = ranges::max_views, allow_negative_numbers = true)]
    pub max_views: usize,
    /// Solve on the centres as detected.
    ///
    /// By default evcal measures how far the centres trail their circles along the motion
    /// (a DVS pixel fires late inside a blurred edge: about a tenth of a pixel, which
    /// biases the focal length when the board comes and goes) and moves them forward by
    /// that much first; the amount is printed and in the JSON result. It also solves the
    /// lag as a distance in proportion to each circle's edge thickness (slow, dim pixels
    /// smear thick edges more) and counts what that changes in each σ. Where a circle
    /// images as a slanted ellipse, the same late events also move its centre across the
    /// motion; the solve estimates how far (the lean, printed and in the JSON result),
    /// moves the centres back by it and counts it in each σ. Slow pixels' lag also bends
    /// with the speed (their delay shortens on faster edges): the part in the square of
    /// each centre's speed is estimated, taken out and counted the same way (the bend).
    #[arg(help_heading = "Advanced: the solve", long)]
    pub no_edge_shift: bool,
    /// Solve on each window's centres alone.
    ///
    /// By default each board point's centre in a view is re-estimated from a quadratic in
    /// time through its centres in the windows within 70 ms (a 4000-event window holds
    /// 20-90 events per circle; five windows say more), and a centre far off the path its
    /// neighbours trace is replaced by it.
    #[arg(help_heading = "Advanced: the solve", long)]
    pub no_smoothing: bool,
    /// Take only the grids the finder labels window by window.
    ///
    /// By default a window where the finder cannot label the grid by itself (an edge row
    /// too faint, too few points) is labelled from the grids found in the windows just
    /// before and after it, when every point lands within a quarter spacing of where they
    /// put it.
    #[arg(help_heading = "Advanced: the solve", long)]
    pub no_tracking: bool,
}

impl SolveArgs {
    /// The run's setup for `pattern` on a sensor of `size`.
    /// (`--min-change-px` and `--max-views` were checked as they were parsed: [`ranges`].)
    pub fn setup(&self, pattern: Pattern, size: [u32; 2]) -> Result<Setup> {
        let mut s = Setup::new(pattern, size);
        s.calib.fix_k3 = self.fix_k3;
        s.k3_only_if_demanded = !self.free_k3;
        s.calib.zero_tangential = self.zero_tangential;
        s.calib.fix_aspect_ratio = self.fix_aspect_ratio;
        s.calib.robust = !self.no_robust;
        s.select.min_change_px = self.min_change_px;
        s.select.max_views = self.max_views;
        s.edge_shift = !self.no_edge_shift;
        if self.no_smoothing {
            s.smooth = None;
        }
        if self.no_tracking {
            s.track = None;
        }
        Ok(s)
    }
}

/// Standard input, read through a buffer whose first bytes tell detections from a recording.
type Stdin = std::io::BufReader<std::io::Stdin>;

/// Whether standard input holds detections: its first bytes (peeked, kept for whichever
/// reader reads it) start with '{', as JSON lines do and no recording does.
fn stdin_holds_detections(r: &mut Stdin) -> Result<bool> {
    use std::io::BufRead;
    let head = r.fill_buf().with_context(|| format!("{STDIN_NAME}: cannot read"))?;
    Ok(head.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{'))
}

/// Whether `path` holds detections (JSON lines) rather than events.
fn is_detections(path: &Path) -> Result<bool> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if matches!(ext.as_str(), "jsonl" | "ndjson") {
        return Ok(true);
    }
    if ext == "json" {
        return Ok(true);
    }
    // A stream sniffed here would lose those bytes for the recording's reader.
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return Ok(false);
    }
    // Otherwise sniff: a detections file starts with '{'.
    use std::io::Read;
    let mut head = [0u8; 64];
    let n = std::fs::File::open(path)
        .with_context(|| format!("{}: cannot open", path.display()))?
        .read(&mut head)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    Ok(head[..n].iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{'))
}

/// The input exists, or is standard input: a mistyped name is an options error, said before
/// anything else happens (an error after the checks removes an earlier run's results).
fn check_input(input: &Path) -> Result<()> {
    if input.as_os_str() != "-" {
        std::fs::metadata(input).with_context(|| format!("{}: cannot open", input.display()))?;
    }
    Ok(())
}

pub fn run(a: CalibrateArgs) -> Result<()> {
    let pattern = Pattern::parse(&a.target.pattern, a.target.spacing).map_err(anyhow::Error::msg)?;
    ranges::check_spacing(a.target.spacing)?;
    if let Some(r) = a.target.radius {
        ranges::check_radius(r, a.target.spacing)?;
    }
    check_outputs(&a.out, a.json.as_deref(), &[("the input", &a.input)])?;
    check_input(&a.input)?;
    a.solve.setup(pattern, [1, 1])?;
    let sensor = a.core.sensor.as_deref().map(parse_sensor).transpose().map_err(anyhow::Error::msg)?;
    // The detection options alone (they do not depend on the sensor); the core checks them
    // again with the sensor.
    a.core.config(sensor.unwrap_or(SensorSize::DAVIS346))?;
    let mut stdin = (a.input.as_os_str() == "-").then(|| std::io::BufReader::with_capacity(1 << 16, std::io::stdin()));
    let from_events = !match &mut stdin {
        Some(r) => stdin_holds_detections(r)?,
        None => is_detections(&a.input)?,
    };
    let r = calibrate(&a, pattern, from_events, sensor, stdin);
    if let Err(e) = &r {
        if !e.chain().any(|c| c.is::<StdoutClosed>()) {
            say_stale_removed(&a.out, a.json.as_deref(), a.quiet);
        }
    }
    r
}

/// The run after the options' checks.
///
/// `sensor`: given, or `None` to take from the recording or the detections; `stdin`:
/// standard input when it is the input, its first bytes peeked. The options were checked.
fn calibrate(
    a: &CalibrateArgs,
    pattern: Pattern,
    from_events: bool,
    sensor: Option<SensorSize>,
    stdin: Option<Stdin>,
) -> Result<()> {
    let (windows, size, frames) = if !from_events {
        let w = match stdin {
            Some(r) => detections::read_jsonl_in_order(r).with_context(|| STDIN_NAME.to_string())?,
            None => {
                let f = std::fs::File::open(&a.input).with_context(|| format!("{}: cannot open", a.input.display()))?;
                detections::read_jsonl_in_order(std::io::BufReader::new(f))
                    .with_context(|| a.input.display().to_string())?
            }
        };
        if w.is_empty() {
            bail!("{}: no detection windows (an empty file)", a.input.display());
        }
        let size = detections_sensor(&w, sensor, &a.input)?;
        (w, size, Vec::new())
    } else {
        detect(a, a.core.filled_discs, stdin)?
    };
    if windows.is_empty() {
        bail!("{}: no detection windows (an empty file)", a.input.display());
    }
    let mut setup = a.solve.setup(pattern, [u32::from(size.width), u32::from(size.height)])?;
    setup.circle_radius = a.target.radius;
    if !a.quiet {
        eprintln!(
            "evcal: target {}x{} asymmetric circle grid, spacing {} m{}",
            pattern.rows,
            pattern.cols,
            pattern.spacing,
            match a.verbose {
                true => format!(", as seen from the front:\n{}", indent(&pattern.picture())),
                false => String::new(),
            }
        );
    }
    let mut views = find_views(&windows, &setup, a.quiet);
    views.event_frames = frames;
    if views.stats.found == 0 {
        if let Some(found) = transposed_finds(&windows, &setup) {
            bail!(
                "{}: no grid found with --pattern {}x{}, but with --pattern {}x{} (rows and columns the other way round) in {} of {} windows tried: run again with --pattern {}x{} (ROWSxCOLS: the rows are the lines of {} circles, see --help)",
                a.input.display(),
                pattern.rows,
                pattern.cols,
                pattern.cols,
                pattern.rows,
                found.0,
                found.1,
                pattern.cols,
                pattern.rows,
                pattern.rows
            );
        }
    }
    let (views, result) = if from_events && !a.core.filled_discs && !a.no_filled_discs {
        with_discs_if_rings_failed(a, &setup, views)?
    } else {
        let result = calibrate_views(&views, &setup);
        if !from_events && !a.quiet {
            if let Some(why) = no_calibration(&result) {
                // Detections cannot be fitted again here; the events they came from can.
                eprintln!(
                    "evcal: no calibration from these detections ({}); if they were made in dim light without --filled-discs, detecting the recording again with it (evcal detect or replay --filled-discs) may give one",
                    why.summary()
                );
            }
        }
        (views, result)
    };
    let outcome = result.map_err(anyhow::Error::from).map_err(|e| {
        // The finder's own message names the pattern; a wrong sensor size (centres
        // normalised, clustered and kept by it) fails the same way.
        let no_grid = e.downcast_ref::<PipelineError>().is_some_and(|p| matches!(p, PipelineError::NoGrid(s) if s.windows > 0));
        if no_grid {
            e.context(format!(
                "{}: no grid found on a {}x{} sensor with --pattern {}; if that size is not the camera's, give --sensor WxH",
                a.input.display(),
                size.width,
                size.height,
                a.target.pattern
            ))
        } else {
            e
        }
    })?;
    let verdict = Verdict::of(&outcome);
    let written = export(&views, &outcome, &verdict, &a.out, a.json.as_deref())?;
    report(&views, &outcome, &setup, None, a.verbose)?;
    list_written(&written, &[])?;
    finish(&verdict, &a.out)
}

/// The rings' views and calibration, or the filled discs' where the rings give none
/// ([`calibrate_with_disc_fallback`]), each step said on standard error. The recording is
/// detected again, so only a regular file can be.
fn with_discs_if_rings_failed(
    a: &CalibrateArgs,
    setup: &Setup,
    views: Views,
) -> Result<(Views, Result<Outcome, PipelineError>)> {
    let discs = |why: &NoCalibration| -> Result<Option<Views>> {
        // Standard input or a pipe was read once and is gone.
        if !std::fs::metadata(&a.input).is_ok_and(|m| m.is_file()) {
            return Ok(None);
        }
        // Where a dark circle's slow pixels fill it, only its outline is a circle.
        if !a.quiet {
            eprintln!(
                "evcal: no calibration from ring fits alone ({}); detecting again with filled discs where no ring fits (--no-filled-discs not to)",
                why.summary()
            );
        }
        let (discs, _, frames) = detect(a, true, None)?;
        Ok(Some(Views { event_frames: frames, ..find_views(&discs, setup, a.quiet) }))
    };
    let Chosen { views, result, fallback } = calibrate_with_disc_fallback(views, setup, discs)?;
    if !a.quiet {
        match &fallback {
            DiscFallback::NotNeeded => {}
            DiscFallback::NotTried { rings_failed } => eprintln!(
                "evcal: no calibration from ring fits alone ({}); a recording read from a stream cannot be detected again with filled discs: run again on it with --filled-discs",
                rings_failed.summary()
            ),
            DiscFallback::Rejected { why, .. } => {
                eprintln!("evcal: filled discs gave no calibration either ({})", why.summary())
            }
            DiscFallback::Taken { .. } => eprintln!("evcal: filled discs: {}", views.stats.summary()),
        }
    }
    Ok((views, result))
}

/// Runs the detection core over the recording, fitting filled discs where no ring fits when
/// `filled_discs`.
/// Standard input, when it is the input, comes as `stdin` (its first bytes already read).
fn detect(
    a: &CalibrateArgs,
    filled_discs: bool,
    stdin: Option<Stdin>,
) -> Result<(Vec<WindowRecord>, evcal_core::event::SensorSize, Vec<EventFrame>)> {
    let second_pass = a.core.sensor.is_none();
    let rec = match stdin {
        None => a.read.open(&a.input, a.quiet, second_pass)?,
        Some(r) => {
            let opts = OpenOptions { rewindable: second_pass, ..a.read.options() };
            let rec = Recording::from_reader(Path::new(STDIN_NAME), Box::new(r), &opts).context(
                "standard input is read as a recording: detections (JSON lines, as evcal detect writes) start with '{'",
            )?;
            if !a.quiet {
                for n in &rec.notes() {
                    eprintln!("evcal: note: {n}");
                }
            }
            rec
        }
    };
    let (sensor, rec) = resolve_sensor(a.core.sensor.as_deref(), rec, a.quiet)?;
    // The core's options as given, but for the discs (and with them the default window).
    let core = CoreArgs { filled_discs, ..a.core.clone() };
    let cfg = core.config(sensor)?;
    if !a.quiet {
        eprintln!("evcal: {}", core.window_line(&cfg));
    }
    let pb = progress_bar(rec.file_bytes, a.quiet, "detecting");
    let mut rec = rec;
    let progress = std::cell::Cell::new(0u64);
    // A few windows' events, for the report to draw under their grids.
    let sampler = std::cell::RefCell::new(FrameSampler::new(cfg.window.events));
    let events = with_position(&mut rec, 65_536, &progress).inspect(|e| {
        if let Ok(e) = e {
            sampler.borrow_mut().event(e);
        }
    });
    let mut windows = Vec::new();
    let summary = detections::run(events, cfg, |d| {
        pb.set_position(progress.get());
        pb.set_prefix(format!("windows {}", d.info.seq + 1));
        sampler.borrow_mut().window(d.info.seq, d.info.t_first_us, d.info.t_last_us);
        windows.push(WindowRecord::from_detection(d));
    })
    .with_context(|| a.input.display().to_string())?;
    pb.finish_and_clear();
    if !a.quiet {
        eprintln!("evcal: {} events, {} windows, {} centres", summary.events_read, summary.windows, summary.centres);
    }
    let name = rec.name().display();
    if let Some(w) = outside_warning(summary.out_of_sensor, summary.events_read, sensor) {
        eprintln!("evcal: warning: {name}: {w}");
    }
    for w in time_order_warnings(&summary) {
        eprintln!("evcal: warning: {name}: {w}");
    }
    if windows.is_empty() {
        return Err(no_window_error(rec.name(), &summary, &cfg));
    }
    Ok((windows, sensor, sampler.into_inner().into_frames()))
}

/// The grid in every window, with a progress bar.
pub fn find_views(windows: &[WindowRecord], setup: &Setup, quiet: bool) -> Views {
    let pb = progress_bar(windows.len() as u64, quiet, "finding grid");
    let views = views_from_windows(windows, setup, &|n| pb.set_position(n as u64));
    pb.finish_and_clear();
    views
}

/// Chooses views and solves.
pub fn solve(views: &Views, setup: &Setup) -> Result<Outcome> {
    Ok(calibrate_views(views, setup)?)
}
