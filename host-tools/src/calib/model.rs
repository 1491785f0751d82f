//! The camera model: OpenCV's pinhole with radial–tangential distortion, exactly as
//! `cv::projectPoints` computes it, and its derivatives.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// Intrinsics and distortion in OpenCV's model: pixel (0, 0) is the centre of the top-left
/// pixel; a point (x, y, z) in camera coordinates (z forward) projects through
/// `x' = x/z, y' = y/z, r² = x'² + y'²`,
/// `x'' = x'(1 + k1r² + k2r⁴ + k3r⁶) + 2p1x'y' + p2(r² + 2x'²)`,
/// `y'' = y'(1 + k1r² + k2r⁴ + k3r⁶) + p1(r² + 2y'²) + 2p2x'y'`,
/// `u = fx·x'' + cx, v = fy·y'' + cy`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, px.
    pub fx: f64,
    /// Focal length along y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
    /// Radial distortion, r².
    pub k1: f64,
    /// Radial distortion, r⁴.
    pub k2: f64,
    /// Tangential distortion.
    pub p1: f64,
    /// Tangential distortion.
    pub p2: f64,
    /// Radial distortion, r⁶.
    pub k3: f64,
}

impl Intrinsics {
    /// The parameters as a vector, in the order of [`PARAMETER_NAMES`].
    pub fn to_array(&self) -> [f64; 9] {
        [self.fx, self.fy, self.cx, self.cy, self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// The parameters from a vector in the order of [`PARAMETER_NAMES`].
    pub fn from_array(a: [f64; 9]) -> Self {
        Self { fx: a[0], fy: a[1], cx: a[2], cy: a[3], k1: a[4], k2: a[5], p1: a[6], p2: a[7], k3: a[8] }
    }

    /// The camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// The distortion coefficients in OpenCV's order: k1, k2, p1, p2, k3.
    pub fn distortion(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// The pixel of a normalised image point (x/z, y/z).
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        let (xd, yd) = distort_normalised(self, x, y);
        [self.fx * xd + self.cx, self.fy * yd + self.cy]
    }

    /// The pixel of a point in camera coordinates, or `None` when it is not in front.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        (p.z > 1e-12).then(|| self.distort(p.x / p.z, p.y / p.z))
    }
}

/// Names of the nine intrinsic parameters, in the order used throughout [`calib`](super).
pub const PARAMETER_NAMES: [&str; 9] = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];

fn distort_normalised(k: &Intrinsics, x: f64, y: f64) -> (f64, f64) {
    let r2 = x * x + y * y;
    let radial = 1.0 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
    let xd = x * radial + 2.0 * k.p1 * x * y + k.p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + k.p1 * (r2 + 2.0 * y * y) + 2.0 * k.p2 * x * y;
    (xd, yd)
}

/// A view's pose: board coordinates to camera coordinates, `p_cam = R·p + t` (OpenCV's rvec,
/// tvec).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Board → camera rotation.
    pub rotation: Rotation3<f64>,
    /// The board's origin in camera coordinates, metres.
    pub translation: Vector3<f64>,
}

impl Pose {
    /// The rotation as a Rodrigues vector (OpenCV's rvec).
    pub fn rvec(&self) -> [f64; 3] {
        let v = self.rotation.scaled_axis();
        [v.x, v.y, v.z]
    }

    /// The translation (OpenCV's tvec), metres.
    pub fn tvec(&self) -> [f64; 3] {
        [self.translation.x, self.translation.y, self.translation.z]
    }

    /// The pose turned by a small rotation `d` (applied after it, in camera coordinates) and
    /// moved by `dt`: the update of the solver's steps.
    pub(crate) fn moved(&self, d: &[f64; 6]) -> Self {
        let turn = Rotation3::from_scaled_axis(Vector3::new(d[0], d[1], d[2]));
        Self { rotation: turn * self.rotation, translation: turn * self.translation + Vector3::new(d[3], d[4], d[5]) }
    }
}

/// One projected point and its derivatives: with respect to the nine intrinsics (in the
/// order of [`PARAMETER_NAMES`]) and to a pose change `(δ, δt)` as [`Pose::moved`] applies it.
pub(crate) struct Projection {
    pub pixel: [f64; 2],
    pub d_intrinsics: [[f64; 9]; 2],
    pub d_pose: [[f64; 6]; 2],
}

/// Projects a board point through a pose and the intrinsics, with derivatives; `None` when
/// the point is behind the camera.
pub(crate) fn project(k: &Intrinsics, pose: &Pose, object: &[f64; 3]) -> Option<Projection> {
    let p = pose.rotation * Vector3::new(object[0], object[1], object[2]) + pose.translation;
    if p.z <= 1e-12 || !p.z.is_finite() {
        return None;
    }
    let iz = 1.0 / p.z;
    let (x, y) = (p.x * iz, p.y * iz);
    let r2 = x * x + y * y;
    let r4 = r2 * r2;
    let r6 = r4 * r2;
    let radial = 1.0 + k.k1 * r2 + k.k2 * r4 + k.k3 * r6;
    let xd = x * radial + 2.0 * k.p1 * x * y + k.p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + k.p1 * (r2 + 2.0 * y * y) + 2.0 * k.p2 * x * y;
    let pixel = [k.fx * xd + k.cx, k.fy * yd + k.cy];

    // ∂(u, v)/∂(fx, fy, cx, cy, k1, k2, p1, p2, k3)
    let d_intrinsics = [
        [xd, 0.0, 1.0, 0.0, k.fx * x * r2, k.fx * x * r4, k.fx * 2.0 * x * y, k.fx * (r2 + 2.0 * x * x), k.fx * x * r6],
        [0.0, yd, 0.0, 1.0, k.fy * y * r2, k.fy * y * r4, k.fy * (r2 + 2.0 * y * y), k.fy * 2.0 * x * y, k.fy * y * r6],
    ];

    // ∂(xd, yd)/∂(x, y): the distortion's own Jacobian.
    let d_radial = 2.0 * (k.k1 + 2.0 * k.k2 * r2 + 3.0 * k.k3 * r4); // ∂radial/∂(r²)·2
    let dxd_dx = radial + x * d_radial * x + 2.0 * k.p1 * y + k.p2 * 6.0 * x;
    let dxd_dy = x * d_radial * y + 2.0 * k.p1 * x + k.p2 * 2.0 * y;
    let dyd_dx = y * d_radial * x + k.p1 * 2.0 * x + 2.0 * k.p2 * y;
    let dyd_dy = radial + y * d_radial * y + k.p1 * 6.0 * y + 2.0 * k.p2 * x;
    // ∂(u, v)/∂(x, y)
    let duv = [[k.fx * dxd_dx, k.fx * dxd_dy], [k.fy * dyd_dx, k.fy * dyd_dy]];
    // ∂(x, y)/∂p (camera point)
    let dxy = [[iz, 0.0, -x * iz], [0.0, iz, -y * iz]];
    // ∂(u, v)/∂p
    let mut dp = [[0.0; 3]; 2];
    for r in 0..2 {
        for c in 0..3 {
            dp[r][c] = duv[r][0] * dxy[0][c] + duv[r][1] * dxy[1][c];
        }
    }
    // p moves by δ × p under a small rotation δ (applied after the pose), and by δt.
    // ∂p/∂δ = −[p]×.
    let px = [[0.0, p.z, -p.y], [-p.z, 0.0, p.x], [p.y, -p.x, 0.0]];
    let mut d_pose = [[0.0; 6]; 2];
    for r in 0..2 {
        for c in 0..3 {
            d_pose[r][c] = dp[r][0] * px[0][c] + dp[r][1] * px[1][c] + dp[r][2] * px[2][c];
            d_pose[r][3 + c] = dp[r][c];
        }
    }
    Some(Projection { pixel, d_intrinsics, d_pose })
}

/// Points on a circle's outline that [`outline_offset`] projects. The polygon's area
/// centroid approaches the outline's as 1/n²: 128 corners put it within 5e-5 px of a fine
/// outline's for a circle of 10 px tilted by 0.3 rad (32 corners: 5e-4 px).
const OUTLINE_CORNERS: usize = 128;

/// The unit circle's [`OUTLINE_CORNERS`] corners, `(cos, sin)`: computed once, since every
/// point of every solve projects them (their sines and cosines were a tenth of `evcal
/// demo`'s time).
fn unit_corners() -> &'static [[f64; 2]; OUTLINE_CORNERS] {
    static CORNERS: std::sync::OnceLock<[[f64; 2]; OUTLINE_CORNERS]> = std::sync::OnceLock::new();
    CORNERS.get_or_init(|| {
        let step = std::f64::consts::TAU / OUTLINE_CORNERS as f64;
        std::array::from_fn(|j| {
            let a = step * j as f64;
            [a.cos(), a.sin()]
        })
    })
}

/// How far the centre of a circle's image lies from the image of its centre, px: the circle
/// of `radius` (metres) around board point `centre`, seen through `pose` and `k`.
///
/// A circle seen at a slant images as an ellipse whose centre is not the projection of the
/// circle's centre (Heikkilä 2000): the nearer half is drawn larger. Circle fits find the
/// outline's centre, so the solve compares them with `project(centre) + outline_offset`.
/// `None` when part of the outline is behind the camera.
pub fn outline_offset(k: &Intrinsics, pose: &Pose, centre: &[f64; 3], radius: f64) -> Option<[f64; 2]> {
    let at = |x: f64, y: f64| k.project(&(pose.rotation * Vector3::new(x, y, centre[2]) + pose.translation));
    let c = at(centre[0], centre[1])?;
    let (mut area, mut sx, mut sy) = (0.0, 0.0, 0.0);
    let unit = unit_corners();
    let corner = |j: usize| {
        let [cos, sin] = unit[j];
        at(centre[0] + radius * cos, centre[1] + radius * sin).map(|p| [p[0] - c[0], p[1] - c[1]])
    };
    let first = corner(0)?;
    let mut prev = first;
    for j in 1..=OUTLINE_CORNERS {
        let next = if j == OUTLINE_CORNERS { first } else { corner(j)? };
        let cross = prev[0] * next[1] - next[0] * prev[1];
        area += cross;
        sx += (prev[0] + next[0]) * cross;
        sy += (prev[1] + next[1]) * cross;
        prev = next;
    }
    (area.abs() > 1e-12).then(|| [sx / (3.0 * area), sy / (3.0 * area)])
}

#[cfg(test)]
mod test {
    use super::*;

    fn camera() -> Intrinsics {
        Intrinsics { fx: 355.0, fy: 354.0, cx: 170.0, cy: 129.0, k1: -0.34, k2: 0.13, p1: 6e-4, p2: -4e-4, k3: 0.02 }
    }

    fn pose() -> Pose {
        Pose {
            rotation: Rotation3::from_scaled_axis(Vector3::new(0.3, -0.2, 0.1)),
            translation: Vector3::new(-0.05, 0.02, 0.4),
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let (k, pose, obj) = (camera(), pose(), [0.07, 0.05, 0.0]);
        let p = project(&k, &pose, &obj).unwrap();
        let h = 1e-7;
        for i in 0..9 {
            let mut a = k.to_array();
            let step = h * a[i].abs().max(1e-3);
            a[i] += step;
            let q = project(&Intrinsics::from_array(a), &pose, &obj).unwrap();
            for r in 0..2 {
                let fd = (q.pixel[r] - p.pixel[r]) / step;
                assert!(
                    (fd - p.d_intrinsics[r][i]).abs() <= 1e-4 * fd.abs().max(1.0),
                    "intrinsic {i} row {r}: {fd} vs {}",
                    p.d_intrinsics[r][i]
                );
            }
        }
        for i in 0..6 {
            let mut d = [0.0; 6];
            d[i] = 1e-7;
            let q = project(&k, &pose.moved(&d), &obj).unwrap();
            for r in 0..2 {
                let fd = (q.pixel[r] - p.pixel[r]) / 1e-7;
                assert!(
                    (fd - p.d_pose[r][i]).abs() <= 1e-3 * fd.abs().max(1.0),
                    "pose {i} row {r}: {fd} vs {}",
                    p.d_pose[r][i]
                );
            }
        }
    }

    #[test]
    fn a_slanted_circle_images_off_its_centre_the_way_the_simulator_draws_it() {
        // Without distortion: the area centroid of a fine outline, independently.
        let k = Intrinsics { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0, ..camera() };
        let (pose, obj, r) = (pose(), [0.07, 0.05, 0.0], 0.012);
        let d = outline_offset(&k, &pose, &obj, r).unwrap();
        let n = 4096;
        let pts: Vec<[f64; 2]> = (0..n)
            .map(|j| {
                let a = std::f64::consts::TAU * j as f64 / n as f64;
                k.project(
                    &(pose.rotation * Vector3::new(obj[0] + r * a.cos(), obj[1] + r * a.sin(), 0.0) + pose.translation),
                )
                .unwrap()
            })
            .collect();
        let (mut area, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for j in 0..n {
            let (p, q) = (pts[j], pts[(j + 1) % n]);
            let c = p[0] * q[1] - q[0] * p[1];
            area += c;
            cx += (p[0] + q[0]) * c;
            cy += (p[1] + q[1]) * c;
        }
        let c = k.project(&(pose.rotation * Vector3::new(obj[0], obj[1], 0.0) + pose.translation)).unwrap();
        let want = [cx / (3.0 * area) - c[0], cy / (3.0 * area) - c[1]];
        assert!(d[0].hypot(d[1]) > 0.01, "a 0.3 rad slant moves the centre: {d:?}");
        assert!((d[0] - want[0]).abs() < 5e-5 && (d[1] - want[1]).abs() < 5e-5, "{d:?} vs {want:?}");
        // Head-on, the image of the centre is the centre of the image.
        let front = Pose { rotation: Rotation3::identity(), translation: Vector3::new(0.0, 0.0, 0.4) };
        let d0 = outline_offset(&k, &front, &[0.0, 0.0, 0.0], r).unwrap();
        assert!(d0[0].hypot(d0[1]) < 1e-9, "{d0:?}");
    }

    #[test]
    fn matches_the_simulator_camera() {
        // The simulator implements the same model independently.
        let k = camera();
        let sim = crate::sim::Camera {
            width: 346,
            height: 260,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            k1: k.k1,
            k2: k.k2,
            p1: k.p1,
            p2: k.p2,
            k3: k.k3,
        };
        for (x, y) in [(0.1, -0.2), (-0.3, 0.25), (0.0, 0.0)] {
            let (a, b) = (k.distort(x, y), sim.distort(x, y));
            assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
        }
    }
}
