//! Ground truth: where each circle of the board is imaged at an instant, as a circle fit to
//! its edge would find it, and whether it is wholly in view.

use super::{Pose, SimConfig, Simulator};
use nalgebra::Vector3;
use serde::Serialize;

/// The true state of one circle at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CircleTruth {
    /// Index in the grid, `i·rows + j`.
    pub index: usize,
    /// Centre of the projected outline (the ellipse's centre; what a circle fit to the edge
    /// estimates), pixels.
    pub ellipse_centre: [f64; 2],
    /// Projection of the circle's centre (differs from the ellipse centre under
    /// perspective), pixels.
    pub projected_centre: [f64; 2],
    /// Mean distance of the projected outline from its centre, pixels.
    pub radius_px: f64,
    /// Whether the whole outline is inside the sensor (and in front of the camera).
    pub in_view: bool,
}

/// The truth at one instant.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameTruth {
    /// The instant, microseconds.
    pub t_us: u64,
    /// Board → camera rotation (Rodrigues vector).
    pub rvec: [f64; 3],
    /// Board → camera translation, metres.
    pub tvec: [f64; 3],
    /// Every circle of the grid.
    pub circles: Vec<CircleTruth>,
}

/// Points on a circle's outline used to find its projected centre and radius.
const OUTLINE_POINTS: usize = 96;

impl Simulator {
    /// Ground truth at `t_us` (timestamps as the events carry them).
    pub fn truth_at(&self, t_us: u64) -> FrameTruth {
        let t = t_us.saturating_sub(self.cfg.start_us) as f64 * 1e-6;
        truth(&self.cfg, &self.pose_at(t), t_us)
    }
}

/// The true image of every circle for a pose.
pub fn truth(cfg: &SimConfig, pose: &Pose, t_us: u64) -> FrameTruth {
    let cam = &cfg.camera;
    let (w, h) = (f64::from(cam.width), f64::from(cam.height));
    let circles = cfg
        .board
        .centres()
        .into_iter()
        .enumerate()
        .map(|(index, [cx, cy])| {
            let r = cfg.board.radius;
            let mut pts = Vec::with_capacity(OUTLINE_POINTS);
            let mut visible = true;
            for k in 0..OUTLINE_POINTS {
                let a = std::f64::consts::TAU * k as f64 / OUTLINE_POINTS as f64;
                match cam.project(&pose.apply(&Vector3::new(cx + r * a.cos(), cy + r * a.sin(), 0.0))) {
                    Some(p) => {
                        visible &= p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w - 1.0 && p[1] <= h - 1.0;
                        pts.push(p)
                    }
                    None => visible = false,
                }
            }
            let centre = polygon_centroid(&pts);
            let radius_px =
                pts.iter().map(|p| ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt()).sum::<f64>()
                    / pts.len().max(1) as f64;
            let projected_centre = cam.project(&pose.apply(&Vector3::new(cx, cy, 0.0))).unwrap_or([f64::NAN; 2]);
            CircleTruth { index, ellipse_centre: centre, projected_centre, radius_px, in_view: visible }
        })
        .collect();
    FrameTruth { t_us, rvec: pose.rvec(), tvec: pose.tvec(), circles }
}

/// Centroid of the area a closed outline encloses: for an ellipse, its centre.
fn polygon_centroid(pts: &[[f64; 2]]) -> [f64; 2] {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for k in 0..pts.len() {
        let [x0, y0] = pts[k];
        let [x1, y1] = pts[(k + 1) % pts.len()];
        let cross = x0 * y1 - x1 * y0;
        a += cross;
        cx += (x0 + x1) * cross;
        cy += (y0 + y1) * cross;
    }
    if a.abs() < 1e-12 {
        return [f64::NAN; 2];
    }
    [cx / (3.0 * a), cy / (3.0 * a)]
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::sim::{Light, Trajectory};

    #[test]
    fn truth_ellipse_centre_is_near_projected_centre_and_in_view_is_honest() {
        let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, 1).unwrap();
        let sim = Simulator::new(cfg);
        let t = sim.truth_at(500_000);
        for c in &t.circles {
            let d = ((c.ellipse_centre[0] - c.projected_centre[0]).powi(2)
                + (c.ellipse_centre[1] - c.projected_centre[1]).powi(2))
            .sqrt();
            assert!(d < 0.3, "ellipse vs projected centre {d}");
            assert!(c.radius_px > 3.0 && c.radius_px < 15.0, "{}", c.radius_px);
        }
        assert!(t.circles.iter().filter(|c| c.in_view).count() >= 30);
    }
}
