//! Finds the asymmetric circle grid among one window's centres, and pairs each of its
//! points with its board point.
//!
//! A window's centres are the grid's circles (some missing) among clutter: discs and blobs
//! of the background, fits to partial circles at the sensor's edge. The search has three
//! steps, none of which tries subsets of the centres:
//!
//! 1. **Consistency filter** (the E-Calib paper's modified hierarchical clustering, its
//!    eq. 8–11): the grid's circles share a radius and a nearest-neighbour distance (the
//!    diagonal spacing; the neighbour of a like size that does not overlap, so that a blob
//!    over or beside a circle does not hide its spacing), the clutter's are scattered. The densest mode of (radius,
//!    nearest-neighbour distance) gives the grid's scale; centres far from it are set aside.
//! 2. **Lattice growth**: the board is a square lattice turned by 45° (diagonal neighbours
//!    `S√2` apart). From a seed whose four nearest neighbours form two opposite pairs, the
//!    lattice is grown cell by cell: each free cell beside it is predicted by an affine map
//!    fitted to the placed cells around it (local, so perspective and distortion bend it
//!    little), and takes the centre nearest the prediction within a quarter step, with a
//!    radius like its neighbours'. Diagonal cells bridge a missing circle.
//! 3. **Placement and checks**: of the eight ways to lay the lattice's axes on the board and
//!    every shift, only those that put the points inside the pattern, on the right parity,
//!    with the board's front towards the camera (a mirror image needs the camera behind the
//!    board) count. Up to [`MAX_STRAYS`] points beyond the pattern (marks printed beside the
//!    grid, a background disc in line) may be left out, but then the placement must hold two
//!    points more than any other: a rival holds the strays instead of a whole edge line. A
//!    unique placement is the answer; several are a miss, except for the pattern's own 180°
//!    symmetry (even COLS only), settled by one rule (below). Every line of the lattice must
//!    then be smooth, and a homography must fit: a wrong ordering is worse than a miss.
//!
//! With odd COLS the pattern is its own mirror image (column i ↔ COLS−1−i), so a mirrored
//! image is also a view of the board from the front, and is labelled as one; with even COLS
//! a mirrored image has no labelling and is a miss.
//!
//! **Pattern convention** (as E-Calib): `ROWSxCOLS`, spacing `S`; board point (i, j), i <
//! COLS, j < ROWS, is at (i·S, (2j + i mod 2)·S, 0) and has index `i·ROWS + j`.
//!
//! **The 180° rule.** A grid with an odd number of columns (4x11, 3x9) has no symmetry that
//! keeps its front to the camera: its labelling is unique. With even COLS, turning the
//! board by 180° maps the grid onto itself; evcal then takes the labelling whose board x
//! axis (increasing i) points to the image's right (+u), or, when the axis is vertical
//! within 1°, down (+v). It does not change the intrinsics; a board swept through vertical
//! flips its labelling there, and the solver takes each view's pose on its own.

mod checks;
mod consistency;
mod lattice;
mod pattern;
mod placement;
#[cfg(test)]
mod tests;

pub(crate) use checks::homography_check;
pub use pattern::{Pattern, MAX_PATTERN_SIDE};
pub use placement::MAX_STRAYS;

use crate::input::detections::CenterRecord;
use checks::check_smooth;
use consistency::consistent;
use evcal_core::config::MAX_CLUSTERS;
use lattice::{grow, seeds, Cell};
use placement::place;
use std::collections::HashMap;
use std::fmt;

/// One circle of the grid as found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridPoint {
    /// Index of its board point (`i·rows + j`).
    pub index: usize,
    /// Image position, px.
    pub image: [f64; 2],
    /// Radius of the fitted circle, px.
    pub radius_px: f64,
    /// How thick its edge looked: the fit's weighted spread of events about the circle, px.
    pub spread_px: f64,
    /// How many events its fit used (a centre fitted to fewer events is less precise).
    pub events: u16,
}

/// The grid found in one window.
#[derive(Debug, Clone, PartialEq)]
pub struct GridDetection {
    /// The circles found, by index: from the finder all of them, or a part spanning every
    /// row and column; followed from the windows around ([`crate::views::track`]) possibly a
    /// smaller part.
    pub points: Vec<GridPoint>,
    /// RMS distance of the points from a homography fitted to them, px (distortion makes
    /// it a few tenths even for perfect centres).
    pub homography_rms_px: f64,
}

/// Why no grid was returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Miss {
    /// Fewer usable centres than the grid needs.
    TooFewCentres,
    /// More usable centres than the finder searches ([`max_centres`]): not a window of a
    /// detector's circles (evcal's gives at most [`MAX_CLUSTERS`]), and a search among them
    /// would take the square of their number.
    TooManyCentres,
    /// No centre has the four neighbours of a lattice point.
    NoLattice,
    /// A lattice was found but holds too few of the grid's points.
    TooFewPoints,
    /// The lattice fits the pattern in no way that keeps the board's front to the camera
    /// (it is larger than the pattern, or a mirror image).
    NoPlacement,
    /// The lattice fits the pattern in more than one way (rows or columns missing at its
    /// edge): the labelling is not known.
    Ambiguous,
    /// The labelled points fail the smoothness or homography check.
    Inconsistent,
}

impl Miss {
    /// Every reason, for reports.
    pub const ALL: [Miss; 7] = [
        Miss::TooFewCentres,
        Miss::TooManyCentres,
        Miss::NoLattice,
        Miss::TooFewPoints,
        Miss::NoPlacement,
        Miss::Ambiguous,
        Miss::Inconsistent,
    ];
}

impl fmt::Display for Miss {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Miss::TooFewCentres => "too few centres",
            Miss::TooManyCentres => {
                return write!(
                    f,
                    "too many centres (more than {CENTRES_PER_GRID_POINT} per circle of the pattern and than the {MAX_CLUSTERS} a window of evcal's detector holds: not searched)"
                )
            }
            Miss::NoLattice => "no lattice",
            Miss::TooFewPoints => "too few grid points",
            Miss::NoPlacement => "lattice does not fit the pattern",
            Miss::Ambiguous => "rows or columns missing at the edge (ambiguous)",
            Miss::Inconsistent => "failed the consistency checks",
        })
    }
}

/// What the finder accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FindOptions {
    /// Fewest points of the pattern a detection must hold, as a fraction of all. Missing
    /// circles are common (a circle moving along its own edge fires few events); the
    /// labelling stays certain as long as every row and column is seen.
    pub min_fraction: f64,
}

impl Default for FindOptions {
    fn default() -> Self {
        Self { min_fraction: 0.6 }
    }
}

/// A usable centre.
#[derive(Debug, Clone, Copy)]
struct Pt {
    p: [f64; 2],
    r: f64,
    spread: f64,
    events: u16,
}

/// Centres a window may hold per circle of the pattern for the finder to search it: room
/// for clutter several times the grid's own. The search compares every centre with every
/// other (9000 centres took 8 s a window), so a window beyond this and beyond
/// [`MAX_CLUSTERS`] is a miss ([`Miss::TooManyCentres`]).
pub const CENTRES_PER_GRID_POINT: usize = 4;

/// Most usable centres the finder searches a window of `pattern` for: [`CENTRES_PER_GRID_POINT`]
/// per circle, and never fewer than a window of evcal's detector holds ([`MAX_CLUSTERS`]).
pub fn max_centres(pattern: &Pattern) -> usize {
    (CENTRES_PER_GRID_POINT * pattern.len()).max(MAX_CLUSTERS)
}

/// Most seeds tried before giving up.
const MAX_SEEDS: usize = 8;

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Finds the grid of `pattern` among `centres`.
pub fn find_grid(centres: &[CenterRecord], pattern: &Pattern, opts: &FindOptions) -> Result<GridDetection, Miss> {
    let m_total = pattern.len();
    let needed = ((opts.min_fraction.clamp(0.0, 1.0) * m_total as f64).ceil() as usize).max(6);
    let pts: Vec<Pt> = centres
        .iter()
        .filter(|c| c.u.is_finite() && c.v.is_finite() && c.r.is_finite() && c.r > 0.0)
        .filter(|c| c.u.abs() < 1e6 && c.v.abs() < 1e6 && c.r < 1e6)
        .map(|c| Pt {
            p: [f64::from(c.u), f64::from(c.v)],
            r: f64::from(c.r),
            spread: f64::from(c.spread),
            events: c.n,
        })
        .collect();
    if pts.len() < needed {
        return Err(Miss::TooFewCentres);
    }
    if pts.len() > max_centres(pattern) {
        return Err(Miss::TooManyCentres);
    }
    let candidates = consistent(&pts);
    if candidates.len() < needed {
        return Err(Miss::TooFewCentres);
    }
    let seeds = seeds(&pts, &candidates);
    if seeds.is_empty() {
        return Err(Miss::NoLattice);
    }
    // The largest lattice grown from the best few seeds.
    let mut best: Option<HashMap<Cell, usize>> = None;
    for &(s, a, b) in seeds.iter().take(MAX_SEEDS) {
        let lattice = grow(&pts, &candidates, s, a, b);
        if best.as_ref().is_none_or(|l| lattice.len() > l.len()) {
            let done = lattice.len() >= m_total;
            best = Some(lattice);
            if done {
                break;
            }
        }
    }
    let lattice = best.unwrap_or_default();
    if lattice.len() < needed {
        return Err(Miss::TooFewPoints);
    }
    let labels = place(&pts, &lattice, pattern)?;
    // The smoothness check sees only the points placed on the board, not the strays.
    let kept: std::collections::HashSet<usize> = labels.iter().map(|&(_, k)| k).collect();
    let lattice: HashMap<Cell, usize> = lattice.into_iter().filter(|(_, k)| kept.contains(k)).collect();
    check_smooth(&pts, &lattice)?;
    let mut points: Vec<GridPoint> = labels
        .iter()
        .map(|&(index, k)| GridPoint {
            index,
            image: pts[k].p,
            radius_px: pts[k].r,
            spread_px: pts[k].spread,
            events: pts[k].events,
        })
        .collect();
    points.sort_by_key(|g| g.index);
    let homography_rms_px = homography_check(&points, pattern)?;
    Ok(GridDetection { points, homography_rms_px })
}
