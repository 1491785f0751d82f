//! The clusterer: its memory, the run that sorts and labels a window's events, and the
//! grouping and merging of the clusters found.

use super::{
    metric::Metric,
    sort::{sort_by_pixel, sort_in_time_by_pixel},
    ClusterConfig, ClusterRange, ClusterStats, MAX_REACH_ROWS,
};
use crate::{event::SensorSize, window::WindowEvent};

/// DBSCAN over at most `N` events per run, keeping at most `C` clusters. All memory is
/// inline: a label per event and a range per cluster, `2N + 4C` bytes; the events and the
/// sort's scratch and sweep's tables ([`ColumnTables`](super::ColumnTables), 16 KiB) are the caller's, so that
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
    pub(super) labels: [u16; N],
    pub(super) ranges: [ClusterRange; C],
    pub(super) len: usize,
    pub(super) clusters: usize,
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
    /// each event's cluster (0-based), [`NOISE`](super::NOISE) or [`DROPPED`](super::DROPPED).
    ///
    /// `tables` is the caller's scratch for the sort and the column tables of the sweep
    /// ([`ColumnTables`](super::ColumnTables), 16 KiB, or more where the neighbourhoods of a wide sensor's rows
    /// need them: a power of two up to [`MAX_TABLE_CELLS`](super::MAX_TABLE_CELLS) cells;
    /// with too few, the sweep walks cursors along the rows instead, to the same result).
    /// It would otherwise sit on the stack while this runs. Its content on entry does not
    /// matter.
    pub fn cluster<const CELLS: usize>(
        &mut self,
        events: &mut [WindowEvent],
        sensor: SensorSize,
        cfg: &ClusterConfig,
        tables: &mut [u16; CELLS],
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
}
