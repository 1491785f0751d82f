//! The simulated camera: pinhole with OpenCV's radial–tangential distortion, and its pose.

use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// Intrinsics and sensor size, in OpenCV's model and conventions (pixel (0, 0) is the centre
/// of the top-left pixel).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Sensor width, pixels.
    pub width: u16,
    /// Sensor height, pixels.
    pub height: u16,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Radial distortion r².
    pub k1: f64,
    /// Radial distortion r⁴.
    pub k2: f64,
    /// Tangential distortion.
    pub p1: f64,
    /// Tangential distortion.
    pub p2: f64,
    /// Radial distortion r⁶.
    pub k3: f64,
}

impl Camera {
    /// A DAVIS346 (346×260) with a 4.5 mm lens: values of the order E-Calib reports.
    pub fn davis346() -> Self {
        Self {
            width: 346,
            height: 260,
            fx: 355.2,
            fy: 354.6,
            cx: 170.4,
            cy: 128.9,
            k1: -0.342,
            k2: 0.134,
            p1: 0.0006,
            p2: -0.0004,
            k3: 0.0,
        }
    }

    /// A DVXplorer (640×480).
    pub fn dvxplorer() -> Self {
        Self {
            width: 640,
            height: 480,
            fx: 553.5,
            fy: 553.1,
            cx: 318.2,
            cy: 241.7,
            k1: -0.214,
            k2: 0.052,
            p1: 0.0004,
            p2: 0.0002,
            k3: 0.0,
        }
    }

    /// A Prophesee IMX636 (EVK4 class, 1280×720, 4.86 µm pixels) behind a 6 mm C-mount
    /// lens: f = 6 mm / 4.86 µm ≈ 1235 px, a 55° horizontal view (the DAVIS346 preset's
    /// 52°, the DVXplorer's 60°). A longer lens than theirs for its sensor, so milder barrel
    /// distortion: 3 % at the corners (the DAVIS346 preset's 11 %).
    pub fn imx636() -> Self {
        Self {
            width: 1280,
            height: 720,
            fx: 1236.8,
            fy: 1236.1,
            cx: 641.3,
            cy: 358.2,
            k1: -0.118,
            k2: 0.092,
            p1: 0.0003,
            p2: -0.0002,
            k3: 0.0,
        }
    }

    /// A Prophesee GenX320 (320×320, 6.3 µm pixels, 1/5" optical format) behind a 2.1 mm M12
    /// lens: f = 2.1 mm / 6.3 µm ≈ 333 px, a 51° view across either side. A short M12 lens
    /// bends strongly: 13 % barrel distortion at the corners (the DAVIS346 preset's 11 %).
    pub fn genx320() -> Self {
        Self {
            width: 320,
            height: 320,
            fx: 334.5,
            fy: 334.1,
            cx: 161.2,
            cy: 158.6,
            k1: -0.361,
            k2: 0.148,
            p1: 0.0005,
            p2: -0.0003,
            k3: 0.0,
        }
    }

    /// The preset a sensor name stands for: `davis346`, `dvxplorer`, `imx636` (also `evk4`)
    /// or `genx320`; `None` for another name.
    pub fn preset(name: &str) -> Option<Self> {
        Some(match name {
            "davis346" => Self::davis346(),
            "dvxplorer" => Self::dvxplorer(),
            "imx636" | "evk4" => Self::imx636(),
            "genx320" => Self::genx320(),
            _ => return None,
        })
    }

    /// The names [`preset`](Self::preset) takes (aliases left out).
    pub const PRESETS: [&'static str; 4] = ["davis346", "dvxplorer", "imx636", "genx320"];

    /// Pixel of a normalised image point (x/z, y/z), through the distortion.
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        [self.fx * xd + self.cx, self.fy * yd + self.cy]
    }

    /// Pixel of a point in camera coordinates, or `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        (p.z > 1e-6).then(|| self.distort(p.x / p.z, p.y / p.z))
    }

    /// The normalised image point (x/z, y/z) seen at pixel (u, v): the inverse of
    /// [`distort`](Self::distort), by fixed-point iteration (as OpenCV's `undistortPoints`),
    /// run to convergence for the moderate distortion of these lenses.
    pub fn undistort(&self, u: f64, v: f64) -> [f64; 2] {
        let (xd, yd) = ((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
            let done = (nx - x).abs() < 1e-14 && (ny - y).abs() < 1e-14;
            (x, y) = (nx, ny);
            if done {
                break;
            }
        }
        [x, y]
    }
}

/// Where the camera is: the rigid motion taking board (world) coordinates into camera
/// coordinates, `p_cam = R · p_board + t` (OpenCV's rvec/tvec).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Board → camera rotation.
    pub rotation: Rotation3<f64>,
    /// Board origin in camera coordinates, metres.
    pub translation: Vector3<f64>,
}

impl Pose {
    /// A board point in camera coordinates.
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }

    /// The camera centre in board coordinates.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.rotation.inverse() * self.translation)
    }

    /// The rotation as a Rodrigues vector (OpenCV's rvec).
    pub fn rvec(&self) -> [f64; 3] {
        let v = self.rotation.scaled_axis();
        [v.x, v.y, v.z]
    }

    /// The translation (OpenCV's tvec), metres.
    pub fn tvec(&self) -> [f64; 3] {
        [self.translation.x, self.translation.y, self.translation.z]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort() {
        for cam in Camera::PRESETS.map(|n| Camera::preset(n).unwrap()) {
            for (u, v) in
                [(0.0, 0.0), (cam.cx, cam.cy), (f64::from(cam.width) - 1.0, 3.0), (17.0, f64::from(cam.height) - 10.0)]
            {
                let [x, y] = cam.undistort(u, v);
                let [u2, v2] = cam.distort(x, y);
                assert!((u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9, "{u} {v} -> {u2} {v2}");
            }
        }
    }
}
