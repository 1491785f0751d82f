//! The emulator example's true images of the board's circles: from the truth's poses,
//! the projected centres and outlines, and the centres fits would find on them (`--diagnose`).

use super::*;

/// The projection of board point `o`'s centre at `t`, and `n` points around its circle's
/// projected outline.
pub(super) fn true_outline(
    truth: &Truth,
    k: &Intrinsics,
    o: &[f64; 3],
    t: f64,
    n: usize,
) -> Option<([f64; 2], Vec<[f64; 2]>)> {
    let (rv, tv) = truth.pose_at(t);
    let rot = Rotation3::new(Vector3::from(rv));
    let tv = Vector3::from(tv);
    let cam = |x: f64, y: f64| rot * Vector3::new(x, y, 0.0) + tv;
    let centre = k.project(&cam(o[0], o[1]))?;
    let r = truth.pattern.radius_m;
    let mut pts = Vec::with_capacity(n);
    for j in 0..n {
        let a = std::f64::consts::TAU * j as f64 / n as f64;
        pts.push(k.project(&cam(o[0] + r * a.cos(), o[1] + r * a.sin()))?);
    }
    Some((centre, pts))
}

/// The true image of board point `o` at `t`: the projection of the circle's centre, and the
/// centre of its projected outline (the ellipse's).
pub(super) fn true_centres(truth: &Truth, k: &Intrinsics, o: &[f64; 3], t: f64) -> Option<([f64; 2], [f64; 2])> {
    let n = 96;
    let (centre, pts) = true_outline(truth, k, o, t, n)?;
    let (mut area, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for j in 0..n {
        let ([x0, y0], [x1, y1]) = (pts[j], pts[(j + 1) % n]);
        let c = x0 * y1 - x1 * y0;
        area += c;
        cx += (x0 + x1) * c;
        cy += (y0 + y1) * c;
    }
    Some((centre, [cx / (3.0 * area), cy / (3.0 * area)]))
}

/// How an outline leans against its motion: ε·sin 2(θ − φ), with ε = (a − b)/(a + b) from
/// the axes of the projected outline of board point `o` at `t` (its second moments), φ the
/// major axis's direction and θ the unit image direction `u`'s. Zero for a circle, or for an
/// ellipse moving along either axis: then the events are symmetric about the motion.
pub(super) fn outline_slant(truth: &Truth, k: &Intrinsics, o: &[f64; 3], t: f64, u: [f64; 2]) -> Option<f64> {
    let n = 64;
    let (_, pts) = true_outline(truth, k, o, t, n)?;
    let m = pts.iter().fold([0.0, 0.0], |a, p| [a[0] + p[0] / n as f64, a[1] + p[1] / n as f64]);
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in &pts {
        let (dx, dy) = (p[0] - m[0], p[1] - m[1]);
        (sxx, syy, sxy) = (sxx + dx * dx, syy + dy * dy, sxy + dx * dy);
    }
    let phi = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let half = 0.5 * (sxx + syy);
    let disc = (half * half - (sxx * syy - sxy * sxy)).max(0.0).sqrt();
    let (a, b) = ((half + disc).sqrt(), (half - disc).max(0.0).sqrt());
    let eps = (a - b) / (a + b).max(1e-12);
    Some(eps * (2.0 * (u[1].atan2(u[0]) - phi)).sin())
}

/// Points about a centre, each with its weight.
type Weighted = Vec<([f64; 2], f64)>;

/// The outline of board point `o` at `t` as a fit sees it: 256 points about their mean
/// (returned too), each weighted by its arc length, times |motion · normal| when `u` (a
/// unit image direction) is given: only the edges moving across themselves give events.
pub(super) fn weighted_outline(
    truth: &Truth,
    k: &Intrinsics,
    o: &[f64; 3],
    t: f64,
    u: Option<[f64; 2]>,
) -> Option<([f64; 2], Weighted)> {
    let n = 256;
    let (_, pts) = true_outline(truth, k, o, t, n)?;
    let c0 = pts.iter().fold([0.0, 0.0], |a, p| [a[0] + p[0] / n as f64, a[1] + p[1] / n as f64]);
    let weighted = (0..n)
        .map(|j| {
            let (p, q) = (pts[(j + n - 1) % n], pts[(j + 1) % n]);
            let (tx, ty) = (q[0] - p[0], q[1] - p[1]);
            let ds = tx.hypot(ty) * 0.5;
            let w = match u {
                Some(u) => ds * ((u[0] * ty - u[1] * tx).abs() / (2.0 * ds).max(1e-12)),
                None => ds,
            };
            ([pts[j][0] - c0[0], pts[j][1] - c0[1]], w)
        })
        .collect();
    Some((c0, weighted))
}

/// The centre a weighted algebraic circle fit (Kåsa) finds on the outline of board point `o`
/// at `t`, weighted for motion `u` (see [`weighted_outline`]).
pub(super) fn fitted_outline_centre(
    truth: &Truth,
    k: &Intrinsics,
    o: &[f64; 3],
    t: f64,
    u: [f64; 2],
) -> Option<[f64; 2]> {
    let (c0, pts) = weighted_outline(truth, k, o, t, Some(u))?;
    // x² + y² + D x + E y + F = 0, in coordinates about c0.
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut b = nalgebra::Vector3::<f64>::zeros();
    for ([x, y], w) in pts {
        let row = nalgebra::Vector3::new(x, y, 1.0);
        m += w * row * row.transpose();
        b += w * row * (-(x * x + y * y));
    }
    let s = m.lu().solve(&b)?;
    Some([c0[0] - 0.5 * s[0], c0[1] - 0.5 * s[1]])
}

/// The centre of the conic fitted to the outline of board point `o` at `t` by the core's
/// algebraic fit (rows x² − y², xy, x, y, 1; target −y²), weighted as [`weighted_outline`]
/// weighs it.
pub(super) fn conic_outline_centre(
    truth: &Truth,
    k: &Intrinsics,
    o: &[f64; 3],
    t: f64,
    u: Option<[f64; 2]>,
) -> Option<[f64; 2]> {
    let (c0, pts) = weighted_outline(truth, k, o, t, u)?;
    let c = evcal_host::views::edge_shift::conic_centre(&pts)?;
    Some([c0[0] + c[0], c0[1] + c[1]])
}
