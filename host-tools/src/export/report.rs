//! The PNG report: four panels a person reads at a glance to judge a calibration.
//!
//! - reprojection error per view (RMS, px), with the median;
//! - every point's residual (dx, dy), with the overall RMS as a circle;
//! - where on the sensor the points were detected, with an 8×6 cell occupancy, and beside
//!   it the projection σ over the sensor with the boards' outlines ([`super::heatmap`]);
//! - circle centres per detection window over time, with the windows whose grid was found.

use super::{ExportError, Result};
use crate::calib::{Calibration, View};
use crate::views::select::COVERAGE_CELLS;
use crate::views::{view_residuals, ViewOrigin, WindowSample};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::Path;
use std::sync::OnceLock;

/// Width and height of the report, px.
pub const REPORT_SIZE: (u32, u32) = (1600, 1200);

/// DejaVu Sans, reduced to the characters drawn here (see assets/DejaVuSans-LICENSE.txt):
/// built in so that the report looks the same on a machine without fonts.
const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-subset.ttf");
/// The family plotters asks for when a style names none (axis labels), so that one
/// registration serves every text.
pub(super) const FAMILY: &str = "sans-serif";
/// Sensor cells counted for coverage: columns × rows.
const CELLS: (usize, usize) = (COVERAGE_CELLS[0], COVERAGE_CELLS[1]);

const BLUE: RGBColor = RGBColor(31, 119, 180);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const GREEN: RGBColor = RGBColor(44, 160, 44);
const RED: RGBColor = RGBColor(214, 39, 40);
const GREY: RGBColor = RGBColor(150, 150, 150);
pub(super) const DARK: RGBColor = RGBColor(40, 40, 40);
/// A good verdict's colour.
const GREEN_DARK: RGBColor = RGBColor(20, 120, 40);
/// A usable verdict's colour.
const AMBER: RGBColor = RGBColor(190, 110, 0);

/// Tick labels and axis names.
pub(super) const LABELS: (&str, u32) = (FAMILY, 15);
pub(super) const DESCS: (&str, u32) = (FAMILY, 16);

pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Tick label of a count or an index: whole numbers only (ticks between them stay bare).
pub(super) fn whole(v: &f64) -> String {
    if (v - v.round()).abs() < 1e-9 {
        format!("{v:.0}")
    } else {
        String::new()
    }
}

fn font_ready() -> std::result::Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err("the report's built-in font does not load".into())
    }
}

/// Draws the report of `cal` into a PNG at `path` ([`REPORT_SIZE`]). `views` are the views
/// given to the solver, `origins` where each came from (used to mark the views on the
/// timeline; may be empty), `timeline` every detection window (may be empty); `notes` what
/// the run says of the result (a failure stamps the report). Written to a temporary file
/// renamed over `path` ([`super::atomic`]).
pub fn write_report(
    path: &Path,
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    timeline: &[WindowSample],
    notes: &Notes<'_>,
) -> Result<()> {
    let png = render_report(path, cal, views, origins, timeline, notes)?;
    Ok(super::atomic::write_file(path, &png)?)
}

/// What the run says of the result, written on the report above the figures.
#[derive(Debug, Clone, Copy, Default)]
pub struct Notes<'a> {
    /// Why the result is no calibration: the report is stamped with it, in red.
    pub failure: Option<&'a str>,
    /// The verdict's line (`verdict: good`, ...).
    pub verdict: Option<&'a str>,
    /// The run's warnings; the first [`NOTE_LINES`] are drawn.
    pub warnings: &'a [String],
}

/// The most warnings drawn on the report: the console and the JSON result hold them all.
pub const NOTE_LINES: usize = 4;

/// The PNG bytes [`write_report`] writes to `path` (named in errors). Drawn into memory, so
/// that a failure leaves no half-drawn file. The PNG names evcal as its `Software`
/// (`PNG_SOFTWARE`).
pub fn render_report(
    path: &Path,
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    timeline: &[WindowSample],
    notes: &Notes<'_>,
) -> Result<Vec<u8>> {
    render(cal, views, origins, timeline, notes)
        .map_err(|message| ExportError::Report { path: path.to_path_buf(), message })
}

/// The most characters of a failed run's stamp: a line across the report.
const STAMP_CHARS: usize = 150;

/// The start of the `Software` text of every report: how [`super::remove_stale`] knows one.
pub const PNG_SOFTWARE: &str = "evcal";

fn render(
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    timeline: &[WindowSample],
    notes: &Notes<'_>,
) -> std::result::Result<Vec<u8>, String> {
    font_ready()?;
    let res = view_residuals(views, cal).map_err(|e| e.to_string())?;
    let (w, h) = REPORT_SIZE;
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw(&root, cal, views, &res, origins, timeline, notes).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let png_error = |e: png::EncodingError| format!("encoding the PNG: {e}");
    enc.add_text_chunk("Software".into(), format!("{PNG_SOFTWARE} {}", env!("CARGO_PKG_VERSION")))
        .map_err(png_error)?;
    let mut writer = enc.write_header().map_err(png_error)?;
    writer.write_image_data(&rgb).map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok(out)
}

pub(super) type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

fn draw(
    root: &Area<'_>,
    cal: &Calibration,
    views: &[View],
    res: &[Vec<[f64; 2]>],
    origins: &[ViewOrigin],
    timeline: &[WindowSample],
    notes: &Notes<'_>,
) -> DrawResult {
    root.fill(&WHITE)?;
    // Room above the title, which plotters sets almost against the edge.
    let root = root.margin(10, 0, 0, 0);
    // A failed run's report says so first, in red, so that no one takes its figures for a
    // calibration's.
    let root = match notes.failure {
        Some(why) => {
            let stamp = format!("NOT A CALIBRATION: {}", why.replace('\n', " "));
            let stamp: String = stamp.chars().take(STAMP_CHARS).collect();
            root.titled(&stamp, (FAMILY, 26).into_font().color(&RED))?
        }
        None => root,
    };
    let k = &cal.intrinsics;
    // Counted as the console counts them: strays set aside are not among the points.
    let points: usize = cal.views.iter().map(|v| v.points).sum::<usize>() - cal.stray_points;
    let sd = &cal.std_dev;
    let title = format!(
        "evcal calibration {}×{} — fx {:.2} ±{:.2}  fy {:.2} ±{:.2}  cx {:.2} ±{:.2}  cy {:.2} ±{:.2} (1σ)",
        cal.image_size[0], cal.image_size[1], k.fx, sd[0], k.fy, sd[1], k.cx, sd[2], k.cy, sd[3]
    );
    let body = root.titled(&title, (FAMILY, 26))?;
    let distortion = format!(
        "k1 {:.4} ±{:.4}  k2 {:.4} ±{:.4}  p1 {:.2e} ±{:.1e}  p2 {:.2e} ±{:.1e}  k3 {:.4} ±{:.4}",
        k.k1, sd[4], k.k2, sd[5], k.p1, sd[6], k.p2, sd[7], k.k3, sd[8]
    );
    let body = body.titled(&distortion, (FAMILY, 20).into_font().color(&DARK))?;
    let subtitle = format!(
        "RMS {:.3} px over {points} points of {} views ({} views set aside, {} stray points); median view {:.3} px",
        cal.rms_px,
        cal.views.len(),
        cal.rejected.len(),
        cal.stray_points,
        cal.median_view_px
    );
    let mut body = body.titled(&subtitle, (FAMILY, 20).into_font().color(&DARK))?;
    if let Some(v) = notes.verdict {
        let colour = match notes.failure {
            Some(_) => RED,
            None if v.ends_with("good") => GREEN_DARK,
            None => AMBER,
        };
        let line: String = v.chars().take(STAMP_CHARS).collect();
        body = body.titled(&line, (FAMILY, 22).into_font().color(&colour))?;
    }
    for w in notes.warnings.iter().take(NOTE_LINES) {
        let line: String = format!("warning: {w}").chars().take(STAMP_CHARS + 40).collect();
        body = body.titled(&line, (FAMILY, 16).into_font().color(&DARK))?;
    }
    let panels = body.split_evenly((2, 2));
    per_view_panel(&panels[0], cal, views.len())?;
    scatter_panel(&panels[1], cal, res)?;
    // The sensor twice, side by side: where the points were, and the σ they leave.
    let (coverage, sigma) = panels[2].split_horizontally(panels[2].dim_in_pixel().0 / 2);
    coverage_panel(&coverage, cal, views)?;
    super::heatmap::sigma_panel(&sigma, cal, views)?;
    timeline_panel(&panels[3], cal, origins, timeline)?;
    Ok(())
}

/// A range that plotters can draw: finite, not empty.
fn span(lo: f64, hi: f64) -> (f64, f64) {
    match (lo.is_finite(), hi.is_finite()) {
        (true, true) if hi > lo => (lo, hi),
        (true, _) => (lo, lo + 1.0),
        _ => (0.0, 1.0),
    }
}

/// Bars of each used view's RMS at its input index; views set aside as red marks on the
/// axis; the median as a line.
fn per_view_panel(area: &Area<'_>, cal: &Calibration, n_views: usize) -> DrawResult {
    let n = n_views.max(cal.views.iter().map(|v| v.view + 1).max().unwrap_or(0)).max(1);
    let top = cal.views.iter().map(|v| v.rms_px).filter(|x| x.is_finite()).fold(0.0, f64::max);
    let (y0, y1) = span(0.0, (top.max(cal.median_view_px) * 1.15).max(1e-3));
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("Reprojection error per view (median {:.3} px; red: set aside)", cal.median_view_px),
            (FAMILY, 20),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(-0.5..n as f64 - 0.5, y0..y1)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .label_style(LABELS)
        .axis_desc_style(DESCS)
        .x_label_formatter(&whole)
        .x_desc("view")
        .y_desc("RMS (px)")
        .draw()?;
    // Half a view wide, or a pixel-wide sliver when there are hundreds.
    let half = 0.4;
    // Bars far above the median stand out in orange.
    let high = 2.0 * cal.median_view_px;
    chart.draw_series(cal.views.iter().filter(|v| v.rms_px.is_finite()).map(|v| {
        let x = v.view as f64;
        let colour = if v.rms_px > high { ORANGE } else { BLUE };
        Rectangle::new([(x - half, 0.0), (x + half, v.rms_px.min(y1))], colour.filled())
    }))?;
    let mark = (y1 - y0) * 0.02;
    chart.draw_series(cal.rejected.iter().map(|r| {
        let x = r.view as f64;
        Rectangle::new([(x - half, 0.0), (x + half, mark)], RED.filled())
    }))?;
    if cal.median_view_px.is_finite() {
        let m = cal.median_view_px;
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(-0.5, m), (n as f64 - 0.5, m)],
            RED.stroke_width(2),
        )))?;
    }
    Ok(())
}

/// The plotting rectangle's margins that give x and y the same scale: extra margin on the
/// longer side of `area` (after `label_w` on the left and `label_h` below) so that its
/// aspect is `want` (width / height).
pub(super) fn equal_aspect_margins(area: &Area<'_>, label_w: u32, label_h: u32, want: f64) -> (u32, u32) {
    let (w, h) = area.dim_in_pixel();
    let (pw, ph) = (f64::from(w.saturating_sub(label_w + 24)), f64::from(h.saturating_sub(label_h + 50)));
    if pw <= 0.0 || ph <= 0.0 || !want.is_finite() || want <= 0.0 {
        return (0, 0);
    }
    if pw / ph > want {
        (((pw - ph * want) / 2.0) as u32, 0)
    } else {
        (0, ((ph - pw / want) / 2.0) as u32)
    }
}

/// Every point's residual with the overall RMS as a circle; the axes span most points and
/// say how many fall outside.
fn scatter_panel(area: &Area<'_>, cal: &Calibration, res: &[Vec<[f64; 2]>]) -> DrawResult {
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
        format!("Residuals, projected − detected ({outside} beyond the axes; circle: RMS)")
    } else {
        "Residuals, projected − detected (circle: RMS)".to_string()
    };
    let titled = area.titled(&caption, (FAMILY, 20))?;
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

/// Which cell of the sensor's `CELLS` grid a pixel falls in.
fn cell(p: [f64; 2], size: [u32; 2]) -> Option<(usize, usize)> {
    let (w, h) = (f64::from(size[0].max(1)), f64::from(size[1].max(1)));
    // Pixel centres are at integers: the sensor spans [-0.5, w - 0.5].
    let (u, v) = ((p[0] + 0.5) / w, (p[1] + 0.5) / h);
    ((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v))
        .then_some(((u * CELLS.0 as f64) as usize, (v * CELLS.1 as f64) as usize))
}

/// The sensor (rows downwards, as in the image) with every detected point: used views' in
/// blue, views set aside in red; cells shaded green by how many used points they hold.
fn coverage_panel(area: &Area<'_>, cal: &Calibration, views: &[View]) -> DrawResult {
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
    // Half a panel wide, beside the σ map.
    let caption = format!(
        "Coverage: {covered} of {} cells ({}×{}), {:.0} %",
        CELLS.0 * CELLS.1,
        CELLS.0,
        CELLS.1,
        100.0 * covered as f64 / (CELLS.0 * CELLS.1) as f64
    );
    let titled = area.titled(&caption, (FAMILY, 17))?;
    let (mx, my) = equal_aspect_margins(&titled, 65, 45, w / h);
    let mut chart = ChartBuilder::on(&titled)
        .margin(12)
        .margin_left(12 + mx)
        .margin_right(12 + mx)
        .margin_top(12 + my)
        .margin_bottom(12 + my)
        .x_label_area_size(45)
        .y_label_area_size(65)
        // Rows grow downwards, as in the image.
        .build_cartesian_2d(-0.5..w - 0.5, h - 0.5..-0.5)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .label_style(LABELS)
        .axis_desc_style(DESCS)
        .x_label_formatter(&whole)
        .y_label_formatter(&whole)
        .x_desc("column (px)")
        .y_desc("row (px)")
        .draw()?;
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
fn timeline_panel(area: &Area<'_>, cal: &Calibration, origins: &[ViewOrigin], timeline: &[WindowSample]) -> DrawResult {
    let ok: Vec<&WindowSample> = timeline.iter().filter(|s| s.t_s.is_finite()).collect();
    let found = ok.iter().filter(|s| s.grid_found).count();
    let used_t: Vec<f64> =
        cal.views.iter().filter_map(|v| origins.get(v.view)).map(|o| o.t_s).filter(|t| t.is_finite()).collect();
    let ts = ok.iter().map(|s| s.t_s).chain(used_t.iter().copied());
    let (lo, hi) = ts.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
    let (t0, t1) = if lo.is_finite() { span(lo, hi) } else { (0.0, 1.0) };
    let pad = (t1 - t0) * 0.02;
    let top = ok.iter().map(|s| s.centres).max().unwrap_or(0).max(1) as f64 * 1.15;
    let caption = format!("Detections over time: grid found in {found} of {} windows (ticks: views used)", ok.len());
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FAMILY, 20))
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

#[cfg(test)]
mod test {
    use super::super::testdata::*;
    use super::*;
    use std::collections::HashSet;

    /// Width, height and RGB(A) pixels of a PNG, and its channel count.
    fn decode(bytes: &[u8]) -> (u32, u32, usize, Vec<u8>) {
        let mut reader = png::Decoder::new(bytes).read_info().expect("a PNG");
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).expect("a frame");
        buf.truncate(info.buffer_size());
        (info.width, info.height, info.color_type.samples(), buf)
    }

    /// Distinct colours in the `(x0..x1, y0..y1)` block of an image.
    fn colours(img: &(u32, u32, usize, Vec<u8>), x: std::ops::Range<u32>, y: std::ops::Range<u32>) -> usize {
        let (w, _, n, px) = img;
        let mut set = HashSet::new();
        for row in y {
            for col in x.clone() {
                let at = (row as usize * *w as usize + col as usize) * n;
                set.insert(px[at..at + n].to_vec());
            }
        }
        set.len()
    }

    #[test]
    fn report_is_a_png_of_four_drawn_panels() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("report.png");
        write_report(&path, &cal, &views, &origins, &timeline, &Notes::default()).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let img = decode(&bytes);
        assert_eq!((img.0, img.1), REPORT_SIZE);
        // Every quadrant (each a panel) holds text, axes and data in several colours.
        let (w, h) = REPORT_SIZE;
        for (x, y) in [(0..w / 2, 80..h / 2), (w / 2..w, 80..h / 2), (0..w / 2, h / 2..h), (w / 2..w, h / 2..h)] {
            let n = colours(&img, x.clone(), y.clone());
            assert!(n >= 8, "panel at {x:?}, {y:?}: {n} colours");
        }
        // The title strip holds anti-aliased text, not a blank band.
        assert!(colours(&img, 0..w, 0..60) >= 4);
    }

    #[test]
    fn report_survives_little_data() {
        let (views, cal, _, _) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("report.png");
        // No timeline and no origins: the panels are drawn empty.
        write_report(&path, &cal, &views, &[], &[], &Notes::default()).unwrap();
        assert_eq!((decode(&std::fs::read(&path).unwrap()).0), REPORT_SIZE.0);
        // One window only; non-finite times are left out.
        let one = [
            WindowSample { t_s: 1.0, centres: 0, grid_found: false },
            WindowSample { t_s: f64::NAN, centres: 3, grid_found: true },
        ];
        write_report(&path, &cal, &views, &[], &one, &Notes::default()).unwrap();
        // A directory that does not exist: an error naming the file, nothing written.
        let bad = dir.path().join("missing/report.png");
        let e = format!("{:#}", write_report(&bad, &cal, &views, &[], &[], &Notes::default()).unwrap_err());
        assert!(e.contains("missing/report.png"), "{e}");
    }

    #[test]
    fn cells_cover_the_sensor() {
        assert_eq!(cell([-0.5, -0.5], [346, 260]), Some((0, 0)));
        assert_eq!(cell([345.4, 259.4], [346, 260]), Some((CELLS.0 - 1, CELLS.1 - 1)));
        assert_eq!(cell([345.5, 0.0], [346, 260]), None);
        assert_eq!(cell([f64::NAN, 0.0], [346, 260]), None);
    }
}
