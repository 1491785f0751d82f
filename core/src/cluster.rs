//! DBSCAN over one window's events, on a sorted pixel grid.
//!
//! Coordinates are normalised by the sensor size (x / W, y / H) as in the paper, so one
//! `eps` (default 0.015) serves every sensor. The optional spatio-temporal variant
//! (ST-DBSCAN) also requires `|Δt| ≤ eps_t · T`, with `T` the window's duration.
//!
//! The grid is the sensor's own pixel grid: the window's events are sorted in place by
//! pixel (row, then column, then time), which makes every row of the grid a contiguous run
//! (a window's events come in time order, so two stable counting passes, by column and then
//! by row, do it; other input takes a radix and insertion sort). The eps-neighbourhood of a
//! pixel covers a few rows (`⌊eps·H⌋` either side) and, in each, one contiguous span of
//! columns. One sweep down the rows keeps, for each row within reach, a table from column
//! to the index of the row's first event at or right of it (see [`TABLE_CELLS`]): the
//! events of a span are then two lookups apart, which counts every event's neighbours
//! exactly without comparing pairs of events, and the first of them is the span's
//! lowest-index event, from which the links between core points and each border point's
//! core neighbour follow. The work is linear in the events and the rows (after the sort);
//! the memory is the events, one label per event and the tables, on the stack.
//!
//! ST-DBSCAN, and neighbourhoods whose tables would not fit, walk two cursors per
//! neighbouring row instead: as the events are visited in sorted order, the start and end of
//! each span only ever move forward, so the counts stay exact at constant cost per row.
//!
//! The result is exactly that of textbook DBSCAN on the same (reordered) events, with one
//! rule made explicit so that it does not depend on the visiting order: a border point joins
//! the cluster of its lowest-index core neighbour. Clusters are numbered in the order of
//! their lowest-index core point. A point is a core point when its eps-neighbourhood,
//! itself included, holds at least `min_pts` points (the scikit-learn convention).

// Index loops read best here: indices are compared, swapped and stored as labels.
#![allow(clippy::needless_range_loop)]

use crate::{event::SensorSize, window::WindowEvent};

/// Label of an event that belongs to no cluster.
pub const NOISE: u16 = 0x7FFF;
/// Label of an event whose cluster did not fit in the clusterer's capacity.
pub const DROPPED: u16 = 0x7FFE;

/// Marks a core point in the label array while clustering runs.
const CORE: u16 = 0x8000;
const MASK: u16 = 0x7FFF;
/// A border point without a core neighbour (yet), while border points are settled.
const NONE: u16 = 0x7FFF;

/// Most rows either side of a pixel that a neighbourhood may span with the sweep's cursors
/// (`⌊eps·H⌋`: 3 for the defaults on a DAVIS346, 10 on a 1280 x 720 sensor). Wider
/// neighbourhoods (eps above 0.1 or so, far from any useful setting) are still exact, by
/// comparing every pair of events.
pub const MAX_REACH_ROWS: usize = 32;

/// Cells (`u16`, 16 KiB, on the stack while a window is clustered) of the column tables of
/// the spatial sweep: one table per row within reach of the row being visited, above and
/// below, each as wide as the events' columns plus the neighbourhood either side. The
/// defaults on a DAVIS346 take 7 rows of 357 cells. Sweeps that need more (wider sensors or
/// neighbourhoods) and ST-DBSCAN walk cursors along the rows instead, as exactly but slower.
pub const TABLE_CELLS: usize = 8192;
/// The clustering's scratch, provided by its caller ([`Clusterer::cluster`]): the sort's
/// buckets, then the sweep's column tables.
pub type ColumnTables = [u16; TABLE_CELLS];

/// DBSCAN settings, in normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ClusterConfig {
    /// Neighbourhood radius in normalised coordinates (x / W, y / H).
    pub eps: f32,
    /// Fewest points in a neighbourhood (the point included) that make a core point.
    pub min_pts: u16,
    /// For ST-DBSCAN: the largest time difference between neighbours, as a fraction of the
    /// window's duration. `None` is plain spatial DBSCAN.
    pub eps_t: Option<f32>,
}

impl Default for ClusterConfig {
    fn default() -> Self {
        Self { eps: crate::config::DEFAULT_EPS, min_pts: crate::config::DEFAULT_MIN_PTS, eps_t: None }
    }
}

/// What one clustering run found and how much work it took.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ClusterStats {
    /// Events clustered.
    pub events: u16,
    /// Events beyond the clusterer's capacity, not clustered.
    pub overflow: u16,
    /// Clusters kept (at most the capacity `C`).
    pub clusters: u16,
    /// Clusters found beyond the capacity `C`; their events are labelled [`DROPPED`].
    pub dropped_clusters: u16,
    /// Core points.
    pub core: u16,
    /// Events labelled [`NOISE`].
    pub noise: u16,
    /// Neighbourhood queries made: pairwise distance checks, or, in the sweeps, spans of a
    /// neighbouring row looked up. The work of the clustering.
    pub distance_checks: u32,
}

/// A cluster's events after [`Clusterer::group`]: `events[start..end]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ClusterRange {
    /// First event of the cluster.
    pub start: u16,
    /// One past the last event of the cluster.
    pub end: u16,
}

/// DBSCAN's neighbourhood in exact integer arithmetic: events `a` and `b` are neighbours when
/// `(Δx/W)² + (Δy/H)² ≤ eps²`, evaluated as `Δx²·H² + Δy²·W² ≤ ⌊(eps·W·H)²⌋`, and, for
/// ST-DBSCAN, `|Δt| ≤ ⌊eps_t·T⌋` microseconds with `T` the window's duration.
///
/// Integers make the test exact and identical on every machine; the only rounding is of the
/// thresholds, once per window, in IEEE double precision (also identical everywhere).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Metric {
    h2: u64,
    w2: u64,
    threshold: u64,
    /// Largest |Δy| of any neighbour pair.
    reach_y: u64,
    dt_max: Option<u32>,
}

impl Metric {
    /// The neighbourhood for a sensor, a configuration and a window lasting `duration_us`.
    pub fn new(sensor: SensorSize, cfg: &ClusterConfig, duration_us: u32) -> Self {
        let w = u64::from(sensor.width.max(1));
        let h = u64::from(sensor.height.max(1));
        let eps = if cfg.eps.is_finite() && cfg.eps > 0.0 { f64::from(cfg.eps) } else { 0.0 };
        let side = eps * (w * h) as f64;
        // Float-to-integer casts saturate (and map NaN to 0): no overflow whatever eps is.
        let threshold = (side * side) as u64;
        let dt_max = match cfg.eps_t {
            Some(et) if et.is_finite() && et >= 0.0 => Some((f64::from(et) * f64::from(duration_us)) as u32),
            Some(_) => Some(0),
            None => None,
        };
        Self { h2: h * h, w2: w * w, threshold, reach_y: isqrt(threshold / (w * w)), dt_max }
    }

    /// Whether `a` and `b` are neighbours in space (eps).
    #[inline]
    fn near_in_space(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        let dy = u64::from(a.y.abs_diff(b.y));
        dy <= self.reach_y && u64::from(a.x.abs_diff(b.x)) <= self.span(dy)
    }

    /// Whether `a` and `b` are within eps of each other (and, for ST-DBSCAN, of eps_t).
    #[inline]
    pub fn neighbours(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        self.near_in_space(a, b) && self.near_in_time(a, b)
    }

    #[inline]
    fn near_in_time(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        self.dt_max.is_none_or(|m| a.dt_us.abs_diff(b.dt_us) <= m)
    }

    /// The largest |Δx| of a neighbour `dy` rows away (`dy ≤ reach_y`).
    #[inline]
    fn span(&self, dy: u64) -> u64 {
        // dy ≤ reach_y keeps dy²·W² within the threshold: no overflow.
        isqrt((self.threshold - dy * dy * self.w2) / self.h2)
    }
}

/// ⌊√x⌋, exactly.
fn isqrt(x: u64) -> u64 {
    let mut r = libm::sqrt(x as f64) as u64;
    while r > 0 && r.checked_mul(r).is_none_or(|q| q > x) {
        r -= 1;
    }
    while (r + 1).checked_mul(r + 1).is_some_and(|q| q <= x) {
        r += 1;
    }
    r
}

/// A pixel as the sort orders it: row, then column.
#[inline]
fn pixel(e: &WindowEvent) -> u32 {
    (u32::from(e.y) << 16) | u32::from(e.x)
}

/// The order [`Clusterer::cluster`] sorts events into: by pixel (row, column), then time.
#[inline]
pub fn pixel_order(e: &WindowEvent) -> u64 {
    (u64::from(pixel(e)) << 32) | u64::from(e.dt_us)
}

/// Sorts events into [`pixel_order`] in place, in time linear in the events for the short
/// rows of an event window: rows are bucketed by an in-place radix pass on each byte of the
/// row (American flag sort), then each row is sorted by column and time, by insertion when
/// short (the usual case) and by the library's sort otherwise.
pub fn sort_by_pixel(events: &mut [WindowEvent]) {
    let mut high = [0u16; 257];
    flag_pass(events, |e| (e.y >> 8) as u8, &mut high);
    let mut low = [0u16; 257];
    for h in 0..256 {
        let (a, b) = (usize::from(high[h]), usize::from(high[h + 1]));
        let Some(part) = events.get_mut(a..b) else { continue };
        if part.len() < 2 {
            continue;
        }
        flag_pass(part, |e| e.y as u8, &mut low);
        for l in 0..256 {
            let Some(row) = part.get_mut(usize::from(low[l])..usize::from(low[l + 1])) else { continue };
            if row.len() <= 24 {
                insertion_sort(row);
            } else {
                row.sort_unstable_by_key(pixel_order);
            }
        }
    }
}

/// Most distinct columns, and rows, that [`sort_in_time_by_pixel`] counts events in (a power
/// of two).
const SORT_BUCKETS: usize = 1024;
const _: () = assert!(SORT_BUCKETS.is_power_of_two());

/// Sorts events that are in time order into [`pixel_order`], as [`sort_by_pixel`] does but
/// in fewer steps: a stable counting sort by column, then by row, so that the events of a
/// pixel stay in time order. `order` and `pos` (at least one entry per event) are scratch.
/// Returns the events' least and greatest column and row (`[min_x, max_x, min_y, max_y]`),
/// which its counting finds on the way, and their latest time, or `None`, having done nothing, when the events are
/// fewer than two or not in time order, a column or row is beyond [`SORT_BUCKETS`], or the
/// scratch is short.
// Kept out of line: inlined, it costs its caller's loops more than the call (measured on
// the Cortex-M4F).
#[inline(never)]
fn sort_in_time_by_pixel(events: &mut [WindowEvent], order: &mut [u16], pos: &mut [u16]) -> Option<([u16; 4], u32)> {
    let n = events.len();
    if n < 2 || n > usize::from(u16::MAX) {
        return None;
    }
    let (order, pos) = (order.get_mut(..n)?, pos.get_mut(..n)?);
    // The events of each column and of each row are counted in one pass (column `x` in
    // bucket `x + 1`), which also checks the time order: the bounds then follow from the
    // counts, without a pass of their own.
    let mut next = [0u16; SORT_BUCKETS + 1];
    let mut by_row = [0u16; SORT_BUCKETS + 1];
    // Steps forward in time, counted rather than and-ed together: a compare and an add.
    let (mut forward, mut latest) = (0u32, 0u32);
    for e in events.iter() {
        forward = forward.wrapping_add(u32::from(e.dt_us >= latest));
        latest = e.dt_us;
        let (bx, by) = (usize::from(e.x) + 1, usize::from(e.y) + 1);
        if bx > SORT_BUCKETS || by > SORT_BUCKETS {
            return None;
        }
        next[bx] = next[bx].wrapping_add(1);
        by_row[by] = by_row[by].wrapping_add(1);
    }
    if forward as usize != n {
        return None;
    }
    // Some bucket of each holds the events (n > 0): the searches find one.
    let first = |c: &[u16; SORT_BUCKETS + 1]| c.iter().position(|&k| k != 0).unwrap_or(1).saturating_sub(1);
    let last = |c: &[u16; SORT_BUCKETS + 1]| c.iter().rposition(|&k| k != 0).unwrap_or(1).saturating_sub(1);
    let (min_x, max_x, min_y, max_y) = (first(&next), last(&next), first(&by_row), last(&by_row));
    // `order` lists the events by column, in time within one.
    for b in min_x + 1..=max_x + 1 {
        next[b] = next[b].wrapping_add(next[b - 1]);
    }
    // Every column and row is below `SORT_BUCKETS` (checked above), a power of two: the masks
    // keep them as they are and spare the bounds checks.
    for (i, e) in events.iter().enumerate() {
        debug_assert!(usize::from(e.x) < SORT_BUCKETS, "column {} beyond the sort's buckets", e.x);
        let b = &mut next[usize::from(e.x) & (SORT_BUCKETS - 1)];
        order[usize::from(*b)] = i as u16;
        *b = b.wrapping_add(1);
    }
    // Taken by row in that order, each event's place in the result.
    let next = &mut by_row;
    for b in min_y + 1..=max_y + 1 {
        next[b] = next[b].wrapping_add(next[b - 1]);
    }
    for &i in order.iter() {
        let i = usize::from(i);
        debug_assert!(usize::from(events[i].y) < SORT_BUCKETS, "row {} beyond the sort's buckets", events[i].y);
        let b = &mut next[usize::from(events[i].y) & (SORT_BUCKETS - 1)];
        pos[i] = *b;
        *b = b.wrapping_add(1);
    }
    // Each cycle of the permutation in one go: the event carried is put in its place and the
    // one there taken up, until the cycle closes (a load and a store per event, where
    // swapping into place moved each event and its place twice).
    for i in 0..n {
        let mut j = usize::from(pos[i]);
        if j == i {
            continue;
        }
        let mut carried = events[i];
        pos[i] = i as u16;
        while j != i {
            let (Some(slot), Some(p)) = (events.get_mut(j), pos.get_mut(j)) else { break };
            carried = core::mem::replace(slot, carried);
            j = usize::from(core::mem::replace(p, j as u16));
        }
        events[i] = carried;
    }
    Some(([min_x as u16, max_x as u16, min_y as u16, max_y as u16], latest))
}

/// One in-place radix pass: reorders `events` by `key` and writes the 256 buckets'
/// boundaries (`bounds[k]..bounds[k + 1]`). `events` holds fewer than 65 536 events.
fn flag_pass(events: &mut [WindowEvent], key: impl Fn(&WindowEvent) -> u8, bounds: &mut [u16; 257]) {
    let mut count = [0u16; 256];
    for e in events.iter() {
        let k = usize::from(key(e));
        count[k] = count[k].wrapping_add(1);
    }
    let mut next = [0u16; 256];
    let mut at = 0u16;
    for k in 0..256 {
        bounds[k] = at;
        next[k] = at;
        at = at.wrapping_add(count[k]);
    }
    bounds[256] = at;
    for k in 0..256 {
        let end = usize::from(bounds[k + 1]);
        while usize::from(next[k]) < end {
            let i = usize::from(next[k]);
            let target = usize::from(key(&events[i]));
            if target == k {
                next[k] += 1;
            } else {
                // Each swap puts one event in its bucket for good, so this ends.
                let j = usize::from(next[target]);
                events.swap(i, j);
                next[target] += 1;
            }
        }
    }
}

fn insertion_sort(row: &mut [WindowEvent]) {
    for i in 1..row.len() {
        let e = row[i];
        let key = pixel_order(&e);
        let mut j = i;
        while j > 0 && pixel_order(&row[j - 1]) > key {
            row[j] = row[j - 1];
            j -= 1;
        }
        row[j] = e;
    }
}

/// A run of events sharing one pixel row, `events[start..end]`, sorted by column.
#[derive(Clone, Copy, Default)]
struct Row {
    y: u16,
    start: u16,
    end: u16,
}

/// The rows of the sorted events, each with the rows at most `reach` above it: the pairs of
/// rows that can hold neighbours. Rows come in order; the window of recent rows is fixed.
struct Rows {
    reach: usize,
    at: usize,
    recent: [Row; MAX_REACH_ROWS + 1],
    len: usize,
}

impl Rows {
    fn new(reach: usize) -> Self {
        Self { reach, at: 0, recent: [Row::default(); MAX_REACH_ROWS + 1], len: 0 }
    }

    /// The next row, and the earlier rows within reach of it (nearest last). `None` at the
    /// end.
    fn next(&mut self, events: &[WindowEvent]) -> Option<(Row, &[Row])> {
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

/// Most rows whose column tables are kept at once: those within reach of the row being
/// linked, and of the rows being counted ahead of it.
const SLOTS: usize = 3 * MAX_REACH_ROWS + 1;

/// Column tables of the rows around the rows being visited. The table of a row maps a column
/// `c` (shifted by `pad`, the widest span, so that every lookup stays inside) to the index of
/// the row's first event at column `c` or beyond, the row's end where there is none. Over a
/// span of columns, the difference of two lookups counts the row's events in it, and the
/// first lookup is the lowest-index one.
///
/// Rows are built ahead of their visits into slot `y mod (3·reach + 1)`, which only rows
/// more than `3·reach` below can take over: by then neither the row being linked nor the
/// rows being counted (at most `reach` below it) can reach it.
struct Tables<'c> {
    cells: &'c mut [u16; TABLE_CELLS],
    /// Row held by each slot and its table's start (past the padding) in the cells, as
    /// `row << CELL_BITS | start` ([`NO_ROW`]: none yet), three times over, so that a slot
    /// shifted by a row distance needs no wrapping; and its events.
    lut: [u32; 3 * SLOTS],
    rows: [Row; SLOTS],
    slots: usize,
    stride: usize,
    min_x: u16,
    pad: usize,
    /// First event of the next row to build.
    next: usize,
}

/// The entry of a slot of [`Tables`] that holds no row: its row, `NO_ROW >> CELL_BITS`, is
/// beyond every row and row distance.
const NO_ROW: u32 = u32::MAX;
/// Bits of a cell index in the entries of [`Tables`].
const CELL_BITS: u32 = 13;
const _: () = assert!(TABLE_CELLS <= 1 << CELL_BITS);

/// The column of no core point in [`Clusterer::link_row`]: any column is further from it than
/// any neighbourhood reaches.
const FAR_COLUMN: u32 = 0x8000_0000;

/// A row within reach in [`Tables`]: the offsets in the cells of the lookups for an event at
/// column offset 0 (the span's start and one past its end).
#[derive(Clone, Copy, Default)]
struct Near {
    lo: usize,
    hi: usize,
}

impl<'c> Tables<'c> {
    /// Tables for `reach` rows either side, events whose columns start at `min_x` and span
    /// `width`, and spans of at most `pad` columns either side; `None` when they do not fit
    /// in [`TABLE_CELLS`].
    fn new(cells: &'c mut [u16; TABLE_CELLS], reach: usize, min_x: u16, width: usize, pad: usize) -> Option<Self> {
        let slots = 3 * reach + 1;
        let stride = width + 2 * pad + 1;
        if slots > SLOTS || slots * stride > TABLE_CELLS {
            return None;
        }
        Some(Self {
            cells,
            lut: [NO_ROW; 3 * SLOTS],
            rows: [Row::default(); SLOTS],
            slots,
            stride,
            min_x,
            pad,
            next: 0,
        })
    }

    /// The cell at `i`. Every lookup is inside the tables by construction; the mask only
    /// spares the bounds check (`TABLE_CELLS` is a power of two).
    #[inline(always)]
    fn at(&self, i: usize) -> usize {
        debug_assert!(i < self.slots * self.stride, "lookup {i} outside the tables");
        usize::from(self.cells[i % TABLE_CELLS])
    }

    /// Builds the table of every row up to row `last`.
    #[inline(never)]
    fn build_to(&mut self, events: &[WindowEvent], last: u32) {
        while let Some(e) = events.get(self.next) {
            if u32::from(e.y) > last {
                break;
            }
            let (start, y) = (self.next, e.y);
            let slot = usize::from(y) % self.slots;
            let base = slot * self.stride;
            let entry = (u32::from(y) << CELL_BITS) | (base + self.pad) as u32;
            for k in 0..3 {
                if let Some(e) = self.lut.get_mut(slot + k * self.slots) {
                    *e = entry;
                }
            }
            // `slots · stride` cells fit (see `new`): the row's table is all there (were it
            // not, the sweep would stop building, and stay panic-free). The row's end is found
            // on the way.
            debug_assert!(base + self.stride <= TABLE_CELLS, "row {y}'s table beyond the cells");
            let Some(table) = self.cells.get_mut(base..base + self.stride) else {
                self.next = events.len();
                break;
            };
            let mut c = 0;
            let first = self.pad + 1;
            let mut end = start;
            while let Some(e) = events.get(end).filter(|e| e.y == y) {
                let to = usize::from(e.x.wrapping_sub(self.min_x)) + first;
                // Events of one pixel or of neighbouring columns (most of them) fill a cell
                // or none: no call for them.
                if to > c {
                    let v = end as u16;
                    if to == c + 1 {
                        if let Some(cell) = table.get_mut(c) {
                            *cell = v;
                        }
                    } else {
                        fill(table, c, to, v);
                    }
                    c = to;
                }
                end += 1;
            }
            self.next = end;
            self.rows[slot] = Row { y, start: start as u16, end: end as u16 };
            fill(table, c, self.stride, end as u16);
        }
    }

    /// How [`around`](Self::around) visits the row `d` rows from the one asked about (`|d|`
    /// within the reach), whose spans are `s` columns either side.
    fn offset(&self, d: i32, s: u16) -> Offset {
        // `slots` exceeds twice the reach: `slots + d` is positive.
        debug_assert!(2 * (d.unsigned_abs() as usize) < self.slots, "row distance {d} beyond the reach");
        Offset { d, shift: self.slots.wrapping_add_signed(d as isize), s: usize::from(s), above: usize::from(d < 0) }
    }

    /// Row `y` (built), and the built rows within reach of it, in `order`'s row distances,
    /// into `out`: returns how many, and how many of them are above row `y`.
    fn around(&self, y: u16, order: &[Offset], out: &mut [Near]) -> (Row, usize, usize) {
        let (mut len, mut above) = (0, 0);
        let own = usize::from(y) % self.slots;
        for o in order {
            // `own + shift` is below three times `slots`.
            debug_assert!(own + o.shift < 3 * self.slots, "slot {own} shifted by {} beyond the table", o.shift);
            let (Some(&entry), Some(near)) = (self.lut.get(own + o.shift), out.get_mut(len)) else {
                break;
            };
            if entry >> CELL_BITS != (i32::from(y) + o.d) as u32 {
                continue;
            }
            let base = (entry & ((1 << CELL_BITS) - 1)) as usize;
            *near = Near { lo: base - o.s, hi: base + o.s + 1 };
            len += 1;
            above += o.above;
        }
        (self.rows[own], len, above)
    }
}

/// A row distance as [`Tables::around`] uses it: the distance `d`, the slot shift
/// `slots + d`, the span `s` of a neighbourhood that many rows away, and whether the row is
/// above (1) or not (0).
#[derive(Clone, Copy, Default)]
struct Offset {
    d: i32,
    shift: usize,
    s: usize,
    above: usize,
}

/// Sets `cells[from..to]` (nothing when empty) to `v`, four at a time.
fn fill(cells: &mut [u16], from: usize, to: usize, v: u16) {
    if let Some(part) = cells.get_mut(from..to) {
        let mut quads = part.chunks_exact_mut(4);
        for q in &mut quads {
            q.copy_from_slice(&[v; 4]);
        }
        for c in quads.into_remainder() {
            *c = v;
        }
    }
}

/// Labels the events of `row` with their own index, marked [`CORE`] for core points: the
/// events within reach of each pixel, over the rows `near` (nearest first, until `min_pts`),
/// are two lookups in the tables a row. Returns the core points and the lookups made.
// Kept out of line: inside the sweep the loop shared the registers of the linking below and
// reloaded its values on every lookup.
#[inline(never)]
fn count_row(
    labels: &mut [u16],
    events: &[WindowEvent],
    t: &Tables,
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

/// For each event of `from` (in column order), the span of events of `to` within `s` columns
/// of it: `(index in from, lo, hi)`. Both rows are sorted by column, so the span slides.
fn spans(events: &[WindowEvent], from: Row, to: Row, s: u16) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
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
fn count_spans(events: &[WindowEvent], counts: &mut [u16], from: Row, to: Row, s: u16) {
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

/// DBSCAN over at most `N` events per run, keeping at most `C` clusters. All memory is
/// inline: a label per event and a range per cluster, `2N + 4C` bytes; the events and the
/// sort's scratch and sweep's tables ([`ColumnTables`], 16 KiB) are the caller's, so that
/// they are counted where the caller keeps them (a detector's static storage on the
/// device) rather than on the stack.
///
/// `N` must be below 32 766 (checked at compile time).
///
/// ```
/// use evcal_core::{cluster::{Clusterer, ClusterConfig, TABLE_CELLS}, event::SensorSize, window::WindowEvent};
/// let mut events = [WindowEvent { x: 10, y: 10, dt_us: 0 }; 12];
/// events[11] = WindowEvent { x: 200, y: 100, dt_us: 5 };
/// let mut c: Clusterer<16, 4> = Clusterer::new();
/// let mut tables = [0u16; TABLE_CELLS];
/// let stats = c.cluster(&mut events, SensorSize::DAVIS346, &ClusterConfig::default(), &mut tables);
/// assert_eq!((stats.clusters, stats.noise), (1, 1));
/// let ranges = c.group(&mut events);
/// assert_eq!(ranges.len(), 1);
/// assert_eq!(ranges[0].end - ranges[0].start, 11);
/// ```
#[derive(Debug, Clone)]
pub struct Clusterer<const N: usize, const C: usize> {
    labels: [u16; N],
    ranges: [ClusterRange; C],
    len: usize,
    clusters: usize,
}

impl<const N: usize, const C: usize> Default for Clusterer<N, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const C: usize> Clusterer<N, C> {
    const CHECK: () = assert!(N < 0x7FFE && C < 0x7FFE, "capacity out of range");

    /// An empty clusterer.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Self { labels: [0; N], ranges: [ClusterRange { start: 0, end: 0 }; C], len: 0, clusters: 0 }
    }

    /// Clusters `events` (at most `N`; the rest are counted as overflow and left out).
    /// Sorts `events` by pixel (row, column, then time); [`labels`](Self::labels) then gives
    /// each event's cluster (0-based), [`NOISE`] or [`DROPPED`].
    ///
    /// `tables` is the caller's scratch for the sort and the column tables of the sweep
    /// ([`ColumnTables`]): 16 KiB that would otherwise sit on the stack while this runs. Its
    /// content on entry does not matter.
    pub fn cluster(
        &mut self,
        events: &mut [WindowEvent],
        sensor: SensorSize,
        cfg: &ClusterConfig,
        tables: &mut ColumnTables,
    ) -> ClusterStats {
        let n = events.len().min(N);
        let mut stats =
            ClusterStats { events: n as u16, overflow: (events.len() - n).min(0xFFFF) as u16, ..Default::default() };
        let events = &mut events[..n];
        self.len = n;
        self.clusters = 0;
        // Scratch for the sort, then the column tables of the sweep: cleared, as a fresh
        // array would be, so that the result never depends on the previous window.
        tables.fill(0);
        let cells = tables;
        // Events in time order (a window's) end with the latest; the sort finds their bounds.
        let (duration, [min_x, max_x, _, _]) = match sort_in_time_by_pixel(events, &mut self.labels, cells) {
            Some((bounds, latest)) => (latest, bounds),
            None => {
                let (mut duration, mut min_x, mut max_x) = (0, u16::MAX, 0);
                for e in events.iter() {
                    duration = duration.max(e.dt_us);
                    min_x = min_x.min(e.x);
                    max_x = max_x.max(e.x);
                }
                sort_by_pixel(events);
                (duration, [min_x, max_x, 0, 0])
            }
        };
        let m = Metric::new(sensor, cfg, duration);
        let min_pts = usize::from(cfg.min_pts.max(1));
        let mut work: u32 = 0;
        if m.reach_y > MAX_REACH_ROWS as u64 {
            self.pairwise(events, &m, min_pts, &mut stats, &mut work);
        } else {
            let tables = match m.dt_max {
                None => self.by_tables(events, cells, &m, min_pts, (min_x, max_x), &mut stats),
                Some(_) => None,
            };
            match tables {
                Some(queries) => work = queries,
                None => self.by_rows(events, &m, min_pts, &mut stats, &mut work),
            }
        }
        // Every sweep ends in `settle_borders`, which leaves no `CORE` mark behind.
        stats.distance_checks = work;
        stats
    }

    /// Spatial DBSCAN by column tables (see [`Tables`]), in one sweep down the rows: tables
    /// are built `2·reach` rows ahead of the row being linked, core points counted `reach`
    /// rows ahead. Returns the neighbourhood queries made, or `None`, having done nothing,
    /// when the tables do not fit in `cells`.
    #[inline(never)]
    fn by_tables(
        &mut self,
        events: &[WindowEvent],
        cells: &mut [u16; TABLE_CELLS],
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
        let mut t = Tables::new(cells, reach, min_x, width, usize::from(span[0]))?;
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
    fn link_row(
        &mut self,
        events: &[WindowEvent],
        t: &Tables,
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
        for k in usize::from(row.start)..end {
            let ex = events[k].x;
            if self.labels[k] & CORE == 0 {
                let x = usize::from(ex.wrapping_sub(min_x));
                let mut best = NONE;
                for nr in near {
                    queries = queries.wrapping_add(1);
                    if let Some(j) = self.first_core(t.at(nr.lo + x), t.at(nr.hi + x)) {
                        best = j as u16;
                        break;
                    }
                }
                self.labels[k] = best;
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
    fn link_run(
        &mut self,
        events: &[WindowEvent],
        t: &Tables,
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

    /// DBSCAN over pairs of neighbouring rows (see the module's documentation).
    fn by_rows(
        &mut self,
        events: &[WindowEvent],
        m: &Metric,
        min_pts: usize,
        stats: &mut ClusterStats,
        work: &mut u32,
    ) {
        let n = events.len();
        let reach = m.reach_y as usize;
        let mut span = [0u16; MAX_REACH_ROWS + 1];
        for (dy, s) in span.iter_mut().enumerate().take(reach + 1) {
            *s = m.span(dy as u64).min(u64::from(u16::MAX)) as u16;
        }
        let near_t = |a: usize, b: usize| m.near_in_time(&events[a], &events[b]);
        let spatial = m.dt_max.is_none();

        // 1. Neighbour counts (in the labels for now), each pair of rows once.
        self.labels[..n].fill(0);
        let mut rows = Rows::new(reach);
        while let Some((b, above)) = rows.next(events) {
            for a in above.iter().chain(core::iter::once(&b)) {
                let s = span[usize::from(b.y - a.y)];
                let ways: &[(Row, Row)] = if a.y == b.y { &[(b, b)] } else { &[(b, *a), (*a, b)] };
                for &(from, to) in ways {
                    *work = work.wrapping_add(u32::from(from.end - from.start));
                    if spatial {
                        count_spans(events, &mut self.labels, from, to, s);
                    } else {
                        for (i, lo, hi) in spans(events, from, to, s) {
                            let c = (lo..hi).filter(|&j| near_t(i, j)).count();
                            self.labels[i] = self.labels[i].saturating_add(c.min(0xFFFF) as u16);
                        }
                    }
                }
            }
        }
        for i in 0..n {
            let core = usize::from(self.labels[i]) >= min_pts;
            stats.core += u16::from(core);
            self.labels[i] = i as u16 | if core { CORE } else { 0 };
        }

        // 2. Join core points that are neighbours, and find each border point's lowest-index
        //    core neighbour (the first core point of a span is the span's lowest; the lowest
        //    over all spans wins), in one sweep. A root is always its component's lowest
        //    index, so the numbering below does not depend on the union order. Border labels
        //    hold their best core neighbour's index meanwhile.
        for l in &mut self.labels[..n] {
            if *l & CORE == 0 {
                *l = NONE;
            }
        }
        let mut rows = Rows::new(reach);
        while let Some((b, above)) = rows.next(events) {
            // Within the row. In a spatial run each core point joins the next one to its
            // right when they are neighbours; that chain and the links below join every pair.
            for (i, lo, hi) in spans(events, b, b, span[0]) {
                *work = work.wrapping_add(1);
                if self.labels[i] & CORE == 0 {
                    self.border_candidate(events, i, lo, hi, m);
                } else if spatial {
                    if let Some(j) = (i + 1..hi).find(|&j| self.labels[j] & CORE != 0) {
                        self.union(i, j);
                    }
                } else {
                    for j in i + 1..hi {
                        if self.labels[j] & CORE != 0 && near_t(i, j) {
                            self.union(i, j);
                        }
                    }
                }
            }
            // With each row above. Every event of a span is a neighbour. In a spatial run,
            // joining a core point to its span's first and last core points is enough: a span
            // is at most twice the same-row reach wide, so at most one gap between
            // consecutive core points in it exceeds that reach, and the row's chain joins
            // each side of such a gap to an end.
            for a in above {
                let s = span[usize::from(b.y - a.y)];
                // Events of the row above before `offered` have been offered this row's
                // first core point within reach of them (spatial runs).
                let mut offered = usize::from(a.start);
                for (i, lo, hi) in spans(events, b, *a, s) {
                    *work = work.wrapping_add(1);
                    if self.labels[i] & CORE == 0 {
                        self.border_candidate(events, i, lo, hi, m);
                    } else if spatial {
                        if let Some(j) = (lo..hi).find(|&j| self.labels[j] & CORE != 0) {
                            self.union(i, j);
                            if let Some(k) = (j + 1..hi).rev().find(|&k| self.labels[k] & CORE != 0) {
                                self.union(i, k);
                            }
                        }
                        // The border points of the row above look down at this one: their
                        // lowest-index core neighbour here is the first core point (in
                        // index order) whose span holds them. Spans only move forward, so
                        // those not yet offered one are exactly the span's events from
                        // `offered` on.
                        for j in lo.max(offered)..hi {
                            if self.labels[j] & CORE == 0 {
                                *work = work.wrapping_add(1);
                                if i < usize::from(self.labels[j]) {
                                    self.labels[j] = i as u16;
                                }
                            }
                        }
                        offered = offered.max(hi);
                    } else {
                        for j in lo..hi {
                            if self.labels[j] & CORE != 0 && near_t(i, j) {
                                self.union(i, j);
                            }
                        }
                    }
                }
                if !spatial {
                    // The border points of the row above look down at this one.
                    for (i, lo, hi) in spans(events, *a, b, s) {
                        if self.labels[i] & CORE == 0 {
                            *work = work.wrapping_add(1);
                            self.border_candidate(events, i, lo, hi, m);
                        }
                    }
                }
            }
        }
        self.number(n, stats);
        self.settle_borders(n, stats);
    }

    /// Offers border point `i` the first core neighbour in `events[lo..hi]` (a span of its
    /// neighbours in space) that comes before its best so far.
    #[inline]
    fn border_candidate(&mut self, events: &[WindowEvent], i: usize, lo: usize, hi: usize, m: &Metric) {
        let best = usize::from(self.labels[i]);
        let e = events[i];
        if let Some(j) = (lo..hi.min(best)).find(|&j| self.labels[j] & CORE != 0 && m.near_in_time(&e, &events[j])) {
            self.labels[i] = j as u16;
        }
    }

    /// DBSCAN by comparing every pair of events: for neighbourhoods too wide for the row sweep.
    fn pairwise(
        &mut self,
        events: &[WindowEvent],
        m: &Metric,
        min_pts: usize,
        stats: &mut ClusterStats,
        work: &mut u32,
    ) {
        let n = events.len();
        for i in 0..n {
            *work = work.wrapping_add(n as u32);
            let core = events.iter().filter(|o| m.neighbours(&events[i], o)).count() >= min_pts;
            stats.core += u16::from(core);
            self.labels[i] = i as u16 | if core { CORE } else { 0 };
        }
        for i in 0..n {
            if self.labels[i] & CORE == 0 {
                continue;
            }
            for j in i + 1..n {
                if self.labels[j] & CORE != 0 && m.neighbours(&events[i], &events[j]) {
                    self.union(i, j);
                }
            }
        }
        self.number(n, stats);
        for i in 0..n {
            if self.labels[i] & CORE == 0 {
                let best = (0..n).find(|&j| self.labels[j] & CORE != 0 && m.neighbours(&events[i], &events[j]));
                self.labels[i] = best.map_or(NONE, |j| j as u16);
            }
        }
        self.settle_borders(n, stats);
    }

    /// 3. Numbers the clusters in index order. A core point's parent has a lower index and so
    ///    already holds its component's label. Core labels become `cluster | CORE`.
    #[inline(never)]
    fn number(&mut self, n: usize, stats: &mut ClusterStats) {
        let mut clusters: usize = 0;
        let mut found: usize = 0;
        let labels = &mut self.labels[..n.min(N)];
        for i in 0..labels.len() {
            let l = labels[i];
            if l & CORE == 0 {
                continue;
            }
            let p = usize::from(l & MASK);
            // A parent is below its child, a root its own parent.
            debug_assert!(p <= i, "core point {i}'s parent {p} is above it");
            let label = if p < i {
                labels[p] & MASK
            } else {
                found += 1;
                if clusters < C {
                    clusters += 1;
                    (clusters - 1) as u16
                } else {
                    DROPPED
                }
            };
            labels[i] = label | CORE;
        }
        self.clusters = clusters;
        stats.clusters = clusters as u16;
        stats.dropped_clusters = (found - clusters).min(0xFFFF) as u16;
    }

    /// Turns each border point's best core neighbour (an index, or [`NONE`]) into that core
    /// point's cluster, or noise, and each core point's label into its cluster (unmarked).
    #[inline(never)]
    fn settle_borders(&mut self, n: usize, stats: &mut ClusterStats) {
        let labels = &mut self.labels[..n.min(N)];
        for i in 0..labels.len() {
            let l = labels[i];
            if l & CORE != 0 {
                // Border points after this one read its cluster below, marked or not.
                labels[i] = l & MASK;
                continue;
            }
            labels[i] = match labels.get(usize::from(l)).filter(|_| l != NONE) {
                Some(&core) => core & MASK,
                None => {
                    stats.noise += 1;
                    NOISE
                }
            };
        }
    }

    /// The label of each event of the last [`cluster`](Self::cluster) run, in the events'
    /// reordered order.
    pub fn labels(&self) -> &[u16] {
        &self.labels[..self.len]
    }

    /// Reorders the events of the last run so that each cluster's events are contiguous, in
    /// cluster order, with noise and dropped events after them; returns the clusters'
    /// ranges. `events` must be the slice given to [`cluster`](Self::cluster), unchanged
    /// since; otherwise (a different length) nothing is grouped.
    pub fn group(&mut self, events: &mut [WindowEvent]) -> &[ClusterRange] {
        let n = self.len;
        if events.len() < n {
            return &[];
        }
        let events = &mut events[..n];
        let k = self.clusters.min(C);
        // Counting sort by label, in place: region c < k holds cluster c, region k the rest
        // (noise and dropped events, labels beyond the clusters), in whatever order its
        // events are left in.
        let mut sizes = [0u16; C];
        for &l in &self.labels[..n] {
            if let Some(s) = sizes.get_mut(usize::from(l)) {
                *s = s.wrapping_add(1);
            }
        }
        // The fill pointer of each region, and of the rest.
        let mut next = [0u16; C];
        let mut at = 0u16;
        for c in 0..k {
            next[c] = at;
            self.ranges[c] = ClusterRange { start: at, end: at.wrapping_add(sizes[c]) };
            at = at.wrapping_add(sizes[c]);
        }
        let mut tail = at;
        let labels = &mut self.labels[..n];
        for r in 0..k {
            let end = usize::from(self.ranges[r].end);
            // `next[r]` moves on past the events that cycles started before put in place.
            let mut fill = usize::from(next[r]);
            while fill < end {
                let l = labels[fill];
                if usize::from(l) != r {
                    // The event at `fill` goes to its region's fill pointer and the one there
                    // is carried on, until one of region `r` comes up: the swaps of events
                    // into place one at a time, with the carried event kept out of memory
                    // in between (each event moved once, not twice).
                    let (mut carried, mut carried_label) = (events[fill], l);
                    loop {
                        let g = usize::from(carried_label);
                        let p = if g < k { &mut next[g] } else { &mut tail };
                        let d = usize::from(*p);
                        *p = p.wrapping_add(1);
                        // Each move puts one event in its final region, so this ends; `d` is
                        // below `n` (every region's pointer stays within it).
                        debug_assert!(d < n, "region {g}'s fill pointer {d} beyond the {n} events");
                        let (Some(slot), Some(slot_label)) = (events.get_mut(d), labels.get_mut(d)) else { break };
                        carried = core::mem::replace(slot, carried);
                        carried_label = core::mem::replace(slot_label, carried_label);
                        if usize::from(carried_label) == r {
                            break;
                        }
                    }
                    events[fill] = carried;
                    labels[fill] = carried_label;
                }
                fill += 1;
            }
        }
        &self.ranges[..k]
    }

    /// The clusters' ranges as the last [`group`](Self::group) or [`merge`](Self::merge) left
    /// them.
    pub fn ranges(&self) -> &[ClusterRange] {
        &self.ranges[..self.clusters]
    }

    /// Merges clusters, then groups again: cluster `c` of the last grouping joins cluster
    /// `into[c]` (`into[c] <= c`; chains are followed). The merged clusters are numbered in the
    /// order of their first member and made contiguous as [`group`](Self::group) does;
    /// returns their ranges. Entries beyond the current clusters are ignored.
    pub fn merge(&mut self, events: &mut [WindowEvent], into: &[u16]) -> &[ClusterRange] {
        let k = self.clusters;
        // New number of each old cluster: roots get the next number, members their root's.
        let mut renumber = [0u16; C];
        let mut next = 0u16;
        for c in 0..k {
            let target = into.get(c).map_or(c, |&t| usize::from(t));
            if target >= c {
                renumber[c] = next;
                next += 1;
            } else {
                renumber[c] = renumber[target];
            }
        }
        for l in &mut self.labels[..self.len] {
            if let Some(&r) = renumber.get(usize::from(*l)).filter(|_| usize::from(*l) < k) {
                *l = r;
            }
        }
        self.clusters = usize::from(next);
        self.group(events)
    }

    fn find(&mut self, mut i: usize) -> usize {
        loop {
            let p = usize::from(self.labels[i] & MASK);
            if p == i {
                return i;
            }
            let gp = usize::from(self.labels[p] & MASK);
            // Path halving keeps trees shallow without recursion or a stack.
            self.labels[i] = (self.labels[i] & CORE) | gp as u16;
            i = gp;
        }
    }

    // Inlined: a call per link cost more than the link itself (most links join points
    // already in one set).
    #[inline(always)]
    fn union(&mut self, a: usize, b: usize) {
        let (la, lb) = (self.labels[a] & MASK, self.labels[b] & MASK);
        // Most links join points already in one set, often through the same parent.
        if la == lb {
            return;
        }
        // A root is its set's lowest index, so a root above the other point's parent can
        // hang from that parent (lower than it) without a search: the usual case of a core
        // point met for the first time, by the previous one in its row.
        if usize::from(lb) == b && a < b {
            self.labels[b] = CORE | la;
        } else if usize::from(la) == a && b < a {
            self.labels[a] = CORE | lb;
        } else {
            self.union_roots(a, b);
        }
    }

    fn union_roots(&mut self, a: usize, b: usize) {
        let ra = self.find(a);
        let rb = self.find(b);
        if ra == rb {
            return;
        }
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        self.labels[hi] = (self.labels[hi] & CORE) | lo as u16;
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    /// Textbook DBSCAN, O(n^2), breadth-first expansion: the reference the hashed version
    /// must equal. Same conventions: core when |N_eps| (self included) >= min_pts; border
    /// points join the lowest-index core neighbour's cluster; clusters numbered by their
    /// lowest-index core point.
    fn brute_force(events: &[WindowEvent], sensor: SensorSize, cfg: &ClusterConfig) -> Vec<u16> {
        let n = events.len();
        let duration = events.iter().map(|e| e.dt_us).max().unwrap_or(0);
        let metric = Metric::new(sensor, cfg, duration);
        let near = |a: &WindowEvent, b: &WindowEvent| metric.neighbours(a, b);
        let core: Vec<bool> =
            (0..n).map(|i| (0..n).filter(|&j| near(&events[i], &events[j])).count() >= cfg.min_pts as usize).collect();
        let mut comp = vec![u16::MAX; n];
        let mut next = 0u16;
        for i in 0..n {
            if !core[i] || comp[i] != u16::MAX {
                continue;
            }
            let mut queue = std::collections::VecDeque::from([i]);
            comp[i] = next;
            while let Some(p) = queue.pop_front() {
                for q in 0..n {
                    if core[q] && comp[q] == u16::MAX && near(&events[p], &events[q]) {
                        comp[q] = next;
                        queue.push_back(q);
                    }
                }
            }
            next += 1;
        }
        (0..n)
            .map(|i| {
                if core[i] {
                    comp[i]
                } else {
                    (0..n).find(|&j| core[j] && near(&events[i], &events[j])).map_or(NOISE, |j| comp[j])
                }
            })
            .collect()
    }

    fn ring(cx: f32, cy: f32, r: f32, k: usize, t0: u32, seed: u32) -> Vec<WindowEvent> {
        let mut s = seed;
        (0..k)
            .map(|i| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let a = i as f32 * 0.37 + (s >> 8) as f32 * 1e-7;
                WindowEvent {
                    x: (cx + r * libm::cosf(a)).round() as u16,
                    y: (cy + r * libm::sinf(a)).round() as u16,
                    dt_us: t0 + i as u32 * 7,
                }
            })
            .collect()
    }

    fn check_equal<const N: usize, const C: usize>(
        input: &[WindowEvent],
        sensor: SensorSize,
        cfg: &ClusterConfig,
    ) -> ClusterStats {
        let mut events = input.to_vec();
        let mut c: Clusterer<N, C> = Clusterer::new();
        let stats = c.cluster(&mut events, sensor, cfg, &mut [0; TABLE_CELLS]);
        // Reordering is a permutation of the input.
        let mut a = input.to_vec();
        let mut b = events.clone();
        let key = |e: &WindowEvent| (e.x, e.y, e.dt_us);
        a.sort_by_key(key);
        b.sort_by_key(key);
        assert_eq!(a, b);
        let reference = brute_force(&events, sensor, cfg);
        let got: Vec<u16> = c.labels().to_vec();
        let clamp = |l: u16| if l != NOISE && usize::from(l) >= C { DROPPED } else { l };
        let reference: Vec<u16> = reference.into_iter().map(clamp).collect();
        assert_eq!(got, reference);
        stats
    }

    #[test]
    fn two_rings_and_noise() {
        let sensor = SensorSize::DAVIS346;
        let mut ev = ring(50.0, 60.0, 6.0, 80, 0, 1);
        ev.extend(ring(150.0, 60.0, 6.0, 80, 3, 2));
        ev.extend([WindowEvent { x: 300, y: 200, dt_us: 9 }, WindowEvent { x: 5, y: 250, dt_us: 11 }]);
        let stats = check_equal::<256, 8>(&ev, sensor, &ClusterConfig::default());
        assert_eq!((stats.clusters, stats.noise, stats.dropped_clusters), (2, 2, 0));
    }

    #[test]
    fn capacity_overflow_is_counted() {
        let sensor = SensorSize::DAVIS346;
        let mut ev = Vec::new();
        for k in 0..5u16 {
            // a dense 5 x 8 blob: one cluster each
            ev.extend((0..40u16).map(|i| WindowEvent { x: 30 + 60 * k + i % 5, y: 100 + i / 5, dt_us: u32::from(i) }));
        }
        let stats = check_equal::<512, 3>(&ev, sensor, &ClusterConfig::default());
        assert_eq!((stats.clusters, stats.dropped_clusters), (3, 2));

        let mut small = ev.clone();
        let mut c: Clusterer<100, 8> = Clusterer::new();
        let s = c.cluster(&mut small, sensor, &ClusterConfig::default(), &mut [0; TABLE_CELLS]);
        assert_eq!((s.events, s.overflow), (100, 100));
    }

    #[test]
    fn spatio_temporal_splits_in_time() {
        let sensor = SensorSize::DAVIS346;
        // The same place visited early and late in the window: one cluster in space, two in
        // space-time.
        let mut ev = ring(100.0, 100.0, 5.0, 60, 0, 3);
        ev.extend(ring(100.0, 100.0, 5.0, 60, 30_000, 4));
        let plain = check_equal::<256, 8>(&ev, sensor, &ClusterConfig::default());
        assert_eq!(plain.clusters, 1);
        let st = ClusterConfig { eps_t: Some(0.1), ..Default::default() };
        let split = check_equal::<256, 8>(&ev, sensor, &st);
        assert_eq!(split.clusters, 2);
    }

    #[test]
    fn default_neighbourhood_on_a_davis346_takes_the_tables() {
        let m = Metric::new(SensorSize::DAVIS346, &ClusterConfig::default(), 1000);
        let mut cells = [0u16; TABLE_CELLS];
        let reach = m.reach_y as usize;
        assert!(Tables::new(&mut cells, reach, 0, 346, m.span(0) as usize).is_some());
    }

    #[test]
    fn group_makes_clusters_contiguous() {
        let sensor = SensorSize::DAVIS346;
        let mut ev = ring(50.0, 60.0, 6.0, 70, 0, 5);
        ev.extend(ring(150.0, 160.0, 8.0, 90, 0, 6));
        ev.extend(ring(250.0, 60.0, 4.0, 50, 0, 7));
        ev.push(WindowEvent { x: 340, y: 5, dt_us: 0 });
        let mut c: Clusterer<512, 8> = Clusterer::new();
        let stats = c.cluster(&mut ev, sensor, &ClusterConfig::default(), &mut [0; TABLE_CELLS]);
        let labels_before: Vec<u16> = c.labels().to_vec();
        let ranges = c.group(&mut ev).to_vec();
        assert_eq!(ranges.len(), usize::from(stats.clusters));
        let mut covered = 0;
        for (k, r) in ranges.iter().enumerate() {
            for l in &c.labels()[usize::from(r.start)..usize::from(r.end)] {
                assert_eq!(usize::from(*l), k);
            }
            covered += r.end - r.start;
        }
        for l in &c.labels()[usize::from(covered)..] {
            assert!(*l == NOISE || *l == DROPPED);
        }
        let mut a = labels_before.clone();
        let mut b = c.labels().to_vec();
        a.sort();
        b.sort();
        assert_eq!(a, b, "grouping is a permutation");
    }

    fn arb_events(max_len: usize, w: u16, h: u16) -> impl Strategy<Value = Vec<WindowEvent>> {
        // Clumps around a few centres so that clusters, borders and noise all occur.
        let centres = prop::collection::vec((0..w, 0..h), 1..6);
        (centres, prop::collection::vec((any::<u8>(), -9i16..=9, -9i16..=9, 0u32..40_000), 0..max_len)).prop_map(
            move |(cs, pts)| {
                pts.into_iter()
                    .map(|(k, dx, dy, t)| {
                        let (cx, cy) = cs[usize::from(k) % cs.len()];
                        WindowEvent {
                            x: (cx as i32 + dx as i32).clamp(0, w as i32 - 1) as u16,
                            y: (cy as i32 + dy as i32).clamp(0, h as i32 - 1) as u16,
                            dt_us: t,
                        }
                    })
                    .collect()
            },
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn radix_sort_sorts(raw in prop::collection::vec((any::<u16>(), 0u16..700, 0u32..50), 0..2000)) {
            let mut ev: Vec<WindowEvent> = raw.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            let mut want = ev.clone();
            want.sort_by_key(pixel_order);
            sort_by_pixel(&mut ev);
            prop_assert_eq!(ev, want);
        }

        #[test]
        fn counting_sort_sorts_events_in_time(raw in prop::collection::vec((0u16..1100, 0u16..700, 0u32..50), 0..2000)) {
            let mut ev: Vec<WindowEvent> = raw.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            ev.sort_by_key(|e| e.dt_us);
            let mut want = ev.clone();
            want.sort_by_key(pixel_order);
            let bounds = [
                ev.iter().map(|e| e.x).min().unwrap_or(0),
                ev.iter().map(|e| e.x).max().unwrap_or(0),
                ev.iter().map(|e| e.y).min().unwrap_or(0),
                ev.iter().map(|e| e.y).max().unwrap_or(0),
            ];
            let (mut order, mut pos) = (vec![0u16; ev.len()], vec![0u16; ev.len()]);
            let before = ev.clone();
            match sort_in_time_by_pixel(&mut ev, &mut order, &mut pos) {
                Some((found, latest)) => {
                    prop_assert_eq!(ev, want);
                    prop_assert_eq!(found, bounds);
                    prop_assert_eq!(latest, before.last().map_or(0, |e| e.dt_us));
                }
                None => prop_assert_eq!(ev, before),
            }
        }

        #[test]
        fn wide_neighbourhoods_equal_brute_force(
            ev in arb_events(150, 346, 260),
            eps in 0.12f32..0.6,
            min_pts in 1u16..30,
            st in prop::option::of(0.01f32..0.5),
        ) {
            let cfg = ClusterConfig { eps, min_pts, eps_t: st };
            check_equal::<150, 16>(&ev, SensorSize::DAVIS346, &cfg);
        }

        #[test]
        fn sweep_equals_brute_force(
            ev in arb_events(400, 346, 260),
            eps in 0.005f32..0.05,
            min_pts in 1u16..15,
            st in prop::option::of(0.01f32..0.5),
        ) {
            let cfg = ClusterConfig { eps, min_pts, eps_t: st };
            // Few cluster slots force dropped clusters; more keep them all.
            check_equal::<400, 16>(&ev, SensorSize::DAVIS346, &cfg);
            check_equal::<400, 64>(&ev, SensorSize::DAVIS346, &cfg);
            // In time order, as windows come, the events take the counting sort.
            let mut timed = ev.clone();
            timed.sort_by_key(|e| e.dt_us);
            check_equal::<400, 64>(&timed, SensorSize::DAVIS346, &cfg);
        }

        #[test]
        fn sweep_equals_brute_force_large_sensor(ev in arb_events(300, 1280, 720), min_pts in 1u16..12) {
            let cfg = ClusterConfig { min_pts, ..Default::default() };
            check_equal::<300, 64>(&ev, SensorSize::new(1280, 720), &cfg);
        }

        #[test]
        fn arbitrary_input_never_panics(
            raw in prop::collection::vec((any::<u16>(), any::<u16>(), any::<u32>()), 0..300),
            w in any::<u16>(), h in any::<u16>(),
            eps in any::<f32>(), min_pts in any::<u16>(), st in prop::option::of(any::<f32>()),
        ) {
            let mut ev: Vec<WindowEvent> = raw.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            let mut c: Clusterer<256, 8> = Clusterer::new();
            let stats = c.cluster(&mut ev, SensorSize::new(w, h), &ClusterConfig { eps, min_pts, eps_t: st }, &mut [0; TABLE_CELLS]);
            prop_assert_eq!(usize::from(stats.events) + usize::from(stats.overflow), ev.len());
            let ranges = c.group(&mut ev).to_vec();
            prop_assert_eq!(ranges.len(), usize::from(stats.clusters));
        }
    }
}
