//! The run's last word: `good`, `usable, but …` or `not a calibration`, from stated
//! thresholds on the parameters' σ, the sensor's coverage, the views and the residuals, with
//! at most [`MAX_ACTIONS`] things to do about it. `evcal calibrate` prints it last and exits
//! with [`Verdict::exit_code`]; `calibration.json` carries it.
//!
//! The thresholds are the accuracy evcal aims at, not the data of any one recording: a
//! focal length within 0.1 % (1σ) is what a lens-swap or a VIO pipeline notices; a
//! principal point within a pixel; points on most of the sensor, or the distortion is
//! guessed where they never were; and reprojection errors of event-fitted centres, which are
//! a few hundredths to a few tenths of a pixel when the pattern and focus are right.

use super::{verdicts::WeakFocalCause, Outcome, FOCAL_WARN_RELATIVE};
use crate::views::select::TiltSpread;
use std::fmt;

/// Good needs σ(fx) and σ(fy) within this fraction of the focal length (1σ): the
/// threshold above which the run already warns that the focal length is weakly fixed.
pub const GOOD_FOCAL_RELATIVE: f64 = FOCAL_WARN_RELATIVE;
/// Good needs σ(cx) and σ(cy) within this, px.
pub const GOOD_CENTRE_PX: f64 = 1.0;
/// Good needs the points on at least this fraction of the sensor's coverage cells
/// ([`crate::views::select::COVERAGE_CELLS`]); below it the advice says to sweep the sensor.
pub const GOOD_COVERAGE: f64 = crate::views::select::WELL_COVERED;
/// Good needs no distortion coefficient whose σ moves the image of the sensor's corner by
/// more than this, px ([`crate::calib::CORNER_SHIFT_PX`]): beyond it the model is guessed
/// where the points never were.
pub const GOOD_CORNER_PX: f64 = crate::calib::CORNER_SHIFT_PX;
/// Good needs the projection σ of a distant point ([`crate::calib::ProjectionSigma`]) within
/// this over 95 % of the sensor, px: the model a program undistorts with is then known to a
/// pixel everywhere, extrapolated corners included (the focal length's 0.1 % and the
/// principal point's pixel above give about as much at the sensor's edge).
pub const GOOD_PROJECTION_PX: f64 = 1.0;
/// Good needs at least this many views solved on.
pub const GOOD_VIEWS: usize = crate::views::select::FEW_VIEWS;
/// Good needs the RMS reprojection error within this, px: well-focused event centres fit
/// to a few hundredths or tenths; beyond half a pixel the pattern, the spacing, the focus or
/// the model is wrong somewhere.
pub const GOOD_RMS_PX: f64 = 0.5;
/// At most this many actions are named: the most useful first.
pub const MAX_ACTIONS: usize = 3;

/// Exit status of a good calibration.
pub const EXIT_GOOD: i32 = 0;
/// Exit status of a usable calibration that misses a threshold: files written, under their
/// usual names, and the actions say what to record again for.
pub const EXIT_USABLE: i32 = 4;
/// Exit status of a result that is no calibration: files named `*.failed.*`.
pub const EXIT_NOT_A_CALIBRATION: i32 = 3;

/// What a run's result is worth.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Every threshold met.
    Good,
    /// A calibration that misses at least one threshold.
    Usable {
        /// What to do, the most useful first; never empty, at most [`MAX_ACTIONS`].
        actions: Vec<String>,
    },
    /// The views leave a parameter too loose for any printed value to mean anything
    /// ([`Outcome::failure`]).
    NotACalibration {
        /// Why, in a clause.
        why: String,
    },
}

impl Verdict {
    /// The verdict on `o`.
    pub fn of(o: &Outcome) -> Self {
        if let Some(loose) = &o.failure {
            let params: Vec<String> = loose.params.iter().map(ToString::to_string).collect();
            return Verdict::NotACalibration { why: format!("{} ({})", loose.summary(), params.join(", ")) };
        }
        let c = &o.calibration;
        let k = &c.intrinsics;
        let mut actions = Vec::new();
        let focal = (c.std_dev[0] / k.fx.abs()).max(c.std_dev[1] / k.fy.abs());
        if exceeds(focal, GOOD_FOCAL_RELATIVE) {
            let cause = o.weak_focal.map(|w| w.cause);
            let tilt = TiltSpread::of(c).max_deg;
            actions.push(match cause {
                Some(WeakFocalCause::LacksTilt { .. }) => format!(
                    "tilt the target 20–40° towards each side in turn (fx ±{:.2} %, views tilted at most {tilt:.0}°)",
                    100.0 * focal
                ),
                _ => format!(
                    "record longer, tilting the target 20–40° while it sweeps the sensor (fx ±{:.2} %)",
                    100.0 * focal
                ),
            });
        }
        if c.views.len() < GOOD_VIEWS {
            actions.push(format!("record more views, from different places ({} used)", c.views.len()));
        }
        if o.coverage.covered.is_nan() || o.coverage.covered < GOOD_COVERAGE {
            actions.push(format!(
                "sweep the target over the whole sensor (points on {:.0} % of it)",
                100.0 * o.coverage.covered
            ));
        }
        // Distortion the views leave loose moves the image where the points never were.
        let shifts = crate::calib::corner_shifts(k, &c.std_dev, c.image_size);
        let (worst, name) = shifts
            .iter()
            .zip(crate::calib::PARAMETER_NAMES)
            .skip(4)
            .map(|(&s, n)| (if s.is_nan() { f64::INFINITY } else { s }, n))
            .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a });
        if worst > GOOD_CORNER_PX {
            actions.push(format!(
                "bring the target into the sensor's corners (1σ of {name} moves a corner {worst:.1} px)"
            ));
        }
        if let Some(p) = &o.projection_sigma {
            if exceeds(p.sensor.p95_px, GOOD_PROJECTION_PX) {
                actions.push(format!(
                    "sweep the target out to the sensor's edges: a distant point's image is uncertain by {} (95 % of the sensor)",
                    match p.sensor.p95_px.is_finite() {
                        true => format!("{:.1} px", p.sensor.p95_px),
                        false => "more than the model can say".into(),
                    }
                ));
            }
        }
        let centre = c.std_dev[2].max(c.std_dev[3]);
        if exceeds(centre, GOOD_CENTRE_PX) {
            actions.push(format!(
                "bring the tilted target into the sensor's corners (cx ±{:.1} px, cy ±{:.1} px)",
                c.std_dev[2], c.std_dev[3]
            ));
        }
        if exceeds(c.rms_px, GOOD_RMS_PX) {
            actions.push(format!(
                "check the focus, --pattern and --spacing: points miss the model by {:.2} px RMS",
                c.rms_px
            ));
        }
        if actions.is_empty() {
            Verdict::Good
        } else {
            actions.truncate(MAX_ACTIONS);
            Verdict::Usable { actions }
        }
    }

    /// The process's exit status for it: [`EXIT_GOOD`], [`EXIT_USABLE`] or
    /// [`EXIT_NOT_A_CALIBRATION`].
    pub fn exit_code(&self) -> i32 {
        match self {
            Verdict::Good => EXIT_GOOD,
            Verdict::Usable { .. } => EXIT_USABLE,
            Verdict::NotACalibration { .. } => EXIT_NOT_A_CALIBRATION,
        }
    }

    /// Its word, as `calibration.json`'s `verdict` holds it.
    pub fn grade(&self) -> &'static str {
        match self {
            Verdict::Good => "good",
            Verdict::Usable { .. } => "usable",
            Verdict::NotACalibration { .. } => "not a calibration",
        }
    }

    /// What to do about it (empty for a good one).
    pub fn actions(&self) -> &[String] {
        match self {
            Verdict::Usable { actions } => actions,
            _ => &[],
        }
    }
}

/// `x` beyond `limit`, or not a number (a σ the views do not fix).
fn exceeds(x: f64, limit: f64) -> bool {
    x.is_nan() || x > limit
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Verdict::Good => write!(f, "verdict: good"),
            Verdict::Usable { actions } => write!(f, "verdict: usable, but {}", actions.join("; ")),
            Verdict::NotACalibration { why } => write!(f, "verdict: not a calibration: {why}"),
        }
    }
}
