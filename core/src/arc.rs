//! Moments of a cluster's events and the algebraic circle through them: enough to tell, in
//! constant time, whether two clusters lie on one circle.
//!
//! A circle's edge moving by a fraction of a pixel fires mostly where the edge crosses
//! itself: two crescents, one ahead and one behind, with gaps where the edge slides along its
//! own tangent. DBSCAN often keeps the crescents apart, and each alone is a poor arc to fit.
//! [`Moments`] summarises a cluster by the power sums `Σ xᵃ yᵇ` (a + b ≤ 4) of its events;
//! the sums of two clusters, moved to a common origin, add up to those of their union, and
//! Kåsa's algebraic circle fit and its residual follow from them without touching the events
//! again. So every pair of nearby clusters can be tried as one circle at the cost of a 3 x 3
//! solve.
//!
//! Sums are taken about a point of the cluster (its first event), so that `f32` holds them
//! to a few parts in a million over the few tens of pixels a circle spans.

use crate::window::WindowEvent;

/// Exponent pairs `(a, b)` of the power sums, in storage order: total degree 0, 1, 2, 3, 4.
const POWERS: [(u8, u8); 15] = [
    (0, 0),
    (1, 0),
    (0, 1),
    (2, 0),
    (1, 1),
    (0, 2),
    (3, 0),
    (2, 1),
    (1, 2),
    (0, 3),
    (4, 0),
    (3, 1),
    (2, 2),
    (1, 3),
    (0, 4),
];

/// Index of `(a, b)` in [`POWERS`].
const fn at(a: usize, b: usize) -> usize {
    let d = a + b;
    // Degree d starts after 1 + 2 + … + d entries; within it, a falls from d to 0.
    d * (d + 1) / 2 + (d - a)
}

/// Power sums `Σ (x − x₀)ᵃ (y − y₀)ᵇ`, a + b ≤ 4, of a set of events about an origin.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Moments {
    origin: [f32; 2],
    sums: [f32; 15],
}

/// The algebraic circle through a set of events and how far the events lie from it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Circle {
    /// Centre column, pixels.
    pub u: f32,
    /// Centre row, pixels.
    pub v: f32,
    /// Radius, pixels.
    pub r: f32,
    /// RMS distance of the events from the circle, pixels (from the algebraic residual
    /// `(d² − r²) ≈ 2r·(d − r)`, so exact for events near the circle).
    pub rms: f32,
}

impl Moments {
    /// The power sums of `events` about the first event (empty: all zero).
    pub fn of(events: &[WindowEvent]) -> Self {
        let origin = events.first().map_or([0.0; 2], |e| [f32::from(e.x), f32::from(e.y)]);
        let mut sums = [0.0f32; 15];
        for e in events {
            let x = f32::from(e.x) - origin[0];
            let y = f32::from(e.y) - origin[1];
            let (x2, y2, xy) = (x * x, y * y, x * y);
            let terms =
                [1.0, x, y, x2, xy, y2, x2 * x, x2 * y, x * y2, y2 * y, x2 * x2, x2 * xy, x2 * y2, xy * y2, y2 * y2];
            for (s, t) in sums.iter_mut().zip(terms) {
                *s += t;
            }
        }
        Self { origin, sums }
    }

    /// Number of events summed.
    pub fn count(&self) -> f32 {
        self.sums[0]
    }

    /// The same sums about `origin` (binomial expansion of `(x − Δx)ᵃ (y − Δy)ᵇ`).
    fn about(&self, origin: [f32; 2]) -> [f32; 15] {
        // New coordinates: x' = x − dx with dx = origin − self.origin.
        let dx = origin[0] - self.origin[0];
        let dy = origin[1] - self.origin[1];
        let mut px = [1.0f32; 5];
        let mut py = [1.0f32; 5];
        for k in 1..5 {
            px[k] = px[k - 1] * -dx;
            py[k] = py[k - 1] * -dy;
        }
        const BINOMIAL: [[f32; 5]; 5] = [
            [1.0, 0.0, 0.0, 0.0, 0.0],
            [1.0, 1.0, 0.0, 0.0, 0.0],
            [1.0, 2.0, 1.0, 0.0, 0.0],
            [1.0, 3.0, 3.0, 1.0, 0.0],
            [1.0, 4.0, 6.0, 4.0, 1.0],
        ];
        let mut out = [0.0f32; 15];
        for (slot, &(a, b)) in out.iter_mut().zip(POWERS.iter()) {
            let (a, b) = (usize::from(a), usize::from(b));
            let mut s = 0.0f32;
            for i in 0..=a {
                for j in 0..=b {
                    s += BINOMIAL[a][i] * BINOMIAL[b][j] * px[a - i] * py[b - j] * self.sums[at(i, j)];
                }
            }
            *slot = s;
        }
        out
    }

    /// Adds the events of `other`: the sums become those of the union (about `self`'s
    /// origin).
    pub fn add(&mut self, other: &Moments) {
        for (s, o) in self.sums.iter_mut().zip(other.about(self.origin)) {
            *s += o;
        }
    }

    /// Kåsa's circle through the events of `self`, or `None` when they are too few or on a
    /// line.
    pub fn circle(&self) -> Option<Circle> {
        fit_about(&[self.about(self.origin)], self.origin)
    }

    /// Kåsa's circle through the union of the events of `self` and `other`, and the RMS
    /// distance of each set's events from it (`(circle, rms_self, rms_other)`).
    pub fn joint_circle(&self, other: &Moments) -> Option<(Circle, f32, f32)> {
        let origin = [(self.origin[0] + other.origin[0]) * 0.5, (self.origin[1] + other.origin[1]) * 0.5];
        let (a, b) = (self.about(origin), other.about(origin));
        let c = fit_about(&[a, b], origin)?;
        let theta = [-2.0 * (c.u - origin[0]), -2.0 * (c.v - origin[1]), squared_offset(&c, origin) - c.r * c.r];
        Some((c, rms(&a, &theta, c.r), rms(&b, &theta, c.r)))
    }
}

/// `(u − x₀)² + (v − y₀)²`: the circle centre's squared distance from an origin.
fn squared_offset(c: &Circle, origin: [f32; 2]) -> f32 {
    let (du, dv) = (c.u - origin[0], c.v - origin[1]);
    du * du + dv * dv
}

/// Sum of the algebraic residuals `(z + Dx + Ey + F)²`, z = x² + y², from power sums.
fn algebraic_residual(s: &[f32; 15], theta: &[f32; 3]) -> f32 {
    let [d, e, f] = *theta;
    let sz2 = s[at(4, 0)] + 2.0 * s[at(2, 2)] + s[at(0, 4)];
    let sxz = s[at(3, 0)] + s[at(1, 2)];
    let syz = s[at(2, 1)] + s[at(0, 3)];
    let sz = s[at(2, 0)] + s[at(0, 2)];
    let quad = d * d * s[at(2, 0)]
        + e * e * s[at(0, 2)]
        + f * f * s[at(0, 0)]
        + 2.0 * (d * e * s[at(1, 1)] + d * f * s[at(1, 0)] + e * f * s[at(0, 1)]);
    sz2 + 2.0 * (d * sxz + e * syz + f * sz) + quad
}

/// RMS geometric distance from the algebraic residual of one set of sums.
fn rms(s: &[f32; 15], theta: &[f32; 3], r: f32) -> f32 {
    let n = s[0];
    if n <= 0.0 || r <= 0.0 {
        return f32::INFINITY;
    }
    // The residual is a difference of large sums: rounding can take it a little below zero.
    libm::sqrtf(algebraic_residual(s, theta).max(0.0) / n) / (2.0 * r)
}

/// Kåsa's fit to the summed power sums `parts`, all about `origin`.
fn fit_about(parts: &[[f32; 15]], origin: [f32; 2]) -> Option<Circle> {
    let mut s = [0.0f32; 15];
    for p in parts {
        for (a, b) in s.iter_mut().zip(p) {
            *a += b;
        }
    }
    if s[0] < 3.0 {
        return None;
    }
    // Least squares of x² + y² + Dx + Ey + F = 0 over rows (x, y, 1).
    let m = [
        [s[at(2, 0)], s[at(1, 1)], s[at(1, 0)]],
        [s[at(1, 1)], s[at(0, 2)], s[at(0, 1)]],
        [s[at(1, 0)], s[at(0, 1)], s[at(0, 0)]],
    ];
    let rhs = [-(s[at(3, 0)] + s[at(1, 2)]), -(s[at(2, 1)] + s[at(0, 3)]), -(s[at(2, 0)] + s[at(0, 2)])];
    let theta = solve3(m, rhs)?;
    let (u, v) = (-0.5 * theta[0], -0.5 * theta[1]);
    let r2 = u * u + v * v - theta[2];
    if !(r2 > 0.0 && r2.is_finite()) {
        return None;
    }
    let r = libm::sqrtf(r2);
    let rms = rms(&s, &theta, r);
    Some(Circle { u: origin[0] + u, v: origin[1] + v, r, rms })
}

/// Solves a symmetric 3 x 3 system by Cramer's rule; `None` when it is singular to f32
/// precision (events on a line, or all at one pixel).
fn solve3(m: [[f32; 3]; 3], b: [f32; 3]) -> Option<[f32; 3]> {
    let det3 = |m: &[[f32; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det3(&m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if !(d.is_finite() && scale.is_finite()) || d.abs() <= 1e-6 * scale.abs() {
        return None;
    }
    let mut out = [0.0f32; 3];
    for (k, slot) in out.iter_mut().enumerate() {
        let mut mk = m;
        for (row, &bi) in mk.iter_mut().zip(&b) {
            row[k] = bi;
        }
        *slot = det3(&mk) / d;
    }
    out.iter().all(|v| v.is_finite()).then_some(out)
}

#[cfg(test)]
mod test {
    use super::*;
    use std::vec::Vec;

    fn arc(cx: f32, cy: f32, r: f32, from: f32, to: f32, k: usize) -> Vec<WindowEvent> {
        (0..k)
            .map(|i| {
                let a = from + (to - from) * i as f32 / (k - 1) as f32;
                WindowEvent {
                    x: (cx + r * libm::cosf(a)).round() as u16,
                    y: (cy + r * libm::sinf(a)).round() as u16,
                    dt_us: i as u32,
                }
            })
            .collect()
    }

    #[test]
    fn indices_follow_the_storage_order() {
        for (k, &(a, b)) in POWERS.iter().enumerate() {
            assert_eq!(at(usize::from(a), usize::from(b)), k);
        }
    }

    #[test]
    fn circle_of_a_full_ring() {
        let ev = arc(100.0, 80.0, 9.0, 0.0, 6.2, 200);
        let c = Moments::of(&ev).circle().expect("circle");
        assert!((c.u - 100.0).abs() < 0.1 && (c.v - 80.0).abs() < 0.1 && (c.r - 9.0).abs() < 0.1, "{c:?}");
        // Pixel rounding alone: about 0.3 px RMS.
        assert!(c.rms < 0.45, "{c:?}");
    }

    #[test]
    fn shifted_sums_equal_direct_sums() {
        let ev = arc(50.0, 60.0, 7.0, 0.3, 2.5, 40);
        let m = Moments::of(&ev);
        let shifted = m.about([45.0, 66.0]);
        let mut direct = Moments::of(&[]);
        direct.origin = [45.0, 66.0];
        for e in &ev {
            let (x, y) = (f32::from(e.x) - 45.0, f32::from(e.y) - 66.0);
            for (k, &(a, b)) in POWERS.iter().enumerate() {
                direct.sums[k] += libm::powf(x, f32::from(a)) * libm::powf(y, f32::from(b));
            }
        }
        for (k, (s, d)) in shifted.iter().zip(&direct.sums).enumerate() {
            let tol = 1e-4 * d.abs().max(1.0);
            assert!((s - d).abs() <= tol, "{k}: {s} vs {d}");
        }
    }

    #[test]
    fn two_crescents_of_one_circle_join_and_two_circles_do_not() {
        let lead = arc(120.0, 100.0, 8.0, -0.9, 0.9, 30);
        let trail = arc(120.0, 100.0, 8.0, 2.3, 4.0, 30);
        let (c, ra, rb) = Moments::of(&lead).joint_circle(&Moments::of(&trail)).expect("circle");
        assert!((c.u - 120.0).abs() < 0.2 && (c.v - 100.0).abs() < 0.2 && (c.r - 8.0).abs() < 0.2, "{c:?}");
        assert!(ra < 0.5 && rb < 0.5, "{ra} {rb}");
        // A crescent of a neighbouring circle, 20 px away: no circle fits both.
        let other = arc(140.0, 100.0, 8.0, 2.3, 4.0, 30);
        let (_, ra, rb) = Moments::of(&lead).joint_circle(&Moments::of(&other)).expect("circle");
        assert!(ra.max(rb) > 1.5, "{ra} {rb}");
    }

    #[test]
    fn added_sums_are_the_union_sums() {
        let (a, b) = (arc(60.0, 60.0, 6.0, 0.0, 2.0, 25), arc(60.0, 60.0, 6.0, 3.0, 5.0, 25));
        let mut m = Moments::of(&a);
        m.add(&Moments::of(&b));
        let union: Vec<_> = a.iter().chain(&b).copied().collect();
        let (x, y) = (m.circle().unwrap(), Moments::of(&union).circle().unwrap());
        assert!((x.u - y.u).abs() < 1e-3 && (x.v - y.v).abs() < 1e-3 && (x.r - y.r).abs() < 1e-3, "{x:?} {y:?}");
    }

    #[test]
    fn degenerate_sets_give_no_circle() {
        let line: Vec<_> = (0..30).map(|i| WindowEvent { x: 10 + i, y: 40, dt_us: 0 }).collect();
        assert_eq!(Moments::of(&line).circle(), None);
        let point = [WindowEvent { x: 7, y: 7, dt_us: 0 }; 20];
        assert_eq!(Moments::of(&point).circle(), None);
        assert_eq!(Moments::of(&[]).circle(), None);
    }
}
