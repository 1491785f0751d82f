//! The integer summary of a set of window events (bounding box, time span, time sum): what a
//! fit's local frame is made from, and what the clustering's moments gather on the way.

use crate::window::WindowEvent;

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
    pub(crate) t_sum: u64,
    pub(crate) count: u32,
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

    /// Takes in one event's pixel: with [`add_time`](Self::add_time) and
    /// [`count`](Self::count), the same as [`add`](Self::add), for a loop that reads only
    /// the pixels (see [`Moments::of_with_extent`](crate::moments::Moments::of_with_extent)).
    #[inline(always)]
    pub(crate) fn add_pixel(&mut self, x: u16, y: u16) {
        self.x_lo = self.x_lo.min(x);
        self.x_hi = self.x_hi.max(x);
        self.y_lo = self.y_lo.min(y);
        self.y_hi = self.y_hi.max(y);
    }

    /// Takes in one event's time (see [`add_pixel`](Self::add_pixel)).
    #[inline(always)]
    pub(crate) fn add_time(&mut self, dt_us: u32) {
        self.t_lo = self.t_lo.min(dt_us);
        self.t_hi = self.t_hi.max(dt_us);
        self.t_sum += u64::from(dt_us);
    }

    /// Counts `n` events taken in by [`add_pixel`](Self::add_pixel) and
    /// [`add_time`](Self::add_time).
    pub(crate) fn count(&mut self, n: usize) {
        self.count = self.count.wrapping_add(n as u32);
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
