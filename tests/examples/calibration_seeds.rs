//! The calibration end to end over several seeds, to tell a bias from the scatter of one
//! run: each seed simulates its own recording (continuous event simulation), runs the core,
//! finds the grid, solves with and without the edge-shift correction, and prints the errors
//! against the truth.
//!
//! `cargo run --release -p evcal-tests --example calibration_seeds -- davis346 4x11 cone good 4 1 2 3 4 5 6 7`
//! (sensor, pattern, trajectory, light, seconds, then the seeds; about 40 s per seed).
//! `--windowed` before the arguments simulates only the milliseconds each window needs, as
//! `evcal demo` does (`eval::simulate_windows`; a few seconds per seed). `--cache DIR` keeps
//! each seed's windows and truth in DIR, so that a second run skips the simulation.
//!
//! Per seed it also prints in how many of the windows with the grid wholly in view the grid
//! was found (the issue's ≥ 95 %), and how many labelled views hold a point whose nearest
//! true circle is another (wrong orderings; must be 0).

use evcal_core::event::SensorSize;
use evcal_host::{
    input::detections::default_events_per_window,
    pipeline::{calibrate_views, views_from_windows, Setup},
};
use evcal_tests::{args, recorded::Recorded};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let cache = args::take_cache(&mut args);
    let windowed = args.first().is_some_and(|a| a == "--windowed");
    if windowed {
        args.remove(0);
    }
    if args.len() < 6 {
        eprintln!("usage: calibration_seeds [--cache DIR] [--windowed] SENSOR PATTERN cone|square|spiral good|low SECONDS SEED...");
        std::process::exit(2);
    }
    let (trajectory, light) = (args::trajectory(&args[2]), args::light(&args[3]));
    let Ok(seconds) = args[4].parse::<f64>() else {
        eprintln!("SECONDS: not a number: {}", args[4]);
        std::process::exit(2);
    };
    let mut with_shift = Vec::new();
    // Per seed, the edge-shift-on solve's fx, fy, cx, cy errors in units of their σ.
    let mut z: Vec<[f64; 4]> = Vec::new();
    for seed in &args[5..] {
        let Ok(seed) = seed.parse::<u64>() else {
            eprintln!("SEED: not a number: {seed}");
            std::process::exit(2);
        };
        let (cfg, pattern) = args::preset_or_exit(&args[0], &args[1], trajectory, light, seed);
        let cam = cfg.camera;
        let file = cache.as_ref().map(|d| {
            let name = format!(
                "{}_{}_{}_{}_{}_{seed}{}_{}ev.json",
                args[0],
                args[1],
                args[2],
                args[3],
                args[4],
                if windowed { "_windowed" } else { "" },
                default_events_per_window(SensorSize { width: cam.width, height: cam.height })
            );
            d.join(name)
        });
        let rec = Recorded::simulate(cfg, seconds, windowed, file.as_deref());
        let windows = &rec.windows;
        let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
        let views = views_from_windows(windows, &setup, &|_| {});
        // Found where the grid is wholly in view; views holding a point labelled as another.
        let in_view: Vec<usize> = (0..windows.len()).filter(|&k| rec.wholly_in_view(k)).collect();
        let found_in_view = in_view.iter().filter(|&&k| views.timeline[k].grid_found).count();
        let by_seq: std::collections::HashMap<u64, usize> =
            windows.iter().enumerate().map(|(k, w)| (u64::from(w.seq), k)).collect();
        let wrong = views
            .views
            .iter()
            .zip(&views.origins)
            .filter(|(v, o)| {
                let k = by_seq[&o.window_seq];
                v.object
                    .iter()
                    .zip(&v.image)
                    .any(|(obj, p)| rec.nearest(k, *p).map(|i| pattern.object_point(i)) != Some(*obj))
            })
            .count();
        println!(
            "seed {seed}: grid found in {found_in_view} of {} wholly-in-view windows ({:.1} %), {} followed; wrong orderings {wrong}",
            in_view.len(),
            100.0 * found_in_view as f64 / in_view.len().max(1) as f64,
            views.stats.followed,
        );
        for shift in [true, false] {
            let s = Setup { edge_shift: shift, ..setup.clone() };
            match calibrate_views(&views, &s) {
                Ok(o) => {
                    let k = o.calibration.intrinsics;
                    let fx = 100.0 * (k.fx / cam.fx - 1.0);
                    let sd = o.calibration.std_dev;
                    let e = [k.fx - cam.fx, k.fy - cam.fy, k.cx - cam.cx, k.cy - cam.cy];
                    let zs: [f64; 4] = std::array::from_fn(|i| e[i] / sd[i]);
                    if shift {
                        with_shift.push(fx);
                        z.push(zs);
                    }
                    let groups = o.calibration.sigma_groups.map_or("points' own".into(), |g| format!("{g} groups"));
                    println!(
                        "seed {seed}, edge shift {}: grid in {}/{} windows, {} views, RMS {:.3} px, fx {fx:+.3} % fy {:+.3} % (σ {:.3} %), cx {:+.2} cy {:+.2} px, error/σ {:+.1} {:+.1} {:+.1} {:+.1} (σ: {groups}), shift {}",
                        if shift { "on " } else { "off" },
                        views.stats.found,
                        views.stats.windows,
                        o.calibration.views.len(),
                        o.calibration.rms_px,
                        100.0 * (k.fy / cam.fy - 1.0),
                        100.0 * o.calibration.std_dev[0] / k.fx,
                        k.cx - cam.cx,
                        k.cy - cam.cy,
                        zs[0],
                        zs[1],
                        zs[2],
                        zs[3],
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
    if z.len() > 1 {
        // An honest σ makes these about 1, and beyond 3 one time in 370.
        let names = ["fx", "fy", "cx", "cy"];
        let parts: Vec<String> = (0..4)
            .map(|i| {
                let rms = (z.iter().map(|z| z[i] * z[i]).sum::<f64>() / z.len() as f64).sqrt();
                let over = z.iter().filter(|z| z[i].abs() > 3.0).count();
                format!("{} RMS {rms:.2} ({over} beyond 3)", names[i])
            })
            .collect();
        println!("error/σ over {} seeds: {}", z.len(), parts.join(", "));
    }
}
