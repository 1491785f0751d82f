//! From detection windows to a calibration: the grid in each window, views, the views
//! chosen, the solve, and what the coverage says about it.
//!
//! Data flows one way: [`views_from_windows`] turns windows into views (with the grid
//! finder's tally), [`calibrate_views`] chooses among them and solves, and
//! [`calibrate_with_disc_fallback`] tries filled discs where the rings give no calibration.
//! `evcal calibrate`, `evcal demo` and the end-to-end tests all go through here.

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

#[cfg(test)]
mod tests;
mod verdict;
mod verdicts;
mod views;

pub use verdict::{
    Verdict, EXIT_GOOD, EXIT_NOT_A_CALIBRATION, EXIT_USABLE, GOOD_CENTRE_PX, GOOD_CORNER_PX, GOOD_COVERAGE,
    GOOD_FOCAL_RELATIVE, GOOD_PROJECTION_PX, GOOD_RMS_PX, GOOD_VIEWS, MAX_ACTIONS,
};
pub use verdicts::{
    calibrate_with_disc_fallback, disc_fallback_rejects, loose_params, no_calibration, Chosen, DiscFallback,
    DiscRejection, Loose, LooseParam, Looseness, NoCalibration, WeakFocal, WeakFocalCause,
    DISC_FALLBACK_FOCAL_RELATIVE, FAILED_RELATIVE, FOCAL_WARN_RELATIVE,
};
pub use views::{view_of, views_from_windows, GridStats, Views};

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
    /// Hold k3 at 0 unless the views demand it ([`K3_DEMANDED_SIGMAS`]); `false` solves it
    /// whatever they say (`calib.fix_k3` holds it at 0 whatever they say).
    pub k3_only_if_demanded: bool,
}

/// k3 is solved for only when the first solve puts it at least this many of its σ from 0
/// (a Wald test with the grouped σ, which counts the errors views of one stretch of the
/// recording share): below it the views cannot tell k3 from 0 over the region they cover,
/// and a free k3 only bends the model where they never were (on an independent emulator's
/// cone, 14.9 px off at a corner with k3 free, 1.6 px with it held). ROS's calibrator and
/// Kalibr's radtan hold it at 0 by default; every file then holds the same model.
pub const K3_DEMANDED_SIGMAS: f64 = 3.0;

/// k3 held at 0 because the views do not demand it: what the free solve said.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct K3Held {
    /// k3 as the solve with it free put it.
    pub free: f64,
    /// Its σ there.
    pub std: f64,
}

impl fmt::Display for K3Held {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "k3 held at 0: the views do not tell it from 0 (free, it came to {:.4} ± {:.4}, within {K3_DEMANDED_SIGMAS} σ), so every file holds k1, k2, p1, p2 alone (--free-k3 to solve it anyway)",
            self.free, self.std
        )
    }
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
            k3_only_if_demanded: true,
        }
    }
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
    /// k3 was held at 0 because the views do not demand it ([`K3_DEMANDED_SIGMAS`]), and what
    /// the solve with it free said; `None` when k3 was solved (or fixed by the caller).
    pub k3_held: Option<K3Held>,
    /// Where on the sensor the chosen views' points fell.
    pub coverage: Coverage,
    /// One standard deviation of where a distant point is seen, over the sensor
    /// ([`calib::ProjectionSigma`]); `None` when it cannot be computed.
    pub projection_sigma: Option<calib::ProjectionSigma>,
    /// What the user should know about the views, and what motion would help.
    pub advice: Vec<String>,
    /// The focal length is looser than [`FOCAL_WARN_RELATIVE`], and what would fix it;
    /// `None` when it is not.
    pub weak_focal: Option<WeakFocal>,
    /// Why the result is no calibration at all, when the views leave a parameter so loose
    /// that no value printed could be trusted ([`loose_params`]); `None` for a calibration.
    pub failure: Option<Loose>,
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
            PipelineError::NoGrid(s) => verdicts::write_no_grid(f, s),
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
    // k3 only where the views demand it: every later solve holds it at 0 otherwise.
    let mut k3_held = None;
    if setup.k3_only_if_demanded && !grouped.fix_k3 {
        let (free, std) = (calibration.intrinsics.k3, calibration.std_dev[8]);
        if std.is_nan() || free.abs() < K3_DEMANDED_SIGMAS * std {
            let held = calib::Options { fix_k3: true, ..grouped.clone() };
            if let Ok(c) = calib::calibrate(&used, setup.image_size, &held) {
                (calibration, grouped) = (c, held);
                k3_held = Some(K3Held { free, std });
            }
        }
    }
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
                calibration.widen(change);
                s.by_thickness = Some(edge_shift::ByThickness { px, change });
            }
        }
    }
    // The shift's σ as a parameter of the final solve, where its scatter over the groups of
    // views counts too.
    if let (Some(s), Some(sd)) = (edge_shift.as_mut(), calibration.shift_std_px) {
        s.std_px = s.std_px.max(sd);
    }
    // The warnings quote the σ printed, widened above.
    calibration.warnings = calib::constraint_warnings(&calibration.intrinsics, &calibration.std_dev, setup.image_size);
    let without_k3 =
        if !grouped.fix_k3 && k3_displacement_px(&calibration.intrinsics, setup.image_size) > K3_NEGLIGIBLE_PX {
            let opts = calib::Options { fix_k3: true, ..grouped.clone() };
            calib::calibrate(&used, setup.image_size, &opts).ok()
        } else {
            None
        };
    let kept: Vec<&View> = calibration.views.iter().filter_map(|v| used.get(v.view)).collect();
    let coverage = Coverage::of(&kept, setup.image_size);
    let projection_sigma = calib::ProjectionSigma::of(&calibration, &used, calib::PROJECTION_SIGMA_STEP_PX);
    let advice = advice(&calibration, &coverage);
    let lag = edge_shift.and_then(|s| s.by_thickness).map(|b| b.change);
    let weak_focal = WeakFocal::of(&calibration, &coverage, lag.as_ref());
    let failure = loose_params(&calibration);
    Ok(Outcome {
        selection,
        used,
        used_origins,
        smoothing,
        edge_shift,
        calibration,
        without_k3,
        k3_held,
        coverage,
        projection_sigma,
        advice,
        weak_focal,
        failure,
    })
}
