//! A few detection windows with the grid as it was labelled: every centre detected in the
//! window small and grey, the grid's points larger and numbered by board index, consecutive
//! indices joined, so that a mislabelled grid (a row read backwards, a point taken from the
//! next circle) shows at a glance, as ROS's calibrator overlay and Kalibr's
//! `--show-extraction` show it.

use super::{equal_aspect_margins, Area, DrawResult, Notes, BLUE, DARK, FAMILY, LABELS, ORANGE, RED};
use crate::calib::{Calibration, View};
use crate::views::ViewOrigin;
use plotters::prelude::*;
use std::collections::{BTreeMap, HashMap};

/// Windows drawn along the bottom of the report.
pub const FRAMES: usize = 4;

/// An event pixel's grey by how many of the window's events fell on it: one, two, three,
/// four or more. Light, so that the centres and the grid stand out on it.
const EVENT_GREYS: [u8; 4] = [205, 180, 155, 130];

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
/// run in time (by input index where a view has no time), in time order: chosen first among
/// the views `kept` says have their events, the rest among the others.
pub(super) fn spread_views(cal: &Calibration, origins: &[ViewOrigin], kept: impl Fn(usize) -> bool) -> Vec<usize> {
    let at = |i: usize| origins.get(cal.views[i].view).map(|o| o.t_s).filter(|t| t.is_finite());
    let by_time = |a: &usize, b: &usize| match (at(*a), at(*b)) {
        (Some(x), Some(y)) => x.total_cmp(&y),
        _ => cal.views[*a].view.cmp(&cal.views[*b].view),
    };
    let (mut with, mut without): (Vec<usize>, Vec<usize>) =
        (0..cal.views.len()).partition(|&i| kept(cal.views[i].view));
    with.sort_by(by_time);
    without.sort_by(by_time);
    let mut picked = spread(&with, FRAMES);
    picked.extend(spread(&without, FRAMES - picked.len()));
    picked.sort_by(by_time);
    picked
}

/// `n` of `order` (fewer if it is shorter): the middle of each of `n` equal parts.
fn spread(order: &[usize], n: usize) -> Vec<usize> {
    let n = order.len().min(n);
    (0..n).map(|k| order[(2 * k + 1) * order.len() / (2 * n)]).collect()
}

/// The bottom strip: [`FRAMES`] windows side by side ([`spread_views`]), with the centres
/// and events of `notes`.
pub(super) fn frames_row(
    area: &Area<'_>,
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    notes: &Notes<'_>,
) -> DrawResult {
    let numbers = board_numbers(views);
    let cells = area.split_evenly((1, FRAMES));
    let kept = |v: usize| notes.events.get(v).is_some_and(|e| !e.is_empty());
    for (slot, i) in cells.iter().zip(spread_views(cal, origins, kept)) {
        frame_panel(slot, cal, views, origins, notes, &numbers, i)?;
    }
    Ok(())
}

/// One window: the sensor, the window's centres, the grid numbered and joined.
fn frame_panel(
    area: &Area<'_>,
    cal: &Calibration,
    views: &[View],
    origins: &[ViewOrigin],
    notes: &Notes<'_>,
    numbers: &BTreeMap<(i64, i64), usize>,
    i: usize,
) -> DrawResult {
    let v = cal.views[i].view;
    let Some(view) = views.get(v) else { return Ok(()) };
    let found = notes.centres.get(v);
    let events = notes.events.get(v).map_or(&[][..], Vec::as_slice);
    let [w, h] = cal.image_size.map(|x| f64::from(x.max(1)));
    let when = origins.get(v).map_or(String::new(), |o| format!(" at {:.2} s", o.t_s));
    let caption = match found {
        Some(c) if !events.is_empty() => {
            format!("View {v}{when}: {} in grid of {} centres, {} events", view.image.len(), c.len(), events.len())
        }
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
    let mut counts: HashMap<[u16; 2], usize> = HashMap::new();
    for p in events {
        *counts.entry(*p).or_default() += 1;
    }
    chart.draw_series(counts.iter().map(|(p, &n)| {
        let g = EVENT_GREYS[n.clamp(1, EVENT_GREYS.len()) - 1];
        let (x, y) = (f64::from(p[0]), f64::from(p[1]));
        Rectangle::new([(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)], RGBColor(g, g, g).filled())
    }))?;
    if let Some(c) = found {
        chart.draw_series(
            c.iter()
                .filter(|p| p[0].is_finite() && p[1].is_finite())
                .map(|p| Circle::new((p[0], p[1]), 3, RED.stroke_width(1))),
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
        let picked = spread_views(&cal, &origins, |_| false);
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
        assert_eq!(spread_views(&few, &origins, |_| true), vec![0, 1]);
        // Views with their events kept come first, still in time order; the rest fill up.
        let kept = |v: usize| v % 3 == 0;
        let with = cal.views.iter().filter(|r| kept(r.view)).count();
        assert!(with >= FRAMES, "{with}");
        let picked = spread_views(&cal, &origins, kept);
        assert_eq!(picked.len(), FRAMES);
        assert!(picked.iter().all(|&i| kept(cal.views[i].view)), "{picked:?}");
        let some = |v: usize| v == 5 || v == 9;
        let picked: Vec<usize> = spread_views(&cal, &origins, some).iter().map(|&i| cal.views[i].view).collect();
        assert_eq!(picked.len(), FRAMES);
        assert!(picked.contains(&5) && picked.contains(&9) && picked.windows(2).all(|p| p[0] < p[1]), "{picked:?}");
    }
}
