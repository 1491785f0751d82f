//! The filled disc: the outline of a dark circle whose inside keeps firing.
//!
//! In dim light a dark pixel's photoreceptor settles slowly (its cutoff falls with the
//! light), so the pixels a dark circle has covered go on firing OFF events long after its
//! leading edge passed: the circle leaves a disc filled with events, with the prompt ON
//! crescent of its trailing edge on one side, not a ring. The cylinder's kernel, centred on
//! a ring, then sees events everywhere inside and its fit ends beyond its spread limit.
//! What is still a circle is the disc's outline: the leading edge's first events and the
//! trailing edge's crescent. This fit finds it with a one-sided kernel: events more than one
//! kernel width inside the circle are the disc's fill and weigh nothing; the rest weigh as
//! in eRWLS. The crescent is denser than the fill's edge and outweighs it: on simulated
//! discs the centre comes out up to a pixel towards the crescent, along the motion, and
//! alike for every disc of a window (within 0.2 px; see the tests), which is the distance
//! the host's edge shift measures and takes out. The DVXplorer in dim light at a 300 Hz
//! photoreceptor, whose grid was found in no window without it, calibrates with it; a dim
//! room's noise makes discs of its own, so it is asked for, not on by default
//! ([`FitConfig::filled_discs`](super::FitConfig::filled_discs); docs/accuracy.md).
//!
//! Only clusters the cylinder gave up on are tried, and only those whose extent is round
//! (the fill makes it so; clutter, mostly edges and lines, is not), so a window of rings is
//! fitted exactly as before. The circle is still (no velocity): its events span a few
//! milliseconds of a window, and the host follows each circle's motion across windows.

use super::{
    frame::{Frame, Local},
    pass::MAX_WEIGHT_EXPONENT,
};
use crate::{
    math::{exp_neg, max, sqrt_approx},
    moments::solve_spd,
    window::WindowEvent,
};

/// Largest ratio of a cluster's longer extent to its shorter one for a disc: a disc with its
/// crescent is about as wide as it is high (a crescent adds a fraction of the radius); an
/// edge or a line of clutter is far longer than it is wide.
const MAX_ASPECT: f32 = 1.5;
/// Fewest pixels of radius: below it a filled disc is a blob of a few pixels, whose
/// outline no kernel can find.
const MIN_RADIUS: f32 = 3.0;
/// Smallest kernel σ, px (the pixel grid's rounding; see the cylinder's `MIN_SIGMA`).
const MIN_SIGMA: f32 = 0.7;
/// The kernel's width in units of the outline events' spread (as the cylinder's).
const KERNEL_WIDTH: f32 = 1.5;
/// Iterations of the reweighted fit: it starts from the events' centroid, farther from the
/// answer than the cylinder's algebraic start.
const ITERATIONS: usize = 32;
/// A step that moves the circle less than this, px, ends the fit (as the cylinder's).
const STEP_TOLERANCE: f32 = 2e-2;
/// From this iteration on, a fit whose spread is beyond [`GIVE_UP_SPREAD`] ends: its kernel
/// has narrowed onto the outline by then (it shrinks by about a quarter an iteration), and
/// one that has not found a sharp outline will not.
const GIVE_UP_AFTER: usize = 6;
/// See [`GIVE_UP_AFTER`]: twice [`MAX_SPREAD`].
const GIVE_UP_SPREAD: f32 = 2.0 * MAX_SPREAD;
/// Largest weighted spread of the outline's events, px: beyond it there is no sharp outline
/// (clutter, or a disc smeared past recognition).
const MAX_SPREAD: f32 = 1.25;
/// Smallest share of the events inside the fitted outline (the fill): below it the cluster
/// is no filled disc, and the cylinder's verdict on it stands.
const MIN_FILL: f32 = 0.25;
/// Largest change of the radius from the start's, as a fraction of it: the start of a
/// uniform disc is its radius; a fit that runs far from it found some other curve.
const MAX_RADIUS_CHANGE: f32 = 0.4;

/// The disc's outline fitted to the `n` events of `parts` in frame `f`, or `None` when the
/// events are no filled disc with a sharp outline.
pub(super) fn disc(parts: &[&[WindowEvent]], n: usize, f: &Frame) -> Option<Local> {
    let (w, h) = (f.half_w + 0.5, f.half_h + 0.5);
    if max(w, h) > MAX_ASPECT * if w < h { w } else { h } {
        return None;
    }
    let events = || parts.iter().flat_map(|p| p.iter());
    // Start: the centroid, and the radius of a uniform disc of the events' second moment.
    if n == 0 {
        return None;
    }
    let n = n as f32;
    let (mut sx, mut sy) = (0.0f32, 0.0f32);
    for e in events() {
        let (x, y, _) = f.local(e);
        sx += x;
        sy += y;
    }
    let (u0, v0) = (sx / n, sy / n);
    let mut s2 = 0.0f32;
    for e in events() {
        let (x, y, _) = f.local(e);
        let q = (x - u0) * (x - u0) + (y - v0) * (y - v0);
        s2 += q;
    }
    let r0 = sqrt_approx(2.0 * s2 / n);
    if r0.is_nan() || r0 < MIN_RADIUS {
        return None;
    }
    let mut p = [u0, v0, r0];
    let mut sigma = KERNEL_WIDTH * max(0.25 * r0, MIN_SIGMA);
    let mut converged = false;
    let (mut spread, mut inside) = (f32::INFINITY, 0.0f32);
    for it in 0..ITERATIONS {
        let scale = 0.5 / (sigma * sigma);
        let mut a = [[0.0f32; 3]; 3];
        let mut g = [0.0f32; 3];
        let (mut sw, mut swe2) = (0.0f32, 0.0f32);
        inside = 0.0;
        for e in events() {
            let (x, y, _) = f.local(e);
            let (dx, dy) = (x - p[0], y - p[1]);
            let q = dx * dx + dy * dy;
            if q.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
                inside += 1.0;
                continue;
            }
            let d = sqrt_approx(q);
            let xi = d - p[2];
            if xi < -sigma {
                inside += 1.0;
                continue;
            }
            let z = xi * xi * scale;
            if z > MAX_WEIGHT_EXPONENT {
                continue;
            }
            let wi = exp_neg(z);
            let (cx, cy) = (dx / d, dy / d);
            // J = −(cx, cy, 1); the lower triangle of JᵀWJ and JᵀWξ.
            a[0][0] += wi * cx * cx;
            a[1][0] += wi * cx * cy;
            a[1][1] += wi * cy * cy;
            a[2][0] += wi * cx;
            a[2][1] += wi * cy;
            a[2][2] += wi;
            g[0] += wi * cx * xi;
            g[1] += wi * cy * xi;
            g[2] += wi * xi;
            sw += wi;
            swe2 += wi * xi * xi;
        }
        if sw.is_nan() || sw <= 0.0 {
            return None;
        }
        spread = sqrt_approx(swe2 / sw);
        if it >= GIVE_UP_AFTER && spread > GIVE_UP_SPREAD {
            return None;
        }
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += 1e-4 * row[i] + 1e-6;
        }
        let step = solve_spd::<3>(a, g)?;
        let moved = sqrt_approx(step[0] * step[0] + step[1] * step[1]);
        let limit = 0.25 * p[2];
        let shrink = if moved > limit { limit / moved } else { 1.0 };
        for (q, s) in p.iter_mut().zip(step) {
            *q += s * shrink;
        }
        sigma = KERNEL_WIDTH * max(spread, MIN_SIGMA);
        if !p.iter().all(|q| q.is_finite()) {
            return None;
        }
        if max(moved, step[2].abs()) < STEP_TOLERANCE {
            converged = true;
            break;
        }
    }
    let fill = inside >= MIN_FILL * n;
    let near_start = (p[2] - r0).abs() <= MAX_RADIUS_CHANGE * r0;
    (converged && fill && near_start && spread <= MAX_SPREAD && all_round(parts, f, &p, sigma)).then_some(Local {
        p: [p[0], p[1], 0.0, 0.0, p[2]],
        spread,
        converged,
    })
}

/// Sectors of the outline checked by [`all_round`].
const SECTORS: usize = 8;
/// Fewest outline events in each sector, as a fraction of the sectors' mean: no sector
/// nearly empty. A filled disc's outline is uneven (its crescent is dense, its fill's edge
/// is not), and on the simulated DVXplorer in dim light a quarter of the mean lost half of
/// its discs; an outline with a gap is what sets clutter apart.
const MIN_SECTOR_SHARE: f32 = 0.03;

/// Whether the events within one kernel width `sigma` of the circle `p` (centre, radius)
/// go all round it: each of [`SECTORS`] sectors holds at least [`MIN_SECTOR_SHARE`] of the
/// mean. A filled disc's outline does (its fill's edge on one side, its crescent on the
/// other); clutter that happens to be a round blob of events mostly does not. In good light
/// the disc is tried on nothing but clutter: on 90 windows of a simulated DAVIS346 cone
/// (3 s, seed 5) it added 104 centres, none on a circle, before this check and 16 with it.
fn all_round(parts: &[&[WindowEvent]], f: &Frame, p: &[f32; 3], sigma: f32) -> bool {
    let mut counts = [0u32; SECTORS];
    for e in parts.iter().flat_map(|p| p.iter()) {
        let (x, y, _) = f.local(e);
        let (dx, dy) = (x - p[0], y - p[1]);
        let d = sqrt_approx(dx * dx + dy * dy);
        if (d - p[2]).abs() > sigma {
            continue;
        }
        // The sector from the signs and the larger component: no arctangent.
        let octant = match (dx >= 0.0, dy >= 0.0, dx.abs() >= dy.abs()) {
            (true, true, true) => 0,
            (true, true, false) => 1,
            (false, true, false) => 2,
            (false, true, true) => 3,
            (false, false, true) => 4,
            (false, false, false) => 5,
            (true, false, false) => 6,
            (true, false, true) => 7,
        };
        counts[octant] += 1;
    }
    let total: u32 = counts.iter().sum();
    let least = MIN_SECTOR_SHARE * total as f32 / SECTORS as f32;
    total > 0 && counts.iter().all(|&c| c as f32 >= least)
}
