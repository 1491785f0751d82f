//! `evcal simulate`: a simulated recording and its ground truth.

use crate::common::{run_simulation, truth_json, window_line, window_truths, write_json};
use anyhow::{bail, Context, Result};
use clap::Args;
use evcal_core::{event::SensorSize, window::WindowConfig};
use evcal_host::{
    detections,
    recording::{write_ecalib_h5, write_text},
    sim::{Camera, Light, SimConfig, Trajectory},
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
    /// Lighting: good, or low (darker, far noisier).
    #[arg(long, value_enum, default_value_t = Light::Good)]
    pub light: Light,
    /// Simulated seconds.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Seed of every random choice (same seed, same events).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where to write the recording (.txt or .h5).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Events per window of the truth (match what you pass to `evcal detect`) [default: as
    /// `evcal detect`'s for the sensor: 4000 for davis346, 7500 dvxplorer, 13000 imx636, 4500
    /// genx320]
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=detections::HOST_MAX_EVENTS as i64))]
    pub events_per_window: Option<u32>,
    /// Milliseconds between window ticks (for the truth).
    #[arg(long, default_value_t = 33.333)]
    pub step_ms: f64,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(a: SimulateArgs) -> Result<()> {
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
    let window = WindowConfig {
        events: a.events_per_window.map_or_else(|| detections::default_events_per_window(sensor), |n| n as usize),
        step_us: (a.step_ms * 1000.0).round() as u64,
    };
    let truths = window_truths(&events, &sim, window);
    let truth_path = a.out.parent().unwrap_or(Path::new(".")).join("truth.json");
    write_json(&truth_path, &truth_json(&sim, &truths))?;
    if !a.quiet {
        eprintln!(
            "evcal: {} events over {:.2} s ({} windows) -> {}; truth -> {}\nevcal: truth for {}",
            events.len(),
            a.seconds,
            truths.len(),
            a.out.display(),
            truth_path.display(),
            window_line(window, sensor, a.events_per_window.is_some())
        );
    }
    Ok(())
}
