//! The column tables of the spatial sweep: for each row within reach, a table from column
//! to the index of the row's first event at or right of it.

use super::{rows::Row, MAX_REACH_ROWS};
use crate::window::WindowEvent;

/// Cells (`u16`, 16 KiB, in the caller's scratch: the detector's `Scratch`) of the column
/// tables of the spatial sweep, by default (a detector's `CELLS` may be larger, up to
/// [`MAX_TABLE_CELLS`], where the board has the memory): one table per row within reach of the row being visited,
/// above and below, each as wide as the events' columns plus the neighbourhood either side. The
/// defaults on a DAVIS346 take 7 rows of 357 cells. Sweeps that need more (wider sensors or
/// neighbourhoods) and ST-DBSCAN walk cursors along the rows instead, as exactly but slower.
pub const TABLE_CELLS: usize = 8192;
/// The clustering's scratch, provided by its caller
/// ([`Clusterer::cluster`](super::Clusterer::cluster)): the sort's buckets, then the sweep's
/// column tables.
pub type ColumnTables = [u16; TABLE_CELLS];

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
pub(super) struct Tables<'c, const CELLS: usize> {
    cells: &'c mut [u16; CELLS],
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
/// beyond every row and row distance that [`Tables::new`] takes (see [`LAST_ROW`]).
const NO_ROW: u32 = u32::MAX;
/// Bits of a cell index in the entries of [`Tables`]: tables of up to 65 536 cells.
const CELL_BITS: u32 = 16;
/// The last row whose neighbourhoods the tables hold: rows and row distances stay below
/// `NO_ROW`'s row, so that a slot holding no row is never taken for one.
const LAST_ROW: usize = (NO_ROW >> CELL_BITS) as usize - 1 - MAX_REACH_ROWS;
/// The most cells tables may have: their starts are kept in 16 bits of each slot's entry.
pub const MAX_TABLE_CELLS: usize = 1 << CELL_BITS;
const _: () = assert!(TABLE_CELLS <= MAX_TABLE_CELLS && TABLE_CELLS.is_power_of_two());

/// A row within reach in [`Tables`]: the offsets in the cells of the lookups for an event at
/// column offset 0 (the span's start and one past its end).
#[derive(Clone, Copy, Default)]
pub(super) struct Near {
    pub(super) lo: usize,
    pub(super) hi: usize,
}

impl<'c, const CELLS: usize> Tables<'c, CELLS> {
    const CHECK: () =
        assert!(CELLS <= MAX_TABLE_CELLS && CELLS.is_power_of_two(), "cells: a power of two up to 65 536");

    /// Tables for `reach` rows either side, events whose columns start at `min_x` and span
    /// `width`, and spans of at most `pad` columns either side; `None` when they do not fit
    /// in [`TABLE_CELLS`].
    pub(super) fn new(
        cells: &'c mut [u16; CELLS],
        reach: usize,
        min_x: u16,
        width: usize,
        pad: usize,
        last_row: u16,
    ) -> Option<Self> {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        let slots = 3 * reach + 1;
        let stride = width + 2 * pad + 1;
        if slots > SLOTS || slots * stride > CELLS || usize::from(last_row) > LAST_ROW {
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
    /// spares the bounds check (`CELLS` is a power of two).
    #[inline(always)]
    pub(super) fn at(&self, i: usize) -> usize {
        debug_assert!(i < self.slots * self.stride, "lookup {i} outside the tables");
        usize::from(self.cells[i % CELLS])
    }

    /// Builds the table of every row up to row `last`.
    #[inline(never)]
    pub(super) fn build_to(&mut self, events: &[WindowEvent], last: u32) {
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
            debug_assert!(base + self.stride <= CELLS, "row {y}'s table beyond the cells");
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
    pub(super) fn offset(&self, d: i32, s: u16) -> Offset {
        // `slots` exceeds twice the reach: `slots + d` is positive.
        debug_assert!(2 * (d.unsigned_abs() as usize) < self.slots, "row distance {d} beyond the reach");
        Offset { d, shift: self.slots.wrapping_add_signed(d as isize), s: usize::from(s), above: usize::from(d < 0) }
    }

    /// Row `y` (built), and the built rows within reach of it, in `order`'s row distances,
    /// into `out`: returns how many, and how many of them are above row `y`.
    pub(super) fn around(&self, y: u16, order: &[Offset], out: &mut [Near]) -> (Row, usize, usize) {
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
pub(super) struct Offset {
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
