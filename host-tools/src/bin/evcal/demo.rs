//! `evcal demo`: the main job on a built-in default.

use crate::common::{run_simulation, truth_json, window_truths, write_json};
use anyhow::{Context, Result};
use clap::Args;
use evcal_core::{detect::DetectConfig, event::SensorSize, fit::FitMethod, window::WindowConfig};
use evcal_host::{
    eval::{self, ScoreRules},
    link::replay::replay_virtual,
    sim::{Light, SimConfig, Trajectory},
};
use std::{
    io::{BufWriter, Write},
    path::PathBuf,
};

#[derive(Args)]
pub struct DemoArgs {
    /// Simulated seconds.
    #[arg(long, default_value_t = 3.0)]
    pub seconds: f64,
    /// Lighting.
    #[arg(long, value_enum, default_value_t = Light::Good)]
    pub light: Light,
    /// Output folder.
    #[arg(long, default_value = "evcal-out")]
    pub out: PathBuf,
}

pub fn run(a: DemoArgs) -> Result<()> {
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
    let mut link_report = None;
    for method in [FitMethod::Centroid, FitMethod::Ols, FitMethod::Erwls] {
        let mut d = det;
        d.fit.method = method;
        let started = std::time::Instant::now();
        let mut s = eval::Score::default();
        let mut windows = 0u64;
        let mut write_err = None;
        if method == FitMethod::Erwls {
            // The method evcal uses runs exactly as on a device: every window through the
            // firmware's protocol loop, the wire encoder and the host's decoder.
            let (records, link) = replay_virtual(&events, d).context("replaying through the virtual device")?;
            for w in &records {
                windows += 1;
                s.add(w, &eval::true_circles(&sim.truth_at(w.t_ref_us)), &rules);
                if write_err.is_none() {
                    write_err = writeln!(out, "{}", w.to_json_line()).err();
                }
            }
            link_report = Some(link);
        } else {
            eval::detect_with_truth(&events, &sim, d, |w, t| {
                windows += 1;
                s.add(w, &eval::true_circles(t), &rules);
            });
        }
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
    if let Some(l) = &link_report {
        println!(
            "  link (eRWLS run, through the device loop and wire codec): {} windows received, {} lost; {:.0} bytes/window back, {:.2} bytes/event replayed in",
            l.windows,
            l.windows_lost,
            l.bytes_received as f64 / l.windows.max(1) as f64,
            l.bytes_sent as f64 / l.events_sent.max(1) as f64
        );
    }
    println!("  (per-stage core timings: cargo bench -p evcal-host --bench core)");
    println!("  wrote {} and {}", path.display(), a.out.join("truth.json").display());
    Ok(())
}
