//! Edges seen late: the shift of event-based circle centres along their motion, measured
//! and taken out before the final solve.
//!
//! A DVS pixel fires when its log intensity has moved a threshold away from the level of its
//! last event, and that level is where its previous change ended. A pixel an edge arrives at
//! has last changed the other way (the previous edge left it), so its first event needs
//! more than one threshold of change and every later one follows from there: the events of
//! an edge sit on the far side of its blurred profile. For a dark circle, the leading arc's
//! OFF events lie inside the true outline and the trailing arc's ON events outside it: the
//! fitted circle sits behind the true one by a distance `δ` along its motion, set by the
//! edge's blur and the thresholds, not by the speed. (A delay that grows with speed, such as
//! a slow photoreceptor's, is harmless: it shows the whole board a little earlier, a pose
//! like any other. A constant distance is not: when the board comes nearer, every circle
//! moves outward and is seen `δ` short, the board looks smaller, and the focal length comes
//! out long.) In the simulator, `δ` is 0.12 px in good light, and the cone motion turned it
//! into fx +0.1 to +0.25 %.
//!
//! `δ` cannot be seen in one window: a shifted circle and a displaced one leave the same
//! arcs. It can across views, where the circles move in different directions: each point's
//! direction of motion comes from where the same board point was in the neighbouring
//! windows, and [`estimate`] finds the `δ` that lets one camera explain all views best. The
//! final solve then runs on centres moved forward by `δ`.
//!
//! "Forward" is the motion's direction only for a circle. A circle seen at a slant images
//! as an ellipse, and where its axes are not the motion's the events on either side of the
//! motion are not alike: events a fixed depth into the edge (along the outline's normals)
//! move the core's ellipse fit across the motion as well, in proportion to the outline's
//! slant, ε·sin 2(θ − φ) (ε = (a − b)/(a + b), φ the major axis, θ the motion). A lag in
//! proportion to the speed moves the whole outline alike and nothing across. A slow
//! pixel's events lie between and beyond the two, so the move across, the *lean*, is
//! measured in its own right: in px of a shift at a fixed depth ([`across_outlines`] gives
//! its directions), which the solve estimates from the views (`calib::Calibration::moves`).
//! Events at a fixed depth lean by the shift itself, a pure delay by nothing.
//!
//! Nor is a slow pixel's lag quite in proportion to the speed. A pixel settles in a time set
//! by its own bandwidth where an edge sweeps past faster than that, and by the edge's sweep
//! where it is slower, so the lag in px bends between two slopes as the speed grows (the
//! simulator's dim cone at 300 Hz: 0.83, 1.52 and 1.85 px behind at 25, 75 and 125 px/s).
//! Its constant part is `δ`; its part in proportion to the speed is a delay each view's pose
//! takes up; the bend is what neither does. Taken as a term in the square of each point's
//! speed ([`directions_and_bends`]), it is one more move the solve estimates from the views, as
//! the lean is, in px at [`BEND_SPEED_PX_S`]. An ideal pixel's lag does not bend.

use crate::calib::{self, board_key, Intrinsics, Pose, View};
use crate::views::ViewOrigin;
use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// Neighbouring windows further apart than this do not give a direction of motion: a hand
/// turns within a few tenths of a second.
pub const MAX_NEIGHBOUR_GAP_S: f64 = 0.1;
/// Below this displacement between neighbouring windows, px, the direction is uncertain and
/// the correction is scaled down in proportion.
pub const FULL_DIRECTION_PX: f64 = 1.0;
/// Largest shift searched for, px. A blurred edge's profile is a few pixels wide; a shift
/// beyond half a pixel would be something else.
pub const MAX_SHIFT_PX: f64 = 0.5;
/// The shift is estimated only from at least this many points with a direction.
pub const MIN_POINTS_WITH_DIRECTION: usize = 200;
/// The image speed at which the lag's bend is given, px/s: a hand-held board's circles
/// move at tens to a few hundred px/s on the sensor. Only the unit of the figure printed;
/// the bend is estimated as what it is at any speed.
pub const BEND_SPEED_PX_S: f64 = 100.0;

/// The measured shift of the centres along their motion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EdgeShift {
    /// How far the centres were behind the circles along their motion, px (negative: ahead).
    pub px: f64,
    /// One standard deviation of `px`.
    pub std_px: f64,
    /// Points with a direction of motion, over the views used.
    pub points: usize,
    /// The other model of the same lag, and what choosing it would change.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub by_thickness: Option<ByThickness>,
    /// How far the centres were also moved across their motion on slanted outlines.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lean: Option<Lean>,
    /// How far the centres were also moved along their motion by the lag's bend in the
    /// speed: px at [`BEND_SPEED_PX_S`], in proportion to the square of each one's speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bend: Option<Lean>,
}

/// A further move of the centres that the views measure (see the module's note): the
/// edge shift's lean across the motion on slanted outlines, in px of a shift at a fixed
/// depth into the edge, or the lag's bend, in px at [`BEND_SPEED_PX_S`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lean {
    /// The move the views ask for, px.
    pub px: f64,
    /// One standard deviation of it, px.
    pub std_px: f64,
    /// The move the centres were moved by, px: `px` shrunk towards 0 ([`shrunk`]), so that
    /// a move the views leave loose moves them little.
    pub used_px: f64,
}

/// `estimate` shrunk towards zero by `estimate² / (estimate² + std²)`: the factor that
/// minimises the expected squared error when the true value is about as large as the
/// estimate (Wiener's), so that a factor the views fix well is kept and one they leave
/// loose moves nothing much. Zero for a non-finite input.
pub fn shrunk(estimate: f64, std: f64) -> f64 {
    let (e2, s2) = (estimate * estimate, std * std);
    let total = e2 + s2;
    if total.is_nan() || total <= 0.0 || total.is_infinite() {
        return 0.0;
    }
    estimate * e2 / total
}

/// The shift taken in proportion to how thick each circle's edge looked, instead of one
/// distance for every circle ([`scaled_by_thickness`]), solved in the same way.
///
/// Both are models of one effect. An ideal pixel's events sit a fixed way into an edge's
/// blurred profile; a slow pixel's trail a dark circle's leading edge by a smear whose
/// length grows with the edge's own blur and with how long the pixel takes to settle. The
/// first reads as one distance, the second as a distance in proportion to the thickness of
/// the edge (the circle fit's spread of events about it, which blur and smear widen alike).
/// Real edges lie between the two, and a constant tuned between them would be tuned to a
/// sensor; where the two give different intrinsics, the views cannot tell which is right,
/// so the difference is counted in the printed σ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ByThickness {
    /// The shift at the median thickness, px.
    pub px: f64,
    /// Each parameter's value under this model less its value under one distance, in the
    /// order of [`calib::PARAMETER_NAMES`].
    pub change: [f64; 9],
}

/// `dirs` with each point's direction scaled by its edge's thickness (`spreads`, px, in the
/// same layout) over the median thickness, so that a shift of `s` moves a point of median
/// thickness by `s`. `None` when the layouts differ or no thickness is known; a point
/// without a usable thickness keeps its direction.
pub fn scaled_by_thickness(dirs: &[Vec<[f64; 2]>], spreads: &[&[f64]]) -> Option<Vec<Vec<[f64; 2]>>> {
    if dirs.len() != spreads.len() || dirs.iter().zip(spreads).any(|(d, s)| d.len() != s.len()) {
        return None;
    }
    let usable = |s: f64| s.is_finite() && s > 0.0;
    let mut all: Vec<f64> = spreads.iter().flat_map(|s| s.iter().copied()).filter(|&s| usable(s)).collect();
    let median = crate::stats::median(&mut all)?;
    Some(
        dirs.iter()
            .zip(spreads)
            .map(|(d, s)| {
                d.iter()
                    .zip(s.iter())
                    .map(|(d, &s)| {
                        let f = if usable(s) { s / median } else { 1.0 };
                        [d[0] * f, d[1] * f]
                    })
                    .collect()
            })
            .collect(),
    )
}

/// A point's step between its neighbouring windows: its displacement, px, and its speed,
/// px/s (see [`neighbour_steps`]).
type Step = ([f64; 2], f64);

/// Each point's step between its neighbouring windows: the displacement from where its
/// board point was in the nearest earlier window that saw it (within
/// [`MAX_NEIGHBOUR_GAP_S`]) to where it was in the nearest later one (one-sided at gaps),
/// px, and its speed: the slower of its two sides' (from the earlier window to this one,
/// and from this one to the later), so that one neighbour paired with the wrong circle
/// does not make it fast. `None` where no neighbouring window saw it.
fn neighbour_steps(views: &[View], origins: &[ViewOrigin]) -> Vec<Vec<Option<Step>>> {
    let maps: Vec<_> = views.iter().map(View::by_board_point).collect();
    let near = |a: usize, b: usize| match (origins.get(a), origins.get(b)) {
        (Some(x), Some(y)) => (x.t_s - y.t_s).abs() <= MAX_NEIGHBOUR_GAP_S,
        _ => false,
    };
    let time = |j: usize| origins.get(j).map_or(f64::NAN, |o| o.t_s);
    (0..views.len())
        .map(|k| {
            views[k]
                .object
                .iter()
                .zip(&views[k].image)
                .map(|(o, here)| {
                    // The nearest window before and after that saw this board point.
                    let seen = |j: usize| maps[j].get(&board_key(o)).map(|p| (*p, time(j)));
                    let prev = (0..k).rev().take_while(|&j| near(j, k)).find_map(seen);
                    let next = (k + 1..views.len()).take_while(|&j| near(j, k)).find_map(seen);
                    let this = (*here, time(k));
                    let side = |(a, ta): ([f64; 2], f64), (b, tb): ([f64; 2], f64)| {
                        let v = (b[0] - a[0]).hypot(b[1] - a[1]) / (tb - ta);
                        if v.is_finite() {
                            v
                        } else {
                            f64::INFINITY
                        }
                    };
                    let ((a, _), (b, _), speed) = match (prev, next) {
                        (Some(a), Some(b)) => (a, b, side(a, this).min(side(this, b))),
                        (Some(a), None) => (a, this, side(a, this)),
                        (None, Some(b)) => (this, b, side(this, b)),
                        (None, None) => return None,
                    };
                    Some(([b[0] - a[0], b[1] - a[1]], speed))
                })
                .collect()
        })
        .collect()
}

/// A step's direction: its unit vector, scaled down below [`FULL_DIRECTION_PX`] of
/// displacement; zero for none.
fn direction_of(step: Option<Step>) -> [f64; 2] {
    let Some((d, _)) = step else { return [0.0; 2] };
    let len = d[0].hypot(d[1]);
    if len <= 1e-9 || len.is_nan() {
        return [0.0; 2];
    }
    let s = (len / FULL_DIRECTION_PX).min(1.0) / len;
    [d[0] * s, d[1] * s]
}

/// Each point's direction of motion: the unit vector from where its board point was in the
/// nearest earlier window that saw it (within [`MAX_NEIGHBOUR_GAP_S`]) to where it was in the
/// nearest later one (one-sided at gaps), scaled down below
/// [`FULL_DIRECTION_PX`] of displacement; zero where no neighbouring window saw it.
/// `views` and `origins` pair up, in time order.
pub fn directions(views: &[View], origins: &[ViewOrigin]) -> Vec<Vec<[f64; 2]>> {
    directions_and_bends(views, origins).0
}

/// One image vector per point of each view, px.
pub type PerPoint = Vec<Vec<[f64; 2]>>;

/// Each point's [`directions`], and the directions of the lag's bend (see the module's
/// note): the same directions times the square of the point's image speed over
/// [`BEND_SPEED_PX_S`], the speed from the same neighbouring windows (the slower of its two
/// sides'); zero where they give none. A bend of `b` moves a point at that speed by `b` px.
/// Both from one pairing of the views' points, which is the costly part.
pub fn directions_and_bends(views: &[View], origins: &[ViewOrigin]) -> (PerPoint, PerPoint) {
    neighbour_steps(views, origins)
        .into_iter()
        .map(|v| {
            v.into_iter()
                .map(|step| {
                    let speed = step.map_or(0.0, |(_, v)| v);
                    let q = if speed.is_finite() { (speed / BEND_SPEED_PX_S).powi(2) } else { 0.0 };
                    let d = direction_of(step);
                    (d, [d[0] * q, d[1] * q])
                })
                .unzip()
        })
        .unzip()
}

/// Corners of the projected outline on which [`outline_response`] fits its conics.
const RESPONSE_CORNERS: usize = 64;

/// How far each outline corner is moved along its normal to measure the response, px: small
/// against any circle the core fits (radius ≥ 3 px), so the response is the fit's linear one.
const RESPONSE_PROBE_PX: f64 = 0.01;

/// The centre of the conic `A x² + B xy + (1 − A) y² + D x + E y + F = 0` that weighted
/// algebraic least squares fits to `pts` (points, each with its weight): the core's ellipse
/// step, in `f64`, for models of what it finds. `None` for no ellipse.
pub fn conic_centre(pts: &[([f64; 2], f64)]) -> Option<[f64; 2]> {
    let mut m = nalgebra::Matrix5::<f64>::zeros();
    let mut b = nalgebra::Vector5::<f64>::zeros();
    for &([x, y], w) in pts {
        let row = nalgebra::Vector5::new(x * x - y * y, x * y, x, y, 1.0);
        m += w * row * row.transpose();
        b += w * row * (-(y * y));
    }
    let s = m.lu().solve(&b)?;
    let (a, bxy, d, e) = (s[0], s[1], s[2], s[3]);
    let c = 1.0 - a;
    let det = 4.0 * a * c - bxy * bxy;
    (det > 0.0).then(|| [(bxy * e - 2.0 * c * d) / det, (bxy * d - 2.0 * a * e) / det])
}

/// How the core's ellipse fit moves the centre of an outline drawn by `corners` (a closed
/// polygon, in order) when its events sit 1 px into the edge along the normals while it
/// moves along unit image direction `u`: the front arc's inward, the back arc's outward.
/// Each corner weighs its arc length times |u · normal|, as the events an edge leaves do.
/// `None` for a degenerate outline.
fn response_of_corners(corners: &[[f64; 2]], u: [f64; 2]) -> Option<[f64; 2]> {
    let n = corners.len();
    let mid = corners.iter().fold([0.0, 0.0], |a, p| [a[0] + p[0] / n as f64, a[1] + p[1] / n as f64]);
    let mut plain = Vec::with_capacity(n);
    let mut moved = Vec::with_capacity(n);
    for j in 0..n {
        let (p, q) = (corners[(j + n - 1) % n], corners[(j + 1) % n]);
        let (tx, ty) = (q[0] - p[0], q[1] - p[1]);
        let len = tx.hypot(ty);
        if len.is_nan() || len <= 1e-12 {
            return None;
        }
        let x = [corners[j][0] - mid[0], corners[j][1] - mid[1]];
        let mut normal = [ty / len, -tx / len];
        if normal[0] * x[0] + normal[1] * x[1] < 0.0 {
            normal = [-normal[0], -normal[1]];
        }
        let facing = normal[0] * u[0] + normal[1] * u[1];
        let w = 0.5 * len * facing.abs();
        let into = if facing > 0.0 { -RESPONSE_PROBE_PX } else { RESPONSE_PROBE_PX };
        plain.push((x, w));
        moved.push(([x[0] + into * normal[0], x[1] + into * normal[1]], w));
    }
    let (a, b) = (conic_centre(&plain)?, conic_centre(&moved)?);
    let r = [(b[0] - a[0]) / RESPONSE_PROBE_PX, (b[1] - a[1]) / RESPONSE_PROBE_PX];
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// The same response for a circle, along its motion (negative: the centre falls behind by
/// about 1.15 times the depth): the unit of [`outline_response`].
fn circle_response() -> f64 {
    static R: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *R.get_or_init(|| {
        let corners: Vec<[f64; 2]> = (0..RESPONSE_CORNERS)
            .map(|j| {
                let a = std::f64::consts::TAU * j as f64 / RESPONSE_CORNERS as f64;
                [10.0 * a.cos(), 10.0 * a.sin()]
            })
            .collect();
        response_of_corners(&corners, [1.0, 0.0]).map_or(-1.0, |r| r[0])
    })
}

/// The forward move of the fitted centre, in units of a circle's (so a circle's is `u`),
/// of the circle of `radius` (metres) about board point `centre` seen through `pose` and
/// `k`, moving along unit image direction `u`. `None` when part of the outline is behind the
/// camera.
fn outline_response(k: &Intrinsics, pose: &Pose, centre: &[f64; 3], radius: f64, u: [f64; 2]) -> Option<[f64; 2]> {
    let corners = (0..RESPONSE_CORNERS)
        .map(|j| {
            let a = std::f64::consts::TAU * j as f64 / RESPONSE_CORNERS as f64;
            let o = Vector3::new(centre[0] + radius * a.cos(), centre[1] + radius * a.sin(), centre[2]);
            k.project(&(pose.rotation * o + pose.translation))
        })
        .collect::<Option<Vec<_>>>()?;
    let r = response_of_corners(&corners, u)?;
    let c = circle_response();
    Some([r[0] / c, r[1] / c])
}

/// Per view and point of `views`, the move across the motion that a shift of 1 px at a
/// fixed depth into the edge (`dirs` its directions, as [`directions`] gives them) makes of
/// a centre, for outlines where `cal` puts them (circles of `radius`, metres): the
/// directions of the edge shift's lean (see the module's note). Zero for a circle, a point
/// without a direction, and one `cal` did not solve (a view set aside, an outline behind
/// the camera).
pub fn across_outlines(
    views: &[View],
    dirs: &[Vec<[f64; 2]>],
    cal: &calib::Calibration,
    radius: f64,
) -> Vec<Vec<[f64; 2]>> {
    let mut out: Vec<Vec<[f64; 2]>> = dirs.iter().map(|d| vec![[0.0; 2]; d.len()]).collect();
    for r in &cal.views {
        let (Some(v), Some(d), Some(o)) = (views.get(r.view), dirs.get(r.view), out.get_mut(r.view)) else {
            continue;
        };
        let pose =
            Pose { rotation: Rotation3::from_scaled_axis(Vector3::from(r.rvec)), translation: Vector3::from(r.tvec) };
        for ((b, d), o) in v.object.iter().zip(d).zip(o.iter_mut()) {
            let len = d[0].hypot(d[1]);
            if len.is_nan() || len <= 1e-12 {
                continue;
            }
            let u = [d[0] / len, d[1] / len];
            if let Some(m) = outline_response(&cal.intrinsics, &pose, b, radius, u) {
                let across = (-m[0] * u[1] + m[1] * u[0]) * len;
                *o = [-across * u[1], across * u[0]];
            }
        }
    }
    out
}

/// `views` with every point moved `shift` px along its direction.
pub fn shifted(views: &[View], dirs: &[Vec<[f64; 2]>], shift: f64) -> Vec<View> {
    views
        .iter()
        .zip(dirs)
        .map(|(v, d)| View {
            object: v.object.clone(),
            image: v.image.iter().zip(d).map(|(p, d)| [p[0] + shift * d[0], p[1] + shift * d[1]]).collect(),
        })
        .collect()
}

/// The shift that lets one camera explain `views` best (plain least squares, `opts`' fixed
/// parameters), or `None` when too few points have a direction or the solves fail.
pub fn estimate(
    views: &[View],
    dirs: &[Vec<[f64; 2]>],
    image_size: [u32; 2],
    opts: &calib::Options,
) -> Option<EdgeShift> {
    let points = dirs.iter().flatten().filter(|d| d[0] != 0.0 || d[1] != 0.0).count();
    if points < MIN_POINTS_WITH_DIRECTION {
        return None;
    }
    let base = calib::Options { robust: false, ..opts.clone() };
    let first = calib::calibrate(views, image_size, &base).ok()?;
    // Centres far off (a cluster that caught clutter, a ring half fired) would pull the
    // shift towards whatever explains them; it is measured on the others.
    let (views, dirs) = trimmed(views, dirs, &first);
    let (views, dirs) = (&views[..], &dirs[..]);
    let first = calib::calibrate(views, image_size, &base).ok()?;
    let total: usize = views.iter().map(|v| v.object.len().min(v.image.len())).sum();
    // Every solve starts where the unshifted one ended: a fraction of a pixel changes little.
    let warm = calib::Options { start: Some(first.intrinsics), ..base };
    let cost = |s: f64| -> f64 {
        match calib::calibrate(&shifted(views, dirs, s), image_size, &warm) {
            Ok(c) if c.views.len() == first.views.len() => c.rms_px * c.rms_px * total as f64,
            _ => f64::INFINITY,
        }
    };
    // Golden-section search: the cost is a smooth bowl in the shift.
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (-MAX_SHIFT_PX, MAX_SHIFT_PX);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (cost(c), cost(d));
    while b - a > 2e-3 {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = cost(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = cost(d);
        }
    }
    let best = 0.5 * (a + b);
    let (f0, h) = (cost(best), 0.05);
    let curvature = (cost(best + h) + cost(best - h) - 2.0 * f0) / (h * h);
    if !f0.is_finite() || curvature.is_nan() || curvature <= 0.0 {
        return None;
    }
    // Residual variance per coordinate; the cost is a sum of squares, so var = 2σ²/curvature.
    let sigma2 = f0 / (2.0 * total as f64).max(1.0);
    Some(EdgeShift {
        px: best,
        std_px: (2.0 * sigma2 / curvature).sqrt(),
        points,
        by_thickness: None,
        lean: None,
        bend: None,
    })
}

/// Points further than [`TRIM_RMS`] times the solve's RMS from their reprojection are left
/// out of the shift's estimate.
const TRIM_RMS: f64 = 2.5;

/// `views` and their directions without the points `cal` reprojects far from where they
/// were seen (views `cal` set aside are dropped whole).
fn trimmed(views: &[View], dirs: &[Vec<[f64; 2]>], cal: &calib::Calibration) -> (Vec<View>, Vec<Vec<[f64; 2]>>) {
    let limit = TRIM_RMS * cal.rms_px;
    let mut out = (Vec::new(), Vec::new());
    for r in &cal.views {
        let (Some(v), Some(d)) = (views.get(r.view), dirs.get(r.view)) else { continue };
        let (mut view, mut dir) = (View { object: Vec::new(), image: Vec::new() }, Vec::new());
        let residuals = cal.residuals(v, r);
        for (((o, m), d), e) in v.object.iter().zip(&v.image).zip(d).zip(residuals) {
            // A point behind the camera has a NaN residual: it is left out too.
            if e[0].hypot(e[1]) <= limit {
                view.object.push(*o);
                view.image.push(*m);
                dir.push(*d);
            }
        }
        out.0.push(view);
        out.1.push(dir);
    }
    out
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::calib::{synthetic_views, Intrinsics};

    fn truth() -> Intrinsics {
        Intrinsics { fx: 330.0, fy: 331.0, cx: 170.0, cy: 128.0, k1: -0.3, k2: 0.12, p1: 0.0005, p2: -0.0003, k3: 0.0 }
    }

    /// Views in time order whose points move: each view is the previous one's pose a little
    /// on, so neighbouring windows give directions.
    fn moving_views(n: usize) -> (Vec<View>, Vec<ViewOrigin>) {
        let views = synthetic_views(&truth(), n, 0.0, 3);
        let origins = (0..n).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect();
        (views, origins)
    }

    #[test]
    fn directions_are_unit_vectors_towards_the_next_window_and_bends_grow_as_the_speed_squared() {
        let o = |x: f64| [x, 0.0, 0.0];
        let views = vec![
            View { object: vec![o(0.0), o(1.0)], image: vec![[10.0, 10.0], [20.0, 10.0]] },
            View { object: vec![o(0.0)], image: vec![[12.0, 10.0]] },
            View { object: vec![o(0.0), o(1.0)], image: vec![[14.0, 10.0], [20.0, 10.3]] },
            View { object: vec![o(0.0)], image: vec![[50.0, 50.0]] },
        ];
        let t = [0.0, 0.033, 0.066, 1.0];
        let origins: Vec<ViewOrigin> =
            t.iter().enumerate().map(|(k, &t_s)| ViewOrigin { window_seq: k as u64, t_s }).collect();
        let (d, b) = directions_and_bends(&views, &origins);
        // The second point is missing from the window between: its neighbours are two apart.
        // It moved 0.3 px: below FULL_DIRECTION_PX, the direction is scaled down.
        let close = |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.len() == b.len()
                && a.iter().zip(b).all(|(p, q)| (p[0] - q[0]).abs() < 1e-12 && (p[1] - q[1]).abs() < 1e-12)
        };
        assert!(close(&d[0], &[[1.0, 0.0], [0.0, 0.3]]), "{:?}", d[0]);
        assert!(close(&d[1], &[[1.0, 0.0]]), "{:?}", d[1]);
        assert!(close(&d[2], &[[1.0, 0.0], [0.0, 0.3]]), "one-sided, the next window is too far: {:?}", d[2]);
        assert!(close(&d[3], &[[0.0, 0.0]]), "the last window is a second later: no neighbour: {:?}", d[3]);
        // The bend's: the same directions times (speed / 100 px/s)², the speed over the same
        // neighbours, the slower side's: 2 px in 33 ms either side, and 0.3 px in 66 ms
        // (one-sided at both ends).
        let q = |px: f64| (px / 0.066 / BEND_SPEED_PX_S).powi(2);
        assert!(close(&b[0], &[[q(4.0), 0.0], [0.0, 0.3 * q(0.3)]]), "{:?}", b[0]);
        assert!(close(&b[1], &[[q(4.0), 0.0]]), "{:?}", b[1]);
        assert!(close(&b[2], &[[q(4.0), 0.0], [0.0, 0.3 * q(0.3)]]), "{:?}", b[2]);
        assert!(close(&b[3], &[[0.0, 0.0]]), "{:?}", b[3]);
    }

    #[test]
    fn a_neighbour_paired_with_the_wrong_circle_does_not_make_a_point_fast() {
        let o = [0.0, 0.0, 0.0];
        let at = |x: f64| View { object: vec![o], image: vec![[x, 10.0]] };
        // 2 px in a window's 33 ms, then a jump of 40 px: another circle taken for it.
        let views = vec![at(10.0), at(12.0), at(52.0)];
        let origins: Vec<ViewOrigin> =
            (0..3).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect();
        let (_, b) = directions_and_bends(&views, &origins);
        let slow = (2.0 / 0.033 / BEND_SPEED_PX_S).powi(2);
        assert!((b[1][0][0] - slow).abs() < 1e-12 && b[1][0][1] == 0.0, "{:?}", b[1]);
    }

    #[test]
    fn finds_a_shift_put_into_exact_views_and_taking_it_out_restores_the_camera() {
        let (views, origins) = moving_views(40);
        let dirs = directions(&views, &origins);
        // The detections trail their circles by 0.15 px along the motion.
        let late = shifted(&views, &dirs, -0.15);
        let est = estimate(&late, &dirs, [346, 260], &calib::Options::default()).expect("an estimate");
        assert!((est.px - 0.15).abs() < 0.01, "{est:?}");
        let fixed = calib::calibrate(&shifted(&late, &dirs, est.px), [346, 260], &calib::Options::default()).unwrap();
        assert!((fixed.intrinsics.fx / truth().fx - 1.0).abs() < 1e-4, "{:?}", fixed.intrinsics);
    }

    #[test]
    fn a_shift_solved_as_a_parameter_has_the_spread_it_claims_and_widens_the_intrinsics() {
        // Noisy views trailing by 0.15 px: over seeds, the shift's estimates scatter as the
        // σ the final solve gives it, and carrying it makes no intrinsic's σ smaller.
        let mut estimates = Vec::new();
        let mut claimed = Vec::new();
        for seed in 0..12 {
            let views = synthetic_views(&truth(), 40, 0.1, 100 + seed);
            let origins: Vec<ViewOrigin> =
                (0..40).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect();
            let dirs = directions(&views, &origins);
            let late = shifted(&views, &dirs, -0.15);
            let est = estimate(&late, &dirs, [346, 260], &calib::Options::default()).expect("an estimate");
            let fixed = shifted(&late, &dirs, est.px);
            let plain = calib::calibrate(&fixed, [346, 260], &calib::Options::default()).unwrap();
            let opts = calib::Options { shift_directions: dirs.clone(), ..calib::Options::default() };
            let joint = calib::calibrate(&fixed, [346, 260], &opts).unwrap();
            assert_eq!(plain.intrinsics, joint.intrinsics, "the σ changes, not the solution");
            for i in 0..4 {
                assert!(joint.std_dev[i] >= plain.std_dev[i] * (1.0 - 1e-9), "{i}: {joint:?} vs {plain:?}");
            }
            assert!(plain.shift_std_px.is_none());
            estimates.push(est.px);
            claimed.push(joint.shift_std_px.expect("a σ for the shift"));
        }
        let mean = estimates.iter().sum::<f64>() / 12.0;
        let scatter = (estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / 11.0).sqrt();
        let sigma = claimed.iter().sum::<f64>() / 12.0;
        assert!((mean - 0.15).abs() < 3.0 * sigma, "mean {mean}, σ {sigma}");
        assert!(scatter < 2.0 * sigma && scatter > 0.4 * sigma, "scatter {scatter} against σ {sigma}");
    }

    #[test]
    fn no_shift_is_found_where_there_is_none_and_too_few_directions_give_none() {
        let (views, origins) = moving_views(40);
        let dirs = directions(&views, &origins);
        let est = estimate(&views, &dirs, [346, 260], &calib::Options::default()).expect("an estimate");
        assert!(est.px.abs() < 0.005, "{est:?}");
        let none: Vec<Vec<[f64; 2]>> = views.iter().map(|v| vec![[0.0, 0.0]; v.object.len()]).collect();
        assert!(estimate(&views, &none, [346, 260], &calib::Options::default()).is_none());
    }

    /// An ellipse of semi-axes `a`, `b` whose major axis points along `phi`, as corners.
    fn ellipse(a: f64, b: f64, phi: f64) -> Vec<[f64; 2]> {
        (0..RESPONSE_CORNERS)
            .map(|j| {
                let t = std::f64::consts::TAU * j as f64 / RESPONSE_CORNERS as f64;
                let (x, y) = (a * t.cos(), b * t.sin());
                [x * phi.cos() - y * phi.sin(), x * phi.sin() + y * phi.cos()]
            })
            .collect()
    }

    #[test]
    fn a_circle_moves_back_along_its_motion_and_a_slanted_ellipse_also_across_it() {
        let c = circle_response();
        assert!((-1.3..-1.0).contains(&c), "a circle's centre falls behind by about the depth: {c}");
        let across = |corners: &[[f64; 2]], th: f64| {
            let u = [th.cos(), th.sin()];
            let r = response_of_corners(corners, u).expect("a response");
            (r[0] * u[0] + r[1] * u[1], -r[0] * u[1] + r[1] * u[0])
        };
        for th in [0.0, 0.4, 1.3, 2.9] {
            let (along, side) = across(&ellipse(6.0, 6.0, 0.0), th);
            assert!((along - c).abs() < 1e-4 && side.abs() < 1e-4, "circle at {th}: {along}, {side}, {c}");
        }
        // Along either axis the events are symmetric about the motion: nothing across.
        let e = ellipse(8.0, 6.0, 0.5);
        for th in [0.5, 0.5 + std::f64::consts::FRAC_PI_2] {
            assert!(across(&e, th).1.abs() < 1e-4, "along an axis at {th}: {:?}", across(&e, th));
        }
        // At 45° to the axes it moves across, to either side as the slant's sign, about in
        // proportion to (a − b)/(a + b).
        let q = std::f64::consts::FRAC_PI_4;
        let (plus, minus) = (across(&e, 0.5 + q).1, across(&e, 0.5 - q).1);
        assert!(plus.abs() > 0.01 && (plus + minus).abs() < 1e-4, "{plus} {minus}");
        let wider = across(&ellipse(10.0, 6.0, 0.5), 0.5 + q).1;
        let ratio = wider / plus;
        let expected = (4.0 / 16.0) / (2.0 / 14.0);
        assert!((ratio / expected - 1.0).abs() < 0.25, "slant 0.25 against 0.143: ratio {ratio}, expected {expected}");
    }

    #[test]
    fn a_loose_factor_is_shrunk_and_a_firm_one_kept() {
        assert_eq!(shrunk(2.0, 0.0), 2.0);
        assert_eq!(shrunk(0.0, 1.0), 0.0);
        assert!((shrunk(1.0, 1.0) - 0.5).abs() < 1e-12);
        assert!((shrunk(-3.0, 0.3) + 3.0 * 9.0 / 9.09).abs() < 1e-12);
        assert_eq!(shrunk(f64::NAN, 1.0), 0.0);
        assert_eq!(shrunk(1.0, f64::INFINITY), 0.0);
    }

    #[test]
    fn a_lean_is_across_the_motion_and_in_proportion_to_it() {
        let (views, origins) = moving_views(12);
        let mut dirs = directions(&views, &origins);
        dirs[3][0] = [0.0, 0.0];
        let cal = calib::calibrate(&views, [346, 260], &calib::Options::default()).unwrap();
        // Circles of 15 mm on these tilted views: outlines that lean.
        let one = across_outlines(&views, &dirs, &cal, 0.015);
        let doubled: Vec<Vec<[f64; 2]>> =
            dirs.iter().map(|d| d.iter().map(|d| [2.0 * d[0], 2.0 * d[1]]).collect()).collect();
        let two = across_outlines(&views, &doubled, &cal, 0.015);
        assert_eq!(one.len(), views.len());
        let mut biggest = 0.0f64;
        for ((d, a), b) in dirs.iter().flatten().zip(one.iter().flatten()).zip(two.iter().flatten()) {
            assert!((d[0] * a[0] + d[1] * a[1]).abs() < 1e-12, "across the motion: {d:?} {a:?}");
            assert!((2.0 * a[0] - b[0]).abs() < 1e-12 && (2.0 * a[1] - b[1]).abs() < 1e-12, "{a:?} {b:?}");
            biggest = biggest.max(a[0].hypot(a[1]));
        }
        assert_eq!(one[3][0], [0.0, 0.0], "no direction, no lean");
        assert!(biggest > 1e-4 && biggest < 0.5, "{biggest}");
    }
}
