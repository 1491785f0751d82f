//! From windows to views: the grid in each window (found, followed, smoothed), each view's
//! points and precision figures, and the grid finder's tally.

use super::*;
use crate::stats::median;

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
        let mut s = self.found_summary();
        if self.points_at_edge > 0 {
            s += &format!("; {} points at the sensor's border left out", self.points_at_edge);
        }
        s
    }

    /// [`summary`](Self::summary) without the points left out at the border: the grid's
    /// count alone, for a note that quotes why a run gave no calibration.
    pub fn found_summary(&self) -> String {
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
    /// Per view: every circle centre detected in its window (the grid's and the others),
    /// px, for the report's pictures of the windows. Empty: not known.
    pub centres: Vec<Vec<[f64; 2]>>,
    /// A few windows' events, sampled while the recording was detected
    /// ([`crate::input::event_frames`]), for the report's pictures. Empty: not kept (the run
    /// read detections).
    pub event_frames: Vec<crate::input::event_frames::EventFrame>,
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
                    out.centres.push(w.centers.iter().map(|c| [f64::from(c.u), f64::from(c.v)]).collect());
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
