//! The calibration over a sweep of the simulated pixel's physics: photoreceptor bandwidth,
//! light, motion, focus, for each sensor asked for. One table row per case: fx, fy error
//! (%), cx, cy error (px), each error in units of the printed σ, the RMS and the views.
//!
//! `cargo run --release -p evcal-tests --example physics_sweep -- [--cache DIR] [--seconds S] SENSOR...`
//! (default: davis346, 8 s per case; each case is a continuous simulation, about a minute
//! of CPU for 8 s of a DAVIS346, so the whole sweep takes a while: `--cache DIR` keeps each
//! case's detection windows for a rerun of the host's steps). `--cases` lists the cases
//! without running them.
//!
//! Cases: photoreceptor cutoff at full light unlimited, 1000, 300 and 100 Hz; good and low
//! light; cone and spiral; in focus, and out of focus (edge blur 2.5 px at the focus
//! distance) for the good-light cone at 300 Hz. Thresholds, mismatch, leak and shot noise
//! are those of `PixelModel::physical` for the light.

use evcal_host::{
    pipeline::{calibrate_views, views_from_windows, Setup},
    sim::{Light, PixelModel, Trajectory},
};
use evcal_tests::{args, recorded::Recorded};

/// One case of the sweep.
struct Case {
    trajectory: Trajectory,
    light: Light,
    photoreceptor_hz: f64,
    blur_px: Option<f64>,
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    for light in [Light::Good, Light::Low] {
        for trajectory in [Trajectory::Cone, Trajectory::Spiral] {
            for hz in [f64::INFINITY, 1000.0, 300.0, 100.0] {
                out.push(Case { trajectory, light, photoreceptor_hz: hz, blur_px: None });
            }
        }
    }
    out.push(Case { trajectory: Trajectory::Cone, light: Light::Good, photoreceptor_hz: 300.0, blur_px: Some(2.5) });
    out
}

fn main() {
    let mut argv: Vec<String> = std::env::args().skip(1).collect();
    let cache = args::take_cache(&mut argv);
    let list_only = argv.iter().position(|a| a == "--cases").map(|i| argv.remove(i)).is_some();
    let mut seconds = 8.0;
    if let Some(i) = argv.iter().position(|a| a == "--seconds") {
        match argv.get(i + 1).and_then(|s| s.parse::<f64>().ok()) {
            Some(s) if s > 0.0 => seconds = s,
            _ => {
                eprintln!("--seconds needs a positive number");
                std::process::exit(2);
            }
        }
        argv.drain(i..i + 2);
    }
    let sensors = if argv.is_empty() { vec!["davis346".to_string()] } else { argv };
    println!("| sensor | motion | light | photoreceptor | focus | fx error | fy error | cx error | cy error | error / σ (fx, fy, cx, cy) | RMS | views |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for sensor in &sensors {
        for c in cases() {
            let pattern_name = if c.trajectory == Trajectory::Spiral { "3x9" } else { "4x11" };
            let (mut cfg, pattern) = args::preset_or_exit(sensor, pattern_name, c.trajectory, c.light, 5);
            cfg.pixel = PixelModel::physical(c.light, c.photoreceptor_hz);
            if let Some(b) = c.blur_px {
                cfg.blur_px = b;
            }
            let hz = if c.photoreceptor_hz.is_finite() {
                format!("{:.0} Hz", c.photoreceptor_hz)
            } else {
                "unlimited".into()
            };
            let focus = if c.blur_px.is_some() { "out (2.5 px)" } else { "in" };
            let label =
                format!("| {sensor} {pattern_name} | {} | {} | {hz} | {focus} |", c.trajectory.name(), c.light.name());
            if list_only {
                println!("{label} | | | | | | | |");
                continue;
            }
            let file = cache.as_ref().map(|d| {
                d.join(format!(
                    "sweep_{sensor}_{pattern_name}_{}_{}_{hz}_{focus}_{seconds}.json",
                    c.trajectory.name(),
                    c.light.name()
                ))
            });
            let cam = cfg.camera;
            let rec = Recorded::simulate(cfg, seconds, false, file.as_deref());
            let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
            let views = views_from_windows(&rec.windows, &setup, &|_| {});
            match calibrate_views(&views, &setup) {
                Ok(o) => {
                    let (k, sd) = (o.calibration.intrinsics, o.calibration.std_dev);
                    let e =
                        [100.0 * (k.fx / cam.fx - 1.0), 100.0 * (k.fy / cam.fy - 1.0), k.cx - cam.cx, k.cy - cam.cy];
                    let s = [100.0 * sd[0] / k.fx, 100.0 * sd[1] / k.fy, sd[2], sd[3]];
                    let ratio: Vec<String> = (0..4).map(|i| format!("{:+.1}", e[i] / s[i])).collect();
                    let failed = o.failure.as_ref().map_or(String::new(), |_| " (no calibration)".into());
                    println!(
                        "{label} {:+.3} % (σ {:.3}){failed} | {:+.3} % | {:+.2} px (σ {:.2}) | {:+.2} px | {} | {:.3} px | {} |",
                        e[0],
                        s[0],
                        e[1],
                        e[2],
                        s[2],
                        e[3],
                        ratio.join(", "),
                        o.calibration.rms_px,
                        o.calibration.views.len()
                    );
                }
                Err(e) => println!("{label} failed: {e} | | | | | | |"),
            }
        }
    }
}
