//! One detector: input filter, windower, clusterer and circle fit, over caller-owned memory.
//!
//! [`Detector::push`] takes events one at a time and, whenever a window completes, clusters
//! it and fits every cluster, returning the window's [`Detection`]. Everything lives inline
//! in the `Detector` value, so the firmware can place it in a `static`.

use crate::{
    cluster::{ClusterConfig, ClusterRange, ClusterStats, Clusterer},
    config::{HASH_BUCKETS, MAX_CLUSTERS, MAX_EVENTS_PER_WINDOW},
    event::{Event, InputFilter, InputStats, SensorSize},
    fit::{fit, Centre, FitConfig},
    window::{WindowConfig, WindowEvent, WindowInfo, Windower},
};

/// Everything the detector needs to know.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectConfig {
    /// Sensor size: events outside it are dropped, coordinates normalised by it.
    pub sensor: SensorSize,
    /// How windows are cut.
    pub window: WindowConfig,
    /// DBSCAN settings.
    pub cluster: ClusterConfig,
    /// Circle fit settings.
    pub fit: FitConfig,
}

impl DetectConfig {
    /// The paper's defaults for a sensor of the given size.
    pub fn new(sensor: SensorSize) -> Self {
        Self { sensor, window: WindowConfig::default(), cluster: ClusterConfig::default(), fit: FitConfig::default() }
    }
}

/// Counts of one window's processing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowStats {
    /// Events in the window.
    pub events: u16,
    /// Events DBSCAN left as noise.
    pub noise: u16,
    /// Clusters found and kept.
    pub clusters: u16,
    /// Clusters beyond the capacity, dropped.
    pub dropped_clusters: u16,
    /// Clusters the fit rejected (too small, degenerate).
    pub rejected_fits: u16,
    /// Clusters joined to another whose fitted circle they share (see [`process`]).
    pub merged_clusters: u16,
    /// Ticks that fell inside the previous window and started none.
    pub ticks_skipped: u32,
    /// Distance checks of the clustering: its work.
    pub distance_checks: u32,
    /// Time spent clustering, in the caller's clock ticks (0 without a clock).
    pub cluster_ticks: u32,
    /// Time spent fitting, in the caller's clock ticks (0 without a clock).
    pub fit_ticks: u32,
}

/// The result of one window: when, what was counted, and the circle centres found.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Detection<const C: usize> {
    /// The window: sequence number and reference time.
    pub info: WindowInfo,
    /// Counts.
    pub stats: WindowStats,
    /// Fitted circle centres, in cluster order.
    pub centres: heapless::Vec<Centre, C>,
}

/// A source of time for per-stage measurements (SysTick on the device). The unit is the
/// caller's; differences are taken with wrapping arithmetic.
pub trait Clock {
    /// The current time.
    fn now(&mut self) -> u32;
}

/// No clock: stage times read 0.
impl Clock for () {
    fn now(&mut self) -> u32 {
        0
    }
}

/// The detection pipeline for windows of at most `N` events, at most `C` clusters per
/// window, and a spatial hash of `B` buckets.
#[derive(Debug, Clone)]
pub struct Detector<
    const N: usize = MAX_EVENTS_PER_WINDOW,
    const C: usize = MAX_CLUSTERS,
    const B: usize = HASH_BUCKETS,
> {
    cfg: DetectConfig,
    filter: InputFilter,
    windower: Windower<N>,
    clusterer: Clusterer<N, C, B>,
    out: Detection<C>,
    ready: bool,
}

impl<const N: usize, const C: usize, const B: usize> Detector<N, C, B> {
    /// A detector with the given configuration (events per window clamped to `1..=N`).
    pub const fn new(cfg: DetectConfig) -> Self {
        Self {
            cfg,
            filter: InputFilter::new(cfg.sensor),
            windower: Windower::new(cfg.window),
            clusterer: Clusterer::new(),
            out: Detection {
                info: WindowInfo { seq: 0, t_ref_us: 0, t_last_us: 0, ticks_skipped: 0 },
                stats: WindowStats {
                    events: 0,
                    noise: 0,
                    clusters: 0,
                    dropped_clusters: 0,
                    rejected_fits: 0,
                    merged_clusters: 0,
                    ticks_skipped: 0,
                    distance_checks: 0,
                    cluster_ticks: 0,
                    fit_ticks: 0,
                },
                centres: heapless::Vec::new(),
            },
            ready: false,
        }
    }

    /// Starts afresh with `cfg`, exactly as [`new`](Self::new) would, but in place: on the
    /// device a temporary detector would not fit the stack.
    pub fn reconfigure(&mut self, cfg: DetectConfig) {
        self.cfg = cfg;
        self.filter = InputFilter::new(cfg.sensor);
        self.windower.reconfigure(cfg.window);
        // The clusterer keeps nothing from one window to the next.
        self.out.info = WindowInfo { seq: 0, t_ref_us: 0, t_last_us: 0, ticks_skipped: 0 };
        self.out.stats = WindowStats::default();
        self.out.centres.clear();
        self.ready = false;
    }

    /// The configuration in force (events per window after clamping).
    pub const fn config(&self) -> DetectConfig {
        let mut cfg = self.cfg;
        cfg.window = self.windower.config();
        cfg
    }

    /// Feeds one event; returns the window's detection when this event completes a window.
    pub fn push(&mut self, e: Event) -> Option<&Detection<C>> {
        if self.feed(e) {
            Some(self.process(&mut ()))
        } else {
            None
        }
    }

    /// Feeds one event without processing: `true` when this event completes a window, which
    /// must then be processed with [`process`](Self::process) before the next `feed`.
    pub fn feed(&mut self, e: Event) -> bool {
        if self.filter.check(&e).is_err() {
            return false;
        }
        match self.windower.push(e) {
            Some(info) => {
                self.out.info = info;
                self.ready = true;
                true
            }
            None => {
                self.ready = false;
                false
            }
        }
    }

    /// Clusters and fits the window that [`feed`](Self::feed) completed, measuring each stage
    /// with `clock`. Without a completed window it returns the last detection unchanged.
    pub fn process(&mut self, clock: &mut impl Clock) -> &Detection<C> {
        if self.ready {
            self.ready = false;
            let cfg = self.cfg;
            let events = self.windower.events_mut();
            process(&mut self.clusterer, events, &cfg, &mut self.out, clock);
        }
        &self.out
    }

    /// What the input filter accepted and dropped.
    pub const fn input_stats(&self) -> InputStats {
        self.filter.stats()
    }

    /// Events held by a window that has not completed yet.
    pub fn pending(&self) -> usize {
        self.windower.pending()
    }
}

/// Clusters one window's events and fits every cluster, writing into `out` (its `info` is
/// left as it is). `events` is reordered. The building block of [`Detector`], public for
/// benchmarks and for callers that cut windows themselves.
///
/// A window covers well under a pixel of motion (4000 events over some 40 circles), so a
/// circle fires mostly where its edge moves across itself: two crescents, leading and
/// trailing, with a gap where the edge slides along its own tangent. DBSCAN then often keeps
/// the crescents apart. Clusters whose first fits describe the same circle (centres within
/// half a radius, radii within a third) are therefore joined and fitted again as one.
pub fn process<const N: usize, const C: usize, const B: usize>(
    clusterer: &mut Clusterer<N, C, B>,
    events: &mut [WindowEvent],
    cfg: &DetectConfig,
    out: &mut Detection<C>,
    clock: &mut impl Clock,
) {
    let t0 = clock.now();
    let cs: ClusterStats = clusterer.cluster(events, cfg.sensor, &cfg.cluster);
    let mut ranges: heapless::Vec<ClusterRange, C> = heapless::Vec::new();
    for r in clusterer.group(events) {
        // The clusterer holds at most C clusters: a push cannot fail.
        let _ = ranges.push(*r);
    }
    let t1 = clock.now();
    let mut fits: heapless::Vec<Option<Centre>, C> = heapless::Vec::new();
    for r in &ranges {
        let _ = fits.push(fit(slice(events, r), &cfg.fit));
    }
    let merged = merge_crescents(events, &mut ranges, &mut fits, &cfg.fit);
    let mut rejected = 0u16;
    out.centres.clear();
    for f in &fits {
        match f {
            Some(c) => {
                let _ = out.centres.push(*c);
            }
            None => rejected += 1,
        }
    }
    let t2 = clock.now();
    out.stats = WindowStats {
        events: cs.events,
        noise: cs.noise,
        clusters: cs.clusters,
        dropped_clusters: cs.dropped_clusters,
        rejected_fits: rejected,
        merged_clusters: merged,
        ticks_skipped: out.info.ticks_skipped,
        distance_checks: cs.distance_checks,
        cluster_ticks: t1.wrapping_sub(t0),
        fit_ticks: t2.wrapping_sub(t1),
    };
}

fn slice<'a>(events: &'a [WindowEvent], r: &ClusterRange) -> &'a [WindowEvent] {
    events.get(usize::from(r.start)..usize::from(r.end)).unwrap_or(&[])
}

/// Whether two fits describe one circle.
fn same_circle(a: &Centre, b: &Centre) -> bool {
    let (r_small, r_big) = if a.r < b.r { (a.r, b.r) } else { (b.r, a.r) };
    let (du, dv) = (a.u - b.u, a.v - b.v);
    du * du + dv * dv <= 0.25 * r_small * r_small && r_big - r_small <= r_big * (1.0 / 3.0)
}

/// Joins clusters that fit the same circle (see [`process`]), moving the events of the later
/// cluster next to the earlier one, and refits the union. Returns how many were joined.
fn merge_crescents<const C: usize>(
    events: &mut [WindowEvent],
    ranges: &mut heapless::Vec<ClusterRange, C>,
    fits: &mut heapless::Vec<Option<Centre>, C>,
    cfg: &FitConfig,
) -> u16 {
    let mut merged = 0u16;
    let mut i = 0;
    while i < ranges.len() {
        let mut j = i + 1;
        let mut grew = false;
        while j < ranges.len() {
            let same = match (fits.get(i).copied().flatten(), fits.get(j).copied().flatten()) {
                (Some(a), Some(b)) => same_circle(&a, &b),
                _ => false,
            };
            if !same {
                j += 1;
                continue;
            }
            // Ranges are in event order: rotate j's events to just after i's.
            let (ri, rj) = (ranges[i], ranges[j]);
            let len_j = rj.end - rj.start;
            if let Some(seg) = events.get_mut(usize::from(ri.end)..usize::from(rj.end)) {
                seg.rotate_right(usize::from(len_j));
            }
            for r in ranges.iter_mut().take(j).skip(i + 1) {
                r.start += len_j;
                r.end += len_j;
            }
            ranges[i].end += len_j;
            ranges.remove(j);
            fits.remove(j);
            merged += 1;
            grew = true;
        }
        if grew {
            let union = fit(slice(events, &ranges[i]), cfg);
            fits[i] = union;
            // The union's better fit may now match clusters passed over before.
            if union.is_some() {
                continue;
            }
        }
        i += 1;
    }
    merged
}
