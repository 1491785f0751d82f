//! The projection σ's tests: its parts by hand, and mrcal's validate-uncertainty on
//! synthetic views (the predicted σ against the spread of many re-solves).

use super::super::{calibrate, synthetic_views, Options};
use super::*;

fn camera() -> Intrinsics {
    Intrinsics { fx: 352.4, fy: 351.1, cx: 171.3, cy: 128.6, k1: -0.31, k2: 0.12, p1: 4e-4, p2: -3e-4, k3: 0.0 }
}

#[test]
fn unproject_finds_the_ray_that_projects_to_the_pixel() {
    let k = camera();
    for (x, y) in [(0.0, 0.0), (-0.45, -0.35), (0.45, 0.35), (0.2, -0.3)] {
        let q = k.distort(x, y);
        let xy = unproject(&k, q).expect("a ray");
        assert!((xy[0] - x).abs() < 1e-9 && (xy[1] - y).abs() < 1e-9, "{x} {y}: {xy:?}");
    }
    // k1 alone, strong: the image radius peaks at r² = −1/(3 k1) and folds back beyond.
    let fold = Intrinsics { k1: -0.5, k2: 0.0, p1: 0.0, p2: 0.0, ..k };
    let peak = (1.0f64 / 1.5).sqrt() * (1.0 - 0.5 / 1.5);
    assert!(unproject(&fold, fold.distort(0.6, 0.0)).is_some());
    assert!(unproject(&fold, [fold.cx + fold.fx * (peak + 0.01), fold.cy]).is_none());
}

#[test]
fn sigma_is_each_parameters_pixel_shift_with_the_ray_held() {
    let k = Intrinsics { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, ..camera() };
    let var = |i: usize, s: f64| {
        let mut c = [[0.0; 9]; 9];
        c[i][i] = s * s;
        c
    };
    // The principal point moves every pixel alike.
    for q in [[0.0, 0.0], [171.3, 128.6], [345.0, 259.0]] {
        assert!((projection_sigma_at(&k, &var(2, 0.5), q) - 0.5).abs() < 1e-9);
    }
    // fx moves a pixel in proportion to its distance from the centre: u − cx = fx·x.
    let q = [300.0, 40.0];
    let want = 0.7 * (q[0] - k.cx) / k.fx;
    assert!((projection_sigma_at(&k, &var(0, 0.7), q) - want).abs() < 1e-9);
    // cx and fx fully anti-correlated so that a pixel stays put: σ 0 there, twice elsewhere.
    let mut c = [[0.0; 9]; 9];
    let (sfx, scx) = (1.0, (q[0] - k.cx) / k.fx);
    c[0][0] = sfx * sfx;
    c[2][2] = scx * scx;
    c[0][2] = -sfx * scx;
    c[2][0] = -sfx * scx;
    assert!(projection_sigma_at(&k, &c, q) < 1e-9);
    let mirrored = [2.0 * k.cx - q[0], q[1]];
    assert!((projection_sigma_at(&k, &c, mirrored) - 2.0 * scx).abs() < 1e-9);
    // The worst direction: σ 0.3 along x and 0.4 along y give 0.4, not their sum.
    let mut c = var(2, 0.3);
    c[3][3] = 0.16;
    assert!((projection_sigma_at(&k, &c, [10.0, 10.0]) - 0.4).abs() < 1e-9);
    // An unbounded parameter the pixel depends on: unbounded; one it does not: no matter.
    let mut c = var(2, 0.3);
    c[4][4] = f64::INFINITY;
    assert!(projection_sigma_at(&k, &c, [10.0, 10.0]).is_infinite());
    assert!((projection_sigma_at(&k, &c, [k.cx, k.cy]) - 0.3).abs() < 1e-9);
}

#[test]
fn the_covered_region_is_the_boards_outlines_and_the_figures_their_nodes() {
    // One board seen as a 5 x 4 grid of points from (100, 80) to (180, 140).
    let board: Vec<[f64; 2]> =
        (0..5).flat_map(|i| (0..4).map(move |j| [100.0 + 20.0 * i as f64, 80.0 + 20.0 * j as f64])).collect();
    let line: Vec<[f64; 2]> = (0..5).map(|i| [10.0 * i as f64, 10.0 * i as f64]).collect();
    let covered = Covered::of([&board[..], &line[..]]);
    for inside in [[140.0, 110.0], [100.0, 80.0], [180.0, 140.0], [150.0, 80.0]] {
        assert!(covered.contains(inside), "{inside:?}");
    }
    for outside in [[99.0, 110.0], [140.0, 141.0], [20.0, 20.0], [0.0, 0.0]] {
        assert!(!covered.contains(outside), "{outside:?}");
    }
    let f = SigmaFigures::of((1..=100).map(f64::from)).expect("figures");
    assert_eq!((f.worst_px, f.p95_px), (100.0, 95.0));
    let f = SigmaFigures::of([0.1, f64::NAN]).expect("figures");
    assert_eq!((f.worst_px, f.p95_px), (f64::INFINITY, f64::INFINITY));
    assert!(SigmaFigures::of([]).is_none());
    // The grid: nodes every 8 px up to the last pixel; σ of the principal point alone.
    let k = camera();
    let mut c = [[0.0; 9]; 9];
    c[2][2] = 0.04;
    let s = ProjectionSigma::with(&k, &c, [346, 260], &covered, 8).expect("a grid");
    assert_eq!((s.columns, s.rows, s.values.len(), s.values[0].len()), (44, 33, 33, 44));
    assert!(s.values.iter().flatten().all(|&v| (v - 0.2).abs() < 1e-9));
    // Nodes (13..=22, 10..=17) lie within the board: x 104…176, y 80…136.
    assert_eq!(s.covered.iter().flatten().filter(|&&c| c).count(), 10 * 8);
    assert!(s.covered[10][13] && !s.covered[10][12] && !s.covered[18][13]);
    assert!(s.within_points.is_some());
    assert!(ProjectionSigma::with(&k, &c, [346, 260], &Covered::default(), 8).unwrap().within_points.is_none());
    assert!(ProjectionSigma::with(&k, &c, [346, 260], &covered, 0).is_none());
    let line = s.summary();
    assert!(line.contains("covered p95 0.20 px, worst 0.20 px") && line.contains("whole sensor p95 0.20 px"), "{line}");
    assert!(!line.contains("no ray"), "{line}");
    // A model that folds back within the sensor (the image radius peaks at 143 px): no ray,
    // an unbounded σ, at the corners, and the line says so.
    let fold = Intrinsics { k1: -0.9, k2: 0.0, p1: 0.0, p2: 0.0, ..k };
    let s = ProjectionSigma::with(&fold, &c, [346, 260], &covered, 8).expect("a grid");
    assert!(s.values[0][0].is_infinite() && (s.values[16][21] - 0.2).abs() < 1e-9);
    assert!(s.sensor.worst_px.is_infinite() && s.within_points.is_some_and(|f| f.worst_px.is_finite()));
    let line = s.summary();
    assert!(line.contains("worst unbounded (") && line.contains("no ray at"), "{line}");
}

/// The band the spread of the re-solves must fall in, as a multiple of the predicted σ.
/// With 40 re-solves a standard deviation is itself uncertain by 1/√(2·39) = 11 %: the band
/// is that about three times over, in both directions, so that a σ too large fails as a σ
/// too small does.
const SPREAD_OVER_SIGMA: std::ops::RangeInclusive<f64> = 0.7..=1.43;

/// mrcal's validate-uncertainty: views of a known camera, projected exactly, with ideal
/// Gaussian noise of known σ drawn anew for each of 40 re-solves. At pixels from the centre
/// to the corners, the spread of where each re-solve puts the ray the true camera sees there
/// (the worst direction of their 2 × 2 covariance) is the predicted σ within
/// [`SPREAD_OVER_SIGMA`]; three times the prediction, or a third of it, would not be.
#[test]
fn the_predicted_sigma_is_the_spread_of_resolves_of_ideal_noise() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let truth = camera();
    let exact = synthetic_views(&truth, 16, 0.0, 11);
    let noise = Normal::new(0.0, 0.3).expect("a normal");
    let opts = Options { robust: false, ..Options::default() };
    let pixels = [[171.0, 129.0], [60.0, 200.0], [300.0, 50.0], [16.0, 16.0], [330.0, 245.0]];
    let rays: Vec<[f64; 2]> = pixels.iter().map(|&q| unproject(&truth, q).expect("a ray")).collect();
    let (mut seen, mut predicted) = (vec![Vec::new(); pixels.len()], vec![Vec::new(); pixels.len()]);
    const RESOLVES: usize = 60;
    for trial in 0..RESOLVES {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(500 + trial as u64);
        let views: Vec<View> = exact
            .iter()
            .map(|v| View {
                object: v.object.clone(),
                image: v.image.iter().map(|m| [m[0] + noise.sample(&mut rng), m[1] + noise.sample(&mut rng)]).collect(),
            })
            .collect();
        let cal = calibrate(&views, [346, 260], &opts).expect("a calibration");
        for (p, (&q, xy)) in pixels.iter().zip(&rays).enumerate() {
            seen[p].push(cal.intrinsics.distort(xy[0], xy[1]));
            predicted[p].push(projection_sigma_at(&cal.intrinsics, &cal.covariance, q));
        }
    }
    for (p, q) in pixels.iter().enumerate() {
        // What a re-solve typically predicts: now and then one's k3 folds its model back
        // short of a corner, where it then predicts no σ at all.
        let typical = crate::stats::median(&mut predicted[p]).expect("predictions");
        let n = seen[p].len() as f64;
        let mean = seen[p].iter().fold([0.0; 2], |m, s| [m[0] + s[0] / n, m[1] + s[1] / n]);
        let mut c = [[0.0; 2]; 2];
        for s in &seen[p] {
            let d = [s[0] - mean[0], s[1] - mean[1]];
            for r in 0..2 {
                for t in 0..2 {
                    c[r][t] += d[r] * d[t] / (n - 1.0);
                }
            }
        }
        let (m, h) = (0.5 * (c[0][0] + c[1][1]), 0.5 * (c[0][0] - c[1][1]));
        let spread = (m + h.hypot(c[0][1])).sqrt();
        let ratio = spread / typical;
        assert!(
            SPREAD_OVER_SIGMA.contains(&ratio),
            "at {q:?}: spread {spread:.4} px over predicted σ {:.4} px = {ratio:.2}",
            typical
        );
        eprintln!("at {q:?}: spread {spread:.4} px over predicted σ {typical:.4} px = {ratio:.2}");
        assert!(!SPREAD_OVER_SIGMA.contains(&(ratio / 3.0)) && !SPREAD_OVER_SIGMA.contains(&(ratio * 3.0)));
    }
}

#[test]
fn the_covariance_agrees_with_the_printed_sigma_and_widens_as_they_do() {
    let views = synthetic_views(&camera(), 12, 0.2, 5);
    let times: Vec<f64> = (0..views.len()).map(|i| 0.6 * i as f64).collect();
    let grouped = Options { view_times: times, ..Options::default() };
    let square = Options { fix_aspect_ratio: true, fix_k3: true, ..Options::default() };
    for (what, opts) in [("points", Options::default()), ("grouped", grouped), ("square pixels, k3 fixed", square)] {
        let mut cal = calibrate(&views, [346, 260], &opts).expect("a calibration");
        let (c, sd) = (cal.covariance, cal.std_dev);
        for i in 0..9 {
            assert!((c[i][i] - sd[i] * sd[i]).abs() <= 1e-12 * sd[i] * sd[i], "{what}: {i}: {} {}", c[i][i], sd[i]);
            for j in 0..9 {
                assert_eq!(c[i][j], c[j][i], "{what}: {i} {j}");
                assert!(c[i][j].abs() <= sd[i] * sd[j] * (1.0 + 1e-12), "{what}: {i} {j}");
            }
        }
        // Parameters move together: the correlations are not left out.
        assert!((0..9).any(|i| (0..i).any(|j| c[i][j].abs() > 0.3 * sd[i] * sd[j])), "{what}: {c:?}");
        if opts.fix_aspect_ratio {
            assert!((c[0][1] - sd[0] * sd[1]).abs() <= 1e-12 * c[0][1], "{what}: fy follows fx");
            assert!(c[8].iter().all(|&x| x == 0.0), "{what}: k3 fixed");
        } else {
            assert!(c[0][1].abs() < sd[0] * sd[1], "{what}");
        }
        let change = [0.5, 0.4, -0.3, 0.2, 1e-3, 0.0, 0.0, 0.0, 0.0];
        cal.widen(change);
        for i in 0..9 {
            assert!((cal.std_dev[i] - sd[i].hypot(change[i])).abs() < 1e-12, "{what}: {i}");
            for j in 0..9 {
                assert!((cal.covariance[i][j] - c[i][j] - change[i] * change[j]).abs() < 1e-12, "{what}: {i} {j}");
            }
        }
    }
}
