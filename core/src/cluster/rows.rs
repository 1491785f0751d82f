//! The rows of the sorted events and the spans of neighbouring rows that the cursors of the
//! row sweep walk.

use crate::window::WindowEvent;

/// Most rows either side of a pixel that a neighbourhood may span with the sweep's cursors
/// (`⌊eps·H⌋`: 3 for the defaults on a DAVIS346, 10 on a 1280 x 720 sensor). Wider
/// neighbourhoods (eps above 0.1 or so, far from any useful setting) are still exact, by
/// comparing every pair of events.
pub const MAX_REACH_ROWS: usize = 32;

/// A run of events sharing one pixel row, `events[start..end]`, sorted by column.
#[derive(Clone, Copy, Default)]
pub(super) struct Row {
    pub(super) y: u16,
    pub(super) start: u16,
    pub(super) end: u16,
}

/// The rows of the sorted events, each with the rows at most `reach` above it: the pairs of
/// rows that can hold neighbours. Rows come in order; the window of recent rows is fixed.
pub(super) struct Rows {
    reach: usize,
    at: usize,
    recent: [Row; MAX_REACH_ROWS + 1],
    len: usize,
}

impl Rows {
    pub(super) fn new(reach: usize) -> Self {
        Self { reach, at: 0, recent: [Row::default(); MAX_REACH_ROWS + 1], len: 0 }
    }

    /// The next row, and the earlier rows within reach of it (nearest last). `None` at the
    /// end.
    pub(super) fn next(&mut self, events: &[WindowEvent]) -> Option<(Row, &[Row])> {
        let start = self.at;
        let y = events.get(start)?.y;
        let mut end = start + 1;
        while end < events.len() && events[end].y == y {
            end += 1;
        }
        self.at = end;
        // Forget rows out of reach of this one, then offer the rest.
        let keep_from = (0..self.len).find(|&k| usize::from(y - self.recent[k].y) <= self.reach).unwrap_or(self.len);
        self.recent.copy_within(keep_from..self.len, 0);
        self.len -= keep_from;
        let row = Row { y, start: start as u16, end: end as u16 };
        debug_assert!(self.len < self.recent.len(), "{} rows within reach {} of row {y}", self.len, self.reach);
        if self.len == self.recent.len() {
            // Unreachable (rows are distinct and at most `reach` apart), kept panic-free.
            self.recent.copy_within(1.., 0);
            self.len -= 1;
        }
        self.recent[self.len] = row;
        self.len += 1;
        Some((row, &self.recent[..self.len - 1]))
    }
}

/// For each event of `from` (in column order), the span of events of `to` within `s` columns
/// of it: `(index in from, lo, hi)`. Both rows are sorted by column, so the span slides.
pub(super) fn spans(
    events: &[WindowEvent],
    from: Row,
    to: Row,
    s: u16,
) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
    let base = usize::from(to.start);
    let target = events.get(base..usize::from(to.end)).unwrap_or(&[]);
    let source = events.get(usize::from(from.start)..usize::from(from.end)).unwrap_or(&[]);
    let (mut lo, mut hi) = (0, 0);
    source.iter().enumerate().map(move |(k, e)| {
        let (first, last) = (e.x.saturating_sub(s), e.x.saturating_add(s));
        while lo < target.len() && target[lo].x < first {
            lo += 1;
        }
        hi = hi.max(lo);
        while hi < target.len() && target[hi].x <= last {
            hi += 1;
        }
        (usize::from(from.start) + k, base + lo, base + hi)
    })
}

/// Adds to the count of each event of row `from` the number of events of row `to` within `s`
/// columns of it: the spatial case of [`spans`], as a tight loop over the two rows.
pub(super) fn count_spans(events: &[WindowEvent], counts: &mut [u16], from: Row, to: Row, s: u16) {
    let (f0, f1) = (usize::from(from.start), usize::from(from.end));
    let target = events.get(usize::from(to.start)..usize::from(to.end)).unwrap_or(&[]);
    let (Some(source), Some(counts)) = (events.get(f0..f1), counts.get_mut(f0..f1)) else { return };
    let (mut lo, mut hi) = (0, 0);
    for (e, c) in source.iter().zip(counts.iter_mut()) {
        let (first, last) = (e.x.saturating_sub(s), e.x.saturating_add(s));
        while lo < target.len() && target[lo].x < first {
            lo += 1;
        }
        hi = hi.max(lo);
        while hi < target.len() && target[hi].x <= last {
            hi += 1;
        }
        *c = c.saturating_add((hi - lo) as u16);
    }
}
