//! Centres smoothed along their path: each board point's centre in a view, re-estimated from
//! the same board point in the windows just before and after.
//!
//! One 4000-event window gives each circle 20–90 events on two crescents, and its centre
//! carries that noise (0.2 px in good light, measured against the simulator's truth). The
//! board moves smoothly over the few windows around a view (33 ms apart), so a quadratic in
//! time fitted to one board point's centres over ±[`SmoothOptions::reach_s`] estimates where
//! it was at the view's time from five windows' events instead of one: the noise drops to
//! about 0.7 of a single window's, and a centre that went wrong (a fit to a short arc of few
//! events, off by a pixel or more) stands out from its neighbours and is replaced by what
//! they say. The fit is only made with windows on both sides of the view (no
//! extrapolation); a point without them keeps its own centre.

use crate::calib::{board_key, View};
use crate::views::ViewOrigin;

/// How centres are smoothed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothOptions {
    /// Farthest a window may be from the view's, s.
    pub reach_s: f64,
    /// Fewest centres of the board point (the view's own included) for a fit.
    pub min_samples: usize,
    /// A centre farther than this from the fit is left out of it, px (then the fit is made
    /// again, if enough remain).
    pub max_residual_px: f64,
}

impl Default for SmoothOptions {
    fn default() -> Self {
        Self { reach_s: 0.07, min_samples: 4, max_residual_px: 0.6 }
    }
}

/// What smoothing did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SmoothStats {
    /// Points re-estimated from their neighbours in time.
    pub smoothed: usize,
    /// Points kept as detected (too few windows around them).
    pub kept: usize,
    /// Of the smoothed points, those whose own centre was left out of the fit (farther than
    /// `max_residual_px` from what the windows around it say).
    pub replaced: usize,
}

/// One centre of a board point: time from the view's (in units of the reach) and position.
type Sample = (f64, [f64; 2]);

/// Quadratic fit (τ in units of the reach, for conditioning) with the worst centre left out
/// while it is farther than the limit: the fit's samples and its value at τ = 0.
fn robust_fit(mut samples: Vec<Sample>, opts: &SmoothOptions) -> Option<(Vec<Sample>, [f64; 2])> {
    loop {
        let before = samples.iter().any(|s| s.0 < 0.0);
        let after = samples.iter().any(|s| s.0 > 0.0);
        if samples.len() < opts.min_samples || !before || !after {
            return None;
        }
        let mut a = nalgebra::Matrix3::<f64>::zeros();
        let mut b = nalgebra::Matrix3x2::<f64>::zeros();
        for &(t, p) in &samples {
            let basis = [1.0, t, t * t];
            for r in 0..3 {
                for c in 0..3 {
                    a[(r, c)] += basis[r] * basis[c];
                }
                b[(r, 0)] += basis[r] * p[0];
                b[(r, 1)] += basis[r] * p[1];
            }
        }
        let x = a.lu().solve(&b)?;
        let at =
            |t: f64| [x[(0, 0)] + t * x[(1, 0)] + t * t * x[(2, 0)], x[(0, 1)] + t * x[(1, 1)] + t * t * x[(2, 1)]];
        let (worst, err) = samples
            .iter()
            .enumerate()
            .map(|(k, &(t, p))| {
                let q = at(t);
                (k, (p[0] - q[0]).hypot(p[1] - q[1]))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        if !err.is_finite() {
            return None;
        }
        if err <= opts.max_residual_px {
            let zero = at(0.0);
            return zero.iter().all(|v| v.is_finite()).then_some((samples, zero));
        }
        samples.remove(worst);
    }
}

/// `views` (in time order, paired with `origins`) with each point's centre replaced by the
/// quadratic fit through the same board point's centres in the windows within reach.
pub fn smoothed(views: &[View], origins: &[ViewOrigin], opts: &SmoothOptions) -> (Vec<View>, SmoothStats) {
    let maps: Vec<_> = views.iter().map(View::by_board_point).collect();
    let mut stats = SmoothStats::default();
    let reach = opts.reach_s.max(1e-9);
    let out = (0..views.len().min(origins.len()))
        .map(|k| {
            let t0 = origins[k].t_s;
            let near: Vec<usize> =
                (0..views.len().min(origins.len())).filter(|&j| (origins[j].t_s - t0).abs() <= opts.reach_s).collect();
            let image = views[k]
                .object
                .iter()
                .zip(&views[k].image)
                .map(|(o, here)| {
                    let samples: Vec<Sample> = near
                        .iter()
                        .filter_map(|&j| maps[j].get(&board_key(o)).map(|p| ((origins[j].t_s - t0) / reach, *p)))
                        .collect();
                    match robust_fit(samples, opts) {
                        Some((used, p)) => {
                            stats.smoothed += 1;
                            if !used.iter().any(|s| s.0 == 0.0) {
                                stats.replaced += 1;
                            }
                            p
                        }
                        None => {
                            stats.kept += 1;
                            *here
                        }
                    }
                })
                .collect();
            View { object: views[k].object.clone(), image }
        })
        .collect();
    (out, stats)
}

#[cfg(test)]
mod test {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn origin(k: usize) -> ViewOrigin {
        ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }
    }

    /// One board point on a curved path, its centres noisy: the smoothed centre is closer to
    /// the path than the detected one, on average by the factor a 5-point quadratic gives.
    #[test]
    fn noise_drops_on_a_curved_path() {
        let path = |t: f64| [100.0 + 150.0 * t + 400.0 * t * t, 80.0 - 90.0 * t + 200.0 * t * t];
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        // Uniform in ±0.35 px (σ 0.2).
        let mut noise = || rng.random_range(-0.35..0.35);
        let n = 200;
        let origins: Vec<ViewOrigin> = (0..n).map(origin).collect();
        let views: Vec<View> = origins
            .iter()
            .map(|o| {
                let p = path(o.t_s);
                View { object: vec![[0.0, 0.0, 0.0]], image: vec![[p[0] + noise(), p[1] + noise()]] }
            })
            .collect();
        let (out, stats) = smoothed(&views, &origins, &SmoothOptions::default());
        assert_eq!(stats.smoothed, n - 2);
        assert_eq!(stats.kept, 2);
        let err = |vs: &[View]| {
            let sq: f64 = vs[2..n - 2]
                .iter()
                .zip(&origins[2..n - 2])
                .map(|(v, o)| {
                    let p = path(o.t_s);
                    (v.image[0][0] - p[0]).powi(2) + (v.image[0][1] - p[1]).powi(2)
                })
                .sum();
            (sq / (n - 4) as f64).sqrt()
        };
        let ratio = err(&out) / err(&views);
        assert!(ratio > 0.6 && ratio < 0.8, "error ratio {ratio:.3}");
    }

    /// A centre two pixels off its path is replaced by what its neighbours say; the
    /// first and last views (no window on one side) keep their own.
    #[test]
    fn a_stray_centre_is_replaced() {
        let origins: Vec<ViewOrigin> = (0..7).map(origin).collect();
        let mut views: Vec<View> = origins
            .iter()
            .map(|o| View { object: vec![[0.0, 0.0, 0.0]], image: vec![[10.0 + 100.0 * o.t_s, 20.0]] })
            .collect();
        views[3].image[0][1] += 2.0;
        let (out, stats) = smoothed(&views, &origins, &SmoothOptions::default());
        assert!((out[3].image[0][1] - 20.0).abs() < 1e-9, "{:?}", out[3].image[0]);
        assert!((out[3].image[0][0] - (10.0 + 100.0 * origins[3].t_s)).abs() < 1e-9);
        assert_eq!(stats.replaced, 1);
        assert_eq!(out[0].image, views[0].image);
        assert_eq!(out[6].image, views[6].image);
    }
}
