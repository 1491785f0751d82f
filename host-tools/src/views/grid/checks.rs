//! The checks a labelled grid must pass: every lattice line smooth, and a homography that
//! fits. A wrong ordering is worse than a miss.

use super::{dist, lattice::Cell, GridPoint, Miss, Pattern, Pt};
use std::collections::HashMap;

/// Every lattice line bends smoothly: the second difference of three consecutive points is
/// small against their spacing. A point labelled one step off breaks this. Perspective is
/// taken out first: the differences are of the points' offsets from a homography of the
/// whole lattice, so a tilted board's shrinking spacings (a second difference of a sixth of
/// a step on a close, wide view) pass while distortion's bend and a wrong label still show.
pub(super) fn check_smooth(pts: &[Pt], lattice: &HashMap<Cell, usize>) -> Result<(), Miss> {
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
