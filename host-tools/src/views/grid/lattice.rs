//! Step 2, lattice growth: from a seed with the four neighbours of a lattice point, cell by
//! cell, each predicted from the cells placed around it.

use super::{dist, Pt, MAX_PATTERN_SIDE};
use std::collections::HashMap;

/// Lattice coordinates: steps along the two diagonal directions of the board.
pub(super) type Cell = (i32, i32);

/// Seeds for the lattice: centres whose four nearest candidate neighbours form two
/// opposite pairs of similar length, best first; with each, the two basis steps.
pub(super) fn seeds(pts: &[Pt], candidates: &[usize]) -> Vec<(usize, [f64; 2], [f64; 2])> {
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
pub(super) fn grow(pts: &[Pt], candidates: &[usize], s: usize, a: [f64; 2], b: [f64; 2]) -> HashMap<Cell, usize> {
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
