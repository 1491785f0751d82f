//! The fit's local frame: the integer extent of a fit's events, and the coordinates about its
//! centre and mean time that the passes work in.

use super::Centre;
use crate::{extent::Extent, math::max, window::WindowEvent};

/// Local coordinates: pixels relative to the cluster's bounding-box centre and time in
/// milliseconds relative to the cluster's mean time, so that f32 keeps full precision and
/// the centre is uncorrelated with the velocity while fitting.
pub(super) struct Frame {
    pub(super) x0: f32,
    pub(super) y0: f32,
    /// Mean event time, ms since `t_ref`.
    pub(super) tc: f32,
    pub(super) half_w: f32,
    pub(super) half_h: f32,
    /// Largest |τ| of the cluster's events, ms: converts velocity steps into pixels.
    pub(super) t_reach: f32,
}

/// A fit in the local frame: centre at the mean time, velocity, radius, spread.
#[derive(Clone, Copy)]
pub(super) struct Local {
    pub(super) p: [f32; 5],
    pub(super) spread: f32,
    pub(super) converged: bool,
}

impl Frame {
    pub(super) fn of(parts: &[&[WindowEvent]]) -> Self {
        let mut x = Extent::EMPTY;
        for part in parts {
            x.add_all(part);
        }
        Self::from_extent(&x)
    }

    /// The frame of events whose [`Extent`] is `x`: the same bits as [`of`](Self::of) those
    /// events, since an extent is made of integers whatever the order they were taken in.
    pub(super) fn from_extent(x: &Extent) -> Self {
        let Extent { x_lo, x_hi, y_lo, y_hi, t_lo, t_hi, t_sum, count } = *x;
        let t_mean_us = t_sum / u64::from(count.max(1));
        let tc = t_mean_us as f32 * 1e-3;
        Self {
            // Halves of integers: exact in f32.
            x0: (f32::from(x_lo) + f32::from(x_hi)) * 0.5,
            y0: (f32::from(y_lo) + f32::from(y_hi)) * 0.5,
            tc,
            t_reach: max(tc - t_lo as f32 * 1e-3, t_hi as f32 * 1e-3 - tc),
            half_w: (f32::from(x_hi) - f32::from(x_lo)) * 0.5,
            half_h: (f32::from(y_hi) - f32::from(y_lo)) * 0.5,
        }
    }

    #[inline]
    pub(super) fn local(&self, e: &WindowEvent) -> (f32, f32, f32) {
        (f32::from(e.x) - self.x0, f32::from(e.y) - self.y0, e.dt_us as f32 * 1e-3 - self.tc)
    }

    /// Back to sensor pixels at `t_ref`, after the checks that keep arcs of straight edges
    /// and runaway fits out.
    pub(super) fn accept(&self, l: Local, n: u16, t_ref_ms: f32) -> Option<Centre> {
        let [u, v, a, b, r] = l.p;
        let u_ref = self.x0 + u + a * (t_ref_ms - self.tc);
        let v_ref = self.y0 + v + b * (t_ref_ms - self.tc);
        let finite = [u_ref, v_ref, a, b, r, l.spread].iter().all(|q| q.is_finite());
        // A circle larger than the cluster's whole extent is a fit to a nearly straight
        // edge; a centre beyond one radius outside the box belongs to no circle of these events.
        let extent = 2.0 * max(self.half_w, self.half_h) + 1.0;
        let plausible = r > 0.5 && r <= extent && u.abs() <= self.half_w + r && v.abs() <= self.half_h + r;
        (finite && plausible).then_some(Centre {
            u: u_ref,
            v: v_ref,
            r,
            vu: a,
            vv: b,
            spread: l.spread,
            n,
            converged: l.converged,
        })
    }
}
