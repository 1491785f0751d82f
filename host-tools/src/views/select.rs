//! Which views to calibrate from, and whether they are enough.
//!
//! An event camera gives hundreds of windows a second and consecutive ones see the target
//! from nearly the same place: near-duplicates add little but time, and a pose the camera
//! dwelt on would outweigh the rest. [`select_views`] keeps a view only when its points have
//! moved far enough from every view kept so far, then thins evenly to a cap.
//!
//! A low reprojection error is not proof of a good calibration: points that never reach
//! the sensor's corners leave the distortion there a guess, and views without tilt leave
//! the focal length tied to the distance. [`Coverage`] and [`advice`] say so, and what
//! motion would fix it.

use crate::calib::{Calibration, View};
use nalgebra::{Rotation3, Vector3};
use serde::Serialize;

/// How views are chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectOptions {
    /// A view is a near-duplicate of a kept one when its points moved by less than this,
    /// RMS over the points, px. 0 (the default) keeps every view: see [`Default`].
    pub min_change_px: f64,
    /// Most views kept; beyond it, views are thinned evenly over the kept ones.
    pub max_views: usize,
}

impl Default for SelectOptions {
    fn default() -> Self {
        // Every view: no two windows share an event, so each window's centres are a
        // measurement of their own, with noise of their own, even where the board barely
        // moved between them (a frame camera's consecutive frames repeat one exposure's
        // noise; windows do not). And an event camera cannot dwell the way a frame camera
        // does: a board at rest fires no events, so a pose lasts only as many windows as
        // its motion fills. Leaving out the windows that moved less than 2 px (the default
        // until 2026-12) dropped two thirds of the slow cones' windows and their
        // information: on the independent emulator's dim cone σ(fx) 0.154 → 0.130 % and
        // fx −0.228 → −0.170 % with all kept (docs/notes/pipeline.md). The standard deviations
        // count neighbouring windows as one group (`calib::group_seconds`), so keeping
        // them all does not feign independence that smoothing took away. 500 views solve in
        // seconds; longer recordings are thinned evenly.
        Self { min_change_px: 0.0, max_views: 500 }
    }
}

/// The views chosen, and why the others were not.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Selection {
    /// Indices of the chosen views, ascending.
    pub chosen: Vec<usize>,
    /// Views offered.
    pub candidates: usize,
    /// Views dropped as near-duplicates of a kept one.
    pub near_duplicates: usize,
    /// Views dropped to keep within the cap.
    pub thinned: usize,
}

impl Selection {
    /// One line for users: how many views were used and why.
    pub fn summary(&self, opts: &SelectOptions) -> String {
        let mut s = format!("{} of {} views used", self.chosen.len(), self.candidates);
        if self.near_duplicates > 0 {
            s += &format!(
                "; {} near-duplicates left out (points moved < {:.1} px from a kept view)",
                self.near_duplicates, opts.min_change_px
            );
        }
        if self.thinned > 0 {
            s += &format!("; {} more left out to stay within {} views", self.thinned, opts.max_views);
        }
        s
    }
}

/// RMS distance between the points two views share (board points in the same order, as
/// the grid finder lists them), or `None` when they share less than half their points.
fn change(a: &View, b: &View) -> Option<f64> {
    let key = |p: &[f64; 3]| (p[0], p[1]);
    let sorted = |v: &View| v.object.windows(2).all(|w| key(&w[0]) < key(&w[1]));
    if !sorted(a) || !sorted(b) {
        return (a.object == b.object && !a.image.is_empty()).then(|| rms_apart(a.image.iter().zip(&b.image)));
    }
    let (mut i, mut j) = (0, 0);
    let mut pairs = Vec::with_capacity(a.image.len().min(b.image.len()));
    while i < a.object.len().min(a.image.len()) && j < b.object.len().min(b.image.len()) {
        match key(&a.object[i]).partial_cmp(&key(&b.object[j])) {
            Some(std::cmp::Ordering::Less) => i += 1,
            Some(std::cmp::Ordering::Greater) => j += 1,
            _ => {
                pairs.push((&a.image[i], &b.image[j]));
                i += 1;
                j += 1;
            }
        }
    }
    let most = a.image.len().max(b.image.len());
    (pairs.len() >= 4 && 2 * pairs.len() >= most).then(|| rms_apart(pairs.into_iter()))
}

fn rms_apart<'a>(pairs: impl Iterator<Item = (&'a [f64; 2], &'a [f64; 2])>) -> f64 {
    let (mut sq, mut n) = (0.0, 0usize);
    for (p, q) in pairs {
        sq += (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
        n += 1;
    }
    (sq / n.max(1) as f64).sqrt()
}

/// Chooses well-spread views: in order, a view is kept unless its points are within
/// `min_change_px` of a view already kept; then, above `max_views`, every k-th is kept.
pub fn select_views(views: &[View], opts: &SelectOptions) -> Selection {
    let mut kept: Vec<usize> = Vec::new();
    let mut near_duplicates = 0;
    for (i, v) in views.iter().enumerate() {
        // Recent views are the likely duplicates: look at them first.
        // At 0 (the default) nothing is a duplicate: no view is compared.
        let duplicate = opts.min_change_px > 0.0
            && kept.iter().rev().any(|&k| change(v, &views[k]).is_some_and(|d| d < opts.min_change_px));
        if duplicate {
            near_duplicates += 1;
        } else {
            kept.push(i);
        }
    }
    let mut thinned = 0;
    if kept.len() > opts.max_views && opts.max_views > 0 {
        let n = kept.len();
        let chosen: Vec<usize> = (0..opts.max_views).map(|j| kept[j * n / opts.max_views]).collect();
        thinned = n - chosen.len();
        kept = chosen;
    }
    Selection { chosen: kept, candidates: views.len(), near_duplicates, thinned }
}

/// Columns and rows of the coverage map.
pub const COVERAGE_CELLS: [usize; 2] = [12, 9];

/// Where on the sensor the views' points fell.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Coverage {
    /// Sensor width and height, px.
    pub image_size: [u32; 2],
    /// Points per cell of a [`COVERAGE_CELLS`] map, row by row from the top left.
    pub counts: Vec<u32>,
    /// Fraction of the map's cells with at least one point.
    pub covered: f64,
    /// Regions of the sensor (of a 3x3 split: corners, edges) without any point.
    pub empty_regions: Vec<&'static str>,
}

const REGION_NAMES: [[&str; 3]; 3] = [
    ["top-left corner", "top edge", "top-right corner"],
    ["left edge", "centre", "right edge"],
    ["bottom-left corner", "bottom edge", "bottom-right corner"],
];

impl Coverage {
    /// The coverage of the sensor by the points of `views`.
    pub fn of(views: &[&View], image_size: [u32; 2]) -> Self {
        let [cw, ch] = COVERAGE_CELLS;
        let (w, h) = (f64::from(image_size[0].max(1)), f64::from(image_size[1].max(1)));
        let mut counts = vec![0u32; cw * ch];
        let mut regions = [[0u32; 3]; 3];
        for p in views.iter().flat_map(|v| &v.image) {
            // Pixel centres are at integers: the sensor spans [-0.5, w - 0.5], as the
            // report's map draws it.
            let (fx, fy) = ((p[0] + 0.5) / w, (p[1] + 0.5) / h);
            if !((0.0..1.0).contains(&fx) && (0.0..1.0).contains(&fy)) {
                continue;
            }
            counts[(fy * ch as f64) as usize * cw + (fx * cw as f64) as usize] += 1;
            // Corner and edge regions are the outer sixth of the sensor on each side: where
            // distortion is largest and least seen.
            let band = |f: f64| {
                if f < 1.0 / 6.0 {
                    0
                } else if f < 5.0 / 6.0 {
                    1
                } else {
                    2
                }
            };
            regions[band(fy)][band(fx)] += 1;
        }
        let covered = counts.iter().filter(|&&c| c > 0).count() as f64 / counts.len() as f64;
        let mut empty_regions = Vec::new();
        for (r, row) in regions.iter().enumerate() {
            for (c, &n) in row.iter().enumerate() {
                if n == 0 {
                    empty_regions.push(REGION_NAMES[r][c]);
                }
            }
        }
        Self { image_size, counts, covered, empty_regions }
    }

    /// The map as text, one character per cell: `.` none, then `1`–`9` for a share of the
    /// busiest cell, for a terminal.
    pub fn picture(&self) -> String {
        let [cw, _] = COVERAGE_CELLS;
        let most = self.counts.iter().copied().max().unwrap_or(0).max(1);
        let mut s = String::new();
        for row in self.counts.chunks(cw) {
            s.push('|');
            for &c in row {
                s.push(if c == 0 { '.' } else { char::from(b'0' + (1 + 8 * (c - 1) / most) as u8) });
            }
            s.push_str("|\n");
        }
        s
    }
}

/// Angles of the views' tilts: each view's board normal against the optical axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TiltSpread {
    /// Largest tilt of any view, degrees.
    pub max_deg: f64,
    /// Largest tilt about the camera's horizontal axis (the board's top toward or away), °.
    pub max_about_x_deg: f64,
    /// Largest tilt about the camera's vertical axis (the board's side toward or away), °.
    pub max_about_y_deg: f64,
}

impl TiltSpread {
    /// The tilts of a calibration's views.
    pub fn of(cal: &Calibration) -> Self {
        let mut t = TiltSpread { max_deg: 0.0, max_about_x_deg: 0.0, max_about_y_deg: 0.0 };
        for v in &cal.views {
            let r = Rotation3::from_scaled_axis(Vector3::from(v.rvec));
            // The board's normal in camera coordinates; a board facing the camera squarely
            // has it along the optical axis.
            let n = r * Vector3::z();
            let n = if n.z < 0.0 { -n } else { n };
            let deg = |a: f64| a.to_degrees().abs();
            t.max_deg = t.max_deg.max(deg(n.z.clamp(-1.0, 1.0).acos()));
            t.max_about_x_deg = t.max_about_x_deg.max(deg(n.y.atan2(n.z)));
            t.max_about_y_deg = t.max_about_y_deg.max(deg(n.x.atan2(n.z)));
        }
        t
    }
}

/// Tilt the views should reach about each axis for the focal length to be well apart from
/// the distance, degrees.
pub const GOOD_TILT_DEG: f64 = 20.0;

/// Below this fraction of the sensor's coverage cells with points, the advice is to sweep
/// the target over all of it.
pub const WELL_COVERED: f64 = 0.6;

/// Fewer views than this, and the advice is to record more.
pub const FEW_VIEWS: usize = 10;

/// What the user should know about the views behind a calibration, and what motion would
/// make it better. Empty when nothing is amiss.
pub fn advice(cal: &Calibration, coverage: &Coverage) -> Vec<String> {
    let mut out = Vec::new();
    if !coverage.empty_regions.is_empty() {
        out.push(format!(
            "no detected points in the sensor's {}: the distortion there is extrapolated; move the target so that it reaches {}",
            coverage.empty_regions.join(", "),
            if coverage.empty_regions.len() == 1 { "it" } else { "them" }
        ));
    } else if coverage.covered < WELL_COVERED {
        out.push(format!(
            "the detected points cover {:.0} % of the sensor; sweep the target over all of it",
            100.0 * coverage.covered
        ));
    }
    let tilt = TiltSpread::of(cal);
    let mut axes = Vec::new();
    if tilt.max_about_x_deg < GOOD_TILT_DEG {
        axes.push(format!("its horizontal axis (now at most {:.0}°)", tilt.max_about_x_deg));
    }
    if tilt.max_about_y_deg < GOOD_TILT_DEG {
        axes.push(format!("its vertical axis (now at most {:.0}°)", tilt.max_about_y_deg));
    }
    if !axes.is_empty() {
        out.push(format!(
            "the views lack tilt: the focal length is then tied to the distance; tilt the target by 30–45° about {}",
            axes.join(" and ")
        ));
    }
    if cal.views.len() < FEW_VIEWS {
        out.push(format!("only {} views used: record more, from different places", cal.views.len()));
    }
    out
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::calib::{calibrate, synthetic_views, Intrinsics, Options};

    fn truth() -> Intrinsics {
        Intrinsics { fx: 352.4, fy: 351.1, cx: 171.3, cy: 128.6, k1: -0.31, k2: 0.12, p1: 0.0, p2: 0.0, k3: 0.0 }
    }

    #[test]
    fn near_duplicates_are_left_out_and_counted() {
        let base = synthetic_views(&truth(), 5, 0.0, 1);
        // Each view followed by nine copies moved by 0.1 px each: a dwell.
        let mut views = Vec::new();
        for v in &base {
            for k in 0..10 {
                let mut c = v.clone();
                c.image.iter_mut().for_each(|p| p[0] += 0.1 * k as f64);
                views.push(c);
            }
        }
        let opts = SelectOptions { min_change_px: 2.0, ..SelectOptions::default() };
        let s = select_views(&views, &opts);
        assert_eq!(s.chosen, vec![0, 10, 20, 30, 40]);
        assert_eq!((s.candidates, s.near_duplicates, s.thinned), (50, 45, 0));
        assert!(s.summary(&opts).starts_with("5 of 50 views used; 45 near-duplicates"), "{}", s.summary(&opts));
        // A cap thins evenly.
        let s = select_views(&views, &SelectOptions { min_change_px: 0.0, max_views: 5 });
        assert_eq!(s.chosen, vec![0, 10, 20, 30, 40]);
        assert_eq!(s.thinned, 45);
        // By default every window is a measurement of its own: none is left out, and the
        // summary names no near-duplicates.
        let s = select_views(&views, &SelectOptions::default());
        assert_eq!((s.chosen.len(), s.near_duplicates, s.thinned), (50, 0, 0));
        assert_eq!(s.summary(&SelectOptions::default()), "50 of 50 views used");
    }

    #[test]
    fn views_of_other_points_are_never_duplicates() {
        let mut views = synthetic_views(&truth(), 2, 0.0, 1);
        // The same pixels, but paired with other board points.
        views[1] = views[0].clone();
        views[1].object.iter_mut().for_each(|p| p[1] += 0.001);
        let two = SelectOptions { min_change_px: 2.0, ..SelectOptions::default() };
        assert_eq!(select_views(&views, &two).chosen, vec![0, 1]);
        // A partial view sharing most points of a kept one is a duplicate; one sharing few
        // is not.
        let mut views = synthetic_views(&truth(), 1, 0.0, 1);
        let most = View { object: views[0].object[4..].to_vec(), image: views[0].image[4..].to_vec() };
        let few = View { object: views[0].object[30..].to_vec(), image: views[0].image[30..].to_vec() };
        views.extend([most, few]);
        assert_eq!(select_views(&views, &two).chosen, vec![0, 2]);
        assert_eq!(select_views(&[], &two).chosen, Vec::<usize>::new());
    }

    #[test]
    fn coverage_names_the_empty_corners() {
        let size = [346, 260];
        let views = synthetic_views(&truth(), 60, 0.0, 2);
        let all: Vec<&View> = views.iter().collect();
        let full = Coverage::of(&all, size);
        assert!(full.covered > 0.6, "{}", full.picture());
        // Only points in the left half: the right corners and edge are empty.
        let left: Vec<View> = views
            .iter()
            .map(|v| {
                let keep: Vec<usize> = (0..v.image.len()).filter(|&i| v.image[i][0] < 150.0).collect();
                View {
                    object: keep.iter().map(|&i| v.object[i]).collect(),
                    image: keep.iter().map(|&i| v.image[i]).collect(),
                }
            })
            .collect();
        let left: Vec<&View> = left.iter().collect();
        let cov = Coverage::of(&left, size);
        for r in ["top-right corner", "right edge", "bottom-right corner"] {
            assert!(cov.empty_regions.contains(&r), "{:?}", cov.empty_regions);
        }
        assert!(!cov.empty_regions.contains(&"top-left corner") || !full.empty_regions.contains(&"top-left corner"));
        assert_eq!(cov.picture().lines().count(), COVERAGE_CELLS[1]);
        assert!(cov.picture().lines().all(|l| l.ends_with(".|")), "{}", cov.picture());
    }

    #[test]
    fn advice_asks_for_tilt_and_corners() {
        let t = truth();
        let views = synthetic_views(&t, 30, 0.05, 3);
        let cal = calibrate(&views, [346, 260], &Options::default()).unwrap();
        let all: Vec<&View> = views.iter().collect();
        let good = advice(&cal, &Coverage::of(&all, [346, 260]));
        assert!(good.iter().all(|a| !a.contains("tilt")), "{good:?}");
        // The same calibration with every view facing the camera squarely.
        let mut flat = cal.clone();
        flat.views.iter_mut().for_each(|v| v.rvec = [0.0, 0.0, v.rvec[2]]);
        let empty = Coverage::of(&[], [346, 260]);
        let bad = advice(&flat, &empty);
        assert!(bad.iter().any(|a| a.contains("tilt the target")), "{bad:?}");
        assert!(bad.iter().any(|a| a.contains("top-left corner")), "{bad:?}");
    }
}
