//! The closed-form start: a homography per view (normalised DLT), Zhang's intrinsics from
//! them, and each view's pose from its homography.

use super::model::{Intrinsics, Pose};
use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};

/// The homography taking board points (x, y) (z = 0) to pixels, by the direct linear
/// transform on coordinates normalised to zero mean and unit spread (Hartley). `None` when
/// the points are too few or degenerate (collinear).
pub(crate) fn homography(object: &[[f64; 3]], image: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    let n = object.len().min(image.len());
    if n < 4 {
        return None;
    }
    let normaliser = |pts: &mut dyn Iterator<Item = [f64; 2]>| -> Option<Matrix3<f64>> {
        let pts: Vec<[f64; 2]> = pts.collect();
        let (mx, my) = pts.iter().fold((0.0, 0.0), |(a, b), p| (a + p[0], b + p[1]));
        let (mx, my) = (mx / n as f64, my / n as f64);
        let spread = pts.iter().map(|p| ((p[0] - mx).powi(2) + (p[1] - my).powi(2)).sqrt()).sum::<f64>() / n as f64;
        if !(spread > 0.0 && spread.is_finite()) {
            return None;
        }
        let s = std::f64::consts::SQRT_2 / spread;
        Some(Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0))
    };
    let tn = normaliser(&mut object.iter().map(|o| [o[0], o[1]]))?;
    let tm = normaliser(&mut image.iter().copied())?;
    let mut a = DMatrix::<f64>::zeros(2 * n, 9);
    for k in 0..n {
        let o = tn * Vector3::new(object[k][0], object[k][1], 1.0);
        let m = tm * Vector3::new(image[k][0], image[k][1], 1.0);
        let (x, y, u, v) = (o.x, o.y, m.x / m.z, m.y / m.z);
        let rows = [[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u], [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v]];
        for (r, row) in rows.iter().enumerate() {
            for (c, &val) in row.iter().enumerate() {
                a[(2 * k + r, c)] = val;
            }
        }
    }
    // The null vector of A: the right singular vector of the smallest singular value, from
    // the eigenvectors of AᵀA (9 x 9), which keeps the decomposition small for many points.
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let (imin, _) = eig.eigenvalues.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    let h = eig.eigenvectors.column(imin);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    // The second smallest eigenvalue near zero too means the points do not pin it down.
    let mut sorted: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    if sorted[1].is_nan() || sorted[1] <= 1e-10 * sorted[8] {
        return None;
    }
    let hm = tm.try_inverse()? * hn * tn;
    let scale = hm[(2, 2)];
    (scale.abs() > 1e-15 && hm.iter().all(|v| v.is_finite())).then(|| hm / scale)
}

/// Zhang's closed form for fx, fy, cx, cy (no skew) from three or more homographies; `None`
/// when they do not determine a camera (too few views, or views all alike).
pub(crate) fn zhang(homographies: &[Matrix3<f64>]) -> Option<[f64; 4]> {
    if homographies.len() < 3 {
        return None;
    }
    // v_ij of Zhang's paper: the constraints h1ᵀBh2 = 0 and h1ᵀBh1 = h2ᵀBh2 on B = K⁻ᵀK⁻¹.
    let v = |h: &Matrix3<f64>, i: usize, j: usize| {
        let (hi, hj) = (h.column(i), h.column(j));
        [
            hi[0] * hj[0],
            hi[0] * hj[1] + hi[1] * hj[0],
            hi[1] * hj[1],
            hi[2] * hj[0] + hi[0] * hj[2],
            hi[2] * hj[1] + hi[1] * hj[2],
            hi[2] * hj[2],
        ]
    };
    let rows = 2 * homographies.len() + 1;
    let mut a = DMatrix::<f64>::zeros(rows, 6);
    for (k, h) in homographies.iter().enumerate() {
        // Scale each homography to unit norm so that no view weighs more than another.
        let h = h / h.norm();
        let (v12, v11, v22) = (v(&h, 0, 1), v(&h, 0, 0), v(&h, 1, 1));
        for c in 0..6 {
            a[(2 * k, c)] = v12[c];
            a[(2 * k + 1, c)] = v11[c] - v22[c];
        }
    }
    // Zero skew: B12 = 0.
    a[(rows - 1, 1)] = 1.0;
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let (imin, _) = eig.eigenvalues.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    let b = eig.eigenvectors.column(imin);
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let d = b11 * b22 - b12 * b12;
    if d.abs() < 1e-300 || b11.abs() < 1e-300 {
        return None;
    }
    let v0 = (b12 * b13 - b11 * b23) / d;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha2 = lambda / b11;
    let beta2 = lambda * b11 / d;
    if !(alpha2 > 0.0 && beta2 > 0.0) {
        return None;
    }
    let (alpha, beta) = (alpha2.sqrt(), beta2.sqrt());
    let gamma = -b12 * alpha2 * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha2 / lambda;
    let out = [alpha, beta, u0, v0];
    out.iter().all(|x| x.is_finite()).then_some(out)
}

/// Focal lengths with the principal point taken at `centre` (OpenCV's start when Zhang's
/// full closed form fails): least squares of the same constraints with the principal point
/// removed from the homographies.
pub(crate) fn focal_with_centre(homographies: &[Matrix3<f64>], centre: [f64; 2]) -> Option<[f64; 2]> {
    let shift = Matrix3::new(1.0, 0.0, -centre[0], 0.0, 1.0, -centre[1], 0.0, 0.0, 1.0);
    // With K = diag(fx, fy, 1) after the shift, B = diag(1/fx², 1/fy², 1): two unknowns a =
    // 1/fx², b = 1/fy², and h1ᵀBh2 = 0, h1ᵀBh1 − h2ᵀBh2 = 0 are linear in them.
    let mut ata = nalgebra::Matrix2::<f64>::zeros();
    let mut atb = nalgebra::Vector2::<f64>::zeros();
    for h in homographies {
        let h = shift * h;
        let h = h / h.norm();
        let (h1, h2) = (h.column(0), h.column(1));
        let rows = [
            ([h1[0] * h2[0], h1[1] * h2[1]], -h1[2] * h2[2]),
            ([h1[0] * h1[0] - h2[0] * h2[0], h1[1] * h1[1] - h2[1] * h2[1]], -(h1[2] * h1[2] - h2[2] * h2[2])),
        ];
        for (r, rhs) in rows {
            let r = nalgebra::Vector2::new(r[0], r[1]);
            ata += r * r.transpose();
            atb += r * rhs;
        }
    }
    let ab = ata.try_inverse()? * atb;
    (ab[0] > 0.0 && ab[1] > 0.0).then(|| [1.0 / ab[0].sqrt(), 1.0 / ab[1].sqrt()])
}

/// The pose of a view from its homography and a camera matrix (distortion ignored): the
/// first two columns of K⁻¹H are the rotation's first two columns up to one scale; the board
/// is put in front of the camera, and the rotation made orthonormal.
pub(crate) fn pose_from_homography(h: &Matrix3<f64>, k: &Intrinsics) -> Option<Pose> {
    let m = k.matrix().try_inverse()? * h;
    let (c1, c2, c3) = (m.column(0).into_owned(), m.column(1).into_owned(), m.column(2).into_owned());
    let norm = 0.5 * (c1.norm() + c2.norm());
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    let mut s = 1.0 / norm;
    if c3.z * s < 0.0 {
        s = -s;
    }
    let (r1, r2, t) = (c1 * s, c2 * s, c3 * s);
    let r3 = r1.cross(&r2);
    let r = Matrix3::from_columns(&[r1, r2, r3]);
    // Nearest rotation: U Vᵀ of the SVD, with the sign that keeps a proper rotation.
    let svd = r.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut rot = u * vt;
    if rot.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        rot = u2 * vt;
    }
    let pose = Pose { rotation: Rotation3::from_matrix_unchecked(rot), translation: Vector3::new(t.x, t.y, t.z) };
    (t.iter().all(|x| x.is_finite()) && t.z > 0.0).then_some(pose)
}

#[cfg(test)]
mod test {
    use super::*;

    type Seen = (Vec<[f64; 3]>, Vec<[f64; 2]>, Pose);

    fn views(n: usize) -> (Intrinsics, Vec<Seen>) {
        let k = Intrinsics { fx: 355.0, fy: 354.0, cx: 170.0, cy: 129.0, k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 };
        let board: Vec<[f64; 3]> = (0..11)
            .flat_map(|i| (0..4).map(move |j| [i as f64 * 0.024, (2 * j + i % 2) as f64 * 0.024, 0.0]))
            .collect();
        let out = (0..n)
            .map(|v| {
                let a = v as f64;
                let pose = Pose {
                    rotation: Rotation3::from_scaled_axis(Vector3::new(
                        0.4 * (a * 1.3).sin(),
                        0.35 * (a * 0.7).cos(),
                        0.2 * a.sin(),
                    )),
                    translation: Vector3::new(-0.12 + 0.01 * a.cos(), -0.08, 0.45 + 0.05 * (a * 0.9).sin()),
                };
                let img = board
                    .iter()
                    .map(|p| k.project(&(pose.rotation * Vector3::from(*p) + pose.translation)).unwrap())
                    .collect();
                (board.clone(), img, pose)
            })
            .collect();
        (k, out)
    }

    #[test]
    fn zhang_recovers_a_distortion_free_camera() {
        let (k, v) = views(8);
        let hs: Vec<_> = v.iter().map(|(o, i, _)| homography(o, i).unwrap()).collect();
        let [fx, fy, cx, cy] = zhang(&hs).unwrap();
        assert!((fx - k.fx).abs() < 1e-3 && (fy - k.fy).abs() < 1e-3, "{fx} {fy}");
        assert!((cx - k.cx).abs() < 1e-3 && (cy - k.cy).abs() < 1e-3, "{cx} {cy}");
        let [fx, fy] = focal_with_centre(&hs, [k.cx, k.cy]).unwrap();
        assert!((fx - k.fx).abs() < 1e-3 && (fy - k.fy).abs() < 1e-3, "{fx} {fy}");
        for ((_, _, truth), h) in v.iter().zip(&hs) {
            let p = pose_from_homography(h, &k).unwrap();
            assert!((p.translation - truth.translation).norm() < 1e-6);
            assert!((p.rotation.matrix() - truth.rotation.matrix()).norm() < 1e-6);
        }
    }

    #[test]
    fn degenerate_points_give_no_homography() {
        let line: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, 0.0, 0.0]).collect();
        let img: Vec<[f64; 2]> = (0..10).map(|i| [i as f64 * 3.0, 5.0]).collect();
        assert!(homography(&line, &img).is_none());
        assert!(homography(&line[..3], &img[..3]).is_none());
    }
}
