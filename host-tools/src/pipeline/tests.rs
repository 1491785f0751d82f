//! The pipeline's tests: windows of a grid seen head-on, views, the solve and its verdicts.

use super::*;
use crate::input::detections::CenterRecord;

mod verdicts;

/// Windows whose centres are a pattern's circles seen head-on (plus one stray), moved a
/// little per window.
fn windows(pattern: &Pattern, n: usize) -> Vec<WindowRecord> {
    (0..n)
        .map(|k| {
            let mut centers: Vec<CenterRecord> = (0..pattern.len())
                .map(|i| {
                    let o = pattern.object_point(i);
                    let s = 600.0 + 20.0 * k as f64;
                    CenterRecord {
                        u: (40.0 + 5.0 * k as f64 + s * o[0]) as f32,
                        v: (30.0 + s * o[1]) as f32,
                        r: 4.0,
                        spread: 0.2,
                        n: 60,
                        converged: true,
                    }
                })
                .collect();
            centers.push(CenterRecord { u: 300.0, v: 240.0, r: 9.0, spread: 0.5, n: 30, converged: true });
            WindowRecord { seq: k as u32, t_ref_us: 1000 * k as u64, events: 4000, noise: 100, centers, sensor: None }
        })
        .collect()
}

#[test]
fn windows_become_views_in_order_with_their_origins() {
    let pattern = Pattern::new(4, 11, 0.024).unwrap();
    let setup = Setup::new(pattern, [346, 260]);
    let w = windows(&pattern, 5);
    let v = views_from_windows(&w, &setup, &|_| {});
    assert_eq!(v.stats.windows, 5);
    assert_eq!(v.stats.found, 5, "{}", v.stats.summary());
    assert_eq!(v.views.len(), 5);
    assert_eq!(v.timeline.len(), 5);
    for (k, (view, origin)) in v.views.iter().zip(&v.origins).enumerate() {
        assert_eq!(origin.window_seq, k as u64);
        assert_eq!(view.object.len(), 44);
        assert_eq!(view.object[0], [0.0, 0.0, 0.0]);
    }
}

/// A window holding only part of the grid (its first four columns) between whole ones is
/// followed, counted as found, and marked partial: not offered to the solve.
#[test]
fn a_partial_grid_is_found_but_not_solved_on() {
    let pattern = Pattern::new(4, 11, 0.024).unwrap();
    let setup = Setup::new(pattern, [346, 260]);
    let mut w = windows(&pattern, 5);
    w[2].centers.drain(16..);
    let v = views_from_windows(&w, &setup, &|_| {});
    assert_eq!((v.stats.found, v.stats.followed, v.stats.partial), (5, 1, 1), "{}", v.stats.summary());
    assert!(v.stats.summary().contains("1 of those part of the grid only"), "{}", v.stats.summary());
    assert_eq!(v.partial, [false, false, true, false, false]);
    assert_eq!(v.views[2].object.len(), 16);
    assert_eq!(solvable(&v), [0, 1, 3, 4]);
}

#[test]
fn points_at_the_border_are_left_out() {
    let pattern = Pattern::new(4, 11, 0.024).unwrap();
    // A sensor that cuts the grid's last column (x = 10 S at 600 px/m ≈ 184 px).
    let setup = Setup::new(pattern, [186, 260]);
    let v = views_from_windows(&windows(&pattern, 1), &setup, &|_| {});
    assert_eq!(v.stats.found, 1);
    assert_eq!(v.stats.points_at_edge, 4);
    assert_eq!(v.views[0].object.len(), 40);
    assert!(v.views[0].image.iter().all(|p| p[0] + 4.0 < 185.5));
}

/// A DAVIS346-like lens for synthetic views.
fn lens() -> calib::Intrinsics {
    calib::Intrinsics { fx: 352.4, fy: 351.1, cx: 171.3, cy: 128.6, k1: -0.31, k2: 0.12, p1: 0.0, p2: 0.0, k3: 0.0 }
}

/// Filled discs, tried where the rings gave no calibration, are taken only when theirs is
/// a calibration whose views fix the focal length within 1 %.
#[test]
fn filled_discs_are_taken_only_where_they_fix_the_focal_length() {
    let pattern = Pattern::new(4, 11, 0.024).unwrap();
    let setup = Setup::new(pattern, [346, 260]);
    let none = calibrate_views(&Views::default(), &setup);
    assert!(no_calibration(&none).is_some() && disc_fallback_rejects(&none).is_some());
    let truth = lens();
    let n = 12;
    let views = Views {
        views: calib::synthetic_views(&truth, n, 0.02, 3),
        origins: (0..n).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect(),
        partial: vec![false; n],
        ..Views::default()
    };
    let mut o = calibrate_views(&views, &setup).expect("a solve");
    o.failure = None;
    let k = o.calibration.intrinsics;
    o.calibration.std_dev[0] = 0.004 * k.fx;
    o.calibration.std_dev[1] = 0.004 * k.fy;
    assert!(no_calibration(&Ok(o.clone())).is_none());
    assert_eq!(disc_fallback_rejects(&Ok(o.clone())), None);
    o.calibration.std_dev[1] = 0.02 * k.fy;
    let why = disc_fallback_rejects(&Ok(o.clone())).expect("refused").to_string();
    assert!(why.contains("±2.0 %") && why.contains("12 views"), "{why}");
    o.calibration.std_dev[1] = f64::NAN;
    assert!(disc_fallback_rejects(&Ok(o.clone())).is_some());
    let loose = Loose { params: vec![LooseParam { index: 0, by: Looseness::NotFixed }] };
    o.failure = Some(loose.clone());
    assert_eq!(no_calibration(&Ok(o.clone())), Some(NoCalibration::Loose(loose.clone())));
    assert_eq!(disc_fallback_rejects(&Ok(o)), Some(DiscRejection::NoCalibration(NoCalibration::Loose(loose))));
}

/// A calibration whose focal length the views leave loose is warned about, and one they
/// leave meaningless is no calibration, with the parameter named.
#[test]
fn loose_parameters_are_warned_about_or_fail_the_calibration() {
    let truth = lens();
    let views = calib::synthetic_views(&truth, 12, 0.02, 3);
    let mut cal = calib::calibrate(&views, [346, 260], &calib::Options::default()).unwrap();
    let coverage = Coverage::of(&views.iter().collect::<Vec<_>>(), [346, 260]);
    assert!(loose_params(&cal).is_none() && WeakFocal::of(&cal, &coverage, None).is_none(), "{:?}", cal.std_dev);
    cal.std_dev[0] = 0.004 * truth.fx;
    let w = WeakFocal::of(&cal, &coverage, None).expect("a warning").to_string();
    assert!(w.contains("fx ±0.40 %") && w.contains("tilt") && !w.contains("late"), "{w}");
    // Most of that σ from the lag's model: said, with what makes edges quicker.
    let mut lag = [0.0; 9];
    lag[0] = 0.0035 * truth.fx;
    let w = WeakFocal::of(&cal, &coverage, Some(&lag)).expect("a warning").to_string();
    assert!(w.contains("how late the edges were seen") && w.contains("+0.35 %") && w.contains("more light"), "{w}");
    lag[0] = 0.001 * truth.fx;
    assert_eq!(WeakFocal::of(&cal, &coverage, Some(&lag)).unwrap().lag_fx_rel, None);
    assert!(loose_params(&cal).is_none());
    cal.std_dev[0] = 1.27 * truth.fx;
    cal.std_dev[3] = f64::NAN;
    let why = loose_params(&cal).expect("no calibration").to_string();
    assert!(why.contains("fx ±127.0 %") && why.contains("cy not fixed at all"), "{why}");
}

/// Centres that trail their circles by a distance in proportion to their edges'
/// thickness: the pipeline estimates both models of the lag, the thickness model finds
/// the distance put in, and the σ printed covers what choosing between them changes.
#[test]
fn the_lags_other_model_is_solved_and_counted_in_sigma() {
    let truth = calib::Intrinsics {
        fx: 330.0,
        fy: 331.0,
        cx: 170.0,
        cy: 128.0,
        k1: -0.3,
        k2: 0.12,
        p1: 0.0005,
        p2: -0.0003,
        k3: 0.0,
    };
    let n = 40;
    let exact = calib::synthetic_views(&truth, n, 0.0, 3);
    let origins: Vec<ViewOrigin> = (0..n).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect();
    // Thin and thick edges in turn, 0.2 and 0.6 px: the median is 0.6 or 0.2, and the
    // lag is 0.5 px per px of thickness.
    let spreads: Vec<Vec<f64>> =
        exact.iter().map(|v| (0..v.image.len()).map(|i| if i % 2 == 0 { 0.2 } else { 0.6 }).collect()).collect();
    let dirs = edge_shift::directions(&exact, &origins);
    let lagging: Vec<View> = exact
        .iter()
        .zip(&dirs)
        .zip(&spreads)
        .map(|((v, d), s)| View {
            object: v.object.clone(),
            image: v
                .image
                .iter()
                .zip(d)
                .zip(s)
                .map(|((p, d), s)| [p[0] - 0.5 * s * d[0], p[1] - 0.5 * s * d[1]])
                .collect(),
        })
        .collect();
    let views =
        Views { views: lagging, origins, spreads: spreads.clone(), partial: vec![false; n], ..Views::default() };
    let mut setup = Setup::new(Pattern::new(4, 11, 0.024).unwrap(), [346, 260]);
    setup.smooth = None;
    let o = calibrate_views(&views, &setup).expect("a calibration");
    let shift = o.edge_shift.expect("a shift");
    let alt = shift.by_thickness.expect("the thickness model solved too");
    let all: Vec<f64> = spreads.iter().flatten().copied().collect();
    let mut sorted = all.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    assert!((alt.px - 0.5 * median).abs() < 0.01, "{alt:?} (median thickness {median})");
    for i in 0..4 {
        assert!(alt.change[i].is_finite() && alt.change[i] != 0.0, "{alt:?}");
        assert!(o.calibration.std_dev[i] >= alt.change[i].abs(), "{i}: {:?} vs {alt:?}", o.calibration.std_dev);
    }
    // The right model is the thickness one: its answer is the camera.
    let k = o.calibration.intrinsics.to_array();
    let fx_alt = k[0] + alt.change[0];
    assert!((fx_alt / truth.fx - 1.0).abs() < 2e-4, "fx {fx_alt} under the thickness model");
}

#[test]
fn no_grid_is_an_error_that_says_why() {
    let pattern = Pattern::new(4, 11, 0.024).unwrap();
    let setup = Setup::new(Pattern::new(3, 9, 0.027).unwrap(), [346, 260]);
    let v = views_from_windows(&windows(&pattern, 3), &setup, &|_| {});
    let e = calibrate_views(&v, &setup).unwrap_err();
    assert!(matches!(e, PipelineError::NoGrid(_)));
    assert!(e.to_string().contains("grid found in 0 of 3 windows"), "{e}");
    assert!(!e.to_string().contains("dim light"), "the grid is there, the pattern wrong: {e}");
    // Windows short of circles (a dim scene's slow pixels): said, with what helps.
    let mut stats = GridStats { windows: 10, ..GridStats::default() };
    stats.misses.insert(Miss::TooFewCentres, 6);
    stats.misses.insert(Miss::NoLattice, 4);
    let dim = PipelineError::NoGrid(stats).to_string();
    assert!(dim.contains("in 6 windows the core found fewer circles") && dim.contains("more light"), "{dim}");
    let none = calibrate_views(&Views::default(), &setup).unwrap_err();
    assert!(none.to_string().contains("no detection windows"), "{none}");
}

/// k3 is held at 0 where the views cannot tell it from 0, and said; solved where they can
/// (a lens with a strong k3 seen to the corners); solved whatever they say when asked.
#[test]
fn k3_is_solved_only_where_the_views_demand_it() {
    let pattern = Pattern::new(4, 11, 0.024).unwrap();
    let views_of = |truth: &calib::Intrinsics, n: usize, noise: f64| Views {
        views: calib::synthetic_views(truth, n, noise, 5),
        origins: (0..n).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect(),
        partial: vec![false; n],
        ..Views::default()
    };
    let setup = Setup::new(pattern, [346, 260]);
    // No k3 in the lens, noisy centres: held, and every export the same model.
    let o = calibrate_views(&views_of(&lens(), 30, 0.1), &setup).expect("a solve");
    let held = o.k3_held.expect("k3 held at 0");
    assert!(held.free.abs() < K3_DEMANDED_SIGMAS * held.std, "{held:?}");
    assert_eq!((o.calibration.intrinsics.k3, o.calibration.std_dev[8]), (0.0, 0.0));
    assert!(o.without_k3.is_none());
    assert!(held.to_string().starts_with("k3 held at 0") && held.to_string().contains("--free-k3"), "{held}");
    // Asked to solve it: solved.
    let free = Setup { k3_only_if_demanded: false, ..setup.clone() };
    let o = calibrate_views(&views_of(&lens(), 30, 0.1), &free).expect("a solve");
    assert!(o.k3_held.is_none() && o.calibration.intrinsics.k3 != 0.0);
    // A strong k3, precise centres: the views demand it.
    let strong = calib::Intrinsics { k3: 0.3, ..lens() };
    let o = calibrate_views(&views_of(&strong, 40, 0.01), &setup).expect("a solve");
    assert!(o.k3_held.is_none(), "{:?}", o.k3_held);
    assert!((o.calibration.intrinsics.k3 - 0.3).abs() < 0.05, "{:?}", o.calibration.intrinsics);
}
