//! What the camera looks at: the printed asymmetric circle grid on a white board, markings
//! on the board beside the grid, and a cluttered background wall behind it.
//!
//! Surfaces report reflectance and the distance to their nearest edge; the renderer turns
//! the distance into a defocus-blurred edge profile and uses it to skip pixels that no edge
//! is near.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Reflectance of the board's white paper and of the printed circles.
pub const PAPER: f64 = 0.85;
/// Reflectance of the printed circles.
pub const INK: f64 = 0.06;

/// An asymmetric circle grid: object point (i, j), i < cols, j < rows, at
/// (i·S, (2j + i mod 2)·S, 0) on the board plane (x right, y down, z into the board).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Board {
    /// Circles per line (the pattern's ROWS).
    pub rows: usize,
    /// Lines (the pattern's COLS).
    pub cols: usize,
    /// Spacing S, metres: neighbours on a line are 2S apart, diagonal neighbours S·√2.
    pub spacing: f64,
    /// Circle radius, metres.
    pub radius: f64,
}

impl Board {
    /// The presets E-Calib's dataset uses: `3x7` (34 mm), `3x9` (27 mm), `4x11` (24 mm).
    /// Circles have a diameter of 0.6 S, as printed grids commonly do.
    pub fn preset(name: &str) -> Option<Self> {
        let (rows, cols, spacing) = match name {
            "3x7" => (3, 7, 0.034),
            "3x9" => (3, 9, 0.027),
            "4x11" => (4, 11, 0.024),
            _ => return None,
        };
        Some(Self { rows, cols, spacing, radius: 0.3 * spacing })
    }

    /// Number of circles.
    pub fn len(&self) -> usize {
        self.rows * self.cols
    }

    /// Whether the grid has no circles.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Circle centres on the board, index `i·rows + j`.
    pub fn centres(&self) -> Vec<[f64; 2]> {
        let mut out = Vec::with_capacity(self.len());
        for i in 0..self.cols {
            for j in 0..self.rows {
                out.push(self.centre(i, j));
            }
        }
        out
    }

    fn centre(&self, i: usize, j: usize) -> [f64; 2] {
        [i as f64 * self.spacing, (2 * j + i % 2) as f64 * self.spacing]
    }

    /// The middle of the grid.
    pub fn middle(&self) -> [f64; 2] {
        [(self.cols - 1) as f64 * self.spacing * 0.5, (2 * self.rows - 1) as f64 * self.spacing * 0.5]
    }

    /// The printed sheet: the grid plus a margin of 1.5 S on every side.
    pub fn sheet(&self) -> [f64; 4] {
        let m = 1.5 * self.spacing;
        [-m, -m, (self.cols - 1) as f64 * self.spacing + m, (2 * self.rows - 1) as f64 * self.spacing + m]
    }

    /// Signed distance from a board point to the nearest circle's outline (negative inside).
    fn circle_distance(&self, x: f64, y: f64) -> f64 {
        let s = self.spacing;
        let i0 = round_i64(x / s);
        // The nearest centre by squared distance, one square root for it: sqrt and the
        // subtraction are monotonic, so this is bit for bit the least of the distances.
        let mut best_sq = f64::INFINITY;
        for i in i0 - 1..=i0 + 1 {
            if i < 0 || i >= self.cols as i64 {
                continue;
            }
            let odd = (i % 2) as f64;
            let j0 = round_i64((y / s - odd) * 0.5);
            for j in j0 - 1..=j0 + 1 {
                if j < 0 || j >= self.rows as i64 {
                    continue;
                }
                let [cx, cy] = self.centre(i as usize, j as usize);
                best_sq = best_sq.min((x - cx).powi(2) + (y - cy).powi(2));
            }
        }
        best_sq.sqrt() - self.radius
    }
}

/// A dark or bright disc or bar somewhere in the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shape {
    Disc { x: f64, y: f64, r: f64 },
    Bar { x0: f64, y0: f64, x1: f64, y1: f64 },
}

impl Shape {
    /// Signed distance (negative inside).
    fn distance(&self, x: f64, y: f64) -> f64 {
        match *self {
            Shape::Disc { x: cx, y: cy, r } => ((x - cx).powi(2) + (y - cy).powi(2)).sqrt() - r,
            Shape::Bar { x0, y0, x1, y1 } => {
                let dx = (x0 - x).max(x - x1);
                let dy = (y0 - y).max(y - y1);
                if dx <= 0.0 && dy <= 0.0 {
                    dx.max(dy)
                } else {
                    (dx.max(0.0).powi(2) + dy.max(0.0).powi(2)).sqrt()
                }
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Blob {
    shape: Shape,
    reflectance: f64,
}

/// Flat shapes on a plane, bucketed so a lookup touches few of them.
#[derive(Debug, Clone)]
struct Layer {
    base: f64,
    blobs: Vec<Blob>,
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    buckets: Vec<Vec<u32>>,
}

impl Layer {
    fn new(base: f64, blobs: Vec<Blob>, area: [f64; 4], cell: f64) -> Self {
        let nx = (((area[2] - area[0]) / cell).ceil() as usize).max(1);
        let ny = (((area[3] - area[1]) / cell).ceil() as usize).max(1);
        let mut buckets = vec![Vec::new(); nx * ny];
        // A blob goes into every cell it reaches, with a border so that distances to it are
        // exact within a cell's width of its edge; beyond that the cell reports "far".
        for (k, b) in blobs.iter().enumerate() {
            let (x0, y0, x1, y1) = match b.shape {
                Shape::Disc { x, y, r } => (x - r, y - r, x + r, y + r),
                Shape::Bar { x0, y0, x1, y1 } => (x0, y0, x1, y1),
            };
            let cx0 = (((x0 - cell - area[0]) / cell).floor().max(0.0) as usize).min(nx - 1);
            let cx1 = (((x1 + cell - area[0]) / cell).floor().max(0.0) as usize).min(nx - 1);
            let cy0 = (((y0 - cell - area[1]) / cell).floor().max(0.0) as usize).min(ny - 1);
            let cy1 = (((y1 + cell - area[1]) / cell).floor().max(0.0) as usize).min(ny - 1);
            for cy in cy0..=cy1 {
                for cx in cx0..=cx1 {
                    buckets[cy * nx + cx].push(k as u32);
                }
            }
        }
        Self { base, blobs, origin: [area[0], area[1]], cell, nx, ny, buckets }
    }

    /// Reflectance and the distance to the nearest edge (at least `cell` when no blob is
    /// near), blurred over `sigma` (metres on this plane).
    fn shade(&self, x: f64, y: f64, sigma: f64) -> (f64, f64) {
        let cx = floor((x - self.origin[0]) / self.cell);
        let cy = floor((y - self.origin[1]) / self.cell);
        if cx < 0.0 || cy < 0.0 || cx >= self.nx as f64 || cy >= self.ny as f64 {
            return (self.base, self.cell);
        }
        let mut value = self.base;
        let mut nearest = self.cell;
        for &k in &self.buckets[cy as usize * self.nx + cx as usize] {
            let b = &self.blobs[k as usize];
            let d = b.shape.distance(x, y);
            nearest = nearest.min(d.abs());
            // Later blobs are painted over earlier ones.
            let cover = smooth_step(-d / sigma);
            value += (b.reflectance - value) * cover;
        }
        (value, nearest)
    }
}

/// The scene: the board on the plane z = 0, a wall behind it.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The grid.
    pub board: Board,
    /// The wall's distance behind the board plane, metres.
    pub wall_depth: f64,
    marks: Layer,
    wall: Layer,
}

impl Scene {
    /// A board with a few markings beside the grid, in front of a wall with `clutter` dark
    /// and bright shapes, some of them discs of about the grid circles' apparent size (they
    /// become false circles), chosen by `seed`.
    pub fn new(board: Board, clutter: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5CE7E);
        let sheet = board.sheet();
        let s = board.spacing;
        // Markings on the sheet's margin: a printed label bar and two dots of circle size,
        // which a grid finder must not take for grid circles.
        let mut marks = vec![Blob {
            shape: Shape::Bar {
                x0: sheet[0] + 0.3 * s,
                y0: sheet[3] - 0.9 * s,
                x1: sheet[0] + 4.0 * s,
                y1: sheet[3] - 0.5 * s,
            },
            reflectance: 0.15,
        }];
        for k in 0..2 {
            let x = sheet[2] - (0.8 + 1.6 * k as f64) * s;
            marks.push(Blob {
                shape: Shape::Disc { x, y: sheet[1] + 0.7 * s, r: board.radius * 0.9 },
                reflectance: INK,
            });
        }
        let marks = Layer::new(PAPER, marks, sheet, 2.0 * s);

        let wall_depth = 0.6;
        let area = [-1.6, -1.3, 1.9, 1.6];
        let mut blobs = Vec::with_capacity(clutter);
        for _ in 0..clutter {
            let x = rng.random_range(area[0]..area[2]);
            let y = rng.random_range(area[1]..area[3]);
            let reflectance =
                if rng.random_bool(0.7) { rng.random_range(0.03..0.2) } else { rng.random_range(0.6..0.95) };
            let shape = match rng.random_range(0..10u8) {
                // Circles that, seen across the wall's extra distance, look like the grid's.
                0..=4 => Shape::Disc { x, y, r: board.radius * rng.random_range(1.5..3.5) },
                5..=6 => Shape::Disc { x, y, r: rng.random_range(0.03..0.12) },
                _ => {
                    let (w, h) = if rng.random_bool(0.5) {
                        (rng.random_range(0.01..0.04), rng.random_range(0.1..0.5))
                    } else {
                        (rng.random_range(0.1..0.5), rng.random_range(0.01..0.04))
                    };
                    Shape::Bar { x0: x, y0: y, x1: x + w, y1: y + h }
                }
            };
            blobs.push(Blob { shape, reflectance });
        }
        let wall = Layer::new(0.45, blobs, area, 0.08);
        Self { board, wall_depth, marks, wall }
    }

    /// Reflectance seen along a ray and an estimate of how far, in pixels, the nearest edge's
    /// blurred zone (4σ either side) is. `origin` is the camera centre and `dir` the ray in board coordinates,
    /// scaled so that its camera-frame z is 1 (so the ray parameter is the depth); `focal`
    /// converts lengths at a depth to pixels; `blur_px(depth)` is the edge blur there.
    pub fn shade(&self, origin: [f64; 3], dir: [f64; 3], focal: f64, blur_px: impl Fn(f64) -> f64) -> (f64, f64) {
        // Board plane z = 0: along the ray, s = −o_z / d_z.
        let hit = |z: f64| -> Option<(f64, f64, f64)> {
            if dir[2].abs() < 1e-12 {
                return None;
            }
            let s = (z - origin[2]) / dir[2];
            (s > 0.0).then(|| (origin[0] + s * dir[0], origin[1] + s * dir[1], s))
        };
        let wall = || match hit(self.wall_depth) {
            Some((x, y, s)) => {
                let px_per_m = focal / s;
                let sigma = blur_px(s) / px_per_m;
                let (v, d) = self.wall.shade(x, y, sigma);
                (v, (d - 4.0 * sigma).max(0.0) * px_per_m)
            }
            None => (self.wall.base, f64::INFINITY),
        };
        let Some((x, y, s)) = hit(0.0) else { return wall() };
        let px_per_m = focal / s;
        let sigma = blur_px(s) / px_per_m;
        let sheet = self.board.sheet();
        // Inside the sheet: distance to its border (positive inside).
        let inside = (x - sheet[0]).min(sheet[2] - x).min(y - sheet[1]).min(sheet[3] - y);
        if inside < -4.0 * sigma {
            let (v, d) = wall();
            return (v, d.min((-inside - 4.0 * sigma) * px_per_m));
        }
        let (paper, mark_d) = self.marks.shade(x, y, sigma);
        let dc = self.board.circle_distance(x, y);
        let on_board = paper + (INK - paper) * smooth_step(-dc / sigma);
        let nearest = (dc.abs().min(mark_d).min(inside.abs()) - 4.0 * sigma).max(0.0) * px_per_m;
        if inside > 4.0 * sigma {
            // The sheet hides the wall here.
            return (on_board, nearest);
        }
        let (wall_v, wall_d) = wall();
        let cover = smooth_step(inside / sigma);
        (wall_v + (on_board - wall_v) * cover, nearest.min(wall_d))
    }
}

/// Below this magnitude a double may have a fraction; from it on every double is an integer.
const FRACTIONS_END: f64 = 4_503_599_627_370_496.0; // 2^52

/// `v.round() as i64`, bit for bit, without a call into the maths library (the baseline x86-64
/// target has no rounding instruction, and shading rounds twice a pixel): below 2^52 the
/// truncation and the fraction it leaves are exact.
fn round_i64(v: f64) -> i64 {
    if v.abs() < FRACTIONS_END {
        let t = v as i64;
        let f = v - t as f64;
        if f >= 0.5 {
            t + 1
        } else if f <= -0.5 {
            t - 1
        } else {
            t
        }
    } else {
        v.round() as i64
    }
}

/// `v.floor()`, bit for bit (−0.0 aside, which compares equal), without a call into the
/// maths library.
fn floor(v: f64) -> f64 {
    if v.abs() < FRACTIONS_END {
        let t = (v as i64) as f64;
        if t > v {
            t - 1.0
        } else {
            t
        }
    } else {
        v.floor()
    }
}

/// The edge profile of a Gaussian blur: Φ(z), the standard normal CDF (erf to 1.5e-7).
pub fn smooth_step(z: f64) -> f64 {
    0.5 * (1.0 + erf(z * std::f64::consts::FRAC_1_SQRT_2))
}

fn erf(x: f64) -> f64 {
    // Beyond |x| = 6 the formula below gives exactly ±1 (its correction, under 2.4e-17, is
    // less than half the spacing of doubles below 1), so skip the exponential; most shading
    // is of points far from an edge.
    if x.abs() >= ERF_IS_ONE {
        return x.signum();
    }
    erf_formula(x)
}

/// Where [`erf_formula`] reaches ±1 exactly.
const ERF_IS_ONE: f64 = 6.0;

fn erf_formula(x: f64) -> f64 {
    // Abramowitz & Stegun 7.1.26.
    let t = 1.0 / (1.0 + 0.3275911 * x.abs());
    let y = 1.0
        - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592)
            * t
            * (-x * x).exp();
    if x >= 0.0 {
        y
    } else {
        -y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_layout_follows_the_convention() {
        let b = Board::preset("4x11").unwrap();
        let c = b.centres();
        assert_eq!(c.len(), 44);
        assert_eq!(c[0], [0.0, 0.0]);
        assert_eq!(c[1], [0.0, 2.0 * 0.024]);
        assert!((c[4][0] - 0.024).abs() < 1e-12 && (c[4][1] - 0.024).abs() < 1e-12);
        assert!(b.circle_distance(0.0, 0.0) + b.radius < 1e-12);
        assert!((b.circle_distance(0.024, 0.024 + b.radius)).abs() < 1e-12);
    }

    #[test]
    fn erf_is_exactly_one_where_the_shortcut_says() {
        // The shortcut must not change a single simulated event: the formula itself gives
        // ±1 there, checked densely near the cut and sparsely far out.
        let mut x = ERF_IS_ONE;
        while x < 12.0 {
            assert_eq!(erf_formula(x), 1.0, "{x}");
            assert_eq!(erf_formula(-x), -1.0, "{x}");
            x += 1e-6;
        }
        for x in [12.0, 26.0, 27.5, 40.0, 1e10, 1e300, f64::MAX, f64::INFINITY] {
            assert_eq!((erf_formula(x), erf_formula(-x)), (1.0, -1.0), "{x}");
            assert_eq!((erf(x), erf(-x)), (1.0, -1.0), "{x}");
        }
        let below = ERF_IS_ONE - 1e-9;
        assert_eq!(erf(below), erf_formula(below));
    }

    #[test]
    fn rounding_without_the_maths_library_is_exact() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4503599627370495.5,
            -4503599627370495.5,
            FRACTIONS_END,
            -FRACTIONS_END,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
        ];
        for _ in 0..200_000 {
            let scale = 10f64.powi(rng.random_range(-3..18));
            values.push(rng.random_range(-1.0..1.0) * scale);
            // Halves and their neighbours.
            let half = rng.random_range(-1000i64..1000) as f64 + 0.5;
            let (up, down) = (f64::from_bits(half.to_bits() + 1), f64::from_bits(half.to_bits() - 1));
            values.extend([half, up, down]);
        }
        for v in values {
            assert_eq!(round_i64(v), v.round() as i64, "round {v:e}");
            let (a, b) = (floor(v), v.floor());
            assert!(a == b || (a.is_nan() && b.is_nan()), "floor {v:e}: {a} vs {b}");
        }
    }

    #[test]
    fn shading_sees_circles_paper_and_wall() {
        let b = Board::preset("4x11").unwrap();
        let scene = Scene::new(b, 0, 1);
        let blur = |_: f64| 0.5;
        // Looking straight at circle (0, 0) from 0.4 m: ink.
        let (v, _) = scene.shade([0.0, 0.0, -0.4], [0.0, 0.0, 1.0], 355.0, blur);
        assert!((v - INK).abs() < 1e-6);
        // Between circles: paper.
        let (v, d) = scene.shade([0.012, 0.036, -0.4], [0.0, 0.0, 1.0], 355.0, blur);
        assert!((v - PAPER).abs() < 1e-3 && d > 0.0);
        // Far off the sheet: the bare wall.
        let (v, _) = scene.shade([1.0, 1.0, -0.4], [0.0, 0.0, 1.0], 355.0, blur);
        assert!((v - 0.45).abs() < 1e-9);
        assert!(erf(0.0).abs() < 1e-9 && (smooth_step(3.0) - 0.99865).abs() < 1e-4);
    }
}
