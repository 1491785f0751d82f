//! A simulated event camera watching an asymmetric circle grid, with ground truth.
//!
//! The simulator renders the scene ([`scene`]) through a distorted pinhole camera
//! ([`camera`]) moving along a hand-held trajectory ([`trajectory`]) and turns the change of
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

pub mod camera;
pub mod scene;
pub mod trajectory;

pub use camera::{Camera, Pose};
pub use scene::{Board, Scene};
pub use trajectory::Trajectory;

use evcal_core::event::Event;
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};
use serde::{Deserialize, Serialize};

/// Lighting presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Light {
    /// An office-lit board: low noise.
    Good,
    /// A dim room: a twentieth of the light, ten times the background activity, more jitter.
    Low,
}

impl Light {
    /// Name as the CLI spells it.
    pub fn name(self) -> &'static str {
        match self {
            Light::Good => "good",
            Light::Low => "low",
        }
    }
}

/// The sensor's pixel model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PixelModel {
    /// Mean contrast threshold (ON and OFF), log units.
    pub threshold: f64,
    /// Pixel-to-pixel standard deviation of the thresholds, log units.
    pub mismatch: f64,
    /// Refractory period, seconds.
    pub refractory_s: f64,
    /// Standard deviation of timestamp jitter, seconds (clipped at 4σ).
    pub jitter_s: f64,
    /// Background activity rate per pixel, Hz.
    pub background_hz: f64,
    /// Fraction of pixels that are hot.
    pub hot_fraction: f64,
    /// Event rate of a hot pixel, Hz.
    pub hot_hz: f64,
    /// Scene illumination (1 = office light).
    pub illumination: f64,
    /// Dark signal in the same units as illumination × reflectance: flattens dark contrast.
    pub dark: f64,
    /// Photoreceptor bandwidth: the cutoff frequency, Hz, of a pixel receiving intensity 1
    /// (illumination 1 on a perfect white); `None` for an unlimited bandwidth (the pixel
    /// follows its log intensity at once, as the presets of [`for_light`](Self::for_light)).
    ///
    /// A real photoreceptor is a first-order low-pass filter on log intensity whose cutoff is
    /// proportional to its photocurrent (Lichtsteiner et al. 2008; v2e): at intensity
    /// I = illumination × reflectance + [`dark`](Self::dark) the pixel's filtered level `y`
    /// follows its log intensity `x = ln I` as dy/dt = (x − y)/τ with
    /// τ = 1 / (2π · photoreceptor_hz · I). The dark signal is the floor: even a black pixel
    /// answers, at photoreceptor_hz × dark. Events fire on the filtered level, so a pixel
    /// going dark (an OFF edge into a printed circle) lags more than one going bright, and
    /// every lag grows as the light falls. At 300 Hz in office light the board's paper
    /// (reflectance 0.85) answers with τ ≈ 0.6 ms and its ink (0.06) with τ ≈ 8 ms.
    #[serde(default)]
    pub photoreceptor_hz: Option<f64>,
    /// Mean rate of leak events per pixel, Hz: the pixel's memorised level leaks so that a
    /// still pixel fires an ON event every 1/rate seconds (v2e's leak: the level an event
    /// counts from creeps down by a threshold per period). 0: none.
    #[serde(default)]
    pub leak_hz: f64,
    /// Pixel-to-pixel spread of the leak rates: standard deviation of their log10, decades.
    #[serde(default)]
    pub leak_spread_decades: f64,
    /// Rate of shot-noise events per pixel in darkness, Hz. Photon and dark-current shot noise
    /// fires more in dark pixels: the rate at intensity I is this × (1 − 0.75·min(I, 1)), a
    /// quarter of it on a perfect white in office light (v2e's law). Random polarity; the
    /// events do not move the pixel's reference. 0: none.
    #[serde(default)]
    pub shot_noise_hz: f64,
}

impl PixelModel {
    /// The model for a lighting preset.
    pub fn for_light(light: Light) -> Self {
        match light {
            Light::Good => Self {
                threshold: 0.25,
                mismatch: 0.03,
                refractory_s: 100e-6,
                jitter_s: 15e-6,
                background_hz: 0.1,
                hot_fraction: 1e-4,
                hot_hz: 400.0,
                illumination: 1.0,
                dark: 0.004,
                photoreceptor_hz: None,
                leak_hz: 0.0,
                leak_spread_decades: 0.0,
                shot_noise_hz: 0.0,
            },
            Light::Low => Self {
                threshold: 0.25,
                mismatch: 0.04,
                refractory_s: 300e-6,
                jitter_s: 150e-6,
                background_hz: 1.5,
                hot_fraction: 3e-4,
                hot_hz: 800.0,
                illumination: 0.05,
                dark: 0.004,
                photoreceptor_hz: None,
                leak_hz: 0.0,
                leak_spread_decades: 0.0,
                shot_noise_hz: 0.0,
            },
        }
    }

    /// The model for a lighting preset with a real pixel's physics: a photoreceptor of
    /// `photoreceptor_hz` at intensity 1 ([`photoreceptor_hz`](Self::photoreceptor_hz);
    /// `f64::INFINITY` for an unlimited bandwidth), leak events at 0.1 Hz per pixel spread
    /// over a third of a decade, and shot noise at 1 Hz per pixel in darkness (a DAVIS346's
    /// order of magnitude; v2e's defaults are alike). Set the fields to change any of it.
    pub fn physical(light: Light, photoreceptor_hz: f64) -> Self {
        Self {
            photoreceptor_hz: (photoreceptor_hz < f64::INFINITY).then_some(photoreceptor_hz.max(0.0)),
            leak_hz: 0.1,
            leak_spread_decades: 0.33,
            shot_noise_hz: 1.0,
            ..Self::for_light(light)
        }
    }

    /// The cutoff at intensity 1 as the pixel update takes it: infinite for an unlimited
    /// bandwidth, never below 1 µHz (a zero cutoff would freeze the pixel).
    fn cutoff_hz(&self) -> f64 {
        match self.photoreceptor_hz {
            Some(f) if f.is_finite() => f.max(1e-6),
            _ => f64::INFINITY,
        }
    }

    /// Whether each pixel's update needs the physics (a finite photoreceptor or leak): if
    /// not, the simpler update of an ideal pixel runs, giving the presets' events bit for bit.
    fn physics(&self) -> bool {
        self.cutoff_hz().is_finite() || self.leak_hz > 0.0
    }
}

/// Everything a simulation depends on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    /// The camera (intrinsics, distortion, sensor size).
    pub camera: Camera,
    /// The grid.
    pub board: Board,
    /// The motion.
    pub trajectory: Trajectory,
    /// The lighting preset the pixel model came from.
    pub light: Light,
    /// The pixel model.
    pub pixel: PixelModel,
    /// Typical distance from camera to board, metres.
    pub distance: f64,
    /// Edge blur at the focus distance, pixels (σ of a Gaussian).
    pub blur_px: f64,
    /// Extra blur per unit of relative distance from the focus distance, pixels.
    pub defocus_px: f64,
    /// Shapes on the background wall.
    pub clutter: usize,
    /// Seed of every random choice.
    pub seed: u64,
    /// Timestamp of the first instant, microseconds (a nonzero start exercises readers).
    pub start_us: u64,
}

impl SimConfig {
    /// A configuration from the presets: sensor `davis346`, `dvxplorer`, `imx636` (`evk4`) or
    /// `genx320` ([`Camera::preset`]), pattern `3x7`, `3x9` or `4x11`. `None` for an unknown
    /// name.
    pub fn preset(sensor: &str, pattern: &str, trajectory: Trajectory, light: Light, seed: u64) -> Option<Self> {
        let camera = Camera::preset(sensor)?;
        let board = Board::preset(pattern)?;
        // Far enough that the grid can sweep the view, near enough that circles stay several
        // pixels wide.
        let grid_w = (board.cols - 1) as f64 * board.spacing + 2.0 * board.radius;
        // On a sensor wider than 4:3 the grid spanning 0.7 of the width would reach past the
        // top and bottom (a 4x11 grid on a 16:9 sensor: 89 % of the height, wholly in view in
        // half the windows of a cone): the grid spans 0.7 of the width a 4:3 sensor of that
        // height would have, as someone holding it in view would keep it. 4:3 sensors (both
        // tangents agree within 0.3 %) and square ones are framed by their width.
        let tan_x = f64::from(camera.width) * 0.5 / camera.fx;
        let tan_y = f64::from(camera.height) * 0.5 / camera.fy;
        let distance = grid_w / (FILL * 2.0 * tan_x.min(tan_y * 4.0 / 3.0));
        Some(Self {
            camera,
            board,
            trajectory,
            light,
            pixel: PixelModel::for_light(light),
            distance,
            blur_px: 0.6,
            defocus_px: 1.5,
            clutter: 60,
            seed,
            start_us: 0,
        })
    }
}

/// The true state of one circle at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CircleTruth {
    /// Index in the grid, `i·rows + j`.
    pub index: usize,
    /// Centre of the projected outline (the ellipse's centre; what a circle fit to the edge
    /// estimates), pixels.
    pub ellipse_centre: [f64; 2],
    /// Projection of the circle's centre (differs from the ellipse centre under
    /// perspective), pixels.
    pub projected_centre: [f64; 2],
    /// Mean distance of the projected outline from its centre, pixels.
    pub radius_px: f64,
    /// Whether the whole outline is inside the sensor (and in front of the camera).
    pub in_view: bool,
}

/// The truth at one instant.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameTruth {
    /// The instant, microseconds.
    pub t_us: u64,
    /// Board → camera rotation (Rodrigues vector).
    pub rvec: [f64; 3],
    /// Board → camera translation, metres.
    pub tvec: [f64; 3],
    /// Every circle of the grid.
    pub circles: Vec<CircleTruth>,
}

/// Fraction of the sensor's width (of a 4:3 sensor's width for a wider one) the grid spans at
/// the typical distance.
const FILL: f64 = 0.7;

/// Points on a circle's outline used to find its projected centre and radius.
const OUTLINE_POINTS: usize = 96;

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

/// Shot noise on a perfect white in office light, relative to darkness (v2e's factor).
const SHOT_AT_FULL_LIGHT: f64 = 0.25;

/// Longest a skipped pixel with leak waits before it is looked at again, s: bounds how far
/// the leak can move its reference unseen (see [`quiet_for`]).
const LEAK_LOOK_S: f64 = 0.5;

/// Rows in a chunk of pixels, the unit of work shared among threads: small enough that the
/// threads share the rows an edge crosses evenly (the board covers a part of the image),
/// large enough that handing out chunks costs little.
const CHUNK_ROWS: usize = 4;

/// How far downstream along the motion [`Simulator::settle`] reads a changing pixel's past
/// at most, px.
const TRACE_MAX_PX: usize = 64;
/// A changing pixel whose past levels stay within [`TRACE_FLAT_LOG`] (log units, a fifth of a
/// threshold) over this many pixels is taken as still: an edge is moving along itself there.
const TRACE_FLAT_PX: usize = 8;
/// See [`TRACE_FLAT_PX`].
const TRACE_FLAT_LOG: f64 = 0.05;

/// Pixels this close to an edge's blurred zone are looked at every step, px: the zones
/// already include their blur; one pixel more for the pixel's own extent and the tilt of the
/// plane (distances are measured along it).
const EDGE_MARGIN_PX: f64 = 1.0;

/// The pasts [`Simulator::trace_pasts`] read for a band of pixels.
struct TracedBand {
    /// Every traced pixel's levels, newest first, one after the other.
    levels: Vec<f64>,
    /// Per traced pixel: its index, where its levels start and how many, and whether the
    /// oldest is still (beyond every edge's zone).
    pixels: Vec<(usize, usize, usize, bool)>,
}

/// Threshold crossings (pixel, time, +1/−1).
type Crossings = Vec<(usize, f64, f64)>;

#[derive(Debug, Clone, Copy)]
struct PixelState {
    /// Log intensity at the last evaluation.
    level: f64,
    /// Log intensity of the last event (the reference the thresholds count from).
    reference: f64,
    on: f64,
    off: f64,
    /// Time of the last event, s.
    last: f64,
    /// The photoreceptor's output, log units: `level` filtered by the photoreceptor's low-pass
    /// ([`PixelModel::photoreceptor_hz`]); the level events are fired from. Equal to `level`
    /// without physics.
    lp: f64,
    /// Time of the last evaluation, s: a skipped pixel's filter and leak are brought from there
    /// to the step that next evaluates it. Unused without physics.
    evaluated: f64,
    /// How fast the reference leaks down, log units per second (the leak rate times the ON
    /// threshold).
    leak: f64,
}

impl PixelState {
    /// The level of the next event a pixel at `level` fires, and its sign (+1 ON, −1 OFF):
    /// a threshold away from the reference; `None` within both thresholds.
    fn crossing(&self, level: f64) -> Option<(f64, f64)> {
        if level - self.reference >= self.on {
            Some((self.reference + self.on, 1.0))
        } else if self.reference - level >= self.off {
            Some((self.reference - self.off, -1.0))
        } else {
            None
        }
    }
}

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
        self.cfg.trajectory.pose(&self.cfg.board, self.cfg.distance, self.fov_half, t)
    }

    fn blur(&self, depth: f64) -> f64 {
        let rel = ((depth - self.cfg.distance) / self.cfg.distance).abs();
        // A pixel integrates over its area: a box of width 1 adds variance 1/12.
        (self.cfg.blur_px.powi(2) + (self.cfg.defocus_px * rel).powi(2) + 1.0 / 12.0).sqrt()
    }

    /// Log intensity at pixel `p` for `pose`, and the distance to the nearest edge (px).
    fn log_intensity(&self, to_board: &nalgebra::Matrix3<f64>, origin: [f64; 3], p: usize) -> (f64, f64) {
        let [x, y] = self.rays[p];
        let d = to_board * Vector3::new(x, y, 1.0);
        let focal = self.cfg.camera.fx.min(self.cfg.camera.fy);
        let (refl, dist) = self.scene.shade(origin, [d.x, d.y, d.z], focal, |depth| self.blur(depth));
        let px = &self.cfg.pixel;
        ((px.illumination * refl + px.dark).ln(), dist)
    }

    /// Image speed bound, px/s, around time `t`: the fastest of sample points on the board
    /// and the wall, doubled for safety.
    fn speed_bound(&self, t: f64) -> f64 {
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
    /// (0.13 px in the demo's case; `tests/tests/calibration.rs`). Without `trace` (the start
    /// of a run) every pixel is treated as still. (Jumps used to put a changing pixel at a
    /// random phase of the change under way, within one threshold of its level: it fired
    /// early, and the pipeline measured an edge shift of 0.01 px after jumps where a
    /// continuous run gives 0.13.)
    fn settle(&mut self, t: f64, trace: bool) {
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

    /// The scene's log intensity at every pixel at `t`, and the distance to the nearest edge's
    /// blurred zone (px); bands of pixels shared among threads.
    fn levels_at(&self, t: f64) -> Vec<(f64, f64)> {
        let pose = self.pose_at(t);
        let origin: [f64; 3] = pose.centre().into();
        let to_board = *pose.rotation.inverse().matrix();
        in_bands(self.pixels.len(), BAND_PIXELS, |range| {
            range.map(|p| self.log_intensity(&to_board, origin, p)).collect::<Vec<_>>()
        })
        .concat()
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

    /// Ground truth at `t_us` (timestamps as the events carry them).
    pub fn truth_at(&self, t_us: u64) -> FrameTruth {
        let t = t_us.saturating_sub(self.cfg.start_us) as f64 * 1e-6;
        truth(&self.cfg, &self.pose_at(t), t_us)
    }
}

/// An ideal pixel (unlimited bandwidth, no leak) from `t0` to `t1`, its log intensity moving
/// linearly to `l1`: the threshold crossings of the log intensity itself, interpolated within
/// the step, pushed to `events` as pixel `p`'s.
fn ideal_update(st: &mut PixelState, l1: f64, t0: f64, t1: f64, refractory: f64, p: usize, events: &mut Crossings) {
    let l0 = st.level;
    while let Some((level, sign)) = st.crossing(l1) {
        let span = l1 - l0;
        let frac = if span.abs() > 1e-12 { ((level - l0) / span).clamp(0.0, 1.0) } else { 1.0 };
        let tc = (t0 + frac * (t1 - t0)).max(st.last + refractory);
        if tc > t1 {
            break; // still blind: fires in a later step if the change persists
        }
        events.push((p, tc, sign));
        st.reference = level;
        st.last = tc;
    }
    st.level = l1;
    st.lp = l1;
}

/// The photoreceptor's time constant over a step in which the log intensity moves linearly
/// from `l0` to `l1`, s ([`PixelModel::photoreceptor_hz`]; 0 for an unlimited bandwidth).
/// The filter's rate is proportional to the intensity, so its mean over the step is taken: the
/// logarithmic mean of the intensities at the ends.
fn tau_over(cutoff_hz: f64, l0: f64, l1: f64) -> f64 {
    if !cutoff_hz.is_finite() {
        return 0.0;
    }
    let (i0, i1) = (l0.exp(), l1.exp());
    let mean = if (l1 - l0).abs() > 1e-9 { (i1 - i0) / (l1 - l0) } else { 0.5 * (i0 + i1) };
    1.0 / (std::f64::consts::TAU * cutoff_hz * mean)
}

/// The photoreceptor's output `h` seconds into a step that starts at `y0` with input
/// `x0 + s·h`: the exact solution of dy/dt = (x − y)/τ for a linear input,
/// y = x0 + s·(h − τ) + (y0 − x0 + s·τ)·e^(−h/τ), written with expm1 so that a slow filter
/// (τ of seconds in a step of microseconds) keeps its precision. τ = 0 follows the input.
fn filtered(y0: f64, x0: f64, s: f64, tau: f64, h: f64) -> f64 {
    if tau <= 0.0 {
        return x0 + s * h;
    }
    y0 + (x0 - y0 - s * tau) * -(-h / tau).exp_m1() + s * h
}

/// Bisections that place a crossing within a step: 2⁻²⁴ of a step of at most 2 ms is far
/// below the timestamps' microsecond.
const CROSSING_ITERATIONS: usize = 24;

/// A pixel with physics ([`PixelModel::physics`]) from `t0` to `t1`, its log intensity moving
/// linearly to `l1`: its photoreceptor filtered exactly over the step, its reference leaking,
/// and the threshold crossings of the filtered level pushed to `events` as pixel `p`'s.
#[allow(clippy::too_many_arguments)]
fn physical_update(
    st: &mut PixelState,
    l1: f64,
    t0: f64,
    t1: f64,
    refractory: f64,
    cutoff_hz: f64,
    p: usize,
    events: &mut Crossings,
) {
    let l0 = st.level;
    if st.evaluated < t0 {
        // Skipped since: its input stayed at its level, and no crossing was due (quiet_for).
        let gap = t0 - st.evaluated;
        st.lp = filtered(st.lp, l0, 0.0, tau_over(cutoff_hz, l0, l0), gap);
        st.reference -= st.leak * gap;
    }
    let dt = (t1 - t0).max(0.0);
    let s = if dt > 0.0 { (l1 - l0) / dt } else { 0.0 };
    let tau = tau_over(cutoff_hz, l0, l1);
    let (y0, k) = (st.lp, st.leak);
    // The leak moves the reference down at k; within the step the reference is held and the
    // level raised instead, z = y + k·h, so that crossings are those of one curve.
    let z = |h: f64| filtered(y0, l0, s, tau, h) + k * h;
    // Without a filter the step ends at l1 itself, not at l0 + s·dt a rounding away: the
    // ideal pixel's comparisons, bit for bit.
    let y1 = if tau <= 0.0 { l1 } else { filtered(y0, l0, s, tau, dt) };
    let z1 = y1 + k * dt;
    let mut from = 0.0;
    while let Some((level, sign)) = st.crossing(z1) {
        let h = if tau <= 0.0 {
            // Linear: interpolated as the ideal pixel does.
            let (za, span) = (z(from), z1 - z(from));
            let frac = if span.abs() > 1e-12 { ((level - za) / span).clamp(0.0, 1.0) } else { 1.0 };
            from + frac * (dt - from)
        } else {
            // z(from) has not reached the level, z(dt) has.
            let (mut lo, mut hi) = (from, dt);
            for _ in 0..CROSSING_ITERATIONS {
                let mid = 0.5 * (lo + hi);
                if (z(mid) - level) * sign >= 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            hi
        };
        let tc = (t0 + h).max(st.last + refractory);
        if tc > t1 {
            break; // still blind: fires in a later step
        }
        events.push((p, tc, sign));
        st.reference = level;
        st.last = tc;
        from = h;
    }
    st.reference -= k * dt;
    st.level = l1;
    st.lp = y1;
    st.evaluated = t1;
}

/// How long after its last evaluation a pixel whose input stays at its level fires no event,
/// s, `most` at most: a lower bound of the time its settling filter and leaking reference
/// take to a threshold crossing, so that it can be skipped until then.
fn quiet_for(st: &PixelState, cutoff_hz: f64, most: f64) -> f64 {
    let (l, y, k) = (st.level, st.lp, st.leak);
    let tau = tau_over(cutoff_hz, l, l);
    // When the settling filter, y(h) = l + (y − l)·e^(−h/τ), first reaches v from below and
    // from above.
    let up = |v: f64| {
        if y >= v {
            0.0
        } else if v < l && tau > 0.0 {
            tau * ((l - y) / (l - v)).ln()
        } else {
            f64::INFINITY
        }
    };
    let down = |v: f64| {
        if y <= v {
            0.0
        } else if v > l && tau > 0.0 {
            tau * ((y - l) / (v - l)).ln()
        } else {
            f64::INFINITY
        }
    };
    let on_level = st.reference + st.on;
    // ON fires when y + k·h reaches on_level. y stays below max(y, l), which bounds h from
    // the leak's side; and within a horizon the leak adds at most k·horizon, which bounds it
    // from the filter's side. The leak's look-ahead is kept short so that bound stays tight.
    let on = if k > 0.0 {
        let horizon = most.min(LEAK_LOOK_S);
        ((on_level - y.max(l)) / k).max(horizon.min(up(on_level - k * horizon)))
    } else {
        up(on_level)
    };
    // The leak only delays OFF.
    let off = down(st.reference - st.off);
    most.min(on).min(off).max(0.0)
}

/// Pixels in a band of work that [`in_bands`] hands out: small enough that the threads share
/// the pixels near edges evenly (the board covers a part of the image), large enough that
/// handing out bands costs little.
const BAND_PIXELS: usize = 1024;

/// `f` of every range of `band` in `0..n` (the last one shorter), the ranges shared among the
/// threads as they come free; the results in the ranges' order, whatever the threads.
fn in_bands<T: Send>(n: usize, band: usize, f: impl Fn(std::ops::Range<usize>) -> T + Sync) -> Vec<T> {
    let band = band.max(1);
    let bands = n.div_ceil(band);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(8).min(bands);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let work = || {
        let mut out = Vec::new();
        loop {
            let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if k >= bands {
                return out;
            }
            out.push((k, f(k * band..((k + 1) * band).min(n))));
        }
    };
    let mut done = if threads > 1 {
        std::thread::scope(|s| {
            let helpers: Vec<_> = (1..threads).map(|_| s.spawn(work)).collect();
            let mut done = work();
            for h in helpers {
                done.extend(h.join().expect("simulator band panicked"));
            }
            done
        })
    } else {
        work()
    };
    done.sort_unstable_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, r)| r).collect()
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

/// The true image of every circle for a pose.
pub fn truth(cfg: &SimConfig, pose: &Pose, t_us: u64) -> FrameTruth {
    let cam = &cfg.camera;
    let (w, h) = (f64::from(cam.width), f64::from(cam.height));
    let circles = cfg
        .board
        .centres()
        .into_iter()
        .enumerate()
        .map(|(index, [cx, cy])| {
            let r = cfg.board.radius;
            let mut pts = Vec::with_capacity(OUTLINE_POINTS);
            let mut visible = true;
            for k in 0..OUTLINE_POINTS {
                let a = std::f64::consts::TAU * k as f64 / OUTLINE_POINTS as f64;
                match cam.project(&pose.apply(&Vector3::new(cx + r * a.cos(), cy + r * a.sin(), 0.0))) {
                    Some(p) => {
                        visible &= p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w - 1.0 && p[1] <= h - 1.0;
                        pts.push(p)
                    }
                    None => visible = false,
                }
            }
            let centre = polygon_centroid(&pts);
            let radius_px =
                pts.iter().map(|p| ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt()).sum::<f64>()
                    / pts.len().max(1) as f64;
            let projected_centre = cam.project(&pose.apply(&Vector3::new(cx, cy, 0.0))).unwrap_or([f64::NAN; 2]);
            CircleTruth { index, ellipse_centre: centre, projected_centre, radius_px, in_view: visible }
        })
        .collect();
    FrameTruth { t_us, rvec: pose.rvec(), tvec: pose.tvec(), circles }
}

/// Centroid of the area a closed outline encloses: for an ellipse, its centre.
fn polygon_centroid(pts: &[[f64; 2]]) -> [f64; 2] {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for k in 0..pts.len() {
        let [x0, y0] = pts[k];
        let [x1, y1] = pts[(k + 1) % pts.len()];
        let cross = x0 * y1 - x1 * y0;
        a += cross;
        cx += (x0 + x1) * cross;
        cy += (y0 + y1) * cross;
    }
    if a.abs() < 1e-12 {
        return [f64::NAN; 2];
    }
    [cx / (3.0 * a), cy / (3.0 * a)]
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn truth_ellipse_centre_is_near_projected_centre_and_in_view_is_honest() {
        let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, 1).unwrap();
        let sim = Simulator::new(cfg);
        let t = sim.truth_at(500_000);
        for c in &t.circles {
            let d = ((c.ellipse_centre[0] - c.projected_centre[0]).powi(2)
                + (c.ellipse_centre[1] - c.projected_centre[1]).powi(2))
            .sqrt();
            assert!(d < 0.3, "ellipse vs projected centre {d}");
            assert!(c.radius_px > 3.0 && c.radius_px < 15.0, "{}", c.radius_px);
        }
        assert!(t.circles.iter().filter(|c| c.in_view).count() >= 30);
    }

    /// A pixel with thresholds of 0.25 at rest at log intensity `l`, its last event long ago.
    fn pixel_at(l: f64) -> PixelState {
        PixelState {
            level: l,
            reference: l,
            on: 0.25,
            off: 0.25,
            last: f64::NEG_INFINITY,
            lp: l,
            evaluated: 0.0,
            leak: 0.0,
        }
    }

    /// The events of a pixel at rest at `from` whose light steps to `to` at time 0, followed
    /// for `seconds` in steps of `dt`, with the photoreceptor at `cutoff_hz`.
    fn step_response(from: f64, to: f64, cutoff_hz: f64, seconds: f64, dt: f64) -> Crossings {
        let mut st = pixel_at(from);
        st.level = to; // the step: the input is at `to` from the first instant
        let mut events = Vec::new();
        let mut t = 0.0;
        while t < seconds {
            physical_update(&mut st, to, t, t + dt, 100e-6, cutoff_hz, 0, &mut events);
            t += dt;
        }
        events
    }

    /// First-order filter: y = ΔL·(1 − e^(−t/τ)) reaches θ at τ·ln(ΔL / (ΔL − θ)).
    fn first_order_delay(from: f64, to: f64, cutoff_hz: f64) -> f64 {
        let tau = 1.0 / (std::f64::consts::TAU * cutoff_hz * to.exp());
        let dl = (to - from).abs();
        tau * (dl / (dl - 0.25)).ln()
    }

    #[test]
    fn a_step_of_light_fires_after_the_first_order_filter_delay_and_later_in_the_dark() {
        let mut last_delay = 0.0;
        // The same contrast (a doubling of light) at falling light levels.
        for bright in [0.8f64, 0.2, 0.05, 0.01] {
            let (from, to) = ((bright / 2.0).ln(), bright.ln());
            let expected = first_order_delay(from, to, 300.0);
            let ev = step_response(from, to, 300.0, 20.0 * expected, expected / 7.3);
            let (_, t, sign) = ev[0];
            assert_eq!(sign, 1.0);
            // The bisection places it within 2⁻²⁴ of a step.
            assert!((t - expected).abs() < 2e-8 * expected, "light {bright}: {t} s, model {expected} s");
            assert!(t > last_delay, "light {bright}: {t} s is not later than {last_delay} s");
            last_delay = t;
            // The filter settles at ΔL = ln 2: two thresholds, two events.
            assert_eq!(ev.len(), 2, "light {bright}");
        }
        // 300 Hz at light 0.8: τ = 0.66 ms and the first event after 0.30 ms; at 0.01,
        // τ = 53 ms and 24 ms.
        assert!(last_delay > 0.02, "{last_delay}");
    }

    #[test]
    fn off_edges_into_the_dark_lag_more_than_on_edges_into_the_bright() {
        let (paper, ink) = ((scene::PAPER + 0.004f64).ln(), (scene::INK + 0.004f64).ln());
        for (illumination, cutoff) in [(1.0f64, 300.0), (0.05, 300.0), (1.0, 1000.0)] {
            let (paper, ink) = (paper + illumination.ln(), ink + illumination.ln());
            let on = step_response(ink, paper, cutoff, 1.0, 1e-5);
            let off = step_response(paper, ink, cutoff, 1.0, 1e-5);
            assert!(on.iter().all(|e| e.2 > 0.0) && off.iter().all(|e| e.2 < 0.0));
            // Each edge steps ln(0.854 / 0.064) = 2.6: ten thresholds.
            assert_eq!((on.len(), off.len()), (10, 10));
            let (t_on, t_off) = (on[0].1, off[0].1);
            assert!((t_on - first_order_delay(ink, paper, cutoff)).abs() < 2e-6, "{t_on}");
            assert!((t_off - first_order_delay(paper, ink, cutoff)).abs() < 2e-6, "{t_off}");
            // The filter is as much faster as the light is brighter.
            assert!((t_off / t_on - (paper - ink).exp()).abs() < 0.05 * (paper - ink).exp(), "{t_on} {t_off}");
            // And the whole edge: its last event.
            assert!(off[9].1 > 3.0 * on[9].1, "{} {}", on[9].1, off[9].1);
        }
    }

    #[test]
    fn unlimited_bandwidth_without_leak_is_the_ideal_pixel() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (mut a, mut b) = (pixel_at(0.0), pixel_at(0.0));
        let (mut ea, mut eb) = (Vec::new(), Vec::new());
        let mut t = 0.0;
        for _ in 0..10_000 {
            let l1 = (a.level + rng.random_range(-0.3..0.3)).clamp(-4.0, 0.0);
            let dt = rng.random_range(1e-5..1e-3);
            ideal_update(&mut a, l1, t, t + dt, 100e-6, 0, &mut ea);
            physical_update(&mut b, l1, t, t + dt, 100e-6, f64::INFINITY, 0, &mut eb);
            t += dt;
        }
        assert!(ea.len() > 1000);
        // The same crossings, interpolated from the step's start or from the crossing before.
        same_times(&ea, &eb);
        assert_eq!(a.level, b.level);
        assert!((a.reference - b.reference).abs() < 1e-12);
    }

    #[test]
    fn presets_have_no_physics_and_physical_at_infinite_bandwidth_has_none_but_noise() {
        for light in [Light::Good, Light::Low] {
            assert!(!PixelModel::for_light(light).physics());
            let p = PixelModel::physical(light, f64::INFINITY);
            assert_eq!(p.photoreceptor_hz, None);
            assert!(PixelModel { leak_hz: 0.0, ..p }.cutoff_hz().is_infinite());
            assert_eq!(PixelModel::physical(light, 300.0).photoreceptor_hz, Some(300.0));
        }
    }

    /// A still pixel followed on a grid of `dt` steps, evaluated at every step or only when
    /// [`quiet_for`] says it could fire (as the simulator skips it).
    fn still_pixel(mut st: PixelState, cutoff_hz: f64, seconds: f64, dt: f64, skip: bool) -> (Crossings, usize) {
        let (mut events, mut evaluations) = (Vec::new(), 0);
        let l = st.level;
        let mut next = 0.0;
        let mut t = 0.0;
        while t < seconds {
            if !skip || next <= t + dt {
                physical_update(&mut st, l, t, t + dt, 100e-6, cutoff_hz, 0, &mut events);
                evaluations += 1;
                next = t + dt + quiet_for(&st, cutoff_hz, 10.0);
            }
            t += dt;
        }
        (events, evaluations)
    }

    fn same_times(a: &Crossings, b: &Crossings) {
        assert_eq!(a.len(), b.len(), "different numbers of events");
        for (x, y) in a.iter().zip(b) {
            assert_eq!(x.2, y.2);
            assert!((x.1 - y.1).abs() < 1e-9, "{} vs {}", x.1, y.1);
        }
    }

    #[test]
    fn leak_fires_on_events_at_its_rate_and_skipping_misses_none() {
        let mut st = pixel_at(-1.0);
        st.leak = 0.2 * st.on; // 0.2 Hz
        st.reference -= 0.1;
        let (dense, _) = still_pixel(st, 300.0, 60.0, 1e-3, false);
        let (skipped, evaluations) = still_pixel(st, 300.0, 60.0, 1e-3, true);
        assert!(dense.iter().all(|e| e.2 > 0.0));
        assert_eq!(dense.len(), 12); // the first after (0.25 − 0.1)/0.05 = 3 s, then every 5 s
        assert!((dense[0].1 - 3.0).abs() < 1e-6 && (dense[1].1 - 8.0).abs() < 1e-6, "{:?}", &dense[..2]);
        same_times(&dense, &skipped);
        assert!(evaluations < 400, "{evaluations} evaluations in 60 s");
    }

    #[test]
    fn a_settling_filter_fires_when_skipped_as_when_followed() {
        // Just past an OFF edge into ink in a dim room: the filter has far to go (τ ≈ 0.1 s).
        let mut st = pixel_at((0.05f64 * 0.06 + 0.004).ln());
        st.lp = st.level + 2.0;
        st.reference = st.lp - 0.1;
        st.leak = 0.1 * st.on;
        let (dense, _) = still_pixel(st, 300.0, 3.0, 1e-4, false);
        let (skipped, evaluations) = still_pixel(st, 300.0, 3.0, 1e-4, true);
        // (2 − 0.1) / 0.25: seven OFF events as it settles.
        assert_eq!(dense.len(), 7);
        assert!(dense.iter().all(|e| e.2 < 0.0));
        same_times(&dense, &skipped);
        assert!(evaluations < 100, "{evaluations} evaluations of 30000 steps");
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
