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

mod centroid;
mod cylinder;
mod disc;
mod ellipse;
mod events;
mod frame;
mod histogram;
mod pass;
#[cfg(test)]
mod tests;

pub(crate) use self::cylinder::MAX_SPREAD;
use self::{
    centroid::centroid,
    cylinder::{cylinder, MAX_START_RMS},
    disc::disc,
    events::Events,
    frame::{Frame, Local},
};
use crate::extent::Extent;
use crate::{
    math::max,
    moments::{Circle, Moments},
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
    /// Whether a cluster the cylinder gives up on may be fitted as a filled disc's outline
    /// (eRWLS only, see `fit::disc`): in dim light a dark circle's slow pixels fill it with
    /// events, and on a large sensor (a DVXplorer's circles of 10 px and more) no ring is
    /// left. Off by default: a dim room's noise makes discs of its own, which cost those
    /// scenes accuracy, and on the M4F it is tried on clutter too (the benchmark's slowest
    /// window 7.1 M instructions instead of 4.39 M before the outline had to go all round).
    pub filled_discs: bool,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            method: FitMethod::Erwls,
            max_iterations: crate::config::DEFAULT_MAX_ITERATIONS,
            min_events: crate::config::DEFAULT_MIN_CLUSTER_EVENTS,
            filled_discs: false,
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
            // A cluster the cylinder gives up on may be a dark circle filled with its slow
            // pixels' events: its outline is still a circle.
            ring(parts, n, &frame, start, t_ref_us, cfg, scratch, give_up).or_else(|| {
                (cfg.method == FitMethod::Erwls && cfg.filled_discs).then(|| disc(parts, n, &frame)).flatten()
            })
        }
    }?;
    frame.accept(result, n as u16, t_ref_us as f32 * 1e-3)
}

/// The slanted cylinder of [`fit_in`]'s events, from the algebraic start (`start`, or made
/// here), or `None` when the events are no ring.
#[allow(clippy::too_many_arguments)]
fn ring(
    parts: &[&[WindowEvent]],
    n: usize,
    frame: &Frame,
    start: Option<Circle>,
    t_ref_us: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
    give_up: f32,
) -> Option<Local> {
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
    let mut events = Events::new(parts, n, frame, scratch);
    cylinder(&mut events, frame, &start, t_ref_us as f32 * 1e-3, cfg, give_up.min(MAX_SPREAD))
}
