//! The slanted-cylinder fit: iteratively reweighted Gauss–Newton from the algebraic start
//! (eRWLS; plain least squares without the weights).

use super::{
    ellipse::{ellipse_offset, LastPass, ELLIPSE_MAX_SPREAD},
    events::Events,
    frame::{Frame, Local},
    histogram::Histogram,
    pass::{pass, Weights},
    FitConfig, FitMethod,
};
use crate::{
    math::{max, sqrt_approx},
    moments::{solve_spd, Circle},
};

/// Smallest σ of the weights, pixels. Events sit on a pixel grid whose rounding alone spreads
/// them uniformly by ±0.5 px; weights much narrower than that select events by rounding luck
/// and pull the centre towards wherever the rounding happened to agree with the current fit.
const MIN_SIGMA: f32 = 0.7;
/// Width of the weighting Gaussian in units of the inliers' own spread. Measured on the unit
/// tests' cylinders (2000 clean events; 300 with 15 % scattered noise and a clump of 40
/// beside the edge; their draws then from a xorshift generator, now from ChaCha8), RMS
/// centre error: at 1.0, 0.056 px clean (plain least squares 0.038); at 1.5, 0.045 clean
/// and 0.145 noisy (least squares 0.87); at 2.0, 0.041 and 0.161.
const KERNEL_WIDTH: f32 = 1.5;

/// A fit has converged when an accepted step moves the centre and radius (and the circle, by
/// its velocity, over the cluster's time span) less than this, px: a tenth of the centre
/// error a window's fit reaches (0.2 px). Measured (detection tests: DAVIS346 cone good
/// and low light, 4000 and 16000 events a window, DVXplorer spiral): 2e-2 leaves every found
/// rate and centre RMS as at 1e-2 to the third decimal; 3e-2 moves low light 0.316 -> 0.317
/// px and 16000-event windows 0.150 -> 0.151 px. Against 1e-2 it ends many fits of circles a
/// pass earlier, and the passes of circles' fits (tilted ones, mostly; clutter is a sixth)
/// are the bulk of the slowest windows' fitting (M4F: 1.62 -> 1.44 M instructions of fitting
/// a window on average, 2.24 -> 2.00 M at most). Before the ellipse step, with the tilt
/// fitted from 160 events, 5e-3 gave centre RMS 0.2045 px, 1e-2 0.2051, 2e-2 0.2063 on the
/// DAVIS346 cone.
const STEP_TOLERANCE: f32 = 2e-2;

/// Fewest events for the cylinder's tilt (the circle's velocity) to be fitted. A still fit
/// gives the centre at the cluster's own mean event time, and the circles of one window fire
/// at different times within it, so each still centre is off by its velocity times its
/// own lead or lag: small against the truth on average, but different from circle to
/// circle, which no pose explains. Measured both ways on simulated recordings (threshold
/// 48 → 160): centre RMS against the truth improves a little (DAVIS346 cone 0.2080 → 0.2051
/// px good light, 0.3060 → 0.3032 low light; DVXplorer spiral 0.2205 → 0.2171), but the
/// calibration's reprojection RMS on the continuous DVXplorer 3x9 spiral goes from 0.198 to
/// 0.227 px (its large, fast circles), with DAVIS346 unchanged to 0.001 px. The calibration
/// is what users get, so the tilt is fitted from 48 events; it costs the M4F about
/// half as much again per event in a tilted pass.
const TILT_MIN_EVENTS: usize = 48;
/// A step that moves the centre by more than this fraction of the radius is shortened to it:
/// Gauss–Newton from the algebraic start is well behaved, but a wild step on a degenerate
/// cluster must not throw the fit somewhere it cannot come back from.
const MAX_STEP_FRACTION: f32 = 0.25;
/// Largest weighted spread, px, of an eRWLS fit from its second pass on: beyond it the events
/// lie on no circle and the fit gives up. From the second pass the kernel follows the
/// residuals' median, so a circle's own events weigh in and clutter beside it weighs out,
/// and the spread is the edge's (some 0.3–0.6 px on simulated recordings, and fragments of
/// circles that join stay within 1.5 px, see `detect`). The clusters beyond it are clutter of
/// hundreds of events (simulated DAVIS346 cone: 300–1000 events, spread 3–9 px), which ran all
/// their iterations as tilted cylinders: a third of the window's passes over events. Centre
/// RMS and found rates of the simulated recordings are unchanged to the fourth decimal.
pub(crate) const MAX_SPREAD: f32 = 3.0;
/// Largest weighted spread, px, of an eRWLS fit's first pass (whose kernel comes from the
/// start's RMS, not yet from the residuals' median, see [`MAX_SPREAD`]). Clutter that starts
/// within [`MAX_START_RMS`] mostly ends between 1 and 3 px after all its iterations (a fifth
/// of a window's passes, tilted ones mostly); circles start within a pixel or so. On five
/// simulated recordings (DAVIS346 cone good and low light, square low light; DVXplorer
/// spiral; 345 windows, 20 000 fits) no fit that ended within 1 px had a first pass beyond
/// 2.5 px, and 1 in 70 of the fits (all of them ending beyond 1 px) are given up there.
const FIRST_MAX_SPREAD: f32 = 2.5;
/// Largest RMS distance, px, of a cluster's events from their algebraic circle (the fit's
/// start) for eRWLS to try: beyond it the cluster is clutter whose fit would end beyond
/// [`MAX_SPREAD`] anyway, after two passes over hundreds of events. Not robust, so wider than
/// [`MAX_SPREAD`]: a crescent with clutter attached starts a few pixels off and the weights
/// then find its circle. On the simulated recordings, 3 px lost a circle in a thousand; 4 and
/// 5 px none (centre RMS and found rates unchanged to the fourth decimal), and 5 px skips
/// three quarters of the tilted passes that remained in 4000-event windows.
pub(super) const MAX_START_RMS: f32 = 5.0;

/// The weights' σ for a median absolute residual (1.4826·MAD is σ for Gaussian inliers).
fn kernel(mad: f32) -> f32 {
    KERNEL_WIDTH * max(1.4826 * mad, MIN_SIGMA)
}

/// The slanted-cylinder fit: the algebraic start, then iteratively reweighted Gauss–Newton
/// (one pass over the events per iteration: weights from the residuals at the current
/// parameters, the weighted normal equations, one step). The kernel width follows the
/// residuals' median (one iteration behind, from the same pass). The tilt is fitted only for
/// clusters of at least [`TILT_MIN_EVENTS`]. `None` for events on no circle (see
/// [`MAX_SPREAD`]).
pub(super) fn cylinder(
    events: &mut Events,
    f: &Frame,
    start: &Circle,
    t_ref_ms: f32,
    cfg: &FitConfig,
    max_spread: f32,
) -> Option<Local> {
    let n = events.n;
    let tilt = n >= TILT_MIN_EVENTS && f.t_reach > 0.0;
    // The start's centre moved to the cluster's mean time, the origin of the local frame.
    let lead = f.tc - t_ref_ms;
    let (a, b) = if tilt { (start.vu, start.vv) } else { (0.0, 0.0) };
    let mut p = [start.u + start.vu * lead - f.x0, start.v + start.vv * lead - f.y0, a, b, start.r];
    let reweight = cfg.method == FitMethod::Erwls;
    // The start's RMS residual is not robust (clutter in the cluster inflates it), but it only
    // sets the first iteration's kernel: the histogram of that pass sets the next one.
    let mut w = Weights { reweight, sigma: KERNEL_WIDTH * max(start.rms, MIN_SIGMA) };
    let mut converged = false;
    let mut spread = f32::INFINITY;
    let mut it = 0usize;
    let mut hist = Histogram::new();
    let mut last = LastPass { p, scale: 0.0, records: None };
    while it < usize::from(cfg.max_iterations) {
        let ps = pass(events, f, &p, &w, tilt, &mut hist);
        last = LastPass { p, scale: ps.scale, records: ps.records };
        if ps.sw > 0.0 {
            spread = sqrt_approx(ps.swe2 / ps.sw);
        }
        let limit = if it == 0 { FIRST_MAX_SPREAD } else { max_spread };
        if reweight && spread > limit {
            return None;
        }
        // A small Marquardt damping, with a floor, keeps a velocity the window cannot observe
        // at zero rather than making the system singular.
        let mut a = ps.a;
        let floor = 1e-6 * max(a[4][4], 1.0);
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += 1e-4 * ps.a[i][i] + floor;
        }
        let rhs = ps.g.map(|x| -x);
        let step = if tilt {
            solve_spd::<5>(a, rhs)
        } else {
            // A still circle: the system of u, v, r alone, the same bits as the full one with
            // the tilt decoupled (unit diagonal, no coupling, zero gradient, zero step) but
            // without its two extra rows (two square roots among them).
            solve_spd::<3>(
                [[a[0][0], 0.0, 0.0], [a[1][0], a[1][1], 0.0], [a[4][0], a[4][1], a[4][4]]],
                [rhs[0], rhs[1], rhs[4]],
            )
            .map(|[du, dv, dr]| [du, dv, 0.0, 0.0, dr])
        };
        let Some(mut step) = step else { break };
        let moved = sqrt_approx(step[0] * step[0] + step[1] * step[1]);
        let limit = MAX_STEP_FRACTION * max(p[4].abs(), 1.0);
        if moved > limit || !moved.is_finite() {
            let shrink = if moved.is_finite() { limit / moved } else { 0.0 };
            step = step.map(|s| s * shrink);
        }
        for (q, s) in p.iter_mut().zip(step) {
            *q += s;
        }
        // The kernel follows the residuals' spread as the fit sheds its outliers.
        if reweight {
            w.sigma = kernel(hist.median());
        }
        let tilted = max(step[2].abs(), step[3].abs()) * f.t_reach;
        if max(max(moved, step[4].abs()), tilted) < STEP_TOLERANCE {
            converged = true;
            break;
        }
        it += 1;
    }
    // `spread` is finite only after a pass, which sets `last`.
    if reweight && spread <= ELLIPSE_MAX_SPREAD {
        if let Some([du, dv]) = ellipse_offset(events, f, &last, &p, 0.5 / (w.sigma * w.sigma), tilt) {
            p[0] = last.p[0] + du;
            p[1] = last.p[1] + dv;
        }
    }
    Some(Local { p, spread, converged })
}
