//! The intrinsics' covariance from groups of views (stretches of the recording), so that
//! centre errors that persist over neighbouring windows are not counted as independent.

use super::*;

/// Each kept view's group (by index in the views given; the others' `u32::MAX`), grouped
/// by stretches of the recording as long as the kept views' times ask for
/// ([`group_seconds`]), in each of [`GROUP_PLACEMENTS`] placements of the groups' bounds;
/// and that stretch, s. `None` without one time per view.
pub(super) fn view_groups(opts: &Options, n_views: usize, kept: &[usize]) -> Option<(Vec<Vec<u32>>, f64)> {
    if opts.view_times.len() != n_views || n_views == 0 {
        return None;
    }
    let times: Vec<f64> = kept.iter().map(|&v| opts.view_times[v]).collect();
    let group_s = group_seconds(&times);
    // Led placements may cut a burst of views shorter than a stretch in two, which counts
    // one moment's error twice: where the groups are few, each one matters, and the groups
    // follow the views alone.
    let place = |p: usize| {
        let (of_kept, count) = groups_of(&times, group_s, group_s * p as f64 / GROUP_PLACEMENTS as f64);
        let mut groups = vec![u32::MAX; n_views];
        for (&v, g) in kept.iter().zip(of_kept) {
            groups[v] = g;
        }
        (groups, count)
    };
    let (first, count) = place(0);
    let mut placements = vec![first];
    if count >= GROUPS_WANTED {
        placements.extend((1..GROUP_PLACEMENTS).map(|p| place(p).0));
    }
    Some((placements, group_s))
}

/// The free parameters' covariance from the scatter of the groups of views, `S⁻¹ B S⁻¹`
/// (`inv` = S⁻¹, the inverse reduced normal matrix; B the sum over groups of the outer
/// product of each group's summed score, times G / (G − 1) for the one degree of freedom
/// the solution takes), widened by [`few_groups_factor`], and averaged over the placements
/// of the groups' bounds given (each a group per view) that make at least [`MIN_GROUPS`]
/// groups. The parameters are the free intrinsics, then the shared shift when
/// `shift_scores` (per kept view) are given; with the fewest groups of a placement used.
/// `None` without placements, or with none of enough groups.
#[allow(clippy::too_many_arguments)]
pub(super) fn grouped_covariance(
    data: &[solve::ViewData],
    kept: &[usize],
    k: &Intrinsics,
    poses: &[Pose],
    free: &solve::Free,
    inv: &nalgebra::DMatrix<f64>,
    placements: &[Vec<u32>],
    move_scores: &[&[f64]],
) -> Option<(nalgebra::DMatrix<f64>, usize)> {
    if placements.is_empty() {
        return None;
    }
    let scores = solve::view_scores(data, k, poses, free)?;
    let n = inv.nrows();
    let n_intrinsics = n - move_scores.len();
    let mut meat = nalgebra::DMatrix::<f64>::zeros(n, n);
    let (mut used, mut fewest) = (0usize, usize::MAX);
    for groups in placements {
        let mut sums: std::collections::BTreeMap<u32, nalgebra::DVector<f64>> = std::collections::BTreeMap::new();
        for (j, (&v, s)) in kept.iter().zip(&scores).enumerate() {
            let g = *groups.get(v)?;
            let sum = sums.entry(g).or_insert_with(|| nalgebra::DVector::zeros(n));
            for c in 0..n_intrinsics {
                sum[c] += s[c];
            }
            for (a, t) in move_scores.iter().enumerate() {
                sum[n_intrinsics + a] += *t.get(j)?;
            }
        }
        let count = sums.len();
        if count < MIN_GROUPS {
            continue;
        }
        let mut b = nalgebra::DMatrix::<f64>::zeros(n, n);
        for s in sums.values() {
            b += s * s.transpose();
        }
        meat += b * (count as f64 / (count - 1) as f64 * few_groups_factor(count).powi(2));
        used += 1;
        fewest = fewest.min(count);
    }
    if used == 0 {
        return None;
    }
    meat /= used as f64;
    Some((inv * meat * inv, fewest))
}

/// The nine parameters' covariance ([`Calibration::covariance`]): `std_dev` on the diagonal,
/// the correlations of `source` (the covariance, or any multiple of it, of the `free`
/// parameters, in their order) off it. With a fixed aspect ratio fy follows fx, and is
/// correlated with it fully. A parameter with an unbounded σ keeps its infinite variance and
/// no correlation, so that what it moves stays unbounded rather than NaN.
pub(super) fn parameter_covariance(
    std_dev: &[f64; 9],
    free: &[usize],
    aspect: Option<f64>,
    source: Option<&nalgebra::DMatrix<f64>>,
) -> [[f64; 9]; 9] {
    let slot = |i: usize| {
        let of = |p: usize| free.iter().position(|&f| f == p);
        of(i).or_else(|| if i == 1 && aspect.is_some() { of(0) } else { None })
    };
    let correlation = |a: usize, b: usize| {
        source.map_or(0.0, |m| {
            let scale = (m[(a, a)] * m[(b, b)]).sqrt();
            if scale > 0.0 && scale.is_finite() {
                (0.5 * (m[(a, b)] + m[(b, a)]) / scale).clamp(-1.0, 1.0)
            } else {
                0.0
            }
        })
    };
    let mut cov = [[0.0; 9]; 9];
    for i in 0..9 {
        for j in 0..=i {
            let (Some(a), Some(b)) = (slot(i), slot(j)) else { continue };
            let (si, sj) = (std_dev[i], std_dev[j]);
            if i == j {
                cov[i][i] = si * si;
            } else if si.is_finite() && sj.is_finite() {
                cov[i][j] = correlation(a, b) * si * sj;
                cov[j][i] = cov[i][j];
            }
        }
    }
    cov
}
