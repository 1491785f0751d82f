//! The labels a run ends with: clusters numbered in index order, border points settled into
//! their core neighbour's cluster or noise.

use super::{ClusterStats, Clusterer, CORE, DROPPED, MASK, NOISE, NONE};

impl<const N: usize, const C: usize> Clusterer<N, C> {
    /// 3. Numbers the clusters in index order. A core point's parent has a lower index and so
    ///    already holds its component's label. Core labels become `cluster | CORE`.
    #[inline(never)]
    pub(super) fn number(&mut self, n: usize, stats: &mut ClusterStats) {
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
    pub(super) fn settle_borders(&mut self, n: usize, stats: &mut ClusterStats) {
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
}
