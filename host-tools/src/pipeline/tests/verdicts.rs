//! The verdicts' words, and the filled discs' fallback decided on synthetic views.

use super::*;
use std::cell::Cell;
use std::convert::Infallible;

/// `n` views of [`lens`] with `noise_px` of noise on every centre, as a run's views.
fn synthetic(n: usize, noise_px: f64) -> Views {
    Views {
        views: calib::synthetic_views(&lens(), n, noise_px, 3),
        origins: (0..n).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect(),
        partial: vec![false; n],
        ..Views::default()
    }
}

fn setup() -> Setup {
    Setup::new(Pattern::new(4, 11, 0.024).unwrap(), [346, 260])
}

/// Views in which no grid was found, out of `windows` windows.
fn no_grid(windows: usize) -> Views {
    Views { stats: GridStats { windows, ..GridStats::default() }, ..Views::default() }
}

#[test]
fn rings_that_calibrate_are_kept_without_asking_for_discs() {
    let asked = Cell::new(false);
    let discs = |_: &NoCalibration| {
        asked.set(true);
        Ok::<_, Infallible>(Some(synthetic(12, 0.02)))
    };
    let Ok(chosen) = calibrate_with_disc_fallback(synthetic(15, 0.02), &setup(), discs);
    assert!(!asked.get(), "the discs were detected though the rings calibrated");
    assert_eq!(chosen.fallback, DiscFallback::NotNeeded);
    assert_eq!(chosen.views.views.len(), 15);
    let o = chosen.result.expect("a calibration");
    assert!(o.failure.is_none() && o.calibration.warnings.iter().all(|w| !w.contains("filled discs")));
}

#[test]
fn discs_are_taken_where_rings_give_none_and_say_so() {
    let told = Cell::new(None);
    let discs = |why: &NoCalibration| {
        told.set(Some(why.clone()));
        Ok::<_, Infallible>(Some(synthetic(12, 0.02)))
    };
    let Ok(chosen) = calibrate_with_disc_fallback(no_grid(0), &setup(), discs);
    let rings_failed = NoCalibration::NoGrid(GridStats::default());
    assert_eq!(told.into_inner(), Some(rings_failed.clone()), "the discs' source is told why");
    assert_eq!(chosen.fallback, DiscFallback::Taken { rings_failed });
    assert_eq!(chosen.views.views.len(), 12, "the discs' views");
    let o = chosen.result.expect("the discs' calibration");
    let warning = "circles fitted as filled discs where no ring fitted: the rings alone gave no calibration (no detection windows to look for the grid in); a disc's centre is less sure than a ring's, so more light (or a faster photoreceptor bias) gives a better calibration";
    assert_eq!(o.calibration.warnings.iter().filter(|w| *w == warning).count(), 1, "{:?}", o.calibration.warnings);
}

#[test]
fn discs_that_are_no_calibration_or_loose_leave_the_rings_failure() {
    // Two views are too few to solve on: no calibration.
    let Ok(chosen) =
        calibrate_with_disc_fallback(no_grid(10), &setup(), |_| Ok::<_, Infallible>(Some(synthetic(2, 0.02))));
    let rings_failed = NoCalibration::NoGrid(GridStats { windows: 10, ..GridStats::default() });
    match &chosen.fallback {
        DiscFallback::Rejected { rings_failed: r, why: DiscRejection::NoCalibration(NoCalibration::Solve(_)) } => {
            assert_eq!(r, &rings_failed)
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(chosen.views.stats.windows, 10, "the rings' views");
    assert!(matches!(chosen.result, Err(PipelineError::NoGrid(_))));
    // A calibration (σ(fx) about 2 %, within the 5 % that fails one) whose focal length is
    // looser than the discs' 1 %: six views of centres 1 px off.
    let loose = synthetic(6, 1.0);
    let Ok(chosen) = calibrate_with_disc_fallback(no_grid(10), &setup(), |_| Ok::<_, Infallible>(Some(loose)));
    match &chosen.fallback {
        DiscFallback::Rejected { why: DiscRejection::LooseFocal { rel, views }, .. } => {
            assert!(*rel > DISC_FALLBACK_FOCAL_RELATIVE && *rel < FAILED_RELATIVE && *views > 0, "{rel} {views}")
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(chosen.result, Err(PipelineError::NoGrid(_))));
    // No discs to be had (standard input was read once): the rings' failure, said as such.
    let Ok(chosen) = calibrate_with_disc_fallback(no_grid(10), &setup(), |_| Ok::<_, Infallible>(None));
    assert_eq!(chosen.fallback, DiscFallback::NotTried { rings_failed });
    // The source's error is the call's.
    let r = calibrate_with_disc_fallback(no_grid(10), &setup(), |_| Err("cannot read"));
    assert_eq!(r.err(), Some("cannot read"));
}

/// What `evcal calibrate` cut from each reason for its one-line notes before the verdicts
/// were values: up to the first colon or semicolon outside brackets.
fn first_clause(why: &str) -> &str {
    let mut depth = 0i32;
    for (i, c) in why.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            ':' | ';' if depth <= 0 => return why[..i].trim(),
            _ => {}
        }
    }
    why.trim()
}

#[test]
fn each_verdict_says_what_it_said_as_a_string() {
    let loose = Loose {
        params: vec![
            LooseParam { index: 0, by: Looseness::Relative(1.27) },
            LooseParam { index: 2, by: Looseness::Px(31.25) },
            LooseParam { index: 3, by: Looseness::NotFixed },
        ],
    };
    assert_eq!(
        loose.to_string(),
        "the views do not fix the camera: fx ±127.0 % (1σ), cx ±31.2 px (1σ), cy not fixed at all (at most 5 % of the focal length or the sensor's size is a calibration); record the target tilted 20–40° to each side, filling the sensor, in light bright enough for the grid to be found in most windows"
    );
    let tilt = WeakFocal {
        fx_rel: 0.004,
        fy_rel: 0.0012,
        cause: WeakFocalCause::LacksTilt { max_deg: 12.4 },
        lag_fx_rel: Some(0.0035),
    };
    assert_eq!(
        tilt.to_string(),
        "the focal length is weakly fixed: fx ±0.40 %, fy ±0.12 % (1σ; evcal aims at 0.1 %); the views tilt the target by at most 12°: only tilt tells the focal length from the distance (a target facing the sensor looks the same to a focal length twice as long from twice as far, its distortion rescaled to match, however near it comes). Record a cone: tilt the target 20–40° towards each side in turn while it sweeps the sensor; most of it is how late the edges were seen (taking the lag in proportion to each edge's thickness rather than as one distance moves fx by +0.35 %): more light, or a sharper focus, makes the edges quicker and thinner"
    );
    let coverage = WeakFocal { cause: WeakFocalCause::Coverage { views: 9, covered: 0.314 }, lag_fx_rel: None, ..tilt };
    assert_eq!(
        coverage.to_string(),
        "the focal length is weakly fixed: fx ±0.40 %, fy ±0.12 % (1σ; evcal aims at 0.1 %); 9 views, their points on 31 % of the sensor: record longer, tilting the target 20–40° to each side while it sweeps the whole sensor (in brighter light if the grid was missed in many windows)"
    );
    let discs = DiscRejection::LooseFocal { rel: 0.0234, views: 8 };
    assert_eq!(
        discs.to_string(),
        "the focal length ±2.3 % (1σ) from 8 views; a disc's centre may lie a pixel off its circle's, so discs are taken only where their views fix the focal length within 1 %"
    );
    let few = NoCalibration::Solve(CalibError::TooFewViews { usable: 1, needed: 3 });
    assert_eq!(
        few.to_string(),
        "1 usable view(s) of the target; a calibration needs at least 3 (views with at least 6 points, not all on a line)"
    );
    let mut stats = GridStats { windows: 240, points_at_edge: 7, ..GridStats::default() };
    stats.misses.insert(Miss::TooFewCentres, 200);
    stats.misses.insert(Miss::NoLattice, 40);
    let no_grid = NoCalibration::NoGrid(stats.clone());
    assert_eq!(no_grid.to_string(), PipelineError::NoGrid(stats).to_string());
    assert!(no_grid.to_string().starts_with("grid found in 0 of 240 windows (not found: 200 too few centres, 40 no lattice); 7 points at the sensor's border left out: check --pattern"), "{no_grid}");
    // The short forms are the clauses the notes quoted.
    let degenerate = NoCalibration::Solve(CalibError::Degenerate("all views alike".into()));
    let none = NoCalibration::NoGrid(GridStats::default());
    for v in [&NoCalibration::Loose(loose), &few, &no_grid, &degenerate, &none] {
        assert_eq!(v.summary(), first_clause(&v.to_string()), "{v:?}");
    }
    assert_eq!(discs.summary(), first_clause(&discs.to_string()));
    assert_eq!(
        DiscRejection::NoCalibration(few.clone()).summary(),
        first_clause(&DiscRejection::NoCalibration(few).to_string())
    );
}

/// The run's verdict from its thresholds: good when every one is met, usable with the
/// actions for what misses (the most useful first, at most three), not a calibration when a
/// parameter is loose; each with its exit status.
#[test]
fn the_verdict_follows_its_thresholds_and_names_at_most_three_actions() {
    let mut o = calibrate_views(&synthetic(40, 0.02), &setup()).expect("a calibration");
    // Synthetic views spread over the sensor, noise of 0.02 px: every threshold met.
    assert!(o.coverage.covered >= GOOD_COVERAGE, "{}", o.coverage.picture());
    assert_eq!(Verdict::of(&o), Verdict::Good, "σ {:?}", o.calibration.std_dev);
    assert_eq!((Verdict::of(&o).exit_code(), Verdict::of(&o).to_string()), (0, "verdict: good".to_string()));

    // Each threshold missed on its own gives one action naming its figure.
    let k = o.calibration.intrinsics;
    let good = o.clone();
    o.calibration.std_dev[0] = 1.5 * GOOD_FOCAL_RELATIVE * k.fx;
    let v = Verdict::of(&o);
    assert_eq!(v.exit_code(), EXIT_USABLE);
    assert!(v.actions().len() == 1 && v.actions()[0].contains("fx ±0.15 %"), "{v}");
    o = good.clone();
    o.calibration.std_dev[3] = 1.2 * GOOD_CENTRE_PX;
    assert!(Verdict::of(&o).actions()[0].contains("cy ±1.2 px"), "{}", Verdict::of(&o));
    o = good.clone();
    o.calibration.rms_px = 2.0 * GOOD_RMS_PX;
    assert!(Verdict::of(&o).actions()[0].contains("1.00 px RMS"), "{}", Verdict::of(&o));
    o = good.clone();
    o.calibration.std_dev[8] = 1.0;
    assert!(Verdict::of(&o).actions()[0].contains("1σ of k3 moves a corner"), "{}", Verdict::of(&o));
    o = good.clone();
    o.projection_sigma.as_mut().expect("a projection σ").sensor.p95_px = 2.0 * GOOD_PROJECTION_PX;
    assert!(Verdict::of(&o).actions()[0].contains("uncertain by 2.0 px"), "{}", Verdict::of(&o));
    o = good.clone();
    o.coverage.covered = 0.3;
    assert!(Verdict::of(&o).actions()[0].contains("30 % of it"), "{}", Verdict::of(&o));

    // Everything missed: three actions, the focal length's first.
    o.calibration.std_dev[0] = 0.01 * k.fx;
    o.calibration.std_dev[2] = 3.0;
    o.calibration.rms_px = 1.0;
    o.calibration.views.truncate(GOOD_VIEWS - 1);
    let v = Verdict::of(&o);
    assert_eq!(v.actions().len(), MAX_ACTIONS, "{v}");
    assert!(v.actions()[0].contains("fx ±1.00 %") && v.to_string().starts_with("verdict: usable, but "), "{v}");

    // A loose parameter: no calibration, whatever else.
    o.failure = Some(Loose { params: vec![LooseParam { index: 1, by: Looseness::Relative(0.08) }] });
    let v = Verdict::of(&o);
    assert_eq!((v.exit_code(), v.grade()), (EXIT_NOT_A_CALIBRATION, "not a calibration"));
    assert!(v.to_string().contains("fy ±8.0 %") && v.actions().is_empty(), "{v}");
}
