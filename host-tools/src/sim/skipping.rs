//! Skipping time: a jump to a later instant leaves every pixel at the level and the
//! reference its history would have left it at, so the windows after the jump are those of
//! a continuous run.

use super::bands::{in_bands, BAND_PIXELS};
use super::stepping::EDGE_MARGIN_PX;
use super::{Simulator, CHUNK_ROWS};
use nalgebra::Vector3;
use rand::RngExt;

/// How far downstream along the motion [`Simulator::settle`] reads a changing pixel's past
/// at most, px.
const TRACE_MAX_PX: usize = 64;
/// A changing pixel whose past levels stay within [`TRACE_FLAT_LOG`] (log units, a fifth of a
/// threshold) over this many pixels is taken as still: an edge is moving along itself there.
const TRACE_FLAT_PX: usize = 8;
/// See [`TRACE_FLAT_PX`].
const TRACE_FLAT_LOG: f64 = 0.05;

/// The pasts [`Simulator::trace_pasts`] read for a band of pixels.
struct TracedBand {
    /// Every traced pixel's levels, newest first, one after the other.
    levels: Vec<f64>,
    /// Per traced pixel: its index, where its levels start and how many, and whether the
    /// oldest is still (beyond every edge's zone).
    pixels: Vec<(usize, usize, usize, bool)>,
}

impl Simulator {
    /// Jumps to `seconds` since the start without simulating the time between: every pixel
    /// takes the scene's log intensity there and the reference level its history would have
    /// left it at, a random point of its threshold cycle where that history is unknown
    /// (`settle`). The events of a window depend on the pixels' states only
    /// through those, so the windows that follow are those of a continuous run, at a
    /// fraction of the cost when windows are far apart (`evcal demo` simulates only the few
    /// milliseconds after each window tick). Events produced before the jump are kept.
    pub fn skip_to(&mut self, seconds: f64) {
        if seconds <= self.t {
            return;
        }
        self.started = true;
        self.t = seconds;
        self.settle(seconds, true);
    }

    /// Every pixel at the scene's log intensity at `t` and the reference level its history
    /// would leave it. A still pixel keeps a random phase of its cycle on the side of its last
    /// change: a pixel brighter than the scene's middle grey was last reached from darker
    /// (paper after a printed circle passed), a darker one from brighter.
    ///
    /// With `trace`, a pixel an edge is crossing at `t` gets the reference its past gives:
    /// what it saw before is what the image now shows downstream of it along the motion
    /// (the scene is still; the image moves over it), so its levels are read there, pixel by
    /// pixel, back to where the image is still ([`TRACE_MAX_PX`] at most), and its reference
    /// is run from that still past to the present as its events would have moved it, a
    /// threshold at a time. A pixel the edge has only begun to reach so keeps the reference of
    /// its still past, more than one threshold away, and fires late inside the blurred edge:
    /// the events of a window after a jump trail their edges as far as a continuous run's
    /// (0.13 px in the demo's case; `tests/tests/end_to_end/calibration.rs`). Without `trace` (the start
    /// of a run) every pixel is treated as still. (Jumps used to put a changing pixel at a
    /// random phase of the change under way, within one threshold of its level: it fired
    /// early, and the pipeline measured an edge shift of 0.01 px after jumps where a
    /// continuous run gives 0.13.)
    pub(super) fn settle(&mut self, t: f64, trace: bool) {
        let now = self.levels_at(t);
        let (lo_l, hi_l) = now.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(l, _)| (a.min(l), b.max(l)));
        let middle = 0.5 * (lo_l + hi_l);
        let pasts = if trace { self.trace_pasts(t, &now) } else { Vec::new() };
        let mut band =
            pasts.iter().flat_map(|b| b.pixels.iter().map(move |&(p, from, len, still)| (b, p, from, len, still)));
        let mut next_traced = band.next();
        for (p, st) in self.pixels.iter_mut().enumerate() {
            let (l, _) = now[p];
            // The levels this pixel passed, newest first, and whether the oldest was still.
            let (past, still): (&[f64], bool) = match next_traced {
                Some((b, q, from, len, still)) if q == p => {
                    next_traced = band.next();
                    (&b.levels[from..from + len], still)
                }
                _ => (&[], true),
            };
            // Where the traced past starts, and the level after it (the direction of the
            // change under way there).
            let (first, next) = match past.len() {
                0 => (l, l),
                1 => (past[0], l),
                n => (past[n - 1], past[n - 2]),
            };
            let falling = if still || next == first { first < middle } else { next < first };
            // Falling: the last OFF event's level is above; rising: the last ON's is below.
            let (lo, hi) = if falling { (0.0, st.off) } else { (-st.on, 0.0) };
            // Strictly within a threshold: level − on < reference < level + off.
            let mut reference = first + self.rng.random_range(lo..hi) * 0.999;
            for &level in past.iter().rev().skip(1).chain(std::iter::once(&l)) {
                loop {
                    if level - reference >= st.on {
                        reference += st.on;
                    } else if reference - level >= st.off {
                        reference -= st.off;
                    } else {
                        break;
                    }
                }
            }
            st.level = l;
            // Settled: the filter's lag after a jump is not traced.
            st.lp = l;
            st.evaluated = t;
            st.reference = reference;
            st.last = f64::NEG_INFINITY;
        }
        if trace {
            // As a step leaves them: a pixel beyond an edge's zone is next looked at when an
            // edge could have reached it (the start of a run looks at every pixel at once).
            let speed = self.speed_bound(t);
            for (next, &(_, d)) in self.next_eval.iter_mut().zip(&now) {
                *next = if d > EDGE_MARGIN_PX { t + (d - EDGE_MARGIN_PX) / speed } else { t };
            }
            let chunk_len = CHUNK_ROWS * usize::from(self.cfg.camera.width);
            for (c, next) in self.chunk_next.iter_mut().zip(self.next_eval.chunks(chunk_len)) {
                *c = next.iter().copied().fold(f64::INFINITY, f64::min);
            }
        } else {
            self.next_eval.fill(t);
            self.chunk_next.fill(t);
        }
    }

    /// The past of every pixel within an edge's zone in `now` (the levels at `t`), read
    /// downstream along the image's motion there ([`Simulator::settle`]); bands of pixels
    /// shared among threads, in pixel order.
    fn trace_pasts(&self, t: f64, now: &[(f64, f64)]) -> Vec<TracedBand> {
        let dt = 1e-4;
        let earlier = self.pose_at((t - dt).max(0.0));
        let dt = t - (t - dt).max(0.0);
        let pose = self.pose_at(t);
        let origin = pose.centre();
        let to_board = pose.rotation.inverse();
        let sheet = self.cfg.board.sheet();
        let cam = &self.cfg.camera;
        let (w, h) = (usize::from(cam.width), usize::from(cam.height));
        // How fast the image moves over pixel `p`, px/s: where the scene point it sees (on the
        // board's sheet, else on the wall) was a moment earlier.
        let motion = |p: usize| -> Option<[f64; 2]> {
            let [x, y] = self.rays[p];
            let dir = to_board * Vector3::new(x, y, 1.0);
            let at = |z: f64| {
                let s = (z - origin.z) / dir.z;
                (dir.z.abs() > 1e-12 && s > 0.0).then(|| origin + dir * s)
            };
            let on_sheet = at(0.0).filter(|q| q.x >= sheet[0] && q.x <= sheet[2] && q.y >= sheet[1] && q.y <= sheet[3]);
            let [u, v] = cam.project(&earlier.apply(&on_sheet.or_else(|| at(self.scene.wall_depth))?))?;
            Some([((p % w) as f64 - u) / dt, ((p / w) as f64 - v) / dt])
        };
        let trace = |p: usize, levels: &mut Vec<f64>| -> bool {
            let from = levels.len();
            let Some([vx, vy]) = motion(p).filter(|_| dt > 0.0) else { return true };
            let speed = vx.hypot(vy);
            if !speed.is_normal() {
                return true;
            }
            let (ux, uy) = (vx / speed, vy / speed);
            let (mut lo, mut hi) = (now[p].0, now[p].0);
            let reach = self.pixels[p].on + self.pixels[p].off;
            // Pixel centres are at integer coordinates: +0.5 and truncation round (the
            // coordinates are checked to be inside the sensor first).
            let (x, y) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
            for k in 1..=TRACE_MAX_PX {
                let (qx, qy) = (x + ux * k as f64, y + uy * k as f64);
                if !(qx >= 0.0 && qy >= 0.0 && qx < w as f64 && qy < h as f64) {
                    break;
                }
                let (lq, dq) = now[qy as usize * w + qx as usize];
                // Only where the change turns matters: a pixel's reference after a rise (or
                // fall) is the same whether it passed the levels between or not.
                let n = levels.len() - from;
                let before = if n == 0 { now[p].0 } else { levels[levels.len() - 1] };
                let before2 = match n {
                    0 => None,
                    1 => Some(now[p].0),
                    _ => Some(levels[levels.len() - 2]),
                };
                match before2 {
                    Some(b2) if (b2 <= before && before <= lq) || (b2 >= before && before >= lq) => {
                        *levels.last_mut().expect("n > 0") = lq;
                    }
                    _ => levels.push(lq),
                }
                if dq > 1.0 {
                    return true;
                }
                // Changed one way by more than both thresholds since here: the pixel fired on
                // the way, so its reference is now a whole number of thresholds from where it
                // was here, at a phase its earlier past drew at random; a draw here does as
                // well.
                if levels.len() - from == 1 && (levels[from] - now[p].0).abs() >= reach {
                    return false;
                }
                // An edge moving along itself: the pixel has not been changing.
                (lo, hi) = (lo.min(lq), hi.max(lq));
                if k >= TRACE_FLAT_PX && hi - lo < TRACE_FLAT_LOG {
                    return true;
                }
            }
            false
        };
        in_bands(now.len(), BAND_PIXELS, |range| {
            let mut out = TracedBand { levels: Vec::new(), pixels: Vec::new() };
            for p in range.filter(|&p| now[p].1 <= 1.0) {
                let from = out.levels.len();
                let still = trace(p, &mut out.levels);
                out.pixels.push((p, from, out.levels.len() - from, still));
            }
            out
        })
    }
}
