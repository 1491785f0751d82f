//! The calibration end to end over several seeds, to tell a bias from the scatter of one
//! run: each seed simulates its own recording (continuous event simulation), runs the core,
//! finds the grid, solves with and without the edge-shift correction, and prints the errors
//! against the truth.
//!
//! `cargo run --release -p evcal-tests --example calibration_seeds -- davis346 4x11 cone good 4 1 2 3 4 5 6 7`
//! (sensor, pattern, trajectory, light, seconds, then the seeds; about 40 s per seed).
//! `--windowed` before the arguments simulates only the milliseconds each window needs, as
//! `evcal demo` does (`eval::simulate_windows`; a few seconds per seed).

use evcal_core::{detect::DetectConfig, event::SensorSize};
use evcal_host::{
    detections::{self, WindowRecord},
    eval::{simulate, simulate_windows},
    grid::Pattern,
    pipeline::{calibrate_views, views_from_windows, Setup},
    sim::{Light, SimConfig, Trajectory},
};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let windowed = args.first().is_some_and(|a| a == "--windowed");
    if windowed {
        args.remove(0);
    }
    if args.len() < 6 {
        eprintln!("usage: calibration_seeds [--windowed] SENSOR PATTERN cone|square|spiral good|low SECONDS SEED...");
        std::process::exit(2);
    }
    let trajectory = match args[2].as_str() {
        "spiral" => Trajectory::Spiral,
        "square" => Trajectory::Square,
        _ => Trajectory::Cone,
    };
    let light = if args[3] == "low" { Light::Low } else { Light::Good };
    let Ok(seconds) = args[4].parse::<f64>() else {
        eprintln!("SECONDS: not a number: {}", args[4]);
        std::process::exit(2);
    };
    let mut with_shift = Vec::new();
    for seed in &args[5..] {
        let Ok(seed) = seed.parse::<u64>() else {
            eprintln!("SEED: not a number: {seed}");
            std::process::exit(2);
        };
        let Some(cfg) = SimConfig::preset(&args[0], &args[1], trajectory, light, seed) else {
            eprintln!("unknown sensor or pattern: {} {}", args[0], args[1]);
            std::process::exit(2);
        };
        let cam = cfg.camera;
        let pattern = Pattern::new(cfg.board.rows, cfg.board.cols, cfg.board.spacing).expect("preset pattern");
        let det = DetectConfig::new(SensorSize { width: cam.width, height: cam.height });
        let (events, _) =
            if windowed { simulate_windows(cfg, seconds, det.window, |_| {}) } else { simulate(cfg, seconds) };
        let mut windows = Vec::new();
        detections::run(events.iter().map(|e| Ok(*e)), det, |d| windows.push(WindowRecord::from_detection(d)))
            .expect("simulated events are valid");
        let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
        let views = views_from_windows(&windows, &setup, &|_| {});
        for shift in [true, false] {
            let s = Setup { edge_shift: shift, ..setup.clone() };
            match calibrate_views(&views, &s) {
                Ok(o) => {
                    let k = o.calibration.intrinsics;
                    let fx = 100.0 * (k.fx / cam.fx - 1.0);
                    if shift {
                        with_shift.push(fx);
                    }
                    println!(
                        "seed {seed}, edge shift {}: grid in {}/{} windows, {} views, RMS {:.3} px, fx {fx:+.3} % fy {:+.3} % (σ {:.3} %), cx {:+.2} cy {:+.2} px, shift {}",
                        if shift { "on " } else { "off" },
                        views.stats.found,
                        views.stats.windows,
                        o.calibration.views.len(),
                        o.calibration.rms_px,
                        100.0 * (k.fy / cam.fy - 1.0),
                        100.0 * o.calibration.std_dev[0] / k.fx,
                        k.cx - cam.cx,
                        k.cy - cam.cy,
                        o.edge_shift.map_or("none".into(), |e| format!("{:.3} ± {:.3} px", e.px, e.std_px)),
                    );
                }
                Err(e) => println!("seed {seed}: {e}"),
            }
        }
    }
    if with_shift.len() > 1 {
        let n = with_shift.len() as f64;
        let mean = with_shift.iter().sum::<f64>() / n;
        let sd = (with_shift.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        println!("fx with the shift correction over {} seeds: mean {mean:+.3} %, scatter {sd:.3} %", with_shift.len());
    }
}
