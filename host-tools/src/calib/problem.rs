//! What a calibration is given: the views of the target and the solver's options.

use super::*;

/// One view of the target: board points (metres, on the plane z = 0) and where they were seen
/// (pixels). The two lists pair up by index; a view may hold any subset of the target's
/// points.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct View {
    /// Board points, metres.
    pub object: Vec<[f64; 3]>,
    /// Their pixels.
    pub image: Vec<[f64; 2]>,
}

impl View {
    /// Where the view saw each board point, keyed by [`board_key`]: the lookup that follows
    /// one board point from view to view.
    pub(crate) fn by_board_point(&self) -> std::collections::HashMap<BoardKey, [f64; 2]> {
        self.object.iter().zip(&self.image).map(|(o, i)| (board_key(o), *i)).collect()
    }
}

/// A board point as a hashable key: its coordinates in micrometres (board points are on a
/// lattice of millimetres, so rounding never merges two).
pub(crate) type BoardKey = (i64, i64);

/// The [`BoardKey`] of the board point `o`.
pub(crate) fn board_key(o: &[f64; 3]) -> BoardKey {
    ((o[0] * 1e6).round() as i64, (o[1] * 1e6).round() as i64)
}

/// What the solve may change, and how hard it tries.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Keep k3 at 0 (OpenCV's CALIB_FIX_K3).
    pub fix_k3: bool,
    /// Keep p1 = p2 = 0 (CALIB_ZERO_TANGENT_DIST).
    pub zero_tangential: bool,
    /// Keep fy / fx fixed (CALIB_FIX_ASPECT_RATIO): at 1 (square pixels; fy = fx exactly,
    /// one focal length solved for), or at the ratio of [`start`](Self::start) when one is
    /// given, as OpenCV keeps its guess's.
    pub fix_aspect_ratio: bool,
    /// Keep the principal point at the starting value (CALIB_FIX_PRINCIPAL_POINT).
    pub fix_principal_point: bool,
    /// Start from these intrinsics instead of Zhang's closed form (CALIB_USE_INTRINSIC_GUESS).
    pub start: Option<Intrinsics>,
    /// Down-weight points whose residual is far above the others' (Huber), and set aside
    /// views whose RMS is far above the others'. Off: plain least squares, as OpenCV.
    pub robust: bool,
    /// Most Levenberg–Marquardt steps per solve.
    pub max_iterations: usize,
    /// A step that lowers the cost by less than this fraction ends the solve.
    pub tolerance: f64,
    /// Per view (by index in the views given), per point: the direction along which its
    /// detected centre was moved by a shift estimated from these same views (`dir` times
    /// the shift; see [`crate::views::edge_shift`]). The shift then counts as one more parameter in
    /// the standard deviations, its uncertainty carried into the intrinsics'
    /// ([`Calibration::shift_std_px`]). Empty, or not one entry per view: no shift.
    pub shift_directions: Vec<Vec<[f64; 2]>>,
    /// Further moves of the detected centres, each by one factor shared by all views: per
    /// move, per view, per point, its direction, as `shift_directions` (the edge shift's
    /// lean across the motion on slanted outlines, and the lag's bend in the image speed;
    /// see [`crate::views::edge_shift`]). The solve reports how far along each the views
    /// would move the points ([`Calibration::moves`]), and each factor counts as one more
    /// parameter in the standard deviations. A move without one entry per view is left out.
    pub moves: Vec<Vec<Vec<[f64; 2]>>>,
    /// Radius of the target's circles, metres: the solve then compares each detected centre
    /// with the centre of its circle's projected outline ([`outline_offset`]), which a circle
    /// fit measures, instead of the projection of the circle's centre. `None`: the latter, as
    /// for points that are the projections themselves (a chessboard's corners).
    pub circle_radius: Option<f64>,
    /// Per view (by index in the views given), when it was seen, s. The views kept are
    /// grouped by stretches of the recording ([`group_seconds`] of their times), whose
    /// views' errors may be alike; the standard deviations then also come from how the
    /// groups pull on the parameters (a cluster-robust, "sandwich" covariance), and the
    /// larger is reported. Empty (or not one per view): every point's error is taken as
    /// independent.
    pub view_times: Vec<f64>,
    /// Per view (by index in the views given), per point: a figure that grows with how
    /// precise the point is (for a circle's centre, the events its fit used). The robust
    /// solve then weighs each point by the inverse of the square error that points of
    /// about its figure show after the plain solve: the points, sorted by figure, in up to
    /// 8 bins of equal count, each bin's median square error, a larger figure never taken
    /// to err more. A centre fitted to few events errs more, and counting it as much as the
    /// others costs precision. Empty, or not one figure per point: every point weighs alike.
    pub precision_hints: Vec<Vec<f64>>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            fix_k3: false,
            zero_tangential: false,
            fix_aspect_ratio: false,
            fix_principal_point: false,
            start: None,
            robust: true,
            max_iterations: 100,
            tolerance: 1e-12,
            circle_radius: None,
            view_times: Vec::new(),
            precision_hints: Vec::new(),
            shift_directions: Vec::new(),
            moves: Vec::new(),
        }
    }
}
