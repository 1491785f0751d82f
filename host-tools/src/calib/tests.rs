//! The calibration's tests: synthetic views, robustness, σ, the groups of views.

use super::*;

fn truth() -> Intrinsics {
    Intrinsics { fx: 352.4, fy: 351.1, cx: 171.3, cy: 128.6, k1: -0.31, k2: 0.12, p1: 4e-4, p2: -3e-4, k3: 0.0 }
}

#[test]
fn precision_weights_follow_the_error_of_points_alike_and_never_favour_a_noisier_figure() {
    // 8 figures, 150 points each; points of figures 10 and 20 err three times as much.
    let hints: Vec<Vec<f64>> = (0..8).map(|b| vec![10.0 * (b + 1) as f64; 150]).collect();
    let errors = |err: &dyn Fn(usize) -> f64| -> Vec<Vec<f64>> {
        (0..8).map(|b| (0..150).map(|i| err(b) * (0.8 + 0.4 * i as f64 / 150.0)).collect()).collect()
    };
    let h: Vec<&[f64]> = hints.iter().map(|h| &h[..]).collect();
    let (w, bins) = precision_weights(&errors(&|b| if b < 2 { 0.3 } else { 0.1 }), &h).expect("weights");
    assert_eq!(bins.iter().map(|b| b.from).collect::<Vec<_>>(), (1..=8).map(|b| 10.0 * b as f64).collect::<Vec<_>>());
    assert_eq!(bins[0].weight, w[0][0]);
    let ratio = w[0][0] / w[7][0];
    assert!((ratio - 1.0 / 9.0).abs() < 0.01, "the noisy figures weigh a ninth: {ratio}");
    assert!(w.iter().all(|v| v.iter().all(|&x| x == v[0])), "one weight per figure");
    assert_eq!(w[0][0], w[1][0]);
    assert_eq!(w[2][0], w[7][0]);
    // Errors that grow with the figure say nothing the figure can be trusted for: the
    // bins are pooled and every point weighs alike.
    let (w, _) = precision_weights(&errors(&|b| 0.1 + 0.01 * b as f64), &h).expect("weights");
    assert!(
        w.iter().flatten().all(|&x| (x - w[0][0]).abs() < 1e-12),
        "{:?}",
        w.iter().map(|v| v[0]).collect::<Vec<_>>()
    );
    // Too few points to tell bins apart.
    let few: Vec<&[f64]> = hints.iter().map(|h| &h[..20]).collect();
    let few_errors: Vec<Vec<f64>> = errors(&|_| 0.1).iter().map(|e| e[..20].to_vec()).collect();
    assert!(precision_weights(&few_errors, &few).is_none());
}

#[test]
fn points_the_hints_call_imprecise_weigh_less_and_the_solve_is_firmer() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let t = truth();
    let exact = synthetic_views(&t, 60, 0.0, 4);
    // Every other point fitted to few events, six times as noisy.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let (loose, firm) = (Normal::new(0.0, 0.6).unwrap(), Normal::new(0.0, 0.1).unwrap());
    let mut hints = Vec::new();
    let views: Vec<View> = exact
        .iter()
        .map(|v| {
            hints.push((0..v.image.len()).map(|i| if i % 2 == 0 { 30.0 } else { 120.0 }).collect::<Vec<f64>>());
            let image = v
                .image
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let n = if i % 2 == 0 { &loose } else { &firm };
                    [p[0] + n.sample(&mut rng), p[1] + n.sample(&mut rng)]
                })
                .collect();
            View { object: v.object.clone(), image }
        })
        .collect();
    let plain = Options { fix_k3: true, ..Options::default() };
    let weighed = Options { precision_hints: hints, ..plain.clone() };
    let (a, b) = (calibrate(&views, [346, 260], &plain).unwrap(), calibrate(&views, [346, 260], &weighed).unwrap());
    for (cal, what) in [(&a, "alike"), (&b, "weighed")] {
        let errors =
            [cal.intrinsics.fx - t.fx, cal.intrinsics.fy - t.fy, cal.intrinsics.cx - t.cx, cal.intrinsics.cy - t.cy];
        for (i, e) in errors.iter().enumerate() {
            assert!(e.abs() <= 3.0 * cal.std_dev[i], "{what}: parameter {i} off by {e}, σ {}", cal.std_dev[i]);
        }
    }
    assert!(a.precision_bins.is_empty() && b.precision_bins.len() == 2, "{:?}", b.precision_bins);
    assert!(b.precision_bins[0].weight < b.precision_bins[1].weight / 10.0, "{:?}", b.precision_bins);
    assert!(b.std_dev[0] < 0.6 * a.std_dev[0], "σ(fx) {} weighed against {} alike", b.std_dev[0], a.std_dev[0]);
    assert!(b.std_dev[2] < 0.6 * a.std_dev[2], "σ(cx) {} weighed against {} alike", b.std_dev[2], a.std_dev[2]);
}

#[test]
fn noisy_views_give_the_truth_within_the_targets() {
    let t = truth();
    for seed in 0..6 {
        // σ(fx) ≈ 0.04 % from these: the 0.1 % target with room for chance.
        let views = synthetic_views(&t, 100, 0.1, seed);
        // The lens has no k3: solved with it fixed, as users of such lenses do.
        let cal = calibrate(&views, [346, 260], &Options { fix_k3: true, ..Options::default() }).unwrap();
        let k = cal.intrinsics;
        assert!((k.fx / t.fx - 1.0).abs() < 1e-3, "seed {seed}: fx {}", k.fx);
        assert!((k.fy / t.fy - 1.0).abs() < 1e-3, "seed {seed}: fy {}", k.fy);
        assert!((k.cx - t.cx).abs() < 0.5 && (k.cy - t.cy).abs() < 0.5, "seed {seed}: {k:?}");
        assert!((k.k1 - t.k1).abs() < 0.01 && (k.k2 - t.k2).abs() < 0.03, "seed {seed}: {k:?}");
        // 0.1 px per axis: a 2-D RMS of about 0.14 px, a little less after the fit.
        assert!(cal.rms_px > 0.12 && cal.rms_px < 0.15, "seed {seed}: RMS {}", cal.rms_px);
        assert!(cal.rejected.is_empty(), "{:?}", cal.rejected);
        assert!(cal.converged);
        assert_eq!(cal.views.len(), 100);
        // With k3 free, fx and k3 trade off and these views (none reaching far into
        // the corners) leave fx looser: the truth lies within a few σ all the same.
        let free = calibrate(&views, [346, 260], &Options::default()).unwrap();
        for (i, truth) in t.to_array().iter().enumerate() {
            let z = (free.intrinsics.to_array()[i] - truth) / free.std_dev[i];
            assert!(z.abs() < 4.0, "seed {seed}: {} off by {z:.1} σ", PARAMETER_NAMES[i]);
        }
    }
}

#[test]
fn moves_the_points_were_given_are_estimated_back_and_counted_in_the_sigma() {
    let t = truth();
    let views = synthetic_views(&t, 40, 0.05, 11);
    // Directions that no pose or intrinsic change can mimic, two unlike patterns.
    let pattern = |f: f64, g: f64| -> Vec<Vec<[f64; 2]>> {
        views
            .iter()
            .enumerate()
            .map(|(v, view)| {
                (0..view.image.len())
                    .map(|i| {
                        let a = f * v as f64 + g * i as f64;
                        [0.2 * a.cos(), 0.2 * a.sin()]
                    })
                    .collect()
            })
            .collect()
    };
    let (lean, bend) = (pattern(0.7, 2.3), pattern(1.9, 0.4));
    let moved: Vec<View> = views
        .iter()
        .zip(lean.iter().zip(&bend))
        .map(|(v, (a, b))| View {
            object: v.object.clone(),
            image: v
                .image
                .iter()
                .zip(a.iter().zip(b))
                .map(|(p, (a, b))| [p[0] + 0.8 * a[0] - 0.5 * b[0], p[1] + 0.8 * a[1] - 0.5 * b[1]])
                .collect(),
        })
        .collect();
    let plain = calibrate(&moved, [346, 260], &Options::default()).unwrap();
    assert!(plain.moves.is_empty());
    // A third move without one entry per view is left out.
    let opts = Options { moves: vec![lean, vec![Vec::new()], bend], ..Options::default() };
    let cal = calibrate(&moved, [346, 260], &opts).unwrap();
    let [Some(a), None, Some(b)] = cal.moves[..] else { panic!("{:?}", cal.moves) };
    // The views ask to move the points back by what moved them.
    assert!((a.step + 0.8).abs() < 3.0 * a.std && a.std < 0.1, "{a:?}");
    assert!((b.step - 0.5).abs() < 3.0 * b.std && b.std < 0.1, "{b:?}");
    assert_eq!(plain.intrinsics, cal.intrinsics, "the σ changes, not the solution");
    for i in 0..4 {
        assert!(cal.std_dev[i] >= plain.std_dev[i] * (1.0 - 1e-9), "{i}: {cal:?} vs {plain:?}");
    }
}

#[test]
fn the_groups_a_sigma_came_from_are_reported() {
    let views = synthetic_views(&truth(), 20, 0.2, 7);
    let plain = calibrate(&views, [346, 260], &Options::default()).unwrap();
    assert_eq!(plain.sigma_groups, None, "no groups given");
    // A view every quarter second: two views a half-second group, 10 groups, enough for
    // a grouped σ, widened for so few.
    let opts = Options { view_times: (0..20).map(|v| 0.25 * v as f64).collect(), ..Options::default() };
    let grouped = calibrate(&views, [346, 260], &opts).unwrap();
    assert_eq!((grouped.sigma_groups, grouped.sigma_group_s), (Some(10), Some(GROUP_SECONDS)));
    assert_eq!(grouped.intrinsics, plain.intrinsics, "the σ changes, not the solution");
    for i in 0..4 {
        assert!(grouped.std_dev[i] >= plain.std_dev[i], "{i}: never below the points' σ");
    }
    // Views in five bursts of four, too short to part into more groups: five groups,
    // their σ widened for so few, by Student's t with four degrees of freedom.
    let bursts = |n: usize| Options {
        view_times: (0..20).map(|v| (v / (20 / n)) as f64 + 0.01 * (v % (20 / n)) as f64).collect(),
        ..Options::default()
    };
    let few = calibrate(&views, [346, 260], &bursts(5)).unwrap();
    assert_eq!((few.sigma_groups, few.sigma_group_s), (Some(5), Some(MIN_GROUP_SECONDS)));
    assert_eq!(few.intrinsics, plain.intrinsics);
    for i in 0..4 {
        assert!(few.std_dev[i] >= plain.std_dev[i], "{i}: never below the points' σ");
    }
    // In two bursts: too few groups for a grouped σ; the points' σ alone.
    let two = calibrate(&views, [346, 260], &bursts(2)).unwrap();
    assert_eq!((two.sigma_groups, two.sigma_group_s), (None, Some(MIN_GROUP_SECONDS)));
    assert_eq!(two.std_dev, plain.std_dev);
}

#[test]
fn standard_deviations_describe_the_scatter() {
    // Over many noisy sets, the error of fx divided by its reported σ should scatter
    // like a unit normal: its RMS near 1.
    let t = truth();
    let mut z = Vec::new();
    for seed in 0..30 {
        let views = synthetic_views(&t, 12, 0.2, 100 + seed);
        let cal = calibrate(&views, [346, 260], &Options { robust: false, ..Options::default() }).unwrap();
        for (i, truth) in [(0, t.fx), (2, t.cx), (4, t.k1)] {
            z.push((cal.intrinsics.to_array()[i] - truth) / cal.std_dev[i]);
        }
    }
    let rms = (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
    assert!(rms > 0.7 && rms < 1.4, "normalised error RMS {rms}");
}

#[test]
fn a_bad_view_is_set_aside_with_its_reason() {
    let t = truth();
    let mut views = synthetic_views(&t, 15, 0.1, 9);
    // View 6: two points swapped, as a wrong grid ordering would give.
    views[6].image.swap(3, 20);
    // View 9: two neighbours swapped, the subtlest wrong ordering.
    views[9].image.swap(0, 1);
    let cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
    assert_eq!(cal.rejected.len(), 2, "{:?}", cal.rejected);
    assert_eq!(cal.rejected[0].view, 6);
    assert!(cal.rejected[0].reason.contains("far above"), "{}", cal.rejected[0].reason);
    assert_eq!(cal.rejected[1].view, 9);
    // Its own pose bends to the two swapped points, so the whole view may look off, or
    // just the two: either way it goes, with the reason.
    let why = &cal.rejected[1].reason;
    assert!(why.contains("far above") || why.contains("2 of its 44 points"), "{why}");
    assert!((cal.intrinsics.fx / t.fx - 1.0).abs() < 1e-3);
    assert!(cal.views.iter().all(|v| v.view != 6 && v.view != 9));
    assert!(cal.rms_px < 0.15, "{}", cal.rms_px);
}

#[test]
fn a_stray_point_is_set_aside() {
    let t = truth();
    let mut views = synthetic_views(&t, 15, 0.1, 11);
    views[3].image[7][0] += 3.0;
    let cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
    assert!(cal.rejected.is_empty(), "{:?}", cal.rejected);
    assert_eq!(cal.stray_points, 1);
    assert_eq!(cal.views[3].strays, 1);
    // The RMS is of the points kept (noise 0.1 px per axis: 0.14 px); the stray's 3 px
    // would raise it to about 0.18 px.
    assert!(cal.rms_px < 0.15, "{}", cal.rms_px);
    assert!(cal.rms_all_px > 0.16, "{}", cal.rms_all_px);
    assert!((cal.intrinsics.fx / t.fx - 1.0).abs() < 1e-3);
    assert!((cal.intrinsics.cx - t.cx).abs() < 0.5);
}

#[test]
fn a_fixed_aspect_ratio_without_a_start_is_one() {
    // Square pixels seen with noise: the closed form's start has fy/fx off 1 by a little,
    // which the solve used to keep.
    let t = Intrinsics { fy: 352.4, ..truth() };
    let views = synthetic_views(&t, 20, 0.2, 11);
    let opts = Options { fix_aspect_ratio: true, fix_k3: true, ..Options::default() };
    let cal = calibrate(&views, [346, 260], &opts).unwrap();
    let k = cal.intrinsics;
    assert_eq!(k.fy.to_bits(), k.fx.to_bits(), "{k:?}");
    assert_eq!(cal.std_dev[1].to_bits(), cal.std_dev[0].to_bits());
    assert_eq!(cal.std_dev_points[1].to_bits(), cal.std_dev_points[0].to_bits());
    assert!(cal.std_dev[0] > 0.0 && cal.std_dev[0] < 1.0, "{:?}", cal.std_dev);
    assert!((k.fx / t.fx - 1.0).abs() < 1e-3, "{k:?}");
    // A start of the user's keeps its own ratio, as OpenCV's guess does.
    let start = Intrinsics { fy: 0.99 * t.fx, ..t };
    let k = calibrate(&views, [346, 260], &Options { start: Some(start), ..opts }).unwrap().intrinsics;
    assert!((k.fy / k.fx - 0.99).abs() < 1e-12, "{k:?}");
}

#[test]
fn fixed_parameters_stay_fixed() {
    let mut t = truth();
    t.p1 = 0.0;
    t.p2 = 0.0;
    let views = synthetic_views(&t, 12, 0.05, 3);
    let opts = Options { fix_k3: true, zero_tangential: true, fix_aspect_ratio: true, ..Options::default() };
    let start = Intrinsics { fx: 340.0, fy: 340.0 * t.fy / t.fx, ..t };
    let cal = calibrate(&views, [346, 260], &Options { start: Some(start), ..opts.clone() }).unwrap();
    let k = cal.intrinsics;
    assert_eq!((k.p1, k.p2, k.k3), (0.0, 0.0, 0.0));
    assert!((k.fy / k.fx - t.fy / t.fx).abs() < 1e-12);
    assert_eq!(cal.std_dev[6..], [0.0, 0.0, 0.0]);
    assert!((k.fx / t.fx - 1.0).abs() < 1e-3, "{k:?}");
    let fixed_pp = Options { fix_principal_point: true, start: Some(Intrinsics { cx: 170.0, cy: 130.0, ..t }), ..opts };
    let k = calibrate(&views, [346, 260], &fixed_pp).unwrap().intrinsics;
    assert_eq!((k.cx, k.cy), (170.0, 130.0));
}

#[test]
fn bad_input_is_a_clear_error() {
    let t = truth();
    assert_eq!(calibrate(&[], [346, 260], &Options::default()), Err(CalibError::NoViews));
    let views = synthetic_views(&t, 2, 0.0, 1);
    assert_eq!(
        calibrate(&views, [346, 260], &Options::default()),
        Err(CalibError::TooFewViews { usable: 2, needed: MIN_VIEWS })
    );
    let mut views = synthetic_views(&t, 5, 0.0, 1);
    views[2].image[4][1] = f64::NAN;
    assert_eq!(calibrate(&views, [346, 260], &Options::default()), Err(CalibError::NotFinite { view: 2, point: 4 }));
    // Every point of every view on one line, or the same view five times.
    let line = View {
        object: (0..10).map(|i| [i as f64 * 0.01, 0.0, 0.0]).collect(),
        image: (0..10).map(|i| [10.0 + i as f64 * 9.0, 50.0]).collect(),
    };
    let err = calibrate(&vec![line; 5], [346, 260], &Options::default()).unwrap_err();
    assert!(matches!(err, CalibError::TooFewViews { usable: 0, .. }), "{err}");
    // One pose seen five times, with noise: the views do not pin the camera down.
    let one = synthetic_views(&t, 1, 0.0, 4).remove(0);
    let same: Vec<View> = (0..5)
        .map(|c| View {
            object: one.object.clone(),
            image: one
                .image
                .iter()
                .enumerate()
                .map(|(i, m)| [m[0] + 0.1 * ((i * 7 + c * 3) % 5) as f64 - 0.2, m[1]])
                .collect(),
        })
        .collect();
    match calibrate(&same, [346, 260], &Options::default()) {
        Err(e) => assert!(e.to_string().contains("views"), "{e}"),
        Ok(cal) => assert!(!cal.warnings.is_empty(), "identical views must at least warn: {cal:?}"),
    }
    let few = View { object: views[0].object[..4].to_vec(), image: views[0].image[..4].to_vec() };
    let mut views = synthetic_views(&t, 4, 0.0, 1);
    views.push(few);
    let cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
    assert_eq!(cal.rejected.len(), 1);
    assert!(cal.rejected[0].reason.contains("points"));
}

/// Views of a target held parallel to the sensor at one distance, turned about the
/// optical axis and moved across it: the image is the same for a focal length `s` times
/// larger seen from `s` times farther (with the distortion rescaled), so no focal length
/// is fixed. Whatever the noise, the solve must refuse or give fx a σ that says so.
#[test]
fn views_parallel_to_the_sensor_fix_no_focal_length() {
    let t = truth();
    let board: Vec<[f64; 3]> =
        (0..11).flat_map(|i| (0..4).map(move |j| [i as f64 * 0.024, (2 * j + i % 2) as f64 * 0.024, 0.0])).collect();
    // (turn about the axis per view (rad), step across (m), a slight tilt per view (rad),
    // views, noise (px))
    let cases = [
        (0.5, [0.03, -0.02], 0.0, 4, 0.0),
        (1.1, [0.0, 0.0], 0.0, 4, 0.0),
        (0.7, [0.02, 0.0], 0.001, 4, 0.0),
        (0.7, [0.02, 0.0], 0.0, 8, 0.0),
        (0.3, [0.02, 0.01], 0.0, 12, 0.1),
    ];
    for (turn, step, tilt, count, noise) in cases {
        let views: Vec<View> = (0..count)
            .map(|k| {
                let kf = k as f64;
                let rot = Rotation3::from_scaled_axis(Vector3::new(tilt * kf, 0.0, turn * kf));
                let centre = rot * Vector3::new(0.12, 0.084, 0.0);
                let pose =
                    Pose { rotation: rot, translation: Vector3::new(step[0] * kf - 0.03, step[1] * kf, 0.5) - centre };
                let image = board
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        let m = t.project(&(pose.rotation * Vector3::from(*p) + pose.translation)).expect("in front");
                        let e = |a: usize| noise * ((a % 5) as f64 - 2.0);
                        [m[0] + e(i * 7 + k * 3), m[1] + e(i * 3 + k)]
                    })
                    .collect();
                View { object: board.clone(), image }
            })
            .collect();
        if let Ok(cal) = calibrate(&views, [346, 260], &Options::default()) {
            let (fx, sd) = (cal.intrinsics.fx, cal.std_dev[0]);
            // Beyond 5 % of itself, the CLI's verdict calls the run no calibration.
            assert!(
                sd.is_nan() || sd > 0.05 * fx.abs(),
                "turn {turn}, {count} views: fx {fx} ± {sd} claims a calibration"
            );
        }
    }
}

#[test]
fn results_are_finite_for_any_input() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..200 {
        let views: Vec<View> = (0..rng.random_range(0..6))
            .map(|_| {
                let n = rng.random_range(0..12);
                View {
                    object: (0..n).map(|_| [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.0]).collect(),
                    image: (0..n).map(|_| [rng.random_range(-10.0..400.0), rng.random_range(-10.0..300.0)]).collect(),
                }
            })
            .collect();
        if let Ok(cal) = calibrate(&views, [346, 260], &Options::default()) {
            assert!(cal.intrinsics.to_array().iter().all(|x| x.is_finite()), "{cal:?}");
            assert!(cal.rms_px.is_finite());
        }
    }
}
