//! The emulator example's second table: each calibration's mapping error against the truth
//! beside the projection σ it predicts (issue 44, item 1).
//!
//! The mapping error at a pixel: the ray the true camera sees there, projected with the
//! estimated camera, px from the pixel (the ray held in the camera frame, as
//! `calib::ProjectionSigma` holds it). Pixels: a 24 × 24 grid from the sensor's first pixel
//! to its last, corners included. "Covered": within the outline of a board seen in a view
//! used (`calib::Covered`).

use evcal_host::calib::{projection_sigma_at, unproject, Calibration, Covered, Intrinsics, View, COVERAGE_SIGMAS};

/// Nodes of the grid along each side.
const GRID: usize = 24;

/// One recording's figures.
pub struct Mapping {
    /// Mapping error over the sensor, px: mean and max.
    pub mean_px: f64,
    pub max_px: f64,
    /// Mean mapping error over the covered nodes, px (NaN for none).
    pub covered_mean_px: f64,
    /// Predicted σ over the sensor, px: mean and max.
    pub sigma_mean_px: f64,
    pub sigma_max_px: f64,
    /// Mean predicted σ over the covered nodes, px.
    pub sigma_covered_mean_px: f64,
    /// Share of the nodes whose error is within [`COVERAGE_SIGMAS`] σ, and of the covered ones.
    pub within: f64,
    pub covered_within: f64,
    /// Covered nodes, of GRID².
    pub covered: usize,
    /// What k3's σ alone moves a node by, px (1σ, [`projection_sigma_at`] with k3's variance
    /// only): the most over the covered nodes, and over the sensor's (issue 44, item 2).
    pub k3_covered_px: f64,
    pub k3_sensor_px: f64,
    /// Nodes where the estimated camera sees no ray (its model folds short of them), whose
    /// σ is unbounded: left out of the σ's mean and max and of the shares within 3σ.
    pub unbounded: usize,
}

fn mean(x: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = x.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    s / n as f64
}

/// The figures of `cal` (solved from `used`, as `Outcome::used`) against `truth`.
pub fn mapping(truth: &Intrinsics, cal: &Calibration, used: &[View]) -> Mapping {
    let covered = Covered::of(cal.views.iter().filter_map(|v| used.get(v.view)).map(|v| &v.image[..]));
    let [w, h] = cal.image_size.map(|s| f64::from(s) - 1.0);
    // (error, σ, covered) per node; a pixel the true camera sees no ray at is left out.
    let all: Vec<(f64, f64, bool)> = (0..GRID)
        .flat_map(|j| (0..GRID).map(move |i| [w * i as f64 / (GRID - 1) as f64, h * j as f64 / (GRID - 1) as f64]))
        .filter_map(|q| {
            let xy = unproject(truth, q)?;
            let p = cal.intrinsics.distort(xy[0], xy[1]);
            let sigma = projection_sigma_at(&cal.intrinsics, &cal.covariance, q);
            Some(((p[0] - q[0]).hypot(p[1] - q[1]), sigma, covered.contains(q)))
        })
        .collect();
    let unbounded = all.iter().filter(|n| !n.1.is_finite()).count();
    let nodes: Vec<(f64, f64, bool)> = all.iter().copied().filter(|n| n.1.is_finite()).collect();
    let inside = || nodes.iter().filter(|n| n.2);
    let mut k3_only = [[0.0; 9]; 9];
    k3_only[8][8] = cal.covariance[8][8];
    let k3 = |covered_only: bool| {
        (0..GRID)
            .flat_map(|j| (0..GRID).map(move |i| [w * i as f64 / (GRID - 1) as f64, h * j as f64 / (GRID - 1) as f64]))
            .filter(|&q| !covered_only || covered.contains(q))
            .map(|q| projection_sigma_at(&cal.intrinsics, &k3_only, q))
            .filter(|s| s.is_finite())
            .fold(0.0, f64::max)
    };
    let share = |n: &mut dyn Iterator<Item = &(f64, f64, bool)>| {
        let (ok, all) = n.fold((0, 0), |(ok, all), (e, s, _)| (ok + usize::from(*e <= COVERAGE_SIGMAS * s), all + 1));
        ok as f64 / all as f64
    };
    Mapping {
        mean_px: mean(all.iter().map(|n| n.0)),
        max_px: all.iter().map(|n| n.0).fold(0.0, f64::max),
        covered_mean_px: mean(all.iter().filter(|n| n.2).map(|n| n.0)),
        sigma_mean_px: mean(nodes.iter().map(|n| n.1)),
        sigma_max_px: nodes.iter().map(|n| n.1).fold(0.0, f64::max),
        sigma_covered_mean_px: mean(inside().map(|n| n.1)),
        within: share(&mut nodes.iter()),
        covered_within: share(&mut inside()),
        covered: inside().count(),
        k3_covered_px: k3(true),
        k3_sensor_px: k3(false),
        unbounded,
    }
}

/// The table's header.
pub fn header() -> String {
    "| recording | mapping error mean / max over the sensor | mean over the covered region | predicted σ mean / max over the sensor's other nodes | σ mean, covered | error ≤ 3σ: sensor, covered | covered nodes | nodes of unbounded σ (no ray) | k3's 1σ alone, most: covered / sensor |\n|---|---|---|---|---|---|---|---|---|".into()
}

/// `m`'s row, named `name`.
pub fn row(name: &str, m: &Mapping) -> String {
    format!(
        "| {name} | {:.2} / {:.1} px | {:.3} px | {:.2} / {:.1} px | {:.3} px | {:.0} %, {:.0} % | {} of {} | {} | {:.3} / {:.1} px |",
        m.mean_px,
        m.max_px,
        m.covered_mean_px,
        m.sigma_mean_px,
        m.sigma_max_px,
        m.sigma_covered_mean_px,
        100.0 * m.within,
        100.0 * m.covered_within,
        m.covered,
        GRID * GRID,
        m.unbounded,
        m.k3_covered_px,
        m.k3_sensor_px
    )
}
