//! Scoring detections against simulated ground truth: centre errors and how often each true
//! circle is found.

use crate::input::detections::WindowRecord;
use serde::Serialize;

/// A true circle in one window, as the simulator knows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueCircle {
    /// Centre of the projected circle outline at the window's t_ref, px.
    pub centre: [f64; 2],
    /// Mean projected radius, px.
    pub radius_px: f64,
    /// Whether the whole circle lies inside the sensor.
    pub in_view: bool,
}

/// Which true circles count: wholly in view and at least this large.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoreRules {
    /// Smallest radius of a scored circle, px.
    pub min_radius_px: f64,
    /// A detection matches a true circle when its centre is within this fraction of the
    /// radius (and within `max_match_px`).
    pub match_fraction: f64,
    /// Upper bound on the match distance, px.
    pub max_match_px: f64,
}

impl Default for ScoreRules {
    fn default() -> Self {
        Self { min_radius_px: 5.0, match_fraction: 0.3, max_match_px: 2.0 }
    }
}

/// Scores over many windows.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Score {
    /// Windows scored.
    pub windows: u64,
    /// True circles scored (in view, large enough), over all windows.
    pub circles: u64,
    /// Of those, found by a detection.
    pub found: u64,
    /// Detections matching no scored true circle (clutter, partial circles, small circles).
    pub unmatched_detections: u64,
    /// Sum of squared centre errors of found circles, px².
    pub sq_error_sum: f64,
    /// Largest centre error of a found circle, px.
    pub max_error_px: f64,
}

impl Score {
    /// Fraction of scored true circles found.
    pub fn found_rate(&self) -> f64 {
        if self.circles == 0 {
            0.0
        } else {
            self.found as f64 / self.circles as f64
        }
    }

    /// RMS centre error of found circles, px.
    pub fn rms_px(&self) -> f64 {
        if self.found == 0 {
            0.0
        } else {
            (self.sq_error_sum / self.found as f64).sqrt()
        }
    }

    /// Adds one window: each scored true circle is matched to its nearest detection.
    pub fn add(&mut self, window: &WindowRecord, truth: &[TrueCircle], rules: &ScoreRules) {
        self.windows += 1;
        let mut used = vec![false; window.centers.len()];
        for t in truth.iter().filter(|t| t.in_view && t.radius_px >= rules.min_radius_px) {
            self.circles += 1;
            let limit = (rules.match_fraction * t.radius_px).min(rules.max_match_px);
            let best = window
                .centers
                .iter()
                .enumerate()
                .map(|(i, c)| (i, (f64::from(c.u) - t.centre[0]).hypot(f64::from(c.v) - t.centre[1])))
                .filter(|&(_, d)| d <= limit)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((i, d)) = best {
                used[i] = true;
                self.found += 1;
                self.sq_error_sum += d * d;
                self.max_error_px = self.max_error_px.max(d);
            }
        }
        self.unmatched_detections += used.iter().filter(|u| !**u).count() as u64;
    }
}

/// Simulates `seconds` of events (all kept in memory: about 16 bytes per event).
pub fn simulate(
    sim_cfg: crate::sim::SimConfig,
    seconds: f64,
) -> (Vec<evcal_core::event::Event>, crate::sim::Simulator) {
    let mut sim = crate::sim::Simulator::new(sim_cfg);
    let mut events = Vec::new();
    sim.run_until(seconds, |batch| events.extend_from_slice(batch));
    (events, sim)
}

/// Simulates only what the windows of `window` need: from each tick (every `step_us`) to the
/// end of the step in which `events` events have come (and 64 more: the timestamp jitter's
/// reach), then jumps to the next tick
/// ([`Simulator::skip_to`](crate::sim::Simulator::skip_to)). With windows of a few
/// milliseconds every 33 ms this simulates about a seventh of the time [`simulate`] does, and
/// the windows the detector cuts are equally distributed: their centres trail their circles
/// as far, and the calibration agrees (`tests/tests/end_to_end/calibration.rs`). `progress` is called
/// after each window with the simulated time reached, seconds.
pub fn simulate_windows(
    sim_cfg: crate::sim::SimConfig,
    seconds: f64,
    window: evcal_core::window::WindowConfig,
    mut progress: impl FnMut(f64),
) -> (Vec<evcal_core::event::Event>, crate::sim::Simulator) {
    let mut sim = crate::sim::Simulator::new(sim_cfg);
    let mut events = Vec::new();
    let step = (window.step_us as f64 * 1e-6).max(1e-3);
    let start_us = sim.config().start_us;
    let mut tick = 0.0f64;
    while tick < seconds {
        sim.skip_to(tick);
        let tick_us = start_us + (tick * 1e6).round() as u64;
        // Simulate until the window (events at or after the tick) is full.
        let mut in_window = 0;
        sim.run_until_or_stop((tick + step).min(seconds), |batch| {
            events.extend_from_slice(batch);
            in_window += batch.iter().filter(|e| e.t_us >= tick_us).count();
            if in_window >= window.events + 64 {
                std::ops::ControlFlow::Break(())
            } else {
                std::ops::ControlFlow::Continue(())
            }
        });
        let t = sim.time();
        progress(t);
        tick += step;
    }
    events.sort_by_key(|e| e.t_us);
    (events, sim)
}

/// Runs events through the detection core and calls `each` with every window's record and
/// the simulator's truth at the window's `t_ref`.
pub fn detect_with_truth(
    events: &[evcal_core::event::Event],
    sim: &crate::sim::Simulator,
    det_cfg: evcal_core::detect::DetectConfig,
    mut each: impl FnMut(&WindowRecord, &crate::sim::FrameTruth),
) {
    let mut det: Box<crate::input::detections::HostDetector> =
        Box::new(crate::input::detections::HostDetector::new(det_cfg));
    let mut events = events.iter();
    loop {
        let d = match events.next() {
            Some(e) => det.push(*e),
            None => match det.end() {
                Some(d) => Some(d),
                None => break,
            },
        };
        if let Some(d) = d {
            let r = WindowRecord::from_detection(d);
            each(&r, &sim.truth_at(r.t_ref_us));
        }
    }
}

/// Scores every window of `events` against the simulator's truth.
pub fn score(
    events: &[evcal_core::event::Event],
    sim: &crate::sim::Simulator,
    det_cfg: evcal_core::detect::DetectConfig,
    rules: &ScoreRules,
) -> Score {
    let mut s = Score::default();
    detect_with_truth(events, sim, det_cfg, |w, t| s.add(w, &true_circles(t), rules));
    s
}

/// The truth of a simulated frame in the form [`Score::add`] takes (ellipse centres).
pub fn true_circles(t: &crate::sim::FrameTruth) -> Vec<TrueCircle> {
    t.circles
        .iter()
        .map(|c| TrueCircle { centre: c.ellipse_centre, radius_px: c.radius_px, in_view: c.in_view })
        .collect()
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::input::detections::CenterRecord;

    fn c(u: f32, v: f32) -> CenterRecord {
        CenterRecord { u, v, r: 6.0, spread: 0.1, n: 50, converged: true }
    }

    #[test]
    fn matches_nearest_within_limit() {
        let w = WindowRecord {
            seq: 0,
            t_ref_us: 0,
            events: 0,
            noise: 0,
            centers: vec![c(10.1, 10.0), c(50.0, 50.0), c(30.0, 30.0)],
            sensor: None,
        };
        let truth = [
            TrueCircle { centre: [10.0, 10.0], radius_px: 6.0, in_view: true },
            TrueCircle { centre: [30.0, 31.9], radius_px: 6.0, in_view: true }, // 1.9 px off: beyond 0.3 r
            TrueCircle { centre: [80.0, 80.0], radius_px: 3.0, in_view: true }, // too small: not scored
            TrueCircle { centre: [50.0, 50.0], radius_px: 6.0, in_view: false }, // partly out: not scored
        ];
        let mut s = Score::default();
        s.add(&w, &truth, &ScoreRules::default());
        assert_eq!((s.circles, s.found, s.unmatched_detections), (2, 1, 2));
        assert!((s.rms_px() - 0.1).abs() < 1e-5);
        assert!((s.found_rate() - 0.5).abs() < 1e-12);
    }
}
