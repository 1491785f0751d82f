//! A few detection windows with the grid as it was labelled: every centre detected in the
//! window small and grey, the grid's points larger and numbered by board index, consecutive
//! indices joined, so that a mislabelled grid (a row read backwards, a point taken from the
//! next circle) shows at a glance, as ROS's calibrator overlay and Kalibr's
//! `--show-extraction` show it.

use super::{equal_aspect_margins, Area, DrawResult, BLUE, DARK, FAMILY, GREY, LABELS, ORANGE};
use crate::calib::{Calibration, View};
use crate::views::ViewOrigin;
use plotters::prelude::*;
use std::collections::BTreeMap;

/// Windows drawn along the bottom of the report.
pub const FRAMES: usize = 4;

/// The windows' captions: smaller than the panels', four to a row.
const FRAME_CAPTION: (&str, u32) = (FAMILY, 16);
/// Room for the windows' tick labels, px: left, below.
const FRAME_LABELS: (u32, u32) = (40, 25);
/// Margin round each window's picture, px.
const FRAME_MARGIN: u32 = 8;

/// The height of the strip of windows `width` px wide that shows a sensor of `size` at the
/// scale its width allows, with its caption and labels.
pub(super) fn strip_height(width: u32, size: [u32; 2]) -> u32 {
    let plot_w = (width / FRAMES as u32).saturating_sub(FRAME_LABELS.0 + 2 * FRAME_MARGIN + 8);
    let plot_h = f64::from(plot_w) * f64::from(size[1].max(1)) / f64::from(size[0].max(1));
    plot_h.round() as u32 + FRAME_LABELS.1 + 2 * FRAME_MARGIN + FRAME_CAPTION.1 * 2
}

/// A board point as a key ordered as the board indices are: by x, then by y, in micrometres
/// (board points are on a grid millimetres apart). The pattern numbers circle `i·rows + j`
/// at (i·s, (2j + i mod 2)·s) ([`crate::views::grid::Pattern::object_point`]), so that
/// order is the index order.
fn key(o: &[f64; 3]) -> (i64, i64) {
    ((o[0] * 1e6).round() as i64, (o[1] * 1e6).round() as i64)
}

/// Each board point seen in any of `views`, numbered in board order: the board's own index
/// wherever every point of the board was seen at least once (a run with views at all sees
/// them all; a point never seen shifts the numbers after it, and is said nowhere else).
pub(super) fn board_numbers(views: &[View]) -> BTreeMap<(i64, i64), usize> {
    let mut order: BTreeMap<(i64, i64), usize> =
        views.iter().flat_map(|v| v.object.iter().map(|o| (key(o), 0))).collect();
    for (i, n) in order.values_mut().enumerate() {
        *n = i;
    }
    order
}

/// Up to [`FRAMES`] of the used views (indices into `cal.views`), spread evenly over the
/// run in time (by input index where a view has no time): the middle of each of
/// [`FRAMES`] equal parts of the used views in time order.
pub(super) fn spread_views(cal: &Calibration, origins: &[ViewOrigin]) -> Vec<usize> {
    let at = |i: usize| origins.get(cal.views[i].view).map(|o| o.t_s).filter(|t| t.is_finite());
    let mut order: Vec<usize> = (0..cal.views.len()).collect();
    order.sort_by(|&a, &b| match (at(a), at(b)) {
        (Some(x), Some(y)) => x.total_cmp(&y),
        _ => cal.views[a].view.cmp(&cal.views[b].view),
    });
    let n = order.len().min(FRAMES);
    (0..n).map(|k| order[(2 * k + 1) * order.len() / (2 * n)]).collect()
}

/// The bottom strip: [`FRAMES`] windows side by side ([`spread_views`]). `centres`: every
/// centre detected in each view's window, indexed like `views` (may be empty).
pub(super) fn frames_row(
    area: &Area<'_>,
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    centres: &[Vec<[f64; 2]>],
) -> DrawResult {
    let numbers = board_numbers(views);
    let cells = area.split_evenly((1, FRAMES));
    for (slot, i) in cells.iter().zip(spread_views(cal, origins)) {
        frame_panel(slot, cal, views, origins, centres, &numbers, i)?;
    }
    Ok(())
}

/// One window: the sensor, the window's centres, the grid numbered and joined.
fn frame_panel(
    area: &Area<'_>,
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    centres: &[Vec<[f64; 2]>],
    numbers: &BTreeMap<(i64, i64), usize>,
    i: usize,
) -> DrawResult {
    let v = cal.views[i].view;
    let Some(view) = views.get(v) else { return Ok(()) };
    let found = centres.get(v);
    let [w, h] = cal.image_size.map(|x| f64::from(x.max(1)));
    let when = origins.get(v).map_or(String::new(), |o| format!(" at {:.2} s", o.t_s));
    let caption = match found {
        Some(c) => format!("View {v}{when}: {} in grid of {} centres", view.image.len(), c.len()),
        None => format!("View {v}{when}: {} points in grid", view.image.len()),
    };
    let titled = area.titled(&caption, FRAME_CAPTION)?;
    let (mx, my) = equal_aspect_margins(&titled, FRAME_LABELS.0, FRAME_LABELS.1, w / h);
    let mut chart = ChartBuilder::on(&titled)
        .margin(FRAME_MARGIN)
        .margin_left(FRAME_MARGIN + mx)
        .margin_right(FRAME_MARGIN + mx)
        .margin_top(FRAME_MARGIN + my)
        .margin_bottom(FRAME_MARGIN + my)
        .x_label_area_size(FRAME_LABELS.1)
        .y_label_area_size(FRAME_LABELS.0)
        .build_cartesian_2d(-0.5..w - 0.5, h - 0.5..-0.5)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .label_style((LABELS.0, 12))
        .x_label_formatter(&super::whole)
        .y_label_formatter(&super::whole)
        .draw()?;
    if let Some(c) = found {
        chart.draw_series(
            c.iter()
                .filter(|p| p[0].is_finite() && p[1].is_finite())
                .map(|p| Circle::new((p[0], p[1]), 2, GREY.filled())),
        )?;
    }
    let mut grid: Vec<(usize, [f64; 2])> =
        view.object.iter().zip(&view.image).filter_map(|(o, p)| numbers.get(&key(o)).map(|&n| (n, *p))).collect();
    grid.sort_by_key(|g| g.0);
    chart.draw_series(
        grid.windows(2)
            .filter(|g| g[1].0 == g[0].0 + 1)
            .map(|g| PathElement::new(vec![(g[0].1[0], g[0].1[1]), (g[1].1[0], g[1].1[1])], ORANGE.stroke_width(1))),
    )?;
    chart.draw_series(grid.iter().map(|(_, p)| Circle::new((p[0], p[1]), 3, BLUE.filled())))?;
    let style = TextStyle::from((FAMILY, 11).into_font()).color(&DARK);
    chart.draw_series(grid.iter().map(|(n, p)| Text::new(n.to_string(), (p[0] + 2.0, p[1] - 2.0), style.clone())))?;
    chart.draw_series(std::iter::once(Rectangle::new([(-0.5, -0.5), (w - 0.5, h - 0.5)], DARK.stroke_width(1))))?;
    Ok(())
}

#[cfg(test)]
mod test {
    use super::super::super::testdata::*;
    use super::*;
    use crate::views::grid::Pattern;

    /// The numbers are the pattern's own indices, whatever order a view lists its points in
    /// and whichever points it misses.
    #[test]
    fn numbering_order_is_board_order() {
        let pattern = Pattern::new(4, 11, 0.024).unwrap();
        let board = pattern.object_points();
        let full = View { object: board.clone(), image: vec![[0.0; 2]; board.len()] };
        // A view of every third point, listed backwards.
        let mut some: Vec<[f64; 3]> = board.iter().copied().step_by(3).collect();
        some.reverse();
        let part = View { image: vec![[0.0; 2]; some.len()], object: some };
        let numbers = board_numbers(&[part.clone(), full]);
        assert_eq!(numbers.len(), pattern.len());
        for (k, o) in board.iter().enumerate() {
            assert_eq!(numbers[&key(o)], k, "point {k} at {o:?}");
        }
        for (o, want) in part.object.iter().zip((0..pattern.len()).step_by(3).rev()) {
            assert_eq!(numbers[&key(o)], want);
        }
    }

    #[test]
    fn spread_views_cover_the_run_in_time() {
        let (_, cal, origins, _) = setup(&TRUTH, false);
        let n = cal.views.len();
        assert!(n >= 2 * FRAMES, "{n} views");
        let picked = spread_views(&cal, &origins);
        assert_eq!(picked.len(), FRAMES);
        let t: Vec<f64> = picked.iter().map(|&i| origins[cal.views[i].view].t_s).collect();
        let all: Vec<f64> = cal.views.iter().map(|v| origins[v.view].t_s).collect();
        let (lo, hi) = all.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        // In time order, one in each quarter of the run.
        assert!(t.windows(2).all(|p| p[0] < p[1]), "{t:?}");
        for (k, x) in t.iter().enumerate() {
            let q = (x - lo) / (hi - lo);
            assert!(q >= k as f64 / FRAMES as f64 - 0.1 && q <= (k + 1) as f64 / FRAMES as f64 + 0.1, "{t:?}");
        }
        // Fewer views than frames: each once.
        let mut few = cal.clone();
        few.views.truncate(2);
        assert_eq!(spread_views(&few, &origins), vec![0, 1]);
    }
}
