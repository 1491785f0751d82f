//! The union-find of core points over the label array: a root is its set's lowest index.

use super::{Clusterer, CORE, MASK};

impl<const N: usize, const C: usize> Clusterer<N, C> {
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
    pub(super) fn union(&mut self, a: usize, b: usize) {
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
