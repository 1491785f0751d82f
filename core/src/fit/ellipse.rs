//! The ellipse step: the centre of the conic through a fit's weighted events, for the image
//! of a tilted circle.

use super::{
    events::Events,
    frame::Frame,
    histogram::Histogram,
    pass::{weigh, MAX_WEIGHT_EXPONENT, RECORD},
};
use crate::{
    math::{exp_neg, sqrt_approx},
    moments::solve_spd,
};

/// What the ellipse (see [`ellipse_offset`]) needs of a fit's last pass: its parameters,
/// kernel (`1/2σ²`) and records.
pub(super) struct LastPass {
    pub(super) p: [f32; 5],
    pub(super) scale: f32,
    pub(super) records: Option<usize>,
}

/// Largest weighted spread, px, of a fit that [`ellipse_offset`] refines. A circle's edge
/// leaves well under a pixel (simulated DAVIS346 cone: no fit beyond 0.88 px was a true
/// circle); the fits beyond are clutter, which ends anyhow between 1 and 3 px and is not
/// worth the M4F a pass over its events.
pub(super) const ELLIPSE_MAX_SPREAD: f32 = 1.25;
/// Largest move of the centre from the fitted circle's to the ellipse's, in radii: a tilted
/// circle's image of b/a = 0.7 (46° of tilt) moves it by a few hundredths of a radius, so a
/// larger move is the conic fitting noise or clutter.
const MAX_ELLIPSE_OFFSET: f32 = 0.15;
/// Smallest ratio of the ellipse's axes accepted (b/a, from the conic's eigenvalues as
/// their ratio's square): below it the conic is no tilted circle's image.
const MIN_ELLIPSE_AXIS_RATIO_SQ: f32 = 0.25;

/// Records [`ellipse_offset`] makes at a time when the last pass left none (a reweighted
/// fit held whole, with room for its records in the rest of the scratch, leaves them; see
/// [`pass`](super::pass::pass)).
const CONIC_CHUNK: usize = 16;

/// The offset, in the local frame, from the centre of the fit's last pass (`last.p`) to the
/// centre of the ellipse through the same events, weighed as the fit's final parameters `p`
/// and kernel (`scale`, `1/2σ²`) weigh them, or `None` when the conic is no plausible ellipse.
///
/// A tilted circle's image is an ellipse, and a circle fitted to an ellipse sits at the
/// ellipse's centre only when the events weigh opposite sides alike. They do not: a pixel
/// fires as often as the edge crosses it, and under perspective the nearer side of a tilted
/// circle moves faster across the sensor than the farther one. The offset lies along the
/// tilt, which is what fixes the focal length, and on simulated spiral recordings it read as
/// fx 0.08–0.13 % long. With the fit's weights and the cylinder's velocity taken out, the
/// conic `A x² + B xy + (1 − A) y² + D x + E y + F = 0` (in radii about the circle's centre;
/// the normalisation excludes no ellipse near a circle) is fitted by weighted algebraic least
/// squares, and its centre is the ellipse's.
///
/// The events come from the last pass's records (see [`weigh`]; a fit without them makes
/// the same ones again, a few at a time), which spares the conic the square root and
/// distance of a pass over the events of its own: it had been a sixth of the slowest
/// windows' fitting.
pub(super) fn ellipse_offset(
    ev: &mut Events,
    f: &Frame,
    last: &LastPass,
    p: &[f32; 5],
    scale: f32,
    tilt: bool,
) -> Option<[f32; 2]> {
    let r = last.p[4];
    if r.partial_cmp(&0.5) != Some(core::cmp::Ordering::Greater) {
        return None;
    }
    let at = &last.p;
    let moments = if tilt { conic_moments::<true> } else { conic_moments::<false> };
    let mut m = [0.0f32; 15];
    if let Some(kept) = last.records {
        let records = ev.scratch.get(ev.n..).unwrap_or(&[]).as_flattened();
        moments(records.get(..kept * RECORD).unwrap_or(&[]), last, p, scale, &mut m);
    } else {
        // The same records, a few at a time, in the same order: the same bits.
        let mut buf = [0.0f32; RECORD * CONIC_CHUNK];
        let mut hist = Histogram::new();
        let mut add = |events: &[[f32; 3]]| {
            for chunk in events.chunks(CONIC_CHUNK) {
                let kept = if tilt {
                    weigh::<true>(chunk, at, last.scale, &mut hist, &mut buf)
                } else {
                    weigh::<false>(chunk, at, last.scale, &mut hist, &mut buf)
                };
                moments(buf.get(..kept * RECORD).unwrap_or(&[]), last, p, scale, &mut m);
            }
        };
        if ev.held {
            add(ev.scratch.get(..ev.n).unwrap_or(&[]));
        } else {
            let mut at = (0, 0);
            loop {
                let k = ev.convert(f, &mut at);
                if k == 0 {
                    break;
                }
                add(ev.scratch.get(..k).unwrap_or(&[]));
            }
        }
    }
    let [s00, s10, s01, s20, s11, s02, s30, s21, s12, s03, s40, s31, s22, s13, s04] = m;
    // The normal equations' lower triangle, row by row, and right-hand side, for rows
    // Z = (x² − y², xy, x, y, 1) and the target −y².
    let s = [
        s40 - 2.0 * s22 + s04,
        s31 - s13,
        s22,
        s30 - s12,
        s21,
        s20,
        s21 - s03,
        s12,
        s11,
        s02,
        s20 - s02,
        s11,
        s10,
        s01,
        s00,
        s04 - s22,
        -s13,
        -s12,
        -s03,
        -s02,
    ];
    ellipse_centre(s, r)
}

/// The weighted moments `Σ w xⁱ yʲ`, `i + j ≤ 4`, added to `m`, of the events of [`weigh`]'s
/// records of the pass at `last.p` (positions in radii about its circle), weighed by their
/// residuals from the circle `p`, the step after that pass: `[S00, S10, S01, S20, S11, S02,
/// S30, S21, S12, S03, S40, S31, S22, S13, S04]`. Every sum of the conic's normal equations
/// is one of them or a difference of two or three: 14 products an event, where the 20 sums
/// took 24.
// The weights must be `p`'s: weighed at `last.p`, the conic is off by the step as much as the
// circle is (IRLS converges linearly; 0.0012 px more centre RMS on the DAVIS346 cone). A
// residual moves by the step along the event's direction (to first order: the step turns the
// direction by a few thousandths of a radian, 1e-4 px), and the weight by the change of its
// exponent, to second order while that change is under 0.25 (a converged step moves a
// residual by some 0.03 px against σ ≥ 1 px), else it is taken afresh. The positions may
// stay `last.p`'s: the conic's centre does not depend on the origin, and the velocity's step
// shears the events by under `STEP_TOLERANCE`. Without an exponential in the common case
// the loop keeps its 15 sums in registers, unlike `weigh`'s.
#[inline(never)]
fn conic_moments<const TILT: bool>(records: &[f32], last: &LastPass, p: &[f32; 5], scale: f32, m: &mut [f32; 15]) {
    let at = &last.p;
    let [du, dv, da, db, dr] = [p[0] - at[0], p[1] - at[1], p[2] - at[2], p[3] - at[3], p[4] - at[4]];
    let (r0, scale0) = (at[4], last.scale);
    let inv_r0 = 1.0 / r0;
    let [mut s00, mut s10, mut s01, mut s20, mut s11, mut s02, mut s30, mut s21, mut s12, mut s03, mut s40, mut s31, mut s22, mut s13, mut s04] =
        *m;
    for rec in records.chunks_exact(RECORD) {
        let &[w, cx, cy, xi, t] = rec else { break };
        let (ox, oy) = if TILT { (du + da * t, dv + db * t) } else { (du, dv) };
        let step = -(cx * ox + cy * oy) - dr;
        let xi1 = xi + step;
        let dz = scale * xi1 * xi1 - scale0 * xi * xi;
        let w = if dz.abs() <= 0.25 {
            w * (1.0 - dz * (1.0 - 0.5 * dz))
        } else {
            let z = xi1 * xi1 * scale;
            // One comparison: a NaN is unordered and weighs nothing too.
            if z.partial_cmp(&MAX_WEIGHT_EXPONENT).is_none_or(|o| o.is_gt()) {
                0.0
            } else {
                exp_neg(z)
            }
        };
        let k = (xi + r0) * inv_r0;
        let (wi, x, y) = (w, cx * k, cy * k);
        let (wx, wy) = (wi * x, wi * y);
        let (wxx, wxy, wyy) = (wx * x, wx * y, wy * y);
        let (wxxx, wxxy, wxyy, wyyy) = (wxx * x, wxx * y, wxy * y, wyy * y);
        s00 += wi;
        s10 += wx;
        s01 += wy;
        s20 += wxx;
        s11 += wxy;
        s02 += wyy;
        s30 += wxxx;
        s21 += wxxy;
        s12 += wxyy;
        s03 += wyyy;
        s40 += wxxx * x;
        s31 += wxxx * y;
        s22 += wxxy * y;
        s13 += wxyy * y;
        s04 += wyyy * y;
    }
    *m = [s00, s10, s01, s20, s11, s02, s30, s21, s12, s03, s40, s31, s22, s13, s04];
}

/// The centre, in the local frame about the fitted circle's, of the conic whose normal
/// equations (see [`ellipse_offset`]) are `s`, for a circle of radius `r`; `None` for no
/// plausible ellipse.
fn ellipse_centre(s: [f32; 20], r: f32) -> Option<[f32; 2]> {
    let [m00, m10, m11, m20, m21, m22, m30, m31, m32, m33, m40, m41, m42, m43, m44, b0, b1, b2, b3, b4] = s;
    let m = [
        [m00, 0.0, 0.0, 0.0, 0.0],
        [m10, m11, 0.0, 0.0, 0.0],
        [m20, m21, m22, 0.0, 0.0],
        [m30, m31, m32, m33, 0.0],
        [m40, m41, m42, m43, m44],
    ];
    let b = [b0, b1, b2, b3, b4];
    let [a, bxy, d, e, _] = solve_spd::<5>(m, b)?;
    let c = 1.0 - a;
    // Eigenvalues of the quadratic part [[a, b/2], [b/2, c]]: both positive for an ellipse.
    let det = 4.0 * a * c - bxy * bxy;
    let half_gap = 0.5 * sqrt_approx((a - c) * (a - c) + bxy * bxy);
    let (lo, hi) = (0.5 * (a + c) - half_gap, 0.5 * (a + c) + half_gap);
    if !(det > 0.0 && lo > MIN_ELLIPSE_AXIS_RATIO_SQ * hi) {
        return None;
    }
    let x0 = (bxy * e - 2.0 * c * d) / det;
    let y0 = (bxy * d - 2.0 * a * e) / det;
    let off = x0 * x0 + y0 * y0;
    (off <= MAX_ELLIPSE_OFFSET * MAX_ELLIPSE_OFFSET).then_some([x0 * r, y0 * r])
}
