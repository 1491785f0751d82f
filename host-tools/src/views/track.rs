//! Following the grid through time: labelling a window the grid finder gave up on from the
//! windows around it.
//!
//! The finder labels each window on its own, and must refuse when the lattice it sees fits
//! the pattern in more than one way (an edge row fired too few events to be detected) or
//! holds too few points to be placed. The board moves smoothly over the 33 ms between
//! windows, so the grids found just before and after say where each board point is now, to a
//! small fraction of the grid's spacing, while a wrong label is a whole spacing away. A
//! centre close to a point's predicted place takes its label; the labelled set is then
//! refined through its own homography and must pass the finder's homography check.
//!
//! Because every label comes from the prediction, a followed grid may be a part of the
//! board: in a dim scene a 4000-event window often holds too few events of a side or a
//! patch of the board for its circles to be fitted, for a run of windows at a time. A part
//! is taken when it holds at least [`MIN_FOLLOWED_POINTS`] points over at least
//! [`MIN_FOLLOWED_SPAN`] board columns and rows, enough for its own homography check.
//!
//! Windows the finder labelled anchor the first round; each round's grids anchor the next,
//! so a run of misses is followed in from both ends, one window a round. A grid so labelled
//! anchors its neighbours through its own homography, fitted to its own centres, not through
//! the prediction it was labelled by: the prediction's error does not add up along the
//! chain (on simulated dim recordings, DAVIS346 4x11 cone, seeds 1-7, the labelled centres
//! lie within 0.25 spacings of their prediction all along runs of up to 27 windows the
//! finder missed).

use crate::calib::fit_homography;
use crate::input::detections::WindowRecord;
use crate::stats::median;
use crate::views::grid::{homography_check, GridDetection, GridPoint, Miss, Pattern};

/// How far and how strictly the grid is followed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackOptions {
    /// Farthest in time an anchor (a window the finder labelled) may be from the window
    /// labelled from it, µs.
    pub max_gap_us: u64,
    /// A centre takes a board point's label when it lies within this fraction of the local
    /// grid spacing of the point's predicted place. A wrong label is a whole spacing off.
    pub gate: f64,
    /// The same after the labels have been refined through the view's own homography.
    pub refined_gate: f64,
    /// Fewest board points a followed grid must hold (never fewer than
    /// [`MIN_FOLLOWED_POINTS`]). Each label comes from the anchors' prediction, not from the
    /// points' own arrangement, so a part of the grid is labelled as surely as the whole;
    /// the count is what the view's own homography check needs to have power.
    pub min_points: usize,
    /// A centre whose radius differs from the median of the labelled ones by more than this
    /// fraction is not a grid circle (clutter near the grid).
    pub radius_tolerance: f64,
}

impl Default for TrackOptions {
    fn default() -> Self {
        Self {
            max_gap_us: 70_000,
            gate: 0.25,
            refined_gate: 0.15,
            min_points: MIN_FOLLOWED_POINTS,
            radius_tolerance: 0.35,
        }
    }
}

/// Fewest points a followed grid holds: three times the four a homography needs, so that
/// the homography check over them has twice as many residuals left as the fit took. With
/// 8 points the property test below found a part whose labels were all one spacing off
/// pass the check.
pub const MIN_FOLLOWED_POINTS: usize = 12;

/// Fewest board columns, and fewest board rows (`y` levels, `2j + i mod 2`), a followed grid
/// must span: points along one or two lines leave the view's homography free across them,
/// and its check blind there.
pub const MIN_FOLLOWED_SPAN: usize = 3;

fn apply(h: &[f64; 9], o: [f64; 2]) -> Option<[f64; 2]> {
    let w = h[6] * o[0] + h[7] * o[1] + h[8];
    if w.abs() < 1e-12 {
        return None;
    }
    let p = [(h[0] * o[0] + h[1] * o[1] + h[2]) / w, (h[3] * o[0] + h[4] * o[1] + h[5]) / w];
    p.iter().all(|x| x.is_finite()).then_some(p)
}

fn board(pattern: &Pattern) -> Vec<[f64; 2]> {
    pattern.object_points().iter().map(|o| [o[0], o[1]]).collect()
}

/// Every board point's image position under the homography of the labelled `points`.
fn projected(points: &[GridPoint], board: &[[f64; 2]]) -> Option<Vec<[f64; 2]>> {
    let obj: Vec<[f64; 2]> = points.iter().map(|g| board[g.index]).collect();
    let img: Vec<[f64; 2]> = points.iter().map(|g| g.image).collect();
    let h = fit_homography(&obj, &img)?;
    board.iter().map(|&o| apply(&h, o)).collect()
}

/// An anchor: every board point's image position under the grid's own homography, where
/// the grid vouches for it (the point or one of its diagonal neighbours on the board was
/// labelled); NaN elsewhere. A homography fitted to part of the grid extrapolates freely
/// beyond it: a grid of eight points on the right of the board put the left of the next
/// window's prediction a whole spacing off (found by the property test below), and labels
/// there are then wrong together and pass the homography check.
fn anchor(grid: &GridDetection, board: &[[f64; 2]], pattern: &Pattern) -> Option<Vec<[f64; 2]>> {
    let mut place = projected(&grid.points, board)?;
    let cell = |index: usize| {
        let (i, j) = (index / pattern.rows, index % pattern.rows);
        (i as i64, (2 * j + i % 2) as i64)
    };
    let seen: std::collections::HashSet<(i64, i64)> = grid.points.iter().map(|g| cell(g.index)).collect();
    for (index, p) in place.iter_mut().enumerate() {
        let (i, y) = cell(index);
        let vouched =
            [(0, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)].iter().any(|&(di, dy)| seen.contains(&(i + di, y + dy)));
        if !vouched {
            *p = [f64::NAN, f64::NAN];
        }
    }
    Some(place)
}

/// Where the anchors put every board point at time `t`: interpolated between one anchor on
/// each side, or extrapolated from the two nearest on one side.
fn predict(anchors: &[(u64, Vec<[f64; 2]>)], t: u64) -> Option<Vec<[f64; 2]>> {
    let before: Vec<&(u64, Vec<[f64; 2]>)> = anchors.iter().filter(|a| a.0 <= t).collect();
    let after: Vec<&(u64, Vec<[f64; 2]>)> = anchors.iter().filter(|a| a.0 > t).collect();
    let (a, b) = match (before.last(), after.first()) {
        (Some(a), Some(b)) => (*a, *b),
        (Some(a), None) if before.len() >= 2 => (before[before.len() - 2], *a),
        (None, Some(b)) if after.len() >= 2 => (*b, after[1]),
        _ => return None,
    };
    let span = b.0 as f64 - a.0 as f64;
    if span <= 0.0 {
        return None;
    }
    let s = (t as f64 - a.0 as f64) / span;
    Some(a.1.iter().zip(&b.1).map(|(p, q)| [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])]).collect())
}

/// Distance from each predicted point to its nearest neighbour among them.
fn spacings(pred: &[[f64; 2]]) -> Vec<f64> {
    pred.iter()
        .enumerate()
        .map(|(i, p)| {
            pred.iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Each board point's nearest centre within `gate` spacings of its predicted place `pred`,
/// and, when `bound` is given as (prediction, gate), within that gate of that prediction too.
fn matched(
    pred: &[[f64; 2]],
    window: &WindowRecord,
    gate: f64,
    radius: Option<(f64, f64)>,
    bound: Option<(&[[f64; 2]], f64)>,
) -> Vec<GridPoint> {
    let spacing = spacings(pred);
    let bound_spacing = bound.map(|(b, _)| spacings(b));
    let mut points = Vec::new();
    for (index, (p, s)) in pred.iter().zip(&spacing).enumerate() {
        let within_bound = |q: [f64; 2]| match (bound, &bound_spacing) {
            (Some((b, g)), Some(bs)) => (q[0] - b[index][0]).hypot(q[1] - b[index][1]) <= g * bs[index],
            _ => true,
        };
        let best = window
            .centers
            .iter()
            .filter(|c| c.u.is_finite() && c.v.is_finite() && c.r.is_finite() && c.r > 0.0)
            .filter(|c| radius.is_none_or(|(median, tol)| (f64::from(c.r) / median - 1.0).abs() <= tol))
            .map(|c| ([f64::from(c.u), f64::from(c.v)], c))
            .map(|(q, c)| (q, c, (q[0] - p[0]).hypot(q[1] - p[1])))
            .filter(|&(q, _, d)| d <= gate * s && within_bound(q))
            .min_by(|a, b| a.2.total_cmp(&b.2));
        if let Some((image, c, _)) = best {
            let (radius_px, spread_px, events) = (f64::from(c.r), f64::from(c.spread), c.n);
            points.push(GridPoint { index, image, radius_px, spread_px, events });
        }
    }
    points
}

/// Most rounds of following: each round's grids anchor the next (a run of windows missed
/// in a row is followed in from both ends). 16 rounds reach half a second into a run from
/// each end at the default 33 ms between windows: a dim scene's runs of partial windows
/// last up to about a second (27 windows on simulated recordings; with 8 rounds 90-96 % of
/// the wholly-in-view windows were labelled instead of all). The bound keeps a grid that
/// passed the checks wrongly from labelling windows without end.
pub const MAX_ROUNDS: usize = 16;

/// Why a window the finder missed was not followed either.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Unfollowed {
    /// The finder labelled the window itself: nothing to follow.
    Found,
    /// No anchors near enough in time to predict the grid from.
    NoAnchors,
    /// Too few centres near the predicted points (how many there were).
    TooFewMatched(usize),
    /// Too few left after the refinement through the view's own homography.
    TooFewRefined(usize),
    /// The points span too few board columns or rows for their homography to check them.
    TooNarrow,
    /// The labelled points failed the finder's homography check.
    Inconsistent,
}

/// A window labelled from the windows around it.
#[derive(Debug, Clone, PartialEq)]
pub struct Followed {
    /// The grid as labelled.
    pub grid: GridDetection,
    /// Farthest a labelled centre lies from where the anchors put its board point, in local
    /// grid spacings: the margin against a wrong label, which would be a whole spacing off.
    pub prediction_offset: f64,
}

/// Labels, where it can, the windows the finder missed: `found[k]` is the finder's result
/// for `windows[k]` (windows in time order); the answer holds a grid for each missed window
/// that its anchors label with confidence, `None` elsewhere (and for every window the finder
/// labelled itself). A window labelled in one round is an anchor in the next, for up to
/// [`MAX_ROUNDS`] rounds: every grid so labelled passed the same checks as the first.
pub fn follow(
    windows: &[WindowRecord],
    found: &[Result<GridDetection, Miss>],
    pattern: &Pattern,
    opts: &TrackOptions,
) -> Vec<Option<GridDetection>> {
    follow_explained(windows, found, pattern, opts).into_iter().map(|r| r.ok().map(|f| f.grid)).collect()
}

/// As [`follow`], with how far each followed grid lay from its prediction and why each
/// window left was not followed (its last round's reason).
pub fn follow_explained(
    windows: &[WindowRecord],
    found: &[Result<GridDetection, Miss>],
    pattern: &Pattern,
    opts: &TrackOptions,
) -> Vec<Result<Followed, Unfollowed>> {
    let board = board(pattern);
    let n = windows.len().min(found.len());
    let mut anchors: Vec<Option<Vec<[f64; 2]>>> =
        found.iter().take(n).map(|r| r.as_ref().ok().and_then(|g| anchor(g, &board, pattern))).collect();
    let mut out: Vec<Result<Followed, Unfollowed>> =
        found.iter().map(|r| Err(if r.is_ok() { Unfollowed::Found } else { Unfollowed::NoAnchors })).collect();
    for _ in 0..MAX_ROUNDS {
        let mut round: Vec<(usize, Followed)> = Vec::new();
        for k in 0..n {
            if found[k].is_ok() || out[k].is_ok() {
                continue;
            }
            match follow_one(windows, &anchors, k, &board, pattern, opts) {
                Ok(g) => round.push((k, g)),
                Err(why) => out[k] = Err(why),
            }
        }
        if round.is_empty() {
            break;
        }
        for (k, g) in round {
            anchors[k] = anchor(&g.grid, &board, pattern);
            out[k] = Ok(g);
        }
    }
    out
}

/// How many distinct board columns and rows (`y` levels) the points span.
fn span(points: &[GridPoint], pattern: &Pattern) -> (usize, usize) {
    let mut cols = std::collections::BTreeSet::new();
    let mut rows = std::collections::BTreeSet::new();
    for g in points {
        let (i, j) = (g.index / pattern.rows, g.index % pattern.rows);
        cols.insert(i);
        rows.insert(2 * j + i % 2);
    }
    (cols.len(), rows.len())
}

/// The points with at least one diagonal neighbour on the board (`(i ± 1, y ± S)`) among
/// them. A lone point lies where the homographies only extrapolate (a side of the board
/// unseen in this window and in the partial windows before it): a blob of clutter there can
/// agree with both to a few pixels and still be nearer another board point.
fn with_neighbours(points: Vec<GridPoint>, pattern: &Pattern) -> Vec<GridPoint> {
    let cell = |g: &GridPoint| {
        let (i, j) = (g.index / pattern.rows, g.index % pattern.rows);
        (i as i64, (2 * j + i % 2) as i64)
    };
    let cells: std::collections::HashSet<(i64, i64)> = points.iter().map(cell).collect();
    points
        .into_iter()
        .filter(|g| {
            let (i, y) = cell(g);
            [(1, 1), (1, -1), (-1, 1), (-1, -1)].iter().any(|&(di, dy)| cells.contains(&(i + di, y + dy)))
        })
        .collect()
}

/// Window `k` labelled from the anchors around it, if they say with confidence.
///
/// Each centre takes its label from where the anchors put the board points (within
/// [`TrackOptions::gate`] spacings), then again from the view's own homography through those
/// (within [`TrackOptions::refined_gate`]), and must stay within the first gate of the
/// anchors' place: a homography fitted to part of the grid extrapolates freely beyond it,
/// and must not carry a label there that the anchors do not give. A part of the grid is
/// labelled as surely as the whole, as long as it holds enough points over enough columns
/// and rows for the homography check ([`MIN_FOLLOWED_POINTS`], [`MIN_FOLLOWED_SPAN`]): in a
/// dim scene a 4000-event window often holds too few events of part of the board for its
/// circles to be fitted.
fn follow_one(
    windows: &[WindowRecord],
    anchors: &[Option<Vec<[f64; 2]>>],
    k: usize,
    board: &[[f64; 2]],
    pattern: &Pattern,
    opts: &TrackOptions,
) -> Result<Followed, Unfollowed> {
    let needed = opts.min_points.max(MIN_FOLLOWED_POINTS);
    let t = windows[k].t_ref_us;
    let near = |j: usize| windows[j].t_ref_us.abs_diff(t) <= opts.max_gap_us;
    // The two nearest anchors on each side, in time order.
    let mut around: Vec<(u64, Vec<[f64; 2]>)> = Vec::new();
    for j in (0..k).rev().take_while(|&j| near(j)).filter(|&j| anchors[j].is_some()).take(2) {
        around.insert(0, (windows[j].t_ref_us, anchors[j].clone().ok_or(Unfollowed::NoAnchors)?));
    }
    for j in (k + 1..anchors.len()).take_while(|&j| near(j)).filter(|&j| anchors[j].is_some()).take(2) {
        around.push((windows[j].t_ref_us, anchors[j].clone().ok_or(Unfollowed::NoAnchors)?));
    }
    let pred = predict(&around, t).ok_or(Unfollowed::NoAnchors)?;
    let first = matched(&pred, &windows[k], opts.gate, None, None);
    if first.len() < needed {
        return Err(Unfollowed::TooFewMatched(first.len()));
    }
    // Refine through the view's own homography, with clutter of the wrong size out.
    let r = median(&mut first.iter().map(|g| g.radius_px).collect::<Vec<_>>()).ok_or(Unfollowed::TooFewMatched(0))?;
    let refined = projected(&first, board).ok_or(Unfollowed::Inconsistent)?;
    let points =
        matched(&refined, &windows[k], opts.refined_gate, Some((r, opts.radius_tolerance)), Some((&pred, opts.gate)));
    let points = with_neighbours(points, pattern);
    if points.len() < needed {
        return Err(Unfollowed::TooFewRefined(points.len()));
    }
    let (cols, rows) = span(&points, pattern);
    if cols.min(rows) < MIN_FOLLOWED_SPAN {
        return Err(Unfollowed::TooNarrow);
    }
    let homography_rms_px = homography_check(&points, pattern).map_err(|_| Unfollowed::Inconsistent)?;
    let spacing = spacings(&pred);
    let prediction_offset = points
        .iter()
        .map(|g| (g.image[0] - pred[g.index][0]).hypot(g.image[1] - pred[g.index][1]) / spacing[g.index])
        .fold(0.0, f64::max);
    Ok(Followed { grid: GridDetection { points, homography_rms_px }, prediction_offset })
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::input::detections::CenterRecord;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A 4x11 grid seen flat: board metres to pixels, moved by `shift` px.
    fn shot(pattern: &Pattern, shift: [f64; 2]) -> Vec<[f64; 2]> {
        board(pattern).iter().map(|o| [60.0 + 600.0 * o[0] + shift[0], 40.0 + 600.0 * o[1] + shift[1]]).collect()
    }

    fn window(seq: u32, t_ref_us: u64, pts: &[[f64; 2]]) -> WindowRecord {
        WindowRecord {
            seq,
            t_ref_us,
            events: 4000,
            noise: 0,
            centers: pts
                .iter()
                .map(|p| CenterRecord { u: p[0] as f32, v: p[1] as f32, r: 5.0, spread: 0.1, n: 60, converged: true })
                .collect(),
            sensor: None,
        }
    }

    fn grid(pts: &[[f64; 2]]) -> GridDetection {
        GridDetection {
            points: pts
                .iter()
                .enumerate()
                .map(|(index, &image)| GridPoint { index, image, radius_px: 5.0, spread_px: 0.1, events: 60 })
                .collect(),
            homography_rms_px: 0.0,
        }
    }

    /// Three windows moving 4 px a step; the middle one lost its first column (the finder
    /// could not tell which column is missing). The anchors label it, every point right.
    #[test]
    fn labels_a_window_with_an_edge_column_missing() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let shots: Vec<Vec<[f64; 2]>> = (0..3).map(|k| shot(&pattern, [4.0 * k as f64, 1.0 * k as f64])).collect();
        let middle: Vec<[f64; 2]> = shots[1][4..].to_vec();
        let windows = [window(0, 0, &shots[0]), window(1, 33_000, &middle), window(2, 66_000, &shots[2])];
        let found = [Ok(grid(&shots[0])), Err(Miss::Ambiguous), Ok(grid(&shots[2]))];
        let out = follow(&windows, &found, &pattern, &TrackOptions::default());
        assert!(out[0].is_none() && out[2].is_none());
        let g = out[1].as_ref().expect("followed");
        assert_eq!(g.points.len(), 40);
        for p in &g.points {
            let want = shots[1][p.index];
            assert!((p.image[0] - want[0]).hypot(p.image[1] - want[1]) < 1e-3, "point {} mislabelled", p.index);
        }
    }

    /// Extrapolation from two anchors on one side; a clutter blob sits near a point whose
    /// circle was not detected and must not take its label.
    #[test]
    fn extrapolates_and_leaves_clutter_out() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let shots: Vec<Vec<[f64; 2]>> = (0..3).map(|k| shot(&pattern, [3.0 * k as f64, -2.0 * k as f64])).collect();
        let mut last: Vec<[f64; 2]> = shots[2].clone();
        last[7] = [last[7][0] + 3.5, last[7][1]];
        let windows = [window(0, 0, &shots[0]), window(1, 33_000, &shots[1]), window(2, 66_000, &last)];
        let found = [Ok(grid(&shots[0])), Ok(grid(&shots[1])), Err(Miss::TooFewPoints)];
        let g = follow(&windows, &found, &pattern, &TrackOptions::default())[2].clone().expect("followed");
        assert_eq!(g.points.len(), 43);
        assert!(g.points.iter().all(|p| p.index != 7));
    }

    /// Five windows missed in a row between two found ones are followed in from both ends,
    /// round by round, every point labelled right.
    #[test]
    fn a_run_of_misses_is_followed_in_from_both_ends() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let shots: Vec<Vec<[f64; 2]>> =
            (0..9).map(|k| shot(&pattern, [3.0 * k as f64 + 0.2 * (k * k) as f64, 1.5 * k as f64])).collect();
        let windows: Vec<WindowRecord> =
            shots.iter().enumerate().map(|(k, s)| window(k as u32, 33_000 * k as u64, &s[4..])).collect();
        let found: Vec<Result<GridDetection, Miss>> =
            (0..9).map(|k| if (2..7).contains(&k) { Err(Miss::Ambiguous) } else { Ok(grid(&shots[k])) }).collect();
        let out = follow(&windows, &found, &pattern, &TrackOptions::default());
        for k in 2..7 {
            let g = out[k].as_ref().unwrap_or_else(|| panic!("window {k} not followed"));
            assert_eq!(g.points.len(), 40);
            for p in &g.points {
                let want = shots[k][p.index];
                assert!((p.image[0] - want[0]).hypot(p.image[1] - want[1]) < 1e-3, "window {k}: point {}", p.index);
            }
        }
    }

    /// A grid a whole spacing away from where the anchors put it is not labelled: that is
    /// what a wrong label would look like.
    #[test]
    fn refuses_when_the_prediction_is_off() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let a = shot(&pattern, [0.0, 0.0]);
        let jumped = shot(&pattern, [6.0, 0.0]);
        let windows = [window(0, 0, &a), window(1, 33_000, &jumped), window(2, 66_000, &a)];
        let found = [Ok(grid(&a)), Err(Miss::Ambiguous), Ok(grid(&a))];
        assert!(follow(&windows, &found, &pattern, &TrackOptions::default())[1].is_none());
        // Too far in time from any anchor: not followed either.
        let windows = [window(0, 0, &a), window(1, 500_000, &a), window(2, 1_000_000, &a)];
        assert!(follow(&windows, &found, &pattern, &TrackOptions::default())[1].is_none());
    }

    /// Three windows; the middle one holds only the board's three leftmost columns (a dim
    /// scene: the rest fired too few events to be fitted), and some clutter. The anchors
    /// label the part, every point right, and leave the clutter out.
    #[test]
    fn a_partial_window_is_followed() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let shots: Vec<Vec<[f64; 2]>> = (0..3).map(|k| shot(&pattern, [4.0 * k as f64, -2.0 * k as f64])).collect();
        let mut part: Vec<[f64; 2]> = shots[1][..12].to_vec();
        part.extend([[200.0, 30.0], [150.0, 90.0], [shots[1][30][0] + 6.0, shots[1][30][1]]]);
        let windows = [window(0, 0, &shots[0]), window(1, 33_000, &part), window(2, 66_000, &shots[2])];
        let found = [Ok(grid(&shots[0])), Err(Miss::TooFewCentres), Ok(grid(&shots[2]))];
        let out = follow_explained(&windows, &found, &pattern, &TrackOptions::default());
        let f = out[1].as_ref().expect("followed");
        assert_eq!(f.grid.points.len(), 12);
        for p in &f.grid.points {
            let want = shots[1][p.index];
            assert!((p.image[0] - want[0]).hypot(p.image[1] - want[1]) < 1e-3, "point {} mislabelled", p.index);
        }
        assert!(f.prediction_offset < 0.01, "offset {}", f.prediction_offset);
        assert_eq!(out[0].as_ref().unwrap_err(), &Unfollowed::Found);
    }

    /// Too few points, or points along two columns only, are not followed: the view's own
    /// homography could not check them. A part half a spacing from its prediction is not
    /// followed either.
    #[test]
    fn a_too_sparse_or_narrow_or_displaced_part_is_refused() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let shots: Vec<Vec<[f64; 2]>> = (0..3).map(|k| shot(&pattern, [4.0 * k as f64, 1.0 * k as f64])).collect();
        let follow_middle = |middle: &[[f64; 2]]| {
            let windows = [window(0, 0, &shots[0]), window(1, 33_000, middle), window(2, 66_000, &shots[2])];
            let found = [Ok(grid(&shots[0])), Err(Miss::TooFewCentres), Ok(grid(&shots[2]))];
            follow_explained(&windows, &found, &pattern, &TrackOptions::default())[1].clone()
        };
        // Eleven points spread over the board: one short of twelve.
        let sparse: Vec<[f64; 2]> = [0, 5, 7, 13, 18, 21, 24, 30, 33, 39, 43].iter().map(|&i| shots[1][i]).collect();
        assert_eq!(follow_middle(&sparse).unwrap_err(), Unfollowed::TooFewMatched(11));
        // Fourteen points, the two leftmost columns of a 7x11 board: too narrow.
        let tall = Pattern::new(7, 11, 0.02).unwrap();
        let t: Vec<Vec<[f64; 2]>> = (0..3).map(|k| shot(&tall, [4.0 * k as f64, 1.0 * k as f64])).collect();
        let windows = [window(0, 0, &t[0]), window(1, 33_000, &t[1][..14]), window(2, 66_000, &t[2])];
        let found = [Ok(grid(&t[0])), Err(Miss::TooFewCentres), Ok(grid(&t[2]))];
        let narrow = follow_explained(&windows, &found, &tall, &TrackOptions::default());
        assert_eq!(narrow[1].clone().unwrap_err(), Unfollowed::TooNarrow);
        // Twelve points, the three leftmost columns, but half a spacing off.
        let off: Vec<[f64; 2]> = shots[1][..12].iter().map(|p| [p[0] + 6.0, p[1]]).collect();
        assert!(matches!(follow_middle(&off).unwrap_err(), Unfollowed::TooFewMatched(_)));
        // The same twelve where they belong: followed.
        assert_eq!(follow_middle(&shots[1][..12]).expect("followed").grid.points.len(), 12);
    }

    /// A run of 24 windows (0.8 s), each holding a part of the board (columns 0-3 or 1-4)
    /// while the board moves along a curve, is followed in from both ends: every point right.
    /// (A part wholly unseen by the windows around is not: no anchor vouches for it.)
    #[test]
    fn a_long_run_of_partial_windows_is_followed() {
        let pattern = Pattern::new(4, 11, 0.02).unwrap();
        let n = 28;
        let shots: Vec<Vec<[f64; 2]>> = (0..n)
            .map(|k| {
                let a = k as f64 * 0.12;
                shot(&pattern, [20.0 * a.sin(), 15.0 * (1.0 - a.cos())])
            })
            .collect();
        let windows: Vec<WindowRecord> = shots
            .iter()
            .enumerate()
            .map(|(k, s)| {
                // Columns 0-3 of the board, or 1-4: each part overlaps the one before.
                let c0 = 4 * (k % 2);
                window(k as u32, 33_000 * k as u64, &s[c0..c0 + 16])
            })
            .collect();
        let found: Vec<Result<GridDetection, Miss>> = (0..n)
            .map(|k| if (2..n - 2).contains(&k) { Err(Miss::TooFewPoints) } else { Ok(grid(&shots[k])) })
            .collect();
        let out = follow(&windows, &found, &pattern, &TrackOptions::default());
        for k in 2..n - 2 {
            let g = out[k].as_ref().unwrap_or_else(|| panic!("window {k} not followed"));
            assert_eq!(g.points.len(), 16, "window {k}");
            for p in &g.points {
                let want = shots[k][p.index];
                assert!((p.image[0] - want[0]).hypot(p.image[1] - want[1]) < 1e-3, "window {k}: point {}", p.index);
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Whatever the smooth motion, the losses (scattered, or a whole side of the board)
        /// and the clutter (of the grid's own size): every point followed is labelled with
        /// the board point whose true place is nearest.
        #[test]
        fn never_a_wrong_label(
            velocity in (-6.0f64..6.0, -6.0f64..6.0),
            accel in (-0.4f64..0.4, -0.4f64..0.4),
            spin_deg in -1.5f64..1.5,
            growth in -0.015f64..0.015,
            losses in proptest::collection::vec((0.0f64..0.85, 0.0f64..6.3, proptest::bool::ANY), 20),
            clutter in proptest::collection::vec((0.0f64..346.0, 0.0f64..260.0), 0..30),
            seed in 0u64..1000,
        ) {
            let pattern = Pattern::new(4, 11, 0.02).unwrap();
            let b = board(&pattern);
            let n = losses.len();
            let truth: Vec<Vec<[f64; 2]>> = (0..n)
                .map(|k| {
                    let t = k as f64;
                    let (a, sc) = ((spin_deg * t).to_radians(), 500.0 * (1.0 + growth * t));
                    let shift = [
                        40.0 + velocity.0 * t + 0.5 * accel.0 * t * t,
                        40.0 + velocity.1 * t + 0.5 * accel.1 * t * t,
                    ];
                    b.iter()
                        .map(|o| {
                            let (x, y) = (sc * o[0], sc * o[1]);
                            [shift[0] + x * a.cos() - y * a.sin(), shift[1] + x * a.sin() + y * a.cos()]
                        })
                        .collect()
                })
                .collect();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut uniform = move || rng.random::<f64>();
            let windows: Vec<WindowRecord> = truth
                .iter()
                .zip(&losses)
                .enumerate()
                .map(|(k, (pts, &(lost, angle, side)))| {
                    // Lose a random share of the circles, or every circle on one side of a
                    // line through the board's middle.
                    let mid = pts.iter().fold([0.0, 0.0], |m, p| [m[0] + p[0] / 44.0, m[1] + p[1] / 44.0]);
                    let mut kept: Vec<[f64; 2]> = Vec::new();
                    for p in pts {
                        let gone = if side {
                            (p[0] - mid[0]) * angle.cos() + (p[1] - mid[1]) * angle.sin() > 0.0
                        } else {
                            uniform() < lost
                        };
                        if !gone {
                            kept.push([p[0] + 0.4 * (uniform() - 0.5), p[1] + 0.4 * (uniform() - 0.5)]);
                        }
                    }
                    kept.extend(clutter.iter().map(|&(u, v)| [u + 3.0 * k as f64, v]));
                    window(k as u32, 33_000 * k as u64, &kept)
                })
                .collect();
            // The finder labelled the first two and the last two windows whole.
            let found: Vec<Result<GridDetection, Miss>> = (0..n)
                .map(|k| if k < 2 || k >= n - 2 { Ok(grid(&truth[k])) } else { Err(Miss::TooFewPoints) })
                .collect();
            for (k, g) in follow(&windows, &found, &pattern, &TrackOptions::default()).iter().enumerate() {
                let Some(g) = g else { continue };
                for p in &g.points {
                    let nearest = (0..44)
                        .min_by(|&x, &y| {
                            let d = |i: usize| (truth[k][i][0] - p.image[0]).hypot(truth[k][i][1] - p.image[1]);
                            d(x).total_cmp(&d(y))
                        })
                        .unwrap();
                    proptest::prop_assert_eq!(nearest, p.index, "window {}: point at {:?}", k, p.image);
                }
            }
        }
    }
}
