//! Statistics of the residuals: RMS, and the weights by each point's precision.

use super::*;
use crate::stats::median;

pub(super) fn rms(e: &[f64]) -> f64 {
    (e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64).sqrt()
}

/// Most bins of [`precision_weights`].
pub(super) const PRECISION_BINS: usize = 8;
/// Fewest points in a bin of [`precision_weights`]: the median of fewer square errors is
/// itself too uncertain to weigh points by.
pub(super) const MIN_POINTS_PER_PRECISION_BIN: usize = 100;

/// Per point of `errors` (per view, per point, px), a weight in inverse proportion to the
/// square error of the points whose precision figures (`hints`, the same shape) are about
/// its own: the points, sorted by figure, fall into up to [`PRECISION_BINS`] bins of equal
/// count (points of one figure in one bin), each bin's square error is the median of its
/// points' (strays do not count), and a larger figure is never taken to err more (the
/// bins' errors are pooled where they would). Weights are 1 where a bin errs as all points
/// do. Also each bin, as [`Calibration::precision_bins`] gives them. `None` for too few
/// points to tell bins apart, or errors that give no weight.
pub(super) fn precision_weights(errors: &[Vec<f64>], hints: &[&[f64]]) -> Option<(Vec<Vec<f64>>, Vec<PrecisionBin>)> {
    let mut points: Vec<(f64, f64)> = errors
        .iter()
        .zip(hints)
        .flat_map(|(e, h)| h.iter().zip(e).map(|(&h, &x)| (h, x * x)))
        .filter(|(h, x2)| h.is_finite() && x2.is_finite())
        .collect();
    let bins = PRECISION_BINS.min(points.len() / MIN_POINTS_PER_PRECISION_BIN);
    if bins < 2 {
        return None;
    }
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Each bin's upper figure, so that equal figures share a bin.
    let mut uppers: Vec<f64> = (1..bins).map(|b| points[b * points.len() / bins].0).collect();
    uppers.dedup();
    let bin_of = |h: f64| uppers.partition_point(|&u| u <= h);
    let mut square: Vec<Vec<f64>> = vec![Vec::new(); uppers.len() + 1];
    for &(h, x2) in &points {
        square[bin_of(h)].push(x2);
    }
    // (median square error, points) per bin, pooled from the low figures up wherever a
    // larger figure's bin errs more than a smaller one's.
    let mut pooled: Vec<(f64, usize, usize)> = Vec::new();
    for (b, s) in square.iter_mut().enumerate() {
        if s.is_empty() {
            continue;
        }
        let mut block = (median(s)?, s.len(), b);
        while let Some(&(m, n, first)) = pooled.last() {
            if m >= block.0 {
                break;
            }
            pooled.pop();
            block = ((m * n as f64 + block.0 * block.1 as f64) / (n + block.1) as f64, n + block.1, first);
        }
        pooled.push(block);
    }
    let mut all: Vec<f64> = points.iter().map(|p| p.1).collect();
    let reference = median(&mut all)?;
    let mut weight_of_bin = vec![1.0; square.len()];
    for (k, &(m, _, first)) in pooled.iter().enumerate() {
        let last = pooled.get(k + 1).map_or(square.len(), |p| p.2);
        for w in &mut weight_of_bin[first..last] {
            *w = reference / m;
        }
    }
    if weight_of_bin.iter().any(|w| !w.is_finite() || *w <= 0.0) {
        return None;
    }
    let bins_used = (0..square.len())
        .filter(|&b| !square[b].is_empty())
        .map(|b| PrecisionBin { from: if b == 0 { points[0].0 } else { uppers[b - 1] }, weight: weight_of_bin[b] })
        .collect();
    let weights = hints
        .iter()
        .map(|h| h.iter().map(|&h| if h.is_finite() { weight_of_bin[bin_of(h)] } else { 1.0 }).collect())
        .collect();
    Some((weights, bins_used))
}
