//! The projection matrix a ROS `camera_info` carries: the camera matrix of the undistorted
//! image, as ROS's `camera_calibration` computes it with OpenCV's
//! `getOptimalNewCameraMatrix(K, D, size, alpha = 0)`, so that `image_proc`'s rectified image
//! from evcal's file is the one a ROS user expects (every pixel of it valid, none black).

use super::Intrinsics;

/// Grid points per side over which the image's border is undistorted: OpenCV's.
const BORDER_SAMPLES: usize = 9;
/// Fixed-point iterations of the undistortion: OpenCV's `undistortPoints` default
/// (`TermCriteria(COUNT, 5)`); more would move the result away from what ROS writes where
/// the distortion is strong at the corners.
const UNDISTORT_ITERATIONS: usize = 5;

/// The camera matrix (row-major 3x3) of the undistorted image of a `size` sensor seen through
/// `k`, scaled so that the largest rectangle inside the undistorted image fills it (OpenCV's
/// `alpha = 0`, principal point not centred). Intrinsics that are not finite give a matrix
/// that is not either.
pub fn optimal_new_camera_matrix(k: &Intrinsics, size: [u32; 2]) -> [f64; 9] {
    let (w, h) = (f64::from(size[0].max(1)), f64::from(size[1].max(1)));
    let n = BORDER_SAMPLES;
    // OpenCV keeps the inner rectangle in single precision; so does this, to write its digits.
    let (mut x0, mut x1, mut y0, mut y1) = (f32::MIN, f32::MAX, f32::MIN, f32::MAX);
    for i in 0..n {
        for j in 0..n {
            let u = j as f64 * (w - 1.0) / (n - 1) as f64;
            let v = i as f64 * (h - 1.0) / (n - 1) as f64;
            let (x, y) = undistort_as_opencv(k, u, v);
            let (x, y) = (x as f32, y as f32);
            if j == 0 {
                x0 = x0.max(x);
            }
            if j == n - 1 {
                x1 = x1.min(x);
            }
            if i == 0 {
                y0 = y0.max(y);
            }
            if i == n - 1 {
                y1 = y1.min(y);
            }
        }
    }
    let (rw, rh) = (f64::from(x1 - x0), f64::from(y1 - y0));
    let (fx, fy) = ((w - 1.0) / rw, (h - 1.0) / rh);
    let (cx, cy) = (-fx * f64::from(x0), -fy * f64::from(y0));
    [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
}

/// The normalised ray OpenCV's `undistortPoints` gives for pixel (u, v): its fixed-point
/// iteration, [`UNDISTORT_ITERATIONS`] times, stopping where the radial factor turns
/// negative (the model folded over) at the distorted coordinates, as OpenCV does.
fn undistort_as_opencv(k: &Intrinsics, u: f64, v: f64) -> (f64, f64) {
    let (x0, y0) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
    let (mut x, mut y) = (x0, y0);
    for _ in 0..UNDISTORT_ITERATIONS {
        let r2 = x * x + y * y;
        let icdist = 1.0 / (1.0 + ((k.k3 * r2 + k.k2) * r2 + k.k1) * r2);
        if icdist < 0.0 {
            return (x0, y0);
        }
        let dx = 2.0 * k.p1 * x * y + k.p2 * (r2 + 2.0 * x * x);
        let dy = k.p1 * (r2 + 2.0 * y * y) + 2.0 * k.p2 * x * y;
        (x, y) = ((x0 - dx) * icdist, (y0 - dy) * icdist);
    }
    (x, y)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn no_distortion_keeps_the_camera_matrix() {
        let k = Intrinsics { fx: 350.0, fy: 349.0, cx: 172.0, cy: 130.0, k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 };
        let m = optimal_new_camera_matrix(&k, [346, 260]);
        for (got, want) in [(m[0], k.fx), (m[4], k.fy), (m[2], k.cx), (m[5], k.cy)] {
            assert!((got - want).abs() < 1e-3 * want, "{m:?}");
        }
    }

    #[test]
    fn barrel_distortion_widens_the_view_and_pincushion_narrows_it() {
        // Barrel (k1 < 0): the sensor's edges undistort to rays farther out than a pinhole
        // would see there, so the largest valid rectangle spans more: a shorter focal length.
        let barrel =
            Intrinsics { fx: 350.0, fy: 350.0, cx: 173.0, cy: 130.0, k1: -0.34, k2: 0.13, p1: 0.0, p2: 0.0, k3: 0.0 };
        let m = optimal_new_camera_matrix(&barrel, [346, 260]);
        assert!(m[0] < barrel.fx && m[4] < barrel.fy, "{m:?}");
        let pincushion = Intrinsics { k1: 0.2, k2: 0.0, ..barrel };
        let m = optimal_new_camera_matrix(&pincushion, [346, 260]);
        assert!(m[0] > barrel.fx && m[4] > barrel.fy, "{m:?}");
    }
}
