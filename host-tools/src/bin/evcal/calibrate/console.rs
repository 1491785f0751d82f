//! What `evcal calibrate` (and `evcal demo`) print: the result for people, the diagnostics
//! behind `-v`, and the verdict last, with the exit status it gives.

use crate::common::outln;
use anyhow::Result;
use evcal_host::{
    calib::{Intrinsics, PARAMETER_NAMES},
    pipeline::{Outcome, Setup, Verdict, Views},
};
use std::path::Path;

/// Ends the run with its verdict: printed last, and the exit status it gives (0 good, 4
/// usable, 3 not a calibration; [`Verdict::exit_code`]).
pub fn finish(verdict: &Verdict, out: &Path) -> Result<()> {
    if let Verdict::NotACalibration { .. } = verdict {
        eprintln!(
            "evcal: the files in {} are named *.failed.* and hold no camera matrix a program would load (no --json copy is written)",
            out.display()
        );
    }
    outln!("{verdict}")?;
    match verdict.exit_code() {
        0 => Ok(()),
        code => std::process::exit(code),
    }
}

pub(super) fn indent(s: &str) -> String {
    s.lines().map(|l| format!("    {l}")).collect::<Vec<_>>().join("\n")
}

/// Prints the result for people, beside `truth` when known: what a user needs (views, the
/// error, the parameters with σ, the coverage, warnings) and, when `verbose`, how the run got
/// there (views set aside, the centres' smoothing and lag, the weights, the σ's method, the
/// coverage map).
pub fn report(views: &Views, o: &Outcome, setup: &Setup, truth: Option<&Intrinsics>, verbose: bool) -> Result<()> {
    let c = &o.calibration;
    outln!("{}", views.stats.summary())?;
    outln!("{}", views_line(o, &setup.select))?;
    if verbose {
        diagnostics(o, setup)?;
    }
    let points = c.views.iter().map(|v| v.points).sum::<usize>();
    let strays = match c.stray_points {
        0 => String::new(),
        n => format!(" ({n} stray points set aside; RMS with them {:.3} px)", c.rms_all_px),
    };
    outln!(
        "reprojection error: RMS {:.3} px over {} points{strays}; per view median {:.3} px",
        c.rms_px,
        points - c.stray_points,
        c.median_view_px
    )?;
    parameter_table(c, truth)?;
    if verbose {
        sigma_method(c)?;
    }
    outln!(
        "coverage: points on {:.0} % of the sensor's cells{}",
        100.0 * o.coverage.covered,
        if verbose { ":" } else { " (the map: report.png, or -v)" }
    )?;
    if verbose {
        outln!("{}", indent(&o.coverage.picture()))?;
    }
    if let Some(s) = &o.projection_sigma {
        outln!("{}", s.summary())?;
    }
    if let Some(h) = &o.k3_held {
        outln!("note: {h}")?;
    }
    for w in c.warnings.iter().chain(&o.advice) {
        outln!("warning: {w}")?;
    }
    if let Some(w) = &o.weak_focal {
        outln!("warning: {w}")?;
    }
    Ok(())
}

/// One line with one count of views: with the grid, solved on, and why the others were not.
fn views_line(o: &Outcome, select: &evcal_host::views::select::SelectOptions) -> String {
    let (c, sel) = (&o.calibration, &o.selection);
    let mut s = format!("views: {} solved on, of {} with the whole grid", c.views.len(), sel.candidates);
    let mut left = Vec::new();
    if sel.near_duplicates > 0 {
        left.push(format!(
            "{} near-duplicates (moved < {:.1} px from a kept view)",
            sel.near_duplicates, select.min_change_px
        ));
    }
    if sel.thinned > 0 {
        left.push(format!("{} thinned to stay within {} views", sel.thinned, select.max_views));
    }
    if !c.rejected.is_empty() {
        left.push(format!("{} set aside by the solve, their error far above the others'", c.rejected.len()));
    }
    if !left.is_empty() {
        s += &format!("; left out: {}", left.join(", "));
    }
    s
}

/// The parameters with their σ, beside `truth` when known.
fn parameter_table(c: &evcal_host::calib::Calibration, truth: Option<&Intrinsics>) -> Result<()> {
    let est = c.intrinsics.to_array();
    match truth {
        Some(t) => {
            let t = t.to_array();
            outln!("  {:<4} {:>12} {:>10} {:>12} {:>12}", "", "estimate", "± 1σ", "truth", "error")?;
            for i in 0..9 {
                let err = est[i] - t[i];
                let rel = if i < 2 { format!(" ({:+.3} %)", 100.0 * err / t[i]) } else { String::new() };
                outln!(
                    "  {:<4} {:>12.5} {:>10.5} {:>12.5} {:>+12.5}{rel}",
                    PARAMETER_NAMES[i],
                    est[i],
                    c.std_dev[i],
                    t[i],
                    err
                )?;
            }
        }
        None => {
            outln!("  {:<4} {:>12} {:>10}", "", "estimate", "± 1σ")?;
            for i in 0..9 {
                outln!("  {:<4} {:>12.5} {:>10.5}", PARAMETER_NAMES[i], est[i], c.std_dev[i])?;
            }
        }
    }
    Ok(())
}

/// How the σ were computed (`-v`).
fn sigma_method(c: &evcal_host::calib::Calibration) -> Result<()> {
    let group_s = c.sigma_group_s.unwrap_or(evcal_host::calib::MIN_GROUP_SECONDS);
    match c.sigma_groups {
        Some(g) => outln!(
            "  σ: the larger of each point's own and the scatter of {g} stretches of {group_s:.2} s of the recording, widened ×{:.2} for so few (a longer recording narrows it)",
            evcal_host::calib::few_groups_factor(g)
        ),
        None => outln!(
            "  σ: each point's error taken as independent (views in fewer than {} stretches of {group_s:.2} s: too few to see how their errors are shared, so it may be too small; views all through at least {:.2} s of the recording give them)",
            evcal_host::calib::MIN_GROUPS,
            evcal_host::calib::MIN_GROUPS as f64 * evcal_host::calib::MIN_GROUP_SECONDS
        ),
    }
}

/// How the run got to its result (`-v`): views set aside, the centres' smoothing and lag,
/// the circles' outlines, the weights.
fn diagnostics(o: &Outcome, setup: &Setup) -> Result<()> {
    let c = &o.calibration;
    for r in &c.rejected {
        outln!(
            "  view {} (window {}) set aside: {}",
            r.view,
            o.used_origins.get(r.view).map_or(0, |v| v.window_seq),
            r.reason
        )?;
    }
    if let Some(s) = &o.smoothing {
        outln!(
            "centres smoothed along their paths: {} points re-estimated from the windows around them ({} of them replaced: off their path), {} kept as detected",
            s.smoothed,
            s.replaced,
            s.kept
        )?;
    }
    if let Some(s) = &o.edge_shift {
        outln!(
            "centres moved {:+.3} ± {:.3} px along their motion before the solve (edges seen late; measured on {} points)",
            s.px,
            s.std_px,
            s.points
        )?;
        if let Some(l) = &s.lean {
            outln!(
                "  and {:+.3} px across it on slanted outlines, in px of a shift at a fixed depth into the edge (the views ask for {:+.3} ± {:.3} px; events at a fixed depth lean by the shift, a pure delay by 0); counted in the σ below",
                l.used_px,
                l.px,
                l.std_px
            )?;
        }
        if let Some(l) = &s.bend {
            outln!(
                "  and {:+.3} px along it at {:.0} px/s, as the square of each one's speed: the lag's bend, as a slow pixel's delay shortens on faster edges (the views ask for {:+.3} ± {:.3} px; an ideal pixel's lag does not bend); counted in the σ below",
                l.used_px,
                evcal_host::views::edge_shift::BEND_SPEED_PX_S,
                l.px,
                l.std_px
            )?;
        }
        if let Some(b) = &s.by_thickness {
            let k = c.intrinsics;
            outln!(
                "  the same lag in proportion to each edge's thickness instead ({:+.3} px at the median): fx {:+.3} %, cx {:+.2} px, cy {:+.2} px; counted in the σ below",
                b.px,
                100.0 * b.change[0] / k.fx.abs(),
                b.change[2],
                b.change[3]
            )?;
        }
    }
    if let Some(r) = c.circle_radius_m {
        let how = if setup.circle_radius.is_some() { "as given" } else { "estimated from the fitted radii" };
        outln!(
            "circle outlines modelled: radius {:.2} mm ({how}); each centre compared with its outline's centre",
            r * 1e3
        )?;
    }
    if let (Some(first), Some(last)) = (c.precision_bins.first(), c.precision_bins.last()) {
        if (last.weight / first.weight - 1.0).abs() < 1e-9 {
            outln!("centres weighed alike: centres fitted to more events err no less in this recording")?;
        } else {
            let bins: Vec<String> =
                c.precision_bins.iter().map(|b| format!("{:.0}+ ×{:.2}", b.from, b.weight)).collect();
            outln!(
                "each centre weighed as precise as centres fitted to as many events are here (events: weight): {}",
                bins.join(", ")
            )?;
        }
    }
    Ok(())
}
