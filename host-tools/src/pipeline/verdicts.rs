//! What a calibration's result says to its user: whether the focal length is weakly fixed,
//! whether there is a calibration at all, and why the filled discs' one is refused.

use super::*;

/// A focal length looser than this (1σ, relative) is worth a warning: the accuracy evcal
/// aims at.
pub const FOCAL_WARN_RELATIVE: f64 = 1e-3;
/// A focal length looser than this (1σ, relative), or a principal point looser than this
/// fraction of the sensor's size, is no calibration: a lens's focal length is known to
/// about this from its data sheet.
pub const FAILED_RELATIVE: f64 = 0.05;

/// A warning when σ(fx) or σ(fy) exceeds [`FOCAL_WARN_RELATIVE`], with the motion that fixes
/// the focal length: more tilt when the views lack it, else more of the sensor and more
/// views; and, when `lag` (what the edges' other lag model changes:
/// [`edge_shift::ByThickness`]) is most of σ, light enough for quick pixels.
pub(super) fn focal_warning(cal: &Calibration, coverage: &Coverage, lag: Option<&[f64; 9]>) -> Option<String> {
    let k = &cal.intrinsics;
    let rel = (cal.std_dev[0] / k.fx.abs()).max(cal.std_dev[1] / k.fy.abs());
    (rel > FOCAL_WARN_RELATIVE).then(|| {
        let tilt = crate::views::select::TiltSpread::of(cal);
        let fix = if tilt.max_deg < crate::views::select::GOOD_TILT_DEG {
            format!(
                "the views tilt the target by at most {:.0}°: only tilt tells the focal length from the distance (a target facing the sensor looks the same to a focal length twice as long from twice as far, its distortion rescaled to match, however near it comes). Record a cone: tilt the target 20–40° towards each side in turn while it sweeps the sensor",
                tilt.max_deg
            )
        } else {
            format!(
                "{} views, their points on {:.0} % of the sensor: record longer, tilting the target 20–40° to each side while it sweeps the whole sensor (in brighter light if the grid was missed in many windows)",
                cal.views.len(),
                100.0 * coverage.covered
            )
        };
        // Most of σ(fx) from the lag's model: the pixels are slow or the edges blurred.
        let lag_note = match lag {
            Some(c) if c[0].abs() > std::f64::consts::FRAC_1_SQRT_2 * cal.std_dev[0] => format!(
                "; most of it is how late the edges were seen (taking the lag in proportion to each edge's thickness rather than as one distance moves fx by {:+.2} %): more light, or a sharper focus, makes the edges quicker and thinner",
                100.0 * c[0] / k.fx.abs()
            ),
            _ => String::new(),
        };
        format!(
            "the focal length is weakly fixed: fx ±{:.2} %, fy ±{:.2} % (1σ; evcal aims at 0.1 %); {fix}{lag_note}",
            100.0 * cal.std_dev[0] / k.fx.abs(),
            100.0 * cal.std_dev[1] / k.fy.abs(),
        )
    })
}

/// Why a calibration attempt gave no calibration (its error, or [`Outcome::failure`]);
/// `None` when it gave one.
///
/// A recording whose ring fits give no calibration is detected again with filled discs
/// (`evcal_core::fit::FitConfig::filled_discs`) by `evcal calibrate` and the physics sweep
/// alike: the discs cost accuracy where rings hold (a dim room's scenes read worse with
/// them, docs/accuracy.md) and are the only circles where the slow pixels of a dark circle
/// fill it (a large sensor in dim light), so they are fitted only where rings failed.
pub fn no_calibration(result: &Result<Outcome, PipelineError>) -> Option<String> {
    match result {
        Ok(o) => o.failure.clone(),
        Err(e) => Some(e.to_string()),
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

/// Why a calibration from filled discs, tried where the rings gave none, is not taken: it is
/// no calibration ([`no_calibration`]), or its focal length is looser than
/// [`DISC_FALLBACK_FOCAL_RELATIVE`]; `None` when it is taken.
pub fn disc_fallback_rejects(result: &Result<Outcome, PipelineError>) -> Option<String> {
    if let Some(why) = no_calibration(result) {
        return Some(why);
    }
    let o = result.as_ref().ok()?;
    let (k, sd) = (&o.calibration.intrinsics, &o.calibration.std_dev);
    let (rx, ry) = (sd[0] / k.fx.abs(), sd[1] / k.fy.abs());
    // A NaN σ is no fixed focal length either (and `f64::max` would pass it over).
    let rel = if rx.is_nan() || ry.is_nan() { f64::NAN } else { rx.max(ry) };
    (rel.is_nan() || rel > DISC_FALLBACK_FOCAL_RELATIVE).then(|| {
        format!(
            "the focal length ±{:.1} % (1σ) from {} views; a disc's centre may lie a pixel off its circle's, so discs are taken only where their views fix the focal length within {:.0} %",
            100.0 * rel,
            o.calibration.views.len(),
            100.0 * DISC_FALLBACK_FOCAL_RELATIVE
        )
    })
}

/// Why `cal` is no calibration, if it is not: a parameter the views leave so loose that its
/// printed value means nothing (beyond [`FAILED_RELATIVE`]).
pub fn verdict(cal: &Calibration) -> Option<String> {
    let (k, sd) = (&cal.intrinsics, &cal.std_dev);
    let size = cal.image_size.map(f64::from);
    let mut loose = Vec::new();
    for (i, scale, unit) in [(0, k.fx.abs(), "%"), (1, k.fy.abs(), "%"), (2, size[0], "px"), (3, size[1], "px")] {
        if !(sd[i].is_finite() && sd[i] <= FAILED_RELATIVE * scale) {
            let name = crate::calib::PARAMETER_NAMES[i];
            loose.push(match unit {
                _ if !sd[i].is_finite() => format!("{name} not fixed at all"),
                "%" => format!("{name} ±{:.1} % (1σ)", 100.0 * sd[i] / scale),
                _ => format!("{name} ±{:.1} px (1σ)", sd[i]),
            });
        }
    }
    (!loose.is_empty()).then(|| {
        format!(
            "the views do not fix the camera: {} (at most {:.0} % of the focal length or the sensor's size is a calibration); record the target tilted 20–40° to each side, filling the sensor, in light bright enough for the grid to be found in most windows",
            loose.join(", "),
            100.0 * FAILED_RELATIVE
        )
    })
}
