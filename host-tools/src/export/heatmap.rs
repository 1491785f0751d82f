//! The report's map of the projection σ over the sensor ([`ProjectionSigma`]), with the
//! region the boards covered outlined: where the σ is the model's own and where it is what
//! the polynomial makes of points elsewhere.

use super::report::{Area, DrawResult, DARK, FAMILY};
use crate::calib::{Calibration, ProjectionSigma, View, PROJECTION_SIGMA_STEP_PX};
use plotters::prelude::*;

/// Viridis at five stops (matplotlib's, from dark blue to yellow): ordered in lightness, so
/// that a grey print and a colour-blind reader still read larger as lighter.
const STOPS: [(u8, u8, u8); 5] = [(68, 1, 84), (59, 82, 139), (33, 145, 140), (94, 201, 98), (253, 231, 37)];

/// The colour of `t` in [0, 1] (clamped) on [`STOPS`].
fn colour(t: f64) -> RGBColor {
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 1.0 };
    let x = t * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    let mix = |a: u8, b: u8| (f64::from(a) + f * (f64::from(b) - f64::from(a))).round() as u8;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The σ the colour scale tops out at, px: three times the covered region's 95th
/// percentile, so that the covered region's own variation shows and the extrapolated
/// corners saturate; the sensor's if nothing is covered. At least a thousandth of a pixel.
fn scale_px(s: &ProjectionSigma) -> f64 {
    let f = s.within_points.unwrap_or(s.sensor);
    let top = if f.p95_px.is_finite() { 3.0 * f.p95_px } else { 1.0 };
    top.max(1e-3)
}

/// Draws the map of `cal`'s projection σ (views: those given to the solve) into `area`;
/// a note in its place when there is none.
pub(super) fn sigma_panel(area: &Area<'_>, cal: &Calibration, views: &[View]) -> DrawResult {
    let Some(s) = ProjectionSigma::of(cal, views, PROJECTION_SIGMA_STEP_PX) else {
        area.titled("Projection σ: none (an empty sensor)", (FAMILY, 20))?;
        return Ok(());
    };
    let top = scale_px(&s);
    let figures = match s.within_points {
        Some(f) => format!("p95 {:.3} within the outline", f.p95_px),
        None => "no board seen".into(),
    };
    let caption = format!("Projection σ (px, 0–{top:.3}): {figures}");
    let titled = area.titled(&caption, (FAMILY, 17))?;
    let [w, h] = cal.image_size.map(|x| f64::from(x.max(1)));
    let mut chart = super::report::sensor_chart(&titled, cal.image_size)?;
    // Each node's cell: the step around it, cut at the sensor's edge.
    let step = f64::from(s.step_px);
    let cell = |i: usize, j: usize| {
        let (u, v) = (i as f64 * step, j as f64 * step);
        let x = ((u - 0.5 * step).max(-0.5), (u + 0.5 * step).min(w - 0.5));
        let y = ((v - 0.5 * step).max(-0.5), (v + 0.5 * step).min(h - 0.5));
        (x, y)
    };
    chart.draw_series(s.values.iter().enumerate().flat_map(|(j, row)| {
        row.iter().enumerate().map(move |(i, &v)| {
            let (x, y) = cell(i, j);
            Rectangle::new([(x.0, y.0), (x.1, y.1)], colour(v / top).filled())
        })
    }))?;
    // The covered region's outline: each side of a covered cell that no covered cell shares.
    let covered = |i: isize, j: isize| {
        i >= 0 && j >= 0 && s.covered.get(j as usize).and_then(|r| r.get(i as usize)).copied().unwrap_or(false)
    };
    let mut sides = Vec::new();
    for j in 0..s.rows {
        for i in 0..s.columns {
            let (ii, jj) = (i as isize, j as isize);
            if !covered(ii, jj) {
                continue;
            }
            let (x, y) = cell(i, j);
            for (di, dj, a, b) in [
                (-1, 0, (x.0, y.0), (x.0, y.1)),
                (1, 0, (x.1, y.0), (x.1, y.1)),
                (0, -1, (x.0, y.0), (x.1, y.0)),
                (0, 1, (x.0, y.1), (x.1, y.1)),
            ] {
                if !covered(ii + di, jj + dj) {
                    sides.push(PathElement::new(vec![a, b], WHITE.stroke_width(2)));
                }
            }
        }
    }
    chart.draw_series(sides)?;
    chart.draw_series(std::iter::once(Rectangle::new([(-0.5, -0.5), (w - 0.5, h - 0.5)], DARK.stroke_width(2))))?;
    Ok(())
}

#[cfg(test)]
mod test {
    use super::super::testdata::*;
    use super::*;

    #[test]
    fn the_report_draws_the_sigma_map_in_its_panel() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let png = super::super::render_report(
            std::path::Path::new("r.png"),
            &cal,
            &views,
            &origins,
            &timeline,
            &super::super::Notes::default(),
        )
        .expect("a report");
        let mut reader = png::Decoder::new(&png[..]).read_info().expect("a PNG");
        let mut rgb = vec![0; reader.output_buffer_size()];
        reader.next_frame(&mut rgb).expect("a frame");
        let (w, h) = super::super::REPORT_SIZE;
        // Its panel: the second row's third, above the strip of windows.
        let count = |c: RGBColor| {
            (2 * h / 5..4 * h / 5)
                .flat_map(|y| (2 * w / 3..w).map(move |x| 3 * (y * w + x) as usize))
                .filter(|&i| rgb[i..i + 3] == [c.0, c.1, c.2])
                .count()
        };
        // The covered middle's colour fills cells (8 px of sensor: several report pixels
        // each), and the outline is drawn.
        let s = ProjectionSigma::of(&cal, &views, PROJECTION_SIGMA_STEP_PX).expect("σ");
        let (j, i) = (s.rows / 2, s.columns / 2);
        assert!(s.covered[j][i]);
        let middle = colour(s.values[j][i] / scale_px(&s));
        assert!(count(middle) >= 20, "{middle:?}: {}", count(middle));
        assert!(count(WHITE) > 100);
    }

    #[test]
    fn the_scale_runs_dark_to_light_and_saturates() {
        let lightness = |c: RGBColor| u32::from(c.0) * 299 + u32::from(c.1) * 587 + u32::from(c.2) * 114;
        let steps: Vec<u32> = (0..=20).map(|k| lightness(colour(k as f64 / 20.0))).collect();
        assert!(steps.windows(2).all(|p| p[0] < p[1]), "{steps:?}");
        assert_eq!(colour(-1.0), colour(0.0));
        assert_eq!(colour(7.0), colour(1.0));
        assert_eq!(colour(f64::INFINITY), colour(1.0));
        assert_eq!(colour(f64::NAN), colour(1.0));
    }
}
