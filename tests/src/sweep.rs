//! The sweep of the simulated pixel's physics: its cases, the targets each is held to
//! (issue 16), and one case run from simulation to calibration. The `physics_sweep`
//! example prints every case as a table; `tests/tests/end_to_end/physics.rs` holds a corner of it (a smoke case in CI, the rest in the slow tier).

use crate::recorded::Recorded;
use evcal_host::{
    pipeline::{calibrate_with_disc_fallback, views_from_windows, Chosen, DiscFallback, Setup, FOCAL_WARN_RELATIVE},
    sim::{Light, PixelModel, SimConfig, Trajectory},
    views::grid::Pattern,
};
use std::path::Path;

/// The seed every case of the sweep's table is simulated with.
pub const SEED: u64 = 5;

/// One case of the sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case {
    /// How the board moves.
    pub trajectory: Trajectory,
    /// Scene light.
    pub light: Light,
    /// Photoreceptor cutoff at full light, Hz (infinite: an ideal pixel).
    pub photoreceptor_hz: f64,
    /// Edge blur at the focus distance, px, when out of focus (`None`: the preset's focus).
    pub blur_px: Option<f64>,
    /// Contrast threshold and its pixel-to-pixel mismatch (σ), log units, when not the
    /// light's (0.25, mismatch 0.03 in good light, 0.04 in low).
    pub threshold: Option<(f64, f64)>,
    /// The noise the pixels add.
    pub noise: Noise,
}

/// How noisy a case's pixels are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Noise {
    /// `PixelModel::physical`'s: leak events at 0.1 Hz a pixel, shot noise at 1 Hz in the
    /// dark, the light's background activity and hot pixels.
    Preset,
    /// None at all: no leak, shot noise, background activity or hot pixels.
    Clean,
    /// A dim room's: leak events at 0.5 Hz a pixel and shot noise at 5 Hz in the dark (v2e's
    /// noisy settings are of this order), the light's background and hot pixels.
    DimRoom,
}

impl Noise {
    /// Name in the table.
    pub fn name(self) -> &'static str {
        match self {
            Noise::Preset => "preset",
            Noise::Clean => "clean",
            Noise::DimRoom => "dim room",
        }
    }
}

impl Case {
    /// The board the case uses: a 3x9 grid on spirals (it stays in view), 4x11 on cones.
    pub fn pattern(&self) -> &'static str {
        if self.trajectory == Trajectory::Spiral {
            "3x9"
        } else {
            "4x11"
        }
    }

    /// The photoreceptor column of the table.
    pub fn photoreceptor(&self) -> String {
        if self.photoreceptor_hz.is_finite() {
            format!("{:.0} Hz", self.photoreceptor_hz)
        } else {
            "unlimited".into()
        }
    }

    /// The focus column of the table.
    pub fn focus(&self) -> String {
        self.blur_px.map_or_else(|| "in".into(), |b| format!("out ({b} px)"))
    }

    /// The threshold and noise column of the table.
    pub fn pixel(&self) -> String {
        let t = self.threshold.map_or_else(|| "θ preset".into(), |(t, m)| format!("θ {t} ± {m}"));
        format!("{t}, noise {}", self.noise.name())
    }

    /// A case of the base grid: the light's threshold, the preset noise, in focus.
    pub const fn base(trajectory: Trajectory, light: Light, photoreceptor_hz: f64) -> Self {
        Self { trajectory, light, photoreceptor_hz, blur_px: None, threshold: None, noise: Noise::Preset }
    }

    /// The simulator's configuration of the case on `sensor` with the sweep's seed
    /// ([`SEED`]), and its grid; `None` for an unknown sensor.
    pub fn config(&self, sensor: &str) -> Option<(SimConfig, Pattern)> {
        self.config_seeded(sensor, SEED)
    }

    /// [`Case::config`] with another seed: the same scene and pixels, another draw of the
    /// pixels' mismatch and noise and of the wall's clutter (the motion is the same), to
    /// tell a bias from one run's scatter.
    pub fn config_seeded(&self, sensor: &str, seed: u64) -> Option<(SimConfig, Pattern)> {
        let mut cfg = SimConfig::preset(sensor, self.pattern(), self.trajectory, self.light, seed)?;
        cfg.pixel = PixelModel::physical(self.light, self.photoreceptor_hz);
        if let Some((t, m)) = self.threshold {
            cfg.pixel.threshold = t;
            cfg.pixel.mismatch = m;
        }
        match self.noise {
            Noise::Preset => {}
            Noise::Clean => {
                cfg.pixel.leak_hz = 0.0;
                cfg.pixel.shot_noise_hz = 0.0;
                cfg.pixel.background_hz = 0.0;
                cfg.pixel.hot_fraction = 0.0;
            }
            Noise::DimRoom => {
                cfg.pixel.leak_hz = 0.5;
                cfg.pixel.shot_noise_hz = 5.0;
            }
        }
        if let Some(b) = self.blur_px {
            cfg.blur_px = b;
        }
        let grid = Pattern::new(cfg.board.rows, cfg.board.cols, cfg.board.spacing).ok()?;
        Some((cfg, grid))
    }

    /// What the case is held to: the figure for its kind of scene.
    pub fn targets(&self) -> Targets {
        // The square keeps the board parallel to the sensor: as little tilt as the spiral.
        let tilting = self.trajectory == Trajectory::Cone;
        match (self.light, self.blur_px.is_some()) {
            (_, true) => Targets { focal_pct: 0.5, centre_px: 2.0 },
            (Light::Good, false) => Targets { focal_pct: 0.1, centre_px: 0.5 },
            (Light::Low, false) if tilting => Targets { focal_pct: 0.2, centre_px: 1.0 },
            (Light::Low, false) => Targets { focal_pct: 0.5, centre_px: 2.0 },
        }
    }
}

/// Every case of the sweep. The base grid: photoreceptor cutoff at full light unlimited,
/// 1000, 300 and 100 Hz; good and low light; cone and spiral, with the light's threshold and
/// `PixelModel::physical`'s noise. Around it, one thing changed at a time from a pixel of
/// 300 Hz: out of focus (edge blur 2.5 px at the focus distance) on the good-light cone and
/// spiral; the square motion (the board parallel to the sensor, its grid along the sensor's
/// edges) in good and low light, and with an ideal pixel in good light; thresholds of 0.15 and 0.5 with mismatch (the cone in good
/// light; 0.5 also on the spiral); no noise at all, and a dim room's noise (the cone in low
/// light; the spiral in low light too).
pub fn cases() -> Vec<Case> {
    use {Light::*, Trajectory::*};
    let mut out = Vec::new();
    for light in [Good, Low] {
        for trajectory in [Cone, Spiral] {
            for hz in [f64::INFINITY, 1000.0, 300.0, 100.0] {
                out.push(Case::base(trajectory, light, hz));
            }
        }
    }
    out.push(Case { blur_px: Some(2.5), ..Case::base(Cone, Good, 300.0) });
    out.push(Case { blur_px: Some(2.5), ..Case::base(Spiral, Good, 300.0) });
    out.push(Case::base(Square, Good, f64::INFINITY));
    out.push(Case::base(Square, Good, 300.0));
    out.push(Case::base(Square, Low, 300.0));
    out.push(Case { threshold: Some((0.15, 0.02)), ..Case::base(Cone, Good, 300.0) });
    out.push(Case { threshold: Some((0.5, 0.06)), ..Case::base(Cone, Good, 300.0) });
    out.push(Case { threshold: Some((0.5, 0.06)), ..Case::base(Spiral, Good, 300.0) });
    out.push(Case { noise: Noise::Clean, ..Case::base(Cone, Low, 300.0) });
    out.push(Case { noise: Noise::DimRoom, ..Case::base(Cone, Low, 300.0) });
    out.push(Case { noise: Noise::DimRoom, ..Case::base(Spiral, Low, 300.0) });
    out
}

/// Largest error of a parameter, in units of its printed σ.
pub const MAX_SIGMAS: f64 = 3.0;

/// The accuracy a case must reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Targets {
    /// |fx|, |fy| error, percent.
    pub focal_pct: f64,
    /// |cx|, |cy| error, px.
    pub centre_px: f64,
}

/// What one case gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// fx, fy error (%), cx, cy error (px).
    pub errors: [f64; 4],
    /// The printed σ of the same, in the same units.
    pub sigmas: [f64; 4],
    /// RMS reprojection error, px.
    pub rms_px: f64,
    /// Views solved on.
    pub views: usize,
    /// The run said the calibration failed (exit status 3).
    pub failed: bool,
    /// The run warned that the focal length is weakly fixed.
    pub focal_warning: bool,
    /// The rings alone gave no calibration and this is the filled discs' (as `evcal
    /// calibrate` falls back to them).
    pub filled_discs: bool,
}

impl Outcome {
    /// What the case misses of its targets (empty: it meets them all): the accuracy, every
    /// error within [`MAX_SIGMAS`] σ, and a warning whenever σ(fx) exceeds 0.1 %.
    pub fn misses(&self, t: &Targets) -> Vec<String> {
        let mut out = Vec::new();
        let [fx, fy, cx, cy] = self.errors;
        if self.failed {
            out.push("the run said the calibration failed".into());
        }
        if fx.abs() > t.focal_pct || fy.abs() > t.focal_pct {
            out.push(format!("fx {fx:+.3} %, fy {fy:+.3} % (target {} %)", t.focal_pct));
        }
        if cx.abs() > t.centre_px || cy.abs() > t.centre_px {
            out.push(format!("cx {cx:+.2}, cy {cy:+.2} px (target {} px)", t.centre_px));
        }
        for (name, (e, s)) in ["fx", "fy", "cx", "cy"].iter().zip(self.errors.iter().zip(&self.sigmas)) {
            if e.abs() > MAX_SIGMAS * s {
                out.push(format!("{name} {:+.1}σ off", e / s));
            }
        }
        if self.sigmas[0] > 100.0 * FOCAL_WARN_RELATIVE && !self.focal_warning {
            out.push(format!("σ(fx) {:.3} % without a warning", self.sigmas[0]));
        }
        out
    }
}

/// Simulates `seconds` of `case` on `sensor` continuously (a slow photoreceptor must not be
/// settled at every window) and calibrates from it with `evcal calibrate`'s defaults; `Err`
/// with the reason when there is no calibration at all. `cache`: see [`Recorded::simulate`].
pub fn run(case: &Case, sensor: &str, seconds: f64, cache: Option<&Path>) -> Result<Outcome, String> {
    let rec = record(case, sensor, SEED, seconds, cache).ok_or_else(|| format!("unknown sensor {sensor}"))?;
    run_on(case, sensor, &rec)
}

/// The core's windows of `seconds` of `case` on `sensor`, simulated continuously (a slow
/// photoreceptor must not be settled at every window), simulated with `seed` ([`SEED`] for
/// the sweep's table); `None` for an unknown sensor. `cache`: see [`Recorded::simulate`].
pub fn record(case: &Case, sensor: &str, seed: u64, seconds: f64, cache: Option<&Path>) -> Option<Recorded> {
    let (cfg, _) = case.config_seeded(sensor, seed)?;
    Some(Recorded::simulate(cfg, seconds, false, cache))
}

/// [`run`] on windows [`record`] gave.
pub fn run_on(case: &Case, sensor: &str, rec: &Recorded) -> Result<Outcome, String> {
    let (cfg, pattern) = case.config(sensor).ok_or_else(|| format!("unknown sensor {sensor}"))?;
    let cam = cfg.camera;
    let setup = Setup::new(pattern, [u32::from(cam.width), u32::from(cam.height)]);
    let views = views_from_windows(&rec.windows, &setup, &|_| {});
    // As `evcal calibrate`: filled discs where the rings give no calibration, if they give one.
    let discs = |_: &_| {
        let some = !rec.disc_windows.is_empty();
        Ok::<_, std::convert::Infallible>(some.then(|| views_from_windows(&rec.disc_windows, &setup, &|_| {})))
    };
    let Ok(Chosen { result, fallback, .. }) = calibrate_with_disc_fallback(views, &setup, discs);
    let filled_discs = matches!(fallback, DiscFallback::Taken { .. });
    let o = result.map_err(|e| e.to_string())?;
    let (k, sd) = (o.calibration.intrinsics, o.calibration.std_dev);
    Ok(Outcome {
        errors: [100.0 * (k.fx / cam.fx - 1.0), 100.0 * (k.fy / cam.fy - 1.0), k.cx - cam.cx, k.cy - cam.cy],
        sigmas: [100.0 * sd[0] / k.fx, 100.0 * sd[1] / k.fy, sd[2], sd[3]],
        rms_px: o.calibration.rms_px,
        views: o.calibration.views.len(),
        failed: o.failure.is_some(),
        focal_warning: o.weak_focal.is_some(),
        filled_discs,
    })
}

/// How far the detected centres of `case` lag their circles along the motion, by the
/// circle's image speed: `(speed from, to (px/s), centres, mean lag (px, negative: behind))`
/// for each 50 px/s bin with at least 20 centres, against the simulator's truth (the centre
/// of each circle's outline at the window's reference time; the motion from the windows on
/// either side). A lag the same at every speed is a distance (what `views::edge_shift`
/// models); one growing in proportion to the speed is a delay, which a view's pose absorbs
/// when all its circles share it. `r`: what [`record`] gave.
pub fn lag_by_speed(r: &Recorded) -> Vec<(f64, f64, usize, f64)> {
    const BIN: f64 = 50.0;
    let mut bins = vec![(0usize, 0.0f64); 16];
    for k in 0..r.windows.len() {
        for (_, _, d, v) in paired(r, k, LAG_PAIRING_PX) {
            let speed = v[0].hypot(v[1]);
            let bin = &mut bins[((speed / BIN) as usize).min(15)];
            bin.0 += 1;
            bin.1 += (d[0] * v[0] + d[1] * v[1]) / speed;
        }
    }
    bins.iter()
        .enumerate()
        .filter(|(_, b)| b.0 >= 20)
        .map(|(i, b)| (BIN * i as f64, BIN * (i + 1) as f64, b.0, b.1 / b.0 as f64))
        .collect()
}

/// A centre paired with its circle: `(centre index in its window, the truth, the error
/// (px), the circle's image velocity (px/s))`.
type Pair = (usize, [f64; 2], [f64; 2], [f64; 2]);

/// How far from its circle's true centre a centre is paired with it for [`lag_by_speed`], px:
/// beyond, the nearest circle is not this centre's, or the fit is a stray.
const LAG_PAIRING_PX: f64 = 2.0;

/// How far for [`decompose`], px: a dim pixel's centres lag their circles by up to 2 px, and
/// the grid's circles lie 10 px and more apart.
const DECOMPOSE_PAIRING_PX: f64 = 4.0;

/// The centres of window `k` of `r` paired with their circles: each centre within `max_px`
/// of a circle wholly in view that moves, its velocity from the windows on either side
/// (none for the first and last windows).
fn paired(r: &Recorded, k: usize, max_px: f64) -> Vec<Pair> {
    let (Some(before), Some(after)) = (k.checked_sub(1).and_then(|j| r.windows.get(j)), r.windows.get(k + 1)) else {
        return Vec::new();
    };
    let dt = (after.t_ref_us as f64 - before.t_ref_us as f64) * 1e-6;
    if dt <= 0.0 {
        return Vec::new();
    }
    let mut out = Vec::new();
    for (ci, c) in r.windows[k].centers.iter().enumerate() {
        let p = [f64::from(c.u), f64::from(c.v)];
        let Some(i) = r.nearest(k, p) else { continue };
        let (t, a, b) = (&r.truth[k][i], &r.truth[k - 1][i], &r.truth[k + 1][i]);
        let d = [p[0] - t.centre[0], p[1] - t.centre[1]];
        if !t.in_view || d[0].hypot(d[1]) > max_px {
            continue;
        }
        let v = [(b.centre[0] - a.centre[0]) / dt, (b.centre[1] - a.centre[1]) / dt];
        if v[0].hypot(v[1]) > 1e-9 {
            out.push((ci, t.centre, d, v));
        }
    }
    out
}

/// Which part of the centres' error carries a case's bias: `run_on` again on the centres
/// paired with a circle (within 4 px; the others left out), each replaced by the
/// truth plus a part of its error. Rows: the paired centres as detected; the truth alone;
/// the truth plus the error along the circle's motion only; plus the error across it only;
/// per window, the error along the motion replaced by a straight line in the image
/// speed fitted to that window's centres (what a lag that differs between a view's circles
/// only by their speeds can be, to first order); and the truth plus each window's mean error
/// along the motion only (a shift that differs from view to view, not between a view's
/// circles; telling only where a view's circles move alike, as on the square: where their
/// speeds differ, as on a cone, it turns a delay the poses absorb into shifts they do not).
/// Each row is `(what, outcome)`. `r`: what
/// [`record`] gave.
pub fn decompose(case: &Case, sensor: &str, r: &Recorded) -> Vec<(&'static str, Result<Outcome, String>)> {
    const PARTS: [&str; 6] = [
        "the paired centres as detected",
        "truth alone",
        "truth plus the error along the motion",
        "truth plus the error across the motion",
        "along the motion: each window's line in the speed",
        "truth plus each window's mean error along the motion",
    ];
    // Per window: its pairs (centre index, truth, unit motion, speed, error along, error
    // across), and the line in the speed fitted to the errors along (mean speed, mean error,
    // slope); the same for every part.
    let windows: Vec<_> = (0..r.windows.len())
        .map(|k| {
            let paired: Vec<_> = paired(r, k, DECOMPOSE_PAIRING_PX)
                .into_iter()
                .map(|(ci, t, d, v)| {
                    let speed = v[0].hypot(v[1]);
                    let u = [v[0] / speed, v[1] / speed];
                    (ci, t, u, speed, d[0] * u[0] + d[1] * u[1], -d[0] * u[1] + d[1] * u[0])
                })
                .collect();
            let n = (paired.len() as f64).max(1.0);
            let ms = paired.iter().map(|x| x.3).sum::<f64>() / n;
            let ma = paired.iter().map(|x| x.4).sum::<f64>() / n;
            let sss: f64 = paired.iter().map(|x| (x.3 - ms).powi(2)).sum();
            let ssa: f64 = paired.iter().map(|x| (x.3 - ms) * (x.4 - ma)).sum();
            let slope = if sss > 1e-9 { ssa / sss } else { 0.0 };
            (paired, ms, ma, slope)
        })
        .collect();
    PARTS
        .iter()
        .enumerate()
        .map(|(part, &what)| {
            let mut moved = r.clone();
            for (k, (paired, ms, ma, slope)) in windows.iter().enumerate() {
                let mut kept = Vec::with_capacity(paired.len());
                for &(ci, t, u, speed, along, across) in paired {
                    let (a, c) = match part {
                        0 => (along, across),
                        1 => (0.0, 0.0),
                        2 => (along, 0.0),
                        3 => (0.0, across),
                        4 => (ma + slope * (speed - ms), across),
                        _ => (*ma, 0.0),
                    };
                    let mut c_ = r.windows[k].centers[ci];
                    c_.u = (t[0] + a * u[0] - c * u[1]) as f32;
                    c_.v = (t[1] + a * u[1] + c * u[0]) as f32;
                    kept.push(c_);
                }
                moved.windows[k].centers = kept;
            }
            (what, run_on(case, sensor, &moved))
        })
        .collect()
}
