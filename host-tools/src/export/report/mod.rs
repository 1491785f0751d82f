//! The PNG report a person reads to judge a calibration: the parameters with σ, the verdict
//! and the warnings above two rows of panels and a strip of detection windows.
//!
//! - reprojection error per view (RMS, px) against time, with the median;
//! - every point's residual (dx, dy), with the overall RMS as a circle;
//! - the mean residual per sensor cell as an arrow ([`directions`]): a pattern means a
//!   wrong model;
//! - where on the sensor the points were detected, with the coverage cells;
//! - circle centres per detection window over time, with the windows whose grid was found;
//! - the projection σ over the sensor with the boards' outlines ([`super::heatmap`]);
//! - a few windows with the grid drawn and numbered on their centres ([`frames`]).

mod directions;
mod frames;
mod panels;

pub use frames::FRAMES;

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
pub const REPORT_SIZE: (u32, u32) = (1600, 1800);

/// DejaVu Sans, reduced to the characters drawn here (see assets/DejaVuSans-LICENSE.txt):
/// built in so that the report looks the same on a machine without fonts.
const FONT: &[u8] = include_bytes!("../../../assets/DejaVuSans-subset.ttf");
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
/// Panels' captions: six panels of a third of the width each.
const CAPTION: (&str, u32) = (FAMILY, 18);

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

/// What the run says of the result, written on the report above the figures, and what the
/// figures draw beside the calibration and its views. Every field defaults to nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Notes<'a> {
    /// Why the result is no calibration: the report is stamped with it, in red.
    pub failure: Option<&'a str>,
    /// The verdict's line (`verdict: good`, ...).
    pub verdict: Option<&'a str>,
    /// The run's warnings; the first [`NOTE_LINES`] are drawn.
    pub warnings: &'a [String],
    /// Every circle centre detected in each view's window, indexed like the views (empty:
    /// not known): drawn under the numbered grid of the windows shown.
    pub centres: &'a [Vec<[f64; 2]>],
    /// The events of each view's window as pixels, indexed like the views (empty, or an empty
    /// list: not kept): drawn as a grey image under the centres. The windows shown are chosen
    /// among the views that have them.
    pub events: &'a [Vec<[u16; 2]>],
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
const STAMP_CHARS: usize = 90;
/// The most characters of the verdict's line (22 pt): the report's width.
const VERDICT_CHARS: usize = 125;
/// The most characters of a warning's line (16 pt): the report's width.
const NOTE_CHARS: usize = 175;

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
    // Best compression with adaptive filters: a 3 s simulated recording's report 1.75 MB ->
    // 0.31 MB, calibrate's run time unchanged within its spread (2.6-3.0 s, then 2.4-2.8 s).
    enc.set_compression(png::Compression::Best);
    enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
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
            // Its first clause: the verdict's line below says the rest at a size that fits.
            let clause = why.split(": ").next().unwrap_or(why).replace('\n', " ");
            let stamp: String = format!("NOT A CALIBRATION: {clause}").chars().take(STAMP_CHARS).collect();
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
        let line: String = v.chars().take(VERDICT_CHARS).collect();
        body = body.titled(&line, (FAMILY, 22).into_font().color(&colour))?;
    }
    for w in notes.warnings.iter().take(NOTE_LINES) {
        let line: String = format!("warning: {w}").chars().take(NOTE_CHARS).collect();
        body = body.titled(&line, (FAMILY, 16).into_font().color(&DARK))?;
    }
    // Two rows of three panels above a strip of windows as high as their pictures need.
    let (body_w, body_h) = body.dim_in_pixel();
    let strip_h = frames::strip_height(body_w, cal.image_size).min(body_h / 3);
    let (rows, strip) = body.split_vertically(body_h - strip_h);
    let rows = rows.split_evenly((2, 3));
    panels::per_view_panel(&rows[0], cal, origins)?;
    panels::scatter_panel(&rows[1], cal, res)?;
    directions::directions_panel(&rows[2], cal, views, res)?;
    panels::coverage_panel(&rows[3], cal, views)?;
    panels::timeline_panel(&rows[4], cal, origins, timeline)?;
    super::heatmap::sigma_panel(&rows[5], cal, views)?;
    frames::frames_row(&strip, cal, views, origins, notes)?;
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

/// A chart of the sensor on `titled` (a panel under its caption): pixel coordinates, rows
/// growing downwards as in the image, the sensor's aspect kept, the axes labelled.
pub(super) fn sensor_chart<'a, 'b>(
    titled: &'a Area<'b>,
    size: [u32; 2],
) -> std::result::Result<SensorChart<'a, 'b>, Box<dyn std::error::Error>> {
    let [w, h] = size.map(|x| f64::from(x.max(1)));
    let (mx, my) = equal_aspect_margins(titled, 65, 45, w / h);
    let mut chart = ChartBuilder::on(titled)
        .margin(12)
        .margin_left(12 + mx)
        .margin_right(12 + mx)
        .margin_top(12 + my)
        .margin_bottom(12 + my)
        .x_label_area_size(45)
        .y_label_area_size(65)
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
    Ok(chart)
}

/// What [`sensor_chart`] gives.
pub(super) type SensorChart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    plotters::coord::cartesian::Cartesian2d<
        plotters::coord::types::RangedCoordf64,
        plotters::coord::types::RangedCoordf64,
    >,
>;

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

/// Which cell of the sensor's `CELLS` grid a pixel falls in.
fn cell(p: [f64; 2], size: [u32; 2]) -> Option<(usize, usize)> {
    let (w, h) = (f64::from(size[0].max(1)), f64::from(size[1].max(1)));
    // Pixel centres are at integers: the sensor spans [-0.5, w - 0.5].
    let (u, v) = ((p[0] + 0.5) / w, (p[1] + 0.5) / h);
    ((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v))
        .then_some(((u * CELLS.0 as f64) as usize, (v * CELLS.1 as f64) as usize))
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
    fn report_is_a_png_of_drawn_panels() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("report.png");
        // Each window's centres: its grid's and two strays.
        let centres: Vec<Vec<[f64; 2]>> =
            views.iter().map(|v| v.image.iter().copied().chain([[20.0, 20.0], [300.0, 40.0]]).collect()).collect();
        // Every view's events: a few pixels round each of its points, once each.
        let events: Vec<Vec<[u16; 2]>> = views
            .iter()
            .map(|v| {
                v.image.iter().flat_map(|p| [[p[0] as u16 + 8, p[1] as u16], [p[0] as u16, p[1] as u16 + 8]]).collect()
            })
            .collect();
        let notes = Notes { centres: &centres, events: &events, ..Notes::default() };
        write_report(&path, &cal, &views, &origins, &timeline, &notes).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let img = decode(&bytes);
        assert_eq!((img.0, img.1), REPORT_SIZE);
        if let Ok(keep) = std::env::var("EVCAL_KEEP_REPORT") {
            std::fs::copy(&path, keep).unwrap();
        }
        let (w, h) = REPORT_SIZE;
        // Each of the five panels of the two rows (the sixth is the heat map's slot) holds
        // text, axes and data in several colours; the panels start below the title block.
        let strip_h = frames::strip_height(w, cal.image_size);
        let (top, row) = (150, (h - 150 - strip_h) / 2);
        for (c, r) in [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1)] {
            let (x, y) = (c * w / 3..(c + 1) * w / 3, top + r * row..top + (r + 1) * row);
            let n = colours(&img, x.clone(), y.clone());
            assert!(n >= 8, "panel at {x:?}, {y:?}: {n} colours");
        }
        // Each window of the strip holds its events (light grey), its centres (red rings) and
        // its numbered grid (blue).
        let strip = h - strip_h + 30..h;
        for f in 0..FRAMES as u32 {
            let x = f * w / FRAMES as u32..(f + 1) * w / FRAMES as u32;
            let n = |c: RGBColor| count(&img, x.clone(), strip.clone(), c);
            let (events, red, blue) = (n(RGBColor(205, 205, 205)), n(RED), n(BLUE));
            assert!(
                events >= 20 && red >= 4 && blue >= 200,
                "window {f}: {events} event, {red} red, {blue} blue pixels"
            );
        }
        // The title strip holds anti-aliased text, not a blank band.
        assert!(colours(&img, 0..w, 0..60) >= 4);
    }

    /// Pixels of exactly `colour` in a block of an image.
    fn count(
        img: &(u32, u32, usize, Vec<u8>),
        x: std::ops::Range<u32>,
        y: std::ops::Range<u32>,
        colour: RGBColor,
    ) -> usize {
        let (w, _, n, px) = img;
        y.flat_map(|row| x.clone().map(move |col| (row as usize * *w as usize + col as usize) * n))
            .filter(|&at| px[at..at + 3] == [colour.0, colour.1, colour.2])
            .count()
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
