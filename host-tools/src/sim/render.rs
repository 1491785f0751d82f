//! What each pixel sees: the scene's log intensity through the camera, blurred by the depth
//! it is seen at, and the distance to the nearest edge.

use super::bands::{in_bands, BAND_PIXELS};
use super::Simulator;
use nalgebra::Vector3;

impl Simulator {
    fn blur(&self, depth: f64) -> f64 {
        let rel = ((depth - self.cfg.distance) / self.cfg.distance).abs();
        // A pixel integrates over its area: a box of width 1 adds variance 1/12.
        (self.cfg.blur_px.powi(2) + (self.cfg.defocus_px * rel).powi(2) + 1.0 / 12.0).sqrt()
    }

    /// Log intensity at pixel `p` for `pose`, and the distance to the nearest edge (px).
    pub(super) fn log_intensity(&self, to_board: &nalgebra::Matrix3<f64>, origin: [f64; 3], p: usize) -> (f64, f64) {
        let [x, y] = self.rays[p];
        let d = to_board * Vector3::new(x, y, 1.0);
        let focal = self.cfg.camera.fx.min(self.cfg.camera.fy);
        let (refl, dist) = self.scene.shade(origin, [d.x, d.y, d.z], focal, |depth| self.blur(depth));
        let px = &self.cfg.pixel;
        ((px.illumination * refl + px.dark).ln(), dist)
    }

    /// The scene's log intensity at every pixel at `t`, and the distance to the nearest edge's
    /// blurred zone (px); bands of pixels shared among threads.
    pub(super) fn levels_at(&self, t: f64) -> Vec<(f64, f64)> {
        let pose = self.pose_at(t);
        let origin: [f64; 3] = pose.centre().into();
        let to_board = *pose.rotation.inverse().matrix();
        in_bands(self.pixels.len(), BAND_PIXELS, |range| {
            range.map(|p| self.log_intensity(&to_board, origin, p)).collect::<Vec<_>>()
        })
        .concat()
    }
}
