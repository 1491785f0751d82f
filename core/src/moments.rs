//! Moments of a cluster's events and the algebraic moving circle through them: enough to
//! tell, in constant time, whether two clusters lie on one circle.
//!
//! A circle's edge moving by a fraction of a pixel fires mostly where the edge crosses
//! itself: two crescents, one ahead and one behind, with gaps where the edge slides along its
//! own tangent. DBSCAN often keeps the crescents apart, and each alone is a poor arc to fit.
//! [`Moments`] summarises a cluster by the power sums `Σ xᵃ yᵇ τᶜ` of its events (τ the time
//! from the window's reference, a + b ≤ 4 − 2c… see `POWERS` in the source); the sums of two clusters,
//! moved to a common origin, add up to those of their union, and Kåsa's algebraic fit of a
//! moving circle, `x² + y² + Dx + Ey + Gτx + Hτy + F + Iτ = 0`, and its residual follow from
//! them without touching the events again. So every pair of nearby clusters can be tried as
//! one circle at the cost of a 6 x 6 solve, and the fit of a joined cluster starts from the
//! circle of its sums.
//!
//! Sums are taken about a point of the cluster (its first event), so that `f32` holds them
//! to a few parts in a million over the few tens of pixels a circle spans.

use crate::{
    extent::Extent,
    math::{max, sqrt_exact},
    window::WindowEvent,
};

/// Exponents `(a, b, c)` of the power sums `Σ xᵃ yᵇ τᶜ`, in storage order: the products the
/// moving-circle fit needs (its rows `x, y, τx, τy, 1, τ` with one another and with
/// `z = x² + y²`, and `z²`).
const POWERS: [(u8, u8, u8); 31] = [
    (0, 0, 0),
    (1, 0, 0),
    (0, 1, 0),
    (2, 0, 0),
    (1, 1, 0),
    (0, 2, 0),
    (3, 0, 0),
    (2, 1, 0),
    (1, 2, 0),
    (0, 3, 0),
    (4, 0, 0),
    (3, 1, 0),
    (2, 2, 0),
    (1, 3, 0),
    (0, 4, 0),
    (0, 0, 1),
    (1, 0, 1),
    (0, 1, 1),
    (2, 0, 1),
    (1, 1, 1),
    (0, 2, 1),
    (3, 0, 1),
    (2, 1, 1),
    (1, 2, 1),
    (0, 3, 1),
    (0, 0, 2),
    (1, 0, 2),
    (0, 1, 2),
    (2, 0, 2),
    (1, 1, 2),
    (0, 2, 2),
];

/// Index of `(a, b, c)` in [`POWERS`] (`a + b ≤ 4 − c` for c ≤ 1, `≤ 2` for c = 2).
const fn at(a: usize, b: usize, c: usize) -> usize {
    let d = a + b;
    // Within one power of τ, degree d starts after 1 + 2 + … + d entries; a falls from d to 0.
    let base = match c {
        0 => 0,
        1 => 15,
        _ => 25,
    };
    base + d * (d + 1) / 2 + (d - a)
}

/// Power sums `Σ (x − x₀)ᵃ (y − y₀)ᵇ τᶜ` of a set of events about a pixel origin, τ in
/// milliseconds from a time origin.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Moments {
    origin: [f32; 2],
    sums: [f32; 31],
}

/// The algebraic moving circle through a set of events and how far the events lie from it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Circle {
    /// Centre column at the time origin, pixels.
    pub u: f32,
    /// Centre row at the time origin, pixels.
    pub v: f32,
    /// Centre velocity along x, pixels per millisecond.
    pub vu: f32,
    /// Centre velocity along y, pixels per millisecond.
    pub vv: f32,
    /// Radius, pixels.
    pub r: f32,
    /// RMS distance of the events from the circle, pixels (from the algebraic residual
    /// `(d² − r²) ≈ 2r·(d − r)`, so close for events near the circle).
    pub rms: f32,
}

/// One term of [`Moments::about`]'s binomial expansion: `out[slot] += binomial · (−Δx)^px ·
/// (−Δy)^py · sums[src]`.
#[derive(Clone, Copy)]
struct ShiftTerm {
    slot: u8,
    binomial: u8,
    px: u8,
    py: u8,
    src: u8,
}

/// Terms of `(x − Δx)ᵃ (y − Δy)ᵇ = Σᵢⱼ C(a,i) C(b,j) xⁱ yʲ (−Δx)ᵃ⁻ⁱ (−Δy)ᵇ⁻ʲ` for every power
/// sum, slot by slot and within a slot by i, then j: listed once at compile time, so that the
/// shift is a flat loop (the product of the two binomials is exact in `f32`).
const SHIFT_TERMS: [ShiftTerm; 120] = shift_terms();

const fn shift_terms() -> [ShiftTerm; 120] {
    const fn binomial(n: usize, k: usize) -> usize {
        let mut r = 1;
        let mut i = 0;
        while i < k {
            r = r * (n - i) / (i + 1);
            i += 1;
        }
        r
    }
    let mut out = [ShiftTerm { slot: 0, binomial: 0, px: 0, py: 0, src: 0 }; 120];
    let mut n = 0;
    let mut slot = 0;
    while slot < POWERS.len() {
        let (a, b, c) = (POWERS[slot].0 as usize, POWERS[slot].1 as usize, POWERS[slot].2 as usize);
        let mut i = 0;
        while i <= a {
            let mut j = 0;
            while j <= b {
                out[n] = ShiftTerm {
                    slot: slot as u8,
                    binomial: (binomial(a, i) * binomial(b, j)) as u8,
                    px: (a - i) as u8,
                    py: (b - j) as u8,
                    src: at(i, j, c) as u8,
                };
                n += 1;
                j += 1;
            }
            i += 1;
        }
        slot += 1;
    }
    assert!(n == 120, "every term listed");
    out
}

/// The rows of the moving-circle fit as exponents: `x, y, τx, τy, 1, τ`.
const ROWS: [(usize, usize, usize); 6] = [(1, 0, 0), (0, 1, 0), (1, 0, 1), (0, 1, 1), (0, 0, 0), (0, 0, 1)];

impl Moments {
    /// The power sums of `events` about the first event, with τ in milliseconds since
    /// `t0_us` (the same clock as the events' `dt_us`). Empty: all zero.
    pub fn of(events: &[WindowEvent], t0_us: u32) -> Self {
        let mut unused = Extent::EMPTY;
        Self::sums::<false>(events, t0_us, &mut unused)
    }

    /// [`of`](Self::of), the same bits, and the events' [`Extent`]: its integer bounds and
    /// sums ride in the core registers of the loops, whose sums are all in the FPU's (8000-event
    /// windows on the M4F: a pass of its own cost 0.195 M instructions a window, riding here
    /// 0.02 M less in all; inlined into the detector, it spilled and cost 0.02 M more).
    #[inline(never)]
    pub(crate) fn of_with_extent(events: &[WindowEvent], t0_us: u32) -> (Self, Extent) {
        let mut x = Extent::EMPTY;
        let m = Self::sums::<true>(events, t0_us, &mut x);
        x.count(events.len());
        (m, x)
    }

    #[inline(always)]
    fn sums<const EXTENT: bool>(events: &[WindowEvent], t0_us: u32, extent: &mut Extent) -> Self {
        let origin = events.first().map_or([0.0; 2], |e| [f32::from(e.x), f32::from(e.y)]);
        let mut sums = [0.0f32; 31];
        // Two loops over the events, each sum added in event order as in one: 31 sums and
        // the terms do not fit the M4F's 32 float registers together, and spilling them cost
        // more than reading the events twice.
        // The count is exact in `f32` (fewer than 2²⁴ events), as the sum of ones was, and
        // the bounds are kept as words, not halfwords (the M4F narrowed them at every event).
        let mut space_sums = [0.0f32; 15];
        let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (u32::MAX, 0u32, u32::MAX, 0u32);
        for e in events {
            if EXTENT {
                let (ex, ey) = (u32::from(e.x), u32::from(e.y));
                x_lo = x_lo.min(ex);
                x_hi = x_hi.max(ex);
                y_lo = y_lo.min(ey);
                y_hi = y_hi.max(ey);
            }
            let x = f32::from(e.x) - origin[0];
            let y = f32::from(e.y) - origin[1];
            let (x2, y2, xy) = (x * x, y * y, x * y);
            let space = [x, y, x2, xy, y2, x2 * x, x2 * y, x * y2, y2 * y, x2 * x2, x2 * xy, x2 * y2, xy * y2, y2 * y2];
            for (s, p) in space_sums[1..].iter_mut().zip(space) {
                *s += p;
            }
        }
        space_sums[0] = events.len() as f32;
        if EXTENT && !events.is_empty() {
            extent.add_pixel(x_lo as u16, y_lo as u16);
            extent.add_pixel(x_hi as u16, y_hi as u16);
        }
        let mut time_sums = [0.0f32; 16];
        for e in events {
            if EXTENT {
                extent.add_time(e.dt_us);
            }
            let x = f32::from(e.x) - origin[0];
            let y = f32::from(e.y) - origin[1];
            let t = (e.dt_us as f32 - t0_us as f32) * 1e-3;
            let (x2, y2, xy) = (x * x, y * y, x * y);
            let space = [1.0, x, y, x2, xy, y2, x2 * x, x2 * y, x * y2, y2 * y];
            for (s, p) in time_sums[..10].iter_mut().zip(space) {
                *s += p * t;
            }
            let tt = t * t;
            for (s, p) in time_sums[10..].iter_mut().zip(&space[..6]) {
                *s += p * tt;
            }
        }
        sums[..15].copy_from_slice(&space_sums);
        sums[15..].copy_from_slice(&time_sums);
        Self { origin, sums }
    }

    /// Number of events summed.
    pub fn count(&self) -> f32 {
        self.sums[0]
    }

    /// Adds the events of `other`: the sums become those of the union (about `self`'s
    /// origin).
    pub fn add(&mut self, other: &Moments) {
        for (s, o) in self.sums.iter_mut().zip(other.about(self.origin)) {
            *s += o;
        }
    }

    /// The same sums about `origin` (binomial expansion of `(x − Δx)ᵃ (y − Δy)ᵇ`; τ stays).
    fn about(&self, origin: [f32; 2]) -> [f32; 31] {
        let dx = origin[0] - self.origin[0];
        let dy = origin[1] - self.origin[1];
        if dx == 0.0 && dy == 0.0 {
            return self.sums;
        }
        let mut px = [1.0f32; 5];
        let mut py = [1.0f32; 5];
        for k in 1..5 {
            px[k] = px[k - 1] * -dx;
            py[k] = py[k - 1] * -dy;
        }
        let mut out = [0.0f32; 31];
        // Written out term by term: with the table's indices and binomials constant, each
        // term is a multiply-add or two on registers (the multiplications by 1 fold away,
        // exactly), where a loop over the table loaded, bounds-checked and converted them
        // (some 30 instructions a term, 120 terms, for every pair of clusters tried).
        macro_rules! terms {
            ($($k:literal)*) => {$({
                const T: ShiftTerm = SHIFT_TERMS[$k];
                out[T.slot as usize] +=
                    T.binomial as f32 * px[T.px as usize] * py[T.py as usize] * self.sums[T.src as usize];
            })*};
        }
        terms!(
            0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29
            30 31 32 33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59
            60 61 62 63 64 65 66 67 68 69 70 71 72 73 74 75 76 77 78 79 80 81 82 83 84 85 86 87 88 89
            90 91 92 93 94 95 96 97 98 99 100 101 102 103 104 105 106 107 108 109 110 111 112 113 114 115 116 117 118 119
        );
        out
    }

    /// Kåsa's moving circle through the events of `self`, or `None` when they are too few or
    /// on a line.
    pub fn circle(&self) -> Option<Circle> {
        fit_about(&[self.sums], self.origin, true).map(|(c, _)| c)
    }

    /// Kåsa's moving circle through the union of the events of `self` and `other`, and the RMS
    /// distance of each set's events from it (`(circle, rms_self, rms_other)`).
    pub fn joint_circle(&self, other: &Moments) -> Option<(Circle, f32, f32)> {
        // About `self`'s origin: the union spans a few tens of pixels from it.
        let (a, b) = (self.sums, other.about(self.origin));
        let (c, theta) = fit_about(&[a, b], self.origin, true)?;
        Some((c, rms(&a, &theta, c.r), rms(&b, &theta, c.r)))
    }

    /// [`joint_circle`](Self::joint_circle)'s radius and the RMS distances of each set, the
    /// same bits, without the union's own RMS distance, which the test of whether two sets
    /// lie on one circle does not use (a fifth of its work).
    pub(crate) fn joint_radius(&self, other: &Moments) -> Option<(f32, f32, f32)> {
        let (a, b) = (self.sums, other.about(self.origin));
        let (c, theta) = fit_about(&[a, b], self.origin, false)?;
        Some((c.r, rms(&a, &theta, c.r), rms(&b, &theta, c.r)))
    }
}

/// Sum of the algebraic residuals `(z + θ·row)²`, z = x² + y², from power sums.
fn algebraic_residual(s: &[f32; 31], theta: &[f32; 6]) -> f32 {
    let sz2 = s[at(4, 0, 0)] + 2.0 * s[at(2, 2, 0)] + s[at(0, 4, 0)];
    let mut linear = 0.0f32;
    let mut quad = 0.0f32;
    for (i, &(a, b, c)) in ROWS.iter().enumerate() {
        linear += theta[i] * (s[at(a + 2, b, c)] + s[at(a, b + 2, c)]);
        for (j, &(a2, b2, c2)) in ROWS.iter().enumerate() {
            quad += theta[i] * theta[j] * s[at(a + a2, b + b2, c + c2)];
        }
    }
    sz2 + 2.0 * linear + quad
}

/// RMS geometric distance from the algebraic residual of one set of sums.
fn rms(s: &[f32; 31], theta: &[f32; 6], r: f32) -> f32 {
    let n = s[0];
    if n <= 0.0 || r <= 0.0 {
        return f32::INFINITY;
    }
    // The residual is a difference of large sums: rounding can take it a little below zero.
    sqrt_exact(max(algebraic_residual(s, theta), 0.0) / n) / (2.0 * r)
}

/// Kåsa's moving-circle fit to the summed power sums `parts`, all about `origin`; also its
/// coefficients `(D, E, G, H, F, I)`.
fn fit_about(parts: &[[f32; 31]], origin: [f32; 2], with_rms: bool) -> Option<(Circle, [f32; 6])> {
    let mut s = [0.0f32; 31];
    for p in parts {
        for (a, b) in s.iter_mut().zip(p) {
            *a += b;
        }
    }
    if s[0] < 6.0 {
        return None;
    }
    let mut m = [[0.0f32; 6]; 6];
    let mut rhs = [0.0f32; 6];
    for (i, &(a, b, c)) in ROWS.iter().enumerate() {
        for (j, &(a2, b2, c2)) in ROWS.iter().enumerate() {
            m[i][j] = s[at(a + a2, b + b2, c + c2)];
        }
        rhs[i] = -(s[at(a + 2, b, c)] + s[at(a, b + 2, c)]);
    }
    // A cluster whose events share one instant cannot show motion: a ridge on the time terms
    // keeps them at zero instead of making the system singular.
    let ridge = 1e-6 * s[0];
    for k in [2, 3, 5] {
        m[k][k] += ridge;
    }
    let theta = solve_spd::<6>(m, rhs)?;
    let (u, v) = (-0.5 * theta[0], -0.5 * theta[1]);
    let r2 = u * u + v * v - theta[4];
    if !(r2 > 0.0 && r2.is_finite()) {
        return None;
    }
    let r = sqrt_exact(r2);
    let rms = if with_rms { rms(&s, &theta, r) } else { f32::NAN };
    let circle = Circle { u: origin[0] + u, v: origin[1] + v, vu: -0.5 * theta[2], vv: -0.5 * theta[3], r, rms };
    Some((circle, theta))
}

/// Solves `M x = b` for symmetric positive definite `M` given by its lower triangle
/// (Cholesky). `None` when `M` is not positive definite to f32 precision.
// Index loops read as the textbook algorithm; iterator chains would hide it.
#[allow(clippy::needless_range_loop)]
pub(crate) fn solve_spd<const K: usize>(mut m: [[f32; K]; K], mut b: [f32; K]) -> Option<[f32; K]> {
    for j in 0..K {
        let mut d = m[j][j];
        for k in 0..j {
            d -= m[j][k] * m[j][k];
        }
        if d.is_nan() || d <= 0.0 || d.is_infinite() {
            return None;
        }
        let d = sqrt_exact(d);
        m[j][j] = d;
        for i in j + 1..K {
            let mut s = m[i][j];
            for k in 0..j {
                s -= m[i][k] * m[j][k];
            }
            m[i][j] = s / d;
        }
    }
    for i in 0..K {
        let mut s = b[i];
        for k in 0..i {
            s -= m[i][k] * b[k];
        }
        b[i] = s / m[i][i];
    }
    for i in (0..K).rev() {
        let mut s = b[i];
        for k in i + 1..K {
            s -= m[k][i] * b[k];
        }
        b[i] = s / m[i][i];
    }
    Some(b)
}

#[cfg(test)]
mod test {
    use super::*;
    use std::vec::Vec;

    /// Events on an arc of a circle moving at (vu, vv) px/ms, `dt` spread over 0..4 ms.
    fn arc(cx: f32, cy: f32, r: f32, from: f32, to: f32, k: usize, vel: (f32, f32)) -> Vec<WindowEvent> {
        (0..k)
            .map(|i| {
                let a = from + (to - from) * i as f32 / (k - 1) as f32;
                let t = (i * 37 % k) as f32 / k as f32 * 4.0; // ms, scrambled over the arc
                WindowEvent {
                    x: (cx + vel.0 * t + r * libm::cosf(a)).round() as u16,
                    y: (cy + vel.1 * t + r * libm::sinf(a)).round() as u16,
                    dt_us: (t * 1000.0) as u32,
                }
            })
            .collect()
    }

    #[test]
    fn indices_follow_the_storage_order() {
        for (k, &(a, b, c)) in POWERS.iter().enumerate() {
            assert_eq!(at(usize::from(a), usize::from(b), usize::from(c)), k);
        }
    }

    #[test]
    fn circle_of_a_full_ring() {
        let ev = arc(100.0, 80.0, 9.0, 0.0, 6.2, 200, (0.0, 0.0));
        let c = Moments::of(&ev, 0).circle().expect("circle");
        assert!((c.u - 100.0).abs() < 0.1 && (c.v - 80.0).abs() < 0.1 && (c.r - 9.0).abs() < 0.1, "{c:?}");
        // Pixel rounding alone: about 0.3 px RMS.
        assert!(c.rms < 0.45, "{c:?}");
    }

    #[test]
    fn moving_ring_gives_centre_at_the_time_origin_and_velocity() {
        let ev = arc(100.0, 80.0, 9.0, 0.0, 6.2, 400, (0.5, -0.25));
        // Time origin at 2 ms: the centre is then at (101, 79.5).
        let c = Moments::of(&ev, 2000).circle().expect("circle");
        assert!((c.u - 101.0).abs() < 0.15 && (c.v - 79.5).abs() < 0.15, "{c:?}");
        assert!((c.vu - 0.5).abs() < 0.05 && (c.vv + 0.25).abs() < 0.05, "{c:?}");
        assert!(c.rms < 0.5, "{c:?}");
    }

    #[test]
    fn shifted_sums_equal_direct_sums() {
        let ev = arc(50.0, 60.0, 7.0, 0.3, 2.5, 40, (0.3, 0.1));
        let m = Moments::of(&ev, 1000);
        let shifted = m.about([45.0, 66.0]);
        let mut direct = [0.0f32; 31];
        for e in &ev {
            let (x, y, t) = (f32::from(e.x) - 45.0, f32::from(e.y) - 66.0, (e.dt_us as f32 - 1000.0) * 1e-3);
            for (k, &(a, b, c)) in POWERS.iter().enumerate() {
                direct[k] += libm::powf(x, f32::from(a)) * libm::powf(y, f32::from(b)) * libm::powf(t, f32::from(c));
            }
        }
        for (k, (s, d)) in shifted.iter().zip(&direct).enumerate() {
            let tol = 1e-4 * d.abs().max(1.0);
            assert!((s - d).abs() <= tol, "{k}: {s} vs {d}");
        }
    }

    #[test]
    fn two_crescents_of_one_moving_circle_join_and_two_circles_do_not() {
        // A circle moving 2 px over the window: a static circle through both crescents
        // would leave them a pixel off; the moving one does not.
        let vel = (0.5, 0.0);
        let lead = arc(120.0, 100.0, 8.0, -0.9, 0.9, 30, vel);
        let trail = arc(120.0, 100.0, 8.0, 2.3, 4.0, 30, vel);
        let (c, ra, rb) = Moments::of(&lead, 2000).joint_circle(&Moments::of(&trail, 2000)).expect("circle");
        assert!((c.u - 121.0).abs() < 0.3 && (c.v - 100.0).abs() < 0.3 && (c.r - 8.0).abs() < 0.3, "{c:?}");
        assert!(ra < 0.6 && rb < 0.6, "{ra} {rb}");
        // A crescent of a neighbouring circle, 20 px away: no circle fits both.
        let other = arc(140.0, 100.0, 8.0, 2.3, 4.0, 30, vel);
        let (_, ra, rb) = Moments::of(&lead, 2000).joint_circle(&Moments::of(&other, 2000)).expect("circle");
        assert!(ra.max(rb) > 1.5, "{ra} {rb}");
    }

    #[test]
    fn written_out_shift_is_the_table_loop_bit_for_bit() {
        let m = Moments::of(&arc(50.0, 60.0, 7.0, 0.3, 2.5, 40, (0.3, 0.1)), 1000);
        for origin in [[45.0, 66.0], [50.5, 59.0], [-3.0, 120.0]] {
            let (dx, dy) = (origin[0] - m.origin[0], origin[1] - m.origin[1]);
            let (mut px, mut py) = ([1.0f32; 5], [1.0f32; 5]);
            for k in 1..5 {
                px[k] = px[k - 1] * -dx;
                py[k] = py[k - 1] * -dy;
            }
            let mut want = [0.0f32; 31];
            for t in &SHIFT_TERMS {
                want[usize::from(t.slot)] +=
                    f32::from(t.binomial) * px[usize::from(t.px)] * py[usize::from(t.py)] * m.sums[usize::from(t.src)];
            }
            assert_eq!(m.about(origin).map(f32::to_bits), want.map(f32::to_bits));
        }
    }

    #[test]
    fn added_sums_are_the_union_sums() {
        let (a, b) = (arc(60.0, 60.0, 6.0, 0.0, 2.0, 25, (0.1, 0.2)), arc(60.0, 60.0, 6.0, 3.0, 5.0, 25, (0.1, 0.2)));
        let mut m = Moments::of(&a, 500);
        m.add(&Moments::of(&b, 500));
        let union: Vec<_> = a.iter().chain(&b).copied().collect();
        let (x, y) = (m.circle().unwrap(), Moments::of(&union, 500).circle().unwrap());
        assert!((x.u - y.u).abs() < 1e-3 && (x.v - y.v).abs() < 1e-3 && (x.r - y.r).abs() < 1e-3, "{x:?} {y:?}");
    }

    #[test]
    fn degenerate_sets_give_no_circle() {
        let line: Vec<_> = (0..30).map(|i| WindowEvent { x: 10 + i, y: 40, dt_us: 0 }).collect();
        assert_eq!(Moments::of(&line, 0).circle(), None);
        let point = [WindowEvent { x: 7, y: 7, dt_us: 0 }; 20];
        assert_eq!(Moments::of(&point, 0).circle(), None);
        assert_eq!(Moments::of(&[], 0).circle(), None);
    }
}
