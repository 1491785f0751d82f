//! eRWLS: fits the slanted cylinder that a moving circle leaves in (x, y, t) and gives its
//! sub-pixel centre at the window's reference time.
//!
//! Model: at time τ (milliseconds since `t_ref`) the circle's edge is the circle of radius
//! `r` centred at `(u + a·τ, v + b·τ)`; the velocity `(a, b)` is the cylinder's tilt (the
//! paper's angles β, α, in an equivalent parameterisation). Residual per event:
//! `ξ = (x − u − aτ)² + (y − v − bτ)² − r²` (paper eq. 5).

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
