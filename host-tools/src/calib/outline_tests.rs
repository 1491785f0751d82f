//! Tests of the circle outlines' offsets on simulated views.

use super::*;
use crate::sim::{Light, SimConfig, Simulator, Trajectory};

/// Views of the simulator's exact, noise-free outline centres (the centroid of 96 points
/// of each circle's distorted outline, computed apart from the solver) along a
/// trajectory, every 40 ms of 12 s.
fn exact_views(trajectory: Trajectory) -> (Vec<View>, Intrinsics, f64) {
    let cfg = SimConfig::preset("davis346", "3x9", trajectory, Light::Good, 3).expect("preset");
    let c = cfg.camera;
    let truth = Intrinsics { fx: c.fx, fy: c.fy, cx: c.cx, cy: c.cy, k1: c.k1, k2: c.k2, p1: c.p1, p2: c.p2, k3: c.k3 };
    let sim = Simulator::new(cfg.clone());
    let board = cfg.board.centres();
    let views = (0..300)
        .filter_map(|i| {
            let t_us = 40_000 * i as u64;
            let frame = sim.truth_at(t_us);
            let seen: Vec<_> = frame.circles.iter().filter(|c| c.in_view).collect();
            (seen.len() >= 20).then(|| View {
                object: seen.iter().map(|c| [board[c.index][0], board[c.index][1], 0.0]).collect(),
                image: seen.iter().map(|c| c.ellipse_centre).collect(),
            })
        })
        .collect();
    (views, truth, cfg.board.radius)
}

fn fx_error(views: &[View], truth: &Intrinsics, circle_radius: Option<f64>) -> f64 {
    let opts = Options { circle_radius, ..Options::default() };
    let cal = calibrate(views, [346, 260], &opts).expect("calibration");
    100.0 * (cal.intrinsics.fx - truth.fx) / truth.fx
}

/// A circle fit measures its outline's centre, not its centre's image: on a spiral (little
/// tilt) solving as if they were the same reads fx short; modelling the outline solves
/// the exact centres exactly.
#[test]
fn outline_centres_solve_exactly_when_the_solve_models_the_outline() {
    let (views, truth, radius) = exact_views(Trajectory::Spiral);
    assert!(views.len() > 100, "{} views", views.len());
    let naive = fx_error(&views, &truth, None);
    let modelled = fx_error(&views, &truth, Some(radius));
    eprintln!("fx error: {naive:+.4} % without the outline, {modelled:+.4} % with");
    assert!(naive.abs() > 0.01, "the outline offsets bias a spiral's fx: {naive:+.4} %");
    assert!(modelled.abs() < 0.002, "with the outline modelled: fx {modelled:+.4} % (without {naive:+.4} %)");
}

/// Residuals as the calibration reports them include the outline offsets: zero on exact
/// outline centres.
#[test]
fn reported_residuals_are_against_the_modelled_outline() {
    let (views, _, radius) = exact_views(Trajectory::Cone);
    let cal = calibrate(&views, [346, 260], &Options { circle_radius: Some(radius), ..Options::default() }).unwrap();
    assert_eq!(cal.circle_radius_m, Some(radius));
    assert!(cal.rms_px < 2e-4, "RMS {}", cal.rms_px);
    let worst =
        cal.views.iter().flat_map(|r| cal.residuals(&views[r.view], r)).map(|e| e[0].hypot(e[1])).fold(0.0, f64::max);
    assert!(worst < 1e-3, "worst residual {worst} px");
}
