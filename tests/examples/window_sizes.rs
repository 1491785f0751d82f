//! How the number of events per window shapes detection and calibration on one simulated
//! scenario: for each window size, a windowed simulation (`eval::simulate_windows`, only the
//! milliseconds each window needs), the core, the grid finder and the solve, against the
//! truth. What the host's default window size (`evcal_host::input::detections::default_events_per_window`)
//! was chosen from.
//!
//! `cargo run --release -p evcal-tests --example window_sizes -- dvxplorer 4x11 cone good 8 1 4000 8000 16000`
//! (sensor, pattern, trajectory, light, seconds, seed, then the window sizes; `default` stands
//! for the host's default for the sensor).
//!
//! Per size it prints: circles wholly in view found by the core (`eval::Score`, the issue's
//! 95 %) and their centre RMS; windows with the grid wholly in view in which the finder
//! labelled it by itself, and with the windows around it (as `evcal calibrate` counts); the
//! window's mean duration; the calibration's errors against the truth.

use evcal_core::{detect::DetectConfig, event::SensorSize, window::WindowConfig};
use evcal_host::{
    eval::{simulate_windows, true_circles, Score, ScoreRules},
    input::detections::{self, default_events_per_window, WindowRecord, HOST_MAX_EVENTS},
    pipeline::{calibrate_views, views_from_windows, Setup},
};
use evcal_tests::args;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "window_sizes SENSOR PATTERN cone|square|spiral good|low SECONDS SEED EVENTS|default...";
    if args.len() < 7 {
        eprintln!("usage: {usage}");
        std::process::exit(2);
    }
    let (cfg, pattern, seconds) = args::scenario_or_exit(&args, usage);
    let seed = cfg.seed;
    let cam = cfg.camera;
    let sensor = SensorSize { width: cam.width, height: cam.height };
    for n in &args[6..] {
        let events = if n == "default" {
            default_events_per_window(sensor)
        } else {
            match n.parse::<usize>() {
                Ok(e) if (1..=HOST_MAX_EVENTS).contains(&e) => e,
                _ => {
                    eprintln!("EVENTS: a number from 1 to {HOST_MAX_EVENTS}, or default: {n}");
                    std::process::exit(2);
                }
            }
        };
        let started = std::time::Instant::now();
        let mut det = DetectConfig::new(sensor);
        det.window = WindowConfig { events, ..det.window };
        let (evs, sim) = simulate_windows(cfg.clone(), seconds, det.window, |_| {});
        let mut windows = Vec::new();
        detections::run(evs.iter().map(|e| Ok(*e)), det, |d| windows.push(WindowRecord::from_detection(d)))
            .expect("simulated events are valid");
        let mut score = Score::default();
        let mut in_view = Vec::with_capacity(windows.len());
        let mut span_us = 0u64;
        for w in &windows {
            let t = sim.truth_at(w.t_ref_us);
            score.add(w, &true_circles(&t), &ScoreRules::default());
            in_view.push(t.circles.iter().all(|c| c.in_view));
        }
        // The windows' durations, as the core cut them.
        let mut w: Box<evcal_core::window::Windower<HOST_MAX_EVENTS>> =
            Box::new(evcal_core::window::Windower::new(det.window));
        let mut durations = 0usize;
        for info in evs.iter().filter_map(|e| w.push(*e)) {
            span_us += info.t_last_us - info.t_first_us;
            durations += 1;
        }
        let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
        let alone = Setup { track: None, ..setup.clone() };
        let views = views_from_windows(&windows, &setup, &|_| {});
        let views_alone = views_from_windows(&windows, &alone, &|_| {});
        let n_in_view = in_view.iter().filter(|&&b| b).count();
        let found = |t: &[evcal_host::views::WindowSample]| {
            t.iter().zip(&in_view).filter(|(s, &iv)| iv && s.grid_found).count()
        };
        let (by_itself, with_tracking) = (found(&views_alone.timeline), found(&views.timeline));
        let calib = match calibrate_views(&views, &setup) {
            Ok(o) => {
                let k = o.calibration.intrinsics;
                format!(
                    "fx {:+.3} % fy {:+.3} %, cx {:+.2} cy {:+.2} px, RMS {:.3} px over {} views",
                    100.0 * (k.fx / cam.fx - 1.0),
                    100.0 * (k.fy / cam.fy - 1.0),
                    k.cx - cam.cx,
                    k.cy - cam.cy,
                    o.calibration.rms_px,
                    o.calibration.views.len()
                )
            }
            Err(e) => format!("no calibration: {e}"),
        };
        println!(
            "{} {} {} {} {seconds} s seed {seed}, {events} events/window ({:.1} ms): circles found {:.1} % of {} (centre RMS {:.3} px); grid wholly in view in {n_in_view} of {} windows, found by the finder in {by_itself} ({:.1} %), with tracking {with_tracking} ({:.1} %); {calib}; {:.0} s",
            args[0],
            args[1],
            args[2],
            args[3],
            1e-3 * span_us as f64 / durations.max(1) as f64,
            100.0 * score.found_rate(),
            score.circles,
            score.rms_px(),
            windows.len(),
            100.0 * by_itself as f64 / n_in_view.max(1) as f64,
            100.0 * with_tracking as f64 / n_in_view.max(1) as f64,
            started.elapsed().as_secs_f64()
        );
    }
}
