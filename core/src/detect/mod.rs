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
    extent::Extent,
    fit::{fit_in, fit_with, Centre, FitConfig, FitMethod},
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

#[cfg(test)]
mod hooks_tests;
mod join;
mod recruit;
#[cfg(test)]
mod tests;

use join::{join_crescents, join_fitted, CLUSTER_GIVE_UP};
use recruit::recruit;
