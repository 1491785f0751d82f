//! Named capacities and defaults.
//!
//! Capacities are compile-time constants (or const generics that default to them) so that
//! the firmware's memory is fixed at link time. Defaults follow the E-Calib paper.

/// Default number of events in a window (the paper's 4000).
pub const DEFAULT_EVENTS_PER_WINDOW: usize = 4000;

/// Default time between window ticks, in microseconds (the paper's 33 ms: 30 windows/s).
pub const DEFAULT_STEP_US: u64 = 33_333;

/// Default DBSCAN radius in normalised coordinates (x / width, y / height).
pub const DEFAULT_EPS: f32 = 0.015;

/// Default DBSCAN minimum number of points in an eps-neighbourhood (the point included)
/// for a point to be a core point, on a clean window (the detector adds the window's
/// background: [`crate::cluster::min_pts_above_background`]).
pub const DEFAULT_MIN_PTS: u16 = 10;

/// Default capacity of a window: the most events one window may hold. The window a
/// DAVIS346 needs ([`window::ring_events_per_window`](crate::window::ring_events_per_window),
/// twice the paper's), which a Cortex-M4F device holds (an STM32F405's 128 KiB of SRAM,
/// the stack in its 64 KiB of CCM); larger sensors' windows need a board that holds more
/// (a `Detector`'s `N`).
pub const MAX_EVENTS_PER_WINDOW: usize = 8000;

/// Default capacity for clusters (and so centres) per window; clusters beyond it are counted
/// as dropped.
pub const MAX_CLUSTERS: usize = 96;

/// Default fewest events a cluster needs to be fitted; smaller clusters are skipped.
pub const DEFAULT_MIN_CLUSTER_EVENTS: u16 = 20;

/// Default most Levenberg–Marquardt iterations of one eRWLS fit.
pub const DEFAULT_MAX_ITERATIONS: u8 = 6;

/// Most events DBSCAN left as noise that one fitted circle takes back (see
/// [`detect::process`](crate::detect::process)); further ones are left out of its fit.
pub const MAX_RECRUITS: usize = 128;

/// Events whose coordinates in a fit's local frame (three `f32` each) the fit converts once
/// and keeps for all its passes; a larger cluster's events are converted again on every pass,
/// this many at a time (same results). [`detect::process`](crate::detect::process) keeps them
/// in the clustering's column tables (16 KiB), done with by then: as many as fit there, so
/// that clusters of up to 510 events (3/8 of them) keep their weights' records for the next
/// sums and the ellipse (8000-event windows on the M4F: slowest window 7.06 -> 6.92 M
/// instructions).
pub const FIT_SCRATCH_EVENTS: usize = 1360;
