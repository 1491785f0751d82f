//! Intrinsic calibration from views of a planar target: Zhang's closed-form start, then
//! Levenberg–Marquardt over the intrinsics, the distortion and every view's pose, in OpenCV's
//! camera model.
//!
//! ```
//! use evcal_host::calib::{calibrate, Options, View};
//! # use evcal_host::calib::Intrinsics;
//! # let truth = Intrinsics { fx: 350.0, fy: 351.0, cx: 172.0, cy: 131.0, k1: -0.3, k2: 0.1, p1: 0.0, p2: 0.0, k3: 0.0 };
//! # let views = evcal_host::calib::synthetic_views(&truth, 12, 0.0, 7);
//! // `views`: each a list of board points (metres, z = 0) and the pixels where they were seen.
//! let cal = calibrate(&views, [346, 260], &Options::default()).expect("calibration");
//! println!("fx {:.2} fy {:.2} cx {:.2} cy {:.2}, RMS {:.3} px", cal.intrinsics.fx, cal.intrinsics.fy,
//!          cal.intrinsics.cx, cal.intrinsics.cy, cal.rms_px);
//! # assert!((cal.intrinsics.fx - 350.0).abs() < 1e-6);
//! ```
//!
//! The problem has one small block (the nine intrinsics) shared by all views and one 6-
//! parameter block per view: each step solves the Schur complement onto the intrinsics and
//! then each pose alone, so hundreds of views cost little more than their points. Views far
//! worse than the others are set aside and named, with the reason; points far off are down-
//! weighted (Huber) when `robust` is on.

mod covariance;
mod groups;
mod init;
mod k3;
mod model;
#[cfg(test)]
mod outline_tests;
mod problem;
mod rectify;
mod result;
mod solve;
mod stats;
#[cfg(test)]
mod tests;
mod uncertainty;

pub use groups::{
    few_groups_factor, group_seconds, groups_of, COVERAGE_SIGMAS, GROUPS_WANTED, GROUP_PLACEMENTS, GROUP_SECONDS,
    MIN_GROUPS, MIN_GROUP_SECONDS,
};
pub use k3::{k3_displacement_px, K3_NEGLIGIBLE_PX};
pub use model::{outline_offset, Intrinsics, Pose, PARAMETER_NAMES};
pub(crate) use problem::board_key;
pub use problem::{Options, View};
pub use rectify::optimal_new_camera_matrix;
pub use result::{CalibError, Calibration, MoveEstimate, PrecisionBin, Rejection, ViewResult};
pub use uncertainty::{
    projection_sigma_at, unproject, Covered, ProjectionSigma, SigmaFigures, PROJECTION_SIGMA_STEP_PX, SIGMA_PERCENTILE,
};

use crate::stats::{median, median_mad};
use covariance::{grouped_covariance, parameter_covariance, view_groups};
use stats::{precision_weights, rms};

use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Most solves of the robust loop (each after setting views aside or reweighing points).
const ROBUST_ROUNDS: usize = 30;

/// Points of one view off by more than this (and 5 σ) are taken for points paired with
/// the wrong board points, px: a wrong pairing moves a point by a grid spacing (several
/// pixels), while centre errors stay within about a pixel.
pub const MISLABEL_PX: f64 = 2.0;

/// Circle outline offsets that moved less than this between two solves are settled, px.
const OFFSET_SETTLED_PX: f64 = 1e-4;
/// Most solves added to let the outline offsets settle.
const OFFSET_ROUNDS: usize = 4;

/// Fewest views a calibration accepts: Zhang's closed form needs three.
pub const MIN_VIEWS: usize = 3;
/// Fewest points a view needs to take part (a homography needs four, a pose with
/// distortion a few more).
pub const MIN_POINTS_PER_VIEW: usize = 6;

/// Calibrates a camera of `image_size` (width, height) from `views`.
pub fn calibrate(views: &[View], image_size: [u32; 2], opts: &Options) -> Result<Calibration, CalibError> {
    if views.is_empty() {
        return Err(CalibError::NoViews);
    }
    for (v, view) in views.iter().enumerate() {
        for (p, (o, m)) in view.object.iter().zip(&view.image).enumerate() {
            if !(o.iter().all(|x| x.is_finite()) && m.iter().all(|x| x.is_finite())) {
                return Err(CalibError::NotFinite { view: v, point: p });
            }
        }
    }
    let mut rejected = Vec::new();
    // Views that can take part: enough points, and a homography.
    let mut homographies = Vec::new();
    let mut usable = Vec::new();
    for (v, view) in views.iter().enumerate() {
        let n = view.object.len().min(view.image.len());
        if n < MIN_POINTS_PER_VIEW {
            rejected.push(Rejection { view: v, reason: format!("{n} points; at least {MIN_POINTS_PER_VIEW} needed") });
            continue;
        }
        match init::homography(&view.object[..n], &view.image[..n]) {
            Some(h) => {
                homographies.push(h);
                usable.push(v);
            }
            None => rejected.push(Rejection { view: v, reason: "points degenerate (collinear or coincident)".into() }),
        }
    }
    if usable.len() < MIN_VIEWS {
        return Err(CalibError::TooFewViews { usable: usable.len(), needed: MIN_VIEWS });
    }
    let centre = [(f64::from(image_size[0]) - 1.0) * 0.5, (f64::from(image_size[1]) - 1.0) * 0.5];
    let start = match opts.start {
        Some(s) => s,
        None => {
            let [fx, fy, cx, cy] = match init::zhang(&homographies) {
                // Zhang's principal point can wander off with few or similar views: then take
                // the image centre, as OpenCV does.
                Some([fx, fy, cx, cy]) if (cx - centre[0]).abs() < centre[0] && (cy - centre[1]).abs() < centre[1] => {
                    [fx, fy, cx, cy]
                }
                _ => {
                    let [fx, fy] = init::focal_with_centre(&homographies, centre).ok_or_else(|| {
                        CalibError::Degenerate(format!(
                            "no focal length fits the {} views: too few to tell the focal length \
                             from the distance, or all nearly parallel to the sensor (tilt the target)",
                            usable.len()
                        ))
                    })?;
                    [fx, fy, centre[0], centre[1]]
                }
            };
            // Square pixels: one focal length, between the two the closed form gives.
            let [fx, fy] = if opts.fix_aspect_ratio { [(fx * fy).sqrt(); 2] } else { [fx, fy] };
            Intrinsics { fx, fy, cx, cy, k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 }
        }
    };
    let mut poses = Vec::with_capacity(usable.len());
    let mut kept = Vec::with_capacity(usable.len());
    for (&v, h) in usable.iter().zip(&homographies) {
        match init::pose_from_homography(h, &start) {
            Some(p) => {
                poses.push(p);
                kept.push(v);
            }
            None => {
                rejected.push(Rejection { view: v, reason: "no pose puts the target in front of the camera".into() })
            }
        }
    }
    if kept.len() < MIN_VIEWS {
        return Err(CalibError::TooFewViews { usable: kept.len(), needed: MIN_VIEWS });
    }

    let mut mask = [true; 9];
    if opts.fix_principal_point {
        mask[2] = false;
        mask[3] = false;
    }
    if opts.zero_tangential {
        mask[6] = false;
        mask[7] = false;
    }
    if opts.fix_k3 {
        mask[8] = false;
    }
    // Without a start of the user's the ratio is 1 and fy is fx itself (`1.0 * fx`), not a
    // ratio the closed form's noise set.
    let aspect = if opts.start.is_some() { start.fy / start.fx } else { 1.0 };
    let free = solve::Free { mask, aspect: opts.fix_aspect_ratio.then_some(aspect) };
    let mut k = start;
    if opts.zero_tangential {
        k.p1 = 0.0;
        k.p2 = 0.0;
    }
    if opts.fix_k3 {
        k.k3 = 0.0;
    }

    // Per-point weights, per kept view.
    let mut weights: Vec<Vec<f64>> = kept.iter().map(|&v| vec![1.0; views[v].object.len()]).collect();
    // Per view (by its index in `views`): what its points are compared with, the detected
    // centres less the offset of each circle's outline centre from its projected centre
    // (`Options::circle_radius`), taken from the previous solve. The offsets hardly depend
    // on the camera (0.02-0.1 px, changing by a small fraction of that between solves), so
    // a few solves settle them.
    let mut targets: Vec<Vec<[f64; 2]>> = views.iter().map(|v| v.image.clone()).collect();
    let mut offset_rounds = 0;
    let mut sol;
    let mut round = 0;
    let mut weighted = false;
    let mut precision_bins = Vec::new();
    loop {
        let data: Vec<solve::ViewData> = kept
            .iter()
            .zip(&weights)
            .map(|(&v, w)| solve::ViewData { object: &views[v].object, image: &targets[v], weight: w })
            .collect();
        sol = solve::solve(&data, k, poses.clone(), &free, opts.max_iterations, opts.tolerance)
            .ok_or_else(|| CalibError::Degenerate("the solve diverged (a point fell behind the camera)".into()))?;
        k = sol.intrinsics;
        poses = sol.poses.clone();
        round += 1;
        let mut offsets_moved = false;
        if let Some(radius) = opts.circle_radius {
            for (&v, pose) in kept.iter().zip(&poses) {
                for ((o, m), t) in views[v].object.iter().zip(&views[v].image).zip(targets[v].iter_mut()) {
                    let d = outline_offset(&k, pose, o, radius).unwrap_or([0.0; 2]);
                    let next = [m[0] - d[0], m[1] - d[1]];
                    offsets_moved |= (next[0] - t[0]).hypot(next[1] - t[1]) > OFFSET_SETTLED_PX;
                    *t = next;
                }
            }
        }
        // A solve that saw offsets since changed is solved again (a few times at most).
        let again = offsets_moved && offset_rounds < OFFSET_ROUNDS;
        offset_rounds += usize::from(again);
        if !opts.robust || round >= ROBUST_ROUNDS {
            if again {
                continue;
            }
            break;
        }
        // Robust rounds. The errors are 2-D distances: for Gaussian noise of σ per axis their
        // median is 1.18 σ, and fewer than 1 in 10⁵ lie beyond 5 σ. First, views whose
        // median error is far above the others' go (a wrong ordering, blur): a grossly wrong
        // view bends the whole solution, so nothing finer is judged until they are gone.
        // Then, with the solution clean: a point beyond 5 σ in a view is a stray (a blob
        // merged with a circle, a centre fitted to few events) and is weighed down; more than
        // one beyond both 5 σ and MISLABEL_PX means the view's points are not what they claim
        // (a point paired with the wrong board point is off by a whole spacing), and it goes.
        // The floor keeps the heavy tail of real centre errors from costing whole views.
        let errors: Vec<Vec<f64>> =
            kept.iter().zip(&poses).map(|(&v, p)| residuals(&views[v].object, &targets[v], &k, p)).collect();
        let mut all: Vec<f64> = errors.iter().flatten().copied().collect();
        let sigma = (median(&mut all).unwrap_or(0.0) / 1.18).max(1e-9);
        let far = (5.0 * sigma).max(MISLABEL_PX);
        let medians: Vec<f64> = errors.iter().map(|e| median(&mut e.clone()).unwrap_or(f64::NAN)).collect();
        let (med, mad) = median_mad(&medians).unwrap_or((0.0, 0.0));
        let limit = (med + 5.0 * 1.4826 * mad).max(2.0 * med);
        // While the worst views bend the solution, a good view can look bad too: only the
        // worst go each round (those within a factor of two of the worst), then all is
        // solved again.
        let worst = medians.iter().copied().fold(0.0, f64::max);
        let cut = limit.max(0.5 * worst);
        let gross: Vec<Option<String>> = medians
            .iter()
            .map(|&m| {
                (m > cut)
                    .then(|| format!("median error {m:.3} px, far above the views' {med:.3} px (limit {limit:.3} px)"))
            })
            .collect();
        let verdicts: Vec<Option<String>> = if gross.iter().any(Option::is_some) {
            gross
        } else {
            errors
                .iter()
                .map(|e| {
                    let strays = e.iter().filter(|&&x| x > far).count();
                    let beyond = e.iter().filter(|&&x| x > 5.0 * sigma).count();
                    let worst = e.iter().copied().fold(0.0, f64::max);
                    if strays > 1 {
                        Some(format!(
                            "{strays} of its {} points are off by more than {far:.2} px (5σ of all points, at least {MISLABEL_PX} px; worst {worst:.2} px): points paired with the wrong board points?",
                            e.len()
                        ))
                    } else if 4 * beyond > e.len() {
                        // Strays are set aside one by one; a view made of them says little.
                        Some(format!(
                            "{beyond} of its {} points are off by more than {:.2} px (5σ of all points; worst {worst:.2} px)",
                            e.len(),
                            5.0 * sigma
                        ))
                    } else {
                        None
                    }
                })
                .collect()
        };
        let bad = verdicts.iter().filter(|v| v.is_some()).count();
        if bad > 0 && kept.len() - bad >= MIN_VIEWS {
            let mut next = (Vec::new(), Vec::new());
            for ((v, p), verdict) in kept.iter().zip(&poses).zip(verdicts) {
                match verdict {
                    Some(reason) => rejected.push(Rejection { view: *v, reason }),
                    None => {
                        next.0.push(*v);
                        next.1.push(*p);
                    }
                }
            }
            (kept, poses) = next;
            weights = kept.iter().map(|&v| vec![1.0; views[v].object.len()]).collect();
            precision_bins.clear();
            weighted = false;
            continue;
        }
        if weighted {
            // Nothing rejected, weights settled: done, once the offsets have settled too.
            if again {
                continue;
            }
            break;
        }
        // Huber: beyond 2.5 σ a point weighs less, in proportion to its distance; beyond 5 σ
        // it is a stray and weighs nothing (its centre says nothing about the camera). Each
        // weight times the point's precision, where the views say how precise it is.
        let (delta, stray) = (2.5 * sigma, 5.0 * sigma);
        let hints: Option<Vec<&[f64]>> = kept
            .iter()
            .map(|&v| opts.precision_hints.get(v).filter(|h| h.len() == views[v].object.len()).map(|h| &h[..]))
            .collect();
        let precision = hints.and_then(|h| precision_weights(&errors, &h));
        precision_bins = precision.as_ref().map_or(Vec::new(), |p| p.1.clone());
        let precision = precision.map(|p| p.0);
        weights = errors
            .iter()
            .enumerate()
            .map(|(j, e)| {
                e.iter()
                    .enumerate()
                    .map(|(i, &x)| {
                        let huber = match x {
                            x if x <= delta => 1.0,
                            x if x <= stray => delta / x,
                            _ => 0.0,
                        };
                        huber * precision.as_ref().map_or(1.0, |p| p[j][i])
                    })
                    .collect()
            })
            .collect();
        weighted = true;
    }

    // Results per view (unweighted errors).
    let mut view_results = Vec::with_capacity(kept.len());
    let (mut sq, mut count, mut sq_all) = (0.0, 0usize, 0.0);
    for ((&v, p), w) in kept.iter().zip(&poses).zip(&weights) {
        let e = residuals(&views[v].object, &targets[v], &k, p);
        let inliers: Vec<f64> = e.iter().zip(w).filter(|(_, &w)| w > 0.0).map(|(&x, _)| x).collect();
        sq += inliers.iter().map(|x| x * x).sum::<f64>();
        sq_all += e.iter().map(|x| x * x).sum::<f64>();
        count += inliers.len();
        view_results.push(ViewResult {
            view: v,
            points: e.len(),
            rms_px: rms(&inliers),
            strays: e.len() - inliers.len(),
            rvec: p.rvec(),
            tvec: p.tvec(),
        });
    }
    let rms_px = (sq / count.max(1) as f64).sqrt();
    let all_points: usize = view_results.iter().map(|r| r.points).sum();
    let rms_all_px = (sq_all / all_points.max(1) as f64).sqrt();
    let per_view: Vec<f64> = view_results.iter().map(|r| r.rms_px).collect();
    let mean_view_px = per_view.iter().sum::<f64>() / per_view.len().max(1) as f64;
    let median_view_px = median(&mut per_view.clone()).unwrap_or(0.0);
    let stray_points = all_points - count;

    // Standard deviations: the residual variance times the inverse of the reduced normal
    // matrix (the intrinsics' block of (JᵀWJ)⁻¹).
    let dof = (2 * count).saturating_sub(sol.free.len() + 6 * kept.len()).max(1) as f64;
    let sigma2 = (sol.cost / dof).max(MIN_POINT_STD_PX * MIN_POINT_STD_PX);
    // A free parameter whose variance cannot be computed (a singular normal matrix, or a
    // diagonal that rounding made negative) is not fixed by the views at all: its σ is
    // infinite, never the zero the arrays start with.
    let mut std_dev_points = [0.0; 9];
    let mut std_dev = [0.0; 9];
    for &i in &sol.free {
        (std_dev_points[i], std_dev[i]) = (f64::INFINITY, f64::INFINITY);
    }
    let mut shift_std_px = None;
    let mut sigma_groups = None;
    let mut sigma_group_s = None;
    let data: Vec<solve::ViewData> = kept
        .iter()
        .zip(&weights)
        .map(|(&v, w)| solve::ViewData { object: &views[v].object, image: &targets[v], weight: w })
        .collect();
    // A shift (and its lean) estimated from these views is one more parameter each: the
    // intrinsics' covariance is the block of the joint one, which carries their own
    // uncertainty into them.
    fn per_kept<'a>(d: &'a [Vec<[f64; 2]>], n_views: usize, kept: &[usize]) -> Option<Vec<&'a [[f64; 2]]>> {
        (d.len() == n_views).then(|| kept.iter().map(|&v| &d[v][..]).collect())
    }
    let shift_dirs = per_kept(&opts.shift_directions, views.len(), &kept);
    let extra: Vec<Option<Vec<&[[f64; 2]]>>> = opts.moves.iter().map(|m| per_kept(m, views.len(), &kept)).collect();
    let has_shift = shift_dirs.is_some();
    let move_dirs: Vec<Vec<&[[f64; 2]]>> = shift_dirs.into_iter().chain(extra.iter().flatten().cloned()).collect();
    let moves = (!move_dirs.is_empty()).then(|| solve::move_terms(&data, &k, &poses, &free, &move_dirs)).flatten();
    let n_free = sol.free.len();
    let n_moves = moves.as_ref().map_or(0, |t| t.scores.len());
    let mut hessian = nalgebra::DMatrix::<f64>::zeros(n_free + n_moves, n_free + n_moves);
    hessian.view_mut((0, 0), (n_free, n_free)).copy_from(&sol.reduced);
    if let Some(t) = &moves {
        for a in 0..n_moves {
            for c in 0..n_free {
                hessian[(c, n_free + a)] = t.cross[a][c];
                hessian[(n_free + a, c)] = t.cross[a][c];
            }
            for b in 0..n_moves {
                hessian[(n_free + a, n_free + b)] = t.curvature[(a, b)];
            }
        }
    }
    let mut estimates: Vec<Option<MoveEstimate>> = vec![None; opts.moves.len()];
    // The covariance whose correlations the parameters' covariance takes.
    let mut correlated = None;
    if let Some(inv) = hessian.try_inverse() {
        let move_scores: Vec<&[f64]> = moves.as_ref().map_or(Vec::new(), |t| t.scores.iter().map(|s| &s[..]).collect());
        let grouped = view_groups(opts, views.len(), &kept).and_then(|(groups, group_s)| {
            sigma_group_s = Some(group_s);
            grouped_covariance(&data, &kept, &k, &poses, &free, &inv, &groups, &move_scores)
        });
        sigma_groups = grouped.as_ref().map(|g| g.1);
        let grouped = grouped.map(|g| g.0);
        correlated = Some(grouped.as_ref().unwrap_or(&inv).view((0, 0), (n_free, n_free)).clone_owned());
        let sd = |c: usize| {
            let var = inv[(c, c)];
            let points = if var > 0.0 && var.is_finite() { (sigma2 * var).sqrt() } else { f64::INFINITY };
            let g = grouped.as_ref().map_or(0.0, |g| g[(c, c)].max(0.0).sqrt());
            (points, points.max(g))
        };
        for (c, &i) in sol.free.iter().enumerate() {
            (std_dev_points[i], std_dev[i]) = sd(c);
        }
        if has_shift && n_moves > 0 {
            shift_std_px = Some(sd(n_free).1);
        }
        if let Some(t) = moves.as_ref() {
            // The intrinsics and poses sit at their optimum; the moves' scores are what is
            // left of the gradient. The further moves follow the shift, those left out
            // skipped.
            let mut l = n_free + usize::from(has_shift);
            for (e, dirs) in estimates.iter_mut().zip(&extra) {
                if dirs.is_none() || l >= n_free + n_moves {
                    continue;
                }
                let step = -(0..n_moves).map(|a| inv[(l, n_free + a)] * t.scores[a].iter().sum::<f64>()).sum::<f64>();
                let std = sd(l).1;
                *e = (step.is_finite() && std.is_finite()).then_some(MoveEstimate { step, std });
                l += 1;
            }
        }
    }
    if let Some(a) = free.aspect {
        std_dev_points[1] = a * std_dev_points[0];
        std_dev[1] = a * std_dev[0];
    }
    let covariance = parameter_covariance(&std_dev, &sol.free, free.aspect, correlated.as_ref());
    let warnings = constraint_warnings(&k, &std_dev, image_size);
    Ok(Calibration {
        intrinsics: k,
        image_size,
        rms_px,
        rms_all_px,
        mean_view_px,
        median_view_px,
        std_dev,
        std_dev_points,
        covariance,
        views: view_results,
        rejected,
        stray_points,
        warnings,
        iterations: sol.iterations,
        converged: sol.converged,
        circle_radius_m: opts.circle_radius,
        shift_std_px,
        moves: estimates,
        sigma_groups,
        sigma_group_s,
        precision_bins,
    })
}

/// The homography from board points (x, y; metres) to pixels that fits them best
/// (normalised DLT), row by row; `None` for fewer than four points or a degenerate set.
pub fn fit_homography(object: &[[f64; 2]], image: &[[f64; 2]]) -> Option<[f64; 9]> {
    let object: Vec<[f64; 3]> = object.iter().map(|o| [o[0], o[1], 0.0]).collect();
    let h = init::homography(&object, image)?;
    let mut out = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            out[3 * r + c] = h[(r, c)];
        }
    }
    out.iter().all(|x| x.is_finite()).then_some(out)
}

/// Reprojection error (px) of each point of a view: board points `object` seen at `image`.
fn residuals(object: &[[f64; 3]], image: &[[f64; 2]], k: &Intrinsics, pose: &Pose) -> Vec<f64> {
    object
        .iter()
        .zip(image)
        .map(|(o, m)| match k.project(&(pose.rotation * Vector3::from(*o) + pose.translation)) {
            Some(p) => (p[0] - m[0]).hypot(p[1] - m[1]),
            None => f64::INFINITY,
        })
        .collect()
}

/// The least spread a point's residual is taken to have in the standard deviations: the
/// rounding of evcal's centres to the wire's 1/1024 px (`evcal_core::wire::fixed`), as a
/// uniform error (its σ is the step over √12). Views that fit better than that, as noise-free synthetic ones do, would
/// otherwise give every parameter a σ of almost zero however loosely the views fix it.
const MIN_POINT_STD_PX: f64 = 1.0 / (evcal_core::wire::fixed::UNITS_PER_PX as f64 * 3.464_101_615_137_754_5);

/// A parameter whose σ moves the image of a sensor corner by more than this is poorly
/// constrained, px: what the points can tell apart is far finer.
pub const CORNER_SHIFT_PX: f64 = 0.5;

/// How far moving each parameter by its `std_dev` moves the image of the sensor's far corner
/// (the bottom-right pixel), px: 0 for a fixed parameter, NaN where it cannot be told.
pub fn corner_shifts(k: &Intrinsics, std_dev: &[f64; 9], size: [u32; 2]) -> [f64; 9] {
    // The normalised point that the base camera sees at the sensor's corner.
    let (u, v) = (f64::from(size[0]) - 1.0, f64::from(size[1]) - 1.0);
    let (x, y) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
    let base = k.distort(x, y);
    std::array::from_fn(|i| {
        if std_dev[i] == 0.0 {
            return 0.0;
        }
        let mut a = k.to_array();
        a[i] += std_dev[i];
        let moved = Intrinsics::from_array(a).distort(x, y);
        (moved[0] - base[0]).hypot(moved[1] - base[1])
    })
}

/// Warnings for parameters the views leave poorly constrained ([`CORNER_SHIFT_PX`]), in one
/// line (none when none is). The pipeline calls it again once it has widened `std_dev`, so
/// that the σ it quotes is the one printed.
pub fn constraint_warnings(k: &Intrinsics, std_dev: &[f64; 9], size: [u32; 2]) -> Vec<String> {
    let shifts = corner_shifts(k, std_dev, size);
    let loose: Vec<String> = PARAMETER_NAMES
        .iter()
        .zip(std_dev)
        .zip(shifts)
        .filter(|&((_, sd), shift)| *sd > 0.0 && (shift.is_nan() || shift > CORNER_SHIFT_PX))
        .map(|((name, sd), shift)| format!("{name} ±{sd:.3e} moves it {shift:.2} px"))
        .collect();
    if loose.is_empty() {
        return Vec::new();
    }
    vec![format!(
        "poorly constrained (1σ moves the image of the sensor's corner by more than {CORNER_SHIFT_PX} px): {}; add views that fill the sensor's corners and tilt the target more",
        loose.join(", ")
    )]
}

/// Views of an asymmetric 4x11 grid (24 mm) seen by `truth` from a spread of poses, with
/// Gaussian pixel noise of `noise_px`: for examples and tests.
pub fn synthetic_views(truth: &Intrinsics, count: usize, noise_px: f64, seed: u64) -> Vec<View> {
    use rand::{RngExt, SeedableRng};
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, noise_px.max(0.0)).unwrap_or(Normal::new(0.0, 0.0).expect("valid"));
    let board: Vec<[f64; 3]> =
        (0..11).flat_map(|i| (0..4).map(move |j| [i as f64 * 0.024, (2 * j + i % 2) as f64 * 0.024, 0.0])).collect();
    let mut views = Vec::new();
    while views.len() < count {
        let (ax, ay, az) = (rng.random_range(-0.8..0.8), rng.random_range(-0.8..0.8), rng.random_range(-3.1..3.1));
        let rot = Rotation3::from_scaled_axis(Vector3::new(ax, ay, az));
        let centre = rot * Vector3::new(0.12, 0.084, 0.0);
        let depth = rng.random_range(0.35..0.6);
        let offset = Vector3::new(rng.random_range(-0.12..0.12), rng.random_range(-0.09..0.09), depth);
        let pose = Pose { rotation: rot, translation: offset - centre };
        let mut image = Vec::new();
        let mut ok = true;
        for p in &board {
            match truth.project(&(pose.rotation * Vector3::from(*p) + pose.translation)) {
                Some(m) if m[0] >= 0.0 && m[1] >= 0.0 && m[0] <= 345.0 && m[1] <= 259.0 => {
                    image.push([m[0] + normal.sample(&mut rng), m[1] + normal.sample(&mut rng)])
                }
                _ => ok = false,
            }
        }
        if ok {
            views.push(View { object: board.clone(), image });
        }
    }
    views
}
