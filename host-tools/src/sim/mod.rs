//! A simulated event camera watching an asymmetric circle grid, with ground truth.
//!
//! The simulator renders the scene ([`scene`]) through a distorted pinhole camera
//! ([`camera`]) moving along a hand-held trajectory ([`trajectory`]), or a recorded one
//! ([`recorded_motion`]), and turns the change of
//! each pixel's log intensity into events the way a DVS pixel does:
//!
//! * an event fires when the log intensity has moved by the pixel's contrast threshold from
//!   the level of its last event (thresholds differ per pixel: mismatch);
//! * a pixel is blind for a refractory period after each event;
//! * timestamps jitter (more in low light);
//! * background activity fires at random pixels and times, hot pixels fire all the time;
//! * in low light the scene is darker, so the dark current flattens the contrast, and noise
//!   rates are much higher;
//! * optionally ([`PixelModel::physical`]), the physics of a real pixel: a photoreceptor that
//!   low-passes the log intensity with a cutoff proportional to the light it receives (dark
//!   pixels lag by milliseconds, OFF edges into the dark more than ON edges), leak events and
//!   shot noise that grows as light falls. The presets leave it out (an ideal pixel).
//!
//! Time advances in steps short enough that no edge moves more than a third of a pixel;
//! crossing times are interpolated within a step. Pixels far from every edge are skipped until
//! an edge could have reached them. Everything is seeded: the same configuration gives the
//! same events, on any machine, whatever the number of threads.

mod bands;
pub mod camera;
mod config;
mod ground_truth;
mod pixel;
pub mod recorded_motion;
mod render;
pub mod scene;
mod skipping;
mod stepping;
pub mod trajectory;

pub use camera::{Camera, Pose};
pub use config::{Light, PixelModel, SimConfig};
pub use ground_truth::{truth, CircleTruth, FrameTruth};
pub use recorded_motion::{MotionError, RecordedMotion};
pub use scene::{Board, Scene};
pub use trajectory::Trajectory;

use evcal_core::event::Event;
use pixel::PixelState;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The simulator.
pub struct Simulator {
    cfg: SimConfig,
    scene: Scene,
    /// Per pixel: the ray through its centre in camera coordinates (z = 1).
    rays: Vec<[f64; 2]>,
    pixels: Vec<PixelState>,
    /// Per pixel: the next time it must be evaluated, s. Kept apart from the states: most
    /// pixels are far from every edge and skipped, and the scan for the due ones then reads
    /// 8 bytes a pixel instead of a whole state.
    next_eval: Vec<f64>,
    /// Per chunk of [`CHUNK_ROWS`] rows: the earliest `next_eval` of its pixels, so that a
    /// chunk with nothing due is skipped without reading it.
    chunk_next: Vec<f64>,
    hot: Vec<u32>,
    rng: ChaCha8Rng,
    /// The physics' random draws (leak rates, shot noise), apart from `rng`.
    phys_rng: ChaCha8Rng,
    fov_half: [f64; 2],
    /// Simulated time reached, seconds since start.
    t: f64,
    /// Time actually simulated, seconds: `t` less the jumps of [`Simulator::skip_to`].
    stepped: f64,
    pending: Vec<Event>,
    started: bool,
}

/// Mixed into the seed of the physics' random stream.
const PHYSICS_SEED: u64 = 0x9e37_79b9_7f4a_7c15;

/// Rows in a chunk of pixels, the unit of work shared among threads: small enough that the
/// threads share the rows an edge crosses evenly (the board covers a part of the image),
/// large enough that handing out chunks costs little.
const CHUNK_ROWS: usize = 4;

impl Simulator {
    /// A simulator at time 0.
    pub fn new(cfg: SimConfig) -> Self {
        let cam = cfg.camera;
        let (w, h) = (usize::from(cam.width), usize::from(cam.height));
        let mut rays = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                rays.push(cam.undistort(x as f64, y as f64));
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let thr = Normal::new(cfg.pixel.threshold, cfg.pixel.mismatch.max(0.0)).expect("finite threshold");
        let floor = cfg.pixel.threshold * 0.3;
        let pixels = (0..w * h)
            .map(|_| PixelState {
                level: 0.0,
                reference: 0.0,
                on: thr.sample(&mut rng).max(floor),
                off: thr.sample(&mut rng).max(floor),
                last: f64::NEG_INFINITY,
                lp: 0.0,
                evaluated: 0.0,
                leak: 0.0,
            })
            .collect::<Vec<_>>();
        let n_hot = ((w * h) as f64 * cfg.pixel.hot_fraction).round() as usize;
        let hot = (0..n_hot).map(|_| rng.random_range(0..(w * h) as u32)).collect();
        let fov_half =
            [(f64::from(cam.width) * 0.5 / cam.fx).atan() * 0.9, (f64::from(cam.height) * 0.5 / cam.fy).atan() * 0.9];
        // The physics draws from a stream of its own, so that the presets (no physics) draw
        // exactly what they drew before it existed.
        let mut phys_rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ PHYSICS_SEED);
        let mut pixels = pixels;
        if cfg.pixel.leak_hz > 0.0 && cfg.pixel.leak_hz.is_finite() {
            let spread = cfg.pixel.leak_spread_decades;
            let spread = if spread.is_finite() { spread.max(0.0) } else { 0.0 };
            for st in &mut pixels {
                let n: f64 = rand_distr::StandardNormal.sample(&mut phys_rng);
                st.leak = cfg.pixel.leak_hz * 10f64.powf(spread * n.clamp(-4.0, 4.0)) * st.on;
            }
        }
        let scene = Scene::new(cfg.board, cfg.clutter, cfg.seed);
        let chunks = h.div_ceil(CHUNK_ROWS);
        Self {
            cfg,
            scene,
            rays,
            pixels,
            next_eval: vec![0.0; w * h],
            chunk_next: vec![0.0; chunks],
            hot,
            rng,
            phys_rng,
            fov_half,
            t: 0.0,
            stepped: 0.0,
            pending: Vec::new(),
            started: false,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// Simulated time reached, seconds since the start.
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Time actually simulated, seconds: [`time`](Self::time) less the jumps of
    /// [`skip_to`](Self::skip_to).
    pub fn simulated_seconds(&self) -> f64 {
        self.stepped
    }

    /// The camera pose at `t` seconds since the start.
    pub fn pose_at(&self, t: f64) -> Pose {
        match &self.cfg.recorded_motion {
            Some(r) => r.pose(t),
            None => self.cfg.trajectory.pose(&self.cfg.board, self.cfg.distance, self.fov_half, t),
        }
    }
}
