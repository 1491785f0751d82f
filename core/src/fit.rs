//! eRWLS: fits the slanted cylinder that a moving circle leaves in (x, y, t) and gives its
//! sub-pixel centre at the window's reference time.
//!
//! Model: at time τ (milliseconds since `t_ref`) the circle's edge is the circle of radius
//! `r` centred at `(u + a·τ, v + b·τ)`. This is a sheared cylinder: the surface a circle that
//! translates across the sensor actually leaves, where the paper tilts a right cylinder by
//! angles β, α; for the small tilts of one window the two agree, and the shear keeps every
//! horizontal slice a true circle. The residual of an event is its geometric distance from
//! that circle, `ξ = ‖(x − u − aτ, y − v − bτ)‖ − r`, in pixels (the paper's eq. 5 up to the
//! algebraic form; the geometric one makes the weights' σ a distance users can read).
//!
//! eRWLS (paper eq. 6–7): every iteration weighs each event by a Gaussian of its residual,
//! `w = exp(−ξ² / 2σ²)`, and takes one Levenberg–Marquardt step of the weighted problem.
//! The paper takes μ and σ as the residuals' mean and standard deviation. Here μ is 0 (at
//! every weighted optimum `Σ wξ = 0`, since r is free) and σ comes from the residuals' median
//! absolute value, which clutter and noise events cannot inflate while they are fewer than
//! the edge's own events; a plain standard deviation grows with every outlier and stops
//! rejecting them. The kernel is `KERNEL_WIDTH` times that inlier spread.
//!
//! Everything is `f32` with the `math` module's square roots and exponential (no `libm`), in
//! a fixed order, so the host and the Cortex-M4F compute the same bits.

use crate::{
    arc::{solve_spd, Circle, Moments},
    math::{exp_neg, inv_sqrt, max, sqrt},
    window::WindowEvent,
};

/// Which estimator [`fit`] uses. `Centroid` and `Ols` exist for the ablation of the paper's
/// Table II; `Erwls` is the method evcal uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FitMethod {
    /// Plain mean of the cluster's pixel coordinates; radius = mean distance to it.
    Centroid,
    /// Unweighted least squares of the cylinder (Levenberg–Marquardt, no reweighting).
    Ols,
    /// Reweighted least squares with Gaussian weights of the residuals (paper eq. 6–7).
    Erwls,
}

/// Settings of the circle fit.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FitConfig {
    /// The estimator.
    pub method: FitMethod,
    /// Most Levenberg–Marquardt iterations.
    pub max_iterations: u8,
    /// Fewest events a cluster needs to be fitted.
    pub min_events: u16,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            method: FitMethod::Erwls,
            max_iterations: crate::config::DEFAULT_MAX_ITERATIONS,
            min_events: crate::config::DEFAULT_MIN_CLUSTER_EVENTS,
        }
    }
}

/// A fitted circle: its centre at the window's reference time and how well it fits.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Centre {
    /// Centre column at `t_ref`, pixels (0 = centre of the leftmost pixel).
    pub u: f32,
    /// Centre row at `t_ref`, pixels (0 = centre of the top pixel).
    pub v: f32,
    /// Radius, pixels.
    pub r: f32,
    /// Velocity of the centre along x (cylinder tilt), pixels per millisecond.
    pub vu: f32,
    /// Velocity of the centre along y (cylinder tilt), pixels per millisecond.
    pub vv: f32,
    /// Weighted RMS distance of the events from the fitted circle, pixels.
    pub spread: f32,
    /// Events in the cluster that was fitted.
    pub n: u16,
    /// Whether the fit converged within the iteration limit.
    pub converged: bool,
}

/// Smallest σ of the weights, pixels. Events sit on a pixel grid whose rounding alone spreads
/// them uniformly by ±0.5 px; weights much narrower than that select events by rounding luck
/// and pull the centre towards wherever the rounding happened to agree with the current fit.
const MIN_SIGMA: f32 = 0.7;
/// Width of the weighting Gaussian in units of the inliers' own spread. Measured on the unit
/// tests' cylinders (2000 clean events; 300 with 15 % scattered noise and a clump of 40 beside
/// the edge), RMS centre error: at 1.0, 0.056 px clean (plain least squares 0.038); at 1.5,
/// 0.045 clean and 0.145 noisy (least squares 0.87); at 2.0, 0.041 and 0.161.
const KERNEL_WIDTH: f32 = 1.5;
/// Weights below `exp(−18)` are taken as zero: such events change nothing, cost nothing, and
/// never produce denormals (which the M4F and the host would treat alike, but slowly).
const MAX_WEIGHT_EXPONENT: f32 = 18.0;
/// A fit has converged when an accepted step moves the centre and radius (and the circle, by
/// its velocity, over the cluster's time span) less than this, px: a tenth of the centre
/// error a window's fit reaches (0.2 px). Measured (detection tests: DAVIS346 cone good
/// and low light, 4000 and 16000 events a window, DVXplorer spiral): 2e-2 leaves every found
/// rate and centre RMS as at 1e-2 to the third decimal; 3e-2 moves low light 0.316 -> 0.317
/// px and 16000-event windows 0.150 -> 0.151 px. Against 1e-2 it ends many fits of circles a
/// pass earlier, and the passes of circles' fits (tilted ones, mostly; clutter is a sixth)
/// are the bulk of the slowest windows' fitting (M4F: 1.62 -> 1.44 M instructions of fitting
/// a window on average, 2.24 -> 2.00 M at most). Before the ellipse step, with the tilt
/// fitted from 160 events, 5e-3 gave centre RMS 0.2045 px, 1e-2 0.2051, 2e-2 0.2063 on the
/// DAVIS346 cone.
const STEP_TOLERANCE: f32 = 2e-2;
/// Histogram of absolute residuals for the robust scale: bin width (px) and count.
const HIST_BIN: f32 = 0.125;
const HIST_BINS: usize = 64;

/// Fits one cluster's events (times relative to the window's `t_ref`) and returns its
/// centre at `t_ref`, or `None` when the cluster is too small, the events are degenerate
/// (a line, a point), the events lie on no circle (for eRWLS: 5 px RMS from their algebraic
/// circle, or a weighted spread beyond 3 px) or the fit lands somewhere no circle of these
/// events can be.
///
/// Cost: a few passes over the events per iteration, no allocation, no recursion.
pub fn fit(events: &[WindowEvent], t_ref_us: u32, cfg: &FitConfig) -> Option<Centre> {
    fit_from(&[events], None, t_ref_us, cfg)
}

/// [`fit`] of the events of all of `parts` together, started from `start`, the algebraic
/// circle through them when the caller has it already (see [`Moments`]); `None` computes
/// it.
pub fn fit_from(parts: &[&[WindowEvent]], start: Option<Circle>, t_ref_us: u32, cfg: &FitConfig) -> Option<Centre> {
    let mut scratch = [[0.0f32; 3]; 64];
    fit_with(parts, start, t_ref_us, cfg, &mut scratch)
}

/// [`fit_from`] with the caller's scratch for the events' coordinates in the fit's local
/// frame: a fit of at most `scratch.len()` events converts them once for all its passes, a
/// larger one converts them again on every pass, `scratch.len()` at a time. An eRWLS fit of
/// at most 3/8 of `scratch.len()` events also keeps each pass's weights in the rest, for
/// fewer instructions. The result is the same, bit for bit, whatever the scratch's size
/// (empty: one event at a time).
pub fn fit_with(
    parts: &[&[WindowEvent]],
    start: Option<Circle>,
    t_ref_us: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
) -> Option<Centre> {
    fit_within(parts, start, t_ref_us, cfg, scratch, MAX_SPREAD)
}

/// [`fit_with`] for a caller that needs the fit only if its weighted spread ends within
/// `give_up` px (less than the default `MAX_SPREAD` of 3 px): an eRWLS fit whose spread is
/// beyond `give_up` from its second pass on ends there with `None`, without its remaining
/// passes. The spread shrinks only slowly once the kernel follows the residuals' median
/// (see `MAX_SPREAD`), so a fit beyond `give_up` after two passes would end beyond a
/// threshold well below it.
pub fn fit_within(
    parts: &[&[WindowEvent]],
    start: Option<Circle>,
    t_ref_us: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
    give_up: f32,
) -> Option<Centre> {
    fit_in(parts, None, start, t_ref_us, cfg, scratch, give_up)
}

/// [`fit_within`] of events whose [`Extent`] the caller has already (`None`: taken here).
pub(crate) fn fit_in(
    parts: &[&[WindowEvent]],
    extent: Option<&Extent>,
    start: Option<Circle>,
    t_ref_us: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
    give_up: f32,
) -> Option<Centre> {
    let n: usize = parts.iter().map(|p| p.len()).sum();
    if n < usize::from(cfg.min_events.max(5)) || n > usize::from(u16::MAX) {
        return None;
    }
    let frame = extent.map_or_else(|| Frame::of(parts), Frame::from_extent);
    let result = match cfg.method {
        FitMethod::Centroid => centroid(parts, &frame),
        FitMethod::Ols | FitMethod::Erwls => {
            let start = start.or_else(|| {
                let mut m = Moments::of(parts[0], t_ref_us);
                for p in &parts[1..] {
                    m.add(&Moments::of(p, t_ref_us));
                }
                m.circle()
            })?;
            // A start larger than the events' extent, or centred far outside them, is the
            // algebraic fit of a nearly straight edge: no circle, and no fit will make one.
            let extent = 2.0 * max(frame.half_w, frame.half_h) + 1.0;
            let (du, dv) = ((start.u - frame.x0).abs(), (start.v - frame.y0).abs());
            if start.r > 2.0 * extent || du > frame.half_w + 2.0 * start.r || dv > frame.half_h + 2.0 * start.r {
                return None;
            }
            // Nor will eRWLS make one of events this far from their algebraic circle.
            if cfg.method == FitMethod::Erwls && start.rms > MAX_START_RMS {
                return None;
            }
            let mut one = [[0.0f32; 3]; 1];
            let scratch = if scratch.is_empty() { &mut one[..] } else { scratch };
            let mut events = Events::new(parts, n, &frame, scratch);
            cylinder(&mut events, &frame, &start, t_ref_us as f32 * 1e-3, cfg, give_up.min(MAX_SPREAD))
        }
    }?;
    frame.accept(result, n as u16, t_ref_us as f32 * 1e-3)
}

/// The integer summary of a set of events that a fit's local frame is made from: their
/// bounding box, time span, and the sum of their times. Extents of disjoint sets join
/// exactly into that of their union, so a caller that has them already (see
/// [`detect::process`](crate::detect::process)) spares the fit a pass over the events.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Extent {
    pub(crate) x_lo: u16,
    pub(crate) x_hi: u16,
    pub(crate) y_lo: u16,
    pub(crate) y_hi: u16,
    pub(crate) t_lo: u32,
    pub(crate) t_hi: u32,
    t_sum: u64,
    count: u32,
}

impl Extent {
    /// Of no events.
    pub(crate) const EMPTY: Self =
        Self { x_lo: u16::MAX, x_hi: 0, y_lo: u16::MAX, y_hi: 0, t_lo: u32::MAX, t_hi: 0, t_sum: 0, count: 0 };

    /// Takes in one event.
    #[inline(always)]
    pub(crate) fn add(&mut self, e: &WindowEvent) {
        self.t_lo = self.t_lo.min(e.dt_us);
        self.t_hi = self.t_hi.max(e.dt_us);
        self.x_lo = self.x_lo.min(e.x);
        self.x_hi = self.x_hi.max(e.x);
        self.y_lo = self.y_lo.min(e.y);
        self.y_hi = self.y_hi.max(e.y);
        self.t_sum += u64::from(e.dt_us);
    }

    /// Takes in `events` (fewer than 2³² in all).
    pub(crate) fn add_all(&mut self, events: &[WindowEvent]) {
        for e in events {
            self.add(e);
        }
        self.count = self.count.wrapping_add(events.len() as u32);
    }

    /// Becomes the extent of the union with `other`'s (disjoint) events.
    pub(crate) fn join(&mut self, other: &Self) {
        self.x_lo = self.x_lo.min(other.x_lo);
        self.x_hi = self.x_hi.max(other.x_hi);
        self.y_lo = self.y_lo.min(other.y_lo);
        self.y_hi = self.y_hi.max(other.y_hi);
        self.t_lo = self.t_lo.min(other.t_lo);
        self.t_hi = self.t_hi.max(other.t_hi);
        self.t_sum += other.t_sum;
        self.count = self.count.wrapping_add(other.count);
    }
}

/// Local coordinates: pixels relative to the cluster's bounding-box centre and time in
/// milliseconds relative to the cluster's mean time, so that f32 keeps full precision and
/// the centre is uncorrelated with the velocity while fitting.
struct Frame {
    x0: f32,
    y0: f32,
    /// Mean event time, ms since `t_ref`.
    tc: f32,
    half_w: f32,
    half_h: f32,
    /// Largest |τ| of the cluster's events, ms: converts velocity steps into pixels.
    t_reach: f32,
}

/// A fit in the local frame: centre at the mean time, velocity, radius, spread.
#[derive(Clone, Copy)]
struct Local {
    p: [f32; 5],
    spread: f32,
    converged: bool,
}

impl Frame {
    fn of(parts: &[&[WindowEvent]]) -> Self {
        let mut x = Extent::EMPTY;
        for part in parts {
            x.add_all(part);
        }
        Self::from_extent(&x)
    }

    /// The frame of events whose [`Extent`] is `x`: the same bits as [`of`](Self::of) those
    /// events, since an extent is made of integers whatever the order they were taken in.
    fn from_extent(x: &Extent) -> Self {
        let Extent { x_lo, x_hi, y_lo, y_hi, t_lo, t_hi, t_sum, count } = *x;
        let t_mean_us = t_sum / u64::from(count.max(1));
        let tc = t_mean_us as f32 * 1e-3;
        Self {
            // Halves of integers: exact in f32.
            x0: (f32::from(x_lo) + f32::from(x_hi)) * 0.5,
            y0: (f32::from(y_lo) + f32::from(y_hi)) * 0.5,
            tc,
            t_reach: max(tc - t_lo as f32 * 1e-3, t_hi as f32 * 1e-3 - tc),
            half_w: (f32::from(x_hi) - f32::from(x_lo)) * 0.5,
            half_h: (f32::from(y_hi) - f32::from(y_lo)) * 0.5,
        }
    }

    #[inline]
    fn local(&self, e: &WindowEvent) -> (f32, f32, f32) {
        (f32::from(e.x) - self.x0, f32::from(e.y) - self.y0, e.dt_us as f32 * 1e-3 - self.tc)
    }

    /// Back to sensor pixels at `t_ref`, after the checks that keep arcs of straight edges
    /// and runaway fits out.
    fn accept(&self, l: Local, n: u16, t_ref_ms: f32) -> Option<Centre> {
        let [u, v, a, b, r] = l.p;
        let u_ref = self.x0 + u + a * (t_ref_ms - self.tc);
        let v_ref = self.y0 + v + b * (t_ref_ms - self.tc);
        let finite = [u_ref, v_ref, a, b, r, l.spread].iter().all(|q| q.is_finite());
        // A circle larger than the cluster's whole extent is a fit to a nearly straight
        // edge; a centre beyond one radius outside the box belongs to no circle of these events.
        let extent = 2.0 * max(self.half_w, self.half_h) + 1.0;
        let plausible = r > 0.5 && r <= extent && u.abs() <= self.half_w + r && v.abs() <= self.half_h + r;
        (finite && plausible).then_some(Centre {
            u: u_ref,
            v: v_ref,
            r,
            vu: a,
            vv: b,
            spread: l.spread,
            n,
            converged: l.converged,
        })
    }
}

fn centroid(parts: &[&[WindowEvent]], f: &Frame) -> Option<Local> {
    let events = || parts.iter().flat_map(|p| p.iter());
    let inv_n = 1.0 / events().count().max(1) as f32;
    let (mut sx, mut sy) = (0.0f32, 0.0f32);
    for e in events() {
        let (x, y, _) = f.local(e);
        sx += x;
        sy += y;
    }
    let (u, v) = (sx * inv_n, sy * inv_n);
    let (mut sd, mut sd2) = (0.0f32, 0.0f32);
    for e in events() {
        let (x, y, _) = f.local(e);
        let d = sqrt((x - u) * (x - u) + (y - v) * (y - v));
        sd += d;
        sd2 += d * d;
    }
    let r = sd * inv_n;
    let spread = sqrt((sd2 * inv_n - r * r).max(0.0));
    // The centroid has no time model: it is the centre of the events' mean time, and `tc`
    // is undone in `accept` with zero velocity.
    Some(Local { p: [u, v, 0.0, 0.0, r], spread, converged: true })
}

/// Fewest events for the cylinder's tilt (the circle's velocity) to be fitted. A still fit
/// gives the centre at the cluster's own mean event time, and the circles of one window fire
/// at different times within it, so each still centre is off by its velocity times its
/// own lead or lag: small against the truth on average, but different from circle to
/// circle, which no pose explains. Measured both ways on simulated recordings (threshold
/// 48 → 160): centre RMS against the truth improves a little (DAVIS346 cone 0.2080 → 0.2051
/// px good light, 0.3060 → 0.3032 low light; DVXplorer spiral 0.2205 → 0.2171), but the
/// calibration's reprojection RMS on the continuous DVXplorer 3x9 spiral goes from 0.198 to
/// 0.227 px (its large, fast circles), with DAVIS346 unchanged to 0.001 px. The calibration
/// is what users get, so the tilt is fitted from 48 events; it costs the M4F about
/// half as much again per event in a tilted pass.
const TILT_MIN_EVENTS: usize = 48;
/// A step that moves the centre by more than this fraction of the radius is shortened to it:
/// Gauss–Newton from the algebraic start is well behaved, but a wild step on a degenerate
/// cluster must not throw the fit somewhere it cannot come back from.
const MAX_STEP_FRACTION: f32 = 0.25;
/// Largest weighted spread, px, of an eRWLS fit from its second pass on: beyond it the events
/// lie on no circle and the fit gives up. From the second pass the kernel follows the
/// residuals' median, so a circle's own events weigh in and clutter beside it weighs out,
/// and the spread is the edge's (some 0.3–0.6 px on simulated recordings, and fragments of
/// circles that join stay within 1.5 px, see `detect`). The clusters beyond it are clutter of
/// hundreds of events (simulated DAVIS346 cone: 300–1000 events, spread 3–9 px), which ran all
/// their iterations as tilted cylinders: a third of the window's passes over events. Centre
/// RMS and found rates of the simulated recordings are unchanged to the fourth decimal.
pub(crate) const MAX_SPREAD: f32 = 3.0;
/// Largest weighted spread, px, of an eRWLS fit's first pass (whose kernel comes from the
/// start's RMS, not yet from the residuals' median, see [`MAX_SPREAD`]). Clutter that starts
/// within [`MAX_START_RMS`] mostly ends between 1 and 3 px after all its iterations (a fifth
/// of a window's passes, tilted ones mostly); circles start within a pixel or so. On five
/// simulated recordings (DAVIS346 cone good and low light, square low light; DVXplorer
/// spiral; 345 windows, 20 000 fits) no fit that ended within 1 px had a first pass beyond
/// 2.5 px, and 1 in 70 of the fits (all of them ending beyond 1 px) are given up there.
const FIRST_MAX_SPREAD: f32 = 2.5;
/// Largest RMS distance, px, of a cluster's events from their algebraic circle (the fit's
/// start) for eRWLS to try: beyond it the cluster is clutter whose fit would end beyond
/// [`MAX_SPREAD`] anyway, after two passes over hundreds of events. Not robust, so wider than
/// [`MAX_SPREAD`]: a crescent with clutter attached starts a few pixels off and the weights
/// then find its circle. On the simulated recordings, 3 px lost a circle in a thousand; 4 and
/// 5 px none (centre RMS and found rates unchanged to the fourth decimal), and 5 px skips
/// three quarters of the tilted passes that remained in 4000-event windows.
const MAX_START_RMS: f32 = 5.0;

/// The weights' σ for a median absolute residual (1.4826·MAD is σ for Gaussian inliers).
fn kernel(mad: f32) -> f32 {
    KERNEL_WIDTH * max(1.4826 * mad, MIN_SIGMA)
}

/// Histogram of absolute residuals, for their median without a sort or a buffer.
struct Histogram {
    bins: [u16; HIST_BINS],
    count: u32,
}

impl Histogram {
    const fn new() -> Self {
        Self { bins: [0; HIST_BINS], count: 0 }
    }

    /// Counts one residual in its bin; `count` is set once the pass is done (a store per
    /// event saved).
    #[inline]
    fn add(&mut self, abs_residual: f32) {
        // The last bin collects everything beyond the histogram (a NaN casts to bin 0).
        let k = ((abs_residual * (1.0 / HIST_BIN)) as usize).min(HIST_BINS - 1);
        // A fit takes at most `u16::MAX` events (see `fit_from`): no bin overflows.
        debug_assert!(self.bins[k] < u16::MAX, "more residuals in one pass than a fit takes events");
        self.bins[k] = self.bins[k].wrapping_add(1);
    }

    /// The median, interpolated within its bin.
    fn median(&self) -> f32 {
        let half = self.count as f32 * 0.5;
        let mut acc = 0.0f32;
        for (k, &c) in self.bins.iter().enumerate() {
            let c = f32::from(c);
            if acc + c >= half && c > 0.0 {
                return (k as f32 + (half - acc) / c) * HIST_BIN;
            }
            acc += c;
        }
        HIST_BINS as f32 * HIST_BIN
    }
}

/// The residual weights of one pass: a Gaussian of width `sigma`, or all ones.
#[derive(Clone, Copy)]
struct Weights {
    reweight: bool,
    sigma: f32,
}

/// What one pass over the events at parameters `p` gives: the weighted normal equations
/// `JᵀWJ` (lower triangle) and `JᵀWξ`, and the weighted sums for the spread. The histogram
/// of |ξ| for the next kernel width goes to the caller's (returned inside `Pass` it was
/// copied on every pass).
struct Pass {
    a: [[f32; 5]; 5],
    g: [f32; 5],
    sw: f32,
    swe2: f32,
    /// How many records of the events of nonzero weight [`weigh`] left in the scratch's tail,
    /// if it did.
    records: Option<usize>,
    /// The kernel's `1/2σ²` of the pass.
    scale: f32,
}

/// What the ellipse (see [`ellipse_offset`]) needs of a fit's last pass: its parameters,
/// kernel (`1/2σ²`) and records.
struct LastPass {
    p: [f32; 5],
    scale: f32,
    records: Option<usize>,
}

/// A fit's events in its local frame, `[x, y, τ]` as [`Frame::local`] gives them: all of
/// them converted once into the scratch when they fit there, else converted a scratchful at
/// a time on every pass.
struct Events<'p, 's> {
    parts: &'p [&'p [WindowEvent]],
    n: usize,
    scratch: &'s mut [[f32; 3]],
    /// Whether `scratch` holds all `n` events.
    held: bool,
}

impl<'p, 's> Events<'p, 's> {
    /// `n` is the events in `parts`; `scratch` is not empty.
    fn new(parts: &'p [&'p [WindowEvent]], n: usize, f: &Frame, scratch: &'s mut [[f32; 3]]) -> Self {
        let held = n <= scratch.len();
        let mut events = Self { parts, n, scratch, held };
        if held {
            events.convert(f, &mut (0, 0));
        }
        events
    }

    /// Converts the events from position `at` (part, index in it) on into the scratch, as
    /// many as it holds, and moves `at` past them; returns how many.
    fn convert(&mut self, f: &Frame, at: &mut (usize, usize)) -> usize {
        let mut m = 0;
        while m < self.scratch.len() {
            let Some(part) = self.parts.get(at.0) else { break };
            let rest = part.get(at.1..).unwrap_or(&[]);
            let room = self.scratch.get_mut(m..).unwrap_or(&mut []);
            let take = rest.len().min(room.len());
            for (o, e) in room.iter_mut().zip(rest) {
                let (x, y, t) = f.local(e);
                *o = [x, y, t];
            }
            m += take;
            at.1 += take;
            if at.1 >= part.len() {
                *at = (at.0 + 1, 0);
            }
        }
        m
    }
}

/// The weighted sums one pass accumulates (see [`pass_with`]), carried from one scratchful
/// of events to the next so that every sum adds its events in the same order.
#[derive(Clone, Copy, Default)]
struct Sums {
    sxx: f32,
    sxy: f32,
    syy: f32,
    sxxt: f32,
    sxyt: f32,
    syyt: f32,
    sxxtt: f32,
    sxytt: f32,
    syytt: f32,
    sx: f32,
    sy: f32,
    sxt: f32,
    syt: f32,
    sw: f32,
    gx: f32,
    gy: f32,
    gxt: f32,
    gyt: f32,
    g1: f32,
    swe2: f32,
}

impl Sums {
    /// Adds one event of weight `wi`, unit direction (`cx`, `cy`) from the centre, residual
    /// `xi` and time `t`. Inlined into each pass's loop, where the sums of a local copy stay
    /// in registers.
    #[inline(always)]
    fn add<const TILT: bool>(&mut self, wi: f32, cx: f32, cy: f32, xi: f32, t: f32) {
        let (wx, wy) = (wi * cx, wi * cy);
        let (wxx, wxy, wyy) = (wx * cx, wx * cy, wy * cy);
        self.sxx += wxx;
        self.sxy += wxy;
        self.syy += wyy;
        self.sx += wx;
        self.sy += wy;
        self.sw += wi;
        let (wxi, wxxi, wyxi) = (wi * xi, wx * xi, wy * xi);
        self.gx += wxxi;
        self.gy += wyxi;
        self.g1 += wxi;
        self.swe2 += wxi * xi;
        if TILT {
            self.sxxt += wxx * t;
            self.sxyt += wxy * t;
            self.syyt += wyy * t;
            let tt = t * t;
            self.sxxtt += wxx * tt;
            self.sxytt += wxy * tt;
            self.syytt += wyy * tt;
            self.sxt += wx * t;
            self.syt += wy * t;
            self.gxt += wxxi * t;
            self.gyt += wyxi * t;
        }
    }
}

fn pass(ev: &mut Events, f: &Frame, p: &[f32; 5], w: &Weights, tilt: bool, hist: &mut Histogram) -> Pass {
    *hist = Histogram::new();
    hist.count = ev.n as u32;
    // exp(−ξ²/2σ²) with the division done once.
    let scale = 0.5 / (w.sigma * w.sigma);
    // Copies of the loop: a still circle needs neither the time columns nor their sums (and
    // most clusters are fitted still), and plain least squares no weights.
    let run = match (tilt, w.reweight) {
        (true, true) => pass_with::<true, true>,
        (true, false) => pass_with::<true, false>,
        (false, true) => pass_with::<false, true>,
        (false, false) => pass_with::<false, false>,
    };
    let mut s = Sums::default();
    let mut made = None;
    let (held, tail) = ev.scratch.split_at_mut(ev.n.min(ev.scratch.len()));
    let records = tail.as_flattened_mut();
    if ev.held && w.reweight && records.len() >= RECORD * ev.n {
        let kept = if tilt {
            weigh::<true>(held, p, scale, hist, records)
        } else {
            weigh::<false>(held, p, scale, hist, records)
        };
        made = Some(kept);
        let records = records.get(..kept * RECORD).unwrap_or(&[]);
        if tilt {
            sum_records::<true>(records, &mut s);
        } else {
            sum_records::<false>(records, &mut s);
        }
    } else if ev.held {
        run(held, p, scale, hist, &mut s);
    } else {
        let mut at = (0, 0);
        loop {
            let m = ev.convert(f, &mut at);
            if m == 0 {
                break;
            }
            run(ev.scratch.get(..m).unwrap_or(&[]), p, scale, hist, &mut s);
        }
    }
    // Signs: each entry is a product of two components of J, each carrying a minus sign.
    let a = [
        [s.sxx, 0.0, 0.0, 0.0, 0.0],
        [s.sxy, s.syy, 0.0, 0.0, 0.0],
        [s.sxxt, s.sxyt, s.sxxtt, 0.0, 0.0],
        [s.sxyt, s.syyt, s.sxytt, s.syytt, 0.0],
        [s.sx, s.sy, s.sxt, s.syt, s.sw],
    ];
    Pass { a, g: [-s.gx, -s.gy, -s.gxt, -s.gyt, -s.g1], sw: s.sw, swe2: s.swe2, records: made, scale }
}

/// One pass's sums over `events` (local `[x, y, τ]`), added to `s`.
// Kept out of line: inlined into the fit, the loop shares the M4F's registers with the code
// around it and spills its sums (a fifth more instructions per event), for one call saved
// per iteration.
#[inline(never)]
fn pass_with<const TILT: bool, const REWEIGHT: bool>(
    events: &[[f32; 3]],
    p: &[f32; 5],
    scale: f32,
    hist: &mut Histogram,
    s: &mut Sums,
) {
    let [u, v, va, vb, r] = *p;
    // J = −(cx, cy, cx·τ, cy·τ, 1) for the unit direction (cx, cy) from the centre: JᵀWJ is
    // made of the weighted sums of cx², cx·cy, cy² times 1, τ, τ², of cx, cy times 1, τ, and
    // of w; JᵀWξ of wξ times cx, cy, cx·τ, cy·τ, 1. A local copy keeps them all in registers.
    let mut acc = *s;
    for &[x, y, t] in events {
        let (dx, dy) = if TILT { (x - u - va * t, y - v - vb * t) } else { (x - u, y - v) };
        let q = dx * dx + dy * dy;
        // NaN compares false: `q > 0` and finite below.
        if q.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            hist.add(r.abs());
            continue; // on the axis: no direction, no information about the centre
        }
        let inv = inv_sqrt(q);
        let d = q * inv;
        let xi = d - r;
        hist.add(xi.abs());
        let wi = if REWEIGHT {
            let z = xi * xi * scale;
            if z > MAX_WEIGHT_EXPONENT {
                continue;
            }
            exp_neg(z)
        } else {
            1.0
        };
        let (cx, cy) = (dx * inv, dy * inv);
        acc.add::<TILT>(wi, cx, cy, xi, t);
    }
    *s = acc;
}

/// Floats of one event's record from [`weigh`] for [`sum_records`]: its weight, unit direction
/// from the centre, residual and time.
const RECORD: usize = 5;

/// The first half of a reweighted pass over `events` (local `[x, y, τ]`): each event's
/// residual into `hist`, and for each event of nonzero weight its record
/// `[w, cx, cy, ξ, τ]` (τ of tilted fits only) packed into `records` while there is room;
/// returns how many.
// In one loop (`pass_with`), the 20 sums, the centre, the kernel and the exponential's
// constants outgrew the M4F's 32 float registers and spilled a dozen times an event; split,
// neither loop spills, for a record's five stores and loads, and the records serve the
// ellipse (see `ellipse_offset`). The sums are `pass_with`'s operations in its order.
#[inline(never)]
fn weigh<const TILT: bool>(
    events: &[[f32; 3]],
    p: &[f32; 5],
    scale: f32,
    hist: &mut Histogram,
    records: &mut [f32],
) -> usize {
    let [u, v, va, vb, r] = *p;
    let mut out = records.chunks_exact_mut(RECORD);
    let mut kept = 0;
    for &[x, y, t] in events {
        let (dx, dy) = if TILT { (x - u - va * t, y - v - vb * t) } else { (x - u, y - v) };
        let q = dx * dx + dy * dy;
        // NaN compares false: `q > 0` and finite below.
        if q.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            hist.add(r.abs());
            continue; // on the axis: no direction, no information about the centre
        }
        let inv = inv_sqrt(q);
        let d = q * inv;
        let xi = d - r;
        hist.add(xi.abs());
        let z = xi * xi * scale;
        if z > MAX_WEIGHT_EXPONENT {
            continue;
        }
        if let Some([rw, rx, ry, rxi, rt]) = out.next() {
            *rw = exp_neg(z);
            *rx = dx * inv;
            *ry = dy * inv;
            *rxi = xi;
            if TILT {
                *rt = t;
            }
            kept += 1;
        }
    }
    kept
}

/// The second half of a reweighted pass: the sums of `pass_with` over [`weigh`]'s records,
/// added to `s`.
#[inline(never)]
fn sum_records<const TILT: bool>(records: &[f32], s: &mut Sums) {
    let mut acc = *s;
    for rec in records.chunks_exact(RECORD) {
        let &[wi, cx, cy, xi, t] = rec else { break };
        acc.add::<TILT>(wi, cx, cy, xi, t);
    }
    *s = acc;
}

/// The slanted-cylinder fit: the algebraic start, then iteratively reweighted Gauss–Newton
/// (one pass over the events per iteration: weights from the residuals at the current
/// parameters, the weighted normal equations, one step). The kernel width follows the
/// residuals' median (one iteration behind, from the same pass). The tilt is fitted only for
/// clusters of at least [`TILT_MIN_EVENTS`]. `None` for events on no circle (see
/// [`MAX_SPREAD`]).
fn cylinder(
    events: &mut Events,
    f: &Frame,
    start: &Circle,
    t_ref_ms: f32,
    cfg: &FitConfig,
    max_spread: f32,
) -> Option<Local> {
    let n = events.n;
    let tilt = n >= TILT_MIN_EVENTS && f.t_reach > 0.0;
    // The start's centre moved to the cluster's mean time, the origin of the local frame.
    let lead = f.tc - t_ref_ms;
    let (a, b) = if tilt { (start.vu, start.vv) } else { (0.0, 0.0) };
    let mut p = [start.u + start.vu * lead - f.x0, start.v + start.vv * lead - f.y0, a, b, start.r];
    let reweight = cfg.method == FitMethod::Erwls;
    // The start's RMS residual is not robust (clutter in the cluster inflates it), but it only
    // sets the first iteration's kernel: the histogram of that pass sets the next one.
    let mut w = Weights { reweight, sigma: KERNEL_WIDTH * max(start.rms, MIN_SIGMA) };
    let mut converged = false;
    let mut spread = f32::INFINITY;
    let mut it = 0usize;
    let mut hist = Histogram::new();
    let mut last = LastPass { p, scale: 0.0, records: None };
    while it < usize::from(cfg.max_iterations) {
        let ps = pass(events, f, &p, &w, tilt, &mut hist);
        last = LastPass { p, scale: ps.scale, records: ps.records };
        if ps.sw > 0.0 {
            spread = sqrt(ps.swe2 / ps.sw);
        }
        let limit = if it == 0 { FIRST_MAX_SPREAD } else { max_spread };
        if reweight && spread > limit {
            return None;
        }
        // A small Marquardt damping, with a floor, keeps a velocity the window cannot observe
        // at zero rather than making the system singular.
        let mut a = ps.a;
        let floor = 1e-6 * max(a[4][4], 1.0);
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += 1e-4 * ps.a[i][i] + floor;
        }
        let rhs = ps.g.map(|x| -x);
        let step = if tilt {
            solve_spd::<5>(a, rhs)
        } else {
            // A still circle: the system of u, v, r alone, the same bits as the full one with
            // the tilt decoupled (unit diagonal, no coupling, zero gradient, zero step) but
            // without its two extra rows (two square roots among them).
            solve_spd::<3>(
                [[a[0][0], 0.0, 0.0], [a[1][0], a[1][1], 0.0], [a[4][0], a[4][1], a[4][4]]],
                [rhs[0], rhs[1], rhs[4]],
            )
            .map(|[du, dv, dr]| [du, dv, 0.0, 0.0, dr])
        };
        let Some(mut step) = step else { break };
        let moved = sqrt(step[0] * step[0] + step[1] * step[1]);
        let limit = MAX_STEP_FRACTION * max(p[4].abs(), 1.0);
        if moved > limit || !moved.is_finite() {
            let shrink = if moved.is_finite() { limit / moved } else { 0.0 };
            step = step.map(|s| s * shrink);
        }
        for (q, s) in p.iter_mut().zip(step) {
            *q += s;
        }
        // The kernel follows the residuals' spread as the fit sheds its outliers.
        if reweight {
            w.sigma = kernel(hist.median());
        }
        let tilted = max(step[2].abs(), step[3].abs()) * f.t_reach;
        if max(max(moved, step[4].abs()), tilted) < STEP_TOLERANCE {
            converged = true;
            break;
        }
        it += 1;
    }
    // `spread` is finite only after a pass, which sets `last`.
    if reweight && spread <= ELLIPSE_MAX_SPREAD {
        if let Some([du, dv]) = ellipse_offset(events, f, &last, &p, 0.5 / (w.sigma * w.sigma), tilt) {
            p[0] = last.p[0] + du;
            p[1] = last.p[1] + dv;
        }
    }
    Some(Local { p, spread, converged })
}

/// Largest weighted spread, px, of a fit that [`ellipse_offset`] refines. A circle's edge
/// leaves well under a pixel (simulated DAVIS346 cone: no fit beyond 0.88 px was a true
/// circle); the fits beyond are clutter, which ends anyhow between 1 and 3 px and is not
/// worth the M4F a pass over its events.
const ELLIPSE_MAX_SPREAD: f32 = 1.25;
/// Largest move of the centre from the fitted circle's to the ellipse's, in radii: a tilted
/// circle's image of b/a = 0.7 (46° of tilt) moves it by a few hundredths of a radius, so a
/// larger move is the conic fitting noise or clutter.
const MAX_ELLIPSE_OFFSET: f32 = 0.15;
/// Smallest ratio of the ellipse's axes accepted (b/a, from the conic's eigenvalues as
/// their ratio's square): below it the conic is no tilted circle's image.
const MIN_ELLIPSE_AXIS_RATIO_SQ: f32 = 0.25;

/// Records [`ellipse_offset`] makes at a time when the last pass left none (a reweighted
/// fit held whole, with room for its records in the rest of the scratch, leaves them; see
/// [`pass`]).
const CONIC_CHUNK: usize = 16;

/// The offset, in the local frame, from the centre of the fit's last pass (`last.p`) to the
/// centre of the ellipse through the same events, weighed as the fit's final parameters `p`
/// and kernel (`scale`, `1/2σ²`) weigh them, or `None` when the conic is no plausible ellipse.
///
/// A tilted circle's image is an ellipse, and a circle fitted to an ellipse sits at the
/// ellipse's centre only when the events weigh opposite sides alike. They do not: a pixel
/// fires as often as the edge crosses it, and under perspective the nearer side of a tilted
/// circle moves faster across the sensor than the farther one. The offset lies along the
/// tilt, which is what fixes the focal length, and on simulated spiral recordings it read as
/// fx 0.08–0.13 % long. With the fit's weights and the cylinder's velocity taken out, the
/// conic `A x² + B xy + (1 − A) y² + D x + E y + F = 0` (in radii about the circle's centre;
/// the normalisation excludes no ellipse near a circle) is fitted by weighted algebraic least
/// squares, and its centre is the ellipse's.
///
/// The events come from the last pass's records (see [`weigh`]; a fit without them makes
/// the same ones again, a few at a time), which spares the conic the square root and
/// distance of a pass over the events of its own: it had been a sixth of the slowest
/// windows' fitting.
fn ellipse_offset(
    ev: &mut Events,
    f: &Frame,
    last: &LastPass,
    p: &[f32; 5],
    scale: f32,
    tilt: bool,
) -> Option<[f32; 2]> {
    let r = last.p[4];
    if r.partial_cmp(&0.5) != Some(core::cmp::Ordering::Greater) {
        return None;
    }
    let at = &last.p;
    let moments = if tilt { conic_moments::<true> } else { conic_moments::<false> };
    let mut m = [0.0f32; 15];
    if let Some(kept) = last.records {
        let records = ev.scratch.get(ev.n..).unwrap_or(&[]).as_flattened();
        moments(records.get(..kept * RECORD).unwrap_or(&[]), last, p, scale, &mut m);
    } else {
        // The same records, a few at a time, in the same order: the same bits.
        let mut buf = [0.0f32; RECORD * CONIC_CHUNK];
        let mut hist = Histogram::new();
        let mut add = |events: &[[f32; 3]]| {
            for chunk in events.chunks(CONIC_CHUNK) {
                let kept = if tilt {
                    weigh::<true>(chunk, at, last.scale, &mut hist, &mut buf)
                } else {
                    weigh::<false>(chunk, at, last.scale, &mut hist, &mut buf)
                };
                moments(buf.get(..kept * RECORD).unwrap_or(&[]), last, p, scale, &mut m);
            }
        };
        if ev.held {
            add(ev.scratch.get(..ev.n).unwrap_or(&[]));
        } else {
            let mut at = (0, 0);
            loop {
                let k = ev.convert(f, &mut at);
                if k == 0 {
                    break;
                }
                add(ev.scratch.get(..k).unwrap_or(&[]));
            }
        }
    }
    let [s00, s10, s01, s20, s11, s02, s30, s21, s12, s03, s40, s31, s22, s13, s04] = m;
    // The normal equations' lower triangle, row by row, and right-hand side, for rows
    // Z = (x² − y², xy, x, y, 1) and the target −y².
    let s = [
        s40 - 2.0 * s22 + s04,
        s31 - s13,
        s22,
        s30 - s12,
        s21,
        s20,
        s21 - s03,
        s12,
        s11,
        s02,
        s20 - s02,
        s11,
        s10,
        s01,
        s00,
        s04 - s22,
        -s13,
        -s12,
        -s03,
        -s02,
    ];
    ellipse_centre(s, r)
}

/// The weighted moments `Σ w xⁱ yʲ`, `i + j ≤ 4`, added to `m`, of the events of [`weigh`]'s
/// records of the pass at `last.p` (positions in radii about its circle), weighed by their
/// residuals from the circle `p`, the step after that pass: `[S00, S10, S01, S20, S11, S02,
/// S30, S21, S12, S03, S40, S31, S22, S13, S04]`. Every sum of the conic's normal equations
/// is one of them or a difference of two or three: 14 products an event, where the 20 sums
/// took 24.
// The weights must be `p`'s: weighed at `last.p`, the conic is off by the step as much as the
// circle is (IRLS converges linearly; 0.0012 px more centre RMS on the DAVIS346 cone). A
// residual moves by the step along the event's direction (to first order: the step turns the
// direction by a few thousandths of a radian, 1e-4 px), and the weight by the change of its
// exponent, to second order while that change is under 0.25 (a converged step moves a
// residual by some 0.03 px against σ ≥ 1 px), else it is taken afresh. The positions may
// stay `last.p`'s: the conic's centre does not depend on the origin, and the velocity's step
// shears the events by under `STEP_TOLERANCE`. Without an exponential in the common case
// the loop keeps its 15 sums in registers, unlike `weigh`'s.
#[inline(never)]
fn conic_moments<const TILT: bool>(records: &[f32], last: &LastPass, p: &[f32; 5], scale: f32, m: &mut [f32; 15]) {
    let at = &last.p;
    let [du, dv, da, db, dr] = [p[0] - at[0], p[1] - at[1], p[2] - at[2], p[3] - at[3], p[4] - at[4]];
    let (r0, scale0) = (at[4], last.scale);
    let inv_r0 = 1.0 / r0;
    let [mut s00, mut s10, mut s01, mut s20, mut s11, mut s02, mut s30, mut s21, mut s12, mut s03, mut s40, mut s31, mut s22, mut s13, mut s04] =
        *m;
    for rec in records.chunks_exact(RECORD) {
        let &[w, cx, cy, xi, t] = rec else { break };
        let (ox, oy) = if TILT { (du + da * t, dv + db * t) } else { (du, dv) };
        let step = -(cx * ox + cy * oy) - dr;
        let xi1 = xi + step;
        let dz = scale * xi1 * xi1 - scale0 * xi * xi;
        let w = if dz.abs() <= 0.25 {
            w * (1.0 - dz * (1.0 - 0.5 * dz))
        } else {
            let z = xi1 * xi1 * scale;
            // One comparison: a NaN is unordered and weighs nothing too.
            if z.partial_cmp(&MAX_WEIGHT_EXPONENT).is_none_or(|o| o.is_gt()) {
                0.0
            } else {
                exp_neg(z)
            }
        };
        let k = (xi + r0) * inv_r0;
        let (wi, x, y) = (w, cx * k, cy * k);
        let (wx, wy) = (wi * x, wi * y);
        let (wxx, wxy, wyy) = (wx * x, wx * y, wy * y);
        let (wxxx, wxxy, wxyy, wyyy) = (wxx * x, wxx * y, wxy * y, wyy * y);
        s00 += wi;
        s10 += wx;
        s01 += wy;
        s20 += wxx;
        s11 += wxy;
        s02 += wyy;
        s30 += wxxx;
        s21 += wxxy;
        s12 += wxyy;
        s03 += wyyy;
        s40 += wxxx * x;
        s31 += wxxx * y;
        s22 += wxxy * y;
        s13 += wxyy * y;
        s04 += wyyy * y;
    }
    *m = [s00, s10, s01, s20, s11, s02, s30, s21, s12, s03, s40, s31, s22, s13, s04];
}

/// The centre, in the local frame about the fitted circle's, of the conic whose normal
/// equations (see [`ellipse_offset`]) are `s`, for a circle of radius `r`; `None` for no
/// plausible ellipse.
fn ellipse_centre(s: [f32; 20], r: f32) -> Option<[f32; 2]> {
    let [m00, m10, m11, m20, m21, m22, m30, m31, m32, m33, m40, m41, m42, m43, m44, b0, b1, b2, b3, b4] = s;
    let m = [
        [m00, 0.0, 0.0, 0.0, 0.0],
        [m10, m11, 0.0, 0.0, 0.0],
        [m20, m21, m22, 0.0, 0.0],
        [m30, m31, m32, m33, 0.0],
        [m40, m41, m42, m43, m44],
    ];
    let b = [b0, b1, b2, b3, b4];
    let [a, bxy, d, e, _] = solve_spd::<5>(m, b)?;
    let c = 1.0 - a;
    // Eigenvalues of the quadratic part [[a, b/2], [b/2, c]]: both positive for an ellipse.
    let det = 4.0 * a * c - bxy * bxy;
    let half_gap = 0.5 * sqrt((a - c) * (a - c) + bxy * bxy);
    let (lo, hi) = (0.5 * (a + c) - half_gap, 0.5 * (a + c) + half_gap);
    if !(det > 0.0 && lo > MIN_ELLIPSE_AXIS_RATIO_SQ * hi) {
        return None;
    }
    let x0 = (bxy * e - 2.0 * c * d) / det;
    let y0 = (bxy * d - 2.0 * a * e) / det;
    let off = x0 * x0 + y0 * y0;
    (off <= MAX_ELLIPSE_OFFSET * MAX_ELLIPSE_OFFSET).then_some([x0 * r, y0 * r])
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Small deterministic generator (xorshift64*), uniform and Gaussian draws.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn gauss(&mut self) -> f64 {
            let (a, b) = (self.next().max(1e-12), self.next());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        }
    }

    struct Cyl {
        u: f64,
        v: f64,
        a: f64,
        b: f64,
        r: f64,
        /// Spread of the events across the edge, px.
        edge: f64,
        duration_ms: f64,
        /// Fraction of extra events scattered around the circle.
        outliers: f64,
    }

    /// Events on a translating circle, rounded to pixels, plus scattered noise near it.
    fn events(c: &Cyl, n: usize, seed: u64) -> Vec<WindowEvent> {
        let mut rng = Rng(seed | 1);
        let mut out = Vec::new();
        for _ in 0..n {
            let t = rng.next() * c.duration_ms;
            let (cx, cy) = (c.u + c.a * t, c.v + c.b * t);
            let (x, y) = if rng.next() < c.outliers {
                let reach = c.r + 4.0;
                (cx + (2.0 * rng.next() - 1.0) * reach, cy + (2.0 * rng.next() - 1.0) * reach)
            } else {
                let th = rng.next() * std::f64::consts::TAU;
                let rr = c.r + c.edge * rng.gauss();
                (cx + rr * th.cos(), cy + rr * th.sin())
            };
            out.push(WindowEvent { x: x.round() as u16, y: y.round() as u16, dt_us: (t * 1000.0) as u32 });
        }
        out
    }

    fn err(c: &Centre, cyl: &Cyl) -> f64 {
        ((c.u as f64 - cyl.u).powi(2) + (c.v as f64 - cyl.v).powi(2)).sqrt()
    }

    fn cfg(method: FitMethod) -> FitConfig {
        FitConfig { method, ..FitConfig::default() }
    }

    /// Events on the moving image of a tilted circle (an ellipse, axes `a`, `b`, the major
    /// one at `angle`), fired more often on the side that moves faster (`gradient`: relative
    /// speed change from the centre to the end of the minor axis), as under perspective.
    fn tilted_events(a: f64, b: f64, angle: f64, gradient: f64, n: usize, seed: u64) -> (Vec<WindowEvent>, [f64; 2]) {
        let mut rng = Rng(seed | 1);
        let (c0, vel, duration) = ([120.0 + 0.31 * seed as f64, 90.0 + 0.17 * seed as f64], [0.35, 0.12], 6.0);
        let (ca, sa) = (angle.cos(), angle.sin());
        let mut out = Vec::new();
        while out.len() < n {
            let th = rng.next() * std::f64::consts::TAU;
            let (ex, ey) = (a * th.cos(), b * th.sin());
            // Outward normal of the ellipse at th, and the speed factor across the minor axis.
            let (nx, ny) = (b * th.cos(), a * th.sin());
            let nl = nx.hypot(ny);
            let (nx, ny) = ((nx * ca - ny * sa) / nl, (nx * sa + ny * ca) / nl);
            let speed = 1.0 + gradient * ey / b;
            let vn = (vel[0] * nx + vel[1] * ny).abs() * speed;
            let ds = (a * th.sin()).hypot(b * th.cos()) / a;
            if rng.next() * 0.5 > vn * ds {
                continue;
            }
            let t = rng.next() * duration;
            let (px, py) = (ex * ca - ey * sa, ex * sa + ey * ca);
            let x = c0[0] + vel[0] * t + px + 0.3 * rng.gauss();
            let y = c0[1] + vel[1] * t + py + 0.3 * rng.gauss();
            out.push((t, x, y));
        }
        out.sort_by(|p, q| p.0.total_cmp(&q.0));
        let events = out
            .iter()
            .map(|&(t, x, y)| WindowEvent { x: x.round() as u16, y: y.round() as u16, dt_us: (t * 1000.0) as u32 })
            .collect();
        // Centre at t_ref = 3 ms.
        (events, [c0[0] + vel[0] * 3.0, c0[1] + vel[1] * 3.0])
    }

    #[test]
    fn tilted_circle_gives_the_ellipse_centre() {
        // b/a = 0.8 (37° of tilt), the near side 30 % faster at the minor axis' end: the
        // circle through these events sat 0.23 px off the ellipse's centre on average (RMS
        // 0.25 px over 40 seeds, measured without the ellipse step); with it, 0.013 px (RMS
        // 0.041 px).
        let trials = 40;
        let (mut sx, mut sy, mut sq) = (0.0, 0.0, 0.0);
        for seed in 1..=trials {
            let (ev, truth) = tilted_events(9.0, 7.2, 0.5, 0.3, 600, seed);
            let c = fit(&ev, 3000, &cfg(FitMethod::Erwls)).expect("fit");
            let (dx, dy) = (c.u as f64 - truth[0], c.v as f64 - truth[1]);
            sx += dx;
            sy += dy;
            sq += dx * dx + dy * dy;
        }
        let n = trials as f64;
        let (mx, my, rms) = (sx / n, sy / n, (sq / n).sqrt());
        eprintln!("tilted: mean error ({mx:+.4}, {my:+.4}) px, RMS {rms:.4} px");
        assert!(mx.hypot(my) < 0.02, "mean error ({mx:+.4}, {my:+.4}) px");
        assert!(rms < 0.1, "RMS {rms:.4} px");
    }

    #[test]
    fn clean_moving_circle_gives_centre_at_t_ref() {
        // Enough events that a biased fit, not chance, would break the bounds: for 2000 events
        // spread 0.5 px about the edge, σ of the centre at t_ref is about 0.03 px.
        let (mut sq_ols, mut sq_erwls) = (0.0, 0.0);
        let trials = 20;
        for seed in 1..=trials {
            let cyl = Cyl {
                u: 100.0 + seed as f64 * 0.37,
                v: 80.0 + seed as f64 * 0.21,
                a: 0.4,
                b: -0.25,
                r: 9.0,
                edge: 0.4,
                duration_ms: 8.0,
                outliers: 0.0,
            };
            let ev = events(&cyl, 2000, seed);
            let c = fit(&ev, 0, &cfg(FitMethod::Erwls)).expect("fit");
            assert!(c.converged);
            assert!((c.r as f64 - 9.0).abs() < 0.1, "r {}", c.r);
            assert!((c.vu as f64 - 0.4).abs() < 0.04 && (c.vv as f64 + 0.25).abs() < 0.04, "{c:?}");
            sq_erwls += err(&c, &cyl).powi(2);
            sq_ols += err(&fit(&ev, 0, &cfg(FitMethod::Ols)).expect("fit"), &cyl).powi(2);
        }
        let (ols, erwls) = ((sq_ols / trials as f64).sqrt(), (sq_erwls / trials as f64).sqrt());
        // Without outliers the weights may cost a little efficiency, never accuracy.
        eprintln!("clean: rms ols {ols:.4} erwls {erwls:.4}");
        assert!(erwls < 0.06 && erwls < 1.3 * ols, "rms ols {ols:.4} erwls {erwls:.4}");
    }

    #[test]
    fn reweighting_beats_plain_least_squares_and_centroid_under_noise() {
        let (mut e_c, mut e_o, mut e_r) = (0.0, 0.0, 0.0);
        let trials = 30;
        for seed in 1..=trials {
            let cyl = Cyl {
                u: 60.0 + seed as f64 * 0.113,
                v: 50.0 - seed as f64 * 0.071,
                a: -0.3,
                b: 0.2,
                r: 7.0,
                edge: 0.5,
                duration_ms: 10.0,
                outliers: 0.15,
            };
            // And a clump on one side only, as clutter beside a circle gives.
            let mut ev = events(&cyl, 300, seed * 7);
            let mut rng = Rng(seed * 13 + 1);
            for _ in 0..40 {
                let (x, y) = (cyl.u + cyl.r + 2.5 + 3.0 * rng.next(), cyl.v - 3.0 + 6.0 * rng.next());
                ev.push(WindowEvent { x: x.round() as u16, y: y.round() as u16, dt_us: (rng.next() * 1e4) as u32 });
            }
            let sq = |m| err(&fit(&ev, 0, &cfg(m)).expect("fit"), &cyl).powi(2);
            e_c += sq(FitMethod::Centroid);
            e_o += sq(FitMethod::Ols);
            e_r += sq(FitMethod::Erwls);
        }
        let rms = |s: f64| (s / trials as f64).sqrt();
        let (c, o, r) = (rms(e_c), rms(e_o), rms(e_r));
        eprintln!("rms centroid {c:.3} ols {o:.3} erwls {r:.3}");
        assert!(r < o && r < c, "rms centroid {c:.3} ols {o:.3} erwls {r:.3}");
        assert!(r < 0.25, "rms erwls {r:.3}");
    }

    #[test]
    fn scratch_size_changes_no_bit_of_circle_fits() {
        // Tilted and still fits (300 and 40 events), held whole or converted chunk by chunk.
        for seed in 1..=12u64 {
            let cyl = Cyl {
                u: 50.0 + seed as f64 * 0.3,
                v: 40.0,
                a: 0.2,
                b: -0.1,
                r: 6.0 + seed as f64 * 0.2,
                edge: 0.5,
                duration_ms: 6.0,
                outliers: 0.1,
            };
            for n in [300, 40] {
                let ev = events(&cyl, n, seed);
                let (a, b) = ev.split_at(n / 3);
                let bits = |c: Option<Centre>| c.map(|c| [c.u, c.v, c.r, c.vu, c.vv, c.spread].map(f32::to_bits));
                let want = bits(fit_from(&[a, b], None, 1000, &FitConfig::default()));
                assert!(want.is_some());
                for size in [0, 1, 7, 39, 64, 299, 300, 4000] {
                    let mut scratch = vec![[0.0f32; 3]; size];
                    let got = bits(fit_with(&[a, b], None, 1000, &FitConfig::default(), &mut scratch));
                    assert_eq!(got, want, "seed {seed}, {n} events, scratch {size}");
                }
            }
        }
    }

    #[test]
    fn degenerate_clusters_are_rejected() {
        let few: Vec<_> = (0..5).map(|i| WindowEvent { x: 10 + i, y: 10, dt_us: 0 }).collect();
        assert_eq!(fit(&few, 0, &FitConfig::default()), None);
        let line: Vec<_> = (0..200).map(|i| WindowEvent { x: 10 + i, y: 40, dt_us: i as u32 }).collect();
        assert_eq!(fit(&line, 0, &FitConfig::default()), None);
        let point = vec![WindowEvent { x: 7, y: 7, dt_us: 3 }; 100];
        assert_eq!(fit(&point, 0, &FitConfig::default()), None);
    }

    #[test]
    fn clutter_is_no_circle() {
        // A blob of scattered events, as clutter leaves: plain least squares finds some
        // circle through it, eRWLS none.
        let mut rng = Rng(99);
        let ev: Vec<_> = (0..600)
            .map(|_| WindowEvent {
                x: 100 + (rng.next() * 30.0) as u16,
                y: 50 + (rng.next() * 30.0) as u16,
                dt_us: (rng.next() * 4000.0) as u32,
            })
            .collect();
        assert_eq!(fit(&ev, 0, &cfg(FitMethod::Erwls)), None);
        assert!(fit(&ev, 0, &cfg(FitMethod::Ols)).is_some_and(|c| c.spread > MAX_SPREAD));
    }

    proptest! {
        #[test]
        fn arbitrary_clusters_never_panic(
            ev in prop::collection::vec((0u16..400, 0u16..300, 0u32..100_000), 0..300),
            method in prop::sample::select(vec![FitMethod::Centroid, FitMethod::Ols, FitMethod::Erwls]),
            iters in 0u8..30,
        ) {
            let ev: Vec<_> = ev.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            let cfg = FitConfig { method, max_iterations: iters, min_events: 1 };
            if let Some(c) = fit(&ev, 0, &cfg) {
                prop_assert!(c.u.is_finite() && c.v.is_finite() && c.r > 0.0 && c.spread.is_finite());
                prop_assert_eq!(usize::from(c.n), ev.len());
            }
        }

        #[test]
        fn scratch_size_changes_no_bit(
            ev in prop::collection::vec((0u16..60, 0u16..60, 0u32..20_000), 20..300),
            split in 0usize..300,
            sizes in prop::collection::vec(0usize..400, 3),
        ) {
            // Clusters of scattered events as well as near-circles: every path of the fit.
            let ev: Vec<_> = ev.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            let (a, b) = ev.split_at(split.min(ev.len()));
            let cfg = FitConfig { min_events: 1, ..FitConfig::default() };
            let want = fit_from(&[a, b], None, 500, &cfg);
            for n in sizes {
                let mut scratch = vec![[0.0f32; 3]; n];
                let got = fit_with(&[a, b], None, 500, &cfg, &mut scratch);
                prop_assert_eq!(got.map(|c| [c.u, c.v, c.r, c.vu, c.vv, c.spread].map(f32::to_bits)),
                    want.map(|c| [c.u, c.v, c.r, c.vu, c.vv, c.spread].map(f32::to_bits)));
            }
        }

        #[test]
        fn extreme_coordinates_and_times_never_panic(
            ev in prop::collection::vec((any::<u16>(), any::<u16>(), any::<u32>()), 5..100),
        ) {
            let ev: Vec<_> = ev.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
            let _ = fit(&ev, 0, &FitConfig { min_events: 1, ..FitConfig::default() });
        }
    }
}
