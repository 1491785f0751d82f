//! The sort of a window's events by pixel (row, column, then time) that makes every row of
//! the grid a contiguous run.

use crate::window::WindowEvent;

/// A pixel as the sort orders it: row, then column.
#[inline]
fn pixel(e: &WindowEvent) -> u32 {
    (u32::from(e.y) << 16) | u32::from(e.x)
}

/// The order [`Clusterer::cluster`](super::Clusterer::cluster) sorts events into: by pixel
/// (row, column), then time.
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
pub(super) fn sort_in_time_by_pixel(
    events: &mut [WindowEvent],
    order: &mut [u16],
    pos: &mut [u16],
) -> Option<([u16; 4], u32)> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

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
    }
}
