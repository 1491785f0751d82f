//! What several commands share: the core's options, sensor resolution, progress bars,
//! simulation with truth.

use crate::ranges;
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use evcal_core::{
    cluster::ClusterConfig,
    detect::DetectConfig,
    event::{Event, SensorSize},
    fit::{FitConfig, FitMethod},
    window::WindowConfig,
};
use evcal_host::input::recording::remove_spools;
use evcal_host::{
    export::atomic::{self, AtomicFile},
    input::detections,
    input::recording::{guess_sensor, parse_sensor, OpenOptions, Recording, TimeUnit},
    sim::{FrameTruth, Simulator},
};
use indicatif::{ProgressBar, ProgressStyle};
use std::{
    io::{BufWriter, Write},
    path::Path,
    sync::atomic::{AtomicBool, Ordering},
};

/// What a recording cannot say about itself: which stream to read, the unit of its times.
#[derive(Args, Clone)]
pub struct ReadArgs {
    /// The stream to read where the file holds several.
    ///
    /// ROS bag: a topic of type dvs_msgs/EventArray (default: the only one, else
    /// /dvs/events). AEDAT4: an event stream's name or id (default: the only one, else
    /// 'events').
    #[arg(long, value_name = "NAME")]
    pub topic: Option<String>,
    /// Unit of timestamps: s, ms, us or ns.
    ///
    /// Text recordings: of every time (default seconds, or µs when the times are integers).
    /// HDF5 files laid out as x, y, t, p datasets: of integer times (default: from the
    /// file's attributes, DSEC's t_offset, else from the values). A guess is said in a note
    /// on standard error, with its reason.
    #[arg(long, value_name = "UNIT", value_parser = parse_time_unit)]
    pub time_unit: Option<TimeUnit>,
}

fn parse_time_unit(s: &str) -> Result<TimeUnit, String> {
    TimeUnit::parse(s).ok_or_else(|| format!("'{s}' is not a time unit: use s, ms, us or ns"))
}

impl ReadArgs {
    /// The reader options these arguments give.
    pub fn options(&self) -> OpenOptions {
        OpenOptions { topic: self.topic.clone(), time_unit: self.time_unit, rewindable: false }
    }

    /// Opens `path` (`-`: standard input), printing the reader's notes (a guessed unit, a
    /// missing index) unless `quiet`. `second_pass`: a stream is copied as it is read, so that
    /// [`resolve_sensor`] can read it again to guess the sensor size.
    pub fn open(&self, path: &Path, quiet: bool, second_pass: bool) -> Result<Recording> {
        let rec = Recording::open_with(path, &OpenOptions { rewindable: second_pass, ..self.options() })?;
        if !quiet {
            for n in &rec.notes() {
                eprintln!("evcal: note: {n}");
            }
        }
        Ok(rec)
    }
}

#[derive(Args, Clone)]
pub struct CoreArgs {
    /// Sensor size: WxH (346x260) or davis346, dvxplorer, imx636, genx320.
    ///
    /// Default: from the file (detections say it on every line), else guessed from a
    /// recording's largest coordinates (a note says so).
    #[arg(long)]
    pub sensor: Option<String>,
    /// Events per window [default: scaled with the sensor, 8000 for 346x260; --help says how]
    ///
    /// Default: 8000 for a DAVIS346 (346x260), twice the E-Calib paper's 4000, scaled with
    /// the sensor's linear size: 8000·√(W·H / (346·260)), rounded to a multiple of 500.
    /// 640x480 (DVXplorer): 15000; 1280x720 (IMX636, EVK4): 25500; 320x320 (GenX320): 8500.
    /// Twice the paper's because a dim pixel answers 15-20 ms late, longer than 4000 events
    /// last: the longer window sees each circle's late events whole, whatever its speed (on
    /// an independent emulator's dim recording the principal point came from 2.2 px off to
    /// 0.3 px). A larger sensor fires more events a second (the board's outlines span more
    /// pixels and cross more of them), so a window of a fixed number of events is shorter
    /// and each circle's events sparser along its outline (docs/accuracy.md: Windows sized
    /// to the sensor). The value chosen is printed on standard error. Up to 32000 on the
    /// host; `evcal replay` asks a device for at most what it holds (the Cortex-M4F
    /// firmware: 8000), unless given this option.
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=detections::HOST_MAX_EVENTS as i64),
          allow_negative_numbers = true)]
    pub events_per_window: Option<u32>,
    /// Milliseconds of event time between window ticks (the paper: 33); 0 (windows back to
    /// back) to 60000.
    #[arg(long, default_value_t = 33.333, value_name = "MS", value_parser = ranges::step_ms,
          allow_negative_numbers = true)]
    pub step_ms: f64,
    /// DBSCAN radius, in coordinates normalised by the sensor size; 0.0001 to 0.5.
    #[arg(long, default_value_t = evcal_core::config::DEFAULT_EPS, value_parser = ranges::eps,
          allow_negative_numbers = true)]
    pub eps: f32,
    /// DBSCAN minimum points in a neighbourhood (the point included), over the background.
    ///
    /// Each window adds the events its pixels' noise puts in a neighbourhood by chance (the
    /// lower quartile of its counts over a 32x24 grid of the sensor, plus two standard
    /// deviations), so that a dim room's noise does not join circles; 0 added on a clean
    /// window. 1 to 32000 (the most events a window holds).
    #[arg(long, default_value_t = evcal_core::config::DEFAULT_MIN_PTS, value_parser = ranges::min_pts,
          allow_negative_numbers = true)]
    pub min_pts: u16,
    /// Use ST-DBSCAN: neighbours must also be within this fraction of the window's duration
    /// (0.0001 to 1).
    #[arg(long, value_name = "FRACTION", value_parser = ranges::eps_t, allow_negative_numbers = true)]
    pub eps_t: Option<f32>,
    /// Circle fit: erwls (the method), ols or centroid (for comparison).
    #[arg(long, value_enum, default_value_t = Method::Erwls)]
    pub method: Method,
    /// Also fit filled discs where no ring fits, in every window.
    ///
    /// In dim light a dark circle's slow pixels go on firing after its edge passed and fill
    /// it with events, most on a large sensor whose circles span more pixels: a DVXplorer at
    /// a slow photoreceptor found its grid in no window. With this flag a cluster no ring
    /// fits is also tried as a filled disc, and the disc's outline gives its centre. Windows
    /// are then longer on a larger sensor (unless --events-per-window is given): the
    /// DAVIS346's 8000 scaled by the area, so that they last as long as on a DAVIS346, as
    /// slow pixels need (27500 on 640x480). Measured on simulations (docs/accuracy.md,
    /// "Filled discs"): the DVXplorer's dim cone then calibrates (fx +0.004 %, cx +0.37 px;
    /// +0.18 %, +1.4 px in the rings' shorter windows), but scenes whose rings hold read worse with
    /// discs among them (DAVIS346 dim-room spiral -0.29 -> -0.79 %). So `evcal detect` and
    /// `replay` fit none unless asked (the firmware's default too; `replay` asks the device,
    /// whose windows then take longer), and `evcal calibrate` fits them only when the rings
    /// alone give no calibration, detecting the recording again (--no-filled-discs: never).
    #[arg(long)]
    pub filled_discs: bool,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Method {
    Erwls,
    Ols,
    Centroid,
}

impl CoreArgs {
    /// The detector's configuration on `sensor` (the values were checked as they were parsed:
    /// [`ranges`]).
    pub fn config(&self, sensor: SensorSize) -> Result<DetectConfig> {
        Ok(DetectConfig {
            sensor,
            window: WindowConfig {
                events: self
                    .events_per_window
                    .map_or_else(|| detections::window_events_for(sensor, self.filled_discs), |n| n as usize),
                step_us: (self.step_ms * 1000.0).round() as u64,
            },
            cluster: ClusterConfig { eps: self.eps, min_pts: self.min_pts, eps_t: self.eps_t },
            fit: FitConfig {
                method: match self.method {
                    Method::Erwls => FitMethod::Erwls,
                    Method::Ols => FitMethod::Ols,
                    Method::Centroid => FitMethod::Centroid,
                },
                filled_discs: self.filled_discs,
                ..FitConfig::default()
            },
        })
    }
}

impl CoreArgs {
    /// The line saying how windows are cut, for standard error: how many events, how often,
    /// and whether that is the sensor's default (and how to change it).
    pub fn window_line(&self, cfg: &DetectConfig) -> String {
        let why = if self.events_per_window.is_some() {
            WindowWhy::Given
        } else if cfg.fit.filled_discs {
            WindowWhy::Discs
        } else {
            WindowWhy::Sensor
        };
        window_line(cfg.window, cfg.sensor, why)
    }
}

/// Where a window's size came from, for [`window_line`].
#[derive(Clone, Copy)]
pub enum WindowWhy {
    /// `--events-per-window`.
    Given,
    /// The sensor's default ([`detections::default_events_per_window`]).
    Sensor,
    /// The sensor's default for filled discs ([`detections::disc_events_per_window`]).
    Discs,
}

/// "windows: N events every S ms (...)" for `window` on `sensor`, saying where N came from.
pub fn window_line(window: WindowConfig, sensor: SensorSize, why: WindowWhy) -> String {
    let (w, h) = (sensor.width, sensor.height);
    let why = match why {
        WindowWhy::Given => "--events-per-window".to_string(),
        WindowWhy::Sensor => format!("default for a {w}x{h} sensor; --events-per-window to change"),
        WindowWhy::Discs => format!(
            "default for filled discs on a {w}x{h} sensor: the DAVIS346's 8000 scaled by the area, to last as long, as slow pixels need; --events-per-window to change"
        ),
    };
    format!("windows: {} events every {:.0} ms ({why})", window.events, window.step_us as f64 * 1e-3)
}

/// The sensor size: given, else from the file, else guessed from a pass over the events;
/// and the recording to detect on, from its start (read again after a guessing pass).
pub fn resolve_sensor(given: Option<&str>, rec: Recording, quiet: bool) -> Result<(SensorSize, Recording)> {
    let name = rec.name().display().to_string();
    if let Some(s) = given {
        let s = parse_sensor(s).map_err(anyhow::Error::msg)?;
        if let Some(f) = rec.sensor.filter(|&f| f != s) {
            if !quiet {
                eprintln!(
                    "evcal: note: {name} states a {}x{} sensor; --sensor {}x{} is used instead",
                    f.width, f.height, s.width, s.height
                );
            }
        }
        return Ok((s, rec));
    }
    if let Some(s) = rec.sensor {
        return Ok((s, rec));
    }
    let (mut mx, mut my, mut any) = (0u16, 0u16, false);
    let mut rec = rec;
    for e in &mut rec {
        let e = e?;
        mx = mx.max(e.x);
        my = my.max(e.y);
        any = true;
    }
    if !any {
        bail!("{name}: no events");
    }
    let s = guess_sensor(mx, my);
    if !quiet {
        eprintln!(
            "evcal: note: {name} does not state its sensor size; using {}x{} (largest x {}, y {}); set --sensor WxH to be sure",
            s.width, s.height, mx, my
        );
    }
    Ok((s, rec.rewind()?))
}

/// Above this share of events outside the sensor, the sensor size is probably wrong.
pub const OUTSIDE_WARN_SHARE: f64 = 0.03;

/// The warning for `outside` of `events` lying outside `sensor`, when they are more than
/// [`OUTSIDE_WARN_SHARE`] of them.
pub fn outside_warning(outside: u64, events: u64, sensor: SensorSize) -> Option<String> {
    let share = outside as f64 / events.max(1) as f64;
    (share > OUTSIDE_WARN_SHARE).then(|| {
        format!(
            "{:.1} % of the events ({outside} of {events}) lie outside the {}x{} sensor (the detector drops them): the sensor size is probably wrong (--sensor WxH)",
            100.0 * share,
            sensor.width,
            sensor.height
        )
    })
}

/// The warnings for events the detector's input filter dropped for their time, one per
/// reason, each saying how many (none when none were).
pub fn time_order_warnings(s: &detections::RunSummary) -> Vec<String> {
    let mut out = Vec::new();
    if s.time_jumps > 0 {
        let ahead = seconds(s.largest_jump_us);
        out.push(if s.time_jumps == 1 {
            format!("1 event dropped: its time was {ahead} ahead of its neighbours (a stray timestamp)")
        } else {
            format!(
                "{} events dropped: their times were up to {ahead} ahead of their neighbours (stray timestamps)",
                s.time_jumps
            )
        });
    }
    if s.time_backwards > 0 {
        out.push(if s.time_backwards == 1 {
            "1 event dropped: its time was earlier than the event before it".to_string()
        } else {
            format!("{} events dropped: their times were earlier than the events before them", s.time_backwards)
        });
    }
    out
}

/// A duration given in microseconds, in seconds (milliseconds below one second).
fn seconds(us: u64) -> String {
    if us < 1_000_000 {
        format!("{:.1} ms", us as f64 / 1e3)
    } else {
        format!("{:.1} s", us as f64 / 1e6)
    }
}

/// The error for a run of the detector that completed no window: what was read and
/// dropped, and what a window needs.
pub fn no_window_error(name: &std::path::Path, s: &detections::RunSummary, cfg: &DetectConfig) -> anyhow::Error {
    let kept = s.events_read.saturating_sub(s.out_of_sensor + s.time_backwards + s.time_jumps);
    anyhow::anyhow!(
        "{}: no detection window: {} events read, {} of them outside the {}x{} sensor, {} earlier than the one before and {} stray times far ahead (dropped), leaving {kept}: fewer than one window of {} events",
        name.display(),
        s.events_read,
        s.out_of_sensor,
        cfg.sensor.width,
        cfg.sensor.height,
        s.time_backwards,
        s.time_jumps,
        cfg.window.events
    )
}

pub fn progress_bar(len: u64, quiet: bool, what: &str) -> ProgressBar {
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

/// The windows the detector cuts from events handed batch by batch, as [`run_simulation`](crate::simulation::run_simulation)
/// hands them: each window's sequence number and reference time, for its truth.
pub struct WindowTimes {
    windower: Box<evcal_core::window::Windower<{ detections::HOST_MAX_EVENTS }>>,
    times: Vec<(u32, u64)>,
}

impl WindowTimes {
    pub fn new(window: WindowConfig) -> Self {
        Self { windower: Box::new(evcal_core::window::Windower::new(window)), times: Vec::new() }
    }

    pub fn push(&mut self, events: &[Event]) {
        for e in events {
            if let Some(info) = self.windower.push(*e) {
                self.times.push((info.seq, info.t_ref_us));
            }
        }
    }

    /// The truth of every window cut.
    pub fn truths(&self, sim: &Simulator) -> Vec<(u32, FrameTruth)> {
        self.times.iter().map(|&(seq, t)| (seq, sim.truth_at(t))).collect()
    }
}

/// The truth of `windows`, for the recording whose file name is `recording` (so that a later
/// run can tell whose truth a `truth.json` is).
pub fn truth_json(sim: &Simulator, windows: &[(u32, FrameTruth)], recording: &str) -> serde_json::Value {
    let c = sim.config();
    serde_json::json!({
        "recording": recording,
        "camera": c.camera,
        "board": { "rows": c.board.rows, "cols": c.board.cols, "spacing": c.board.spacing, "radius": c.board.radius },
        "trajectory": c.trajectory.name(),
        "light": c.light.name(),
        "pixel": c.pixel,
        "seed": c.seed,
        "windows": windows.iter().map(|(seq, t)| serde_json::json!({
            "seq": seq, "t_ref_us": t.t_us, "rvec": t.rvec, "tvec": t.tvec, "circles": t.circles,
        })).collect::<Vec<_>>(),
    })
}

/// Writes `v` to `path` through a temporary file renamed over it.
pub fn write_json(path: &Path, v: &serde_json::Value) -> Result<()> {
    let mut w = BufWriter::new(AtomicFile::create(path)?);
    serde_json::to_writer(&mut w, v).with_context(|| format!("writing {}", path.display()))?;
    w.into_inner().map_err(|e| e.into_error()).with_context(|| format!("writing {}", path.display()))?.commit()?;
    Ok(())
}

/// Where the device is and how to reach it.
#[derive(Args, Clone)]
pub struct LinkArgs {
    /// The device: a serial port (e.g. /dev/ttyACM0, COM3) or tcp:HOST:PORT (QEMU's
    /// `-serial tcp:127.0.0.1:PORT,server=on,wait=on,nodelay=on`, or `evcal device`).
    #[arg(long)]
    pub port: String,
    /// Serial line rate in baud, 50 to 20000000 (ignored for tcp:).
    #[arg(long, default_value_t = 115_200, value_parser = ranges::baud, allow_negative_numbers = true)]
    pub baud: u32,
    /// Seconds to keep retrying a refused TCP connection (QEMU may still be starting); 0 (one
    /// attempt) to a year. Ctrl-C stops the retries.
    #[arg(long, default_value = "10", value_name = "SECONDS", value_parser = ranges::wait,
          allow_negative_numbers = true)]
    pub connect_timeout: std::time::Duration,
}

impl LinkArgs {
    /// Opens the link; Ctrl-C while connecting (`stop` set) ends the command with status 130.
    pub fn open(&self, stop: &AtomicBool) -> Result<evcal_host::input::link::Link> {
        use evcal_host::input::link::{Link, LinkError, Port};
        let port = Port::parse(&self.port)?;
        match Link::open(&port, self.baud, self.connect_timeout, stop) {
            Err(LinkError::Interrupted) => {
                eprintln!("evcal: interrupted while connecting to {}", self.port);
                exit_interrupted()
            }
            r => Ok(r?),
        }
    }
}

/// Set by Ctrl-C (or SIGTERM, SIGHUP).
static STOP: AtomicBool = AtomicBool::new(false);
/// Whether the command stops by itself on [`STOP`] (see [`stop_on_ctrl_c`]); until then the
/// signal ends the process at once.
static COOPERATIVE: AtomicBool = AtomicBool::new(false);

/// Handles Ctrl-C, SIGTERM and SIGHUP for every command: the temporary copies of streams
/// ([`remove_spools`]) and the outputs still being written ([`atomic::remove_unfinished`],
/// each target left as it was) are removed and the process ends at once with status 130, unless the
/// command stops by itself ([`stop_on_ctrl_c`]); a second signal then ends it at once.
pub fn handle_signals() {
    // Only fails if a handler is already set, and then that one stops us.
    let _ = ctrlc::set_handler(|| {
        let again = STOP.swap(true, Ordering::SeqCst);
        if again || !COOPERATIVE.load(Ordering::SeqCst) {
            remove_spools();
            atomic::remove_unfinished();
            // Not `exit`: its handlers (HDF5's library shutdown among them) would run while
            // the main thread may be inside HDF5.
            #[cfg(unix)]
            #[allow(unsafe_code)]
            // SAFETY: `_exit` ends the process without touching its state.
            unsafe {
                libc::_exit(EXIT_INTERRUPTED)
            };
            #[cfg(not(unix))]
            std::process::exit(EXIT_INTERRUPTED);
        }
    });
}

/// The exit status of a command stopped by Ctrl-C or SIGTERM (128 + SIGINT, as shells give).
pub const EXIT_INTERRUPTED: i32 = 130;

/// The flag Ctrl-C (or SIGTERM) sets from now on instead of ending the process, so that a
/// command can stop cleanly with everything received so far written; it then ends with
/// [`exit_interrupted`].
pub fn stop_on_ctrl_c() -> &'static AtomicBool {
    COOPERATIVE.store(true, Ordering::SeqCst);
    &STOP
}

/// Ends a command that stopped on Ctrl-C: temporary copies removed, status 130.
pub fn exit_interrupted() -> ! {
    remove_spools();
    atomic::remove_unfinished();
    std::process::exit(EXIT_INTERRUPTED)
}

/// Standard output's reader went away (`evcal ... | head`). Not a failure: `main` ends
/// quietly with status 0 when a command stops with it. Kept apart from other broken pipes
/// (a device's TCP link closing is an error to report).
#[derive(Debug)]
pub struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("standard output was closed")
    }
}

impl std::error::Error for StdoutClosed {}

/// A failed write to standard output as an error: [`StdoutClosed`] for a closed pipe,
/// otherwise the cause (a full disk behind a redirection is a real failure).
pub fn stdout_error(e: std::io::Error) -> anyhow::Error {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        anyhow::Error::new(StdoutClosed)
    } else {
        anyhow::Error::new(e).context("writing to standard output")
    }
}

/// Writes one line to standard output. `println!` panics when the reader has gone; this
/// returns [`StdoutClosed`] for the command to stop on.
pub fn print_line(args: std::fmt::Arguments<'_>) -> Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(args).and_then(|()| out.write_all(b"\n")).map_err(stdout_error)
}

/// `println!` for the commands' reports: `outln!(...)?` stops the command when standard
/// output has closed.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::common::print_line(format_args!($($arg)*))
    };
}
pub(crate) use outln;

/// Where a command's JSON lines go: standard output, or a file written through a temporary
/// file beside it ([`AtomicFile`]), buffered.
pub struct Output {
    w: Sink,
    /// The file; `None` for standard output.
    path: Option<std::path::PathBuf>,
}

enum Sink {
    Stdout(BufWriter<std::io::StdoutLock<'static>>),
    File(BufWriter<AtomicFile>),
}

impl Output {
    /// Writes one line.
    pub fn line(&mut self, line: &str) -> Result<()> {
        let r = match &mut self.w {
            Sink::Stdout(w) => writeln!(w, "{line}"),
            Sink::File(w) => writeln!(w, "{line}"),
        };
        r.map_err(|e| self.error(e))
    }

    /// Flushes what was written and puts the file in place (renamed over the target). Not
    /// called, the file is left as it was: the way to give up after an error.
    pub fn finish(self) -> Result<()> {
        match self.w {
            Sink::Stdout(mut w) => w.flush().map_err(stdout_error),
            Sink::File(w) => {
                let path = self.path.unwrap_or_default();
                let f = w
                    .into_inner()
                    .map_err(|e| e.into_error())
                    .with_context(|| format!("writing {}", path.display()))?;
                Ok(f.commit()?)
            }
        }
    }

    fn error(&self, e: std::io::Error) -> anyhow::Error {
        match &self.path {
            None => stdout_error(e),
            Some(p) => anyhow::Error::new(e).context(format!("writing {} (left as it was)", p.display())),
        }
    }
}

/// Checks before any work that `path` may be written as the output `what`: not a link, not
/// a directory, its folder exists, and not the same file as any of `inputs` (description,
/// path; `-` is standard input). A run that fails only at its end, after minutes of work, is
/// the worse failure; an output that destroys an input, worse still.
pub fn check_output(path: &Path, what: &str, inputs: &[(&str, &Path)]) -> Result<()> {
    Ok(atomic::check_output(path, what, inputs)?)
}

/// Standard output (no path, or `-`) or a file written through a temporary file, buffered.
pub fn output(path: Option<&Path>) -> Result<Output> {
    Ok(match path.filter(|p| p.as_os_str() != "-") {
        Some(p) => Output { w: Sink::File(BufWriter::new(AtomicFile::create(p)?)), path: Some(p.to_path_buf()) },
        None => Output { w: Sink::Stdout(BufWriter::new(std::io::stdout().lock())), path: None },
    })
}

/// A spinner with live counts, for commands whose length is unknown.
pub fn spinner(quiet: bool, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg:12} {elapsed}  {prefix}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.set_message(what.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(120));
    pb
}

/// The recording's events, noting the reader's byte position in `position` every `every`
/// events, for a progress bar to read between events.
pub fn with_position<'a>(
    rec: &'a mut Recording,
    every: u64,
    position: &'a std::cell::Cell<u64>,
) -> impl Iterator<Item = Result<evcal_core::event::Event, evcal_host::input::recording::ReadError>> + 'a {
    let mut counter = 0u64;
    std::iter::from_fn(move || {
        let e = rec.next();
        counter += 1;
        if counter % every == 0 {
            position.set(rec.progress_bytes());
        }
        e
    })
}
