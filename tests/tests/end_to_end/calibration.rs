//! End to end: simulated recordings (event simulation with clutter and noise, of the
//! milliseconds each window needs) through the detection core, the grid finder and the
//! solver, against the simulator's truth.
//!
//! Checked strictly: the grid finder never pairs a point with the wrong board point (zero
//! wrong orderings, against the truth of every window, windows followed from their
//! neighbours included), every scenario gives a calibration, and each meets the issue's
//! targets: reprojection RMS ≤ 0.13 px, fx, fy within 0.1 %, cx, cy within 0.5 px, grid found
//! in ≥ 95 % of windows where it is wholly in view. The simulated pixels
//! fire late inside a blurred edge, so the centres trail their circles along the motion by
//! about a tenth of a pixel: the pipeline measures that shift from the views and takes it
//! out before the final solve, and the test checks the measurement against the trailing
//! measured from the truth. The recordings last 12 s ([`RECORDING_S`]): a calibration needs
//! views that span the motion's tilts, and on the 4 s these cases once used fx read 0.11–0.16 %
//! long from a pose set covering half the cone's tilt cycle. Over seeds (`examples/calibration_seeds.rs`) one DAVIS346 3x9 spiral seed
//! of seven reads fx +0.106 % and one dim cone seed +0.103 %; the means are within 0.07 %.
//! With the true centres in the same views the solve is exact. Windows are the host's
//! defaults (`detections::host_config`), as `evcal calibrate` cuts them: 8000 events on the
//! DAVIS346, 15 000 on the DVXplorer.
//!
//! In low light a window often holds too few events of part of the grid for the
//! finder to label it; the windows around it label the part that was seen
//! (`evcal_host::views::track`), which counts as found but is not solved on. The figures are in
//! the closing note.

use evcal_core::event::SensorSize;
use evcal_host::{
    calib::{calibrate, Intrinsics, Options, View},
    eval::{simulate, simulate_windows},
    input::detections::{self, host_config, WindowRecord},
    pipeline::{calibrate_views, views_from_windows, Outcome, Setup},
    sim::{FrameTruth, Light, SimConfig, Trajectory},
    views::grid::Pattern,
};

/// Length of the simulated recordings, seconds: 360 windows at the paper's 30 per second.
/// The cone's tilt runs through its 15–35° in 7.3 s and its roll in 9 s; a 4 s recording saw
/// half a tilt cycle, and on it fx read 0.11 % long with a standard deviation of 0.03 %
/// (seed 5), where 12 s give +0.016 % (seven seeds: +0.038 % mean, none beyond 0.064 %).
/// Windowed simulation (`eval::simulate_windows`) keeps it cheap, and
/// `windowed_simulation_calibrates_as_continuous_does` checks that it calibrates as a
/// continuous one does.
const RECORDING_S: f64 = 12.0;
/// The target for the reprojection RMS in good light (the paper's figure), px; the
/// low-light case meets it too (0.105 px) and is held to it.
const TARGET_RMS_PX: f64 = 0.13;
/// Low light has no RMS target in the issue; guarded at what the dimmest case reaches with a
/// margin.
const LOW_LIGHT_RMS_PX: f64 = 0.18;
/// The target for fx and fy, percent.
const TARGET_FOCAL_PCT: f64 = 0.1;
/// The 3 s recordings of the windowed-against-continuous comparison are too short for the
/// target (a third of the cone's tilt cycle); only gross errors are guarded there.
const SHORT_FOCAL_PCT: f64 = 0.5;

struct Case {
    sensor: &'static str,
    pattern: &'static str,
    trajectory: Trajectory,
    light: Light,
    seconds: f64,
    seed: u64,
    /// Simulate only the milliseconds each window needs (`eval::simulate_windows`, as
    /// `evcal demo` does) instead of the whole recording.
    windowed: bool,
    /// A stretch of the recording, s (from, to), whose windows are left out, as where a dim
    /// grid's discs go unfound: the views then come in bursts.
    unseen: Option<(f64, f64)>,
}

struct Figures {
    fx_pct: f64,
    fy_pct: f64,
    cx_px: f64,
    cy_px: f64,
    rms_px: f64,
    found_in_view: f64,
    /// As `found_in_view`, counting only grids of the finder's size (not parts).
    whole_in_view: f64,
    /// As `found_in_view`, counting only the grids the finder labels by itself (none
    /// followed from the windows around: what the window holds on its own).
    alone_in_view: f64,
    wrong_orderings: usize,
    views: usize,
    /// The pipeline's estimate of how far the centres trail their circles, px.
    shift_estimate: Option<f64>,
    /// The same measured against the truth: mean error of the labelled centres against the
    /// motion, px.
    shift_true: f64,
    /// fx, fy, cx, cy errors in units of the σ the calibration printed.
    error_in_sigma: [f64; 4],
    /// How many groups of views the σ came from (`None`: the points' own σ).
    sigma_groups: Option<usize>,
    /// The pipeline's calibration and the views it solved.
    outcome: Outcome,
}

fn run(case: &Case) -> Figures {
    let cfg = SimConfig::preset(case.sensor, case.pattern, case.trajectory, case.light, case.seed).unwrap();
    let cam = cfg.camera;
    let truth = Intrinsics {
        fx: cam.fx,
        fy: cam.fy,
        cx: cam.cx,
        cy: cam.cy,
        k1: cam.k1,
        k2: cam.k2,
        p1: cam.p1,
        p2: cam.p2,
        k3: cam.k3,
    };
    let pattern = Pattern::new(cfg.board.rows, cfg.board.cols, cfg.board.spacing).unwrap();
    // The host's defaults, as `evcal calibrate` runs them: windows sized to the sensor.
    let det = host_config(SensorSize { width: cam.width, height: cam.height });
    let (events, sim) = if case.windowed {
        simulate_windows(cfg, case.seconds, det.window, |_| {})
    } else {
        simulate(cfg, case.seconds)
    };
    let mut windows = Vec::new();
    detections::run(events.iter().map(|e| Ok(*e)), det, |d| windows.push(WindowRecord::from_detection(d))).unwrap();
    if let Some((from, to)) = case.unseen {
        windows.retain(|w| !(from..to).contains(&(w.t_ref_us as f64 * 1e-6)));
    }
    let truths: Vec<FrameTruth> = windows.iter().map(|w| sim.truth_at(w.t_ref_us)).collect();

    let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
    let views = views_from_windows(&windows, &setup, &|_| {});

    // Every labelled point against the truth of its window: the nearest true circle must be
    // the one it is paired with.
    let mut wrong_orderings = 0;
    let (mut trailing, mut moving) = (0.0, 0usize);
    let by_seq: std::collections::HashMap<u64, usize> =
        windows.iter().enumerate().map(|(k, w)| (u64::from(w.seq), k)).collect();
    for (view, origin) in views.views.iter().zip(&views.origins) {
        let k = by_seq[&origin.window_seq];
        let t = &truths[k];
        let wrong = view.object.iter().zip(&view.image).any(|(o, p)| {
            let nearest = t
                .circles
                .iter()
                .min_by(|a, b| {
                    let d = |c: &[f64; 2]| (c[0] - p[0]).hypot(c[1] - p[1]);
                    d(&a.ellipse_centre).total_cmp(&d(&b.ellipse_centre))
                })
                .unwrap();
            pattern.object_point(nearest.index) != *o
        });
        wrong_orderings += usize::from(wrong);
        // How far each centre trails its circle along the circle's true motion.
        let (before, after) = (sim.truth_at(windows[k].t_ref_us - 500), sim.truth_at(windows[k].t_ref_us + 500));
        for (o, p) in view.object.iter().zip(&view.image) {
            let Some(i) = (0..pattern.len()).find(|&i| pattern.object_point(i) == *o) else { continue };
            let (a, b, c) =
                (before.circles[i].ellipse_centre, after.circles[i].ellipse_centre, t.circles[i].ellipse_centre);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len = d[0].hypot(d[1]);
            if len > 0.02 {
                trailing -= ((p[0] - c[0]) * d[0] + (p[1] - c[1]) * d[1]) / len;
                moving += 1;
            }
        }
    }
    // Found where the grid is wholly in view.
    let in_view: Vec<bool> = truths.iter().map(|t| t.circles.iter().all(|c| c.in_view)).collect();
    let found_seqs: std::collections::HashSet<u64> =
        windows.iter().zip(&views.timeline).filter(|(_, s)| s.grid_found).map(|(w, _)| u64::from(w.seq)).collect();
    let n_in_view = in_view.iter().filter(|&&b| b).count();
    let found_in_view =
        windows.iter().zip(&in_view).filter(|(w, &iv)| iv && found_seqs.contains(&u64::from(w.seq))).count() as f64
            / n_in_view.max(1) as f64;
    // The same counting only grids of the finder's size (parts followed through a dim run are
    // found but not solved on): reported beside it, not guarded.
    let partial_seqs: std::collections::HashSet<u64> =
        views.origins.iter().zip(&views.partial).filter(|(_, &p)| p).map(|(o, _)| o.window_seq).collect();
    let whole_in_view = windows
        .iter()
        .zip(&in_view)
        .filter(|(w, &iv)| {
            let seq = u64::from(w.seq);
            iv && found_seqs.contains(&seq) && !partial_seqs.contains(&seq)
        })
        .count() as f64
        / n_in_view.max(1) as f64;

    let alone = views_from_windows(&windows, &Setup { track: None, ..setup.clone() }, &|_| {});
    let alone_in_view = alone.timeline.iter().zip(&in_view).filter(|(s, &iv)| iv && s.grid_found).count() as f64
        / n_in_view.max(1) as f64;

    let outcome = calibrate_views(&views, &setup).unwrap_or_else(|e| panic!("{}: {e}", case.sensor));
    let k = outcome.calibration.intrinsics;
    let sd = outcome.calibration.std_dev;
    let f = Figures {
        fx_pct: 100.0 * (k.fx / truth.fx - 1.0),
        fy_pct: 100.0 * (k.fy / truth.fy - 1.0),
        cx_px: k.cx - truth.cx,
        cy_px: k.cy - truth.cy,
        rms_px: outcome.calibration.rms_px,
        found_in_view,
        whole_in_view,
        alone_in_view,
        wrong_orderings,
        views: outcome.calibration.views.len(),
        shift_estimate: outcome.edge_shift.map(|s| s.px),
        shift_true: trailing / moving.max(1) as f64,
        error_in_sigma: [
            (k.fx - truth.fx) / sd[0],
            (k.fy - truth.fy) / sd[1],
            (k.cx - truth.cx) / sd[2],
            (k.cy - truth.cy) / sd[3],
        ],
        sigma_groups: outcome.calibration.sigma_groups,
        outcome,
    };
    println!(
        "{} {} {:?} {:?} {} s seed {}{}, {} events/window: {}; {} views used; centres trail by {:.3} px, measured {:?}; fx {:+.3} % fy {:+.3} % (± {:.3} %, target ±0.1 %), cx {:+.2} cy {:+.2} px (±0.5), RMS {:.3} px (≤ 0.13 good light); found in {:.1} % of {} wholly-in-view windows (≥ 95 %; {:.1} % as grids of the finder's size, not parts; {:.1} % by the finder alone, ≥ 90 % for the DVXplorer); wrong orderings {}",
        case.sensor,
        case.pattern,
        case.trajectory,
        case.light,
        case.seconds,
        case.seed,
        if case.windowed { " windowed" } else { "" },
        det.window.events,
        views.stats.summary(),
        f.views,
        f.shift_true,
        f.shift_estimate,
        f.fx_pct,
        f.fy_pct,
        100.0 * sd[0] / k.fx,
        f.cx_px,
        f.cy_px,
        f.rms_px,
        100.0 * f.found_in_view,
        n_in_view,
        100.0 * f.whole_in_view,
        100.0 * f.alone_in_view,
        f.wrong_orderings
    );
    f
}

/// Guards: zero wrong orderings, RMS within `rms_px` and fx and fy within `focal_pct` (the
/// issue's 0.13 px and 0.1 %, looser only for the short comparison runs), cx and cy within
/// 0.5 px, the grid found in 95 % of the windows where it is wholly in view, and the measured
/// edge shift within 0.06 px of the truth's.
fn guard(f: &Figures, rms_px: f64, focal_pct: f64) {
    assert_eq!(f.wrong_orderings, 0, "a grid was labelled wrongly");
    assert!(f.views >= 20, "only {} views", f.views);
    assert!(
        f.fx_pct.abs() < focal_pct && f.fy_pct.abs() < focal_pct,
        "fx {:+.3} %, fy {:+.3} % (limit {focal_pct} %)",
        f.fx_pct,
        f.fy_pct
    );
    // The 0.5 px for the principal point.
    assert!(f.cx_px.abs() < 0.5 && f.cy_px.abs() < 0.5, "cx {:+.2}, cy {:+.2} px", f.cx_px, f.cy_px);
    assert!(f.rms_px < rms_px, "RMS {:.3} px (limit {rms_px} px)", f.rms_px);
    // The 95 %, low light too since parts of the grid are followed (12 s, seed 5:
    // 97.7 %; 89.4 % counting only grids of the finder's size).
    let found = 0.95;
    assert!(f.found_in_view > found, "grid found in {:.1} % of in-view windows", 100.0 * f.found_in_view);
    let shift = f.shift_estimate.expect("the edge shift is measured");
    assert!(
        (shift - f.shift_true).abs() < 0.06,
        "edge shift measured {shift:.3} px, the centres trail their circles by {:.3} px",
        f.shift_true
    );
}

#[test]
fn davis346_4x11_cone_good_light() {
    let f = run(&Case {
        sensor: "davis346",
        pattern: "4x11",
        trajectory: Trajectory::Cone,
        light: Light::Good,
        seconds: RECORDING_S,
        seed: 5,
        windowed: true,
        unseen: None,
    });
    guard(&f, TARGET_RMS_PX, TARGET_FOCAL_PCT);
}

#[test]
fn davis346_4x11_cone_low_light() {
    let f = run(&Case {
        sensor: "davis346",
        pattern: "4x11",
        trajectory: Trajectory::Cone,
        light: Light::Low,
        seconds: RECORDING_S,
        seed: 5,
        windowed: true,
        unseen: None,
    });
    guard(&f, TARGET_RMS_PX, TARGET_FOCAL_PCT);
}

#[test]
fn davis346_3x9_spiral_good_light() {
    let f = run(&Case {
        sensor: "davis346",
        pattern: "3x9",
        trajectory: Trajectory::Spiral,
        light: Light::Good,
        seconds: RECORDING_S,
        seed: 5,
        windowed: true,
        unseen: None,
    });
    guard(&f, TARGET_RMS_PX, TARGET_FOCAL_PCT);
}

/// On 3 s of recording the views lie in 6 half-second stretches, too few for a grouped σ,
/// and the points' own σ (every point's error taken as independent) left fy's error beyond
/// 3σ in 5 of 8 seeds (these two: 4.2σ and 5.6σ). Shorter stretches for short recordings
/// (`calib::group_seconds`) give the grouped σ, and it covers every error within 3σ.
#[test]
fn a_short_recordings_sigma_covers_its_error() {
    grouped_sigma_covers_the_error(3.0, None);
}

/// A grid seen in bursts (its windows between 0.5 and 3.2 s left out, as a dim grid's are
/// where its discs go unfound) spans 5 s but lies in 5 half-seconds, too few for a grouped σ;
/// on the same bursts of a dim DVXplorer's discs the points' own σ left cy 5σ off. Groups
/// as long as the views ask for (`calib::group_seconds`) give the grouped σ, and it covers
/// every error within 3σ.
#[test]
fn a_grid_seen_in_bursts_gets_a_grouped_sigma_that_covers_its_error() {
    grouped_sigma_covers_the_error(5.0, Some((0.5, 3.2)));
}

/// On `seconds` of a simulated DAVIS346 cone in good light (seeds 3 and 8), with `unseen`
/// left out: the σ came from groups of views, and it covers every error within 3σ; and it
/// is not inflated: σ(fx) at most [`MAX_SIGMA_OVER_DRAWS`] times what noise draws at the
/// centres' own scatter give ([`noise_draws_sigma_fx`]), whose spread the points' own σ
/// reproduces within ×0.6–1.6 (measured ×0.77–0.95 against 256 draws: the solve weighs
/// precise centres more, which noise of one σ for all points does not reward).
fn grouped_sigma_covers_the_error(seconds: f64, unseen: Option<(f64, f64)>) {
    for seed in [3, 8] {
        let f = run(&Case {
            sensor: "davis346",
            pattern: "4x11",
            trajectory: Trajectory::Cone,
            light: Light::Good,
            seconds,
            seed,
            windowed: true,
            unseen,
        });
        assert!(
            f.sigma_groups.is_some_and(|g| g >= evcal_host::calib::GROUPS_WANTED),
            "seed {seed}: {:?}",
            f.sigma_groups
        );
        assert!(
            f.error_in_sigma.iter().all(|z| z.abs() <= 3.0),
            "seed {seed}: errors in σ (fx, fy, cx, cy) {:?}",
            f.error_in_sigma
        );
        // The other way: σ not inflated. The points' own σ must reproduce what noise of the
        // centres' own scatter does to fx, and the printed σ may exceed that only by what
        // errors shared across windows and the few groups' widening explain.
        let draws = noise_draws_sigma_fx(&f.outcome, seed);
        let cal = &f.outcome.calibration;
        let (points, printed) = (cal.std_dev_points[0] / draws, cal.std_dev[0] / draws);
        println!(
            "seed {seed}: σ(fx) of {NOISE_DRAWS} noise draws {draws:.4} px; the points' own σ ×{points:.3} of it, the printed ×{printed:.3}"
        );
        assert!(
            (0.6..=1.6).contains(&points),
            "seed {seed}: the points' own σ(fx) is ×{points:.3} of the {NOISE_DRAWS} draws' {draws:.4} px"
        );
        assert!(
            printed <= MAX_SIGMA_OVER_DRAWS,
            "seed {seed}: the printed σ(fx) is ×{printed:.3} of the {NOISE_DRAWS} draws' {draws:.4} px (limit ×{MAX_SIGMA_OVER_DRAWS})"
        );
    }
}

/// How many times the views of a calibration are solved anew with noise of their own
/// scatter ([`noise_draws_sigma_fx`]): the σ of 64 draws is known to about ±9 % (1σ,
/// 1/√(2 (64 − 1))). 16 draws (±18 %) put the points' own σ at ×0.575 of theirs on seed 3
/// of 3 s, where 64 and 256 draws put it at ×0.786 and ×0.768; a draw costs 0.04 s.
const NOISE_DRAWS: usize = 64;

/// Most the printed σ(fx) may be over what [`NOISE_DRAWS`] noise draws at the centres' own
/// scatter give. It is legitimately larger: a centre's error persists over neighbouring
/// windows, so groups of views err alike (the grouped σ), and 8 groups widen it ×1.51
/// (`calib::few_groups_factor`). Measured on 3 s of the good-light cone (seeds 3, 8, 5, 1):
/// ×3.05, 3.09, 2.42, 2.75 against 256 draws (×3.12, 3.59, 2.48, 2.82 against 64); on the
/// bursts of 5 s (seeds 3, 8): ×1.63, 2.08 (×1.77, 1.97). ×5 leaves a margin of ×1.4 over
/// the largest; a σ three times today's exceeds it on every seed of 3 s (×7.3 and more).
const MAX_SIGMA_OVER_DRAWS: f64 = 5.0;

/// The σ of fx over [`NOISE_DRAWS`] solves of `outcome`'s views made anew: each view the
/// solve kept, its board points where the solved model (intrinsics, the view's pose, the
/// circles' outlines) puts them, plus Gaussian noise of the centres' own scatter, each
/// solved as `evcal_host::calib::calibrate` does by default (the circles' radius modelled,
/// no view times: every point's error independent), seeded by `seed`.
fn noise_draws_sigma_fx(outcome: &Outcome, seed: u64) -> f64 {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let cal = &outcome.calibration;
    // The model's points: each used view's (shifted) centres plus their residuals.
    let modelled: Vec<View> = cal
        .views
        .iter()
        .map(|r| {
            let view = &outcome.used[r.view];
            let image =
                view.image.iter().zip(cal.residuals(view, r)).map(|(m, d)| [m[0] + d[0], m[1] + d[1]]).collect();
            View { object: view.object.clone(), image }
        })
        .collect();
    // `rms_px` is the RMS of 2-D distances over the points kept (strays out): for isotropic
    // Gaussian noise of σ per coordinate its square is 2σ², less the share the solve's
    // parameters (the free intrinsics, 6 per view) fit away of the 2n coordinates.
    let points = cal.views.iter().map(|r| r.points).sum::<usize>() - cal.stray_points;
    let coords = 2.0 * points as f64;
    let fitted = (cal.std_dev_points.iter().filter(|&&s| s > 0.0).count() + 6 * cal.views.len()) as f64;
    let sigma_px = cal.rms_px / std::f64::consts::SQRT_2 * (coords / (coords - fitted)).sqrt();
    let noise = Normal::new(0.0, sigma_px).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x5167_0000 + seed);
    let opts = Options { circle_radius: cal.circle_radius_m, ..Options::default() };
    let fx: Vec<f64> = (0..NOISE_DRAWS)
        .map(|_| {
            let noisy: Vec<View> = modelled
                .iter()
                .map(|v| View {
                    object: v.object.clone(),
                    image: v
                        .image
                        .iter()
                        .map(|m| [m[0] + noise.sample(&mut rng), m[1] + noise.sample(&mut rng)])
                        .collect(),
                })
                .collect();
            calibrate(&noisy, cal.image_size, &opts).unwrap().intrinsics.fx
        })
        .collect();
    let mean = fx.iter().sum::<f64>() / fx.len() as f64;
    (fx.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (fx.len() - 1) as f64).sqrt()
}

/// A smoke case of the DVXplorer for CI's fast tier ([`slow`] holds its full cases): 3 s of
/// the good-light cone, too short for the focal length's target (a third of the cone's tilt
/// cycle, as [`SHORT_FOCAL_PCT`] says), but every other guard of the 12 s case: no wrong
/// ordering, the grid found, by the finder alone too, in the sensor's own windows.
#[test]
fn dvxplorer_4x11_cone_smoke() {
    let f = run(&Case {
        sensor: "dvxplorer",
        pattern: "4x11",
        trajectory: Trajectory::Cone,
        light: Light::Good,
        seconds: 3.0,
        seed: 5,
        windowed: true,
        unseen: None,
    });
    guard(&f, TARGET_RMS_PX, SHORT_FOCAL_PCT);
    assert!(
        f.alone_in_view >= 0.90,
        "the finder alone labels the grid in {:.1} % of in-view windows",
        100.0 * f.alone_in_view
    );
}

/// The DVXplorer's cases at full length and the windowed simulation against the continuous one:
/// minutes of CPU each (a 640x480 sensor's 12 s, 100–145 s; the continuous simulation 57 s),
/// run by the slow tier. CI's fast tier holds [`dvxplorer_4x11_cone_smoke`].
mod slow {
    use super::*;

    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn dvxplorer_4x11_cone_good_light() {
        let f = run(&Case {
            sensor: "dvxplorer",
            pattern: "4x11",
            trajectory: Trajectory::Cone,
            light: Light::Good,
            seconds: RECORDING_S,
            seed: 5,
            windowed: true,
            unseen: None,
        });
        guard(&f, TARGET_RMS_PX, TARGET_FOCAL_PCT);
        // The target for windows sized to the sensor: the finder labels the grid by
        // itself in 90 % of the windows where it is wholly in view (15 000-event windows: 100 %,
        // RMS 0.041 px; 7500: 94.4 %, 0.069 px; 4000, the paper's size for a DAVIS346: 78.9 %,
        // the rest followed from the windows around them, 0.111 px).
        assert!(
            f.alone_in_view >= 0.90,
            "the finder alone labels the grid in {:.1} % of in-view windows",
            100.0 * f.alone_in_view
        );
    }

    /// The DVXplorer in low light: its far columns often too dim for the core, the case in which
    /// the finder once labelled a grid two columns off (a background disc lined up beyond the
    /// seen columns; seed 2, window 297; see `grid::place`). The issue sets no RMS target for low
    /// light; this one reached 0.164 px with 4000-event windows (seeds 1, 5: 0.141, 0.143 before
    /// the 1.75 px give-up of clutter fits), 0.090 px with 7500, 0.054 px with the host's 15 000.
    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn dvxplorer_4x11_cone_low_light() {
        let f = run(&Case {
            sensor: "dvxplorer",
            pattern: "4x11",
            trajectory: Trajectory::Cone,
            light: Light::Low,
            seconds: RECORDING_S,
            seed: 2,
            windowed: true,
            unseen: None,
        });
        guard(&f, LOW_LIGHT_RMS_PX, TARGET_FOCAL_PCT);
    }

    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn dvxplorer_3x9_spiral_good_light() {
        let f = run(&Case {
            sensor: "dvxplorer",
            pattern: "3x9",
            trajectory: Trajectory::Spiral,
            light: Light::Good,
            seconds: RECORDING_S,
            seed: 5,
            windowed: true,
            unseen: None,
        });
        guard(&f, TARGET_RMS_PX, TARGET_FOCAL_PCT);
    }

    /// `evcal demo` simulates only the milliseconds each window needs, jumping between window
    /// ticks (`Simulator::skip_to`). The pipeline's edge-shift measurement had been validated on
    /// continuous simulations only: here the demo's own case (seed 1, 3 s) both ways, each
    /// against its own truth. The centres must trail their circles as far after jumps as in a
    /// continuous run (a jump that left each pixel's reference within one threshold of its
    /// present level made them trail by 0.01 px instead of 0.13), the pipeline must measure
    /// that, and the calibrations must agree within their scatter from seed to seed (0.05 %).
    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn windowed_simulation_calibrates_as_continuous_does() {
        let case = |windowed| Case {
            sensor: "davis346",
            pattern: "4x11",
            trajectory: Trajectory::Cone,
            light: Light::Good,
            seconds: 3.0,
            seed: 1,
            windowed,
            unseen: None,
        };
        let (c, w) = (run(&case(false)), run(&case(true)));
        guard(&c, TARGET_RMS_PX, SHORT_FOCAL_PCT);
        guard(&w, TARGET_RMS_PX, SHORT_FOCAL_PCT);
        assert!(
            (w.shift_true - c.shift_true).abs() < 0.03,
            "centres trail their circles by {:.3} px after jumps, {:.3} px in a continuous run",
            w.shift_true,
            c.shift_true
        );
        let (ws, cs) = (w.shift_estimate.unwrap(), c.shift_estimate.unwrap());
        assert!((ws - cs).abs() < 0.03, "edge shift measured {ws:.3} px after jumps, {cs:.3} px in a continuous run");
        assert!(
            (w.fx_pct - c.fx_pct).abs() < 0.15 && (w.fy_pct - c.fy_pct).abs() < 0.15,
            "fx {:+.3} % fy {:+.3} % after jumps, fx {:+.3} % fy {:+.3} % in a continuous run",
            w.fx_pct,
            w.fy_pct,
            c.fx_pct,
            c.fy_pct
        );
        assert!(
            (w.rms_px - c.rms_px).abs() < 0.03,
            "RMS {:.3} px after jumps, {:.3} px in a continuous run",
            w.rms_px,
            c.rms_px
        );
    }
}
