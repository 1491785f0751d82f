//! Grid-hashed DBSCAN over one window's events.
//!
//! Coordinates are normalised by the sensor size (x / W, y / H) as in the paper, so one
//! `eps` (default 0.015) serves every sensor. The optional spatio-temporal variant
//! (ST-DBSCAN) also requires `|Δt| / T <= eps_t`, with `T` the window's duration.
//!
//! Neighbour queries go through a fixed-size spatial hash: pixels are binned into cells at
//! least `eps` wide in each axis, cells are hashed into `B` buckets, and the window's events
//! are sorted in place by bucket. An eps-neighbourhood then lies in the 3 x 3 cells around
//! a point, so a query scans at most 9 contiguous runs of events: the work is linear in the
//! events for a bounded density, and no memory beyond the fixed arrays is needed.
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
    /// Pairwise distance checks made: the work of the neighbour queries.
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

/// Precomputed geometry of one run: cell sizes, hash, distance scales.
#[derive(Clone, Copy)]
struct Geometry {
    cell_w: u16,
    cell_h: u16,
    cells_x: u32,
    sx: f32,
    sy: f32,
    eps2: f32,
    /// 1 / window duration, for ST-DBSCAN; 0 when time is ignored.
    st: Option<(f32, f32)>,
}

impl Geometry {
    fn new(sensor: SensorSize, cfg: &ClusterConfig, duration_us: u32) -> Self {
        let w = f32::from(sensor.width.max(1));
        let h = f32::from(sensor.height.max(1));
        let eps = if cfg.eps.is_finite() && cfg.eps > 0.0 { cfg.eps } else { 0.0 };
        // A cell at least eps wide keeps every eps-neighbour within the adjacent cells.
        let cell = |size: f32| -> u16 {
            let c = libm::ceilf(eps * size);
            if c >= 65535.0 {
                u16::MAX
            } else if c >= 1.0 {
                c as u16
            } else {
                1
            }
        };
        let cell_w = cell(w);
        let cell_h = cell(h);
        let st = match cfg.eps_t {
            Some(et) if et.is_finite() && et >= 0.0 => {
                let inv = if duration_us > 0 { 1.0 / duration_us as f32 } else { 0.0 };
                Some((inv, et))
            }
            _ => None,
        };
        Self {
            cell_w,
            cell_h,
            cells_x: u32::from(sensor.width.max(1)) / u32::from(cell_w) + 1,
            sx: 1.0 / (w * w),
            sy: 1.0 / (h * h),
            eps2: eps * eps,
            st,
        }
    }

    fn cell(&self, e: &WindowEvent) -> (u32, u32) {
        (u32::from(e.x / self.cell_w), u32::from(e.y / self.cell_h))
    }

    fn bucket<const B: usize>(&self, cx: u32, cy: u32) -> usize {
        // A row-major cell index spreads neighbouring cells over distinct buckets; the
        // multiplicative mix keeps far-apart cells that collide from forming patterns.
        let idx = cy.wrapping_mul(self.cells_x).wrapping_add(cx);
        (idx.wrapping_mul(0x9E37_79B1) >> 7) as usize % B
    }

    fn neighbours(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        let dx = f32::from(a.x) - f32::from(b.x);
        let dy = f32::from(a.y) - f32::from(b.y);
        if dx * dx * self.sx + dy * dy * self.sy > self.eps2 {
            return false;
        }
        match self.st {
            None => true,
            Some((inv, eps_t)) => {
                let dt = a.dt_us.abs_diff(b.dt_us);
                dt as f32 * inv <= eps_t
            }
        }
    }

    /// The distinct buckets of the 3 x 3 cells around `e`.
    fn around<const B: usize>(&self, e: &WindowEvent) -> ([u16; 9], usize) {
        let (cx, cy) = self.cell(e);
        let mut out = [0u16; 9];
        let mut n = 0;
        for ny in cy.saturating_sub(1)..=cy + 1 {
            for nx in cx.saturating_sub(1)..=cx + 1 {
                let b = self.bucket::<B>(nx, ny) as u16;
                // Two cells may share a bucket: scan it once, or neighbours count twice.
                if !out[..n].contains(&b) {
                    out[n] = b;
                    n += 1;
                }
            }
        }
        (out, n)
    }
}

/// DBSCAN over at most `N` events per run, keeping at most `C` clusters, with a spatial hash
/// of `B` buckets. All memory is inline: about `2N + 4B + 4C` bytes.
///
/// `N` must be below 32 768 and `B` below 65 536 (checked at compile time).
///
/// ```
/// use evcal_core::{cluster::{Clusterer, ClusterConfig}, event::SensorSize, window::WindowEvent};
/// let mut events = [WindowEvent { x: 10, y: 10, dt_us: 0 }; 12];
/// events[11] = WindowEvent { x: 200, y: 100, dt_us: 5 };
/// let mut c: Clusterer<16, 4, 64> = Clusterer::new();
/// let stats = c.cluster(&mut events, SensorSize::DAVIS346, &ClusterConfig::default());
/// assert_eq!((stats.clusters, stats.noise), (1, 1));
/// let ranges = c.group(&mut events);
/// assert_eq!(ranges.len(), 1);
/// assert_eq!(ranges[0].end - ranges[0].start, 11);
/// ```
#[derive(Debug, Clone)]
pub struct Clusterer<const N: usize, const C: usize, const B: usize> {
    labels: [u16; N],
    start: [u16; B],
    next: [u16; B],
    ranges: [ClusterRange; C],
    len: usize,
    clusters: usize,
}

impl<const N: usize, const C: usize, const B: usize> Default for Clusterer<N, C, B> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const C: usize, const B: usize> Clusterer<N, C, B> {
    const CHECK: () = assert!(N < 0x7FFE && B > 0 && B <= 0xFFFF && C < 0x7FFE, "capacity out of range");

    /// An empty clusterer.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Self {
            labels: [0; N],
            start: [0; B],
            next: [0; B],
            ranges: [ClusterRange { start: 0, end: 0 }; C],
            len: 0,
            clusters: 0,
        }
    }

    /// Clusters `events` (at most `N`; the rest are counted as overflow and left out).
    /// Reorders `events` by hash bucket; [`labels`](Self::labels) then gives each event's
    /// cluster (0-based), [`NOISE`] or [`DROPPED`].
    pub fn cluster(&mut self, events: &mut [WindowEvent], sensor: SensorSize, cfg: &ClusterConfig) -> ClusterStats {
        let n = events.len().min(N);
        let mut stats =
            ClusterStats { events: n as u16, overflow: (events.len() - n).min(0xFFFF) as u16, ..Default::default() };
        let events = &mut events[..n];
        self.len = n;
        self.clusters = 0;
        let duration = events.iter().map(|e| e.dt_us).max().unwrap_or(0);
        let g = Geometry::new(sensor, cfg, duration);
        self.sort_by_bucket(events, &g);

        let min_pts = usize::from(cfg.min_pts.max(1));
        let mut checks: u32 = 0;

        // 1. Core points; every point starts as its own union-find root.
        for i in 0..n {
            let e = events[i];
            let (bs, nb) = g.around::<B>(&e);
            let mut count = 0usize;
            'scan: for &b in &bs[..nb] {
                let (s, t) = self.bucket_range(usize::from(b), n);
                for other in &events[s..t] {
                    checks = checks.wrapping_add(1);
                    if g.neighbours(&e, other) {
                        count += 1;
                        if count >= min_pts {
                            break 'scan;
                        }
                    }
                }
            }
            self.labels[i] = i as u16 | if count >= min_pts { CORE } else { 0 };
        }

        // 2. Join core points that are neighbours. A root is always its component's lowest
        //    index, so the numbering below does not depend on the union order.
        for i in 0..n {
            if self.labels[i] & CORE == 0 {
                continue;
            }
            stats.core += 1;
            let e = events[i];
            let (bs, nb) = g.around::<B>(&e);
            for &b in &bs[..nb] {
                let (s, t) = self.bucket_range(usize::from(b), n);
                for j in s..t {
                    if j >= i || self.labels[j] & CORE == 0 {
                        continue;
                    }
                    checks = checks.wrapping_add(1);
                    if g.neighbours(&e, &events[j]) {
                        self.union(i, j);
                    }
                }
            }
        }

        // 3. Number the clusters in index order. A core point's parent has a lower index and
        //    so already holds its component's label.
        let mut clusters: usize = 0;
        let mut found: usize = 0;
        for i in 0..n {
            let l = self.labels[i];
            if l & CORE == 0 {
                continue;
            }
            let p = usize::from(l & MASK);
            let label = if p == i {
                found += 1;
                if clusters < C {
                    clusters += 1;
                    (clusters - 1) as u16
                } else {
                    DROPPED
                }
            } else {
                self.labels[p] & MASK
            };
            self.labels[i] = label | CORE;
        }
        self.clusters = clusters;
        stats.clusters = clusters as u16;
        stats.dropped_clusters = (found - clusters).min(0xFFFF) as u16;

        // 4. Border points join their lowest-index core neighbour's cluster; the rest is noise.
        for i in 0..n {
            if self.labels[i] & CORE != 0 {
                continue;
            }
            let e = events[i];
            let (bs, nb) = g.around::<B>(&e);
            let mut best: Option<usize> = None;
            for &b in &bs[..nb] {
                let (s, t) = self.bucket_range(usize::from(b), n);
                for j in s..t {
                    if self.labels[j] & CORE == 0 || best.is_some_and(|k| k < j) {
                        continue;
                    }
                    checks = checks.wrapping_add(1);
                    if g.neighbours(&e, &events[j]) {
                        best = Some(j);
                    }
                }
            }
            self.labels[i] = match best {
                Some(j) => self.labels[j] & MASK,
                None => {
                    stats.noise += 1;
                    NOISE
                }
            };
        }
        for l in &mut self.labels[..n] {
            *l &= MASK;
        }
        stats.distance_checks = checks;
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
        let k = self.clusters;
        // Counting sort by label, in place: region c < k holds cluster c, region k the rest.
        let mut sizes = [0u16; C];
        for &l in &self.labels[..n] {
            if let Some(s) = sizes.get_mut(usize::from(l)) {
                *s += 1;
            }
        }
        let mut at = 0u16;
        for c in 0..k {
            self.ranges[c] = ClusterRange { start: at, end: at };
            at += sizes[c];
        }
        let clustered = usize::from(at);
        let region = |l: u16| if usize::from(l) < k { usize::from(l) } else { k };
        // `ranges[c].end` (and `tail` for the rest) is the fill pointer of each region.
        let mut tail = clustered;
        for r in 0..=k {
            loop {
                let (fill, end) = if r < k {
                    (usize::from(self.ranges[r].end), usize::from(self.ranges[r].start + sizes[r]))
                } else {
                    (tail, n)
                };
                if fill >= end {
                    break;
                }
                let l = region(self.labels[fill]);
                if l == r {
                    if r < k {
                        self.ranges[r].end += 1;
                    } else {
                        tail += 1;
                    }
                } else {
                    // Each swap puts one event in its final region, so this ends.
                    let dest = if l < k { usize::from(self.ranges[l].end) } else { tail };
                    events.swap(fill, dest);
                    self.labels.swap(fill, dest);
                    if l < k {
                        self.ranges[l].end += 1;
                    } else {
                        tail += 1;
                    }
                }
            }
        }
        &self.ranges[..k]
    }

    fn bucket_range(&self, b: usize, n: usize) -> (usize, usize) {
        let s = usize::from(self.start[b]);
        let t = if b + 1 < B { usize::from(self.start[b + 1]) } else { n };
        (s, t)
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

    fn union(&mut self, a: usize, b: usize) {
        let ra = self.find(a);
        let rb = self.find(b);
        if ra == rb {
            return;
        }
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        self.labels[hi] = (self.labels[hi] & CORE) | lo as u16;
    }

    /// Sorts events by bucket in place (American flag sort) and fills `start`.
    fn sort_by_bucket(&mut self, events: &mut [WindowEvent], g: &Geometry) {
        let n = events.len();
        self.start = [0; B];
        for e in events.iter() {
            let (cx, cy) = g.cell(e);
            let b = g.bucket::<B>(cx, cy);
            self.start[b] += 1;
        }
        let mut acc = 0u16;
        for b in 0..B {
            let c = self.start[b];
            self.start[b] = acc;
            self.next[b] = acc;
            acc += c;
        }
        for b in 0..B {
            let end = if b + 1 < B { usize::from(self.start[b + 1]) } else { n };
            while usize::from(self.next[b]) < end {
                let i = usize::from(self.next[b]);
                let (cx, cy) = g.cell(&events[i]);
                let tb = g.bucket::<B>(cx, cy);
                if tb == b {
                    self.next[b] += 1;
                } else {
                    let j = usize::from(self.next[tb]);
                    events.swap(i, j);
                    self.next[tb] += 1;
                }
            }
        }
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
        let w = f64::from(sensor.width.max(1));
        let h = f64::from(sensor.height.max(1));
        let near = |a: &WindowEvent, b: &WindowEvent| {
            // Same arithmetic as the hashed version (f32), so that borderline pairs agree.
            let dx = f32::from(a.x) - f32::from(b.x);
            let dy = f32::from(a.y) - f32::from(b.y);
            let sx = 1.0 / (w as f32 * w as f32);
            let sy = 1.0 / (h as f32 * h as f32);
            let spatial = dx * dx * sx + dy * dy * sy <= cfg.eps * cfg.eps;
            let temporal = match cfg.eps_t {
                None => true,
                Some(et) => {
                    let inv = if duration > 0 { 1.0 / duration as f32 } else { 0.0 };
                    (a.dt_us.abs_diff(b.dt_us)) as f32 * inv <= et
                }
            };
            spatial && temporal
        };
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

    fn check_equal<const N: usize, const C: usize, const B: usize>(
        input: &[WindowEvent],
        sensor: SensorSize,
        cfg: &ClusterConfig,
    ) -> ClusterStats {
        let mut events = input.to_vec();
        let mut c: Clusterer<N, C, B> = Clusterer::new();
        let stats = c.cluster(&mut events, sensor, cfg);
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
        let stats = check_equal::<256, 8, 64>(&ev, sensor, &ClusterConfig::default());
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
        let stats = check_equal::<512, 3, 32>(&ev, sensor, &ClusterConfig::default());
        assert_eq!((stats.clusters, stats.dropped_clusters), (3, 2));

        let mut small = ev.clone();
        let mut c: Clusterer<100, 8, 32> = Clusterer::new();
        let s = c.cluster(&mut small, sensor, &ClusterConfig::default());
        assert_eq!((s.events, s.overflow), (100, 100));
    }

    #[test]
    fn spatio_temporal_splits_in_time() {
        let sensor = SensorSize::DAVIS346;
        // The same place visited early and late in the window: one cluster in space, two in
        // space-time.
        let mut ev = ring(100.0, 100.0, 5.0, 60, 0, 3);
        ev.extend(ring(100.0, 100.0, 5.0, 60, 30_000, 4));
        let plain = check_equal::<256, 8, 64>(&ev, sensor, &ClusterConfig::default());
        assert_eq!(plain.clusters, 1);
        let st = ClusterConfig { eps_t: Some(0.1), ..Default::default() };
        let split = check_equal::<256, 8, 64>(&ev, sensor, &st);
        assert_eq!(split.clusters, 2);
    }

    #[test]
    fn group_makes_clusters_contiguous() {
        let sensor = SensorSize::DAVIS346;
        let mut ev = ring(50.0, 60.0, 6.0, 70, 0, 5);
        ev.extend(ring(150.0, 160.0, 8.0, 90, 0, 6));
        ev.extend(ring(250.0, 60.0, 4.0, 50, 0, 7));
        ev.push(WindowEvent { x: 340, y: 5, dt_us: 0 });
        let mut c: Clusterer<512, 8, 64> = Clusterer::new();
        let stats = c.cluster(&mut ev, sensor, &ClusterConfig::default());
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
        fn hashed_equals_brute_force(
            ev in arb_events(400, 346, 260),
            eps in 0.005f32..0.05,
            min_pts in 1u16..15,
            st in prop::option::of(0.01f32..0.5),
        ) {
            let cfg = ClusterConfig { eps, min_pts, eps_t: st };
            // Few buckets force collisions between far cells, many buckets avoid them.
            check_equal::<400, 16, 7>(&ev, SensorSize::DAVIS346, &cfg);
            check_equal::<400, 64, 1024>(&ev, SensorSize::DAVIS346, &cfg);
        }

        #[test]
        fn hashed_equals_brute_force_large_sensor(ev in arb_events(300, 1280, 720), min_pts in 1u16..12) {
            let cfg = ClusterConfig { min_pts, ..Default::default() };
            check_equal::<300, 64, 256>(&ev, SensorSize::new(1280, 720), &cfg);
        }

        #[test]
        fn arbitrary_input_never_panics(
            raw in prop::collection::vec((any::<u16>(), any::<u16>(), any::<u32>()), 0..300),
            w in any::<u16>(), h in any::<u16>(),
            eps in any::<f32>(), min_pts in any::<u16>(), st in prop::option::of(any::<f32>()),
        ) {
            let mut ev: Vec<WindowEvent> = raw.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            let mut c: Clusterer<256, 8, 16> = Clusterer::new();
            let stats = c.cluster(&mut ev, SensorSize::new(w, h), &ClusterConfig { eps, min_pts, eps_t: st });
            prop_assert_eq!(usize::from(stats.events) + usize::from(stats.overflow), ev.len());
            let ranges = c.group(&mut ev).to_vec();
            prop_assert_eq!(ranges.len(), usize::from(stats.clusters));
        }
    }
}
