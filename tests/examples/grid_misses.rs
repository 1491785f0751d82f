//! Why the grid is missed where it is wholly in view: for each such window the pipeline
//! leaves without a grid, how many of the true circles the core found (a centre within
//! 1.5 px of the true outline's centre), why the finder refused, and why following it from
//! the windows around it did too. Also checks every labelled point against the truth.
//!
//! `cargo run --release -p evcal-tests --example grid_misses -- davis346 4x11 cone low 4 5`
//! (sensor, pattern, trajectory, light, seconds, seed). `--cache DIR` keeps the core's
//! windows and the truth in DIR, so that a second run with the same arguments skips the
//! simulation (minutes) and only reruns the host's steps (seconds).

use evcal_core::event::SensorSize;
use evcal_host::{
    input::detections::{default_events_per_window, WindowRecord},
    pipeline::Setup,
    views::grid::{find_grid, Pattern},
    views::track::{follow_explained, Unfollowed},
};
use evcal_tests::{
    args,
    recorded::{Recorded, TrueCentre},
};
use std::collections::BTreeMap;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let cache = args::take_cache(&mut args);
    let usage = "grid_misses [--cache DIR] SENSOR PATTERN cone|square|spiral good|low SECONDS SEED";
    if args.len() != 6 {
        eprintln!("usage: {usage}");
        std::process::exit(2);
    }
    let (cfg, pattern, seconds) = args::scenario_or_exit(&args, usage);
    let cam = cfg.camera;
    let events = default_events_per_window(SensorSize { width: cam.width, height: cam.height });
    let file = cache.map(|d| d.join(format!("{}_{events}ev.json", args.join("_"))));
    let rec = Recorded::simulate(cfg, seconds, false, file.as_deref());
    let (windows, truths) = (&rec.windows, &rec.truth);

    let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
    let found: Vec<_> = windows.iter().map(|w| find_grid(&w.centers, &pattern, &setup.find)).collect();
    let followed = follow_explained(windows, &found, &pattern, &setup.track.unwrap_or_default());
    // True circles the core found in a window: a centre within 1.5 px of the outline's centre.
    let true_found = |k: usize| {
        truths[k]
            .iter()
            .filter(|t| {
                let d = |c: &evcal_host::input::detections::CenterRecord| {
                    (f64::from(c.u) - t.centre[0]).hypot(f64::from(c.v) - t.centre[1])
                };
                windows[k].centers.iter().any(|c| d(c) < 1.5)
            })
            .count()
    };
    let (mut n_in_view, mut n_found, mut n_followed, mut wrong) = (0, 0, 0, 0);
    let (mut worst_offset, mut smallest) = (0.0f64, usize::MAX);
    let mut reasons: BTreeMap<String, usize> = BTreeMap::new();
    let mut hist_found: BTreeMap<usize, usize> = BTreeMap::new();
    let mut hist_missed: BTreeMap<usize, usize> = BTreeMap::new();
    for k in 0..windows.len() {
        let grid = found[k].as_ref().ok().or(followed[k].as_ref().ok().map(|f| &f.grid));
        if let Ok(f) = &followed[k] {
            if std::env::var_os("GRID_MISSES_MAP").is_some() {
                println!(
                    "followed window {k:4}: {} points, {:.3} spacings from the prediction",
                    f.grid.points.len(),
                    f.prediction_offset
                );
            }
            worst_offset = worst_offset.max(f.prediction_offset);
            smallest = smallest.min(f.grid.points.len());
        }
        if let Some(g) = grid {
            // Wrong ordering: a labelled point whose nearest true circle is another.
            let bad = g.points.iter().any(|p| rec.nearest(k, p.image) != Some(p.index));
            if bad {
                wrong += 1;
                println!("WRONG ORDERING in window {} (seq {})", k, windows[k].seq);
            }
        }
        if !rec.wholly_in_view(k) {
            continue;
        }
        n_in_view += 1;
        let tf = true_found(k);
        match grid {
            Some(g) => {
                n_found += 1;
                n_followed += usize::from(found[k].is_err());
                *hist_found.entry(tf).or_default() += 1;
                let _ = g;
            }
            None => {
                *hist_missed.entry(tf).or_default() += 1;
                let finder = found[k].as_ref().err().map_or("-".to_string(), |m| format!("{m:?}"));
                let track = match &followed[k] {
                    Err(Unfollowed::TooFewMatched(_)) => "TooFewMatched".to_string(),
                    Err(Unfollowed::TooFewRefined(_)) => "TooFewRefined".to_string(),
                    Err(u) => format!("{u:?}"),
                    Ok(_) => "-".into(),
                };
                *reasons.entry(format!("finder {finder}, track {track}")).or_default() += 1;
                println!(
                    "missed window {k:4} t {:7.3} s: core found {tf:2}/{} true circles ({} centres); finder {finder}; track {:?}",
                    (windows[k].t_ref_us - windows[0].t_ref_us) as f64 * 1e-6,
                    truths[k].len(),
                    windows[k].centers.len(),
                    followed[k].as_ref().err(),
                );
                if std::env::var_os("GRID_MISSES_MAP").is_some() {
                    print_map(&windows[k], &truths[k], &pattern);
                }
            }
        }
    }
    println!(
        "found in {n_found} of {n_in_view} wholly-in-view windows ({:.1} %), {n_followed} followed; wrong orderings {wrong} (all windows)",
        100.0 * n_found as f64 / n_in_view.max(1) as f64
    );
    // The longest run of windows the finder missed in a row: how far following must reach.
    let (mut run, mut longest) = (0usize, 0usize);
    for r in &found {
        run = if r.is_err() { run + 1 } else { 0 };
        longest = longest.max(run);
    }
    println!("longest run of windows the finder missed in a row: {longest}");
    println!("followed grids: fewest points {smallest}, farthest from the prediction {worst_offset:.3} spacings");
    for (r, n) in &reasons {
        println!("  missed: {n:3} {r}");
    }
    println!("true circles found by the core, windows found: {hist_found:?}");
    println!("true circles found by the core, windows missed: {hist_missed:?}");
}

/// The board as the core saw it in one window, one line per board row as `Pattern::picture`:
/// `#` a centre within 1.5 px of the truth, `~` within 5 px (a poor fit), `.` none; then
/// the centres matching no circle.
fn print_map(w: &WindowRecord, truth: &[TrueCentre], pattern: &Pattern) {
    let near = |t: [f64; 2]| {
        w.centers
            .iter()
            .map(|c| ((f64::from(c.u) - t[0]).hypot(f64::from(c.v) - t[1]), c))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    };
    for k in 0..2 * pattern.rows {
        let mut line = String::from("      ");
        for i in 0..pattern.cols {
            if (k + i) % 2 == 1 {
                line.push_str("  ");
                continue;
            }
            let idx = i * pattern.rows + (k - i % 2) / 2;
            line.push(match near(truth[idx].centre) {
                Some((d, _)) if d < 1.5 => '#',
                Some((d, _)) if d < 5.0 => '~',
                _ => '.',
            });
            line.push(' ');
        }
        println!("{line}");
    }
    let stray: Vec<String> = w
        .centers
        .iter()
        .filter(|c| truth.iter().all(|t| (f64::from(c.u) - t.centre[0]).hypot(f64::from(c.v) - t.centre[1]) >= 1.5))
        .map(|c| {
            let (d, i) = truth
                .iter()
                .enumerate()
                .map(|(i, t)| ((f64::from(c.u) - t.centre[0]).hypot(f64::from(c.v) - t.centre[1]), i))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .unwrap_or((f64::NAN, 0));
            format!("r {:.1} n {} conv {} {:.1} px from {}", c.r, c.n, c.converged, d, i)
        })
        .collect();
    println!("      other centres: {}", stray.join("; "));
}
