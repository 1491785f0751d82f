//! The emulator example's `--diagnose`: the same views solved on the true centres, and how
//! the detected centres err against them.

use super::images::*;
use super::*;

/// Solves the views used on the true centres, and says how the detected ones err.
///
/// Per view, the delay that best explains its centres (detected ≈ truth at t_ref − d); the
/// residual left after it, split along and across each circle's motion; and the solve of
/// the same views on the truth plus only one part of that residual, which tells which part
/// moves the intrinsics (plain least squares, so that every point counts alike). Also each
/// view's own shift along the motion, fitted with its delay against the truth, and the solve
/// with each view's shift taken out: how much of the error a shift that changes from view
/// to view (the light, and with it the pixels' latency, changing with the board's tilt)
/// would explain.
pub(super) fn diagnose_run(truth: &Truth, k: &Intrinsics, windows: &[WindowRecord], out: &Outcome, setup: &Setup) {
    let t_of = |seq: u64| windows.iter().find(|w| u64::from(w.seq) == seq).map_or(0.0, |w| w.t_ref_us as f64 * 1e-6);
    let plain = Options { robust: false, circle_radius: Some(truth.pattern.radius_m), ..setup.calib.clone() };
    let mut exact = Vec::new();
    let mut delayed = Vec::new();
    let mut detected = Vec::new();
    // Per point of `delayed`: the unit direction of its circle's motion and its residual.
    let mut motion: Vec<([f64; 2], [f64; 2])> = Vec::new();
    // Per point of `delayed`: its image speed (px/s) and its place from the principal point.
    let mut kin: Vec<[f64; 3]> = Vec::new();
    let mut delays = Vec::new();
    // Per point of `delayed`: how its outline leans against its motion (`outline_slant`).
    let mut slants: Vec<f64> = Vec::new();
    let mut fitted = Vec::new();
    let (mut conic_u, mut conic_plain) = (Vec::new(), Vec::new());
    let mut radial_bins = [[0.0f64; 4]; 8];
    let mut feats: Vec<[f64; 10]> = Vec::new();
    let mut fit_gap: Vec<([f64; 2], [f64; 2], [f64; 2])> = Vec::new();
    let mut view_shifts: Vec<f64> = Vec::new();
    let mut per_view_moved: Vec<View> = Vec::new();
    // Per view, per point of `detected`: the true image acceleration of its outline centre.
    let mut accels: Vec<Vec<[f64; 2]>> = Vec::new();
    for r in &out.calibration.views {
        let v = &out.used[r.view];
        let t = t_of(out.used_origins[r.view].window_seq);
        let outline = |o: &[f64; 3], dt: f64| true_centres(truth, k, o, t - dt).map(|(_, e)| e);
        let cost = |d: f64| -> f64 {
            v.object
                .iter()
                .zip(&v.image)
                .filter_map(|(o, m)| outline(o, d).map(|e| (m[0] - e[0]).powi(2) + (m[1] - e[1]).powi(2)))
                .sum()
        };
        // Golden section over ±60 ms (dim pixels answer tens of milliseconds late).
        let (mut lo, mut hi) = (-0.06, 0.06);
        for _ in 0..60 {
            let (a, b) = (lo + (hi - lo) * 0.382, lo + (hi - lo) * 0.618);
            if cost(a) < cost(b) {
                hi = b
            } else {
                lo = a
            }
        }
        let d = 0.5 * (lo + hi);
        delays.push(d);
        let (mut e0, mut e1, mut e2, mut e3) = (View::default(), View::default(), View::default(), View::default());
        let (mut e4, mut e5) = (View::default(), View::default());
        let mut view_acc = Vec::new();
        for (o, m) in v.object.iter().zip(&v.image) {
            let (Some((c, _)), Some(e), Some(later)) =
                (true_centres(truth, k, o, t), outline(o, d), outline(o, d - 1e-3))
            else {
                continue;
            };
            let (vx, vy) = (later[0] - e[0], later[1] - e[1]);
            let n = vx.hypot(vy).max(1e-12);
            motion.push(([vx / n, vy / n], [m[0] - e[0], m[1] - e[1]]));
            kin.push([n / 1e-3, e[0] - k.cx, e[1] - k.cy]);
            slants.push(outline_slant(truth, k, o, t - d, [vx / n, vy / n]).unwrap_or(0.0));
            let f = fitted_outline_centre(truth, k, o, t - d, [vx / n, vy / n]).unwrap_or(e);
            {
                let (rx, ry) = (e[0] - k.cx, e[1] - k.cy);
                let rho = rx.hypot(ry).max(1e-9);
                let res_r = ((m[0] - e[0]) * rx + (m[1] - e[1]) * ry) / rho;
                let res_t = (-(m[0] - e[0]) * ry + (m[1] - e[1]) * rx) / rho;
                let b = ((rho / 40.0) as usize).min(7);
                radial_bins[b][0] += 1.0;
                radial_bins[b][1] += res_r;
                radial_bins[b][2] += res_t;
                radial_bins[b][3] += res_r * res_r;
            }
            e4.object.push(*o);
            e4.image.push(conic_outline_centre(truth, k, o, t - d, Some([vx / n, vy / n])).unwrap_or(e));
            e5.object.push(*o);
            e5.image.push(conic_outline_centre(truth, k, o, t - d, None).unwrap_or(e));
            if let Some(earlier) = outline(o, d + 1e-3) {
                // Image velocity (px/s) and acceleration (px/s²) of the outline centre.
                let vel = [(later[0] - earlier[0]) / 2e-3, (later[1] - earlier[1]) / 2e-3];
                let acc = [(later[0] - 2.0 * e[0] + earlier[0]) / 1e-6, (later[1] - 2.0 * e[1] + earlier[1]) / 1e-6];
                let (ux, uy) = (vx / n, vy / n);
                let res_c = -(m[0] - e[0]) * uy + (m[1] - e[1]) * ux;
                let res_a = (m[0] - e[0]) * ux + (m[1] - e[1]) * uy;
                let acc_c = -acc[0] * uy + acc[1] * ux;
                let rho_c = -(e[0] - k.cx) * uy + (e[1] - k.cy) * ux;
                let rho_a = (e[0] - k.cx) * ux + (e[1] - k.cy) * uy;
                let sp = vel[0].hypot(vel[1]);
                let rr = ((e[0] - k.cx).powi(2) + (e[1] - k.cy).powi(2)) / 1e4;
                feats.push([
                    res_c,
                    res_a,
                    acc_c,
                    rho_c,
                    rho_a,
                    sp,
                    sp * (e[0] - k.cx) / 100.0,
                    sp * (e[1] - k.cy) / 100.0,
                    sp * rr,
                    // The path's curvature, 1/px, signed as the acceleration across.
                    if sp > 10.0 { acc_c / (sp * sp) } else { 0.0 },
                ]);
            }
            view_acc.push(match outline(o, d + 1e-3) {
                Some(earlier) => {
                    [(later[0] - 2.0 * e[0] + earlier[0]) / 1e-6, (later[1] - 2.0 * e[1] + earlier[1]) / 1e-6]
                }
                None => [0.0, 0.0],
            });
            fit_gap.push(([vx / n, vy / n], [f[0] - e[0], f[1] - e[1]], [m[0] - e[0], m[1] - e[1]]));
            e3.object.push(*o);
            e3.image.push(f);
            for (view, p) in [(&mut e0, c), (&mut e1, e), (&mut e2, *m)] {
                view.object.push(*o);
                view.image.push(p);
            }
        }
        {
            // A shift along the motion of this view's own, fitted with its delay (least
            // squares of the residual on the unit direction and on the velocity): what a
            // constant edge shift cannot take out when the light, and with it the pixels'
            // latency, changes from view to view.
            let (mut aa, mut ab, mut bb, mut ra, mut rb) = (0.0, 0.0, 0.0, 0.0, 0.0);
            let mut units = Vec::new();
            // e1 (truth at the delay) and e2 (detected) hold the same points, in order.
            for ((o, e), m) in e1.object.iter().zip(&e1.image).zip(&e2.image) {
                let Some(later) = outline(o, d - 1e-3) else {
                    units.push([0.0, 0.0]);
                    continue;
                };
                let vel = [later[0] - e[0], later[1] - e[1]];
                let n = vel[0].hypot(vel[1]).max(1e-12);
                let u = [vel[0] / n, vel[1] / n];
                units.push(u);
                let r = [m[0] - e[0], m[1] - e[1]];
                aa += 1.0;
                ab += u[0] * vel[0] + u[1] * vel[1];
                bb += vel[0] * vel[0] + vel[1] * vel[1];
                ra += r[0] * u[0] + r[1] * u[1];
                rb += r[0] * vel[0] + r[1] * vel[1];
            }
            let det = aa * bb - ab * ab;
            let a = if det.abs() > 1e-12 { (ra * bb - rb * ab) / det } else { 0.0 };
            view_shifts.push(a);
            let mut moved = e2.clone();
            for (p, u) in moved.image.iter_mut().zip(&units) {
                p[0] -= a * u[0];
                p[1] -= a * u[1];
            }
            per_view_moved.push(moved);
        }
        accels.push(view_acc);
        exact.push(e0);
        fitted.push(e3);
        conic_u.push(e4);
        conic_plain.push(e5);
        delayed.push(e1);
        detected.push(e2);
    }
    let solve = |vs: &[View], opts: &Options| calibrate(vs, setup.image_size, opts).map(|c| errors(&c.intrinsics, k));
    let show = |name: &str, vs: &[View], opts: &Options| match solve(vs, opts) {
        Ok(e) => println!("    {name}: fx {:+.3} %, fy {:+.3} %, cx {:+.2}, cy {:+.2} px", e[0], e[1], e[2], e[3]),
        Err(e) => println!("    {name}: {e}"),
    };
    let centre_only = Options { circle_radius: None, ..plain.clone() };
    show("true projections of the circles' centres, solved as centres", &exact, &centre_only);
    show("true outline centres at each view's best delay, solved as centres", &delayed, &centre_only);
    show("true outline centres at each view's best delay, outlines modelled", &delayed, &plain);
    show("detected, outlines modelled", &detected, &plain);
    // Whether fewer unknowns would hold the error: a focal length traded against the
    // distortion or the principal point moves with them.
    show("detected, k3 = 0, p = 0", &detected, &Options { fix_k3: true, zero_tangential: true, ..plain.clone() });
    show(
        "detected, principal point fixed at the truth",
        &detected,
        &Options { fix_principal_point: true, start: Some(*k), ..plain.clone() },
    );
    show(
        "detected, k3 = 0, p = 0, principal point fixed",
        &detected,
        &Options { fix_k3: true, zero_tangential: true, fix_principal_point: true, start: Some(*k), ..plain.clone() },
    );
    for (i, b) in radial_bins.iter().enumerate() {
        if b[0] > 0.0 {
            let n = b[0];
            println!(
                "    image radius {:3}-{:3} px: {:5} points, residual radial {:+.4} px (± {:.4}), tangential {:+.4}",
                40 * i,
                40 * i + 40,
                n,
                b[1] / n,
                ((b[3] / n - (b[1] / n).powi(2)).max(0.0) / n).sqrt(),
                b[2] / n
            );
        }
    }
    show("true outline, conic-fitted (weights |motion · normal|), outlines modelled", &conic_u, &plain);
    show("true outline, conic-fitted (uniform weights), outlines modelled", &conic_plain, &plain);
    {
        // Least squares: residual = a + b·x + c·y over the features.
        let ls = |yi: usize, xs: &[usize]| {
            let m = xs.len() + 1;
            let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
            let mut b = nalgebra::DVector::<f64>::zeros(m);
            for f in &feats {
                let mut row = vec![1.0];
                row.extend(xs.iter().map(|&i| f[i]));
                for i in 0..m {
                    b[i] += row[i] * f[yi];
                    for j in 0..m {
                        a[(i, j)] += row[i] * row[j];
                    }
                }
            }
            a.lu().solve(&b).map(|s| s.iter().copied().collect::<Vec<_>>()).unwrap_or_default()
        };
        let speeds: Vec<f64> = feats.iter().map(|f| f[5]).collect();
        let mut sp = speeds.clone();
        sp.sort_by(f64::total_cmp);
        println!("    speed px/s: median {:.1}, 90 % {:.1}", sp[sp.len() / 2], sp[sp.len() * 9 / 10]);
        // A centre error that grows with the distance from the principal point reads as a
        // focal-length error; one that grows with the image speed, as a delay that differs
        // between circles; one with the acceleration across the motion, as the curvature of
        // the path within a window.
        let g = ls(1, &[5, 6, 7, 8]);
        if let [g0, g1, g2, g3, g4] = g.as_slice() {
            println!(
                "    along residual = {g0:+.4} px + speed · ({:+.2} ms {:+.2} ms/100 px · x {:+.2} ms/100 px · y {:+.2} ms/(100 px)² · ρ²)",
                1e3 * g1, 1e3 * g2, 1e3 * g3, 1e3 * g4
            );
            // A delay that differs over the sensor would move the principal point: its parts
            // taken out of the detected centres.
            for (name, cx_, cy_, r2) in [("x", *g2, 0.0, 0.0), ("y", 0.0, *g3, 0.0), ("x, y, ρ²", *g2, *g3, *g4)] {
                let mut moved = detected.clone();
                let mut j = 0;
                for v in moved.iter_mut() {
                    for p in v.image.iter_mut() {
                        let (u, _) = motion[j];
                        let [sp, x, y] = kin[j];
                        j += 1;
                        let a = sp * (cx_ * x / 100.0 + cy_ * y / 100.0 + r2 * (x * x + y * y) / 1e4);
                        *p = [p[0] - a * u[0], p[1] - a * u[1]];
                    }
                }
                show(&format!("detected less the delay's part in {name} (fitted against the truth)"), &moved, &plain);
            }
        }
        if let [k0, k1] = ls(0, &[9]).as_slice() {
            let ks: Vec<f64> = feats.iter().map(|f| f[9].abs()).collect();
            let mut ks2 = ks.clone();
            ks2.sort_by(f64::total_cmp);
            println!(
                "    across residual = {k0:+.4} px {k1:+.4} px² · curvature (median |curvature| {:.4}/px, 90 % {:.4}/px)",
                ks2[ks2.len() / 2],
                ks2[ks2.len() * 9 / 10]
            );
        }
        let (a, b) = (ls(0, &[2, 3]), ls(1, &[4, 5]));
        if let ([a0, a1, a2], [b0, b1, b2]) = (a.as_slice(), b.as_slice()) {
            println!(
                "    across residual = {a0:+.4} px {:+.2e} s² · acceleration across {:+.5} · distance from (cx, cy) across",
                a1, a2
            );
            println!(
                "    along residual = {b0:+.4} px {:+.5} · distance from (cx, cy) along {:+.2} ms · speed",
                b1,
                1e3 * b2
            );
        }
    }
    for c in [2e-6, 5e-6, 1e-5, 2e-5] {
        // A window's centre leans toward its path's centre of curvature by acceleration ×
        // (the window's time spread)²: taken out with the true acceleration.
        let moved: Vec<View> = detected
            .iter()
            .zip(&accels)
            .map(|(v, acc)| View {
                object: v.object.clone(),
                image: v.image.iter().zip(acc).map(|(p, a)| [p[0] - c * a[0], p[1] - c * a[1]]).collect(),
            })
            .collect();
        show(&format!("detected less {c:.0e} s² · true acceleration"), &moved, &plain);
    }
    {
        // Does the imaged grid shrink or swell? Each residual's component away from its
        // view's grid centroid, by how crowded the circle is (its nearest neighbour's image
        // distance) and whether it is on the grid's rim (fewer than 4 neighbours within 1.6
        // nearest-neighbour distances): neighbouring circles' events in a fit's tails would
        // pull rim circles inward, more as the board recedes.
        // (outward residual, 1 / gap, on the rim, outward unit vector)
        type Row = (f64, f64, bool, [f64; 2]);
        let mut rows: Vec<Row> = Vec::new();
        for (t, m) in delayed.iter().zip(&detected) {
            let n = t.image.len();
            if n < 6 {
                continue;
            }
            let c = t.image.iter().fold([0.0, 0.0], |a, p| [a[0] + p[0] / n as f64, a[1] + p[1] / n as f64]);
            let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
            for i in 0..n {
                let p = t.image[i];
                let mut ds: Vec<f64> = (0..n).filter(|&j| j != i).map(|j| dist(p, t.image[j])).collect();
                ds.sort_by(f64::total_cmp);
                let nn = ds[0];
                let rim = ds.iter().filter(|&&d| d < 1.6 * nn).count() < 4;
                let o = [p[0] - c[0], p[1] - c[1]];
                let on = o[0].hypot(o[1]).max(1e-9);
                let u = [o[0] / on, o[1] / on];
                let r = [m.image[i][0] - p[0], m.image[i][1] - p[1]];
                rows.push((r[0] * u[0] + r[1] * u[1], 1.0 / nn, rim, u));
            }
        }
        let mean = |f: &dyn Fn(&Row) -> bool| {
            let v: Vec<f64> = rows.iter().filter(|r| f(r)).map(|r| r.0).collect();
            (v.iter().sum::<f64>() / v.len().max(1) as f64, v.len())
        };
        let (rim_m, rim_n) = mean(&|r| r.2);
        let (in_m, in_n) = mean(&|r| !r.2);
        // outward = a + b / gap, least squares
        let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
        for r in &rows {
            sx += r.1;
            sy += r.0;
            sxx += r.1 * r.1;
            sxy += r.1 * r.0;
        }
        let nr = rows.len().max(1) as f64;
        let b = (sxy - sx * sy / nr) / (sxx - sx * sx / nr).max(1e-18);
        let a = (sy - b * sx) / nr;
        println!(
            "    residual away from the grid's centroid: rim circles {rim_m:+.4} px ({rim_n}), inner {in_m:+.4} px ({in_n}); = {a:+.4} px {b:+.3} px² / gap"
        );
        let mut k = 0;
        let moved: Vec<View> = detected
            .iter()
            .zip(&delayed)
            .map(|(m, t)| {
                if t.image.len() < 6 {
                    return m.clone();
                }
                let image = m
                    .image
                    .iter()
                    .map(|p| {
                        let (res, _, _, u) = rows[k];
                        k += 1;
                        [p[0] - res * u[0], p[1] - res * u[1]]
                    })
                    .collect();
                View { object: m.object.clone(), image }
            })
            .collect();
        show("detected less each residual's component away from the grid's centroid", &moved, &plain);
    }
    show("outline circle-fitted across the motion at the best delay, outlines modelled", &fitted, &plain);
    {
        let mut sorted = view_shifts.clone();
        sorted.sort_by(f64::total_cmp);
        let q = |f: f64| sorted[((sorted.len() - 1) as f64 * f) as usize];
        println!(
            "    per-view shift along the motion (with the view's delay): median {:+.3}, 10 % {:+.3}, 90 % {:+.3} px",
            q(0.5),
            q(0.1),
            q(0.9)
        );
        show("detected less each view's own shift (fitted against the truth)", &per_view_moved, &plain);
    }
    {
        // How the fitted-minus-centroid gap compares with the detected residual, across the motion.
        let (mut sg, mut sr, mut sgg, mut sgr, mut srr) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for ([ux, uy], g, r) in &fit_gap {
            let gc = -g[0] * uy + g[1] * ux;
            let rc = -r[0] * uy + r[1] * ux;
            sg += gc;
            sr += rc;
            sgg += gc * gc;
            sgr += gc * rc;
            srr += rc * rc;
        }
        let n = fit_gap.len().max(1) as f64;
        let (mg, mr) = (sg / n, sr / n);
        let cov = sgr / n - mg * mr;
        let (vg, vr) = (sgg / n - mg * mg, srr / n - mr * mr);
        println!("    fit gap across the motion: RMS {:.4} px; detected residual across: slope on the gap {:.2}, correlation {:.2}",
            (sgg / n).sqrt(), cov / vg.max(1e-18), cov / (vg * vr).sqrt().max(1e-18));
    }
    // How much of the error is the noise of weakly fixed parameters: the halves of the
    // recording solved apart (on a spiral the two differ by far more than the whole errs).
    let half = detected.len() / 2;
    show("  first half of the views alone", &detected[..half], &plain);
    show("  second half of the views alone", &detected[half..], &plain);
    delays.sort_by(f64::total_cmp);
    let q = |f: f64| 1e3 * delays[((delays.len() - 1) as f64 * f) as usize];
    println!("    best delay per view: median {:.2} ms (10 % {:.2}, 90 % {:.2})", q(0.5), q(0.1), q(0.9));
    // The residual after each view's delay, along and across the motion, alone on the truth.
    let (mut along, mut across) = (delayed.clone(), delayed.clone());
    let mut sums = [0.0; 4];
    let mut j = 0;
    for (va, vc) in along.iter_mut().zip(across.iter_mut()) {
        for (pa, pc) in va.image.iter_mut().zip(vc.image.iter_mut()) {
            let ([ux, uy], [rx, ry]) = motion[j];
            j += 1;
            let a = rx * ux + ry * uy;
            let c = -rx * uy + ry * ux;
            sums = [sums[0] + a, sums[1] + a * a, sums[2] + c, sums[3] + c * c];
            *pa = [pa[0] + a * ux, pa[1] + a * uy];
            *pc = [pc[0] - c * uy, pc[1] + c * ux];
        }
    }
    let n = j.max(1) as f64;
    println!(
        "    residual after the delay: along the motion mean {:+.4}, RMS {:.3} px; across mean {:+.4}, RMS {:.3} px ({j} points)",
        sums[0] / n,
        (sums[1] / n).sqrt(),
        sums[2] / n,
        (sums[3] / n).sqrt()
    );
    {
        // What the views allow at the centres' own noise: the truth at each view's delay plus
        // independent noise as large as the detected residual (along and across the motion
        // apart), solved over 16 draws. Real errors are not independent (they persist over
        // neighbouring windows), so this spread is the least a centre this noisy can give.
        use rand::{RngExt, SeedableRng};
        let (sd_along, sd_across) = ((sums[1] / n).sqrt(), (sums[3] / n).sqrt());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
        let mut gauss = || {
            let (a, b) = (rng.random::<f64>().max(1e-300), rng.random::<f64>());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let mut draws = Vec::new();
        for _ in 0..16 {
            let mut noisy = delayed.clone();
            let mut j = 0;
            for v in noisy.iter_mut() {
                for p in v.image.iter_mut() {
                    let ([ux, uy], _) = motion[j];
                    j += 1;
                    let (a, c) = (sd_along * gauss(), sd_across * gauss());
                    *p = [p[0] + a * ux - c * uy, p[1] + a * uy + c * ux];
                }
            }
            if let Ok(e) = solve(&noisy, &plain) {
                draws.push(e);
            }
        }
        let m = draws.len().max(1) as f64;
        let stat = |i: usize| {
            let mean = draws.iter().map(|e| e[i]).sum::<f64>() / m;
            let sd = (draws.iter().map(|e| (e[i] - mean).powi(2)).sum::<f64>() / (m - 1.0).max(1.0)).sqrt();
            (mean, sd)
        };
        let ((fx_mean, fx_sd), (cx_mean, cx_sd)) = (stat(0), stat(2));
        println!(
            "    truth at the delay plus independent noise of the residual's size ({sd_along:.3} px along, {sd_across:.3} across), {} draws: fx {fx_mean:+.3} ± {fx_sd:.3} %, cx {cx_mean:+.2} ± {cx_sd:.2} px",
            draws.len()
        );
    }
    {
        // Only the mean of the across-motion residual: a constant shift to one side of the
        // motion, as a curved path or a lag that is not symmetric about the motion would give.
        let mean_c = sums[2] / n;
        let mut shifted = delayed.clone();
        let mut j = 0;
        for v in shifted.iter_mut() {
            for p in v.image.iter_mut() {
                let ([ux, uy], _) = motion[j];
                j += 1;
                *p = [p[0] - mean_c * uy, p[1] + mean_c * ux];
            }
        }
        show(&format!("truth at the delay plus a constant {mean_c:+.4} px across the motion"), &shifted, &plain);
    }
    {
        // Does the error across the motion depend on the motion's direction on the pixel
        // grid (the sensor's rows and columns sample a ring's sides unevenly)? Least
        // squares of it on the direction's harmonics, and the solve with that part taken out.
        let harm = |u: [f64; 2]| {
            let th = u[1].atan2(u[0]);
            [(2.0 * th).cos(), (2.0 * th).sin(), (4.0 * th).cos(), (4.0 * th).sin()]
        };
        let mut a = nalgebra::SMatrix::<f64, 5, 5>::zeros();
        let mut b = nalgebra::SVector::<f64, 5>::zeros();
        for (u, r) in &motion {
            let h = harm(*u);
            let row = nalgebra::SVector::<f64, 5>::from([1.0, h[0], h[1], h[2], h[3]]);
            let c = -r[0] * u[1] + r[1] * u[0];
            a += row * row.transpose();
            b += row * c;
        }
        if let Some(x) = a.lu().solve(&b) {
            println!(
                "    across residual = {:+.4} px {:+.4} cos 2θ {:+.4} sin 2θ {:+.4} cos 4θ {:+.4} sin 4θ (θ: the motion's direction on the sensor)",
                x[0], x[1], x[2], x[3], x[4]
            );
            let mut moved = detected.clone();
            let mut j = 0;
            for v in moved.iter_mut() {
                for p in v.image.iter_mut() {
                    let (u, _) = motion[j];
                    j += 1;
                    let h = harm(u);
                    let f = x[1] * h[0] + x[2] * h[1] + x[3] * h[2] + x[4] * h[3];
                    *p = [p[0] + f * u[1], p[1] - f * u[0]];
                }
            }
            show("detected less the across-motion part that follows the direction", &moved, &plain);
        }
    }
    {
        // A slanted outline's events are not symmetric about its motion: wherever they sit
        // relative to the edge, the fit's centre can move across the motion in proportion to
        // the slant. Least squares of the residual across on it, and the solve without it.
        let (mut sf, mut sc, mut sff, mut sfc, mut scc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (f, (u, r)) in slants.iter().zip(&motion) {
            let c = -r[0] * u[1] + r[1] * u[0];
            (sf, sc, sff, sfc, scc) = (sf + f, sc + c, sff + f * f, sfc + f * c, scc + c * c);
        }
        let n = slants.len().max(3) as f64;
        let (vf, vc, cov) = (sff / n - (sf / n).powi(2), scc / n - (sc / n).powi(2), sfc / n - sf * sc / (n * n));
        let (slope, corr) = (cov / vf.max(1e-18), cov / (vf * vc).sqrt().max(1e-18));
        println!(
            "    across residual = {:+.4} px · ε sin 2(θ − φ) (the outline's slant to the motion; RMS {:.4}; correlation {:+.3}, t {:+.1})",
            slope,
            (sff / n).sqrt(),
            corr,
            corr * (n - 2.0).sqrt() / (1.0 - corr * corr).max(1e-12).sqrt()
        );
        let mut moved = detected.clone();
        let mut j = 0;
        for v in moved.iter_mut() {
            for p in v.image.iter_mut() {
                let (u, _) = motion[j];
                let g = slope * slants[j];
                j += 1;
                *p = [p[0] + g * u[1], p[1] - g * u[0]];
            }
        }
        show("detected less the across part that follows the outline's slant", &moved, &plain);
    }
    show("truth at the delay plus the residual along the motion only", &along, &plain);
    show("truth at the delay plus the residual across the motion only", &across, &plain);
    {
        // Where the across-motion error's focal-length error comes from: the truth plus the
        // across part of one grid position's (or one stretch of time's) residuals only.
        let base = solve(&delayed, &plain).map(|e| e[0]).unwrap_or(0.0);
        let mut keys: Vec<[i64; 2]> = Vec::new();
        for v in &delayed {
            for o in &v.object {
                let key = [(o[0] * 1e4).round() as i64, (o[1] * 1e4).round() as i64];
                if !keys.contains(&key) {
                    keys.push(key);
                }
            }
        }
        keys.sort();
        // Each part's fx (%) beside the truth alone's, and their sum (the whole, when the
        // solve is linear in so small an error).
        let split = |what: &str, parts: Vec<Vec<View>>| {
            let fx: Vec<f64> = parts.iter().map(|m| solve(m, &plain).map_or(f64::NAN, |e| e[0] - base)).collect();
            let list: Vec<String> = fx.iter().map(|e| format!("{e:+.3}")).collect();
            println!(
                "      fx (%) from the across part of {what} alone: {}; sum {:+.3} %",
                list.join(" "),
                fx.iter().sum::<f64>()
            );
        };
        let by_circle = keys
            .iter()
            .map(|key| {
                let mut moved = delayed.clone();
                for (vd, va) in moved.iter_mut().zip(&across) {
                    for ((p, o), q) in vd.image.iter_mut().zip(&vd.object).zip(&va.image) {
                        if [(o[0] * 1e4).round() as i64, (o[1] * 1e4).round() as i64] == *key {
                            *p = *q;
                        }
                    }
                }
                moved
            })
            .collect();
        split("each circle (in index order)", by_circle);
        let (nv, groups) = (delayed.len(), 12);
        let by_time = (0..groups)
            .map(|g| {
                let (a, b) = (g * nv / groups, (g + 1) * nv / groups);
                let mut moved = delayed.clone();
                moved[a..b].clone_from_slice(&across[a..b]);
                moved
            })
            .collect();
        split("each twelfth of the views", by_time);
    }
}
