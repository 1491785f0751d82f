//! A simulated recording run through the core, with each window's truth: what the
//! calibration examples start from, optionally kept on disk so that a second run with the
//! same arguments skips the simulation (minutes) and reruns only the host's steps (seconds).

use evcal_core::event::SensorSize;
use evcal_host::{
    eval::{simulate, simulate_windows},
    input::detections::{self, WindowRecord},
    sim::SimConfig,
};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A grid circle in one window as the simulator knows it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrueCentre {
    /// Centre of the projected outline at the window's t_ref, px (what a circle fit estimates).
    pub centre: [f64; 2],
    /// Whether the whole outline is inside the sensor.
    pub in_view: bool,
}

/// The core's windows of a simulated recording and, per window, every grid circle's truth
/// (by board index).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Recorded {
    /// The windows, in time order.
    pub windows: Vec<WindowRecord>,
    /// The same windows with filled discs fitted where no ring fits
    /// (`FitConfig::filled_discs`): what `evcal calibrate` detects again when the rings give
    /// no calibration ([`evcal_host::pipeline::no_calibration`]). Empty in a cache written
    /// before they were kept.
    #[serde(default)]
    pub disc_windows: Vec<WindowRecord>,
    /// Per window, the grid's circles by index.
    pub truth: Vec<Vec<TrueCentre>>,
}

impl Recorded {
    /// Simulates `seconds` of `cfg` (only what each window needs when `windowed`) and runs
    /// the core over it with the host's defaults ([`detections::host_config`]). With `cache`,
    /// the result is read from `cache` if it is there (the caller names the file after
    /// everything that shapes it, the window size included) and written there otherwise.
    pub fn simulate(cfg: SimConfig, seconds: f64, windowed: bool, cache: Option<&Path>) -> Self {
        if let Some(r) = cache.and_then(|f| std::fs::read(f).ok()).and_then(|b| serde_json::from_slice(&b).ok()) {
            return r;
        }
        let cam = cfg.camera;
        // The host's defaults: windows sized to the sensor, as `evcal calibrate` cuts them.
        let det = detections::host_config(SensorSize { width: cam.width, height: cam.height });
        let (events, sim) =
            if windowed { simulate_windows(cfg, seconds, det.window, |_| {}) } else { simulate(cfg, seconds) };
        let sensor = SensorSize { width: cam.width, height: cam.height };
        let detect = |filled_discs: bool| {
            // The discs' windows are longer on a larger sensor (`host_disc_config`); the
            // truth is kept for the rings' windows only.
            let det = if filled_discs { detections::host_disc_config(sensor) } else { det };
            let mut windows = Vec::new();
            detections::run(events.iter().map(|e| Ok(*e)), det, |d| windows.push(WindowRecord::from_detection(d)))
                .expect("simulated events are valid");
            windows
        };
        let (windows, disc_windows) = (detect(false), detect(true));
        let truth = windows
            .iter()
            .map(|w| {
                sim.truth_at(w.t_ref_us)
                    .circles
                    .iter()
                    .map(|c| TrueCentre { centre: c.ellipse_centre, in_view: c.in_view })
                    .collect()
            })
            .collect();
        let r = Self { windows, disc_windows, truth };
        if let Some(f) = cache {
            if let Some(dir) = f.parent() {
                let _ = std::fs::create_dir_all(dir);
            }
            // A cache that cannot be written costs the next run its time, nothing else.
            let _ = serde_json::to_vec(&r).map(|b| std::fs::write(f, b));
        }
        r
    }

    /// Whether the whole grid is in view in window `k`.
    pub fn wholly_in_view(&self, k: usize) -> bool {
        self.truth[k].iter().all(|c| c.in_view)
    }

    /// The board index of the true circle nearest `p` in window `k`.
    pub fn nearest(&self, k: usize, p: [f64; 2]) -> Option<usize> {
        let d = |c: &TrueCentre| (c.centre[0] - p[0]).hypot(c.centre[1] - p[1]);
        (0..self.truth[k].len()).min_by(|&a, &b| d(&self.truth[k][a]).total_cmp(&d(&self.truth[k][b])))
    }
}
