//! What a calibration gives: the intrinsics with their σ, each view's result, what was set
//! aside and why, and the errors.

use super::*;

/// A view set aside, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rejection {
    /// Index of the view in the input.
    pub view: usize,
    /// Why, in words.
    pub reason: String,
}

/// One view's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewResult {
    /// Index of the view in the input.
    pub view: usize,
    /// Points of the view.
    pub points: usize,
    /// RMS reprojection error of its points, px, strays left out.
    pub rms_px: f64,
    /// Its points set aside as strays by the robust rule.
    pub strays: usize,
    /// Board → camera rotation (Rodrigues vector).
    pub rvec: [f64; 3],
    /// Board → camera translation, metres.
    pub tvec: [f64; 3],
}

/// The result of a calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Calibration {
    /// The intrinsics and distortion.
    pub intrinsics: Intrinsics,
    /// Image size, pixels (width, height).
    pub image_size: [u32; 2],
    /// RMS reprojection error over the points of the views used, px, without the strays the
    /// robust rule set aside (`stray_points`); `rms_all_px` counts them too.
    pub rms_px: f64,
    /// RMS reprojection error over every point of the views used, strays included, px.
    pub rms_all_px: f64,
    /// Mean of the views' RMS errors, px.
    pub mean_view_px: f64,
    /// Median of the views' RMS errors, px.
    pub median_view_px: f64,
    /// One standard deviation of each parameter (0 for a fixed one), in the order of
    /// [`PARAMETER_NAMES`]: the larger of `std_dev_points` and, when the views were grouped
    /// ([`Options::view_times`]), of what the scatter of the groups says (widened for their
    /// number: [`few_groups_factor`]). The pipeline adds
    /// to it what the edges' other lag model changes
    /// ([`ByThickness`](crate::views::edge_shift::ByThickness)).
    pub std_dev: [f64; 9],
    /// The standard deviations as if every point's error were independent of every other's
    /// (the residual variance times the inverse normal matrix, as OpenCV reports them).
    /// Centre errors are not independent: a circle's error persists over the windows of a
    /// slow motion and is shared by its neighbours, so these can be several times too small.
    pub std_dev_points: [f64; 9],
    /// The parameters' covariance, in the order of [`PARAMETER_NAMES`] (rows and columns of
    /// a fixed parameter 0): its diagonal is the square of `std_dev`, its correlations those
    /// of the figure `std_dev` came from (the grouped one when the views were grouped, else
    /// each point's own). Where `std_dev` is the larger of two figures the correlations are
    /// the grouped figure's scaled to it: the covariance stays one the σ printed agree with,
    /// which [`ProjectionSigma`] carries into pixels. An unbounded σ
    /// is an infinite diagonal entry with no correlation.
    pub covariance: [[f64; 9]; 9],
    /// Every view used, with its error and pose.
    pub views: Vec<ViewResult>,
    /// Views set aside, with the reason.
    pub rejected: Vec<Rejection>,
    /// Points set aside by the robust rule: beyond 5 σ of all points' errors (a centre
    /// fitted to a short arc of few events, a blob merged with a circle). They take no part
    /// in the final solve nor in `rms_px`.
    pub stray_points: usize,
    /// What the user should know: poorly constrained parameters, and the like.
    pub warnings: Vec<String>,
    /// Levenberg–Marquardt steps of the final solve.
    pub iterations: usize,
    /// Whether the final solve converged.
    pub converged: bool,
    /// The circles' radius the solve modelled, metres ([`Options::circle_radius`]), if any.
    pub circle_radius_m: Option<f64>,
    /// One standard deviation of the shift the points were moved by, px, as a parameter of
    /// this solve ([`Options::shift_directions`]; the larger of the independent-error and
    /// the grouped figure, like `std_dev`); `None` without one.
    pub shift_std_px: Option<f64>,
    /// Per move of [`Options::moves`], in its order: how far along it the views would move
    /// the points from where they were given, and that factor's σ as a parameter of this
    /// solve (`None` for a move left out, or when the solve could not tell).
    pub moves: Vec<Option<MoveEstimate>>,
    /// How many groups of views ([`Options::view_times`]) the grouped σ came from, widened
    /// for their number by [`few_groups_factor`]; `None` when `std_dev` is the
    /// independent-error figure alone (no times, or too few groups for a grouped σ).
    pub sigma_groups: Option<usize>,
    /// How long a stretch of the recording each group spans, s ([`group_seconds`] of the
    /// kept views' times): the one the grouped σ came from, or with too few groups the
    /// shortest tried. `None` without times.
    pub sigma_group_s: Option<f64>,
    /// How the points were weighed by their precision figures ([`Options::precision_hints`]),
    /// bin by bin from the smallest figure up; empty when they were not (no figures, too
    /// few points, or a plain solve).
    pub precision_bins: Vec<PrecisionBin>,
}

/// A bin of points of about the same precision figure ([`Options::precision_hints`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PrecisionBin {
    /// The smallest figure in the bin (the events of its centres' fits).
    pub from: f64,
    /// Each of its points' weight: the median square error of all points over the bin's.
    pub weight: f64,
}

impl Calibration {
    /// Widens the parameters' uncertainty by a systematic `change` that the views cannot
    /// tell from the answer (another model's solve minus this one's): each σ becomes
    /// `hypot(σ, change)` and the covariance gains `change·changeᵀ`, so that the pixels'
    /// uncertainty ([`ProjectionSigma`]) counts it as the σ do, along the
    /// direction it moves the parameters together. A non-finite `change` changes nothing.
    pub fn widen(&mut self, change: [f64; 9]) {
        if !change.iter().all(|c| c.is_finite()) {
            return;
        }
        for (sd, c) in self.std_dev.iter_mut().zip(change) {
            *sd = sd.hypot(c);
        }
        for (i, row) in self.covariance.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += change[i] * change[j];
            }
        }
    }

    /// Each point's reprojection residual, modelled minus detected (px), in one used view:
    /// `view` is the view the solve was given as `result.view`. The model is where the
    /// view's pose and the intrinsics put each circle's outline centre (or the board point
    /// itself when no radius was modelled). A point behind the camera gives NaN.
    pub fn residuals(&self, view: &View, result: &ViewResult) -> Vec<[f64; 2]> {
        let pose = Pose {
            rotation: Rotation3::from_scaled_axis(Vector3::from(result.rvec)),
            translation: Vector3::from(result.tvec),
        };
        let k = &self.intrinsics;
        view.object
            .iter()
            .zip(&view.image)
            .map(|(o, m)| {
                let d = match self.circle_radius_m {
                    Some(r) => outline_offset(k, &pose, o, r),
                    None => Some([0.0; 2]),
                };
                match (k.project(&(pose.rotation * Vector3::from(*o) + pose.translation)), d) {
                    (Some(p), Some(d)) => [p[0] + d[0] - m[0], p[1] + d[1] - m[1]],
                    _ => [f64::NAN; 2],
                }
            })
            .collect()
    }
}

/// A move of the points shared by all views, as the solve estimates it
/// ([`Calibration::moves`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MoveEstimate {
    /// The factor the views ask for: one Gauss–Newton step from the points as given, with
    /// the poses, the free intrinsics and any shift free as well.
    pub step: f64,
    /// One standard deviation of it (the larger of the independent-error and the grouped
    /// figure, like [`Calibration::std_dev`]).
    pub std: f64,
}

/// Why a calibration could not be made.
#[derive(Debug, Clone, PartialEq)]
pub enum CalibError {
    /// No views at all.
    NoViews,
    /// Fewer usable views than a solve needs.
    TooFewViews {
        /// Views usable.
        usable: usize,
        /// Views needed.
        needed: usize,
    },
    /// A point or pixel is not a finite number.
    NotFinite {
        /// The view.
        view: usize,
        /// The point within it.
        point: usize,
    },
    /// The views do not determine a camera (all alike, or degenerate).
    Degenerate(String),
}

impl fmt::Display for CalibError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CalibError::NoViews => write!(f, "no views to calibrate from"),
            CalibError::TooFewViews { usable, needed } => write!(
                f,
                "{usable} usable view(s) of the target; a calibration needs at least {needed} (views with at least 6 points, not all on a line)"
            ),
            CalibError::NotFinite { view, point } => write!(f, "view {view}, point {point}: not a finite number"),
            CalibError::Degenerate(why) => write!(f, "the views do not determine a camera: {why}"),
        }
    }
}

impl std::error::Error for CalibError {}
