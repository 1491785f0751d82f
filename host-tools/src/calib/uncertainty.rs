//! The calibration's uncertainty in pixels (issue 44, item 1): how far, one standard
//! deviation, the pixel a distant point is seen at may lie from where the estimated camera
//! puts it, at each pixel of the sensor.
//!
//! mrcal's projection uncertainty, here with the camera frame held fixed: a pixel is
//! unprojected with the estimated intrinsics to a ray, and the parameters' covariance
//! ([`Calibration::covariance`]: grouped by stretches of the recording, widened for how few
//! groups there are and for what the lag's other model changes) is carried through
//! projecting that same ray, `Σ_q = J Σ_θ Jᵀ` with `J = ∂q/∂θ`. mrcal also lets the camera
//! frame turn with the views' poses (an error of cx is then largely a small turn of the
//! camera, which a user who only maps rays within one camera does not see). evcal does not:
//! the intrinsics' covariance is already the block with the poses profiled out, and what a
//! user of the calibration compares with the truth (undistorting a pixel with the estimate,
//! and the mapping error of issue 44's table) holds the ray fixed in the camera frame, where
//! a principal point off by a pixel is a pixel off everywhere. So this σ is the larger,
//! and it is the one such errors are to be read against.

use super::{model, Calibration, Intrinsics, Pose, View};
use nalgebra::{Rotation3, Vector3};

/// Grid step of [`ProjectionSigma::of`] in the exports, px: 44 × 33 nodes on a DAVIS346,
/// finer than the distortion varies (its terms are at most r⁶ over the sensor) and few
/// enough for `calibration.json` to stay readable.
pub const PROJECTION_SIGMA_STEP_PX: u32 = 8;

/// The share of the grid's nodes at or below the percentile [`ProjectionSigma`] gives
/// besides the worst: the worst alone is one corner's.
pub const SIGMA_PERCENTILE: f64 = 0.95;

/// Newton steps [`unproject`] takes at most: from the undistorted guess it converges in a
/// handful wherever the model is one-to-one.
const UNPROJECT_STEPS: usize = 50;

/// Points from the axis out to [`unproject`]'s ray where the model must be one-to-one: the
/// distortion's terms are at most r⁶, so its Jacobian changes sign at most a few times
/// along the way and 32 points see any fold wider than a thirtieth of the radius.
const FOLD_CHECKS: usize = 32;

/// How close [`unproject`]'s ray must project to its pixel, px.
const UNPROJECT_TOLERANCE_PX: f64 = 1e-7;

/// The normalised image point `(x/z, y/z)` whose projection through `k` is `pixel`: the ray
/// through that pixel. `None` where no ray projects there with the model one-to-one from the
/// axis out to it (beyond where the distortion polynomial folds back, as a large k3 makes it
/// do in a sensor's corner): there the model gives no camera to be uncertain about.
pub fn unproject(k: &Intrinsics, pixel: [f64; 2]) -> Option<[f64; 2]> {
    let origin = Pose { rotation: Rotation3::identity(), translation: Vector3::zeros() };
    // The projection, its miss (px) and its derivative by (x, y) (at depth 1 the derivative
    // by the translation).
    let at = |xy: [f64; 2]| {
        let p = model::project(k, &origin, &[xy[0], xy[1], 1.0])?;
        let r = [p.pixel[0] - pixel[0], p.pixel[1] - pixel[1]];
        let j = [[p.d_pose[0][3], p.d_pose[0][4]], [p.d_pose[1][3], p.d_pose[1][4]]];
        r.iter().chain(j.iter().flatten()).all(|x| x.is_finite()).then_some((r, r[0].hypot(r[1]), j))
    };
    let mut xy = [(pixel[0] - k.cx) / k.fx, (pixel[1] - k.cy) / k.fy];
    let (mut r, mut miss, mut j) = at(xy)?;
    for _ in 0..UNPROJECT_STEPS {
        let [[a, b], [c, d]] = j;
        let det = a * d - b * c;
        if miss < UNPROJECT_TOLERANCE_PX {
            // The ray counts where the model is one-to-one all the way out to it from the
            // axis: beyond a fold the polynomial brings far rays back, mirrored (k1 < 0
            // alone: past r² = 1/|k1|), to pixels a ray nearer the axis would be seen at.
            let unfolded = (1..=FOLD_CHECKS).all(|s| {
                let t = s as f64 / FOLD_CHECKS as f64;
                at([t * xy[0], t * xy[1]]).is_some_and(|(_, _, [[a, b], [c, d]])| a * d - b * c > 0.0)
            });
            return (det > 0.0 && unfolded).then_some(xy);
        }
        if det == 0.0 {
            return None;
        }
        let step = [(d * r[0] - b * r[1]) / det, (a * r[1] - c * r[0]) / det];
        // Newton's step, halved until it misses by less: a step across a fold of the model
        // would otherwise throw the ray far off.
        let mut scale = 1.0;
        loop {
            let next = [xy[0] - scale * step[0], xy[1] - scale * step[1]];
            match at(next) {
                Some(n) if n.1 < miss => {
                    xy = next;
                    (r, miss, j) = n;
                    break;
                }
                _ if scale > 1e-6 => scale *= 0.5,
                // No step misses by less: the pixel lies beyond a fold, where no ray is seen.
                _ => return None,
            }
        }
    }
    None
}

/// One standard deviation of the projection at `pixel` of a point far away, px, in the
/// direction it is largest (mrcal's "worst direction"): the square root of the largest
/// eigenvalue of `J Σ Jᵀ`, `J` the pixel's derivative by the nine parameters with the ray
/// through `pixel` held fixed, `Σ` their covariance in [`Calibration::covariance`]'s order.
/// Infinite where a parameter the pixel depends on has an unbounded σ, or where the ray
/// cannot be found ([`unproject`]).
pub fn projection_sigma_at(k: &Intrinsics, covariance: &[[f64; 9]; 9], pixel: [f64; 2]) -> f64 {
    let origin = Pose { rotation: Rotation3::identity(), translation: Vector3::zeros() };
    let Some(j) = unproject(k, pixel).and_then(|xy| model::project(k, &origin, &[xy[0], xy[1], 1.0])) else {
        return f64::INFINITY;
    };
    let j = j.d_intrinsics;
    let mut s = [[0.0; 2]; 2];
    for (i, row) in covariance.iter().enumerate() {
        if !row[i].is_finite() {
            if j[0][i] != 0.0 || j[1][i] != 0.0 {
                return f64::INFINITY;
            }
            continue;
        }
        for (l, &c) in row.iter().enumerate() {
            if l == i || covariance[l][l].is_finite() {
                for r in 0..2 {
                    for t in 0..2 {
                        s[r][t] += j[r][i] * c * j[t][l];
                    }
                }
            }
        }
    }
    let (mean, half) = (0.5 * (s[0][0] + s[1][1]), 0.5 * (s[0][0] - s[1][1]));
    (mean + half.hypot(s[0][1])).max(0.0).sqrt()
}

/// Where on the sensor the board lay in some view used: the union of the convex hulls of
/// each view's detected points. Within a board's outline the model is interpolated between
/// points a spacing apart; outside every outline it is extrapolated, and what the points
/// say of it is what the polynomial makes of them. A node near a point but outside every
/// board is a board's edge (no closer than its outer circles' centres), so the hulls are
/// what the points fixed, not a disc around each.
#[derive(Debug, Clone, Default)]
pub struct Covered {
    /// Each view's hull, counter-clockwise in pixel coordinates as drawn (y down).
    hulls: Vec<Vec<[f64; 2]>>,
}

impl Covered {
    /// The region the points of `views` cover (views of fewer than three points, or all on
    /// a line, cover nothing).
    pub fn of<'a>(views: impl IntoIterator<Item = &'a [[f64; 2]]>) -> Self {
        Self { hulls: views.into_iter().filter_map(convex_hull).collect() }
    }

    /// Whether `pixel` lies within (or on) some view's hull.
    pub fn contains(&self, pixel: [f64; 2]) -> bool {
        self.hulls.iter().any(|h| {
            h.iter()
                .zip(h.iter().cycle().skip(1))
                .all(|(a, b)| cross(*a, *b, pixel) >= -1e-9 * (1.0 + cross_scale(*a, *b)))
        })
    }
}

fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

fn cross_scale(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).abs() + (a[1] - b[1]).abs()
}

/// The convex hull of `points` (Andrew's monotone chain), turning with positive
/// [`cross`]; `None` for fewer than three points not on a line.
fn convex_hull(points: &[[f64; 2]]) -> Option<Vec<[f64; 2]>> {
    let mut p: Vec<[f64; 2]> = points.iter().copied().filter(|q| q[0].is_finite() && q[1].is_finite()).collect();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return None;
    }
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> =
            if pass == 0 { Box::new(p.iter()) } else { Box::new(p.iter().rev()) };
        for &q in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    (hull.len() >= 3).then_some(hull)
}

/// The worst and the [`SIGMA_PERCENTILE`] of a set of σ, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmaFigures {
    /// The largest σ (infinite where one is unbounded).
    pub worst_px: f64,
    /// The σ that [`SIGMA_PERCENTILE`] of them are at or below (the nearest rank).
    pub p95_px: f64,
}

impl SigmaFigures {
    /// The figures of `values`; `None` for none.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Self> {
        let mut v: Vec<f64> = values.into_iter().map(|x| if x.is_nan() { f64::INFINITY } else { x }).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let rank = ((SIGMA_PERCENTILE * v.len() as f64).ceil() as usize).clamp(1, v.len());
        Some(Self { worst_px: v[v.len() - 1], p95_px: v[rank - 1] })
    }
}

/// The projection σ over the sensor ([`projection_sigma_at`]) on a grid, with the region the
/// points covered ([`Covered`]) and the figures over both.
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectionSigma {
    /// Grid step, px: node (i, j) is pixel (i·step, j·step).
    pub step_px: u32,
    /// Nodes per row, i = 0 … columns − 1 (the last at most at the sensor's last pixel).
    pub columns: usize,
    /// Rows, j = 0 … rows − 1.
    pub rows: usize,
    /// σ at each node, px, row by row (`values[j][i]`); infinite where unbounded.
    pub values: Vec<Vec<f64>>,
    /// Whether each node lies where a board was seen (`covered[j][i]`).
    pub covered: Vec<Vec<bool>>,
    /// Worst and percentile over every node of the sensor.
    pub sensor: SigmaFigures,
    /// Worst and percentile over the covered nodes; `None` when no node is covered.
    pub within_points: Option<SigmaFigures>,
}

impl ProjectionSigma {
    /// The projection σ of `cal` on a grid of `step_px` over its sensor, the covered region
    /// made from the points of the views it used (`views`: those given to the solve, which
    /// [`ViewResult::view`](super::ViewResult::view) indexes). `None` for a step of 0 or an
    /// empty sensor.
    pub fn of(cal: &Calibration, views: &[View], step_px: u32) -> Option<Self> {
        let covered = Covered::of(cal.views.iter().filter_map(|v| views.get(v.view)).map(|v| &v.image[..]));
        Self::with(&cal.intrinsics, &cal.covariance, cal.image_size, &covered, step_px)
    }

    /// As [`of`](Self::of), from the parts: intrinsics, their covariance, the sensor's
    /// width and height, and the covered region.
    pub fn with(
        k: &Intrinsics,
        covariance: &[[f64; 9]; 9],
        image_size: [u32; 2],
        covered: &Covered,
        step_px: u32,
    ) -> Option<Self> {
        if step_px == 0 || image_size[0] == 0 || image_size[1] == 0 {
            return None;
        }
        let columns = ((image_size[0] - 1) / step_px + 1) as usize;
        let rows = ((image_size[1] - 1) / step_px + 1) as usize;
        let at = |i: usize, j: usize| [(i as u64 * u64::from(step_px)) as f64, (j as u64 * u64::from(step_px)) as f64];
        let values: Vec<Vec<f64>> =
            (0..rows).map(|j| (0..columns).map(|i| projection_sigma_at(k, covariance, at(i, j))).collect()).collect();
        let covered: Vec<Vec<bool>> =
            (0..rows).map(|j| (0..columns).map(|i| covered.contains(at(i, j))).collect()).collect();
        let sensor = SigmaFigures::of(values.iter().flatten().copied())?;
        let within_points = SigmaFigures::of(
            values.iter().flatten().zip(covered.iter().flatten()).filter(|(_, &c)| c).map(|(&v, _)| v),
        );
        Some(Self { step_px, columns, rows, values, covered, sensor, within_points })
    }

    /// One line for the console: the figures over the covered region, then over the sensor.
    pub fn summary(&self) -> String {
        let covered = match &self.within_points {
            Some(f) => format!("covered p95 {}, worst {}", px(f.p95_px), px(f.worst_px)),
            None => "no part of the sensor covered by a board".into(),
        };
        let nodes = self.values.iter().flatten();
        let unbounded = nodes.clone().filter(|v| !v.is_finite()).count();
        let folds = match unbounded {
            0 => String::new(),
            n => format!(
                "; no ray at {:.0} % of the sensor: the distortion folds back short of it",
                (100.0 * n as f64 / nodes.count() as f64).max(1.0)
            ),
        };
        format!(
            "projection σ (a distant point, 1σ): {covered}; whole sensor p95 {}, worst {} (extrapolated beyond the boards){folds}",
            px(self.sensor.p95_px),
            px(self.sensor.worst_px)
        )
    }
}

/// A σ in pixels for people, with its unit: two significant digits down to a thousandth.
fn px(x: f64) -> String {
    match x {
        x if !x.is_finite() => "unbounded".into(),
        x if x < 0.1 => format!("{x:.3} px"),
        x if x < 10.0 => format!("{x:.2} px"),
        x => format!("{x:.0} px"),
    }
}

#[cfg(test)]
#[path = "uncertainty_tests.rs"]
mod tests;
