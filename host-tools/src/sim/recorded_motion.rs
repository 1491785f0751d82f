//! A recorded motion played back: the simulator's camera follows poses read from a file
//! instead of one of the hand-held [`Trajectory`](super::Trajectory) families.
//!
//! What it is for: telling what a recording's motion allows from what its pixels do. The
//! same poses (and, when the file gives them, the same camera and grid) simulated with
//! evcal's pixels and several seeds show how far the calibration of that motion scatters
//! when only the noise changes; a recording that errs within that scatter errs by its
//! motion, not by a bias of its pixels.
//!
//! The file is JSON, as the ground truth of recordings made by an independent pixel
//! emulator lays it out (`truth.json`, see `docs/accuracy.md`): poses at a fixed rate in
//! `frames30.frames` (or `frames`), each `{"t": s, "rvec": [..], "tvec": [..]}`, board to
//! camera as OpenCV's (`X_cam = R(rvec)·X_board + tvec`, metres), with the board's circle
//! (i, j) at (i·S, (2j + i mod 2)·S, 0). Optional: `K` (`fx, fy, cx, cy`), `dist` (`k1, k2,
//! p1, p2, k3`), `sensor` (`width, height`) and `pattern` (`rows, cols, spacing_m,
//! radius_m`), which [`RecordedMotion::apply`] puts into a configuration.

use super::{camera::Pose, SimConfig};
use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// Poses at a fixed rate, and what else the file gave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedMotion {
    /// Time of the first pose, seconds from the simulation's start.
    pub t0: f64,
    /// Seconds between poses.
    pub dt: f64,
    /// Each pose's Rodrigues vector and translation (board → camera).
    pub poses: Vec<([f64; 3], [f64; 3])>,
    /// The camera's intrinsics and distortion `[fx, fy, cx, cy, k1, k2, p1, p2, k3]`, when
    /// the file gives them.
    pub intrinsics: Option<[f64; 9]>,
    /// The sensor's size, when the file gives it.
    pub sensor: Option<[u16; 2]>,
    /// The grid `[rows, cols]`, its spacing and its circles' radius (metres), when the file
    /// gives them.
    pub pattern: Option<([usize; 2], f64, f64)>,
}

/// Why a file is no recorded motion.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionError(pub String);

impl std::fmt::Display for MotionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for MotionError {}

/// Largest departure of a pose's time from the fixed rate, in intervals: the interpolation
/// assumes evenly spaced poses.
const RATE_TOLERANCE: f64 = 1e-3;

impl RecordedMotion {
    /// Reads a recorded motion from JSON text (see the module's documentation).
    pub fn from_json(text: &str) -> Result<Self, MotionError> {
        let err = |m: String| MotionError(m);
        let v: serde_json::Value = serde_json::from_str(text).map_err(|e| err(format!("not JSON: {e}")))?;
        let frames = v
            .pointer("/frames30/frames")
            .or_else(|| v.get("frames"))
            .and_then(|f| f.as_array())
            .ok_or_else(|| err("no poses: expected an array `frames30.frames` or `frames`".into()))?;
        if frames.len() < 2 {
            return Err(err(format!("{} pose(s): a motion needs at least 2", frames.len())));
        }
        let num = |f: &serde_json::Value, k: &str, i: usize| -> Result<f64, MotionError> {
            f.get(k)
                .and_then(|x| x.as_f64())
                .filter(|x| x.is_finite())
                .ok_or_else(|| err(format!("pose {i}: `{k}` is missing or not a finite number")))
        };
        let vec3 = |f: &serde_json::Value, k: &str, i: usize| -> Result<[f64; 3], MotionError> {
            let a = f
                .get(k)
                .and_then(|x| x.as_array())
                .filter(|a| a.len() == 3)
                .ok_or_else(|| err(format!("pose {i}: `{k}` is not an array of 3 numbers")))?;
            let mut out = [0.0; 3];
            for (o, x) in out.iter_mut().zip(a) {
                *o = x
                    .as_f64()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| err(format!("pose {i}: `{k}` holds a value that is not a finite number")))?;
            }
            Ok(out)
        };
        let mut times = Vec::with_capacity(frames.len());
        let mut poses = Vec::with_capacity(frames.len());
        for (i, f) in frames.iter().enumerate() {
            times.push(num(f, "t", i)?);
            let (r, t) = (vec3(f, "rvec", i)?, vec3(f, "tvec", i)?);
            if t[2] <= 0.0 {
                return Err(err(format!("pose {i}: the board is not in front of the camera (tvec z = {})", t[2])));
            }
            poses.push((r, t));
        }
        let (t0, dt) = (times[0], (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64);
        if dt.is_nan() || dt <= 0.0 {
            return Err(err("the poses' times do not increase".into()));
        }
        if let Some((i, t)) =
            times.iter().enumerate().find(|(i, t)| ((*t - t0 - *i as f64 * dt) / dt).abs() > RATE_TOLERANCE)
        {
            return Err(err(format!(
                "pose {i} at {t} s is off the fixed rate of one pose every {dt} s: the poses must be evenly spaced"
            )));
        }
        let field = |o: &str, k: &str| v.get(o).and_then(|x| x.get(k)).and_then(|x| x.as_f64());
        let intrinsics = match (v.get("K"), v.get("dist")) {
            (Some(_), Some(_)) => {
                let mut out = [0.0; 9];
                for (o, (obj, k)) in out.iter_mut().zip([
                    ("K", "fx"),
                    ("K", "fy"),
                    ("K", "cx"),
                    ("K", "cy"),
                    ("dist", "k1"),
                    ("dist", "k2"),
                    ("dist", "p1"),
                    ("dist", "p2"),
                    ("dist", "k3"),
                ]) {
                    *o = field(obj, k)
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| err(format!("`{obj}.{k}` is missing or not a finite number")))?;
                }
                if !(out[0] > 0.0 && out[1] > 0.0) {
                    return Err(err("`K`: the focal lengths must be positive".into()));
                }
                Some(out)
            }
            _ => None,
        };
        let sensor = match (field("sensor", "width"), field("sensor", "height")) {
            (Some(w), Some(h)) if (1.0..=65535.0).contains(&w) && (1.0..=65535.0).contains(&h) => {
                Some([w as u16, h as u16])
            }
            (None, None) => None,
            _ => return Err(err("`sensor`: width and height must be whole numbers of pixels".into())),
        };
        let pattern = match v.get("pattern") {
            None => None,
            Some(_) => {
                let rows = field("pattern", "rows").filter(|x| *x >= 1.0 && x.fract() == 0.0);
                let cols = field("pattern", "cols").filter(|x| *x >= 1.0 && x.fract() == 0.0);
                let s = field("pattern", "spacing_m").filter(|x| *x > 0.0 && x.is_finite());
                let r = field("pattern", "radius_m").filter(|x| *x > 0.0 && x.is_finite());
                match (rows, cols, s, r) {
                    (Some(rows), Some(cols), Some(s), Some(r)) if r < s => Some(([rows as usize, cols as usize], s, r)),
                    _ => {
                        return Err(err(
                            "`pattern`: rows and cols (whole numbers), spacing_m and radius_m (metres, the \
                             radius less than the spacing) are needed"
                                .into(),
                        ))
                    }
                }
            }
        };
        Ok(Self { t0, dt, poses, intrinsics, sensor, pattern })
    }

    /// Seconds from the simulation's start to the last pose.
    pub fn end(&self) -> f64 {
        self.t0 + self.dt * (self.poses.len() - 1) as f64
    }

    /// The pose at `t` seconds: a Catmull–Rom spline through the poses, component by
    /// component (rotation vectors of a smooth motion sampled tens of times a second change
    /// little from one pose to the next); the first or last pose outside their span.
    pub fn pose(&self, t: f64) -> Pose {
        let n = self.poses.len();
        let s = ((t - self.t0) / self.dt).clamp(0.0, (n - 1) as f64);
        let i = (s.floor() as usize).min(n - 2);
        let u = s - i as f64;
        // Beyond either end, a pose continued in a straight line from the last two (a
        // repeated end pose would bend the first and last intervals of a steady motion).
        let at = |k: isize| -> ([f64; 3], [f64; 3]) {
            let last = n as isize - 1;
            let (a, b) = match k {
                k if k < 0 => (self.poses[0], self.poses[1]),
                k if k > last => (self.poses[n - 1], self.poses[n - 2]),
                k => return self.poses[k as usize],
            };
            ([0, 1, 2].map(|j| 2.0 * a.0[j] - b.0[j]), [0, 1, 2].map(|j| 2.0 * a.1[j] - b.1[j]))
        };
        let i = i as isize;
        let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
        let spline = |a: f64, b: f64, c: f64, d: f64| {
            0.5 * (2.0 * b
                + (c - a) * u
                + (2.0 * a - 5.0 * b + 4.0 * c - d) * u * u
                + (3.0 * b - a - 3.0 * c + d) * u * u * u)
        };
        let r = [0, 1, 2].map(|k| spline(p0.0[k], p1.0[k], p2.0[k], p3.0[k]));
        let t = [0, 1, 2].map(|k| spline(p0.1[k], p1.1[k], p2.1[k], p3.1[k]));
        Pose { rotation: Rotation3::new(Vector3::from(r)), translation: Vector3::from(t) }
    }

    /// Puts into `cfg` this motion and what else the file gave: the camera's intrinsics,
    /// distortion and sensor size, and the grid; the lens is focused at the median depth of
    /// the grid's middle over the motion ([`SimConfig::distance`]). Returns what it took from
    /// the file, for the user to read (e.g. `["camera", "grid"]`).
    pub fn apply(self, cfg: &mut SimConfig) -> Vec<&'static str> {
        let mut took = Vec::new();
        if let Some([fx, fy, cx, cy, k1, k2, p1, p2, k3]) = self.intrinsics {
            let c = &mut cfg.camera;
            (c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.p1, c.p2, c.k3) = (fx, fy, cx, cy, k1, k2, p1, p2, k3);
            took.push("camera");
        }
        if let Some([w, h]) = self.sensor {
            (cfg.camera.width, cfg.camera.height) = (w, h);
            took.push("sensor size");
        }
        if let Some(([rows, cols], spacing, radius)) = self.pattern {
            let b = &mut cfg.board;
            (b.rows, b.cols, b.spacing, b.radius) = (rows, cols, spacing, radius);
            took.push("grid");
        }
        // In focus where the board mostly is: its middle's median depth over the motion.
        let [mx, my] = cfg.board.middle();
        let mut depths: Vec<f64> = self
            .poses
            .iter()
            .map(|(r, t)| (Rotation3::new(Vector3::from(*r)) * Vector3::new(mx, my, 0.0)).z + t[2])
            .filter(|z| z.is_finite() && *z > 0.0)
            .collect();
        depths.sort_by(f64::total_cmp);
        if let Some(z) = depths.get(depths.len() / 2) {
            cfg.distance = *z;
        }
        cfg.recorded_motion = Some(self);
        took
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{Board, Trajectory};

    fn json_of(frames: &[(f64, [f64; 3], [f64; 3])]) -> String {
        let f: Vec<_> = frames.iter().map(|(t, r, tv)| serde_json::json!({ "t": t, "rvec": r, "tvec": tv })).collect();
        serde_json::json!({ "frames30": { "frames": f } }).to_string()
    }

    #[test]
    fn follows_a_smooth_motion_between_its_poses() {
        // A spiral sampled at 30 Hz, read back at times between the samples.
        let b = Board::preset("3x7").unwrap();
        let traj = |t: f64| Trajectory::Spiral.pose(&b, 0.5, [0.45, 0.35], t);
        let frames: Vec<_> = (0..=60).map(|k| k as f64 / 30.0).map(|t| (t, traj(t).rvec(), traj(t).tvec())).collect();
        let r = RecordedMotion::from_json(&json_of(&frames)).unwrap();
        assert!((r.dt - 1.0 / 30.0).abs() < 1e-12 && r.end() > 1.99);
        for k in 0..50 {
            let t = 0.1 + 0.037 * k as f64;
            let (got, want) = (r.pose(t), traj(t));
            let dr = got.rotation.angle_to(&want.rotation);
            let dt = (got.translation - want.translation).norm();
            assert!(dr < 2e-4 && dt < 2e-4, "t {t}: rotation off by {dr} rad, translation by {dt} m");
        }
        // At the poses themselves, the poses.
        let p = r.pose(1.0);
        assert!(p.rotation.angle_to(&traj(1.0).rotation) < 1e-9);
    }

    #[test]
    fn says_what_is_wrong_with_a_file() {
        let ok = [0.0, 0.0, 0.0];
        let front = [0.0, 0.0, 0.5];
        let cases = [
            ("[1, 2]".to_string(), "no poses"),
            (json_of(&[(0.0, ok, front)]), "at least 2"),
            (json_of(&[(0.0, ok, front), (0.1, ok, front), (0.25, ok, front)]), "evenly spaced"),
            (json_of(&[(0.1, ok, front), (0.0, ok, front)]), "do not increase"),
            (json_of(&[(0.0, ok, front), (0.1, ok, [0.0, 0.0, -0.5])]), "not in front"),
            (
                r#"{"frames": [{"t": 0, "rvec": [0, 0, 0], "tvec": [0, 0, 1]}, {"t": 1, "rvec": [0, 0], "tvec": [0, 0, 1]}]}"#
                    .to_string(),
                "pose 1: `rvec` is not an array of 3",
            ),
            ("{".to_string(), "not JSON"),
        ];
        for (text, says) in cases {
            let e = RecordedMotion::from_json(&text).unwrap_err().to_string();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn takes_the_camera_and_grid_the_file_gives() {
        let text = r#"{"K": {"fx": 355.0, "fy": 354.3, "cx": 160.4, "cy": 125.3},
            "dist": {"k1": -0.34, "k2": 0.12, "p1": -0.0005, "p2": -0.0005, "k3": 0.0},
            "sensor": {"width": 346, "height": 260},
            "pattern": {"rows": 3, "cols": 7, "spacing_m": 0.034, "radius_m": 0.0119},
            "frames": [{"t": 0, "rvec": [0, 0, 0], "tvec": [0, 0, 0.5]},
                       {"t": 0.5, "rvec": [0, 0, 0], "tvec": [0, 0, 0.6]}]}"#;
        let r = RecordedMotion::from_json(text).unwrap();
        let mut cfg = SimConfig::preset("dvxplorer", "4x11", Trajectory::Cone, crate::sim::Light::Good, 1).unwrap();
        let took = r.apply(&mut cfg);
        assert_eq!(took, ["camera", "sensor size", "grid"]);
        assert_eq!((cfg.camera.width, cfg.camera.fx, cfg.camera.k1), (346, 355.0, -0.34));
        assert_eq!((cfg.board.rows, cfg.board.cols, cfg.board.radius), (3, 7, 0.0119));
        let mid = cfg.recorded_motion.as_ref().unwrap().pose(0.25);
        assert!((mid.translation.z - 0.55).abs() < 1e-12);
        // Focused on the board: its middle at the median of 0.5 and 0.6 m (the upper one).
        assert!((cfg.distance - 0.6).abs() < 1e-12, "{}", cfg.distance);
    }
}
