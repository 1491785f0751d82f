//! What the views stage hands on beside the views themselves ([`View`]): where each view came
//! from, every window searched for the grid, and how far a calibration leaves each view's
//! points.
//!
//! These are made where the views are made ([`crate::pipeline::views_from_windows`]) and read
//! by the steps after it (smoothing, the edge shift, the exports), so they live here rather
//! than with any one reader.

pub mod edge_shift;
pub mod grid;
pub mod select;
pub mod smooth;
pub mod track;

use crate::calib::{Calibration, View};

/// Where one input view came from: the detection window whose grid it is. Indexed like the
/// views passed to [`calibrate`](crate::calib::calibrate).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewOrigin {
    /// The window's sequence number (the `seq` of the detections file).
    pub window_seq: u64,
    /// The window's time, seconds from the start of the recording.
    pub t_s: f64,
}

/// One detection window as the report's timeline draws it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowSample {
    /// The window's time, seconds from the start of the recording.
    pub t_s: f64,
    /// Circle centres the detector found in the window.
    pub centres: usize,
    /// Whether the grid was found among them.
    pub grid_found: bool,
}

/// A calibration that names a view the caller did not hand over with it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("the calibration used view {view} but only {given} views were given")]
pub struct MissingView {
    /// The view the calibration names.
    pub view: usize,
    /// How many views were given.
    pub given: usize,
}

/// The residuals of every view the calibration used, in the order of `calibration.views`
/// (see [`Calibration::residuals`]). `views` are the views given to the solver; an error when the
/// calibration names a view that is not among them.
pub fn view_residuals(views: &[View], calibration: &Calibration) -> Result<Vec<Vec<[f64; 2]>>, MissingView> {
    calibration
        .views
        .iter()
        .map(|r| match views.get(r.view) {
            Some(v) => Ok(calibration.residuals(v, r)),
            None => Err(MissingView { view: r.view, given: views.len() }),
        })
        .collect()
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::calib::{calibrate, synthetic_views, Intrinsics, Options};

    #[test]
    fn residuals_match_the_solver_view_errors() {
        let truth = Intrinsics {
            fx: 352.5,
            fy: 351.25,
            cx: 171.3,
            cy: 128.7,
            k1: -0.31,
            k2: 0.11,
            p1: 4e-4,
            p2: -3e-4,
            k3: 0.0,
        };
        let views = synthetic_views(&truth, 14, 0.15, 11);
        let cal = calibrate(&views, [346, 260], &Options::default()).expect("calibration");
        let res = view_residuals(&views, &cal).unwrap();
        assert_eq!(res.len(), cal.views.len());
        for (r, v) in res.iter().zip(&cal.views) {
            assert_eq!(r.len(), v.points);
            let rms = (r.iter().map(|d| d[0] * d[0] + d[1] * d[1]).sum::<f64>() / r.len() as f64).sqrt();
            assert!((rms - v.rms_px).abs() < 1e-9, "view {}: {rms} vs the solver's {}", v.view, v.rms_px);
        }
        // Too few views for the calibration's indices: an error, not a panic.
        let e = view_residuals(&views[..2], &cal).unwrap_err().to_string();
        assert!(e.contains("only 2 views were given"), "{e}");
    }
}
