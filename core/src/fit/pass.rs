//! One pass over a fit's events: the residuals, their weights and the weighted normal
//! equations of the cylinder.

use super::{events::Events, frame::Frame, histogram::Histogram};
use crate::math::{exp_neg, inv_sqrt};

/// Weights below `exp(−18)` are taken as zero: such events change nothing, cost nothing, and
/// never produce denormals (which the M4F and the host would treat alike, but slowly).
pub(super) const MAX_WEIGHT_EXPONENT: f32 = 18.0;

/// The residual weights of one pass: a Gaussian of width `sigma`, or all ones.
#[derive(Clone, Copy)]
pub(super) struct Weights {
    pub(super) reweight: bool,
    pub(super) sigma: f32,
}

/// What one pass over the events at parameters `p` gives: the weighted normal equations
/// `JᵀWJ` (lower triangle) and `JᵀWξ`, and the weighted sums for the spread. The histogram
/// of |ξ| for the next kernel width goes to the caller's (returned inside `Pass` it was
/// copied on every pass).
pub(super) struct Pass {
    pub(super) a: [[f32; 5]; 5],
    pub(super) g: [f32; 5],
    pub(super) sw: f32,
    pub(super) swe2: f32,
    /// How many records of the events of nonzero weight [`weigh`] left in the scratch's tail,
    /// if it did.
    pub(super) records: Option<usize>,
    /// The kernel's `1/2σ²` of the pass.
    pub(super) scale: f32,
}

/// The weighted sums one pass accumulates (see [`pass_with`]), carried from one scratchful
/// of events to the next so that every sum adds its events in the same order.
#[derive(Clone, Copy, Default)]
struct Sums {
    sxx: f32,
    sxy: f32,
    syy: f32,
    sxxt: f32,
    sxyt: f32,
    syyt: f32,
    sxxtt: f32,
    sxytt: f32,
    syytt: f32,
    sx: f32,
    sy: f32,
    sxt: f32,
    syt: f32,
    sw: f32,
    gx: f32,
    gy: f32,
    gxt: f32,
    gyt: f32,
    g1: f32,
    swe2: f32,
}

impl Sums {
    /// Adds one event of weight `wi`, unit direction (`cx`, `cy`) from the centre, residual
    /// `xi` and time `t`. Inlined into each pass's loop, where the sums of a local copy stay
    /// in registers.
    #[inline(always)]
    fn add<const TILT: bool>(&mut self, wi: f32, cx: f32, cy: f32, xi: f32, t: f32) {
        let (wx, wy) = (wi * cx, wi * cy);
        let (wxx, wxy, wyy) = (wx * cx, wx * cy, wy * cy);
        self.sxx += wxx;
        self.sxy += wxy;
        self.syy += wyy;
        self.sx += wx;
        self.sy += wy;
        self.sw += wi;
        let (wxi, wxxi, wyxi) = (wi * xi, wx * xi, wy * xi);
        self.gx += wxxi;
        self.gy += wyxi;
        self.g1 += wxi;
        self.swe2 += wxi * xi;
        if TILT {
            self.sxxt += wxx * t;
            self.sxyt += wxy * t;
            self.syyt += wyy * t;
            let tt = t * t;
            self.sxxtt += wxx * tt;
            self.sxytt += wxy * tt;
            self.syytt += wyy * tt;
            self.sxt += wx * t;
            self.syt += wy * t;
            self.gxt += wxxi * t;
            self.gyt += wyxi * t;
        }
    }
}

pub(super) fn pass(ev: &mut Events, f: &Frame, p: &[f32; 5], w: &Weights, tilt: bool, hist: &mut Histogram) -> Pass {
    *hist = Histogram::new();
    hist.count = ev.n as u32;
    // exp(−ξ²/2σ²) with the division done once.
    let scale = 0.5 / (w.sigma * w.sigma);
    // Copies of the loop: a still circle needs neither the time columns nor their sums (and
    // most clusters are fitted still), and plain least squares no weights.
    let run = match (tilt, w.reweight) {
        (true, true) => pass_with::<true, true>,
        (true, false) => pass_with::<true, false>,
        (false, true) => pass_with::<false, true>,
        (false, false) => pass_with::<false, false>,
    };
    let mut s = Sums::default();
    let mut made = None;
    let (held, tail) = ev.scratch.split_at_mut(ev.n.min(ev.scratch.len()));
    let records = tail.as_flattened_mut();
    if ev.held && w.reweight && records.len() >= RECORD * ev.n {
        let kept = if tilt {
            weigh::<true>(held, p, scale, hist, records)
        } else {
            weigh::<false>(held, p, scale, hist, records)
        };
        made = Some(kept);
        let records = records.get(..kept * RECORD).unwrap_or(&[]);
        if tilt {
            sum_records::<true>(records, &mut s);
        } else {
            sum_records::<false>(records, &mut s);
        }
    } else if ev.held {
        run(held, p, scale, hist, &mut s);
    } else {
        let mut at = (0, 0);
        loop {
            let m = ev.convert(f, &mut at);
            if m == 0 {
                break;
            }
            run(ev.scratch.get(..m).unwrap_or(&[]), p, scale, hist, &mut s);
        }
    }
    // Signs: each entry is a product of two components of J, each carrying a minus sign.
    let a = [
        [s.sxx, 0.0, 0.0, 0.0, 0.0],
        [s.sxy, s.syy, 0.0, 0.0, 0.0],
        [s.sxxt, s.sxyt, s.sxxtt, 0.0, 0.0],
        [s.sxyt, s.syyt, s.sxytt, s.syytt, 0.0],
        [s.sx, s.sy, s.sxt, s.syt, s.sw],
    ];
    Pass { a, g: [-s.gx, -s.gy, -s.gxt, -s.gyt, -s.g1], sw: s.sw, swe2: s.swe2, records: made, scale }
}

/// One pass's sums over `events` (local `[x, y, τ]`), added to `s`.
// Kept out of line: inlined into the fit, the loop shares the M4F's registers with the code
// around it and spills its sums (a fifth more instructions per event), for one call saved
// per iteration.
#[inline(never)]
fn pass_with<const TILT: bool, const REWEIGHT: bool>(
    events: &[[f32; 3]],
    p: &[f32; 5],
    scale: f32,
    hist: &mut Histogram,
    s: &mut Sums,
) {
    let [u, v, va, vb, r] = *p;
    // J = −(cx, cy, cx·τ, cy·τ, 1) for the unit direction (cx, cy) from the centre: JᵀWJ is
    // made of the weighted sums of cx², cx·cy, cy² times 1, τ, τ², of cx, cy times 1, τ, and
    // of w; JᵀWξ of wξ times cx, cy, cx·τ, cy·τ, 1. A local copy keeps them all in registers.
    let mut acc = *s;
    for &[x, y, t] in events {
        let (dx, dy) = if TILT { (x - u - va * t, y - v - vb * t) } else { (x - u, y - v) };
        let q = dx * dx + dy * dy;
        // NaN compares false: `q > 0` and finite below.
        if q.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            hist.add(r.abs());
            continue; // on the axis: no direction, no information about the centre
        }
        let inv = inv_sqrt(q);
        let d = q * inv;
        let xi = d - r;
        hist.add(xi.abs());
        let wi = if REWEIGHT {
            let z = xi * xi * scale;
            if z > MAX_WEIGHT_EXPONENT {
                continue;
            }
            exp_neg(z)
        } else {
            1.0
        };
        let (cx, cy) = (dx * inv, dy * inv);
        acc.add::<TILT>(wi, cx, cy, xi, t);
    }
    *s = acc;
}

/// Floats of one event's record from [`weigh`] for [`sum_records`]: its weight, unit direction
/// from the centre, residual and time.
pub(super) const RECORD: usize = 5;

/// The first half of a reweighted pass over `events` (local `[x, y, τ]`): each event's
/// residual into `hist`, and for each event of nonzero weight its record
/// `[w, cx, cy, ξ, τ]` (τ of tilted fits only) packed into `records` while there is room;
/// returns how many.
// In one loop (`pass_with`), the 20 sums, the centre, the kernel and the exponential's
// constants outgrew the M4F's 32 float registers and spilled a dozen times an event; split,
// neither loop spills, for a record's five stores and loads, and the records serve the
// ellipse (see `ellipse_offset`). The sums are `pass_with`'s operations in its order.
#[inline(never)]
pub(super) fn weigh<const TILT: bool>(
    events: &[[f32; 3]],
    p: &[f32; 5],
    scale: f32,
    hist: &mut Histogram,
    records: &mut [f32],
) -> usize {
    let [u, v, va, vb, r] = *p;
    let mut out = records.chunks_exact_mut(RECORD);
    let mut kept = 0;
    for &[x, y, t] in events {
        let (dx, dy) = if TILT { (x - u - va * t, y - v - vb * t) } else { (x - u, y - v) };
        let q = dx * dx + dy * dy;
        // NaN compares false: `q > 0` and finite below.
        if q.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            hist.add(r.abs());
            continue; // on the axis: no direction, no information about the centre
        }
        let inv = inv_sqrt(q);
        let d = q * inv;
        let xi = d - r;
        hist.add(xi.abs());
        let z = xi * xi * scale;
        if z > MAX_WEIGHT_EXPONENT {
            continue;
        }
        if let Some([rw, rx, ry, rxi, rt]) = out.next() {
            *rw = exp_neg(z);
            *rx = dx * inv;
            *ry = dy * inv;
            *rxi = xi;
            if TILT {
                *rt = t;
            }
            kept += 1;
        }
    }
    kept
}

/// The second half of a reweighted pass: the sums of `pass_with` over [`weigh`]'s records,
/// added to `s`.
#[inline(never)]
fn sum_records<const TILT: bool>(records: &[f32], s: &mut Sums) {
    let mut acc = *s;
    for rec in records.chunks_exact(RECORD) {
        let &[wi, cx, cy, xi, t] = rec else { break };
        acc.add::<TILT>(wi, cx, cy, xi, t);
    }
    *s = acc;
}
