//! DBSCAN over one window's events, on a sorted pixel grid.
//!
//! Coordinates are normalised by the sensor size (x / W, y / H) as in the paper, so one
//! `eps` (default 0.015) serves every sensor. The optional spatio-temporal variant
//! (ST-DBSCAN) also requires `|Δt| ≤ eps_t · T`, with `T` the window's duration.
//!
//! The grid is the sensor's own pixel grid: the window's events are sorted in place by
//! pixel (row, then column, then time), which makes every row of the grid a contiguous run
//! (a window's events come in time order, so two stable counting passes, by column and then
//! by row, do it; other input takes a radix and insertion sort). The eps-neighbourhood of a
//! pixel covers a few rows (`⌊eps·H⌋` either side) and, in each, one contiguous span of
//! columns. One sweep down the rows keeps, for each row within reach, a table from column
//! to the index of the row's first event at or right of it (see [`TABLE_CELLS`]): the
//! events of a span are then two lookups apart, which counts every event's neighbours
//! exactly without comparing pairs of events, and the first of them is the span's
//! lowest-index event, from which the links between core points and each border point's
//! core neighbour follow. The work is linear in the events and the rows (after the sort);
//! the memory is the events, one label per event and the tables, on the stack.
//!
//! ST-DBSCAN, and neighbourhoods whose tables would not fit, walk two cursors per
//! neighbouring row instead: as the events are visited in sorted order, the start and end of
//! each span only ever move forward, so the counts stay exact at constant cost per row.
//!
//! The result is exactly that of textbook DBSCAN on the same (reordered) events, with one
//! rule made explicit so that it does not depend on the visiting order: a border point joins
//! the cluster of its lowest-index core neighbour. Clusters are numbered in the order of
//! their lowest-index core point. A point is a core point when its eps-neighbourhood,
//! itself included, holds at least `min_pts` points (the scikit-learn convention).

// Index loops read best here: indices are compared, swapped and stored as labels.
#![allow(clippy::needless_range_loop)]

mod background;
mod clusterer;
mod labelling;
mod metric;
mod pairwise;
mod row_sweep;
mod rows;
mod sort;
mod table_sweep;
mod tables;
#[cfg(test)]
mod tests;
mod union_find;

pub use background::{background_per_neighbourhood, min_pts_above_background, BACKGROUND_CELLS, BACKGROUND_Z};
pub use clusterer::Clusterer;
pub use metric::Metric;
pub use rows::MAX_REACH_ROWS;
pub use sort::{pixel_order, sort_by_pixel};
pub use tables::{ColumnTables, MAX_TABLE_CELLS, TABLE_CELLS};

/// Label of an event that belongs to no cluster.
pub const NOISE: u16 = 0x7FFF;
/// Label of an event whose cluster did not fit in the clusterer's capacity.
pub const DROPPED: u16 = 0x7FFE;

/// Marks a core point in the label array while clustering runs.
const CORE: u16 = 0x8000;
const MASK: u16 = 0x7FFF;
/// A border point without a core neighbour (yet), while border points are settled.
const NONE: u16 = 0x7FFF;

/// DBSCAN settings, in normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ClusterConfig {
    /// Neighbourhood radius in normalised coordinates (x / W, y / H).
    pub eps: f32,
    /// Fewest points in a neighbourhood (the point included) that make a core point. The
    /// [`Detector`](crate::detect::Detector) takes it as the edges' own density and adds the
    /// window's background to it ([`min_pts_above_background`]); [`Clusterer::cluster`] uses
    /// it as it is.
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
    /// Neighbourhood queries made: pairwise distance checks, or, in the sweeps, spans of a
    /// neighbouring row looked up. The work of the clustering.
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
