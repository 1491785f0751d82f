//! The neighbourhood test of DBSCAN, in exact integer arithmetic.

use super::ClusterConfig;
use crate::{event::SensorSize, window::WindowEvent};

/// DBSCAN's neighbourhood in exact integer arithmetic: events `a` and `b` are neighbours when
/// `(Δx/W)² + (Δy/H)² ≤ eps²`, evaluated as `Δx²·H² + Δy²·W² ≤ ⌊(eps·W·H)²⌋`, and, for
/// ST-DBSCAN, `|Δt| ≤ ⌊eps_t·T⌋` microseconds with `T` the window's duration.
///
/// Integers make the test exact and identical on every machine; the only rounding is of the
/// thresholds, once per window, in IEEE double precision (also identical everywhere).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Metric {
    h2: u64,
    w2: u64,
    threshold: u64,
    /// Largest |Δy| of any neighbour pair.
    pub(super) reach_y: u64,
    pub(super) dt_max: Option<u32>,
}

impl Metric {
    /// The neighbourhood for a sensor, a configuration and a window lasting `duration_us`.
    pub fn new(sensor: SensorSize, cfg: &ClusterConfig, duration_us: u32) -> Self {
        let w = u64::from(sensor.width.max(1));
        let h = u64::from(sensor.height.max(1));
        let eps = if cfg.eps.is_finite() && cfg.eps > 0.0 { f64::from(cfg.eps) } else { 0.0 };
        let side = eps * (w * h) as f64;
        // Float-to-integer casts saturate (and map NaN to 0): no overflow whatever eps is.
        let threshold = (side * side) as u64;
        let dt_max = match cfg.eps_t {
            Some(et) if et.is_finite() && et >= 0.0 => Some((f64::from(et) * f64::from(duration_us)) as u32),
            Some(_) => Some(0),
            None => None,
        };
        Self { h2: h * h, w2: w * w, threshold, reach_y: isqrt(threshold / (w * w)), dt_max }
    }

    /// Whether `a` and `b` are neighbours in space (eps).
    #[inline]
    fn near_in_space(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        let dy = u64::from(a.y.abs_diff(b.y));
        dy <= self.reach_y && u64::from(a.x.abs_diff(b.x)) <= self.span(dy)
    }

    /// Whether `a` and `b` are within eps of each other (and, for ST-DBSCAN, of eps_t).
    #[inline]
    pub fn neighbours(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        self.near_in_space(a, b) && self.near_in_time(a, b)
    }

    #[inline]
    pub(super) fn near_in_time(&self, a: &WindowEvent, b: &WindowEvent) -> bool {
        self.dt_max.is_none_or(|m| a.dt_us.abs_diff(b.dt_us) <= m)
    }

    /// The largest |Δx| of a neighbour `dy` rows away (`dy ≤ reach_y`).
    #[inline]
    pub(super) fn span(&self, dy: u64) -> u64 {
        // dy ≤ reach_y keeps dy²·W² within the threshold: no overflow.
        isqrt((self.threshold - dy * dy * self.w2) / self.h2)
    }
}

/// ⌊√x⌋, exactly.
fn isqrt(x: u64) -> u64 {
    let mut r = libm::sqrt(x as f64) as u64;
    while r > 0 && r.checked_mul(r).is_none_or(|q| q > x) {
        r -= 1;
    }
    while (r + 1).checked_mul(r + 1).is_some_and(|q| q <= x) {
        r += 1;
    }
    r
}
