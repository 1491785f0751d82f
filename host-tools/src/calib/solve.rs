//! Levenberg–Marquardt over the intrinsics and every view's pose, with the block structure
//! of the problem: each pose touches only its own view's points, so the normal equations are
//! an arrow matrix, and the Schur complement onto the intrinsics leaves one small system per
//! step whatever the number of views.

use super::model::{project, Intrinsics, Pose};
use nalgebra::{DMatrix, SMatrix, SVector};

type M6 = SMatrix<f64, 6, 6>;
type V6 = SVector<f64, 6>;

/// What the solver may change: the intrinsic parameters that are free, and how fy follows fx
/// when the aspect ratio is fixed.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Free {
    /// Which of fx, fy, cx, cy, k1, k2, p1, p2, k3 move (with a fixed aspect ratio, fy is not
    /// free but follows fx).
    pub mask: [bool; 9],
    /// `Some(fy / fx)` when the aspect ratio is fixed.
    pub aspect: Option<f64>,
}

impl Free {
    /// The indices of the free intrinsic parameters.
    fn indices(&self) -> ([usize; 9], usize) {
        let mut idx = [0usize; 9];
        let mut n = 0;
        for (i, &f) in self.mask.iter().enumerate() {
            if f && !(i == 1 && self.aspect.is_some()) {
                idx[n] = i;
                n += 1;
            }
        }
        (idx, n)
    }
}

/// One view's data as the solver sees it.
pub(crate) struct ViewData<'a> {
    pub object: &'a [[f64; 3]],
    pub image: &'a [[f64; 2]],
    /// Per-point weight (1 for plain least squares).
    pub weight: &'a [f64],
}

/// The state after a solve.
pub(crate) struct Solution {
    pub intrinsics: Intrinsics,
    pub poses: Vec<Pose>,
    /// Weighted sum of squared residuals, px².
    pub cost: f64,
    /// The Schur complement onto the free intrinsics at the solution (undamped JᵀWJ reduced):
    /// its inverse is their covariance up to the residual variance.
    pub reduced: nalgebra::DMatrix<f64>,
    /// The free intrinsics' indices (rows of `reduced`).
    pub free: Vec<usize>,
    pub iterations: usize,
    pub converged: bool,
}

/// Accumulated normal equations at one point of the parameter space.
struct Normal {
    /// JᵀWJ over the free intrinsics (9 x 9, only the leading `n` used).
    u: SMatrix<f64, 9, 9>,
    g: SVector<f64, 9>,
    /// Per view: JᵀWJ of the pose, JᵀWJ between intrinsics and pose, gradient of the pose.
    v: Vec<M6>,
    w: Vec<SMatrix<f64, 9, 6>>,
    gv: Vec<V6>,
    /// Per view: its share of `g`.
    gt: Vec<SVector<f64, 9>>,
    cost: f64,
}

/// The Jacobian row of the free intrinsics for one residual row.
fn free_row(d: &[f64; 9], free: &Free, idx: &[usize]) -> SVector<f64, 9> {
    let mut out = SVector::<f64, 9>::zeros();
    for (c, &i) in idx.iter().enumerate() {
        out[c] = d[i];
        // fy = a·fx: a change of fx moves fy too.
        if i == 0 {
            if let Some(a) = free.aspect {
                out[c] += a * d[1];
            }
        }
    }
    out
}

fn normal(views: &[ViewData], k: &Intrinsics, poses: &[Pose], free: &Free) -> Option<Normal> {
    let (idx, n) = free.indices();
    let idx = &idx[..n];
    let mut out = Normal {
        u: SMatrix::zeros(),
        g: SVector::zeros(),
        v: Vec::with_capacity(views.len()),
        w: Vec::with_capacity(views.len()),
        gv: Vec::with_capacity(views.len()),
        gt: Vec::with_capacity(views.len()),
        cost: 0.0,
    };
    for (view, pose) in views.iter().zip(poses) {
        let (mut v, mut w, mut gv) = (M6::zeros(), SMatrix::<f64, 9, 6>::zeros(), V6::zeros());
        let mut gt = SVector::<f64, 9>::zeros();
        for ((o, m), &wt) in view.object.iter().zip(view.image).zip(view.weight) {
            let p = project(k, pose, o)?;
            for (r, &mr) in m.iter().enumerate() {
                let res = p.pixel[r] - mr;
                let jt = free_row(&p.d_intrinsics[r], free, idx);
                let jp = V6::from_row_slice(&p.d_pose[r]);
                out.u += wt * jt * jt.transpose();
                out.g += wt * res * jt;
                gt += wt * res * jt;
                v += wt * jp * jp.transpose();
                w += wt * jt * jp.transpose();
                gv += wt * res * jp;
                out.cost += wt * res * res;
            }
        }
        out.v.push(v);
        out.w.push(w);
        out.gv.push(gv);
        out.gt.push(gt);
    }
    out.cost.is_finite().then_some(out)
}

fn cost(views: &[ViewData], k: &Intrinsics, poses: &[Pose]) -> Option<f64> {
    let mut c = 0.0;
    for (view, pose) in views.iter().zip(poses) {
        for ((o, m), &wt) in view.object.iter().zip(view.image).zip(view.weight) {
            let p = k.project(&(pose.rotation * nalgebra::Vector3::from(*o) + pose.translation))?;
            c += wt * ((p[0] - m[0]).powi(2) + (p[1] - m[1]).powi(2));
        }
    }
    c.is_finite().then_some(c)
}

/// The reduced system S Δθ = r of one damped step: S = U − Σ W V⁻¹ Wᵀ, r = −g + Σ W V⁻¹ gv.
fn reduce(nm: &Normal, n: usize, lambda: f64) -> Option<(nalgebra::DMatrix<f64>, nalgebra::DVector<f64>, Vec<M6>)> {
    let mut s = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut r = nalgebra::DVector::<f64>::zeros(n);
    for i in 0..n {
        for j in 0..n {
            s[(i, j)] = nm.u[(i, j)];
        }
        s[(i, i)] += lambda * nm.u[(i, i)].max(1e-12);
        r[i] = -nm.g[i];
    }
    let mut vinv = Vec::with_capacity(nm.v.len());
    for ((v, w), gv) in nm.v.iter().zip(&nm.w).zip(&nm.gv) {
        let mut vd = *v;
        for d in 0..6 {
            vd[(d, d)] += lambda * v[(d, d)].max(1e-12);
        }
        let vi = vd.try_inverse()?;
        let wvi = w * vi; // 9 x 6
        for i in 0..n {
            for j in 0..n {
                let mut acc = 0.0;
                for c in 0..6 {
                    acc += wvi[(i, c)] * w[(j, c)];
                }
                s[(i, j)] -= acc;
            }
            let mut acc = 0.0;
            for c in 0..6 {
                acc += wvi[(i, c)] * gv[c];
            }
            r[i] += acc;
        }
        vinv.push(vi);
    }
    Some((s, r, vinv))
}

/// Levenberg–Marquardt from a start; stops when a step changes the cost by less than
/// `tolerance` relative, after `max_iterations`, or when no damping lowers the cost.
pub(crate) fn solve(
    views: &[ViewData],
    start: Intrinsics,
    poses: Vec<Pose>,
    free: &Free,
    max_iterations: usize,
    tolerance: f64,
) -> Option<Solution> {
    let (idx, n) = free.indices();
    let idx = idx[..n].to_vec();
    let mut k = start;
    let mut poses = poses;
    let mut lambda = 1e-3;
    let mut nm = normal(views, &k, &poses, free)?;
    let mut converged = false;
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        let Some((s, r, vinv)) = reduce(&nm, n, lambda) else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
            continue;
        };
        let Some(dtheta) = s.clone().cholesky().map(|c| c.solve(&r)).or_else(|| s.lu().solve(&r)) else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
            continue;
        };
        // Back-substitute each pose: Δω = V⁻¹(−gv − Wᵀ Δθ).
        let mut trial_k = k.to_array();
        for (c, &i) in idx.iter().enumerate() {
            trial_k[i] += dtheta[c];
        }
        if let Some(a) = free.aspect {
            trial_k[1] = a * trial_k[0];
        }
        let trial_k = Intrinsics::from_array(trial_k);
        let mut trial_poses = Vec::with_capacity(poses.len());
        for (((pose, w), gv), vi) in poses.iter().zip(&nm.w).zip(&nm.gv).zip(&vinv) {
            let mut rhs = -gv;
            for c in 0..6 {
                let mut acc = 0.0;
                for i in 0..n {
                    acc += w[(i, c)] * dtheta[i];
                }
                rhs[c] -= acc;
            }
            let d = vi * rhs;
            trial_poses.push(pose.moved(&[d[0], d[1], d[2], d[3], d[4], d[5]]));
        }
        match cost(views, &trial_k, &trial_poses) {
            Some(c) if c <= nm.cost => {
                let relative = (nm.cost - c) / nm.cost.max(1e-300);
                k = trial_k;
                poses = trial_poses;
                lambda = (lambda * 0.2).max(1e-15);
                nm = normal(views, &k, &poses, free)?;
                if relative < tolerance {
                    converged = true;
                    break;
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > 1e12 {
                    // No damping lowers the cost: a minimum to the precision of the data.
                    converged = true;
                    break;
                }
            }
        }
    }
    let (reduced, _, _) = reduce(&nm, n, 0.0)?;
    Some(Solution { intrinsics: k, poses, cost: nm.cost, reduced, free: idx, iterations, converged })
}

/// Moves of every detected point along directions of its own, each by one amount shared
/// by all views and estimated from these same views (the edge shift and its lean across
/// the motion, see `crate::views::edge_shift`): their terms in the normal equations, each
/// pose profiled out. With them each move counts as one more parameter of the solve when
/// its uncertainty is carried into the intrinsics'.
pub(crate) struct MoveTerms {
    /// Per move, per view: the move's score, `Σ w r·∂r/∂δ − bᵀ V⁻¹ gv` (`b` its cross term
    /// with the view's pose).
    pub scores: Vec<Vec<f64>>,
    /// Per move: its cross term with the free intrinsics (the leading `n` entries),
    /// `Σ (Σ w Jθᵀ ∂r/∂δ − W V⁻¹ b)`.
    pub cross: Vec<SVector<f64, 9>>,
    /// The moves' curvature, `Σ (Σ w ∂r/∂δₐ·∂r/∂δᵦ − bₐᵀ V⁻¹ bᵦ)`.
    pub curvature: DMatrix<f64>,
}

/// [`MoveTerms`] of the views' points moved by `δₐ · moves[a][view][point]` for each move
/// `a` (a residual is model minus detected, so `∂r/∂δ = −dir`). `None` when a pose block is
/// singular or a point cannot be projected.
pub(crate) fn move_terms(
    views: &[ViewData],
    k: &Intrinsics,
    poses: &[Pose],
    free: &Free,
    moves: &[Vec<&[[f64; 2]]>],
) -> Option<MoveTerms> {
    let (idx, n) = free.indices();
    let idx = &idx[..n];
    let m = moves.len();
    let mut out = MoveTerms {
        scores: vec![Vec::with_capacity(views.len()); m],
        cross: vec![SVector::zeros(); m],
        curvature: DMatrix::zeros(m, m),
    };
    for (j, (view, pose)) in views.iter().zip(poses).enumerate() {
        let (mut v, mut gv, mut w) = (M6::zeros(), V6::zeros(), SMatrix::<f64, 9, 6>::zeros());
        let mut b = vec![V6::zeros(); m];
        let mut score = vec![0.0; m];
        let mut cross = vec![SVector::<f64, 9>::zeros(); m];
        let mut curv = DMatrix::<f64>::zeros(m, m);
        for (i, ((o, mo), &wt)) in view.object.iter().zip(view.image).zip(view.weight).enumerate() {
            let p = project(k, pose, o)?;
            for (r, &mr) in mo.iter().enumerate() {
                let res = p.pixel[r] - mr;
                let jt = free_row(&p.d_intrinsics[r], free, idx);
                let jp = V6::from_row_slice(&p.d_pose[r]);
                v += wt * jp * jp.transpose();
                w += wt * jt * jp.transpose();
                gv += wt * res * jp;
                let dr: Vec<f64> =
                    moves.iter().map(|d| d.get(j).and_then(|d| d.get(i)).map_or(0.0, |d| -d[r])).collect();
                for a in 0..m {
                    b[a] += wt * dr[a] * jp;
                    score[a] += wt * res * dr[a];
                    cross[a] += wt * dr[a] * jt;
                    for c in 0..m {
                        curv[(a, c)] += wt * dr[a] * dr[c];
                    }
                }
            }
        }
        let vi = v.try_inverse()?;
        let vib: Vec<V6> = b.iter().map(|b| vi * b).collect();
        for a in 0..m {
            out.scores[a].push(score[a] - vib[a].dot(&gv));
            out.cross[a] += cross[a] - w * vib[a];
            for c in 0..m {
                out.curvature[(a, c)] += curv[(a, c)] - b[a].dot(&vib[c]);
            }
        }
    }
    Some(out)
}

/// Each view's score for the free intrinsics with its pose profiled out, `gθ − W V⁻¹ gv`
/// (the first `n` entries, `n` the number of free intrinsics): at a solution the scores
/// sum to zero, and how they scatter tells how the views' errors move the intrinsics
/// (the "meat" of a sandwich covariance). `None` when a pose block is singular.
pub(crate) fn view_scores(
    views: &[ViewData],
    k: &Intrinsics,
    poses: &[Pose],
    free: &Free,
) -> Option<Vec<SVector<f64, 9>>> {
    let nm = normal(views, k, poses, free)?;
    nm.gt
        .iter()
        .zip(&nm.v)
        .zip(&nm.w)
        .zip(&nm.gv)
        .map(|(((gt, v), w), gv)| Some(gt - w * (v.try_inverse()? * gv)))
        .collect()
}
