//! `evcal demo`: the main job on a built-in default, end to end with known truth.

use crate::calibrate::{check_outputs, export, find_views, list_written, report, say_stale_removed, solve};
use crate::common::{check_output, outln, StdoutClosed};
use crate::simulation::run_windowed_simulation;
use anyhow::{Context, Result};
use clap::Args;
use evcal_core::{detect::DetectConfig, event::SensorSize};
use evcal_host::{
    calib::Intrinsics,
    eval::{self, ScoreRules},
    export::atomic::AtomicFile,
    input::detections::WindowRecord,
    input::link::replay::replay_virtual,
    pipeline::{Setup, Verdict},
    sim::{Light, SimConfig, Trajectory},
    views::grid::Pattern,
};
use std::{
    io::{BufWriter, Write},
    path::{Path, PathBuf},
};

#[derive(Args)]
pub struct DemoArgs {
    /// Seconds of motion (an 8000-event window every 33 ms: 30 windows a second; only the
    /// milliseconds each window needs are simulated). 8 s take the cone through its whole
    /// range of tilts (15–35°, a 7.3 s cycle): with 3 s, half of it, fx read 0.13 % long.
    /// 0.001 to 3600.
    #[arg(long, default_value_t = 8.0, value_parser = crate::ranges::sim_seconds, allow_negative_numbers = true)]
    pub seconds: f64,
    /// Lighting.
    #[arg(long, value_enum, default_value_t = Light::Good)]
    pub light: Light,
    /// Output folder.
    #[arg(long, default_value = "evcal-out")]
    pub out: PathBuf,
    /// No progress bars.
    #[arg(long, short)]
    pub quiet: bool,
    /// Also say how the run got to its result, as `evcal calibrate -v` does.
    #[arg(long, short)]
    pub verbose: bool,
}

pub fn run(a: DemoArgs) -> Result<()> {
    // Before any work: none of the files in --out a link or a folder.
    check_outputs(&a.out, None, &[])?;
    if a.out.is_dir() {
        check_output(&a.out.join(DETECTIONS), "--out", &[])?;
    }
    let r = demo(&a);
    if let Err(e) = &r {
        if !e.chain().any(|c| c.is::<StdoutClosed>()) {
            say_stale_removed(&a.out, None, a.quiet);
        }
    }
    r
}

/// The detections' file in --out.
const DETECTIONS: &str = "detections.jsonl";

/// The demo after the checks.
fn demo(a: &DemoArgs) -> Result<()> {
    let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, a.light, 1).context("built-in preset")?;
    let c = cfg.camera;
    let truth = Intrinsics { fx: c.fx, fy: c.fy, cx: c.cx, cy: c.cy, k1: c.k1, k2: c.k2, p1: c.p1, p2: c.p2, k3: c.k3 };
    let pattern = Pattern::new(cfg.board.rows, cfg.board.cols, cfg.board.spacing).map_err(anyhow::Error::msg)?;
    outln!(
        "evcal demo: a simulated DAVIS346 ({}x{}) sweeps a {}x{} asymmetric circle grid ({} mm) in front of a cluttered wall, {} light, cone motion, {:.1} s",
        c.width,
        c.height,
        pattern.rows,
        pattern.cols,
        pattern.spacing * 1e3,
        a.light.name(),
        a.seconds
    )?;
    // Every window goes through the device's protocol loop below, in the window a device
    // boots with, the host's for the sensor (8000 events on a DAVIS346).
    let det = DetectConfig::for_sensor(SensorSize { width: c.width, height: c.height });
    let (events, sim) = run_windowed_simulation(cfg, a.seconds, det.window, a.quiet)?;
    // As simulate_windows steps.
    let step_s = (det.window.step_us as f64 * 1e-6).max(1e-3);
    let ticks = (0u32..).take_while(|&k| f64::from(k) * step_s < a.seconds).count();
    outln!(
        "simulated {} events: after each of {} window ticks only the time its {} events take ({:.1} ms on average; {:.2} s of the {:.1} s simulated, the rest skipped)",
        events.len(),
        ticks,
        det.window.events,
        1e3 * sim.simulated_seconds() / ticks.max(1) as f64,
        sim.simulated_seconds(),
        a.seconds
    )?;

    // Every window goes through the firmware's protocol loop, the wire encoder and the
    // host's decoder, exactly as from a device.
    let (windows, link) = replay_virtual(&events, det).context("replaying through the virtual device")?;
    let mut score = eval::Score::default();
    let rules = ScoreRules::default();
    for w in &windows {
        score.add(w, &eval::true_circles(&sim.truth_at(w.t_ref_us)), &rules);
    }
    outln!(
        "detection core on the virtual device: {} windows of {} events, {:.0} bytes/window over the link; circles wholly in view found {:.1} %, centre RMS {:.3} px against the truth",
        link.windows,
        det.window.events,
        link.bytes_received as f64 / link.windows.max(1) as f64,
        100.0 * score.found_rate(),
        score.rms_px()
    )?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create the directory", a.out.display()))?;
    write_detections(&a.out.join(DETECTIONS), &windows)?;

    let setup = Setup::new(pattern, [u32::from(c.width), u32::from(c.height)]);
    let views = find_views(&windows, &setup, a.quiet);
    let outcome = solve(&views, &setup)?;
    let verdict = Verdict::of(&outcome);
    let written = export(&views, &outcome, &verdict, &a.out, None)?;
    report(&views, &outcome, &setup, Some(&truth), a.verbose)?;
    list_written(&written, &[a.out.join(DETECTIONS)])?;
    crate::calibrate::finish(&verdict, &a.out)
}

fn write_detections(path: &Path, windows: &[WindowRecord]) -> Result<()> {
    let cannot = || format!("{}: cannot write", path.display());
    let mut out = BufWriter::new(AtomicFile::create(path)?);
    for w in windows {
        writeln!(out, "{}", w.to_json_line()).with_context(cannot)?;
    }
    out.into_inner().map_err(|e| e.into_error()).with_context(cannot)?.commit()?;
    Ok(())
}
