//! The calibration over a sweep of the simulated pixel's physics: photoreceptor bandwidth,
//! light, motion, focus, for each sensor asked for. One table row per case: fx, fy error
//! (%), cx, cy error (px), each error in units of the printed σ, the RMS and the views.
//!
//! `cargo run --release -p evcal-tests --example physics_sweep -- [--cache DIR] [--seconds S] SENSOR...`
//! (default: davis346, 8 s per case; each case is a continuous simulation, about a minute
//! of CPU for 8 s of a DAVIS346, so the whole sweep takes a while: `--cache DIR` keeps each
//! case's detection windows for a rerun of the host's steps). `--cases` lists the cases
//! without running them; `--only TEXT` (repeatable) runs only the cases whose table row
//! names TEXT (`--only "cone | good | 300 Hz"`), for a large sensor's slower cases.
//! `--seed N` simulates every case with seed N instead of the table's
//! (`sweep::SEED`): another draw of the pixels' mismatch, noise and clutter, to tell a
//! case's bias from one run's scatter.
//! `--lag` prints, under each case's row, how far its centres lag their circles along the
//! motion at each image speed, against the simulator's truth (`sweep::lag_by_speed`).
//! `--decompose` solves each case again on the truth plus only a part of its centres' error
//! (along the motion, across it, along it as a line in the speed per window, or along it
//! as each window's mean; `sweep::decompose`), to tell which part carries a bias.
//!
//! The cases and their targets are `evcal_tests::sweep`'s; the last column says which
//! targets a case misses. `tests/tests/end_to_end/physics.rs` runs a corner of the sweep (CI a smoke case, the slow tier the rest).

use evcal_core::event::SensorSize;
use evcal_host::input::detections::window_events_for;
use evcal_tests::{args, sweep};

fn main() {
    let mut argv: Vec<String> = std::env::args().skip(1).collect();
    let cache = args::take_cache(&mut argv);
    let list_only = argv.iter().position(|a| a == "--cases").map(|i| argv.remove(i)).is_some();
    let lag = argv.iter().position(|a| a == "--lag").map(|i| argv.remove(i)).is_some();
    let decompose = argv.iter().position(|a| a == "--decompose").map(|i| argv.remove(i)).is_some();
    let mut only = Vec::new();
    while let Some(i) = argv.iter().position(|a| a == "--only") {
        let Some(text) = argv.get(i + 1).cloned() else {
            eprintln!("--only needs the text of the rows to run");
            std::process::exit(2);
        };
        only.push(text);
        argv.drain(i..i + 2);
    }
    let seconds = args::take_value(&mut argv, "--seconds", "a positive number", |s: &f64| *s > 0.0).unwrap_or(8.0);
    let seed = args::take_value(&mut argv, "--seed", "a whole number", |_: &u64| true).unwrap_or(sweep::SEED);
    let sensors = if argv.is_empty() { vec!["davis346".to_string()] } else { argv };
    println!("| sensor | motion | light | photoreceptor | focus | threshold, noise | fx error | fy error | cx error | cy error | error / σ (fx, fy, cx, cy) | RMS | views | targets |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut missed = 0;
    for sensor in &sensors {
        for c in sweep::cases() {
            if c.config(sensor).is_none() {
                eprintln!("unknown sensor {sensor}");
                std::process::exit(2);
            }
            let (hz, focus) = (c.photoreceptor(), c.focus());
            let label = format!(
                "| {sensor} {} | {} | {} | {hz} | {focus} | {} |",
                c.pattern(),
                c.trajectory.name(),
                c.light.name(),
                c.pixel()
            );
            if !only.is_empty() && !only.iter().any(|t| label.contains(t.as_str())) {
                continue;
            }
            if list_only {
                println!("{label} | | | | | | | | |");
                continue;
            }
            // The base grid's names as they were before the threshold and noise were swept,
            // so that caches written then still serve.
            let pixel = if c.threshold.is_none() && c.noise == sweep::Noise::Preset {
                String::new()
            } else {
                format!("_{}", c.pixel().replace([' ', ',', '±'], ""))
            };
            // The discs' windows, where they are not the rings' (a larger sensor), name the
            // file too: caches written with other disc windows do not serve.
            let discs = c.config(sensor).map_or(String::new(), |(cfg, _)| {
                let size = SensorSize { width: cfg.camera.width, height: cfg.camera.height };
                let (rings, discs) = (window_events_for(size, false), window_events_for(size, true));
                if discs == rings {
                    String::new()
                } else {
                    format!("_discs{discs}")
                }
            });
            let file = cache.as_ref().map(|d| {
                d.join(format!(
                    "sweep_{sensor}_{}_{}_{}_{hz}_{focus}{pixel}_{seconds}{discs}{}.json",
                    c.pattern(),
                    c.trajectory.name(),
                    c.light.name(),
                    if seed == sweep::SEED { String::new() } else { format!("_seed{seed}") }
                ))
            });
            // Recorded once for both the calibration and the lag.
            let Some(rec) = sweep::record(&c, sensor, seed, seconds, file.as_deref()) else { continue };
            match sweep::run_on(&c, sensor, &rec) {
                Ok(o) => {
                    let (e, s) = (o.errors, o.sigmas);
                    let ratio: Vec<String> = (0..4).map(|i| format!("{:+.1}", e[i] / s[i])).collect();
                    let failed = if o.failed { " (no calibration)" } else { "" };
                    let discs = if o.filled_discs { " (filled discs)" } else { "" };
                    let misses = o.misses(&c.targets());
                    missed += usize::from(!misses.is_empty());
                    let verdict = if misses.is_empty() { "met".to_string() } else { misses.join("; ") };
                    println!(
                        "{label} {:+.3} % (σ {:.3}){failed} | {:+.3} % | {:+.2} px (σ {:.2}) | {:+.2} px | {} | {:.3} px | {}{discs} | {verdict} |",
                        e[0],
                        s[0],
                        e[1],
                        e[2],
                        s[2],
                        e[3],
                        ratio.join(", "),
                        o.rms_px,
                        o.views
                    );
                }
                Err(e) => {
                    missed += 1;
                    println!("{label} failed: {e} | | | | | | | |")
                }
            }
            if lag {
                for (lo, hi, n, mean) in sweep::lag_by_speed(&rec) {
                    println!("    lag along the motion at {lo:.0}-{hi:.0} px/s: {mean:+.3} px ({n} centres)");
                }
            }
            if decompose {
                for (what, o) in sweep::decompose(&c, sensor, &rec) {
                    match o {
                        Ok(o) => println!(
                            "    {what}: fx {:+.3} % (σ {:.3}), fy {:+.3} %, cx {:+.2}, cy {:+.2} px, {} views",
                            o.errors[0], o.sigmas[0], o.errors[1], o.errors[2], o.errors[3], o.views
                        ),
                        Err(e) => println!("    {what}: {e}"),
                    }
                }
            }
        }
    }
    if !list_only {
        println!("\n{missed} case(s) miss a target");
    }
}
