//! `evcal simulate`: a simulated recording and its ground truth.

use crate::common::{check_output, truth_json, window_line, write_json, WindowTimes, WindowWhy};
use crate::ranges;
use crate::simulation::run_simulation;
use anyhow::{bail, Context, Result};
use clap::Args;
use evcal_core::{event::SensorSize, window::WindowConfig};
use evcal_host::{
    export::atomic::{folder_of, same_file},
    input::detections,
    input::recording::{EcalibH5Writer, TextWriter},
    sim::{Camera, Light, PixelModel, RecordedMotion, SimConfig, Trajectory},
};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct SimulateArgs {
    /// Sensor preset: davis346 (346x260, 4.5 mm lens), dvxplorer (640x480), imx636
    /// (1280x720, Prophesee EVK4 class, 6 mm lens) or genx320 (320x320, 2.1 mm M12 lens).
    #[arg(long, default_value = "davis346", value_parser = Camera::PRESETS)]
    pub sensor: String,
    /// Grid preset: 3x7 (34 mm), 3x9 (27 mm) or 4x11 (24 mm).
    #[arg(long, default_value = "4x11", value_parser = ["3x7", "3x9", "4x11"])]
    pub pattern: String,
    /// Camera motion.
    #[arg(long, value_enum, default_value_t = Trajectory::Cone)]
    pub trajectory: Trajectory,
    /// Follow a recorded motion instead of --trajectory: a JSON file of evenly spaced poses,
    /// `frames30.frames` or `frames`, each `{"t": s, "rvec": [..], "tvec": [..]}` (board to
    /// camera, OpenCV's convention, metres), as the truth.json of an independent emulator's
    /// recording holds them. The camera (`K`, `dist`), the sensor's size (`sensor`) and the
    /// grid (`pattern`: rows, cols, spacing_m, radius_m) are taken from the file too when it
    /// has them, in place of --sensor's and --pattern's. Use it to see how far a recording's
    /// motion lets the calibration scatter with evcal's own pixels: simulate it with a few
    /// seeds.
    #[arg(long, value_name = "FILE", conflicts_with = "trajectory")]
    pub poses: Option<PathBuf>,
    /// Lighting: good, or low (darker, far noisier).
    #[arg(long, value_enum, default_value_t = Light::Good)]
    pub light: Light,
    /// Simulated seconds, 0.001 to 3600 (every event is held in memory).
    #[arg(long, default_value_t = 5.0, value_parser = ranges::sim_seconds, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Seed of every random choice (same seed, same events).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub seed: u64,
    /// Where to write the recording (.txt or .h5).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Where to write the truth [default: truth.json beside the recording, which replaces a
    /// truth.json there only when that is the truth of a recording of the same name, as a
    /// run again writes].
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Events per window of the truth (match what you pass to `evcal detect`) [default: as
    /// `evcal detect`'s for the sensor: 8000 for davis346, 15000 dvxplorer, 25500 imx636,
    /// 8500 genx320]
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=detections::HOST_MAX_EVENTS as i64),
          allow_negative_numbers = true)]
    pub events_per_window: Option<u32>,
    /// Milliseconds between window ticks (for the truth); 0 (back to back) to 60000.
    #[arg(long, default_value_t = 33.333, value_name = "MS", value_parser = ranges::step_ms,
          allow_negative_numbers = true)]
    pub step_ms: f64,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    pub pixel: PixelArgs,
}

/// The pixel's physics; each left out keeps the lighting preset's value (an ideal pixel:
/// unlimited bandwidth, no leak, no shot noise).
#[derive(Args)]
#[command(next_help_heading = "Pixel physics")]
pub struct PixelArgs {
    /// Photoreceptor bandwidth: its low-pass cutoff, Hz, for a perfect white in office light
    /// (--light good); a pixel receiving intensity I (illumination x reflectance) answers
    /// with a cutoff I times this, so dark pixels (the printed circles, 6 % reflectance, or
    /// anything under --light low, a twentieth of the light) lag by milliseconds and OFF edges
    /// into a circle lag more than ON edges out of it. Real DVS pixels: hundreds of Hz to a few
    /// kHz in office light. "inf" (the default) follows the light at once. 1 to 1000000, or
    /// inf.
    #[arg(long, value_name = "HZ", value_parser = ranges::photoreceptor_hz, allow_negative_numbers = true)]
    pub photoreceptor_hz: Option<f64>,
    /// Contrast threshold, ON and OFF, in log intensity (0.25: a 28 % change fires an event);
    /// 0.01 to 5.
    #[arg(long, value_name = "LOG", value_parser = ranges::threshold, allow_negative_numbers = true)]
    pub threshold: Option<f64>,
    /// Pixel-to-pixel standard deviation of the thresholds, log units; 0 to 1.
    #[arg(long, value_name = "LOG", value_parser = ranges::mismatch, allow_negative_numbers = true)]
    pub mismatch: Option<f64>,
    /// Leak events: mean rate per pixel, Hz, of the ON events a still pixel fires as its
    /// memorised level leaks (real sensors: about 0.1 Hz); rates spread over a third of a
    /// decade from pixel to pixel. 0 to 100.
    #[arg(long, value_name = "HZ", value_parser = ranges::leak_hz, allow_negative_numbers = true)]
    pub leak_hz: Option<f64>,
    /// Shot noise: rate per pixel in darkness, Hz, of random ON/OFF events; a quarter of it
    /// on a perfect white in office light, more the darker a pixel (real sensors under dim
    /// light: about 1 Hz). 0 to 1000.
    #[arg(long, value_name = "HZ", value_parser = ranges::shot_noise_hz, allow_negative_numbers = true)]
    pub shot_noise_hz: Option<f64>,
    /// Scene illumination, 1 = office light (the --light preset gives 1 or 0.05): scales the
    /// photoreceptor's speed and the shot noise, and flattens the contrast against the dark
    /// signal. 0.0001 to 10000.
    #[arg(long, value_name = "X", value_parser = ranges::illumination, allow_negative_numbers = true)]
    pub illumination: Option<f64>,
}

impl PixelArgs {
    /// The preset's pixel model with the flags given (their ranges were checked as they were
    /// parsed: [`ranges`]).
    pub fn apply(&self, mut px: PixelModel) -> PixelModel {
        if let Some(f) = self.photoreceptor_hz {
            px.photoreceptor_hz = f.is_finite().then_some(f);
        }
        if let Some(v) = self.threshold {
            px.threshold = v;
        }
        if let Some(v) = self.mismatch {
            px.mismatch = v;
        }
        if let Some(v) = self.leak_hz {
            px.leak_hz = v;
            px.leak_spread_decades = 0.33;
        }
        if let Some(v) = self.shot_noise_hz {
            px.shot_noise_hz = v;
        }
        if let Some(v) = self.illumination {
            px.illumination = v;
        }
        px
    }
}

/// The recording being written.
enum Out {
    Text(TextWriter),
    H5(EcalibH5Writer),
}

pub fn run(a: SimulateArgs) -> Result<()> {
    let mut cfg = SimConfig::preset(&a.sensor, &a.pattern, a.trajectory, a.light, a.seed)
        .ok_or_else(|| anyhow::anyhow!("unknown sensor or pattern preset"))?;
    cfg.pixel = a.pixel.apply(cfg.pixel);
    let mut took = Vec::new();
    if let Some(path) = &a.poses {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let motion = RecordedMotion::from_json(&text)
            .with_context(|| format!("{} holds no motion to follow", path.display()))?;
        // One interval past the last pose holds it (a recording's poses often stop a frame
        // short of its events); more would be a still camera the file never showed.
        if a.seconds > motion.end() + motion.dt * 1.001 {
            bail!(
                "{} holds poses from {:.3} to {:.3} s; --seconds {} goes beyond them",
                path.display(),
                motion.t0,
                motion.end(),
                a.seconds
            );
        }
        took = motion.apply(&mut cfg);
    }
    let truth_path = a.truth.clone().unwrap_or_else(|| folder_of(&a.out).join(TRUTH));
    check_outputs(&a, &truth_path)?;
    // Before the simulation, not after it: a missing folder is no reason to lose its work.
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create the folder {}", dir.display()))?;
    }
    let sensor = SensorSize { width: cfg.camera.width, height: cfg.camera.height };
    let window = WindowConfig {
        events: a.events_per_window.map_or_else(|| detections::default_events_per_window(sensor), |n| n as usize),
        step_us: (a.step_ms * 1000.0).round() as u64,
    };
    // Written as they come, and the windows cut as they come: memory does not grow with the
    // events (a leak of 10 kHz a pixel makes gigabytes of them).
    let is_h5 = a.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("h5") || e.eq_ignore_ascii_case("hdf5"));
    let writing = || format!("writing {}", a.out.display());
    let mut out = if is_h5 {
        Out::H5(EcalibH5Writer::create(&a.out).and_then(|w| w.with_sensor(sensor)).map_err(anyhow::Error::msg)?)
    } else {
        Out::Text(TextWriter::create(&a.out, Some(sensor)).with_context(writing)?)
    };
    let mut cuts = WindowTimes::new(window);
    // What a text line (`0.123456 123 45 1`) and an HDF5 row (four f64) take.
    let bytes_per_event = if is_h5 { 32.0 } else { 18.0 };
    let (n_events, sim) = run_simulation(cfg, a.seconds, a.quiet, bytes_per_event, |b| {
        cuts.push(b);
        match &mut out {
            Out::H5(w) => w.write(b).map_err(anyhow::Error::msg),
            Out::Text(w) => w.write(b).with_context(writing),
        }
    })?;
    match out {
        Out::H5(w) => w.finish().map_err(anyhow::Error::msg)?,
        Out::Text(w) => w.finish().with_context(writing)?,
    }
    let truths = cuts.truths(&sim);
    write_json(&truth_path, &truth_json(&sim, &truths, &recording_name(&a.out)))?;
    if !a.quiet {
        if let (Some(path), false) = (&a.poses, took.is_empty()) {
            eprintln!("evcal: motion, {} from {}", took.join(", "), path.display());
        } else if let Some(path) = &a.poses {
            eprintln!("evcal: motion from {}", path.display());
        }
        eprintln!(
            "evcal: {} events over {:.2} s ({} windows) -> {}; truth -> {}\nevcal: truth for {}",
            n_events,
            a.seconds,
            truths.len(),
            a.out.display(),
            truth_path.display(),
            window_line(
                window,
                sensor,
                if a.events_per_window.is_some() { WindowWhy::Given } else { WindowWhy::Sensor }
            )
        );
    }
    Ok(())
}

/// The truth's file beside the recording, unless --truth.
const TRUTH: &str = "truth.json";

/// The recording's file name, as the truth records it.
fn recording_name(out: &Path) -> String {
    out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

/// Checks the outputs before any work: the recording and the truth neither links, folders
/// nor the --poses file, not one file, and a truth.json beside the recording that is not its
/// own (another recording's, or another program's) left alone.
fn check_outputs(a: &SimulateArgs, truth: &Path) -> Result<()> {
    if a.out.as_os_str() == "-" {
        bail!("--out -: simulate writes a file (and truth.json beside it); give a name");
    }
    let inputs: Vec<(&str, &Path)> = a.poses.iter().map(|p| ("--poses", p.as_path())).collect();
    let truth_what = if a.truth.is_some() { "--truth" } else { "the truth" };
    // A folder still to be made holds nothing to clobber.
    if folder_of(&a.out).is_dir() {
        check_output(&a.out, "--out", &inputs)?;
    }
    if folder_of(truth).is_dir() || a.truth.is_some() {
        check_output(truth, truth_what, &inputs)?;
    }
    if same_file(&a.out, truth) {
        match &a.truth {
            Some(t) => bail!("--truth {}: is the same file as --out {}; give another name", t.display(), a.out.display()),
            None => bail!(
                "--out {}: is where the truth goes ({TRUTH} beside the recording); name the recording otherwise, or give --truth FILE",
                a.out.display()
            ),
        }
    }
    if a.truth.is_none() && std::fs::symlink_metadata(truth).is_ok() {
        let name = recording_name(&a.out);
        let owner = truth_owner(truth);
        if owner.as_deref() != Some(name.as_str()) {
            let whose = match owner {
                Some(o) => format!("holds the truth of another recording, {o}"),
                None => "is not the truth of a recording evcal simulated".to_string(),
            };
            bail!(
                "{}: {whose}; it is left as it is: simulate into another folder, or give --truth FILE for this recording's",
                truth.display()
            );
        }
    }
    Ok(())
}

/// The recording a truth file names (`recording`, written since issue 46); `None` for a file
/// that is not a truth evcal wrote, or one written before it named its recording.
fn truth_owner(truth: &Path) -> Option<String> {
    #[derive(serde::Deserialize)]
    struct Owner {
        recording: Option<String>,
        // Only evcal's truth has these; another program's file with a `recording` is not one.
        #[allow(dead_code)]
        camera: serde::de::IgnoredAny,
        #[allow(dead_code)]
        windows: serde::de::IgnoredAny,
    }
    let f = std::fs::File::open(truth).ok()?;
    let o: Owner = serde_json::from_reader(std::io::BufReader::new(f)).ok()?;
    o.recording
}
