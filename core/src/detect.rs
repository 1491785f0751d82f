//! One detector: input filter, windower, clusterer and circle fit, over caller-owned memory.
//!
//! [`Detector::push`] takes events one at a time and, whenever a window completes, clusters
//! it and fits every cluster, returning the window's [`Detection`]. Everything lives inline
//! in the `Detector` value, so the firmware can place it in a `static`.

use crate::{
    cluster::sort_by_pixel,
    cluster::{
        background_per_neighbourhood, min_pts_above_background, ClusterConfig, ClusterRange, ClusterStats, Clusterer,
        MAX_TABLE_CELLS, TABLE_CELLS,
    },
    config::{
        DEFAULT_EPS, DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_CLUSTER_EVENTS, DEFAULT_MIN_PTS, DEFAULT_STEP_US,
        FIT_SCRATCH_EVENTS, MAX_CLUSTERS, MAX_EVENTS_PER_WINDOW, MAX_RECRUITS,
    },
    event::{Event, InputFilter, InputStats, SensorSize, MAX_HELD_EVENTS},
    fit::{fit_in, fit_with, Centre, Extent, FitConfig, FitMethod},
    math::sqrt_approx,
    moments::{Circle, Moments},
    window::{disc_events_per_window, ring_events_per_window, WindowConfig, WindowEvent, WindowInfo, Windower},
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
    /// The paper's defaults for a sensor of the given size (its 4000 events per window).
    pub fn new(sensor: SensorSize) -> Self {
        Self { sensor, window: WindowConfig::default(), cluster: ClusterConfig::default(), fit: FitConfig::default() }
    }

    /// evcal's defaults for a sensor: the paper's settings in windows sized to the sensor
    /// ([`ring_events_per_window`]). What `evcal detect` runs and what a device boots with,
    /// so that the two give the same detections of the same events. A `const fn`, so that a
    /// device's detector can be a `static` set up at compile time, with no temporary of its
    /// size on a small stack.
    pub const fn for_sensor(sensor: SensorSize) -> Self {
        Self {
            sensor,
            window: WindowConfig { events: ring_events_per_window(sensor), step_us: DEFAULT_STEP_US },
            cluster: ClusterConfig { eps: DEFAULT_EPS, min_pts: DEFAULT_MIN_PTS, eps_t: None },
            fit: FitConfig {
                method: FitMethod::Erwls,
                max_iterations: DEFAULT_MAX_ITERATIONS,
                min_events: DEFAULT_MIN_CLUSTER_EVENTS,
                filled_discs: false,
            },
        }
    }

    /// [`for_sensor`](Self::for_sensor) fitting filled discs where no ring fits, in windows
    /// of [`disc_events_per_window`]: what the host detects again with when the rings give
    /// no calibration, and what it asks a device to switch to.
    pub const fn discs_for_sensor(sensor: SensorSize) -> Self {
        let mut cfg = Self::for_sensor(sensor);
        cfg.fit.filled_discs = true;
        cfg.window.events = disc_events_per_window(sensor);
        cfg
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
    /// Clusters the fit rejected (too small, degenerate, or clutter on no circle).
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
///
/// [`Detector::process`] also calls [`window_begins`](Self::window_begins) and
/// [`window_ends`](Self::window_ends) around each window's clustering and fitting, so that
/// the firmware can mark them for an external instruction counter however deep in a protocol
/// loop the detector sits. Both do nothing unless a clock overrides them.
pub trait Clock {
    /// The current time.
    fn now(&mut self) -> u32;

    /// A window's clustering and fitting start.
    fn window_begins(&mut self) {}

    /// A window's clustering and fitting are done.
    fn window_ends(&mut self) {}
}

/// No clock: stage times read 0.
impl Clock for () {
    fn now(&mut self) -> u32 {
        0
    }
}

/// The working memory of one window's clustering and fits, which [`process`] takes from its
/// caller: kept in the [`Detector`] (so in its `static` on the device, where the linker
/// counts it) instead of on the stack while a window is processed. Nothing in it outlives a
/// window, and nothing in it outlives its stage: the clustering's column tables are done
/// with before the first fit, so the fits' events take the same memory (all of it but 64 B;
/// 6 KiB of the device's static RAM saved, the architecture's 64 KiB kept). Each stage
/// clears what it uses first, so no result depends on what the other left.
///
/// `CELLS` cells of `u16` ([`TABLE_CELLS`] by default, 16 KiB): a board with the memory
/// gives a wide sensor's column tables room (up to [`MAX_TABLE_CELLS`]; a 640x480 sensor's
/// need some 14 500 cells, a 1280x720 one's some 41 000), and the clustering then sweeps by
/// tables instead of walking cursors along the rows, to the same result.
#[derive(Debug, Clone)]
#[repr(C, align(4))]
pub struct Scratch<const CELLS: usize = TABLE_CELLS> {
    /// The clustering's sort buckets and column tables (`u16`), then the fits' events in
    /// their local frames (see `fit_with`; `[f32; 3]` each), aligned for those.
    cells: [u16; CELLS],
}

// The fits' events fit in the smallest scratch.
const _: () = assert!(6 * FIT_SCRATCH_EVENTS <= TABLE_CELLS);

impl<const CELLS: usize> Scratch<CELLS> {
    const CHECK: () = assert!(
        CELLS >= TABLE_CELLS && CELLS <= MAX_TABLE_CELLS && CELLS.is_power_of_two(),
        "a detector's scratch: a power of two from TABLE_CELLS to MAX_TABLE_CELLS cells"
    );

    /// Scratch memory, zeroed.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Self { cells: [0; CELLS] }
    }

    /// The clustering's column tables.
    fn tables(&mut self) -> &mut [u16; CELLS] {
        &mut self.cells
    }

    /// The fits' events, [`FIT_SCRATCH_EVENTS`] of them (in the tables' memory: the
    /// clustering must be done).
    fn fit(&mut self) -> &mut [[f32; 3]] {
        // The cells are aligned for `f32` (the struct's `align(4)`) and hold the events
        // (checked above): the cast does not fail.
        match self.cells.get_mut(..6 * FIT_SCRATCH_EVENTS) {
            Some(cells) => bytemuck::try_cast_slice_mut(cells).unwrap_or_default(),
            None => &mut [],
        }
    }
}

impl<const CELLS: usize> Default for Scratch<CELLS> {
    fn default() -> Self {
        Self::new()
    }
}

/// The detection pipeline for windows of at most `N` events and at most `C` clusters per
/// window, its input filter holding up to `H` events (see [`InputFilter`]).
#[derive(Debug, Clone)]
pub struct Detector<
    const N: usize = MAX_EVENTS_PER_WINDOW,
    const C: usize = MAX_CLUSTERS,
    const H: usize = MAX_HELD_EVENTS,
    const CELLS: usize = TABLE_CELLS,
> {
    cfg: DetectConfig,
    filter: InputFilter<H>,
    windower: Windower<N>,
    clusterer: Clusterer<N, C>,
    scratch: Scratch<CELLS>,
    out: Detection<C>,
    ready: bool,
}

impl<const N: usize, const C: usize, const H: usize, const CELLS: usize> Detector<N, C, H, CELLS> {
    /// A detector with the given configuration (events per window clamped to `1..=N`).
    pub const fn new(cfg: DetectConfig) -> Self {
        Self {
            cfg,
            filter: InputFilter::new(cfg.sensor),
            windower: Windower::new(cfg.window),
            clusterer: Clusterer::new(),
            scratch: Scratch::new(),
            out: Detection {
                info: WindowInfo { seq: 0, t_first_us: 0, t_ref_us: 0, t_last_us: 0, ticks_skipped: 0 },
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
        self.filter.reset(cfg.sensor);
        self.windower.reconfigure(cfg.window);
        // The clusterer keeps nothing from one window to the next.
        self.out.info = WindowInfo { seq: 0, t_first_us: 0, t_ref_us: 0, t_last_us: 0, ticks_skipped: 0 };
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

    /// Feeds one event; returns the window's detection when a window completes. At the end
    /// of the input call [`end`](Self::end) until `None`.
    pub fn push(&mut self, e: Event) -> Option<&Detection<C>> {
        if self.feed(e) {
            Some(self.process(&mut ()))
        } else {
            None
        }
    }

    /// The end of the input: the events the input filter still holds go on to the windower;
    /// returns a detection when they complete a window. Call until `None`.
    pub fn end(&mut self) -> Option<&Detection<C>> {
        if self.finish() {
            Some(self.process(&mut ()))
        } else {
            None
        }
    }

    /// Feeds one event without processing: `true` when a window completes, which must then be
    /// processed with [`process`](Self::process) before the next `feed`. The window may be
    /// completed by events the input filter held and released now (after a pause, see
    /// [`InputFilter`]); the rest of them wait for the next `feed` or [`finish`](Self::finish).
    pub fn feed(&mut self, e: Event) -> bool {
        self.ready = false;
        if let Some(e) = self.filter.push(e) {
            if self.window(e) {
                return true;
            }
            // The usual case, nothing held: no call into the hold for every event (it cost
            // the device 73 instructions an event, docs/firmware.md#performance).
            if self.filter.held() == 0 {
                return false;
            }
        }
        self.release()
    }

    /// The end of the input, without processing: the input filter decides what it holds
    /// and releases it. `true` when that completes a window, to be processed with
    /// [`process`](Self::process); call again until `false`.
    pub fn finish(&mut self) -> bool {
        self.ready = false;
        self.filter.finish();
        self.release()
    }

    /// Feeds the windower what the input filter releases, up to the end of a window.
    fn release(&mut self) -> bool {
        while let Some(e) = self.filter.pop() {
            if self.window(e) {
                return true;
            }
        }
        false
    }

    /// Feeds one accepted event to the windower: `true` when it completes a window.
    fn window(&mut self, e: Event) -> bool {
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
            clock.window_begins();
            process(&mut self.clusterer, &mut self.scratch, events, &cfg, &mut self.out, clock);
            clock.window_ends();
        }
        &self.out
    }

    /// What the input filter accepted and dropped.
    pub const fn input_stats(&self) -> InputStats {
        self.filter.stats()
    }

    /// Events were lost before they reached the detector (an input FIFO overran while a
    /// window was worked on; the caller counts them): the window filling is dropped and the
    /// next one starts after the loss, so that no window holds their place (see
    /// [`Windower::lost`]). Events the input filter holds are earlier than the loss, and go
    /// on to the windower as if after it, which only moves the next window later.
    pub fn lost(&mut self) {
        self.windower.lost();
    }

    /// Events held by a window that has not completed yet, or by the input filter.
    pub fn pending(&self) -> usize {
        self.windower.pending() + self.filter.held()
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
///
/// DBSCAN's `min_pts` is first raised by what the window's background (its pixels' noise)
/// puts in a neighbourhood by chance (`cluster::background`), so that a dim room's noise does
/// not join the circles.
pub fn process<const N: usize, const C: usize, const CELLS: usize>(
    clusterer: &mut Clusterer<N, C>,
    scratch: &mut Scratch<CELLS>,
    events: &mut [WindowEvent],
    cfg: &DetectConfig,
    out: &mut Detection<C>,
    clock: &mut impl Clock,
) {
    let t0 = clock.now();
    // The configured `min_pts` is the edges' own density; the background's is added to it.
    let background = background_per_neighbourhood(events, cfg.sensor, cfg.cluster.eps, scratch.tables());
    let min_pts = min_pts_above_background(cfg.cluster.min_pts, background);
    let cfg = DetectConfig { cluster: ClusterConfig { min_pts, ..cfg.cluster }, ..*cfg };
    process_at_threshold(clusterer, scratch, events, &cfg, out, clock, t0);
}

/// [`process`] with `cfg.cluster.min_pts` as it is, the background not counted; `t0` is the
/// clock's reading when the window's processing began.
fn process_at_threshold<const N: usize, const C: usize, const CELLS: usize>(
    clusterer: &mut Clusterer<N, C>,
    scratch: &mut Scratch<CELLS>,
    events: &mut [WindowEvent],
    cfg: &DetectConfig,
    out: &mut Detection<C>,
    clock: &mut impl Clock,
    t0: u32,
) {
    let t_ref = out.info.t_ref_us.saturating_sub(out.info.t_first_us).min(u64::from(u32::MAX)) as u32;
    let cs: ClusterStats = clusterer.cluster(events, cfg.sensor, &cfg.cluster, scratch.tables());
    let mut starts: heapless::Vec<Option<Circle>, C> = heapless::Vec::new();
    let mut extents: heapless::Vec<Extent, C> = heapless::Vec::new();
    let merged = join_crescents(clusterer, events, t_ref, &mut starts, &mut extents);
    let mut ranges: heapless::Vec<ClusterRange, C> = heapless::Vec::new();
    for r in clusterer.ranges() {
        // The clusterer holds at most C clusters: a push cannot fail.
        let _ = ranges.push(*r);
    }
    let t1 = clock.now();
    // The fits' events in their local frames (see `fit_with`), cleared as a fresh array
    // would be: no window's result may depend on the one before.
    let scratch = scratch.fit();
    scratch.fill([0.0; 3]);
    let mut fits: heapless::Vec<Option<Centre>, C> = heapless::Vec::new();
    for (k, r) in ranges.iter().enumerate() {
        let start = starts.get(k).copied().flatten();
        let extent = extents.get(k);
        let _ = fits.push(fit_in(&[slice(events, r)], extent, start, t_ref, &cfg.fit, scratch, CLUSTER_GIVE_UP));
    }
    let merged = merged + join_fitted(events, &mut ranges, &mut extents, &mut fits, t_ref, &cfg.fit, scratch);
    recruit(events, &ranges, &extents, &mut fits, t_ref, &cfg.fit, scratch);
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

/// Largest RMS distance, px, of two clusters' events from the circle through their union for
/// the clusters to be joined: the edge's own spread (about half a pixel) and the motion
/// within a window, with room to spare, but well below what two neighbouring circles or a
/// circle and clutter leave.
const JOIN_MAX_RMS: f32 = 1.0;

/// Joins clusters whose events lie on one circle (the crescents of a circle that DBSCAN
/// keeps apart, see [`process`]) and leaves the events grouped by the joined clusters.
/// Candidates are pairs whose bounding boxes are no further apart than the smaller box is
/// wide; they join when the algebraic circle through their union ([`Moments`]) passes within
/// [`JOIN_MAX_RMS`] of the events of each and is no larger than the union. Returns how many
/// clusters were joined to another; `starts` receives the algebraic circle of each
/// cluster as it is then (joined or not), to start its fit from, and `extents` its events'
/// [`Extent`].
fn join_crescents<const N: usize, const C: usize>(
    clusterer: &mut Clusterer<N, C>,
    events: &mut [WindowEvent],
    t_ref: u32,
    starts: &mut heapless::Vec<Option<Circle>, C>,
    extents: &mut heapless::Vec<Extent, C>,
) -> u16 {
    let mut boxes: heapless::Vec<[u16; 4], C> = heapless::Vec::new();
    let mut sums: heapless::Vec<Moments, C> = heapless::Vec::new();
    extents.clear();
    for r in clusterer.group(events) {
        let part = slice(events, r);
        let (m, x) = Moments::of_with_extent(part, t_ref);
        let _ = boxes.push([x.x_lo, x.y_lo, x.x_hi, x.y_hi]);
        let _ = sums.push(m);
        let _ = extents.push(x);
    }
    let k = boxes.len();
    // Union-find over clusters, each root the lowest index of its set.
    let mut into = [0u16; C];
    for (c, slot) in into.iter_mut().enumerate() {
        *slot = c as u16;
    }
    let merged = join_pairs(&boxes, &sums, &mut into);
    // The joined clusters' sums, in the order `merge` numbers them (by their lowest member).
    // The extents are joined in place: a set's slot is at most its lowest member's index,
    // and every member comes after it, so no extent is overwritten before it is read.
    let mut joined: heapless::Vec<Moments, C> = heapless::Vec::new();
    let mut slot = [0u16; C];
    for c in 0..k {
        let r = root(&into, c);
        let own = extents.get(c).copied().unwrap_or(Extent::EMPTY);
        if r == c {
            slot[c] = joined.len() as u16;
            if let Some(x) = extents.get_mut(joined.len()) {
                *x = own;
            }
            let _ = joined.push(sums[c]);
        } else {
            if let Some(m) = joined.get_mut(usize::from(slot[r])) {
                m.add(&sums[c]);
            }
            if let Some(x) = extents.get_mut(usize::from(slot[r])) {
                x.join(&own);
            }
        }
    }
    extents.truncate(joined.len());
    starts.clear();
    for m in &joined {
        let _ = starts.push(m.circle());
    }
    if merged > 0 {
        clusterer.merge(events, &into[..k]);
    }
    merged
}

/// The root of cluster `c` in `into` (each root the lowest index of its set).
fn root(into: &[u16], mut c: usize) -> usize {
    while let Some(&p) = into.get(c).filter(|&&p| usize::from(p) != c) {
        c = usize::from(p);
    }
    c
}

/// The pairs test of [`join_crescents`]: clusters with bounding boxes `boxes` (`[x_lo, y_lo,
/// x_hi, y_hi]`) and power sums `sums` that lie on one circle are joined in the union-find
/// `into` (each entry at first its own index). Returns how many joins were made.
fn join_pairs<const C: usize>(boxes: &[[u16; 4]], sums: &[Moments], into: &mut [u16; C]) -> u16 {
    let k = boxes.len().min(sums.len()).min(C);
    // Each box's larger side: two crescents of one circle are no further apart than either
    // spans.
    let mut sizes = [0u16; C];
    for (s, b) in sizes.iter_mut().zip(boxes) {
        *s = b[2].wrapping_sub(b[0]).max(b[3].wrapping_sub(b[1]));
    }
    // The clusters by their boxes' top rows (DBSCAN numbers them nearly so: insertion is
    // quick), so that each meets only the boxes that start within its reach below it. The
    // sets that come out are the connected components of the pairs that join, whatever the
    // order the pairs are tried in, and every pair is tried as (lower index, higher index).
    let mut order = [0u16; C];
    for c in 0..k {
        let mut at = c;
        while at > 0 && boxes[usize::from(order[at - 1])][1] > boxes[c][1] {
            order[at] = order[at - 1];
            at -= 1;
        }
        order[at] = c as u16;
    }
    let mut merged = 0u16;
    for (p, &oi) in order[..k].iter().enumerate() {
        let oi = usize::from(oi);
        let (top_a, reach) = (boxes[oi], sizes[oi]);
        for &oj in &order[p + 1..k] {
            let oj = usize::from(oj);
            // Every later box starts at least this far below this one.
            if boxes[oj][1].saturating_sub(top_a[3]) > reach {
                break;
            }
            let (i, j) = if oi < oj { (oi, oj) } else { (oj, oi) };
            let (a, b) = (boxes[i], boxes[j]);
            let gap = a[0].max(b[0]).saturating_sub(a[2].min(b[2])).max(a[1].max(b[1]).saturating_sub(a[3].min(b[3])));
            if gap > sizes[i].min(sizes[j]) {
                continue;
            }
            let (ri, rj) = (root(&into[..], i), root(&into[..], j));
            if ri == rj {
                continue;
            }
            let extent = f32::from(a[2].max(b[2]) - a[0].min(b[0])).max(f32::from(a[3].max(b[3]) - a[1].min(b[1])));
            let joins = sums[i]
                .joint_radius(&sums[j])
                .is_some_and(|(r, ra, rb)| r > 0.5 && r <= extent && ra <= JOIN_MAX_RMS && rb <= JOIN_MAX_RMS);
            if joins {
                let (lo, hi) = if ri < rj { (ri, rj) } else { (rj, ri) };
                into[hi] = lo as u16;
                merged += 1;
            }
        }
    }
    merged
}

/// Whether two fits may be fragments of one circle: each centre lies inside the other circle
/// (two circles of a grid never overlap like that).
fn overlapping(a: &Centre, b: &Centre) -> bool {
    let (du, dv) = (a.u - b.u, a.v - b.v);
    // The larger radius, without a library call (fitted radii are never NaN).
    let r = if a.r < b.r { b.r } else { a.r };
    du * du + dv * dv <= r * r
}

/// Weighted spread, px, beyond which a cluster's own fit gives up from its second pass on
/// (see [`fit_within`](crate::fit::fit_within); tighter than [`MAX_SPREAD`](crate::fit::MAX_SPREAD)). A circle's
/// edge leaves well under a pixel (simulated DAVIS346 cone: no fit that matched a circle
/// ended beyond 0.88 px), and fragments that join stay within 1.5 px (see
/// [`JOIN_MAX_PART_SPREAD`]); the fits beyond are clutter, which ran its remaining
/// iterations only to end between 1.5 and 3 px. The detection tests (DAVIS346 cone good and
/// low light, DVXplorer spiral): 1.75 px changed one circle of 984 in low light (found 80.8
/// -> 80.7 %, centre RMS 0.317 -> 0.316 px), nothing else; 1.5 px lost three (80.6 %, 0.318
/// px; 92.0 -> 91.9 % on the spiral). On the M4F it saves 0.11 M instructions a window.
const CLUSTER_GIVE_UP: f32 = 1.75 * JOIN_MAX_SPREAD;

/// Largest weighted spread, px, of the fit to two joined fragments for the join to stand.
const JOIN_MAX_SPREAD: f32 = 1.0;

/// Largest weighted spread, px, of either fragment's own fit for their union to be fitted.
/// A subset of events is fitted at least as closely by its own circle as by any other, so a
/// fragment spread this much (clutter, or a straight edge fitted as a huge circle whose
/// centre then lies inside every circle nearby) makes a union that cannot meet
/// [`JOIN_MAX_SPREAD`]; fitting it anyway cost a few windows several times the usual. On
/// four simulated recordings (349 windows) no join had a fragment beyond 1.5 px, and this
/// skips 1261 of the 1509 union fits that failed, 95 % of their events.
const JOIN_MAX_PART_SPREAD: f32 = 2.0 * JOIN_MAX_SPREAD;

/// Weighted spread, px, beyond which a union's fit gives up from its second pass on (see
/// [`fit_within`](crate::fit::fit_within)): the join could not stand. Measured on five simulated recordings (DAVIS346
/// cone good and low light, 4x11, and square low light, 3x7; DVXplorer spiral 3x9; 465 union
/// fits that joined, 111 that failed): a union that joined was within 1.37 px at its second
/// pass (low light; within 1.01 px on the others), and giving up beyond 1.75 px loses none
/// of them while it skips most of the failed unions' passes, the costliest work of the
/// slowest windows.
const JOIN_GIVE_UP: f32 = 1.75 * JOIN_MAX_SPREAD;

/// The second joining stage: clusters whose robust fits overlap (a crescent that DBSCAN also
/// tied to a little clutter or noise, which the algebraic test of [`join_crescents`] cannot
/// see past, or two sparse crescents each fitted as a smaller circle) are fitted as one; the
/// join stands when that fit is good (spread within [`JOIN_MAX_SPREAD`]). The events of the
/// later cluster are moved next to the earlier one's. Returns how many were joined.
fn join_fitted<const C: usize>(
    events: &mut [WindowEvent],
    ranges: &mut heapless::Vec<ClusterRange, C>,
    extents: &mut heapless::Vec<Extent, C>,
    fits: &mut heapless::Vec<Option<Centre>, C>,
    t_ref: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
) -> u16 {
    let mut merged = 0u16;
    let mut i = 0;
    while i < ranges.len() {
        let mut j = i + 1;
        let mut grew = false;
        while j < ranges.len() {
            // Borrowed, not copied: most pairs are far apart.
            let candidate = match (fits.get(i), fits.get(j)) {
                (Some(Some(a)), Some(Some(b))) => {
                    overlapping(a, b) && !(a.spread > JOIN_MAX_PART_SPREAD || b.spread > JOIN_MAX_PART_SPREAD)
                }
                _ => false,
            };
            if !candidate {
                j += 1;
                continue;
            }
            let (ri, rj) = (ranges[i], ranges[j]);
            let extent = match (extents.get(i), extents.get(j)) {
                (Some(a), Some(b)) => Some({
                    let mut x = *a;
                    x.join(b);
                    x
                }),
                _ => None,
            };
            let parts = [slice(events, &ri), slice(events, &rj)];
            let union = fit_in(&parts, extent.as_ref(), None, t_ref, cfg, scratch, JOIN_GIVE_UP);
            let Some(u) = union.filter(|u| u.spread <= JOIN_MAX_SPREAD) else {
                j += 1;
                continue;
            };
            // Ranges are in event order: rotate j's events to just after i's.
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
            if let (Some(x), Some(slot)) = (extent, extents.get_mut(i)) {
                *slot = x;
            }
            if j < extents.len() {
                extents.remove(j);
            }
            fits.remove(j);
            fits[i] = Some(u);
            merged += 1;
            grew = true;
        }
        // The union's fit may now overlap clusters passed over before.
        if !grew {
            i += 1;
        }
    }
    merged
}

/// How far from a fitted circle, px, an event DBSCAN left out may be and still be taken as
/// the circle's: some three times the edge's own spread.
const RECRUIT_GATE: f32 = 2.0;
/// Rounds of recruiting: a circle fitted to one crescent can be a pixel or two off, and the
/// events of the other side reach it only once a first round has brought it closer.
const RECRUIT_ROUNDS: usize = 2;

/// Gives every fitted circle the events DBSCAN left as noise that lie on it, and fits it
/// again with them. Where a circle's edge barely moves, it fires sparsely: DBSCAN finds the
/// dense crescent and calls the rest noise, and a fit to that one crescent misplaces the
/// centre along the crescent's axis. Events within [`RECRUIT_GATE`] of the circle (moving
/// with its velocity) join the fit when there are at least a tenth as many as it has; the
/// fit starts from the circle found so far. The noise events are sorted by pixel once, so
/// each circle searches only the rows it spans; at most [`MAX_RECRUITS`] events per circle.
fn recruit<const C: usize>(
    events: &mut [WindowEvent],
    ranges: &heapless::Vec<ClusterRange, C>,
    extents: &heapless::Vec<Extent, C>,
    fits: &mut heapless::Vec<Option<Centre>, C>,
    t_ref: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
) {
    let clustered = ranges.iter().map(|r| usize::from(r.end)).max().unwrap_or(0);
    let Some(noise) = events.get_mut(clustered..) else { return };
    sort_by_pixel(noise);
    let (events, noise) = events.split_at(clustered);
    let t_ref_ms = t_ref as f32 * 1e-3;
    // The largest |τ| of any noise event, ms: how long a circle moves for any of them.
    let t_last_ms = noise.iter().fold(0, |m, e| m.max(e.dt_us)) as f32 * 1e-3;
    let t_far = t_ref_ms.max(t_last_ms - t_ref_ms);
    let mut found = [WindowEvent::default(); MAX_RECRUITS];
    for (k, (r, f)) in ranges.iter().zip(fits.iter_mut()).enumerate() {
        if f.is_none() {
            continue;
        }
        let part = slice(events, r);
        let (t_lo, t_hi) = match extents.get(k) {
            Some(x) => (x.t_lo, x.t_hi),
            None => part.iter().fold((u32::MAX, 0), |(lo, hi), e| (lo.min(e.dt_us), hi.max(e.dt_us))),
        };
        // A round that takes no events, or whose fit fails, leaves the circle as it was: the
        // next round would search the same rows for the same events, so none follows.
        for _round in 0..RECRUIT_ROUNDS {
            let Some(c) = *f else { break };
            // The rows the circle sweeps over the window, with the gate.
            let reach = c.r + RECRUIT_GATE + c.vv.abs() * (t_hi.saturating_sub(t_lo) as f32 * 1e-3) + 1.0;
            let (y_lo, y_hi) = ((c.v - reach).max(0.0) as u16, (c.v + reach).min(65535.0) as u16);
            let lo = noise.partition_point(|e| e.y < y_lo);
            let hi = noise.partition_point(|e| e.y <= y_hi);
            // The columns of the same band: an event beyond them is further from the circle
            // than the gate at any time of the window (the pixel of margin covers the
            // approximate square root below), so it is passed over without one.
            let reach_x = c.r + RECRUIT_GATE + c.vu.abs() * t_far + 1.0;
            let (x_lo, x_hi) = ((c.u - reach_x).max(0.0) as u16, (c.u + reach_x).min(65535.0) as u16);
            let mut k = 0;
            for e in &noise[lo..hi] {
                if e.x < x_lo || e.x > x_hi {
                    continue;
                }
                let t = e.dt_us as f32 * 1e-3 - t_ref_ms;
                let (dx, dy) = (f32::from(e.x) - c.u - c.vu * t, f32::from(e.y) - c.v - c.vv * t);
                if (sqrt_approx(dx * dx + dy * dy) - c.r).abs() <= RECRUIT_GATE && k < MAX_RECRUITS {
                    found[k] = *e;
                    k += 1;
                }
            }
            if k == 0 || k * 10 < part.len() {
                break;
            }
            let start = Circle { u: c.u, v: c.v, vu: c.vu, vv: c.vv, r: c.r, rms: c.spread };
            match fit_with(&[part, &found[..k]], Some(start), t_ref, cfg, scratch) {
                Some(better) => *f = Some(better),
                None => break,
            }
        }
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    #[test]
    fn sensor_defaults_are_the_papers_in_windows_sized_to_the_sensor() {
        for s in [SensorSize::DAVIS346, SensorSize::DVXPLORER, SensorSize::new(320, 320), SensorSize::new(1280, 720)] {
            let mut paper = DetectConfig::new(s);
            paper.window.events = ring_events_per_window(s);
            assert_eq!(DetectConfig::for_sensor(s), paper);
            paper.window.events = disc_events_per_window(s);
            paper.fit.filled_discs = true;
            assert_eq!(DetectConfig::discs_for_sensor(s), paper);
        }
    }

    /// Events on rings (two crescents each, moving) plus scattered noise.
    fn scene(circles: &[(f32, f32, f32)], per_circle: usize, noise: usize, seed: u32) -> Vec<Event> {
        let mut s = seed | 1;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut out = Vec::new();
        for _ in 0..per_circle {
            for &(cx, cy, r) in circles {
                let t = rnd() * 4000.0;
                // Crescents: angles near the motion axis (x), edge spread ±0.5 px.
                let a = (rnd() - 0.5) * 2.2 + if rnd() < 0.5 { 0.0 } else { core::f32::consts::PI };
                let rr = r + rnd() - 0.5;
                let x = cx + 0.2e-3 * t + rr * libm::cosf(a);
                let y = cy + rr * libm::sinf(a);
                out.push(Event { t_us: t as u64, x: x.round() as u16, y: y.round() as u16, polarity: true });
            }
        }
        for _ in 0..noise {
            let t = rnd() * 4000.0;
            out.push(Event { t_us: t as u64, x: (rnd() * 340.0) as u16, y: (rnd() * 255.0) as u16, polarity: false });
        }
        out.sort_by_key(|e| e.t_us);
        out
    }

    /// A dim room: shot noise all over the sensor, more events than the window's edges put
    /// together. Every circle is still found where it is (the threshold raised above the
    /// background); at the paper's fixed `min_pts` of 10 the noise joins circles to each other
    /// and to noise, and many are lost.
    #[test]
    fn circles_are_found_on_a_background_of_noise() {
        // Circles 6 px across on a 24 px lattice, 80 events each (1920 in all); 7000 events
        // of noise, some 5 in every neighbourhood.
        const SP: f32 = 24.0;
        const PER: usize = 80;
        const NOISE: usize = 7000;
        let circles: Vec<(f32, f32, f32)> = (0..24)
            .map(|i| (40.0 + (i % 6) as f32 * SP, 40.0 + (i / 6) as f32 * SP + (i % 2) as f32 * SP / 2.0, 6.0))
            .collect();
        let mut found_adaptive = 0;
        let mut found_fixed = 0;
        for seed in 1..4u32 {
            let ev = scene(&circles, PER, NOISE, seed);
            let cfg = DetectConfig::new(SensorSize::DAVIS346);
            let count = |min_pts_fixed: bool| {
                let mut w: Vec<WindowEvent> =
                    ev.iter().map(|e| WindowEvent { x: e.x, y: e.y, dt_us: e.t_us as u32 }).collect();
                let mut clusterer: Box<Clusterer<8192, 64>> = Box::default();
                let mut scratch: Box<Scratch> = Box::default();
                let info = WindowInfo { seq: 0, t_first_us: 0, t_ref_us: 2000, t_last_us: 4000, ticks_skipped: 0 };
                let mut out: Box<Detection<64>> =
                    Box::new(Detection { info, stats: WindowStats::default(), centres: heapless::Vec::new() });
                if min_pts_fixed {
                    // The threshold as it was, the background's count not added.
                    process_at_threshold(&mut clusterer, &mut scratch, &mut w, &cfg, &mut out, &mut (), 0);
                } else {
                    process(&mut clusterer, &mut scratch, &mut w, &cfg, &mut out, &mut ());
                }
                circles
                    .iter()
                    .filter(|&&(x, y, _)| {
                        out.centres.iter().any(|k| (k.u - (x + 0.4)).abs() < 0.5 && (k.v - y).abs() < 0.5)
                    })
                    .count()
            };
            found_adaptive += count(false);
            found_fixed += count(true);
        }
        // Measured: 71 and 41 of 72.
        assert!(found_adaptive >= 68, "{found_adaptive} of 72 circles found");
        assert!(found_fixed < 60, "{found_fixed} of 72 circles found at min_pts 10");
    }

    /// Every pair tried in index order: what `join_pairs` must agree with.
    fn join_pairs_naive(boxes: &[[u16; 4]], sums: &[Moments], into: &mut [u16; 64]) -> u16 {
        let mut merged = 0;
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                let (a, b) = (boxes[i], boxes[j]);
                let gap =
                    a[0].max(b[0]).saturating_sub(a[2].min(b[2])).max(a[1].max(b[1]).saturating_sub(a[3].min(b[3])));
                let size = (a[2] - a[0]).max(a[3] - a[1]).min((b[2] - b[0]).max(b[3] - b[1]));
                let (ri, rj) = (root(&into[..], i), root(&into[..], j));
                if gap > size || ri == rj {
                    continue;
                }
                let extent = f32::from(a[2].max(b[2]) - a[0].min(b[0])).max(f32::from(a[3].max(b[3]) - a[1].min(b[1])));
                let joins = sums[i]
                    .joint_circle(&sums[j])
                    .is_some_and(|(c, ra, rb)| c.r > 0.5 && c.r <= extent && ra <= JOIN_MAX_RMS && rb <= JOIN_MAX_RMS);
                if joins {
                    into[ri.max(rj)] = ri.min(rj) as u16;
                    merged += 1;
                }
            }
        }
        merged
    }

    #[test]
    fn crescents_join_as_when_every_pair_is_tried() {
        let mut joins = 0;
        for seed in 1..40u32 {
            // Rings of crescents, some close enough to each other to be candidates, and noise.
            let circles: Vec<(f32, f32, f32)> = (0..24)
                .map(|i| {
                    let (col, row) = ((i % 6) as f32, (i / 6) as f32);
                    (30.0 + col * (20.0 + seed as f32 * 0.3), 30.0 + row * 22.0 + col * 3.0, 5.0 + (i % 3) as f32)
                })
                .collect();
            let ev = scene(&circles, 40, 300, seed);
            let mut w: Vec<WindowEvent> =
                ev.iter().map(|e| WindowEvent { x: e.x, y: e.y, dt_us: e.t_us as u32 }).collect();
            let mut c: Clusterer<2048, 64> = Clusterer::new();
            c.cluster(&mut w, SensorSize::DAVIS346, &ClusterConfig::default(), &mut [0; TABLE_CELLS]);
            let (mut boxes, mut sums) = (Vec::new(), Vec::new());
            for r in c.group(&mut w) {
                let part = &w[usize::from(r.start)..usize::from(r.end)];
                boxes.push(part.iter().fold([u16::MAX, u16::MAX, 0, 0], |b, e| {
                    [b[0].min(e.x), b[1].min(e.y), b[2].max(e.x), b[3].max(e.y)]
                }));
                sums.push(Moments::of(part, 0));
            }
            // The clusters in a shuffled order too: the sweep sorts them itself.
            for shuffle in [false, true] {
                if shuffle {
                    let k = boxes.len();
                    for i in 0..k {
                        let j = (i * 7 + seed as usize) % k;
                        boxes.swap(i, j);
                        sums.swap(i, j);
                    }
                }
                let mut fast = [0u16; 64];
                let mut naive = [0u16; 64];
                for (i, (f, n)) in fast.iter_mut().zip(naive.iter_mut()).enumerate() {
                    (*f, *n) = (i as u16, i as u16);
                }
                let m = join_pairs(&boxes, &sums, &mut fast);
                assert_eq!(m, join_pairs_naive(&boxes, &sums, &mut naive), "seed {seed}");
                for i in 0..boxes.len() {
                    assert_eq!(root(&fast, i), root(&naive, i), "seed {seed}, cluster {i}");
                }
                joins += m;
            }
        }
        assert!(joins > 20, "the scenes must join crescents: {joins}");
    }

    #[test]
    fn finds_every_ring_of_a_clean_scene() {
        let circles =
            [(60.0, 60.0, 7.0), (120.0, 60.0, 7.0), (180.0, 60.0, 7.5), (60.0, 150.0, 6.5), (150.0, 170.0, 9.0)];
        let events = scene(&circles, 150, 200, 7);
        let mut cfg = DetectConfig::new(SensorSize::DAVIS346);
        cfg.window = WindowConfig { events: events.len(), step_us: 0 };
        let mut det: Detector<1024, 32> = Detector::new(cfg);
        let mut found = None;
        for e in &events {
            if let Some(d) = det.push(*e) {
                found = Some(d.clone());
            }
        }
        let d = found.expect("one window");
        // The centres are given at the window's middle: the rings moved 0.2 px/ms.
        let mid = (d.info.t_ref_us - d.info.t_first_us) as f32 * 1e-3;
        for &(cx, cy, r) in &circles {
            let best = d
                .centres
                .iter()
                .map(|c| ((c.u - cx - 0.2 * mid).powi(2) + (c.v - cy).powi(2)).sqrt())
                .fold(f32::INFINITY, f32::min);
            assert!(best < 0.25, "ring at ({cx}, {cy}) r {r}: nearest centre {best} px away; {:?}", d.centres);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Any stream of events: no panic, windows as configured, finite centres.
        #[test]
        fn any_stream_gives_consistent_windows(
            raw in prop::collection::vec((0u16..400, 0u16..300, 0u32..300, any::<bool>()), 0..3000),
            per_window in 1usize..800,
            eps in 0.0f32..0.1,
            min_pts in 0u16..15,
        ) {
            let mut cfg = DetectConfig::new(SensorSize::DAVIS346);
            cfg.window = WindowConfig { events: per_window, step_us: 2_000 };
            cfg.cluster = ClusterConfig { eps, min_pts, eps_t: None };
            let mut det: Detector<1024, 16> = Detector::new(cfg);
            let mut t = 0u64;
            for (x, y, dt, p) in raw {
                t += u64::from(dt);
                if let Some(d) = det.push(Event { t_us: t, x, y, polarity: p }) {
                    prop_assert_eq!(usize::from(d.stats.events), per_window.min(1024));
                    prop_assert!(d.info.t_first_us <= d.info.t_ref_us && d.info.t_ref_us <= d.info.t_last_us);
                    prop_assert!(d.centres.len() <= 16);
                    for c in &d.centres {
                        prop_assert!(c.u.is_finite() && c.v.is_finite() && c.r > 0.0 && c.spread.is_finite());
                    }
                }
            }
        }
    }
}

/// In-place reconfiguration and the clock's window hooks.
#[cfg(test)]
mod reconfigure_and_hooks {
    use super::*;
    use crate::window::WindowConfig;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Two rings of radius 6 that drift, plus scattered pixels: windows with circles.
    fn events(n: u64, seed: u64) -> Vec<Event> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|i| {
                let h = rng.random::<u64>() >> 40;
                let (cx, cy) =
                    if i % 2 == 0 { (18.0 + i as f32 / 900.0, 16.0) } else { (42.0, 26.0 + i as f32 / 1000.0) };
                let a = (h % 360) as f32 * core::f32::consts::PI / 180.0;
                let (x, y) = if h % 9 == 0 {
                    ((h % 60) as f32, ((h >> 8) % 40) as f32)
                } else {
                    (cx + 6.0 * a.cos(), cy + 6.0 * a.sin())
                };
                Event { t_us: i * 3, x: x.round() as u16, y: y.round() as u16, polarity: h % 2 == 0 }
            })
            .collect()
    }

    fn run(det: &mut Detector<256, 16>, evs: &[Event]) -> Vec<Detection<16>> {
        evs.iter().filter_map(|e| det.push(*e).cloned()).collect()
    }

    /// Counts the hooks and readings of a clock, checking the hooks bracket the readings.
    #[derive(Default)]
    struct Probe {
        begins: u32,
        ends: u32,
        readings_inside: u32,
    }

    impl Clock for Probe {
        fn now(&mut self) -> u32 {
            assert_eq!(self.begins, self.ends + 1, "read outside a window's processing");
            self.readings_inside += 1;
            self.readings_inside
        }
        fn window_begins(&mut self) {
            assert_eq!(self.begins, self.ends);
            self.begins += 1;
        }
        fn window_ends(&mut self) {
            self.ends += 1;
            assert_eq!(self.begins, self.ends);
        }
    }

    #[test]
    fn hooks_bracket_each_processed_window_once() {
        let mut cfg = DetectConfig::new(SensorSize::new(64, 48));
        cfg.window = WindowConfig { events: 200, step_us: 0 };
        cfg.cluster.eps = 0.06;
        let mut det: Box<Detector<256, 16>> = Box::new(Detector::new(cfg));
        let mut probe = Probe::default();
        let mut windows = 0;
        for e in events(1000, 3) {
            if det.feed(e) {
                det.process(&mut probe);
                // a second call without a new window processes nothing
                det.process(&mut probe);
                windows += 1;
            }
        }
        assert_eq!((windows, probe.begins, probe.ends), (5, 5, 5));
        assert!(probe.readings_inside >= 10);
    }

    #[test]
    fn reconfigure_is_the_same_as_new() {
        let mut a = DetectConfig::new(SensorSize::new(64, 48));
        a.window = WindowConfig { events: 200, step_us: 700 };
        a.cluster.eps = 0.06;
        let mut b = DetectConfig::new(SensorSize::new(60, 40));
        b.window = WindowConfig { events: 250, step_us: 0 };
        b.cluster.eps = 0.07;
        b.cluster.min_pts = 6;
        let (ea, eb) = (events(3000, 1), events(2500, 2));

        let mut reused: Box<Detector<256, 16>> = Box::new(Detector::new(a));
        let first = run(&mut reused, &ea);
        assert!(first.len() >= 5 && first.iter().any(|d| !d.centres.is_empty()), "the data make detections");
        reused.reconfigure(b);
        assert_eq!(reused.config(), b);
        assert_eq!((reused.pending(), reused.input_stats()), (0, InputStats::default()));
        let again = run(&mut reused, &eb);

        let mut fresh: Box<Detector<256, 16>> = Box::new(Detector::new(b));
        let want = run(&mut fresh, &eb);
        assert!(want.len() >= 5);
        assert_eq!(again, want);
        assert_eq!(reused.input_stats(), fresh.input_stats());
    }
}
