//! Time in steps: each step short enough that no edge moves more than a third of a pixel,
//! the due pixels advanced over it, the noise of the step added, and the events handed on in
//! time order once no later step can precede them.

use super::pixel::{ideal_update, physical_update, quiet_for, Crossings, PixelState};
use super::{Simulator, CHUNK_ROWS};
use evcal_core::event::Event;
use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson};

/// Shot noise on a perfect white in office light, relative to darkness (v2e's factor).
const SHOT_AT_FULL_LIGHT: f64 = 0.25;

/// Pixels this close to an edge's blurred zone are looked at every step, px: the zones
/// already include their blur; one pixel more for the pixel's own extent and the tilt of the
/// plane (distances are measured along it).
pub(super) const EDGE_MARGIN_PX: f64 = 1.0;

impl Simulator {
    /// Image speed bound, px/s, around time `t`: the fastest of sample points on the board
    /// and the wall, doubled for safety.
    pub(super) fn speed_bound(&self, t: f64) -> f64 {
        let dt = 1e-3;
        let (p0, p1) = (self.pose_at(t), self.pose_at(t + dt));
        let sheet = self.cfg.board.sheet();
        let mut pts: Vec<Vector3<f64>> = vec![
            Vector3::new(sheet[0], sheet[1], 0.0),
            Vector3::new(sheet[2], sheet[1], 0.0),
            Vector3::new(sheet[0], sheet[3], 0.0),
            Vector3::new(sheet[2], sheet[3], 0.0),
        ];
        // Wall points seen at the image corners.
        let origin = p0.centre();
        let cam = &self.cfg.camera;
        for (u, v) in [
            (0.0, 0.0),
            (f64::from(cam.width), 0.0),
            (0.0, f64::from(cam.height)),
            (f64::from(cam.width), f64::from(cam.height)),
        ] {
            let [x, y] = cam.undistort(u, v);
            let d = p0.rotation.inverse() * Vector3::new(x, y, 1.0);
            if d.z.abs() > 1e-9 {
                let s = (self.scene.wall_depth - origin.z) / d.z;
                if s > 0.0 {
                    pts.push(origin + d * s);
                }
            }
        }
        let mut fastest = 0.0f64;
        for p in &pts {
            if let (Some(a), Some(b)) = (cam.project(&p0.apply(p)), cam.project(&p1.apply(p))) {
                fastest = fastest.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() / dt);
            }
        }
        2.0 * fastest + 20.0
    }

    /// Simulates until `seconds` since the start, the end of the recording, handing events in
    /// time order to `sink` in batches; the last step ends at `seconds` and every event is
    /// handed. Returns the number of events produced.
    ///
    /// Calling it again continues, but as a new piece: the timestamp jitter of its first events
    /// can put them before the last ones of the call before. To simulate a recording in
    /// pieces (for progress), use [`run_part`](Self::run_part), which gives exactly the events
    /// of one call, in order.
    pub fn run_until(&mut self, seconds: f64, sink: impl FnMut(&[Event])) -> u64 {
        self.run_part(seconds, seconds, sink)
    }

    /// Simulates a recording that ends at `end` seconds up to `seconds` at least, handing
    /// `sink` (in time order) the events that no later step can precede; at `end`, every
    /// event. Steps are cut only at `end`, and events wait across calls for the jitter's
    /// horizon, so that `run_part(s1, end)`, `run_part(s2, end)`, …, `run_part(end, end)`
    /// hand exactly the events of [`run_until(end)`](Self::run_until), in order, whatever
    /// the pieces. Returns the number of events handed.
    pub fn run_part(&mut self, seconds: f64, end: f64, mut sink: impl FnMut(&[Event])) -> u64 {
        self.run(seconds, end, |b| {
            sink(b);
            std::ops::ControlFlow::Continue(())
        })
    }

    /// As [`run_until`](Self::run_until), but stops early at the end of the step in which
    /// `sink` returns `Break`, handing it the events still pending (those a later step's
    /// timestamp jitter could still have overtaken) first.
    pub fn run_until_or_stop(&mut self, seconds: f64, sink: impl FnMut(&[Event]) -> std::ops::ControlFlow<()>) -> u64 {
        self.run(seconds, seconds, sink)
    }

    /// Simulates a recording ending at `end` up to `seconds` (see [`run_part`](Self::run_part)),
    /// stopping as [`run_until_or_stop`](Self::run_until_or_stop) does.
    fn run(&mut self, seconds: f64, end: f64, mut sink: impl FnMut(&[Event]) -> std::ops::ControlFlow<()>) -> u64 {
        let seconds = seconds.min(end);
        let cam = self.cfg.camera;
        let (w, npix) = (usize::from(cam.width), self.pixels.len());
        let px = self.cfg.pixel;
        let jitter_cap = 4.0 * px.jitter_s;
        let mut produced = 0u64;
        if !self.started {
            self.started = true;
            self.settle(0.0, false);
        }
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(8);
        let noise_rate = px.background_hz * npix as f64;
        while self.t < seconds {
            let speed = self.speed_bound(self.t);
            let dt = (0.33 / speed).clamp(5e-6, 2e-3).min(end - self.t).max(1e-7);
            let (t0, t1) = (self.t, self.t + dt);
            let pose = self.pose_at(t1);
            let origin: [f64; 3] = pose.centre().into();
            let to_board = *pose.rotation.inverse().matrix();
            let crossings = self.step_pixels(&to_board, origin, t0, t1, speed, threads);
            let mut fresh: Vec<Event> = Vec::new();
            // In pixel order, as the jitter's random draws follow it.
            for (p, t, pol) in crossings {
                fresh.push(self.stamp(p, t, pol > 0.0, w));
            }
            // Background activity and hot pixels: independent of the scene.
            let noise = |rng: &mut ChaCha8Rng, rate: f64| -> u64 {
                if rate * dt <= 0.0 {
                    return 0;
                }
                Poisson::new(rate * dt).map(|d| d.sample(rng) as u64).unwrap_or(0)
            };
            let n_bg = noise(&mut self.rng, noise_rate);
            for _ in 0..n_bg {
                let p = self.rng.random_range(0..npix);
                let t = self.rng.random_range(t0..t1);
                let pol = self.rng.random_bool(0.5);
                fresh.push(self.stamp(p, t, pol, w));
            }
            for k in 0..self.hot.len() {
                let n = noise(&mut self.rng, px.hot_hz);
                for _ in 0..n {
                    let t = self.rng.random_range(t0..t1);
                    let pol = self.rng.random_bool(0.5);
                    fresh.push(self.stamp(self.hot[k] as usize, t, pol, w));
                }
            }
            // Shot noise: candidates at the darkest pixels' rate, each kept with its pixel's
            // share of it (its level is the one of its last evaluation: a skipped pixel's is
            // flat).
            let n_shot = noise(&mut self.phys_rng, px.shot_noise_hz * npix as f64);
            for _ in 0..n_shot {
                let p = self.phys_rng.random_range(0..npix);
                let t = self.phys_rng.random_range(t0..t1);
                let pol = self.phys_rng.random_bool(0.5);
                let keep = 1.0 - (1.0 - SHOT_AT_FULL_LIGHT) * self.pixels[p].level.exp().min(1.0);
                if self.phys_rng.random_bool(keep.clamp(0.0, 1.0)) {
                    fresh.push(self.stamp(p, t, pol, w));
                }
            }
            // Events with equal keys are equal, so any sort gives the same stream. The pending
            // events are sorted already: sort the fresh ones and merge.
            let key = |e: &Event| (e.t_us, e.y, e.x, e.polarity);
            fresh.sort_unstable_by_key(key);
            merge_sorted(&mut self.pending, &fresh, key);
            // Jitter is at most `jitter_cap`: events before t1 − cap can no longer be
            // overtaken by later ones.
            let horizon = self.to_us(if t1 >= end { f64::INFINITY } else { t1 - jitter_cap });
            let ready = self.pending.partition_point(|e| e.t_us < horizon);
            let mut stop = false;
            if ready > 0 {
                stop = sink(&self.pending[..ready]).is_break();
                produced += ready as u64;
                self.pending.drain(..ready);
            }
            self.stepped += t1 - t0;
            self.t = t1;
            if stop {
                if !self.pending.is_empty() {
                    let _ = sink(&self.pending);
                    produced += self.pending.len() as u64;
                    self.pending.clear();
                }
                break;
            }
        }
        produced
    }

    fn to_us(&self, t: f64) -> u64 {
        if t.is_infinite() {
            return u64::MAX;
        }
        self.cfg.start_us + (t.max(0.0) * 1e6).round() as u64
    }

    fn stamp(&mut self, p: usize, t: f64, polarity: bool, w: usize) -> Event {
        let px = self.cfg.pixel;
        let j = if px.jitter_s > 0.0 {
            let n: f64 = rand_distr::StandardNormal.sample(&mut self.rng);
            n.clamp(-4.0, 4.0) * px.jitter_s
        } else {
            0.0
        };
        Event { t_us: self.to_us(t + j), x: (p % w) as u16, y: (p / w) as u16, polarity }
    }

    /// Advances every pixel due by `t1` from `t0` to `t1`, chunks of rows shared among
    /// `threads`; the threshold crossings in pixel order.
    fn step_pixels(
        &mut self,
        to_board: &nalgebra::Matrix3<f64>,
        origin: [f64; 3],
        t0: f64,
        t1: f64,
        speed: f64,
        threads: usize,
    ) -> Crossings {
        let chunk_len = (CHUNK_ROWS * usize::from(self.cfg.camera.width)).max(1);
        // Out of `self` for the step, so the threads can change disjoint chunks of them while
        // reading the rest of the simulator.
        let mut pixels = std::mem::take(&mut self.pixels);
        let mut next_eval = std::mem::take(&mut self.next_eval);
        let mut chunk_next = std::mem::take(&mut self.chunk_next);
        let sim = &*self;
        let due: Vec<_> = pixels
            .chunks_mut(chunk_len)
            .zip(next_eval.chunks_mut(chunk_len))
            .zip(chunk_next.iter_mut())
            .enumerate()
            .filter(|(_, (_, next))| **next <= t1)
            .map(|(k, ((st, ne), next))| (k, st, ne, next))
            .collect();
        let workers = threads.min(due.len()).max(1);
        let queue = std::sync::Mutex::new(due.into_iter());
        let work = || {
            let mut out: Vec<(usize, Crossings)> = Vec::new();
            // The guard is dropped inside `and_then`, so the queue is locked only to take a
            // chunk. A worker that panicked poisons it; the others stop and the join below
            // passes the panic on.
            while let Some((k, st, ne, next)) = queue.lock().ok().and_then(|mut q| q.next()) {
                let c = sim.step_chunk(k * chunk_len, st, ne, next, to_board, origin, t0, t1, speed);
                if !c.is_empty() {
                    out.push((k, c));
                }
            }
            out
        };
        let mut done = if workers > 1 {
            std::thread::scope(|s| {
                let helpers: Vec<_> = (1..workers).map(|_| s.spawn(work)).collect();
                let mut done = work();
                for h in helpers {
                    done.extend(h.join().expect("simulator thread panicked"));
                }
                done
            })
        } else {
            work()
        };
        self.pixels = pixels;
        self.next_eval = next_eval;
        self.chunk_next = chunk_next;
        done.sort_unstable_by_key(|(k, _)| *k);
        done.into_iter().flat_map(|(_, c)| c).collect()
    }

    /// Advances the due pixels of one chunk (`states` and `next_eval` from pixel `base`) from
    /// `t0` to `t1`, and sets `chunk_next` to the chunk's earliest next evaluation.
    #[allow(clippy::too_many_arguments)]
    fn step_chunk(
        &self,
        base: usize,
        states: &mut [PixelState],
        next_eval: &mut [f64],
        chunk_next: &mut f64,
        to_board: &nalgebra::Matrix3<f64>,
        origin: [f64; 3],
        t0: f64,
        t1: f64,
        speed: f64,
    ) -> Crossings {
        let mut events = Vec::new();
        let refractory = self.cfg.pixel.refractory_s;
        let (physics, cutoff_hz) = (self.cfg.pixel.physics(), self.cfg.pixel.cutoff_hz());
        let margin = EDGE_MARGIN_PX;
        let mut earliest = f64::INFINITY;
        for (i, (st, next)) in states.iter_mut().zip(next_eval.iter_mut()).enumerate() {
            if *next > t1 {
                earliest = earliest.min(*next);
                continue;
            }
            let p = base + i;
            let (l1, dist) = self.log_intensity(to_board, origin, p);
            if physics {
                physical_update(st, l1, t0, t1, refractory, cutoff_hz, p, &mut events);
                // Beyond an edge's zone the input is flat, but the filter may still be settling
                // or the reference leaking towards a crossing: looked at again by then.
                *next = if dist > margin { t1 + quiet_for(st, cutoff_hz, (dist - margin) / speed) } else { t1 };
            } else {
                ideal_update(st, l1, t0, t1, refractory, p, &mut events);
                // Beyond an edge's blurred zone a pixel is flat until an edge could have
                // travelled the difference.
                *next = if dist > margin { t1 + (dist - margin) / speed } else { t1 };
            }
            earliest = earliest.min(*next);
        }
        *chunk_next = earliest;
        events
    }
}

/// Merges the sorted `fresh` into the sorted `into`, keeping it sorted by `key`.
fn merge_sorted<K: Ord>(into: &mut Vec<Event>, fresh: &[Event], key: impl Fn(&Event) -> K) {
    match (into.last(), fresh.first()) {
        (_, None) => {}
        (Some(last), Some(first)) if key(last) > key(first) => {
            let old = std::mem::take(into);
            into.reserve(old.len() + fresh.len());
            let (mut i, mut j) = (0, 0);
            while i < old.len() && j < fresh.len() {
                if key(&fresh[j]) < key(&old[i]) {
                    into.push(fresh[j]);
                    j += 1;
                } else {
                    into.push(old[i]);
                    i += 1;
                }
            }
            into.extend_from_slice(&old[i..]);
            into.extend_from_slice(&fresh[j..]);
        }
        _ => into.extend_from_slice(fresh),
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::sim::{Light, PixelModel, SimConfig, Trajectory};

    fn short(light: Light, seconds: f64) -> (Vec<Event>, Simulator) {
        let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, light, 7).unwrap();
        let mut sim = Simulator::new(cfg);
        let mut out = Vec::new();
        sim.run_until(seconds, |b| out.extend_from_slice(b));
        (out, sim)
    }

    #[test]
    fn events_are_ordered_inside_the_sensor_and_deterministic() {
        let (a, sim) = short(Light::Good, 0.05);
        assert!(a.len() > 10_000, "only {} events in 50 ms", a.len());
        assert!(a.windows(2).all(|w| w[0].t_us <= w[1].t_us));
        let c = sim.config().camera;
        assert!(a.iter().all(|e| e.x < c.width && e.y < c.height));
        let (b, _) = short(Light::Good, 0.05);
        assert_eq!(a, b);
    }

    #[test]
    fn events_gather_on_the_circle_edges() {
        let (ev, sim) = short(Light::Good, 0.03);
        let truth = sim.truth_at(15_000);
        let near = ev
            .iter()
            .filter(|e| (10_000..20_000).contains(&e.t_us))
            .filter(|e| {
                truth.circles.iter().any(|c| {
                    let d = ((f64::from(e.x) - c.ellipse_centre[0]).powi(2)
                        + (f64::from(e.y) - c.ellipse_centre[1]).powi(2))
                    .sqrt();
                    (d - c.radius_px).abs() < 3.0
                })
            })
            .count();
        let all = ev.iter().filter(|e| (10_000..20_000).contains(&e.t_us)).count();
        assert!(near as f64 > 0.5 * all as f64, "{near} of {all} events near circle edges");
    }

    fn run_physical(seconds: f64, pieces: &[f64]) -> Vec<Event> {
        let mut cfg = SimConfig::preset("davis346", "3x7", Trajectory::Spiral, Light::Good, 3).unwrap();
        cfg.pixel = PixelModel { shot_noise_hz: 5.0, ..PixelModel::physical(Light::Good, 200.0) };
        let mut sim = Simulator::new(cfg);
        let mut out = Vec::new();
        for &t in pieces {
            sim.run_part(t, seconds, |b| out.extend_from_slice(b));
        }
        sim.run_part(seconds, seconds, |b| out.extend_from_slice(b));
        out
    }

    #[test]
    fn a_run_in_pieces_gives_the_events_of_one_run_in_order() {
        let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Low, 7).unwrap();
        let mut sim = Simulator::new(cfg);
        let mut pieces = Vec::new();
        for k in 1..=9 {
            sim.run_part(0.011 * k as f64, 0.1, |b| pieces.extend_from_slice(b));
        }
        sim.run_part(0.1, 0.1, |b| pieces.extend_from_slice(b));
        let (one, _) = short(Light::Low, 0.1);
        assert!(one.windows(2).all(|w| w[0].t_us <= w[1].t_us));
        assert!(pieces == one, "{} events in pieces, {} in one go", pieces.len(), one.len());
        // With the physics too.
        let one = run_physical(0.06, &[]);
        assert!(one.len() > 10_000, "{}", one.len());
        assert!(one.windows(2).all(|w| w[0].t_us <= w[1].t_us));
        assert!(run_physical(0.06, &[0.007, 0.02, 0.021, 0.05]) == one);
    }

    #[test]
    fn physics_is_deterministic_and_inside_the_sensor() {
        let a = run_physical(0.05, &[]);
        assert!(a == run_physical(0.05, &[]));
        let c = SimConfig::preset("davis346", "3x7", Trajectory::Spiral, Light::Good, 3).unwrap().camera;
        assert!(a.iter().all(|e| e.x < c.width && e.y < c.height));
    }

    #[test]
    fn shot_noise_fires_more_in_the_dark() {
        let mut cfg = SimConfig::preset("davis346", "3x7", Trajectory::Spiral, Light::Good, 3).unwrap();
        cfg.pixel = PixelModel { shot_noise_hz: 400.0, background_hz: 0.0, hot_fraction: 0.0, ..cfg.pixel };
        let mut sim = Simulator::new(cfg);
        let mut ev = Vec::new();
        // Still scene: no motion is needed to count noise, but the trajectory moves; the board's
        // pixels see paper or ink, and the noise at each is counted per pixel of each.
        sim.run_until(0.02, |b| ev.extend_from_slice(b));
        let w = usize::from(c_width(&sim));
        let (mut dark, mut bright) = ((0usize, 0usize), (0usize, 0usize));
        for (p, st) in sim.pixels.iter().enumerate() {
            let n = ev.iter().filter(|e| usize::from(e.y) * w + usize::from(e.x) == p).count();
            if st.level < (0.1f64).ln() {
                dark = (dark.0 + n, dark.1 + 1);
            } else if st.level > (0.7f64).ln() {
                bright = (bright.0 + n, bright.1 + 1);
            }
        }
        let rate = |(n, pixels): (usize, usize)| n as f64 / pixels.max(1) as f64 / 0.02;
        let (rd, rb) = (rate(dark), rate(bright));
        assert!(rd > 2.5 * rb, "dark {rd} Hz, bright {rb} Hz");
        assert!((rd - 400.0 * (1.0 - 0.75 * 0.07)).abs() < 60.0, "dark {rd} Hz");
    }

    fn c_width(sim: &Simulator) -> u16 {
        sim.config().camera.width
    }
}
