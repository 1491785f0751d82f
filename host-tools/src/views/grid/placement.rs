//! Step 3, placement: the one way to lay the lattice on the pattern with the board's front to
//! the camera, and the 180° rule where the pattern has two.

use super::{lattice::Cell, Miss, Pattern, Pt};
use std::collections::HashMap;

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
pub(super) fn place(
    pts: &[Pt],
    lattice: &HashMap<Cell, usize>,
    pattern: &Pattern,
) -> Result<Vec<(usize, usize)>, Miss> {
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
