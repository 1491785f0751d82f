//! Spatial DBSCAN by column tables, in one sweep down the rows: core points counted by two
//! lookups a row, then linked and border points settled run by run.

use super::{
    metric::Metric,
    rows::Row,
    tables::{Near, Offset, Tables},
    ClusterStats, Clusterer, CORE, MASK, MAX_REACH_ROWS, NONE,
};
use crate::window::WindowEvent;

/// The column of no core point in [`Clusterer::link_row`]: any column is further from it than
/// any neighbourhood reaches.
const FAR_COLUMN: u32 = 0x8000_0000;

/// Labels the events of `row` with their own index, marked [`CORE`] for core points: the
/// events within reach of each pixel, over the rows `near` (nearest first, until `min_pts`),
/// are two lookups in the tables a row. Returns the core points and the lookups made.
// Kept out of line: inside the sweep the loop shared the registers of the linking below and
// reloaded its values on every lookup.
#[inline(never)]
fn count_row<const CELLS: usize>(
    labels: &mut [u16],
    events: &[WindowEvent],
    t: &Tables<CELLS>,
    row: Row,
    near: &[Near],
    min_x: u16,
    min_pts: usize,
) -> (u16, u32) {
    let (mut cores, mut queries) = (0u16, 0u32);
    let (start, end) = (usize::from(row.start), usize::from(row.end));
    let (Some(events), Some(labels)) = (events.get(start..end), labels.get_mut(start..end)) else {
        return (0, 0);
    };
    // Events of one pixel share their neighbourhood. Each label is the event's index and the
    // pixel's mark (`CORE` or 0).
    let (mut last_x, mut mark) = (usize::MAX, 0u16);
    let mut label = start as u16;
    for (e, l) in events.iter().zip(labels.iter_mut()) {
        let x = usize::from(e.x.wrapping_sub(min_x));
        if x != last_x {
            last_x = x;
            let (mut count, mut used) = (0, near.len());
            mark = 0;
            for (i, nr) in near.iter().enumerate() {
                count += t.at(nr.hi + x).wrapping_sub(t.at(nr.lo + x));
                if count >= min_pts {
                    (mark, used) = (CORE, i + 1);
                    break;
                }
            }
            queries = queries.wrapping_add(used as u32);
        }
        cores += mark >> 15;
        *l = label | mark;
        label = label.wrapping_add(1);
    }
    (cores, queries)
}

impl<const N: usize, const C: usize> Clusterer<N, C> {
    /// Spatial DBSCAN by column tables (see [`Tables`]), in one sweep down the rows: tables
    /// are built `2·reach` rows ahead of the row being linked, core points counted `reach`
    /// rows ahead. Returns the neighbourhood queries made, or `None`, having done nothing,
    /// when the tables do not fit in `cells`.
    #[inline(never)]
    pub(super) fn by_tables<const CELLS: usize>(
        &mut self,
        events: &[WindowEvent],
        cells: &mut [u16; CELLS],
        m: &Metric,
        min_pts: usize,
        (min_x, max_x): (u16, u16),
        stats: &mut ClusterStats,
    ) -> Option<u32> {
        let n = events.len();
        let reach = m.reach_y as usize;
        if reach > MAX_REACH_ROWS {
            return None;
        }
        let mut span = [0u16; MAX_REACH_ROWS + 1];
        for (dy, s) in span.iter_mut().enumerate().take(reach + 1) {
            *s = m.span(dy as u64).min(u64::from(u16::MAX)) as u16;
        }
        let width = usize::from(max_x.saturating_sub(min_x)) + 1;
        // Events are sorted by row: the last is on the last row.
        let last_row = events.last().map_or(0, |e| e.y);
        let mut t = Tables::new(cells, reach, min_x, width, usize::from(span[0]), last_row)?;
        // Row distances: nearest first for counting (most core points are known within a
        // few rows), from the top down for border points (lowest index first), and above.
        let mut nearest = [0i32; 2 * MAX_REACH_ROWS + 1];
        let mut top_down = [0i32; 2 * MAX_REACH_ROWS + 1];
        let r = reach as i32;
        for d in 0..=2 * r {
            top_down[d as usize] = d - r;
            nearest[d as usize] = if d % 2 == 1 { -(d + 1) / 2 } else { d / 2 };
        }
        let mut by_nearest = [Offset::default(); 2 * MAX_REACH_ROWS + 1];
        let mut by_row = [Offset::default(); 2 * MAX_REACH_ROWS + 1];
        for (k, (a, b)) in by_nearest.iter_mut().zip(by_row.iter_mut()).enumerate().take(2 * reach + 1) {
            *a = t.offset(nearest[k], span[nearest[k].unsigned_abs() as usize]);
            *b = t.offset(top_down[k], span[top_down[k].unsigned_abs() as usize]);
        }
        let (nearest, top_down) = (&by_nearest[..2 * reach + 1], &by_row[..2 * reach + 1]);
        let mut near = [Near::default(); 2 * MAX_REACH_ROWS + 1];
        let s0 = span[0];
        // Runs of core points for linking (see `link_row`) are cut at gaps wider than this.
        let gap = s0.min(span[reach].saturating_mul(2).saturating_add(1));
        // `gap` holds for every row within reach, and `pad` (the widest span) keeps every
        // lookup inside the tables, only if spans narrow with the row distance.
        debug_assert!(span[..=reach].windows(2).all(|w| w[0] >= w[1]), "spans widen with the row distance: {span:?}");

        let (mut counted, mut linked) = (0, 0);
        let (mut queries, mut core_points) = (0u32, 0u16);
        while let Some(e) = events.get(linked) {
            let y = u32::from(e.y);
            // 1. Core points, up to `reach` rows below the row to link: the events of each
            //    row within reach that a span holds are two lookups.
            while let Some(c) = events.get(counted).filter(|c| u32::from(c.y) <= y + reach as u32) {
                t.build_to(events, u32::from(c.y) + reach as u32);
                let (row, len, _) = t.around(c.y, nearest, &mut near);
                let (cores, lookups) = count_row(&mut self.labels, events, &t, row, &near[..len], min_x, min_pts);
                core_points = core_points.wrapping_add(cores);
                queries = queries.wrapping_add(lookups);
                counted = usize::from(row.end).max(counted + 1);
            }

            // 2. Links and border points. Each core point joins the previous one in its row
            //    when they are neighbours, and each run of them the core points within reach
            //    in the rows above (see `link_row`). A border point takes the first core
            //    point of the first span, from the top down, that holds one.
            let (row, len, above) = t.around(e.y, top_down, &mut near);
            queries = queries.wrapping_add(self.link_row(events, &t, row, &near[..len], above, min_x, (s0, gap)));
            linked = usize::from(row.end).max(linked + 1);
        }
        stats.core = core_points;
        self.number(n, stats);
        self.settle_borders(n, stats);
        Some(queries)
    }

    /// Links the core points of `row` (core points marked by [`count_row`]) to the core
    /// points before them within reach, and gives its border points their first core
    /// neighbour, from the rows `near` (from the top down; the first `above` of them above
    /// `row`). Returns the lookups made.
    ///
    /// Each core point joins the previous one in its row when they are neighbours (`s0`
    /// columns apart at most). Those chains are cut into runs whose gaps are at most `gap`
    /// columns, no more than twice the narrowest span plus one: every column from a run's
    /// first less a span to its last plus that span is then within a span of one of the
    /// run's points, so every core point there, in a row above, is a neighbour of the run,
    /// and no other is. The run joins, in each row above, the first core point of that range
    /// and each one more than `s0` columns right of the previous: the others are chained to
    /// those already. A lookup per run and row where linking each core point took one per
    /// point and row.
    // Kept out of line, as `count_row` is.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn link_row<const CELLS: usize>(
        &mut self,
        events: &[WindowEvent],
        t: &Tables<CELLS>,
        row: Row,
        near: &[Near],
        above: usize,
        min_x: u16,
        (s0, gap): (u16, u16),
    ) -> u32 {
        let mut queries = 0u32;
        // The previous core point and its column (none yet: a column as far as a column can
        // be from every other); the run's first core point and column.
        let (mut prev, mut prev_x) = (0usize, FAR_COLUMN);
        let (mut first, mut first_x) = (usize::MAX, 0u32);
        let (s0, gap) = (u32::from(s0), u32::from(gap));
        let above = near.get(..above).unwrap_or(&[]);
        let end = usize::from(row.end).min(events.len()).min(N);
        // The last border point's column, core point and lookups: the events of one pixel
        // (two in an 8000-event window, on average) share them, since the core marks stay as
        // they are while the row is linked (M4F: 0.72 -> 0.67 M instructions a window).
        let (mut border_x, mut border_best, mut border_used) = (usize::MAX, NONE, 0u32);
        for k in usize::from(row.start)..end {
            let ex = events[k].x;
            if self.labels[k] & CORE == 0 {
                let x = usize::from(ex.wrapping_sub(min_x));
                if x != border_x {
                    let (mut best, mut used) = (NONE, 0u32);
                    for nr in near {
                        used += 1;
                        if let Some(j) = self.first_core(t.at(nr.lo + x), t.at(nr.hi + x)) {
                            best = j as u16;
                            break;
                        }
                    }
                    (border_x, border_best, border_used) = (x, best, used);
                }
                queries = queries.wrapping_add(border_used);
                self.labels[k] = border_best;
                continue;
            }
            let ex = u32::from(ex);
            let step = ex.wrapping_sub(prev_x);
            if step <= s0 {
                // `union(prev, k)`: no link has reached `k` yet (only rows above and points
                // before it in its row have been linked), so it is its own root.
                debug_assert_eq!(usize::from(self.labels[k] & MASK), k, "core point {k} linked before its row");
                let parent = self.labels.get(prev).map_or(0, |&l| l & MASK);
                self.labels[k] = CORE | parent;
            }
            if step > gap {
                if first != usize::MAX {
                    let cols = (first_x as u16, prev_x as u16);
                    queries = queries.wrapping_add(self.link_run(events, t, above, first, cols, min_x, s0 as u16));
                }
                (first, first_x) = (k, ex);
            }
            (prev, prev_x) = (k, ex);
        }
        if first != usize::MAX {
            let cols = (first_x as u16, prev_x as u16);
            queries = queries.wrapping_add(self.link_run(events, t, above, first, cols, min_x, s0 as u16));
        }
        queries
    }

    /// Joins the run of core points starting at `first`, from column `lo_x` to `hi_x`, to the
    /// core points within reach of it in the rows `above` (see [`link_row`](Self::link_row)).
    /// Returns the lookups made.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn link_run<const CELLS: usize>(
        &mut self,
        events: &[WindowEvent],
        t: &Tables<CELLS>,
        above: &[Near],
        first: usize,
        (lo_x, hi_x): (u16, u16),
        min_x: u16,
        s0: u16,
    ) -> u32 {
        let (lo_x, hi_x) = (usize::from(lo_x.wrapping_sub(min_x)), usize::from(hi_x.wrapping_sub(min_x)));
        for nr in above {
            let (lo, hi) = (t.at(nr.lo + lo_x), t.at(nr.hi + hi_x).min(events.len()).min(N));
            // Far enough left of any column that the first core point is joined.
            let mut last = -i32::from(u16::MAX);
            for j in lo..hi {
                if self.labels[j] & CORE != 0 {
                    let x = i32::from(events[j].x);
                    if x - last > i32::from(s0) {
                        self.union(j, first);
                    }
                    last = x;
                }
            }
        }
        above.len() as u32
    }

    /// The first core point of `events[lo..hi]`.
    #[inline]
    fn first_core(&self, lo: usize, hi: usize) -> Option<usize> {
        let part = self.labels.get(lo..hi)?;
        part.iter().position(|l| l & CORE != 0).map(|p| lo + p)
    }
}
