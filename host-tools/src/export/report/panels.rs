//! The panels of the first report: the error per view, the residuals, the coverage and the
//! detections over time.

use super::{
    cell, equal_aspect_margins, span, whole, Area, DrawResult, BLUE, CAPTION, CELLS, DARK, DESCS, GREEN, GREY, LABELS,
    ORANGE, RED,
};
use crate::calib::{Calibration, View};
use crate::views::{ViewOrigin, WindowSample};
use plotters::prelude::*;

/// Each used view's RMS at its window's time ([`ViewOrigin::t_s`]), orange where far above the
/// median; views set aside (no pose, so no RMS) as red marks on the axis at theirs; the median
/// as a line. Without origins, at the view's input index instead.
pub(super) fn per_view_panel(area: &Area<'_>, cal: &Calibration, origins: &[ViewOrigin]) -> DrawResult {
    let timed = !origins.is_empty();
    let x_of = |view: usize| match timed {
        true => origins.get(view).map(|o| o.t_s).filter(|t| t.is_finite()),
        false => Some(view as f64),
    };
    let xs = cal.views.iter().map(|v| v.view).chain(cal.rejected.iter().map(|r| r.view)).filter_map(x_of);
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
    let (x0, x1) = if lo.is_finite() { span(lo, hi) } else { (0.0, 1.0) };
    let pad = (x1 - x0) * 0.02;
    let (x0, x1) = (x0 - pad, x1 + pad);
    let top = cal.views.iter().map(|v| v.rms_px).filter(|x| x.is_finite()).fold(0.0, f64::max);
    let (y0, y1) = span(0.0, (top.max(cal.median_view_px) * 1.15).max(1e-3));
    let mut chart = ChartBuilder::on(area)
        .caption(format!("Error per view (median {:.3} px; red: set aside)", cal.median_view_px), CAPTION)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    let mut mesh = chart.configure_mesh();
    mesh.label_style(LABELS).axis_desc_style(DESCS).y_desc("RMS (px)");
    match timed {
        true => mesh.x_desc("time (s)"),
        false => mesh.x_label_formatter(&whole).x_desc("view"),
    };
    mesh.draw()?;
    // Views far above the median stand out in orange.
    let high = 2.0 * cal.median_view_px;
    chart.draw_series(cal.views.iter().filter(|v| v.rms_px.is_finite()).filter_map(|v| {
        let colour = if v.rms_px > high { ORANGE } else { BLUE };
        x_of(v.view).map(|x| Circle::new((x, v.rms_px.min(y1)), 3, colour.filled()))
    }))?;
    let mark = (y1 - y0) * 0.03;
    chart.draw_series(
        cal.rejected
            .iter()
            .filter_map(|r| x_of(r.view))
            .map(|x| PathElement::new(vec![(x, y0), (x, y0 + mark)], RED.stroke_width(2))),
    )?;
    if cal.median_view_px.is_finite() {
        let m = cal.median_view_px;
        chart.draw_series(std::iter::once(PathElement::new(vec![(x0, m), (x1, m)], RED.stroke_width(2))))?;
    }
    Ok(())
}

/// Every point's residual with the overall RMS as a circle; the axes span most points and
/// say how many fall outside.
pub(super) fn scatter_panel(area: &Area<'_>, cal: &Calibration, res: &[Vec<[f64; 2]>]) -> DrawResult {
    let mut all: Vec<[f64; 2]> =
        res.iter().flatten().copied().filter(|d| d[0].is_finite() && d[1].is_finite()).collect();
    // The 99.5th percentile of |dx|, |dy| sets the scale, so that a few wild points do
    // not shrink the cloud to a dot.
    let mut mags: Vec<f64> = all.iter().flat_map(|d| [d[0].abs(), d[1].abs()]).collect();
    mags.sort_by(f64::total_cmp);
    let p = mags.get((mags.len() as f64 * 0.995) as usize).or(mags.last()).copied().unwrap_or(0.0);
    let r = (p * 1.1).max(cal.rms_px * 1.5).max(0.05);
    let r = if r.is_finite() { r } else { 1.0 };
    let outside = all.iter().filter(|d| d[0].abs() > r || d[1].abs() > r).count();
    all.retain(|d| d[0].abs() <= r && d[1].abs() <= r);
    let caption = if outside > 0 {
        format!("Residuals, projected − detected (circle: RMS; {outside} off the axes)")
    } else {
        "Residuals, projected − detected (circle: RMS)".to_string()
    };
    let titled = area.titled(&caption, CAPTION)?;
    let (mx, my) = equal_aspect_margins(&titled, 65, 45, 1.0);
    let mut chart = ChartBuilder::on(&titled)
        .margin(12)
        .margin_left(12 + mx)
        .margin_right(12 + mx)
        .margin_top(12 + my)
        .margin_bottom(12 + my)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(-r..r, -r..r)?;
    chart.configure_mesh().label_style(LABELS).axis_desc_style(DESCS).x_desc("dx (px)").y_desc("dy (px)").draw()?;
    let axis = GREY.stroke_width(1);
    chart.draw_series([
        PathElement::new(vec![(-r, 0.0), (r, 0.0)], axis),
        PathElement::new(vec![(0.0, -r), (0.0, r)], axis),
    ])?;
    // Faint dots, so that where they pile up shows.
    let style = BLUE.mix(0.35).filled();
    chart.draw_series(all.iter().map(|d| Circle::new((d[0], d[1]), 2, style)))?;
    let rms = cal.rms_px;
    if rms.is_finite() && rms > 0.0 && rms <= r {
        let circle: Vec<(f64, f64)> = (0..=120)
            .map(|i| {
                let a = i as f64 / 120.0 * std::f64::consts::TAU;
                (rms * a.cos(), rms * a.sin())
            })
            .collect();
        chart.draw_series(std::iter::once(PathElement::new(circle, RED.stroke_width(2))))?;
    }
    Ok(())
}

/// The sensor (rows downwards, as in the image) with every detected point: used views' in
/// blue, views set aside in red; cells shaded green by how many used points they hold.
pub(super) fn coverage_panel(area: &Area<'_>, cal: &Calibration, views: &[View]) -> DrawResult {
    let [w, h] = cal.image_size.map(|x| f64::from(x.max(1)));
    let mut used = vec![false; views.len()];
    for v in &cal.views {
        if let Some(u) = used.get_mut(v.view) {
            *u = true;
        }
    }
    let mut counts = [[0usize; CELLS.0]; CELLS.1];
    for (v, _) in views.iter().enumerate().filter(|&(i, _)| used[i]) {
        for &p in &views[v].image {
            if let Some((c, r)) = cell(p, cal.image_size) {
                counts[r][c] += 1;
            }
        }
    }
    let covered = counts.iter().flatten().filter(|&&n| n > 0).count();
    let most = counts.iter().flatten().copied().max().unwrap_or(0).max(1);
    let caption = format!(
        "Coverage: {covered} of {} cells ({}×{}) hold points ({:.0} %)",
        CELLS.0 * CELLS.1,
        CELLS.0,
        CELLS.1,
        100.0 * covered as f64 / (CELLS.0 * CELLS.1) as f64
    );
    let titled = area.titled(&caption, CAPTION)?;
    let mut chart = super::sensor_chart(&titled, cal.image_size)?;
    let (cw, ch) = (w / CELLS.0 as f64, h / CELLS.1 as f64);
    let mut cells = Vec::new();
    for (r, row) in counts.iter().enumerate() {
        for (c, &n) in row.iter().enumerate() {
            let x0 = c as f64 * cw - 0.5;
            let y0 = r as f64 * ch - 0.5;
            // Empty cells stay white; a single point already shows as a tint.
            let shade = if n == 0 { 0.0 } else { 0.15 + 0.45 * n as f64 / most as f64 };
            cells.push(Rectangle::new([(x0, y0), (x0 + cw, y0 + ch)], GREEN.mix(shade).filled()));
            cells.push(Rectangle::new([(x0, y0), (x0 + cw, y0 + ch)], GREY.mix(0.5).stroke_width(1)));
        }
    }
    chart.draw_series(cells)?;
    for (i, view) in views.iter().enumerate() {
        let colour = if used[i] { BLUE } else { RED };
        chart.draw_series(
            view.image
                .iter()
                .filter(|p| p[0].is_finite() && p[1].is_finite())
                .map(|p| Circle::new((p[0], p[1]), 2, colour.filled())),
        )?;
    }
    chart.draw_series(std::iter::once(Rectangle::new([(-0.5, -0.5), (w - 0.5, h - 0.5)], DARK.stroke_width(2))))?;
    Ok(())
}

/// Centres per window over time: green where the grid was found, grey where not; the views
/// the calibration used are ticked along the top.
pub(super) fn timeline_panel(
    area: &Area<'_>,
    cal: &Calibration,
    origins: &[ViewOrigin],
    timeline: &[WindowSample],
) -> DrawResult {
    let ok: Vec<&WindowSample> = timeline.iter().filter(|s| s.t_s.is_finite()).collect();
    let found = ok.iter().filter(|s| s.grid_found).count();
    let used_t: Vec<f64> =
        cal.views.iter().filter_map(|v| origins.get(v.view)).map(|o| o.t_s).filter(|t| t.is_finite()).collect();
    let ts = ok.iter().map(|s| s.t_s).chain(used_t.iter().copied());
    let (lo, hi) = ts.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
    let (t0, t1) = if lo.is_finite() { span(lo, hi) } else { (0.0, 1.0) };
    let pad = (t1 - t0) * 0.02;
    let top = ok.iter().map(|s| s.centres).max().unwrap_or(0).max(1) as f64 * 1.15;
    let caption = format!("Grid found in {found} of {} windows (ticks: views used)", ok.len());
    let mut chart = ChartBuilder::on(area)
        .caption(caption, CAPTION)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(t0 - pad..t1 + pad, 0.0..top)?;
    chart
        .configure_mesh()
        .label_style(LABELS)
        .axis_desc_style(DESCS)
        .y_label_formatter(&whole)
        .x_desc("time (s)")
        .y_desc("circle centres in window")
        .draw()?;
    chart.draw_series(
        ok.iter().filter(|s| !s.grid_found).map(|s| Circle::new((s.t_s, s.centres as f64), 2, GREY.filled())),
    )?;
    chart.draw_series(
        ok.iter().filter(|s| s.grid_found).map(|s| Circle::new((s.t_s, s.centres as f64), 3, GREEN.filled())),
    )?;
    let tick = top * 0.05;
    chart
        .draw_series(used_t.iter().map(|&t| PathElement::new(vec![(t, top), (t, top - tick)], BLUE.stroke_width(2))))?;
    Ok(())
}
