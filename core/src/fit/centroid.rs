//! The centroid estimator, the baseline of the ablation.

use super::frame::{Frame, Local};
use crate::{math::sqrt_approx, window::WindowEvent};

pub(super) fn centroid(parts: &[&[WindowEvent]], f: &Frame) -> Option<Local> {
    let events = || parts.iter().flat_map(|p| p.iter());
    let inv_n = 1.0 / events().count().max(1) as f32;
    let (mut sx, mut sy) = (0.0f32, 0.0f32);
    for e in events() {
        let (x, y, _) = f.local(e);
        sx += x;
        sy += y;
    }
    let (u, v) = (sx * inv_n, sy * inv_n);
    let (mut sd, mut sd2) = (0.0f32, 0.0f32);
    for e in events() {
        let (x, y, _) = f.local(e);
        let d = sqrt_approx((x - u) * (x - u) + (y - v) * (y - v));
        sd += d;
        sd2 += d * d;
    }
    let r = sd * inv_n;
    let spread = sqrt_approx((sd2 * inv_n - r * r).max(0.0));
    // The centroid has no time model: it is the centre of the events' mean time, and `tc`
    // is undone in `accept` with zero velocity.
    Some(Local { p: [u, v, 0.0, 0.0, r], spread, converged: true })
}
