//! Hand-held calibration motions: where the camera is and where it looks, over time.

use super::{camera::Pose, scene::Board};
use nalgebra::{Rotation3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// The motion families of E-Calib's dataset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Trajectory {
    /// The camera circles the board on a cone (tilted 15–35°), its gaze sweeping the grid
    /// over the whole sensor, with a slow roll and a varying distance.
    Cone,
    /// The camera moves on a square parallel to the board, looking at points that sweep the
    /// grid along the sensor's edges and corners.
    Square,
    /// The camera spirals out and back in, rolling up to ±60° about its axis.
    Spiral,
}

impl Trajectory {
    /// Name as the CLI spells it.
    pub fn name(self) -> &'static str {
        match self {
            Trajectory::Cone => "cone",
            Trajectory::Square => "square",
            Trajectory::Spiral => "spiral",
        }
    }

    /// The pose at time `t` (seconds) for a board viewed from about `distance` metres.
    /// `fov_half` is the sensor's half field of view (x, y), radians, used to sweep the
    /// grid across the image.
    pub fn pose(self, board: &Board, distance: f64, fov_half: [f64; 2], t: f64) -> Pose {
        let [gx, gy] = board.middle();
        let grid_w = (board.cols - 1) as f64 * board.spacing;
        let grid_h = (2 * board.rows - 1) as f64 * board.spacing;
        // How far the gaze may wander so that the grid reaches the sensor's edges: the view's
        // half extent at this distance, less the grid's half size.
        let reach = |half_fov: f64, half_grid: f64| (distance * half_fov.tan() - half_grid).max(0.0) * 0.95;
        let (ax, ay) = (reach(fov_half[0], grid_w * 0.5), reach(fov_half[1], grid_h * 0.5));
        let (centre, target, roll) = match self {
            Trajectory::Cone => {
                let tilt = (25.0 + 10.0 * (TAU * t / 7.3).sin()).to_radians();
                let d = distance * (1.0 + 0.12 * (TAU * t / 5.1).sin());
                let phi = TAU * t / 2.5;
                let rho = d * tilt.tan();
                let c = [gx + rho * phi.cos(), gy + rho * phi.sin(), -d];
                let g = [gx + ax * (TAU * t / 3.1).sin(), gy + ay * (TAU * t / 1.9 + 0.7).sin()];
                (c, g, 0.25 * (TAU * t / 9.0).sin())
            }
            Trajectory::Square => {
                let side = distance * 0.35;
                let (sx, sy) = square_path(t / 4.0);
                let (qx, qy) = square_path(t / 3.0 + 0.5);
                let c = [gx + side * sx, gy + side * sy, -distance * (1.0 + 0.1 * (TAU * t / 4.3).sin())];
                (c, [gx + ax * qx, gy + ay * qy], 0.1 * (TAU * t / 8.0).sin())
            }
            Trajectory::Spiral => {
                let grow = 0.15 + 0.85 * (std::f64::consts::PI * t / 8.0).sin().abs();
                let phi = TAU * t / 2.0;
                let rho = distance * 0.55 * grow;
                let c = [gx + rho * phi.cos(), gy + rho * phi.sin(), -distance * (1.0 - 0.1 * grow)];
                let g = [gx + ax * grow * (phi + 1.9).cos(), gy + ay * grow * (phi + 1.9).sin()];
                (c, g, (60.0f64).to_radians() * (TAU * t / 11.0).sin())
            }
        };
        look_at(centre, [target[0], target[1], 0.0], roll)
    }
}

/// A unit square walked at constant speed, one lap per unit of `s`: (x, y) in [−1, 1]².
fn square_path(s: f64) -> (f64, f64) {
    let u = (s.rem_euclid(1.0)) * 4.0;
    let f = u.fract() * 2.0 - 1.0;
    match u as u32 {
        0 => (f, -1.0),
        1 => (1.0, f),
        2 => (-f, 1.0),
        _ => (-1.0, -f),
    }
}

/// The pose of a camera at `centre` (board coordinates) looking at `target`, with the image's
/// down direction towards the board's +y, then rolled by `roll` about the optical axis.
pub fn look_at(centre: [f64; 3], target: [f64; 3], roll: f64) -> Pose {
    let c = Vector3::from(centre);
    let z = (Vector3::from(target) - c).normalize();
    let x = Vector3::y().cross(&z).normalize();
    let y = z.cross(&x);
    // Rows are the camera axes in board coordinates: board → camera.
    let r =
        Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]));
    let rolled = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::z()), roll) * r;
    Pose { rotation: rolled, translation: -(rolled * c) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_board_stays_in_front_of_the_camera() {
        let b = Board::preset("4x11").unwrap();
        for traj in [Trajectory::Cone, Trajectory::Square, Trajectory::Spiral] {
            for k in 0..200 {
                let pose = traj.pose(&b, 0.4, [0.45, 0.35], k as f64 * 0.05);
                let m = b.middle();
                let p = pose.apply(&Vector3::new(m[0], m[1], 0.0));
                assert!(p.z > 0.2 && p.z < 0.8, "{traj:?} t {}: depth {}", k as f64 * 0.05, p.z);
                // The printed side faces the camera: the board's +z points away from it.
                assert!((pose.rotation * Vector3::z()).z > 0.3);
            }
        }
    }
}
