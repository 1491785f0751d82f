//! Step 1, the consistency filter: the centres that share the grid's scale.

use super::{dist, Pt};

/// Largest ratio of radii between a centre and the neighbour that gives its spacing:
/// neighbouring circles of a board tilted by 60° differ by well under this.
const LIKE_SIZE: f64 = 1.5;

/// Indices of the centres whose radius and nearest-neighbour distance agree with the
/// densest mode of both: the grid's scale.
pub(super) fn consistent(pts: &[Pt]) -> Vec<usize> {
    // Each centre's nearest neighbour that could be its neighbour on a board: of a like size
    // and not overlapping it (the board's circles are apart by several radii). A blob beside
    // or over a circle (a noise cluster, a fragment) is not the grid's spacing; counting it
    // would set the circle aside, cut the lattice there and let clutter beyond its edge
    // decide the labelling (the property test's roll 154° case).
    let like = |a: usize, b: usize| {
        (pts[a].r / pts[b].r).ln().abs() < LIKE_SIZE.ln() && dist(pts[a].p, pts[b].p) > pts[a].r + pts[b].r
    };
    let nn: Vec<f64> = (0..pts.len())
        .map(|a| {
            (0..pts.len())
                .filter(|&b| b != a && like(a, b))
                .map(|b| dist(pts[a].p, pts[b].p))
                .fold(f64::INFINITY, f64::min)
        })
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
    // Never empty: the mode is its own member (features are finite, so no NaN is left out).
    let median = |mut v: Vec<f64>| crate::stats::median(&mut v).unwrap_or(f64::NAN);
    let centre = (
        median(members.iter().map(|&k| feature(k).0).collect()),
        median(members.iter().map(|&k| feature(k).1).collect()),
    );
    (0..pts.len()).filter(|&k| near(centre, feature(k), 0.6)).collect()
}
