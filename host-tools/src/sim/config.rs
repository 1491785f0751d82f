//! Everything a simulation depends on: the camera, the board, the motion, the light and the
//! pixels' model, and the seed.

use super::{Board, Camera, RecordedMotion, Trajectory};
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
    pub(super) fn cutoff_hz(&self) -> f64 {
        match self.photoreceptor_hz {
            Some(f) if f.is_finite() => f.max(1e-6),
            _ => f64::INFINITY,
        }
    }

    /// Whether each pixel's update needs the physics (a finite photoreceptor or leak): if
    /// not, the simpler update of an ideal pixel runs, giving the presets' events bit for bit.
    pub(super) fn physics(&self) -> bool {
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
    /// Typical distance from camera to board, metres; the lens is focused there.
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
    /// A recorded motion the camera follows instead of [`trajectory`](Self::trajectory)
    /// ([`RecordedMotion`]); `None` for the trajectory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recorded_motion: Option<RecordedMotion>,
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
            recorded_motion: None,
        })
    }
}

/// Fraction of the sensor's width (of a 4:3 sensor's width for a wider one) the grid spans at
/// the typical distance.
const FILL: f64 = 0.7;

#[cfg(test)]
mod test {
    use super::*;

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
}
