//! How far the k3 term of a lens model reaches: what decides whether a model without it
//! (Kalibr's radtan) is still the calibrated camera, and whether a solve with k3 fixed is
//! worth offering beside one with it free.

use super::Intrinsics;

/// The largest pixel displacement k3 may cause and still be left out of a Kalibr camchain
/// (radtan has no k3): a twentieth of a pixel, well below what a grid of circle centres
/// measures (a calibration's RMS is a few tenths of a pixel at best).
pub const K3_NEGLIGIBLE_PX: f64 = 0.05;

/// How far (px) the k3 term moves the image of the ray that lands on the farthest of the
/// four corner pixels: `|k3|·r⁶` times that ray's distance from the axis, in pixels, where r
/// is its normalised (undistorted) radius. Leaving k3 out of a model moves the image by at
/// most this much; 0 when k3 is 0. NaN for intrinsics that are not finite.
pub fn k3_displacement_px(k: &Intrinsics, image_size: [u32; 2]) -> f64 {
    if k.k3 == 0.0 {
        return 0.0;
    }
    let (w, h) = (f64::from(image_size[0].max(1)) - 1.0, f64::from(image_size[1].max(1)) - 1.0);
    let without = Intrinsics { k3: 0.0, ..*k };
    let mut worst = 0.0f64;
    for (u, v) in [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)] {
        let (x, y) = undistort(k, u, v);
        let a = k.distort(x, y);
        let b = without.distort(x, y);
        let d = (a[0] - b[0]).hypot(a[1] - b[1]);
        if d.is_nan() {
            return f64::NAN;
        }
        worst = worst.max(d);
    }
    worst
}

/// The normalised ray (x/z, y/z) that `k` images at pixel (u, v), by the fixed-point
/// iteration OpenCV's `undistortPoints` uses, run until it settles. Where it does not
/// (distortion so strong that the model folds over before the corner), the pixel's
/// distorted normalised coordinates stand in: the displacement then errs low, which is the
/// side a warning about a badly behaved k3 can afford.
fn undistort(k: &Intrinsics, u: f64, v: f64) -> (f64, f64) {
    let (xd, yd) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
    let (mut x, mut y) = (xd, yd);
    for _ in 0..200 {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
        let dx = 2.0 * k.p1 * x * y + k.p2 * (r2 + 2.0 * x * x);
        let dy = k.p1 * (r2 + 2.0 * y * y) + 2.0 * k.p2 * x * y;
        if radial <= 0.0 || !radial.is_finite() {
            break;
        }
        (x, y) = ((xd - dx) / radial, (yd - dy) / radial);
        let p = k.distort(x, y);
        if (p[0] - u).hypot(p[1] - v) < 1e-9 {
            return (x, y);
        }
    }
    (xd, yd)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn k3_displacement_matches_a_direct_solution() {
        // Only k3: the corner's distorted radius ρ (normalised) comes from a ray of radius r
        // with r(1 + k3·r⁶) = ρ, solved here by bisection; k3 moves it by f·k3·r⁷ pixels.
        let k3 = 0.02;
        let k = Intrinsics { fx: 300.0, fy: 300.0, cx: 172.5, cy: 129.5, k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3 };
        let rho = 172.5f64.hypot(129.5) / 300.0;
        let (mut lo, mut hi) = (0.0, rho);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid * (1.0 + k3 * mid.powi(6)) < rho {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let want = 300.0 * k3 * lo.powi(7);
        let got = k3_displacement_px(&k, [346, 260]);
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        assert_eq!(k3_displacement_px(&Intrinsics { k3: 0.0, ..k }, [346, 260]), 0.0);
        // The farthest corner counts: a principal point off centre moves the worst corner.
        let off = Intrinsics { cx: 100.0, cy: 60.0, ..k };
        assert!(k3_displacement_px(&off, [346, 260]) > got);
    }
}
