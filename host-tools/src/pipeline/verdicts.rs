//! What a calibration's result says to its user, as values: whether the focal length is
//! weakly fixed, whether there is a calibration at all, and whether the filled discs' one is
//! taken where the rings gave none ([`calibrate_with_disc_fallback`]).
//!
//! Each verdict's `Display` is the sentence files and reports carry; `summary()` is the
//! clause a one-line note quotes. Callers match on the variants rather than read the words.

use super::*;

/// A focal length looser than this (1σ, relative) is worth a warning: the accuracy evcal
/// aims at.
pub const FOCAL_WARN_RELATIVE: f64 = 1e-3;
/// A focal length looser than this (1σ, relative), or a principal point looser than this
/// fraction of the sensor's size, is no calibration: a lens's focal length is known to
/// about this from its data sheet.
pub const FAILED_RELATIVE: f64 = 0.05;

/// The focal length is looser than [`FOCAL_WARN_RELATIVE`]: a calibration, but one to record
/// again for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeakFocal {
    /// σ(fx) / fx.
    pub fx_rel: f64,
    /// σ(fy) / fy.
    pub fy_rel: f64,
    /// What the views lack.
    pub cause: WeakFocalCause,
    /// How far fx moves, relative, when the edges' lag is taken in proportion to their
    /// thickness ([`edge_shift::ByThickness`]), when that is most of σ(fx); `None` otherwise.
    pub lag_fx_rel: Option<f64>,
}

/// Why the focal length is weakly fixed, as far as the views tell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WeakFocalCause {
    /// No view tilts the target by [`GOOD_TILT_DEG`](crate::views::select::GOOD_TILT_DEG).
    LacksTilt {
        /// The largest tilt among the views, degrees.
        max_deg: f64,
    },
    /// Tilt enough, but too few views or too little of the sensor.
    Coverage {
        /// Views solved on.
        views: usize,
        /// Fraction of the sensor's cells the points fell in.
        covered: f64,
    },
}

impl WeakFocal {
    /// The verdict on `cal`, whose points cover `coverage`; `lag` is what the edges' other
    /// lag model changes ([`edge_shift::ByThickness::change`]). `None`: the focal length is
    /// fixed within [`FOCAL_WARN_RELATIVE`].
    pub fn of(cal: &Calibration, coverage: &Coverage, lag: Option<&[f64; 9]>) -> Option<Self> {
        let k = &cal.intrinsics;
        let (fx_rel, fy_rel) = (cal.std_dev[0] / k.fx.abs(), cal.std_dev[1] / k.fy.abs());
        if fx_rel.max(fy_rel) <= FOCAL_WARN_RELATIVE {
            return None;
        }
        let tilt = crate::views::select::TiltSpread::of(cal);
        let cause = if tilt.max_deg < crate::views::select::GOOD_TILT_DEG {
            WeakFocalCause::LacksTilt { max_deg: tilt.max_deg }
        } else {
            WeakFocalCause::Coverage { views: cal.views.len(), covered: coverage.covered }
        };
        // Most of σ(fx) from the lag's model: the pixels are slow or the edges blurred.
        let lag_fx_rel =
            lag.filter(|c| c[0].abs() > std::f64::consts::FRAC_1_SQRT_2 * cal.std_dev[0]).map(|c| c[0] / k.fx.abs());
        Some(Self { fx_rel, fy_rel, cause, lag_fx_rel })
    }
}

impl fmt::Display for WeakFocal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the focal length is weakly fixed: fx ±{:.2} %, fy ±{:.2} % (1σ; evcal aims at 0.1 %); ",
            100.0 * self.fx_rel,
            100.0 * self.fy_rel
        )?;
        match self.cause {
            WeakFocalCause::LacksTilt { max_deg } => write!(
                f,
                "the views tilt the target by at most {max_deg:.0}°: only tilt tells the focal length from the distance (a target facing the sensor looks the same to a focal length twice as long from twice as far, its distortion rescaled to match, however near it comes). Record a cone: tilt the target 20–40° towards each side in turn while it sweeps the sensor"
            )?,
            WeakFocalCause::Coverage { views, covered } => write!(
                f,
                "{views} views, their points on {:.0} % of the sensor: record longer, tilting the target 20–40° to each side while it sweeps the whole sensor (in brighter light if the grid was missed in many windows)",
                100.0 * covered
            )?,
        }
        if let Some(r) = self.lag_fx_rel {
            write!(
                f,
                "; most of it is how late the edges were seen (taking the lag in proportion to each edge's thickness rather than as one distance moves fx by {:+.2} %): more light, or a sharper focus, makes the edges quicker and thinner",
                100.0 * r
            )?;
        }
        Ok(())
    }
}

/// How loose the views leave one of fx, fy, cx, cy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Looseness {
    /// Its σ is not a finite number.
    NotFixed,
    /// σ relative to the focal length (fx, fy).
    Relative(f64),
    /// σ in pixels (cx, cy).
    Px(f64),
}

/// A parameter the views leave looser than [`FAILED_RELATIVE`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LooseParam {
    /// Its index in [`crate::calib::PARAMETER_NAMES`] (0 to 3).
    pub index: usize,
    /// How loose.
    pub by: Looseness,
}

impl fmt::Display for LooseParam {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = crate::calib::PARAMETER_NAMES[self.index];
        match self.by {
            Looseness::NotFixed => write!(f, "{name} not fixed at all"),
            Looseness::Relative(r) => write!(f, "{name} ±{:.1} % (1σ)", 100.0 * r),
            Looseness::Px(px) => write!(f, "{name} ±{px:.1} px (1σ)"),
        }
    }
}

/// The views leave a parameter so loose that no value printed could be trusted: no
/// calibration ([`Outcome::failure`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Loose {
    /// The parameters, in the solver's order; never empty.
    pub params: Vec<LooseParam>,
}

impl Loose {
    /// The clause a one-line note quotes.
    pub fn summary(&self) -> String {
        "the views do not fix the camera".into()
    }
}

impl fmt::Display for Loose {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let params: Vec<String> = self.params.iter().map(ToString::to_string).collect();
        write!(
            f,
            "{}: {} (at most {:.0} % of the focal length or the sensor's size is a calibration); record the target tilted 20–40° to each side, filling the sensor, in light bright enough for the grid to be found in most windows",
            self.summary(),
            params.join(", "),
            100.0 * FAILED_RELATIVE
        )
    }
}

/// Why `cal` is no calibration, if it is not: a parameter the views leave so loose that its
/// printed value means nothing (beyond [`FAILED_RELATIVE`]).
pub fn loose_params(cal: &Calibration) -> Option<Loose> {
    let (k, sd) = (&cal.intrinsics, &cal.std_dev);
    let size = cal.image_size.map(f64::from);
    let mut params = Vec::new();
    for (index, scale, relative) in
        [(0, k.fx.abs(), true), (1, k.fy.abs(), true), (2, size[0], false), (3, size[1], false)]
    {
        if !(sd[index].is_finite() && sd[index] <= FAILED_RELATIVE * scale) {
            let by = match relative {
                _ if !sd[index].is_finite() => Looseness::NotFixed,
                true => Looseness::Relative(sd[index] / scale),
                false => Looseness::Px(sd[index]),
            };
            params.push(LooseParam { index, by });
        }
    }
    (!params.is_empty()).then_some(Loose { params })
}

/// Why a calibration attempt gave no calibration.
#[derive(Debug, Clone, PartialEq)]
pub enum NoCalibration {
    /// No window held the grid ([`PipelineError::NoGrid`]).
    NoGrid(GridStats),
    /// The solve failed: too few views, or views that determine no camera
    /// ([`PipelineError::Calib`]).
    Solve(CalibError),
    /// A solve whose views leave a parameter meaningless ([`Outcome::failure`]).
    Loose(Loose),
}

impl NoCalibration {
    /// The clause a one-line note quotes: what failed, without the advice.
    pub fn summary(&self) -> String {
        match self {
            NoCalibration::NoGrid(s) if s.windows == 0 => NO_WINDOWS.into(),
            NoCalibration::NoGrid(s) => s.found_summary(),
            NoCalibration::Solve(CalibError::TooFewViews { usable, .. }) => {
                format!("{usable} usable view(s) of the target")
            }
            NoCalibration::Solve(CalibError::Degenerate(_)) => "the views do not determine a camera".into(),
            NoCalibration::Solve(e) => e.to_string(),
            NoCalibration::Loose(l) => l.summary(),
        }
    }
}

impl From<PipelineError> for NoCalibration {
    fn from(e: PipelineError) -> Self {
        match e {
            PipelineError::NoGrid(s) => NoCalibration::NoGrid(s),
            PipelineError::Calib(e) => NoCalibration::Solve(e),
        }
    }
}

/// Said when there were no windows at all.
const NO_WINDOWS: &str = "no detection windows to look for the grid in";

/// Why no grid was found in the windows `s` tallies, and what helps.
pub(super) fn write_no_grid(f: &mut fmt::Formatter<'_>, s: &GridStats) -> fmt::Result {
    if s.windows == 0 {
        return f.write_str(NO_WINDOWS);
    }
    write!(f, "{}: check --pattern (ROWSxCOLS as the board is printed) and that the board is in view", s.summary())?;
    // Most windows short of circles: the rings themselves were not there.
    let short = s.misses.get(&Miss::TooFewCentres).copied().unwrap_or(0);
    if 2 * short > s.windows {
        write!(
            f,
            "; in {short} windows the core found fewer circles than the grid has, so the circles did not show as clean rings of events: in dim light the pixels answer slowly and smear each edge over many pixels (more light helps most), and a board out of focus, moving too fast to follow or barely moving does the same"
        )?;
    }
    Ok(())
}

impl fmt::Display for NoCalibration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NoCalibration::NoGrid(s) => write_no_grid(f, s),
            NoCalibration::Solve(e) => write!(f, "{e}"),
            NoCalibration::Loose(l) => write!(f, "{l}"),
        }
    }
}

/// Why a calibration attempt gave no calibration (its error, or [`Outcome::failure`]);
/// `None` when it gave one.
pub fn no_calibration(result: &Result<Outcome, PipelineError>) -> Option<NoCalibration> {
    match result {
        Ok(o) => o.failure.clone().map(NoCalibration::Loose),
        Err(e) => Some(e.clone().into()),
    }
}

/// Largest σ of the focal length (1σ, relative) of a calibration from filled discs that is
/// taken where the rings gave none ([`disc_fallback_rejects`]).
///
/// A disc's centre lies up to a pixel from its circle's along the motion (its ON crescent
/// outweighs its fill's edge), the same for the discs of one window only to about 0.2 px;
/// the edge shift takes out one distance, and what differs between centres the σ does not
/// hold. Many views from varied poses average it down; a handful do not: on the simulated
/// DVXplorer's dim spiral at a 100 Hz photoreceptor the discs gave 8 views and fx +16 %
/// with σ 4.9 %, inside [`FAILED_RELATIVE`] and 3.4σ off, while its dim cone and spiral at
/// 300 Hz read +0.18 % (σ 0.18 %) and −0.57 % (σ 0.33 %) (+0.004 % and −0.21 % since the
/// discs' windows last as long as a DAVIS346's:
/// [`disc_events_per_window`](crate::input::detections::disc_events_per_window)).
pub const DISC_FALLBACK_FOCAL_RELATIVE: f64 = 0.01;

/// Why a calibration from filled discs, tried where the rings gave none, is not taken.
#[derive(Debug, Clone, PartialEq)]
pub enum DiscRejection {
    /// The discs gave no calibration either.
    NoCalibration(NoCalibration),
    /// A calibration, but its focal length is looser than [`DISC_FALLBACK_FOCAL_RELATIVE`].
    LooseFocal {
        /// The larger of σ(fx)/fx and σ(fy)/fy; NaN when either is.
        rel: f64,
        /// Views solved on.
        views: usize,
    },
}

impl DiscRejection {
    /// The clause a one-line note quotes.
    pub fn summary(&self) -> String {
        match self {
            DiscRejection::NoCalibration(n) => n.summary(),
            DiscRejection::LooseFocal { rel, views } => {
                format!("the focal length ±{:.1} % (1σ) from {views} views", 100.0 * rel)
            }
        }
    }
}

impl fmt::Display for DiscRejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DiscRejection::NoCalibration(n) => write!(f, "{n}"),
            DiscRejection::LooseFocal { .. } => write!(
                f,
                "{}; a disc's centre may lie a pixel off its circle's, so discs are taken only where their views fix the focal length within {:.0} %",
                self.summary(),
                100.0 * DISC_FALLBACK_FOCAL_RELATIVE
            ),
        }
    }
}

/// Why a calibration from filled discs, tried where the rings gave none, is not taken: it is
/// no calibration ([`no_calibration`]), or its focal length is looser than
/// [`DISC_FALLBACK_FOCAL_RELATIVE`]; `None` when it is taken.
pub fn disc_fallback_rejects(result: &Result<Outcome, PipelineError>) -> Option<DiscRejection> {
    if let Some(why) = no_calibration(result) {
        return Some(DiscRejection::NoCalibration(why));
    }
    let o = result.as_ref().ok()?;
    let (k, sd) = (&o.calibration.intrinsics, &o.calibration.std_dev);
    let (rx, ry) = (sd[0] / k.fx.abs(), sd[1] / k.fy.abs());
    // A NaN σ is no fixed focal length either (and `f64::max` would pass it over).
    let rel = if rx.is_nan() || ry.is_nan() { f64::NAN } else { rx.max(ry) };
    (rel.is_nan() || rel > DISC_FALLBACK_FOCAL_RELATIVE)
        .then_some(DiscRejection::LooseFocal { rel, views: o.calibration.views.len() })
}

/// What [`calibrate_with_disc_fallback`] did about filled discs.
#[derive(Debug, Clone, PartialEq)]
pub enum DiscFallback {
    /// The rings gave a calibration; no discs were asked for.
    NotNeeded,
    /// The rings gave none, and the caller had no discs to offer (a stream read once, or
    /// discs not wanted).
    NotTried {
        /// Why the rings gave none.
        rings_failed: NoCalibration,
    },
    /// The rings gave none and the discs' calibration was refused: the rings' result stands.
    Rejected {
        /// Why the rings gave none.
        rings_failed: NoCalibration,
        /// Why the discs' was refused.
        why: DiscRejection,
    },
    /// The rings gave none and the discs' calibration is the result.
    Taken {
        /// Why the rings gave none.
        rings_failed: NoCalibration,
    },
}

impl DiscFallback {
    /// The warning a calibration from discs carries among its own, so that calibration.json
    /// says it too; `None` unless the discs were taken.
    pub fn warning(&self) -> Option<String> {
        let DiscFallback::Taken { rings_failed } = self else { return None };
        Some(format!(
            "circles fitted as filled discs where no ring fitted: the rings alone gave no calibration ({}); a disc's centre is less sure than a ring's, so more light (or a faster photoreceptor bias) gives a better calibration",
            rings_failed.summary()
        ))
    }
}

/// The views calibrated from and what came of them ([`calibrate_with_disc_fallback`]).
#[derive(Debug, Clone)]
pub struct Chosen {
    /// The rings' views, or the discs' when those were taken.
    pub views: Views,
    /// Their calibration.
    pub result: Result<Outcome, PipelineError>,
    /// Whether the discs were asked for and taken.
    pub fallback: DiscFallback,
}

/// Calibrates from `views` (ring fits) and, when they give no calibration, from the views of
/// filled discs that `discs` gives, taking those only if [`disc_fallback_rejects`] passes
/// them (their calibration carries [`DiscFallback::warning`]).
///
/// The discs cost accuracy where rings hold (a dim room's scenes read worse with them,
/// docs/accuracy.md) and are the only circles where the slow pixels of a dark circle fill it
/// (a large sensor in dim light), so they are fitted only where rings failed: `discs` is
/// called only then, with why, and returns `Ok(None)` when it has none to give (standard
/// input was read once). It returns views rather than detections so that the caller finds
/// the grid with the same [`Setup`] as it shows its progress, and keeps the windows if it
/// wants them.
pub fn calibrate_with_disc_fallback<E>(
    views: Views,
    setup: &Setup,
    discs: impl FnOnce(&NoCalibration) -> Result<Option<Views>, E>,
) -> Result<Chosen, E> {
    let result = calibrate_views(&views, setup);
    let Some(rings_failed) = no_calibration(&result) else {
        return Ok(Chosen { views, result, fallback: DiscFallback::NotNeeded });
    };
    let Some(disc_views) = discs(&rings_failed)? else {
        return Ok(Chosen { views, result, fallback: DiscFallback::NotTried { rings_failed } });
    };
    let disc_result = calibrate_views(&disc_views, setup);
    if let Some(why) = disc_fallback_rejects(&disc_result) {
        return Ok(Chosen { views, result, fallback: DiscFallback::Rejected { rings_failed, why } });
    }
    let fallback = DiscFallback::Taken { rings_failed };
    let result = disc_result.map(|mut o| {
        o.calibration.warnings.extend(fallback.warning());
        o
    });
    Ok(Chosen { views: disc_views, result, fallback })
}
