//! Recruiting: the events DBSCAN left as noise that lie on a fitted circle join its fit.

use super::*;

/// How far from a fitted circle, px, an event DBSCAN left out may be and still be taken as
/// the circle's: some three times the edge's own spread.
const RECRUIT_GATE: f32 = 2.0;
/// Rounds of recruiting: a circle fitted to one crescent can be a pixel or two off, and the
/// events of the other side reach it only once a first round has brought it closer.
const RECRUIT_ROUNDS: usize = 2;

/// Gives every fitted circle the events DBSCAN left as noise that lie on it, and fits it
/// again with them. Where a circle's edge barely moves, it fires sparsely: DBSCAN finds the
/// dense crescent and calls the rest noise, and a fit to that one crescent misplaces the
/// centre along the crescent's axis. Events within [`RECRUIT_GATE`] of the circle (moving
/// with its velocity) join the fit when there are at least a tenth as many as it has; the
/// fit starts from the circle found so far. The noise events are sorted by pixel once, so
/// each circle searches only the rows it spans; at most [`MAX_RECRUITS`] events per circle.
pub(super) fn recruit<const C: usize>(
    events: &mut [WindowEvent],
    ranges: &heapless::Vec<ClusterRange, C>,
    extents: &heapless::Vec<Extent, C>,
    fits: &mut heapless::Vec<Option<Centre>, C>,
    t_ref: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
) {
    let clustered = ranges.iter().map(|r| usize::from(r.end)).max().unwrap_or(0);
    let Some(noise) = events.get_mut(clustered..) else { return };
    sort_by_pixel(noise);
    let (events, noise) = events.split_at(clustered);
    let t_ref_ms = t_ref as f32 * 1e-3;
    // The largest |τ| of any noise event, ms: how long a circle moves for any of them.
    let t_last_ms = noise.iter().fold(0, |m, e| m.max(e.dt_us)) as f32 * 1e-3;
    let t_far = t_ref_ms.max(t_last_ms - t_ref_ms);
    let mut found = [WindowEvent::default(); MAX_RECRUITS];
    for (k, (r, f)) in ranges.iter().zip(fits.iter_mut()).enumerate() {
        if f.is_none() {
            continue;
        }
        let part = slice(events, r);
        let (t_lo, t_hi) = match extents.get(k) {
            Some(x) => (x.t_lo, x.t_hi),
            None => part.iter().fold((u32::MAX, 0), |(lo, hi), e| (lo.min(e.dt_us), hi.max(e.dt_us))),
        };
        // A round that takes no events, or whose fit fails, leaves the circle as it was: the
        // next round would search the same rows for the same events, so none follows.
        for _round in 0..RECRUIT_ROUNDS {
            let Some(c) = *f else { break };
            // The rows the circle sweeps over the window, with the gate.
            let reach = c.r + RECRUIT_GATE + c.vv.abs() * (t_hi.saturating_sub(t_lo) as f32 * 1e-3) + 1.0;
            let (y_lo, y_hi) = ((c.v - reach).max(0.0) as u16, (c.v + reach).min(65535.0) as u16);
            let lo = noise.partition_point(|e| e.y < y_lo);
            let hi = noise.partition_point(|e| e.y <= y_hi);
            // The columns of the same band: an event beyond them is further from the circle
            // than the gate at any time of the window (the pixel of margin covers the
            // approximate square root below), so it is passed over without one.
            let reach_x = c.r + RECRUIT_GATE + c.vu.abs() * t_far + 1.0;
            let (x_lo, x_hi) = ((c.u - reach_x).max(0.0) as u16, (c.u + reach_x).min(65535.0) as u16);
            let mut k = 0;
            for e in &noise[lo..hi] {
                if e.x < x_lo || e.x > x_hi {
                    continue;
                }
                let t = e.dt_us as f32 * 1e-3 - t_ref_ms;
                let (dx, dy) = (f32::from(e.x) - c.u - c.vu * t, f32::from(e.y) - c.v - c.vv * t);
                if (sqrt_approx(dx * dx + dy * dy) - c.r).abs() <= RECRUIT_GATE && k < MAX_RECRUITS {
                    found[k] = *e;
                    k += 1;
                }
            }
            if k == 0 || k * 10 < part.len() {
                break;
            }
            let start = Circle { u: c.u, v: c.v, vu: c.vu, vv: c.vv, r: c.r, rms: c.spread };
            match fit_with(&[part, &found[..k]], Some(start), t_ref, cfg, scratch) {
                Some(better) => *f = Some(better),
                None => break,
            }
        }
    }
}
