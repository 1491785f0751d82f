//! From detection windows to a calibration: the grid in each window, views, the views
//! chosen, the solve, and what the coverage says about it.
//!
//! Data flows one way: [`views_from_windows`] turns windows into views (with the grid
//! finder's tally), [`calibrate_views`] chooses among them and solves. `evcal calibrate`,
//! `evcal demo` and the end-to-end tests all go through here.

use crate::calib::{self, k3_displacement_px, CalibError, Calibration, View, K3_NEGLIGIBLE_PX};
use crate::input::detections::WindowRecord;
use crate::views::edge_shift::{self, EdgeShift};
use crate::views::grid::{find_grid, FindOptions, GridDetection, Miss, Pattern};
use crate::views::select::{advice, select_views, Coverage, SelectOptions, Selection};
use crate::views::smooth::{smoothed, SmoothOptions, SmoothStats};
use crate::views::track::{follow, TrackOptions};
use crate::views::{ViewOrigin, WindowSample};
use std::collections::BTreeMap;
use std::fmt;

/// What the run is told: the target, the sensor, and how each step behaves.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The target.
    pub pattern: Pattern,
    /// Sensor width and height, px.
    pub image_size: [u32; 2],
    /// What the grid finder accepts.
    pub find: FindOptions,
    /// How windows the finder missed are labelled from their neighbours in time; `None`
    /// to take only what the finder labels window by window.
    pub track: Option<TrackOptions>,
    /// How each point's centre is re-estimated from the windows around its view
    /// ([`crate::views::smooth`]); `None` to solve on the centres as detected.
    pub smooth: Option<SmoothOptions>,
    /// How views are chosen.
    pub select: SelectOptions,
    /// What the solve may change.
    pub calib: calib::Options,
    /// A circle whose fitted outline comes closer than this to the sensor's border is left
    /// out of its view, px: the sensor cut its arc, and a fit to part of a ring is biased.
    pub edge_margin_px: f64,
    /// Measure how far the centres trail their circles along the motion and solve on
    /// centres moved back by that much ([`edge_shift`]).
    pub edge_shift: bool,
    /// Radius of the board's circles, metres, when known; `None` to estimate it from the
    /// fitted radii ([`Views::circle_radius_m`]). The solve models where each circle's
    /// outline centre lies ([`calib::Options::circle_radius`]); `calib.circle_radius`, when
    /// set, wins over both.
    pub circle_radius: Option<f64>,
}

impl Setup {
    /// Defaults for `pattern` on a sensor of `image_size`.
    pub fn new(pattern: Pattern, image_size: [u32; 2]) -> Self {
        Self {
            pattern,
            image_size,
            find: FindOptions::default(),
            track: Some(TrackOptions::default()),
            smooth: Some(SmoothOptions::default()),
            select: SelectOptions::default(),
            calib: calib::Options::default(),
            edge_margin_px: 1.0,
            edge_shift: true,
            circle_radius: None,
        }
    }
}

/// How the grid finder fared over the windows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GridStats {
    /// Windows looked at.
    pub windows: usize,
    /// Windows in which the grid was found (by the finder, or followed from the windows
    /// around it).
    pub found: usize,
    /// Of those, the windows labelled from their neighbours in time ([`crate::views::track`]).
    pub followed: usize,
    /// Of those, the ones holding fewer points than the finder asks of a grid of its own
    /// (see [`Views::partial`]): found, but not solved on.
    pub partial: usize,
    /// Windows without a grid, by reason.
    pub misses: BTreeMap<Miss, usize>,
    /// Grid points left out because their circle touched the sensor's border.
    pub points_at_edge: usize,
    /// Grids found that kept too few points once those were left out.
    pub too_few_after_edge: usize,
}

impl GridStats {
    /// One line for users: found in how many windows, and why not in the rest.
    pub fn summary(&self) -> String {
        let mut s = format!("grid found in {} of {} windows", self.found, self.windows);
        if self.followed > 0 {
            s += &format!(" ({} of them followed from the windows around them", self.followed);
            if self.partial > 0 {
                s += &format!(", {} of those part of the grid only, not solved on", self.partial);
            }
            s += ")";
        }
        if !self.misses.is_empty() {
            let why: Vec<String> = self.misses.iter().map(|(m, n)| format!("{n} {m}")).collect();
            s += &format!(" (not found: {})", why.join(", "));
        }
        if self.points_at_edge > 0 {
            s += &format!("; {} points at the sensor's border left out", self.points_at_edge);
        }
        s
    }
}

/// The views a run's windows give.
#[derive(Debug, Clone, Default)]
pub struct Views {
    /// One view per window whose grid was found, in window order.
    pub views: Vec<View>,
    /// Where each view came from.
    pub origins: Vec<ViewOrigin>,
    /// Per view, per point (as in `views`): how thick the circle's edge looked, the fit's
    /// spread of events about it, px ([`GridPoint::spread_px`](crate::views::grid::GridPoint::spread_px)). Empty: not known.
    pub spreads: Vec<Vec<f64>>,
    /// Per view, per point (as in `views`): how many events its circle's fit used
    /// ([`GridPoint::events`](crate::views::grid::GridPoint::events)), what the solve weighs
    /// it by (`calib::Options::precision_hints`). Empty: not known.
    pub events: Vec<Vec<u16>>,
    /// Per view: its grid was followed from the windows around it and holds fewer points
    /// than the finder asks of a grid of its own ([`FindOptions::min_fraction`]). Such a
    /// view is labelled right (its labels come from its neighbours), and its centres help
    /// smooth its neighbours' ([`crate::views::smooth`]), but it is not solved on: these are
    /// windows in which part of the board fired too few events (a dim scene), and with them
    /// in the solve fx read 0.03 % longer on every one of seven simulated dim recordings
    /// (DAVIS346 4x11 cone, mean +0.118 % against +0.088 % without them), for no smaller
    /// standard deviation. An empty list means none is partial.
    pub partial: Vec<bool>,
    /// Every window, for the report's timeline.
    pub timeline: Vec<WindowSample>,
    /// The grid finder's tally.
    pub stats: GridStats,
    /// The board's circle radius as the views show it, metres: the median over every point
    /// of the solvable views of its fitted radius over the local scale of its view's
    /// homography (pixels per metre there). `None` without such views.
    pub circle_radius_m: Option<f64>,
}

/// The grid of one window as a view, with points at the sensor's border left out; also
/// each point's spread and events (as [`Views::spreads`], [`Views::events`]) and how many
/// points were left out.
pub fn view_of(grid: &GridDetection, setup: &Setup) -> (View, Vec<f64>, Vec<u16>, usize) {
    let [w, h] = setup.image_size.map(f64::from);
    let m = setup.edge_margin_px;
    let mut view = View { object: Vec::with_capacity(grid.points.len()), image: Vec::with_capacity(grid.points.len()) };
    let mut spreads = Vec::with_capacity(grid.points.len());
    let mut events = Vec::with_capacity(grid.points.len());
    let mut at_edge = 0;
    for p in &grid.points {
        let [u, v] = p.image;
        let r = p.radius_px + m;
        // Pixel centres run from 0 to size − 1; the sensor's border is half a pixel out.
        if u - r < -0.5 || v - r < -0.5 || u + r > w - 0.5 || v + r > h - 0.5 {
            at_edge += 1;
            continue;
        }
        view.object.push(setup.pattern.object_point(p.index));
        view.image.push(p.image);
        spreads.push(p.spread_px);
        events.push(p.events);
    }
    (view, spreads, events, at_edge)
}

/// Finds the grid in every window and makes views of it. `progress` is called with the
/// number of windows done so far (from one thread at a time, in no fixed order of calls).
pub fn views_from_windows(windows: &[WindowRecord], setup: &Setup, progress: &(dyn Fn(usize) + Sync)) -> Views {
    // Windows are independent: split them over the cores; each result lands at its index.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(8);
    let chunk = windows.len().div_ceil(threads).max(1);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let found: Vec<Result<GridDetection, Miss>> = std::thread::scope(|s| {
        let handles: Vec<_> = windows
            .chunks(chunk)
            .map(|part| {
                let done = &done;
                s.spawn(move || {
                    part.iter()
                        .map(|w| {
                            let r = find_grid(&w.centers, &setup.pattern, &setup.find);
                            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
                            r
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_default()).collect()
    });
    let followed = match &setup.track {
        Some(opts) => follow(windows, &found, &setup.pattern, opts),
        None => vec![None; found.len()],
    };
    let t0 = windows.first().map_or(0, |w| w.t_ref_us);
    let mut out = Views::default();
    let mut radii = Vec::new();
    out.stats.windows = windows.len();
    let needed = calib::MIN_POINTS_PER_VIEW;
    // The finder's own minimum, as it counts it.
    let finder_minimum =
        ((setup.find.min_fraction.clamp(0.0, 1.0) * setup.pattern.len() as f64).ceil() as usize).max(6);
    for ((w, r), f) in windows.iter().zip(found).zip(followed) {
        let t_s = w.t_ref_us.saturating_sub(t0) as f64 * 1e-6;
        let (r, partial) = match (r, f) {
            (Err(_), Some(g)) => {
                out.stats.followed += 1;
                let partial = g.points.len() < finder_minimum;
                out.stats.partial += usize::from(partial);
                (Ok(g), partial)
            }
            (r, _) => (r, false),
        };
        let grid_found = match r {
            Ok(g) => {
                out.stats.found += 1;
                if !partial {
                    radii.extend(radii_of(&g, &setup.pattern));
                }
                let (view, spreads, events, at_edge) = view_of(&g, setup);
                out.stats.points_at_edge += at_edge;
                if view.object.len() >= needed {
                    out.views.push(view);
                    out.spreads.push(spreads);
                    out.events.push(events);
                    out.origins.push(ViewOrigin { window_seq: u64::from(w.seq), t_s });
                    out.partial.push(partial);
                } else {
                    out.stats.too_few_after_edge += 1;
                }
                true
            }
            Err(m) => {
                *out.stats.misses.entry(m).or_default() += 1;
                false
            }
        };
        out.timeline.push(WindowSample { t_s, centres: w.centers.len(), grid_found });
    }
    out.circle_radius_m = median(&mut radii);
    out
}

/// Each point's circle radius in metres, as `grid` shows it: its fitted radius (px) over the
/// local scale of the homography from the board to the image (px per metre at the point).
/// Empty when no homography fits. Circle fits run short of the true radius by a few tenths
/// of a pixel (a DVS pixel fires once the log intensity has moved by a threshold, inside a
/// blurred edge), which the outline offsets feel squared: a 5 % short radius leaves 10 % of
/// the offsets, a few thousandths of a pixel.
fn radii_of(grid: &GridDetection, pattern: &Pattern) -> Vec<f64> {
    let object: Vec<[f64; 2]> = grid
        .points
        .iter()
        .map(|p| {
            let o = pattern.object_point(p.index);
            [o[0], o[1]]
        })
        .collect();
    let image: Vec<[f64; 2]> = grid.points.iter().map(|p| p.image).collect();
    let Some(h) = calib::fit_homography(&object, &image) else { return Vec::new() };
    object
        .iter()
        .zip(&grid.points)
        .filter_map(|(&[x, y], p)| {
            // The Jacobian of (u, v) = (h0 x + h1 y + h2, h3 x + h4 y + h5) / (h6 x + h7 y + h8).
            let w = h[6] * x + h[7] * y + h[8];
            let (u, v) = ((h[0] * x + h[1] * y + h[2]) / w, (h[3] * x + h[4] * y + h[5]) / w);
            let j = [(h[0] - u * h[6]) / w, (h[1] - u * h[7]) / w, (h[3] - v * h[6]) / w, (h[4] - v * h[7]) / w];
            let scale = (j[0] * j[3] - j[1] * j[2]).abs().sqrt();
            let r = p.radius_px / scale;
            (r.is_finite() && r > 0.0).then_some(r)
        })
        .collect()
}

/// The median of `x` (reordered), `None` when empty.
fn median(x: &mut [f64]) -> Option<f64> {
    if x.is_empty() {
        return None;
    }
    let mid = x.len() / 2;
    let (_, m, _) = x.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// A calibration and what stands behind it.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The views chosen (indices into the views offered) and why the others were not.
    pub selection: Selection,
    /// The chosen views, in the order the solver saw them (centres moved by `edge_shift`).
    pub used: Vec<View>,
    /// Where each chosen view came from.
    pub used_origins: Vec<ViewOrigin>,
    /// What smoothing the centres along their paths did, when it was on.
    pub smoothing: Option<SmoothStats>,
    /// How far the centres trailed their circles along the motion, when measured; the
    /// solve saw them moved forward by that much.
    pub edge_shift: Option<EdgeShift>,
    /// The solve.
    pub calibration: Calibration,
    /// The same views solved with k3 fixed at 0, for exports whose model has no k3
    /// (Kalibr's radtan), when k3 is not negligible; `None` otherwise.
    pub without_k3: Option<Calibration>,
    /// Where on the sensor the chosen views' points fell.
    pub coverage: Coverage,
    /// What the user should know about the views, and what motion would help.
    pub advice: Vec<String>,
    /// Why the result is no calibration at all, when the views leave a parameter so loose
    /// that no value printed could be trusted ([`verdict`]); `None` for a calibration.
    pub failure: Option<String>,
}

/// Why no calibration came out.
#[derive(Debug, Clone, PartialEq)]
pub enum PipelineError {
    /// No window held the grid.
    NoGrid(GridStats),
    /// The solve failed.
    Calib(CalibError),
}

impl fmt::Display for PipelineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PipelineError::NoGrid(s) if s.windows == 0 => write!(f, "no detection windows to look for the grid in"),
            PipelineError::NoGrid(s) => {
                write!(
                    f,
                    "{}: check --pattern (ROWSxCOLS as the board is printed) and that the board is in view",
                    s.summary()
                )?;
                // Most windows short of circles: the rings themselves were not there.
                let short = s.misses.get(&Miss::TooFewCentres).copied().unwrap_or(0);
                if 2 * short > s.windows {
                    write!(
                        f,
                        "; in {short} windows the core found fewer circles than the grid has, so the circles did not show as clean rings of events: in dim light the pixels answer slowly and smear each edge over many pixels (more light helps most), and a board out of focus, moving too fast to follow or barely moving does the same"
                    )?;
                }
                Ok(())
            }
            PipelineError::Calib(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for PipelineError {}

/// Indices of the views that may be solved on: all but the partial ones.
fn solvable(views: &Views) -> Vec<usize> {
    (0..views.views.len()).filter(|&i| !views.partial.get(i).copied().unwrap_or(false)).collect()
}

/// Chooses among `views` and solves.
pub fn calibrate_views(views: &Views, setup: &Setup) -> Result<Outcome, PipelineError> {
    if views.views.is_empty() {
        return Err(PipelineError::NoGrid(views.stats.clone()));
    }
    let (all_views, smoothing) = match &setup.smooth {
        Some(opts) => {
            let (v, s) = smoothed(&views.views, &views.origins, opts);
            (v, Some(s))
        }
        None => (views.views.clone(), None),
    };
    // Partial views are left out before the selection, so that none takes the place of a
    // whole view of nearly the same pose as a near-duplicate.
    let offered = solvable(views);
    let offered_views: Vec<View> = offered.iter().map(|&i| all_views[i].clone()).collect();
    let mut selection = select_views(&offered_views, &setup.select);
    selection.chosen = selection.chosen.iter().map(|&j| offered[j]).collect();
    let mut used: Vec<View> = selection.chosen.iter().map(|&i| all_views[i].clone()).collect();
    let used_origins: Vec<ViewOrigin> = selection.chosen.iter().map(|&i| views.origins[i]).collect();
    let mut calib_opts = setup.calib.clone();
    calib_opts.circle_radius = calib_opts.circle_radius.or(setup.circle_radius).or(views.circle_radius_m);
    let setup = &Setup { calib: calib_opts, ..setup.clone() };
    let mut edge_shift = None;
    let mut shift_directions = Vec::new();
    let mut bend_directions = Vec::new();
    let mut alternative = None;
    if setup.edge_shift {
        // Directions come from every view's neighbours, chosen or not.
        let (all, bends) = edge_shift::directions_and_bends(&all_views, &views.origins);
        let dirs: Vec<Vec<[f64; 2]>> = selection.chosen.iter().map(|&i| all[i].clone()).collect();
        let spreads: Vec<&[f64]> =
            selection.chosen.iter().filter_map(|&i| views.spreads.get(i).map(|s| &s[..])).collect();
        // The other model of the lag, solved as the chosen one is (see `ByThickness`).
        alternative = edge_shift::scaled_by_thickness(&dirs, &spreads).and_then(|d| {
            let s = edge_shift::estimate(&used, &d, setup.image_size, &setup.calib)?;
            Some((edge_shift::shifted(&used, &d, s.px), d, s.px))
        });
        edge_shift = edge_shift::estimate(&used, &dirs, setup.image_size, &setup.calib);
        if let Some(s) = edge_shift {
            used = edge_shift::shifted(&used, &dirs, s.px);
            shift_directions = dirs;
            bend_directions = selection.chosen.iter().map(|&i| bends[i].clone()).collect();
        }
    }
    // Views of one stretch of the recording err alike; the σ printed must know it.
    let mut grouped = calib::Options {
        view_times: used_origins.iter().map(|o| o.t_s).collect(),
        precision_hints: selection
            .chosen
            .iter()
            .filter_map(|&i| views.events.get(i).map(|e| e.iter().map(|&n| f64::from(n)).collect()))
            .collect(),
        shift_directions,
        ..setup.calib.clone()
    };
    let mut calibration = calib::calibrate(&used, setup.image_size, &grouped).map_err(PipelineError::Calib)?;
    // Further moves the views measure (see `edge_shift`'s note): on slanted outlines the
    // shift leans across the motion, and a slow pixel's lag bends with the speed. Solved once
    // more to estimate them together, then again on the centres they move, where they count
    // in the σ as the shift does.
    let mut applied: Vec<(Vec<Vec<[f64; 2]>>, f64)> = Vec::new();
    if let Some(s) = edge_shift.as_mut() {
        let lean = setup
            .calib
            .circle_radius
            .map(|r| (false, edge_shift::across_outlines(&used, &grouped.shift_directions, &calibration, r)));
        let bend = (bend_directions.len() == used.len()).then_some((true, bend_directions));
        let candidates: Vec<(bool, Vec<Vec<[f64; 2]>>)> = lean.into_iter().chain(bend).collect();
        let probe = calib::Options { moves: candidates.iter().map(|c| c.1.clone()).collect(), ..grouped.clone() };
        let estimates = match candidates.is_empty() {
            true => Vec::new(),
            false => calib::calibrate(&used, setup.image_size, &probe).map(|c| c.moves).unwrap_or_default(),
        };
        let mut moved = used.clone();
        let mut found = (None, None);
        for ((is_bend, dirs), e) in candidates.into_iter().zip(estimates) {
            let Some(e) = e else { continue };
            let px = edge_shift::shrunk(e.step, e.std);
            moved = edge_shift::shifted(&moved, &dirs, px);
            let m = Some(edge_shift::Lean { px: e.step, std_px: e.std, used_px: px });
            *(if is_bend { &mut found.1 } else { &mut found.0 }) = m;
            applied.push((dirs, px));
        }
        if !applied.is_empty() {
            let opts = calib::Options { moves: applied.iter().map(|a| a.0.clone()).collect(), ..grouped.clone() };
            match calib::calibrate(&moved, setup.image_size, &opts) {
                Ok(c) => {
                    (s.lean, s.bend) = found;
                    (calibration, used, grouped) = (c, moved, opts);
                }
                Err(_) => applied.clear(),
            }
        }
    }
    // What the views cannot tell apart is uncertain: the lag's other model's answer counts.
    if let (Some(s), Some((views, dirs, px))) = (edge_shift.as_mut(), alternative) {
        // With the same further moves (their own, whichever model the shift follows).
        let views = applied.iter().fold(
            views,
            |v, (d, px)| {
                if d.len() == v.len() {
                    edge_shift::shifted(&v, d, *px)
                } else {
                    v
                }
            },
        );
        let opts = calib::Options { shift_directions: dirs, ..grouped.clone() };
        if let Ok(alt) = calib::calibrate(&views, setup.image_size, &opts) {
            let (a, b) = (alt.intrinsics.to_array(), calibration.intrinsics.to_array());
            let change: [f64; 9] = std::array::from_fn(|i| a[i] - b[i]);
            if change.iter().all(|c| c.is_finite()) {
                for (sd, c) in calibration.std_dev.iter_mut().zip(change) {
                    *sd = sd.hypot(c);
                }
                s.by_thickness = Some(edge_shift::ByThickness { px, change });
            }
        }
    }
    // The shift's σ as a parameter of the final solve, where its scatter over the groups of
    // views counts too.
    if let (Some(s), Some(sd)) = (edge_shift.as_mut(), calibration.shift_std_px) {
        s.std_px = s.std_px.max(sd);
    }
    let without_k3 =
        if !setup.calib.fix_k3 && k3_displacement_px(&calibration.intrinsics, setup.image_size) > K3_NEGLIGIBLE_PX {
            let opts = calib::Options { fix_k3: true, ..grouped.clone() };
            calib::calibrate(&used, setup.image_size, &opts).ok()
        } else {
            None
        };
    let kept: Vec<&View> = calibration.views.iter().filter_map(|v| used.get(v.view)).collect();
    let coverage = Coverage::of(&kept, setup.image_size);
    let mut advice = advice(&calibration, &coverage);
    let lag = edge_shift.and_then(|s| s.by_thickness).map(|b| b.change);
    advice.extend(focal_warning(&calibration, &coverage, lag.as_ref()));
    let failure = verdict(&calibration);
    Ok(Outcome {
        selection,
        used,
        used_origins,
        smoothing,
        edge_shift,
        calibration,
        without_k3,
        coverage,
        advice,
        failure,
    })
}

/// A focal length looser than this (1σ, relative) is worth a warning: the accuracy evcal
/// aims at.
pub const FOCAL_WARN_RELATIVE: f64 = 1e-3;
/// A focal length looser than this (1σ, relative), or a principal point looser than this
/// fraction of the sensor's size, is no calibration: a lens's focal length is known to
/// about this from its data sheet.
pub const FAILED_RELATIVE: f64 = 0.05;

/// A warning when σ(fx) or σ(fy) exceeds [`FOCAL_WARN_RELATIVE`], with the motion that fixes
/// the focal length: more tilt when the views lack it, else more of the sensor and more
/// views; and, when `lag` (what the edges' other lag model changes:
/// [`edge_shift::ByThickness`]) is most of σ, light enough for quick pixels.
fn focal_warning(cal: &Calibration, coverage: &Coverage, lag: Option<&[f64; 9]>) -> Option<String> {
    let k = &cal.intrinsics;
    let rel = (cal.std_dev[0] / k.fx.abs()).max(cal.std_dev[1] / k.fy.abs());
    (rel > FOCAL_WARN_RELATIVE).then(|| {
        let tilt = crate::views::select::TiltSpread::of(cal);
        let fix = if tilt.max_deg < crate::views::select::GOOD_TILT_DEG {
            format!(
                "the views tilt the target by at most {:.0}°: only tilt tells the focal length from the distance (a target facing the sensor looks the same to a focal length twice as long from twice as far, its distortion rescaled to match, however near it comes). Record a cone: tilt the target 20–40° towards each side in turn while it sweeps the sensor",
                tilt.max_deg
            )
        } else {
            format!(
                "{} views, their points on {:.0} % of the sensor: record longer, tilting the target 20–40° to each side while it sweeps the whole sensor (in brighter light if the grid was missed in many windows)",
                cal.views.len(),
                100.0 * coverage.covered
            )
        };
        // Most of σ(fx) from the lag's model: the pixels are slow or the edges blurred.
        let lag_note = match lag {
            Some(c) if c[0].abs() > std::f64::consts::FRAC_1_SQRT_2 * cal.std_dev[0] => format!(
                "; most of it is how late the edges were seen (taking the lag in proportion to each edge's thickness rather than as one distance moves fx by {:+.2} %): more light, or a sharper focus, makes the edges quicker and thinner",
                100.0 * c[0] / k.fx.abs()
            ),
            _ => String::new(),
        };
        format!(
            "the focal length is weakly fixed: fx ±{:.2} %, fy ±{:.2} % (1σ; evcal aims at 0.1 %); {fix}{lag_note}",
            100.0 * cal.std_dev[0] / k.fx.abs(),
            100.0 * cal.std_dev[1] / k.fy.abs(),
        )
    })
}

/// Why a calibration attempt gave no calibration (its error, or [`Outcome::failure`]);
/// `None` when it gave one.
///
/// A recording whose ring fits give no calibration is detected again with filled discs
/// (`evcal_core::fit::FitConfig::filled_discs`) by `evcal calibrate` and the physics sweep
/// alike: the discs cost accuracy where rings hold (a dim room's scenes read worse with
/// them, docs/accuracy.md) and are the only circles where the slow pixels of a dark circle
/// fill it (a large sensor in dim light), so they are fitted only where rings failed.
pub fn no_calibration(result: &Result<Outcome, PipelineError>) -> Option<String> {
    match result {
        Ok(o) => o.failure.clone(),
        Err(e) => Some(e.to_string()),
    }
}

/// Largest σ of the focal length (1σ, relative) of a calibration from filled discs that is
/// taken where the rings gave none ([`disc_fallback_rejects`]).
///
/// A disc's centre lies up to a pixel from its circle's along the motion (its ON crescent
/// outweighs its fill's edge), the same for the discs of one window only to about 0.2 px;
/// the edge shift takes out one distance, and what differs between centres the σ does not
/// hold. Many views from varied poses average it down; a handful do not: on the simulated
/// DVXplorer's dim spiral at a 100 Hz photoreceptor the discs gave 8 views and fx +16 %
/// with σ 4.9 %, inside [`FAILED_RELATIVE`] and 3.4σ off, while its dim cone and spiral at
/// 300 Hz read +0.18 % (σ 0.18 %) and −0.57 % (σ 0.33 %) (+0.004 % and −0.21 % since the
/// discs' windows last as long as a DAVIS346's:
/// [`disc_events_per_window`](crate::input::detections::disc_events_per_window)).
pub const DISC_FALLBACK_FOCAL_RELATIVE: f64 = 0.01;

/// Why a calibration from filled discs, tried where the rings gave none, is not taken: it is
/// no calibration ([`no_calibration`]), or its focal length is looser than
/// [`DISC_FALLBACK_FOCAL_RELATIVE`]; `None` when it is taken.
pub fn disc_fallback_rejects(result: &Result<Outcome, PipelineError>) -> Option<String> {
    if let Some(why) = no_calibration(result) {
        return Some(why);
    }
    let o = result.as_ref().ok()?;
    let (k, sd) = (&o.calibration.intrinsics, &o.calibration.std_dev);
    let (rx, ry) = (sd[0] / k.fx.abs(), sd[1] / k.fy.abs());
    // A NaN σ is no fixed focal length either (and `f64::max` would pass it over).
    let rel = if rx.is_nan() || ry.is_nan() { f64::NAN } else { rx.max(ry) };
    (rel.is_nan() || rel > DISC_FALLBACK_FOCAL_RELATIVE).then(|| {
        format!(
            "the focal length ±{:.1} % (1σ) from {} views; a disc's centre may lie a pixel off its circle's, so discs are taken only where their views fix the focal length within {:.0} %",
            100.0 * rel,
            o.calibration.views.len(),
            100.0 * DISC_FALLBACK_FOCAL_RELATIVE
        )
    })
}

/// Why `cal` is no calibration, if it is not: a parameter the views leave so loose that its
/// printed value means nothing (beyond [`FAILED_RELATIVE`]).
pub fn verdict(cal: &Calibration) -> Option<String> {
    let (k, sd) = (&cal.intrinsics, &cal.std_dev);
    let size = cal.image_size.map(f64::from);
    let mut loose = Vec::new();
    for (i, scale, unit) in [(0, k.fx.abs(), "%"), (1, k.fy.abs(), "%"), (2, size[0], "px"), (3, size[1], "px")] {
        if !(sd[i].is_finite() && sd[i] <= FAILED_RELATIVE * scale) {
            let name = crate::calib::PARAMETER_NAMES[i];
            loose.push(match unit {
                _ if !sd[i].is_finite() => format!("{name} not fixed at all"),
                "%" => format!("{name} ±{:.1} % (1σ)", 100.0 * sd[i] / scale),
                _ => format!("{name} ±{:.1} px (1σ)", sd[i]),
            });
        }
    }
    (!loose.is_empty()).then(|| {
        format!(
            "the views do not fix the camera: {} (at most {:.0} % of the focal length or the sensor's size is a calibration); record the target tilted 20–40° to each side, filling the sensor, in light bright enough for the grid to be found in most windows",
            loose.join(", "),
            100.0 * FAILED_RELATIVE
        )
    })
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::input::detections::CenterRecord;

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
                WindowRecord { seq: k as u32, t_ref_us: 1000 * k as u64, events: 4000, noise: 100, centers }
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
        let why = disc_fallback_rejects(&Ok(o.clone())).expect("refused");
        assert!(why.contains("±2.0 %") && why.contains("12 views"), "{why}");
        o.calibration.std_dev[1] = f64::NAN;
        assert!(disc_fallback_rejects(&Ok(o.clone())).is_some());
        o.failure = Some("loose".into());
        assert_eq!(no_calibration(&Ok(o.clone())).as_deref(), Some("loose"));
        assert_eq!(disc_fallback_rejects(&Ok(o)).as_deref(), Some("loose"));
    }

    /// A calibration whose focal length the views leave loose is warned about, and one they
    /// leave meaningless is no calibration, with the parameter named.
    #[test]
    fn loose_parameters_are_warned_about_or_fail_the_calibration() {
        let truth = lens();
        let views = calib::synthetic_views(&truth, 12, 0.02, 3);
        let mut cal = calib::calibrate(&views, [346, 260], &calib::Options::default()).unwrap();
        let coverage = Coverage::of(&views.iter().collect::<Vec<_>>(), [346, 260]);
        assert!(verdict(&cal).is_none() && focal_warning(&cal, &coverage, None).is_none(), "{:?}", cal.std_dev);
        cal.std_dev[0] = 0.004 * truth.fx;
        let w = focal_warning(&cal, &coverage, None).expect("a warning");
        assert!(w.contains("fx ±0.40 %") && w.contains("tilt") && !w.contains("late"), "{w}");
        // Most of that σ from the lag's model: said, with what makes edges quicker.
        let mut lag = [0.0; 9];
        lag[0] = 0.0035 * truth.fx;
        let w = focal_warning(&cal, &coverage, Some(&lag)).expect("a warning");
        assert!(w.contains("how late the edges were seen") && w.contains("+0.35 %") && w.contains("more light"), "{w}");
        lag[0] = 0.001 * truth.fx;
        assert!(!focal_warning(&cal, &coverage, Some(&lag)).unwrap().contains("late"));
        assert!(verdict(&cal).is_none());
        cal.std_dev[0] = 1.27 * truth.fx;
        cal.std_dev[3] = f64::NAN;
        let why = verdict(&cal).expect("no calibration");
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
        let origins: Vec<ViewOrigin> =
            (0..n).map(|k| ViewOrigin { window_seq: k as u64, t_s: 0.033 * k as f64 }).collect();
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
}
