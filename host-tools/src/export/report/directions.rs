//! The residuals' directions over the sensor: per coverage cell, the mean residual of the
//! points detected there, as an arrow. Noise averages out in a cell; what a wrong model
//! leaves does not, and shows as a pattern (arrows pointing out or in: radial distortion
//! not modelled; turning round the centre: a tilt or tangential term), the check mrcal's
//! and Kalibr's residual maps give.

use super::{Area, DrawResult, BLUE, CAPTION, CELLS, DARK, GREY};
use crate::calib::{Calibration, View};
use plotters::prelude::*;

/// The fewest points whose mean a cell draws: with fewer, one noisy point is its arrow.
pub(super) const MIN_CELL_POINTS: usize = 3;

/// The longest arrow, as a fraction of a cell's width, that the scale allows: arrows stay
/// inside their cell.
const LONGEST: f64 = 0.9;

/// One cell's points: how many, and their mean residual (projected − detected, px).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct CellMean {
    /// Points detected in the cell (finite residuals only).
    pub points: usize,
    /// Their mean residual, px; `[0, 0]` without points.
    pub mean: [f64; 2],
}

/// The mean residual in each of the sensor's [`CELLS`] (`[row][column]`), a point counted in
/// the cell where it was detected. `res` are [`crate::views::view_residuals`] of `views`
/// under `cal` (in the order of `cal.views`).
pub(super) fn cell_means(cal: &Calibration, views: &[View], res: &[Vec<[f64; 2]>]) -> Vec<Vec<CellMean>> {
    let mut sums = vec![vec![(0usize, [0.0f64; 2]); CELLS.0]; CELLS.1];
    for (v, r) in cal.views.iter().zip(res) {
        let Some(view) = views.get(v.view) else { continue };
        for (p, d) in view.image.iter().zip(r) {
            if !(d[0].is_finite() && d[1].is_finite()) {
                continue;
            }
            if let Some((c, row)) = super::cell(*p, cal.image_size) {
                let s = &mut sums[row][c];
                s.0 += 1;
                s.1[0] += d[0];
                s.1[1] += d[1];
            }
        }
    }
    sums.into_iter()
        .map(|row| {
            row.into_iter()
                .map(|(n, s)| match n {
                    0 => CellMean::default(),
                    n => CellMean { points: n, mean: [s[0] / n as f64, s[1] / n as f64] },
                })
                .collect()
        })
        .collect()
}

/// The arrows' scale: the largest of 1, 2, 5 × 10^k that keeps the longest drawn arrow
/// (`largest` px before scaling) within [`LONGEST`] of a cell `cell_px` wide, so that the
/// caption states a round factor.
pub(super) fn arrow_scale(largest: f64, cell_px: f64) -> f64 {
    if !(largest.is_finite() && largest > 0.0 && cell_px > 0.0) {
        return 1.0;
    }
    let most = LONGEST * cell_px / largest;
    let decade = 10f64.powf(most.log10().floor());
    [5.0, 2.0, 1.0].iter().map(|m| m * decade).find(|&s| s <= most).unwrap_or(decade)
}

/// The sensor with its cells, each cell that holds [`MIN_CELL_POINTS`] or more drawn as an
/// arrow from its centre along its mean residual, scaled (the factor in the caption).
pub(super) fn directions_panel(
    area: &Area<'_>,
    cal: &Calibration,
    views: &[View],
    res: &[Vec<[f64; 2]>],
) -> DrawResult {
    let [w, h] = cal.image_size.map(|x| f64::from(x.max(1)));
    let means = cell_means(cal, views, res);
    let (cw, ch) = (w / CELLS.0 as f64, h / CELLS.1 as f64);
    let drawn = || means.iter().flatten().filter(|m| m.points >= MIN_CELL_POINTS);
    let largest = drawn().map(|m| m.mean[0].hypot(m.mean[1])).fold(0.0, f64::max);
    let scale = arrow_scale(largest, cw.min(ch));
    let caption = format!("Mean residual per cell, ×{scale} (largest {largest:.3} px)");
    let titled = area.titled(&caption, CAPTION)?;
    let mut chart = super::sensor_chart(&titled, cal.image_size)?;
    let mut lines = Vec::new();
    for c in 1..CELLS.0 {
        let x = c as f64 * cw - 0.5;
        lines.push(PathElement::new(vec![(x, -0.5), (x, h - 0.5)], GREY.mix(0.4).stroke_width(1)));
    }
    for r in 1..CELLS.1 {
        let y = r as f64 * ch - 0.5;
        lines.push(PathElement::new(vec![(-0.5, y), (w - 0.5, y)], GREY.mix(0.4).stroke_width(1)));
    }
    chart.draw_series(lines)?;
    let mut arrows = Vec::new();
    let mut dots = Vec::new();
    for (r, row) in means.iter().enumerate() {
        for (c, m) in row.iter().enumerate().filter(|(_, m)| m.points >= MIN_CELL_POINTS) {
            let from = ((c as f64 + 0.5) * cw - 0.5, (r as f64 + 0.5) * ch - 0.5);
            let to = (from.0 + scale * m.mean[0], from.1 + scale * m.mean[1]);
            dots.push(Circle::new(from, 2, BLUE.filled()));
            let len = (to.0 - from.0).hypot(to.1 - from.1);
            if len < 1e-9 {
                continue;
            }
            arrows.push(PathElement::new(vec![from, to], BLUE.stroke_width(2)));
            // The head: two strokes back from the tip, 25° off the shaft.
            let head = (0.35 * len).min(0.25 * cw);
            let back = ((from.1 - to.1).atan2(from.0 - to.0), 25f64.to_radians());
            for a in [back.0 - back.1, back.0 + back.1] {
                arrows.push(PathElement::new(
                    vec![to, (to.0 + head * a.cos(), to.1 + head * a.sin())],
                    BLUE.stroke_width(2),
                ));
            }
        }
    }
    chart.draw_series(dots)?;
    chart.draw_series(arrows)?;
    chart.draw_series(std::iter::once(Rectangle::new([(-0.5, -0.5), (w - 0.5, h - 0.5)], DARK.stroke_width(2))))?;
    Ok(())
}

#[cfg(test)]
mod test {
    use super::super::super::testdata::*;
    use super::*;
    use crate::views::view_residuals;

    /// Moving every detected point by a known field moves each cell's mean residual by
    /// minus that field's mean over the cell's points (residual = projected − detected),
    /// with the calibration held: the means are computed over the right points.
    #[test]
    fn cell_means_follow_an_added_distortion() {
        let (views, cal, _, _) = setup(&TRUTH, false);
        let before = cell_means(&cal, &views, &view_residuals(&views, &cal).unwrap());
        // A radial pull plus a swirl about the sensor's centre, up to ~1.5 px at the corners.
        let field = |p: [f64; 2]| {
            let (x, y) = (p[0] - 173.0, p[1] - 130.0);
            [0.005 * x - 0.003 * y, 0.005 * y + 0.003 * x]
        };
        let mut moved = views.clone();
        let mut want = vec![vec![(0usize, [0.0f64; 2]); CELLS.0]; CELLS.1];
        // Cells a point moved into or out of hold other points after: left out.
        let mut crossed = vec![vec![false; CELLS.0]; CELLS.1];
        let at = |p: [f64; 2]| crate::export::report::cell(p, cal.image_size).expect("on the sensor");
        for v in &cal.views {
            for p in &mut moved[v.view].image {
                let f = field(*p);
                let ((c, r), q) = (at(*p), [p[0] + f[0], p[1] + f[1]]);
                want[r][c].0 += 1;
                want[r][c].1[0] += f[0];
                want[r][c].1[1] += f[1];
                if at(q) != (c, r) {
                    crossed[r][c] = true;
                    crossed[at(q).1][at(q).0] = true;
                }
                *p = q;
            }
        }
        let after = cell_means(&cal, &moved, &view_residuals(&moved, &cal).unwrap());
        let mut cells = 0;
        for r in 0..CELLS.1 {
            for c in 0..CELLS.0 {
                let (n, s) = want[r][c];
                if n == 0 || crossed[r][c] {
                    continue;
                }
                assert_eq!((after[r][c].points, before[r][c].points), (n, n), "cell ({c}, {r})");
                cells += 1;
                for (k, sum) in s.iter().enumerate() {
                    let shift = after[r][c].mean[k] - before[r][c].mean[k];
                    assert!((shift + sum / n as f64).abs() < 1e-9, "cell ({c}, {r}): {shift} vs {}", -sum / n as f64);
                }
            }
        }
        assert!(cells >= 40, "only {cells} cells compared");
    }

    /// The mean of a cell is the mean of its own points alone: two points in one cell and
    /// one in another.
    #[test]
    fn cell_means_average_within_a_cell() {
        let (views, mut cal, _, _) = setup(&TRUTH, false);
        cal.views.truncate(1);
        let mut one = views[cal.views[0].view].clone();
        one.image = vec![[1.0, 1.0], [2.0, 2.0], [340.0, 250.0]];
        one.object.truncate(3);
        let res = vec![vec![[0.2, -0.4], [0.4, 0.0], [f64::NAN, 1.0]]];
        let mut all = views.clone();
        all[cal.views[0].view] = one;
        let m = cell_means(&cal, &all, &res);
        assert_eq!(m[0][0], CellMean { points: 2, mean: [0.30000000000000004, -0.2] });
        assert_eq!(m[CELLS.1 - 1][CELLS.0 - 1].points, 0, "a NaN residual is left out");
        assert_eq!(m.iter().flatten().map(|c| c.points).sum::<usize>(), 2);
    }

    #[test]
    fn arrow_scale_is_round_and_keeps_arrows_in_their_cell() {
        // 0.1 px in a 28.8 px cell: up to 259×, so 200×.
        assert_eq!(arrow_scale(0.1, 28.8), 200.0);
        assert_eq!(arrow_scale(2.0, 28.8), 10.0);
        assert_eq!(arrow_scale(0.0, 28.8), 1.0);
        for largest in [0.003, 0.07, 0.4, 3.0, 40.0] {
            let s = arrow_scale(largest, 28.8);
            assert!(s * largest <= LONGEST * 28.8 + 1e-9 && s * largest > 0.2 * LONGEST * 28.8, "{largest}: {s}");
        }
    }
}
