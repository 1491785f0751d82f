//! DBSCAN by comparing every pair of events, for neighbourhoods too wide for the row sweep.

use super::{metric::Metric, ClusterStats, Clusterer, CORE, NONE};
use crate::window::WindowEvent;

impl<const N: usize, const C: usize> Clusterer<N, C> {
    /// DBSCAN by comparing every pair of events: for neighbourhoods too wide for the row sweep.
    pub(super) fn pairwise(
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
}
