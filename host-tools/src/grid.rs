//! Finds the asymmetric circle grid among one window's centres, and pairs each of its
//! points with its board point.
//!
//! A window's centres are the grid's circles (some missing) among clutter: discs and blobs
//! of the background, fits to partial circles at the sensor's edge. The search has three
//! steps, none of which tries subsets of the centres:
//!
//! 1. **Consistency filter** (the E-Calib paper's modified hierarchical clustering, its
//!    eq. 8–11): the grid's circles share a radius and a nearest-neighbour distance (the
//!    diagonal spacing), the clutter's are scattered. The densest mode of (radius,
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

use crate::detections::CenterRecord;
use std::collections::HashMap;
use std::fmt;

/// An asymmetric circle grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pattern {
    /// Rows: circles per column (j < rows).
    pub rows: usize,
    /// Columns (i < cols).
    pub cols: usize,
    /// Spacing S, metres: circles on one column are 2·S apart, diagonal neighbours S·√2.
    pub spacing: f64,
}

/// Largest pattern side accepted (the wire carries at most 96 centres a window anyway).
pub const MAX_PATTERN_SIDE: usize = 64;

impl Pattern {
    /// A pattern of `rows` x `cols` circles, `spacing` metres.
    pub fn new(rows: usize, cols: usize, spacing: f64) -> Result<Self, String> {
        if !(2..=MAX_PATTERN_SIDE).contains(&rows) || !(3..=MAX_PATTERN_SIDE).contains(&cols) {
            return Err(format!(
                "pattern {rows}x{cols}: an asymmetric circle grid needs 2 to {MAX_PATTERN_SIDE} rows and 3 to {MAX_PATTERN_SIDE} columns"
            ));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(format!("spacing {spacing}: must be a positive length in metres (e.g. 0.024)"));
        }
        Ok(Self { rows, cols, spacing })
    }

    /// Parses `ROWSxCOLS` (e.g. `4x11`).
    pub fn parse(text: &str, spacing: f64) -> Result<Self, String> {
        let bad = || format!("pattern '{text}': expected ROWSxCOLS, e.g. 4x11 (4 circles per column, 11 columns)");
        let (r, c) = text.trim().split_once(['x', 'X']).ok_or_else(bad)?;
        let rows = r.trim().parse().map_err(|_| bad())?;
        let cols = c.trim().parse().map_err(|_| bad())?;
        Self::new(rows, cols, spacing)
    }

    /// Number of circles.
    pub fn len(&self) -> usize {
        self.rows * self.cols
    }

    /// Whether the pattern has no circles (never, for a pattern made by [`Pattern::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The board point of circle `index` (`i·rows + j`), metres.
    pub fn object_point(&self, index: usize) -> [f64; 3] {
        let (i, j) = (index / self.rows, index % self.rows);
        [i as f64 * self.spacing, (2 * j + i % 2) as f64 * self.spacing, 0.0]
    }

    /// Every board point, by index.
    pub fn object_points(&self) -> Vec<[f64; 3]> {
        (0..self.len()).map(|k| self.object_point(k)).collect()
    }

    /// The layout as text, to compare with the printed board: one line per board row
    /// (y = 0, S, 2S, ...), `o` a circle, index 0 at the top left and i growing to the right.
    pub fn picture(&self) -> String {
        let mut s = String::new();
        for k in 0..2 * self.rows {
            for i in 0..self.cols {
                s.push(if (k + i) % 2 == 0 { 'o' } else { ' ' });
                if i + 1 < self.cols {
                    s.push(' ');
                }
            }
            s.push('\n');
        }
        s
    }
}

/// One circle of the grid as found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridPoint {
    /// Index of its board point (`i·rows + j`).
    pub index: usize,
    /// Image position, px.
    pub image: [f64; 2],
    /// Radius of the fitted circle, px.
    pub radius_px: f64,
}

/// The grid found in one window.
#[derive(Debug, Clone, PartialEq)]
pub struct GridDetection {
    /// The circles found, by index: from the finder all of them, or a part spanning every
    /// row and column; followed from the windows around ([`crate::track`]) possibly a
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
    pub const ALL: [Miss; 6] = [
        Miss::TooFewCentres,
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
}

/// Lattice coordinates: steps along the two diagonal directions of the board.
type Cell = (i32, i32);

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
        .map(|c| Pt { p: [f64::from(c.u), f64::from(c.v)], r: f64::from(c.r) })
        .collect();
    if pts.len() < needed {
        return Err(Miss::TooFewCentres);
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
    let mut points: Vec<GridPoint> =
        labels.iter().map(|&(index, k)| GridPoint { index, image: pts[k].p, radius_px: pts[k].r }).collect();
    points.sort_by_key(|g| g.index);
    let homography_rms_px = homography_check(&points, pattern)?;
    Ok(GridDetection { points, homography_rms_px })
}

/// Indices of the centres whose radius and nearest-neighbour distance agree with the
/// densest mode of both: the grid's scale.
fn consistent(pts: &[Pt]) -> Vec<usize> {
    let nn: Vec<f64> = (0..pts.len())
        .map(|a| (0..pts.len()).filter(|&b| b != a).map(|b| dist(pts[a].p, pts[b].p)).fold(f64::INFINITY, f64::min))
        .collect();
    let feature = |k: usize| (pts[k].r.ln(), nn[k].max(1e-9).ln());
    // Within 25 % of each other in both: the same circle size and spacing seen at nearly
    // the same depth.
    let near = |a: (f64, f64), b: (f64, f64), tol: f64| (a.0 - b.0).abs() < tol && (a.1 - b.1).abs() < tol;
    let mut mode = None;
    let mut most = 0;
    for a in 0..pts.len() {
        let fa = feature(a);
        let count = (0..pts.len()).filter(|&b| near(fa, feature(b), 0.22)).count();
        if count > most {
            most = count;
            mode = Some(a);
        }
    }
    let Some(m) = mode else { return Vec::new() };
    // The mode's centre: median of its members, then everything within a factor ~1.8 (a
    // tilted board is seen larger at its near side than at its far side).
    let fm = feature(m);
    let members: Vec<usize> = (0..pts.len()).filter(|&b| near(fm, feature(b), 0.22)).collect();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let centre = (
        median(members.iter().map(|&k| feature(k).0).collect()),
        median(members.iter().map(|&k| feature(k).1).collect()),
    );
    (0..pts.len()).filter(|&k| near(centre, feature(k), 0.6)).collect()
}

/// Seeds for the lattice: centres whose four nearest candidate neighbours form two
/// opposite pairs of similar length, best first; with each, the two basis steps.
fn seeds(pts: &[Pt], candidates: &[usize]) -> Vec<(usize, [f64; 2], [f64; 2])> {
    let mut out = Vec::new();
    for &s in candidates {
        let mut near: Vec<(f64, usize)> =
            candidates.iter().filter(|&&k| k != s).map(|&k| (dist(pts[s].p, pts[k].p), k)).collect();
        if near.len() < 4 {
            continue;
        }
        near.select_nth_unstable_by(3, |a, b| a.0.total_cmp(&b.0));
        let mut four: Vec<(f64, usize)> = near[..4].to_vec();
        four.sort_by(|a, b| a.0.total_cmp(&b.0));
        let v: Vec<[f64; 2]> =
            four.iter().map(|&(_, k)| [pts[k].p[0] - pts[s].p[0], pts[k].p[1] - pts[s].p[1]]).collect();
        let len = |a: [f64; 2]| a[0].hypot(a[1]);
        // Pair the nearest with its opposite.
        let Some(opp) = (1..4).min_by(|&x, &y| {
            len([v[0][0] + v[x][0], v[0][1] + v[x][1]]).total_cmp(&len([v[0][0] + v[y][0], v[0][1] + v[y][1]]))
        }) else {
            continue;
        };
        let rest: Vec<usize> = (1..4).filter(|&x| x != opp).collect();
        let (a, a2, b, b2) = (v[0], v[opp], v[rest[0]], v[rest[1]]);
        let mean = (len(a) + len(a2) + len(b) + len(b2)) / 4.0;
        let gap = |x: [f64; 2], y: [f64; 2]| len([x[0] + y[0], x[1] + y[1]]);
        // Opposite steps cancel (to second order under perspective) and the two axes are
        // neither parallel nor wildly unequal.
        let cross = (a[0] * b[1] - a[1] * b[0]).abs() / (len(a) * len(b));
        let ratio = len(a).max(len(b)) / len(a).min(len(b)).max(1e-9);
        let radii_ok = four.iter().all(|&(_, k)| (pts[k].r / pts[s].r - 1.0).abs() < 0.35);
        if gap(a, a2) < 0.2 * mean && gap(b, b2) < 0.2 * mean && cross > 0.5 && ratio < 2.0 && radii_ok {
            let score = (gap(a, a2) + gap(b, b2)) / mean;
            out.push((score, s, a, b));
        }
    }
    out.sort_by(|x, y| x.0.total_cmp(&y.0));
    out.into_iter().map(|(_, s, a, b)| (s, a, b)).collect()
}

/// Grows the lattice from seed `s` with basis steps `a` (cell +1, 0) and `b` (0, +1).
///
/// Each free cell next to the lattice (the eight around a placed cell, so that diagonal
/// steps bridge a missing circle) is predicted by an affine map fitted to the placed cells around it: local, so
/// perspective and distortion bend it no more than they bend the grid over two spacings.
/// The cells with the most placed neighbours go first; passes repeat until nothing is added.
fn grow(pts: &[Pt], candidates: &[usize], s: usize, a: [f64; 2], b: [f64; 2]) -> HashMap<Cell, usize> {
    let mut at: HashMap<Cell, usize> = HashMap::from([((0, 0), s)]);
    let mut used: std::collections::HashSet<usize> = std::collections::HashSet::from([s]);
    let seed_map = Affine { origin: [0.0, 0.0], base: pts[s].p, a, b };
    loop {
        let mut frontier: Vec<(usize, Cell)> = Vec::new();
        let mut seen = std::collections::HashSet::new();
        for &(m, n) in at.keys() {
            for dm in -1..=1 {
                for dn in -1..=1 {
                    let c = (m + dm, n + dn);
                    if !at.contains_key(&c) && seen.insert(c) {
                        let support = around(&at, c, 1).len();
                        frontier.push((support, c));
                    }
                }
            }
        }
        frontier.sort_by_key(|&(support, c)| (std::cmp::Reverse(support), c));
        let before = at.len();
        for (_, c) in frontier {
            let near = around(&at, c, 2);
            // Too few placed cells around for a fit: step from the nearest with the seed's basis.
            let map = Affine::fit(pts, &near).or_else(|| {
                let &(q, k) = near.iter().min_by_key(|&&(q, _)| (q.0 - c.0).abs() + (q.1 - c.1).abs())?;
                Some(Affine { origin: [f64::from(q.0), f64::from(q.1)], base: pts[k].p, ..seed_map })
            });
            let Some(map) = map else { continue };
            let pred = map.at(c);
            let step = map.step();
            let r_ref = near.iter().map(|&(_, k)| pts[k].r).sum::<f64>() / near.len().max(1) as f64;
            let found = candidates
                .iter()
                .copied()
                .filter(|k| !used.contains(k))
                .map(|k| (dist(pts[k].p, pred), k))
                .filter(|&(e, k)| e < 0.25 * step && (pts[k].r / r_ref - 1.0).abs() < 0.3)
                .min_by(|x, y| x.0.total_cmp(&y.0));
            if let Some((_, k)) = found {
                at.insert(c, k);
                used.insert(k);
            }
        }
        // A lattice far larger than any pattern is not a grid (a wall of similar discs).
        if at.len() == before || at.len() > 4 * MAX_PATTERN_SIDE * MAX_PATTERN_SIDE {
            break;
        }
    }
    at
}

/// Placed cells within Chebyshev distance `reach` of `c`: `(cell, point)`.
fn around(at: &HashMap<Cell, usize>, c: Cell, reach: i32) -> Vec<(Cell, usize)> {
    let mut out = Vec::new();
    for dm in -reach..=reach {
        for dn in -reach..=reach {
            let q = (c.0 + dm, c.1 + dn);
            if let Some(&k) = at.get(&q) {
                out.push((q, k));
            }
        }
    }
    out
}

/// An affine map from lattice cells to the image: `base + a·(m − origin.m) + b·(n − origin.n)`.
#[derive(Debug, Clone, Copy)]
struct Affine {
    origin: [f64; 2],
    base: [f64; 2],
    a: [f64; 2],
    b: [f64; 2],
}

impl Affine {
    /// Least-squares fit to placed cells; `None` when they are fewer than three or in a line.
    fn fit(pts: &[Pt], cells: &[(Cell, usize)]) -> Option<Self> {
        if cells.len() < 3 {
            return None;
        }
        let n = cells.len() as f64;
        let om = cells.iter().map(|&((m, _), _)| f64::from(m)).sum::<f64>() / n;
        let on = cells.iter().map(|&((_, q), _)| f64::from(q)).sum::<f64>() / n;
        let base = [
            cells.iter().map(|&(_, k)| pts[k].p[0]).sum::<f64>() / n,
            cells.iter().map(|&(_, k)| pts[k].p[1]).sum::<f64>() / n,
        ];
        let (mut smm, mut smn, mut snn) = (0.0, 0.0, 0.0);
        let (mut sum_, mut sun, mut svm, mut svn) = (0.0, 0.0, 0.0, 0.0);
        for &((m, q), k) in cells {
            let (x, y) = (f64::from(m) - om, f64::from(q) - on);
            let (u, v) = (pts[k].p[0] - base[0], pts[k].p[1] - base[1]);
            smm += x * x;
            smn += x * y;
            snn += y * y;
            sum_ += u * x;
            sun += u * y;
            svm += v * x;
            svn += v * y;
        }
        let det = smm * snn - smn * smn;
        // Collinear cells leave one direction unknown.
        if det < 0.25 * n * n * 0.1 || det < 1e-9 {
            return None;
        }
        let (i00, i01, i11) = (snn / det, -smn / det, smm / det);
        let a = [sum_ * i00 + sun * i01, svm * i00 + svn * i01];
        let b = [sum_ * i01 + sun * i11, svm * i01 + svn * i11];
        Some(Self { origin: [om, on], base, a, b })
    }

    fn at(&self, c: Cell) -> [f64; 2] {
        let (x, y) = (f64::from(c.0) - self.origin[0], f64::from(c.1) - self.origin[1]);
        [self.base[0] + self.a[0] * x + self.b[0] * y, self.base[1] + self.a[1] * x + self.b[1] * y]
    }

    /// The shorter of the two cell steps, px.
    fn step(&self) -> f64 {
        self.a[0].hypot(self.a[1]).min(self.b[0].hypot(self.b[1]))
    }
}

/// The eight ways to lay the lattice's axes: quarter turns, with and without a swap.
fn symmetry(c: Cell, t: usize) -> Cell {
    let (m, n) = if t >= 4 { (c.1, c.0) } else { c };
    match t % 4 {
        0 => (m, n),
        1 => (-n, m),
        2 => (-m, -n),
        _ => (n, -m),
    }
}

/// Most lattice points a placement may leave outside the pattern: strays at the lattice's
/// edge (marks printed beside the grid, a disc of the background that happens to line up).
pub const MAX_STRAYS: usize = 2;

/// Labels the lattice's points with the pattern's indices: `(index, point)` pairs.
///
/// Each of the eight axis layouts and every shift is scored by how many lattice points it
/// puts inside the pattern (on the right parity, with the board's front to the camera).
/// A placement that holds them all is taken if it is the only one; otherwise the best
/// placement may leave a few strays outside, but only if no other placement comes close.
fn place(pts: &[Pt], lattice: &HashMap<Cell, usize>, pattern: &Pattern) -> Result<Vec<(usize, usize)>, Miss> {
    let (cols, rows2) = (pattern.cols as i64, 2 * pattern.rows as i64);
    let n = lattice.len();
    let mut scored: Vec<Vec<(usize, usize)>> = Vec::new();
    for t in 0..8 {
        // Board coordinates: i along x, k = 2j + i mod 2 along y; a cell step is a
        // diagonal step on the board.
        let ik: Vec<((i64, i64), usize)> = lattice
            .iter()
            .map(|(&c, &k)| {
                let (m, n) = symmetry(c, t);
                ((i64::from(m) + i64::from(n), i64::from(m) - i64::from(n)), k)
            })
            .collect();
        let (imin, imax) = ik.iter().fold((i64::MAX, i64::MIN), |(lo, hi), ((i, _), _)| (lo.min(*i), hi.max(*i)));
        let (kmin, kmax) = ik.iter().fold((i64::MAX, i64::MIN), |(lo, hi), ((_, k), _)| (lo.min(*k), hi.max(*k)));
        // Shifts that keep most points inside: the pattern's box overlaps the lattice's.
        for di in (imin - cols + 1)..=imax {
            for dk in (kmin - rows2 + 1)..=kmax {
                // The two shifts have equal parity, so that k ≡ i (mod 2) holds after them.
                if (di - dk).rem_euclid(2) != 0 {
                    continue;
                }
                let labels: Vec<(usize, usize)> = ik
                    .iter()
                    .filter(|&&((i, k), _)| (0..cols).contains(&(i - di)) && (0..rows2).contains(&(k - dk)))
                    .map(|&((i, k), p)| {
                        let (i, k) = ((i - di) as usize, (k - dk) as usize);
                        (i * pattern.rows + (k - i % 2) / 2, p)
                    })
                    .collect();
                if labels.len() + MAX_STRAYS >= n && front_facing(pts, &labels, pattern) {
                    scored.push(labels);
                }
            }
        }
    }
    scored.sort_by_key(|l| std::cmp::Reverse(l.len()));
    let Some(best) = scored.first().map(Vec::len) else { return Err(Miss::NoPlacement) };
    // Rivals: placements nearly as good that are not the best's own half turn (even COLS).
    // The best must hold at least two points more than any other. A placement that leaves
    // strays out competes with one that holds the strays instead of a whole edge line of the
    // grid; and one that holds every point may owe that to a single point in an edge line,
    // a disc of the background that lines up with the lattice one step beyond a grid whose
    // far columns are too dim to be seen (simulated DVXplorer 4x11 cone, low light, seed 2:
    // nine columns and such a disc were labelled two columns off, every point wrong).
    let twin = |a: &[(usize, usize)], b: &[(usize, usize)]| pattern.cols % 2 == 0 && is_half_turn(a, b, pattern);
    let margin = 2;
    let rivals: Vec<usize> = (1..scored.len()).filter(|&q| scored[q].len() + margin > best).collect();
    match rivals.as_slice() {
        [] => Ok(scored.swap_remove(0)),
        [q] if twin(&scored[0], &scored[*q]) => {
            let x0 = x_axis(pts, &scored[0], pattern);
            let first = if x0[0].abs() > x0[1].abs() * 1f64.to_radians().tan() { x0[0] > 0.0 } else { x0[1] > 0.0 };
            Ok(scored.swap_remove(if first { 0 } else { *q }))
        }
        _ => Err(Miss::Ambiguous),
    }
}

/// Whether two labellings differ by the pattern's half turn: (i, j) ↔ (COLS−1−i, ROWS−1−j).
fn is_half_turn(a: &[(usize, usize)], b: &[(usize, usize)], pattern: &Pattern) -> bool {
    let of: HashMap<usize, usize> = b.iter().map(|&(idx, p)| (p, idx)).collect();
    a.iter().all(|&(idx, p)| {
        let (i, j) = (idx / pattern.rows, idx % pattern.rows);
        of.get(&p) == Some(&((pattern.cols - 1 - i) * pattern.rows + (pattern.rows - 1 - j)))
    })
}

/// The least-squares affine map from board (x, y) to image: its 2x2 linear part.
fn affine(pts: &[Pt], labels: &[(usize, usize)], pattern: &Pattern) -> [[f64; 2]; 2] {
    let n = labels.len() as f64;
    let obj: Vec<[f64; 3]> = labels.iter().map(|&(idx, _)| pattern.object_point(idx)).collect();
    let (mx, my) = (obj.iter().map(|o| o[0]).sum::<f64>() / n, obj.iter().map(|o| o[1]).sum::<f64>() / n);
    let (mu, mv) = (
        labels.iter().map(|&(_, p)| pts[p].p[0]).sum::<f64>() / n,
        labels.iter().map(|&(_, p)| pts[p].p[1]).sum::<f64>() / n,
    );
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    let (mut sux, mut suy, mut svx, mut svy) = (0.0, 0.0, 0.0, 0.0);
    for (o, &(_, p)) in obj.iter().zip(labels) {
        let (x, y) = (o[0] - mx, o[1] - my);
        let (u, v) = (pts[p].p[0] - mu, pts[p].p[1] - mv);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sux += u * x;
        suy += u * y;
        svx += v * x;
        svy += v * y;
    }
    let det = sxx * syy - sxy * sxy;
    if det.abs() < 1e-30 {
        return [[0.0; 2]; 2];
    }
    // [u] = A [x y]ᵀ: A = [Σux Σuy; Σvx Σvy] · inv([Σxx Σxy; Σxy Σyy]).
    let inv = [[syy / det, -sxy / det], [-sxy / det, sxx / det]];
    [
        [sux * inv[0][0] + suy * inv[1][0], sux * inv[0][1] + suy * inv[1][1]],
        [svx * inv[0][0] + svy * inv[1][0], svx * inv[0][1] + svy * inv[1][1]],
    ]
}

/// The board's front faces the camera: board x and y map to the image without a mirror
/// (image u right, v down, as the camera's x and y; a mirrored map needs the camera
/// behind the board).
fn front_facing(pts: &[Pt], labels: &[(usize, usize)], pattern: &Pattern) -> bool {
    let a = affine(pts, labels, pattern);
    a[0][0] * a[1][1] - a[0][1] * a[1][0] > 0.0
}

/// Image direction of the board's x axis under a labelling.
fn x_axis(pts: &[Pt], labels: &[(usize, usize)], pattern: &Pattern) -> [f64; 2] {
    let a = affine(pts, labels, pattern);
    [a[0][0], a[1][0]]
}

/// Every lattice line bends smoothly: the second difference of three consecutive points is
/// small against their spacing. A point labelled one step off breaks this. Perspective is
/// taken out first: the differences are of the points' offsets from a homography of the
/// whole lattice, so a tilted board's shrinking spacings (a second difference of a sixth of
/// a step on a close, wide view) pass while distortion's bend and a wrong label still show.
fn check_smooth(pts: &[Pt], lattice: &HashMap<Cell, usize>) -> Result<(), Miss> {
    let cells: Vec<(Cell, usize)> = lattice.iter().map(|(&c, &k)| (c, k)).collect();
    let grid: Vec<[f64; 2]> = cells.iter().map(|&((m, n), _)| [f64::from(m), f64::from(n)]).collect();
    let image: Vec<[f64; 2]> = cells.iter().map(|&(_, k)| pts[k].p).collect();
    let h = crate::calib::fit_homography(&grid, &image);
    // Offset of a point from the homography's image of its cell (the point itself without one).
    let offset = |(m, n): Cell, p: [f64; 2]| -> [f64; 2] {
        let Some(h) = h else { return p };
        let (x, y) = (f64::from(m), f64::from(n));
        let w = h[6] * x + h[7] * y + h[8];
        if w.abs() <= 1e-12 || w.is_nan() {
            return p;
        }
        [p[0] - (h[0] * x + h[1] * y + h[2]) / w, p[1] - (h[3] * x + h[4] * y + h[5]) / w]
    };
    for (&(m, n), &k) in lattice {
        for d in [(1, 0), (0, 1), (1, 1), (1, -1)] {
            let (ca, cb) = ((m - d.0, n - d.1), (m + d.0, n + d.1));
            let (Some(&a), Some(&b)) = (lattice.get(&ca), lattice.get(&cb)) else {
                continue;
            };
            let (pa, pb) = (pts[a].p, pts[b].p);
            let (ra, r, rb) = (offset(ca, pa), offset((m, n), pts[k].p), offset(cb, pb));
            let second = (ra[0] - 2.0 * r[0] + rb[0]).hypot(ra[1] - 2.0 * r[1] + rb[1]);
            if second > 0.15 * dist(pa, pb) / 2.0 + 0.5 {
                return Err(Miss::Inconsistent);
            }
        }
    }
    Ok(())
}

/// Fits a homography from board to image to the labelled points; the largest residual must
/// stay well below the local spacing (distortion bends the grid by a few pixels at most; a
/// wrong label moves a point by a whole spacing). Returns the RMS residual.
pub(crate) fn homography_check(points: &[GridPoint], pattern: &Pattern) -> Result<f64, Miss> {
    let obj: Vec<[f64; 2]> = points
        .iter()
        .map(|g| {
            let o = pattern.object_point(g.index);
            [o[0], o[1]]
        })
        .collect();
    let img: Vec<[f64; 2]> = points.iter().map(|g| g.image).collect();
    let h = crate::calib::fit_homography(&obj, &img).ok_or(Miss::Inconsistent)?;
    let mut sq = 0.0;
    let mut worst_rel: f64 = 0.0;
    for (k, (o, m)) in obj.iter().zip(&img).enumerate() {
        let w = h[6] * o[0] + h[7] * o[1] + h[8];
        if w.abs() < 1e-12 {
            return Err(Miss::Inconsistent);
        }
        let (u, v) = ((h[0] * o[0] + h[1] * o[1] + h[2]) / w, (h[3] * o[0] + h[4] * o[1] + h[5]) / w);
        let e = (u - m[0]).hypot(v - m[1]);
        sq += e * e;
        // The local spacing: distance to the nearest other grid point.
        let spacing =
            img.iter().enumerate().filter(|&(q, _)| q != k).map(|(_, p)| dist(*p, *m)).fold(f64::INFINITY, f64::min);
        worst_rel = worst_rel.max(e / spacing);
    }
    if worst_rel.is_nan() || worst_rel >= 0.3 {
        return Err(Miss::Inconsistent);
    }
    Ok((sq / points.len() as f64).sqrt())
}

#[cfg(test)]
mod test {
    use super::*;
    use proptest::prelude::*;

    /// A camera looking at the board: rotation about the optical axis `roll`, then tilts
    /// about the board's x and y axes, the board's middle at `distance` metres.
    #[derive(Debug, Clone, Copy)]
    struct Shot {
        roll: f64,
        tilt_x: f64,
        tilt_y: f64,
        distance: f64,
        k1: f64,
    }

    const F: f64 = 300.0;
    const SIZE: [f64; 2] = [346.0, 260.0];

    impl Shot {
        fn flat(roll_deg: f64) -> Self {
            Self { roll: roll_deg.to_radians(), tilt_x: 0.0, tilt_y: 0.0, distance: 0.7, k1: 0.0 }
        }

        /// Image of board point (x, y) (board middle at the origin), px; and the circle's
        /// apparent radius.
        fn project(&self, pattern: &Pattern, x: f64, y: f64) -> ([f64; 2], f64) {
            let mid = [
                (pattern.cols - 1) as f64 * pattern.spacing / 2.0,
                (2 * pattern.rows - 1) as f64 * pattern.spacing / 2.0,
            ];
            let (x, y) = (x - mid[0], y - mid[1]);
            // Tilt about y (x toward the camera), then about x.
            let (cy, sy) = (self.tilt_y.cos(), self.tilt_y.sin());
            let (x1, z1) = (x * cy, -x * sy);
            let (cx, sx) = (self.tilt_x.cos(), self.tilt_x.sin());
            let (y2, z2) = (y * cx - z1 * sx, y * sx + z1 * cx);
            let (cr, sr) = (self.roll.cos(), self.roll.sin());
            let (x3, y3) = (x1 * cr - y2 * sr, x1 * sr + y2 * cr);
            let z = self.distance + z2;
            let (a, b) = (x3 / z, y3 / z);
            let d = 1.0 + self.k1 * (a * a + b * b);
            ([SIZE[0] / 2.0 + F * a * d, SIZE[1] / 2.0 + F * b * d], F * pattern.spacing * 0.3 / z)
        }
    }

    fn centre(p: [f64; 2], r: f64) -> CenterRecord {
        CenterRecord { u: p[0] as f32, v: p[1] as f32, r: r as f32, spread: 0.3, n: 60, converged: true }
    }

    /// The centres of a shot, each with its true index (`None`: clutter), noise `noise` px
    /// from a fixed generator.
    fn shoot(pattern: &Pattern, shot: &Shot, noise: f64, seed: u64) -> Vec<(CenterRecord, Option<usize>)> {
        let mut rng = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..pattern.len())
            .map(|k| {
                let o = pattern.object_point(k);
                let (p, r) = shot.project(pattern, o[0], o[1]);
                (centre([p[0] + noise * next(), p[1] + noise * next()], r), Some(k))
            })
            .collect()
    }

    fn in_view(c: &[(CenterRecord, Option<usize>)]) -> Vec<(CenterRecord, Option<usize>)> {
        c.iter()
            .filter(|(c, _)| c.u > 0.0 && c.v > 0.0 && f64::from(c.u) < SIZE[0] && f64::from(c.v) < SIZE[1])
            .copied()
            .collect()
    }

    /// Every point found carries the index of the board position it lies on: the nearest
    /// true circle position (of `truth`'s grid circles, lost ones included where given) is the
    /// one it is paired with, and lies within 30 % of that circle's nearest-neighbour spacing.
    /// A wrong ordering fails. (A blob exactly where a lost circle would be is, to any finder,
    /// that circle.)
    fn check(found: &GridDetection, truth: &[(CenterRecord, Option<usize>)]) {
        let circles: Vec<([f64; 2], usize)> =
            truth.iter().filter_map(|(c, i)| Some(([f64::from(c.u), f64::from(c.v)], (*i)?))).collect();
        for g in &found.points {
            let (p, idx) = circles.iter().min_by(|a, b| dist(a.0, g.image).total_cmp(&dist(b.0, g.image))).unwrap();
            let spacing = circles.iter().filter(|c| c.1 != *idx).map(|c| dist(c.0, *p)).fold(f64::INFINITY, f64::min);
            assert_eq!(*idx, g.index, "point at {:?} labelled {}", g.image, g.index);
            assert!(dist(*p, g.image) < 0.3 * spacing, "point at {:?} is off its board position", g.image);
        }
    }

    fn find(c: &[(CenterRecord, Option<usize>)], pattern: &Pattern) -> Result<GridDetection, Miss> {
        let centres: Vec<CenterRecord> = c.iter().map(|x| x.0).collect();
        find_grid(&centres, pattern, &FindOptions::default())
    }

    /// The far columns of the board too dim to be seen, and a background disc that lines up
    /// with the lattice one diagonal step beyond the first column: shifted by two columns,
    /// the lattice plus the disc fills the whole pattern, the true labelling leaves the disc
    /// out. Labelled it would be two columns off, every point wrong; it must be a miss.
    #[test]
    fn a_lone_disc_beyond_a_partial_grid_does_not_shift_its_labels() {
        let pattern = Pattern::new(4, 11, 0.024).unwrap();
        for deg in (0..360).step_by(30) {
            let shot = Shot { distance: 0.9, ..Shot::flat(f64::from(deg) + 4.0) };
            let all = shoot(&pattern, &shot, 0.1, deg as u64);
            let mut seen: Vec<(CenterRecord, Option<usize>)> =
                all.iter().filter(|(_, i)| i.is_some_and(|i| i / pattern.rows <= 8)).copied().collect();
            // Board point (column −2, row 1): where a grid two columns longer would have one.
            let (p, r) = shot.project(&pattern, -2.0 * pattern.spacing, 2.0 * pattern.spacing);
            seen.push((centre(p, r), None));
            let truth: Vec<_> = all.iter().copied().chain(std::iter::once((centre(p, r), None))).collect();
            match find(&seen, &pattern) {
                Ok(g) => check(&g, &truth),
                Err(m) => assert_eq!(m, Miss::Ambiguous, "{deg}°"),
            }
        }
    }

    #[test]
    fn any_rotation_gives_the_one_labelling() {
        for (rows, cols) in [(4, 11), (3, 9), (3, 7)] {
            let pattern = Pattern::new(rows, cols, 0.024).unwrap();
            for deg in (0..360).step_by(10) {
                let shot = Shot { distance: 0.35 + 0.05 * cols as f64, ..Shot::flat(f64::from(deg) + 3.0) };
                let c = shoot(&pattern, &shot, 0.2, deg as u64);
                let g = find(&c, &pattern).unwrap_or_else(|m| panic!("{rows}x{cols} at {deg}°: {m}"));
                assert_eq!(g.points.len(), pattern.len());
                check(&g, &c);
            }
        }
    }

    #[test]
    fn even_columns_take_the_labelling_whose_x_axis_points_right() {
        let pattern = Pattern::new(4, 10, 0.024).unwrap();
        for deg in (0..360).step_by(15) {
            let shot = Shot::flat(f64::from(deg) + 2.0);
            let c = shoot(&pattern, &shot, 0.1, 7);
            let g = find(&c, &pattern).unwrap_or_else(|m| panic!("{deg}°: {m}"));
            assert_eq!(g.points.len(), 40);
            let at = |i: usize| g.points.iter().find(|p| p.index == i).unwrap().image;
            // Board x runs from index 0 (i = 0) to the last column.
            let x_axis = [at(36)[0] - at(0)[0], at(36)[1] - at(0)[1]];
            let horizontal = x_axis[0].abs() > x_axis[1].abs() * 1f64.to_radians().tan();
            assert!(if horizontal { x_axis[0] > 0.0 } else { x_axis[1] > 0.0 }, "{deg}°: x axis {x_axis:?}");
            // Either labelling is the board's, or its half turn.
            let truth =
                c.iter().map(|(c, i)| (*c, i.map(|i| if x_axis == x_axis { i } else { 0 }))).collect::<Vec<_>>();
            let half_turn = |i: usize| (pattern.cols - 1 - i / 4) * 4 + (3 - i % 4);
            let direct = g
                .points
                .iter()
                .all(|p| truth.iter().any(|(c, i)| *i == Some(p.index) && (f64::from(c.u) - p.image[0]).abs() < 1e-3));
            let turned = g.points.iter().all(|p| {
                truth.iter().any(|(c, i)| *i == Some(half_turn(p.index)) && (f64::from(c.u) - p.image[0]).abs() < 1e-3)
            });
            assert!(direct || turned, "{deg}°");
        }
    }

    /// A board tilted steeply and close fills a wide view with spacings shrinking by half
    /// from its near side to its far side; the lines are straight, so it is a grid.
    #[test]
    fn close_steep_views_pass_the_smoothness_check() {
        let pattern = Pattern::new(3, 9, 0.027).unwrap();
        for (k, (tx, ty)) in [(0.0, 0.7), (0.0, -0.7), (0.7, 0.0), (0.5, 0.5)].into_iter().enumerate() {
            let shot = Shot { tilt_x: tx, tilt_y: ty, distance: 0.32, ..Shot::flat(10.0 + 40.0 * k as f64) };
            let c = in_view(&shoot(&pattern, &shot, 0.2, k as u64));
            assert_eq!(c.len(), pattern.len(), "shot {k} must be wholly in view");
            let g = find(&c, &pattern).unwrap_or_else(|m| panic!("shot {k}: {m}"));
            assert_eq!(g.points.len(), pattern.len());
            check(&g, &c);
        }
    }

    #[test]
    fn perspective_and_distortion() {
        let pattern = Pattern::new(4, 11, 0.024).unwrap();
        for (k, (tx, ty, k1)) in
            [(0.6, 0.0, 0.0), (0.0, 0.7, 0.0), (-0.5, 0.5, -0.3), (0.4, -0.6, -0.35), (0.0, 0.0, 0.2)]
                .into_iter()
                .enumerate()
        {
            let shot = Shot { tilt_x: tx, tilt_y: ty, k1, ..Shot::flat(25.0 * k as f64) };
            let c = shoot(&pattern, &shot, 0.3, k as u64);
            let g = find(&c, &pattern).unwrap_or_else(|m| panic!("shot {k}: {m}"));
            assert_eq!(g.points.len(), 44);
            check(&g, &c);
        }
    }

    #[test]
    fn missing_circles_and_clutter_beside_the_grid() {
        let pattern = Pattern::new(4, 11, 0.024).unwrap();
        let shot = Shot::flat(20.0);
        let mut c = shoot(&pattern, &shot, 0.2, 3);
        // Five circles lost (a circle moving along its own edge fires few events).
        for k in [5, 12, 21, 30, 38] {
            c.retain(|x| x.1 != Some(k));
        }
        let s = pattern.spacing;
        let r = c[0].0.r as f64;
        // Marks printed beside the grid, nearly where a next row would be; blobs around.
        for (x, y) in [(9.1 * s, -0.8 * s), (10.7 * s, -0.8 * s)] {
            c.push((centre(shot.project(&pattern, x, y).0, r * 0.9), None));
        }
        for k in 0..25 {
            let a = k as f64 * 2.4;
            c.push((
                centre([173.0 + 160.0 * a.cos(), 130.0 + 125.0 * a.sin()], r * (0.6 + 0.1 * (k % 9) as f64)),
                None,
            ));
        }
        let c = in_view(&c);
        let g = find(&c, &pattern).unwrap_or_else(|m| panic!("{m}"));
        assert_eq!(g.points.len(), 39);
        check(&g, &c);
    }

    #[test]
    fn a_second_partial_grid_is_not_taken_for_the_grid() {
        let pattern = Pattern::new(4, 11, 0.024).unwrap();
        let shot = Shot { distance: 1.1, ..Shot::flat(0.0) };
        let c = shoot(&pattern, &shot, 0.1, 4);
        // Another print of a 3x5 piece of the pattern at the same scale, to the right.
        let piece: Vec<_> = c
            .iter()
            .filter(|(_, i)| i.is_some_and(|i| i / 4 < 5 && i % 4 < 3))
            .map(|(p, _)| (CenterRecord { u: p.u + 200.0, ..*p }, None))
            .collect();
        let mut all = c.clone();
        all.extend(piece);
        let all = in_view(&all);
        match find(&all, &pattern) {
            Ok(g) => check(&g, &all),
            Err(m) => panic!("grid beside a second partial grid: {m}"),
        }
        // Only the piece: too small to be the grid.
        let piece_only: Vec<_> = all.iter().filter(|x| x.1.is_none()).copied().collect();
        assert!(find(&piece_only, &pattern).is_err());
    }

    #[test]
    fn mirrored_views() {
        // With odd COLS the pattern is its own mirror image (column i ↔ COLS−1−i): a mirrored
        // view is a view of the board from the front, labelled as such. With even COLS no
        // labelling keeps the board's front to the camera: a miss.
        for deg in [0.0, 40.0, 130.0, 250.0] {
            let odd = Pattern::new(4, 11, 0.024).unwrap();
            let c = shoot(&odd, &Shot::flat(deg), 0.1, 5);
            let mirrored: Vec<_> = c
                .iter()
                .map(|(p, i)| (CenterRecord { u: SIZE[0] as f32 - p.u, ..*p }, i.map(|i| (10 - i / 4) * 4 + i % 4)))
                .collect();
            let g = find(&mirrored, &odd).unwrap_or_else(|m| panic!("{deg}°: {m}"));
            check(&g, &mirrored);
            let even = Pattern::new(4, 10, 0.024).unwrap();
            let c = shoot(&even, &Shot::flat(deg), 0.1, 5);
            let mirrored: Vec<_> =
                c.iter().map(|(p, i)| (CenterRecord { u: SIZE[0] as f32 - p.u, ..*p }, *i)).collect();
            assert_eq!(find(&mirrored, &even).unwrap_err(), Miss::NoPlacement, "{deg}°");
        }
    }

    #[test]
    fn a_larger_grid_or_a_partial_view_is_not_labelled() {
        let big = Pattern::new(4, 11, 0.024).unwrap();
        let c = shoot(&big, &Shot::flat(10.0), 0.1, 6);
        // The 4x11 grid is no 3x9 grid (it holds more than two strays around one).
        assert!(find(&c, &Pattern::new(3, 9, 0.024).unwrap()).is_err());
        // Two whole columns out of view: which columns are seen is not known.
        let cut: Vec<_> = c.iter().filter(|(_, i)| i.is_some_and(|i| i / 4 >= 2)).copied().collect();
        assert_eq!(find(&cut, &big).unwrap_err(), Miss::Ambiguous);
    }

    #[test]
    fn bad_numbers_and_empty_input_are_misses() {
        let pattern = Pattern::new(4, 11, 0.024).unwrap();
        assert_eq!(find(&[], &pattern).unwrap_err(), Miss::TooFewCentres);
        let mut c = shoot(&pattern, &Shot::flat(0.0), 0.1, 8);
        for (k, x) in c.iter_mut().enumerate() {
            match k % 4 {
                0 => x.0.u = f32::NAN,
                1 => x.0.r = f32::INFINITY,
                2 => x.0.v = -1e30,
                _ => {}
            }
        }
        assert!(find(&c, &pattern).is_err());
        let same = vec![(centre([10.0, 10.0], 3.0), None); 60];
        assert!(find(&same, &pattern).is_err());
    }

    #[test]
    fn pattern_text_and_points() {
        let p = Pattern::parse("4x11", 0.024).unwrap();
        assert_eq!((p.rows, p.cols, p.len()), (4, 11, 44));
        let o = p.object_point(5);
        assert!((o[0] - 0.024).abs() < 1e-12 && (o[1] - 0.072).abs() < 1e-12 && o[2] == 0.0);
        assert!(Pattern::parse("4-11", 0.02).unwrap_err().contains("ROWSxCOLS"));
        assert!(Pattern::parse("1x11", 0.02).is_err());
        assert!(Pattern::new(4, 11, -1.0).is_err());
        assert_eq!(p.picture().lines().next().unwrap(), "o   o   o   o   o   o");
    }

    /// Whatever the pose, clutter and losses: a grid found is labelled right. Random cases
    /// (proptest's runner, so a failure shrinks and is kept in proptest-regressions/), and a
    /// floor on the grids found: a finder that never succeeded would pass the labelling check
    /// vacuously.
    #[test]
    fn never_a_wrong_ordering() {
        const CASES: u32 = 200;
        // Measured: found in 187 to 193 of the 200 cases over six runs (94 %, a standard
        // deviation of 3.4 cases); 160 is eight deviations below, so chance never fails it, but a
        // finder losing a sixth of these grids does.
        const FLOOR: u32 = 160;
        let config = ProptestConfig { source_file: Some(file!()), ..ProptestConfig::with_cases(CASES) };
        let mut runner = proptest::test_runner::TestRunner::new(config);
        let cases = (
            0.0f64..360.0,
            -0.7f64..0.7,
            -0.7f64..0.7,
            0.45f64..1.2,
            -0.35f64..0.1,
            proptest::collection::vec(0usize..44, 0..10),
            proptest::collection::vec((0.0f64..346.0, 0.0f64..260.0, 0.5f64..1.6), 0..40),
            0u64..1000,
        );
        let found = std::cell::Cell::new(0u32);
        let result = runner.run(&cases, |(roll, tilt_x, tilt_y, distance, k1, lost, clutter, seed)| {
            let pattern = Pattern::new(4, 11, 0.024).unwrap();
            let shot = Shot { roll: roll.to_radians(), tilt_x, tilt_y, distance, k1 };
            let all = shoot(&pattern, &shot, 0.3, seed);
            let mut c = all.clone();
            c.retain(|x| !lost.contains(&x.1.unwrap_or(usize::MAX)));
            let r = f64::from(c.first().map_or(4.0, |x| x.0.r));
            c.extend(clutter.iter().map(|&(u, v, f)| (centre([u, v], r * f), None)));
            let c = in_view(&c);
            if let Ok(g) = find(&c, &pattern) {
                found.set(found.get() + 1);
                check(&g, &all);
            }
            Ok(())
        });
        if let Err(e) = result {
            panic!("{e}\n{runner}");
        }
        let found = found.get();
        println!("grid found in {found} of {CASES} cases");
        assert!(found >= FLOOR, "grid found in only {found} of {CASES} cases, fewer than {FLOOR}");
    }
}
