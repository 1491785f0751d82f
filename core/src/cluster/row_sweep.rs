//! DBSCAN over pairs of neighbouring rows, with two cursors per row: ST-DBSCAN, and spatial
//! neighbourhoods whose column tables do not fit.

use super::{
    metric::Metric,
    rows::{count_spans, spans, Row, Rows},
    ClusterStats, Clusterer, CORE, MAX_REACH_ROWS, NONE,
};
use crate::window::WindowEvent;

impl<const N: usize, const C: usize> Clusterer<N, C> {
    /// DBSCAN over pairs of neighbouring rows (see the module's documentation).
    pub(super) fn by_rows(
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
}
