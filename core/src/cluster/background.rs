//! The background a window's edges stand on: events that belong to no edge (a pixel's leak
//! and shot noise, which grow as the light falls), counted so that DBSCAN's threshold can
//! stay above them.
//!
//! `min_pts` is a density: a point is a core point when its neighbourhood holds that many
//! events. The paper's 10 assumes a clean window. A dim room's pixels fire shot noise all
//! over the sensor, and every neighbourhood, on an edge, in the gap between two circles or on
//! the bare wall, gains the background's count on top of its own. Neighbourhoods between
//! circles then reach the threshold, circles join each other and the noise, and their fits
//! fail (measured on the simulator's dim-room cone, 8000-event windows: the grid found in 103
//! of 240 windows at `min_pts` 10, in 231 at 14). Raising the threshold by what the
//! background adds keeps it on the edges' own density: by the background's expected count in
//! a neighbourhood plus [`BACKGROUND_Z`] of its standard deviations (Poisson: its square
//! root). A clean window's background is zero and its threshold the configured one.
//!
//! The background is the lower quartile of the counts of a [`BACKGROUND_CELLS`] grid over the
//! sensor: a board held close may put edges in most cells (the median read a background on
//! the simulator's clean cone in 10 of 240 windows), the quartile passes over any that fill
//! fewer than three quarters of them. A Poisson count's lower quartile lies some two thirds
//! of its standard deviation below its mean, so the background reads a little low and the
//! threshold errs towards the configured one. It is a count of this window alone: no
//! window's result depends on another's.

use crate::event::SensorSize;
use crate::window::WindowEvent;

/// Cells across and down the sensor in which the background is counted (768 cells, whatever
/// the sensor: some 11 px square on a DAVIS346, 20 on a DVXplorer).
pub const BACKGROUND_CELLS: [usize; 2] = [32, 24];

/// Standard deviations of the background's count added to `min_pts` above its mean: two
/// leave a neighbourhood of background alone at the edge's threshold about one time in forty.
pub const BACKGROUND_Z: f64 = 2.0;

/// Expected events of the background in one neighbourhood of radius `eps` (normalised, as
/// [`ClusterConfig::eps`](super::ClusterConfig::eps)): the lower quartile of the events per
/// cell of the [`BACKGROUND_CELLS`] grid, times the neighbourhood's share of a cell (an ellipse of
/// semi-axes `eps·W`, `eps·H`: `π·eps²` of the sensor). `cells` is scratch (its first 768
/// cells are overwritten). 0 for a sensor of no size or an `eps` that is not positive.
pub fn background_per_neighbourhood<const CELLS: usize>(
    events: &[WindowEvent],
    sensor: SensorSize,
    eps: f32,
    cells: &mut [u16; CELLS],
) -> f64 {
    let [nx, ny] = BACKGROUND_CELLS;
    let (w, h) = (u32::from(sensor.width), u32::from(sensor.height));
    if w == 0 || h == 0 || !(eps.is_finite() && eps > 0.0) {
        return 0.0;
    }
    // Scratch too small for the counts counts no background (never for the detector's).
    let Some((counts, rest)) = cells.split_at_mut_checked(COUNT_SLOTS) else { return 0.0 };
    let Some((histogram, luts)) = rest.split_at_mut_checked(HISTOGRAM_BINS) else { return 0.0 };
    counts.fill(0);
    let (wu, hu) = (w as usize, h as usize);
    // Each column's and row's share of a cell's index, `⌊x·32/W⌋` and `32·⌊y·24/H⌋`, looked
    // up in tables as long as the next power of two at or above the sensor's larger side: an
    // event's cell is then two masked loads and an add, no compare (this pass runs on every
    // event of every window on the device). Columns and rows off the sensor index the cell
    // `OFF`, past the grid, not counted; events beyond the tables wrap into them (the
    // detector's input filter keeps events off the sensor out). Sensors too large for the
    // tables compute each event's cell.
    let side = wu.max(hu).next_power_of_two();
    if let Some((col, rest)) = luts.split_at_mut_checked(side) {
        if let Some((row, _)) = rest.split_at_mut_checked(side) {
            let mask = side - 1;
            for (x, c) in col.iter_mut().enumerate() {
                *c = if x < wu { (x * nx / wu) as u16 } else { OFF as u16 };
            }
            for (y, r) in row.iter_mut().enumerate() {
                *r = if y < hu { (y * ny / hu * nx) as u16 } else { OFF as u16 };
            }
            for e in events {
                let k = usize::from(col[usize::from(e.x) & mask] + row[usize::from(e.y) & mask]);
                counts[k & (COUNT_SLOTS - 1)] = counts[k & (COUNT_SLOTS - 1)].wrapping_add(1);
            }
        }
    }
    if 2 * side > luts.len() {
        for e in events {
            let (x, y) = (usize::from(e.x), usize::from(e.y));
            if x < wu && y < hu {
                let k = &mut counts[(y * ny / hu * nx + x * nx / wu) & (COUNT_SLOTS - 1)];
                *k = k.wrapping_add(1);
            }
        }
    }
    let counts = &counts[..nx * ny];
    // The lower quartile by a histogram of the counts (cheaper than a selection); counts
    // beyond its last bin read as that bin, a background no window of sensible size reaches.
    histogram.fill(0);
    for &c in counts.iter() {
        histogram[usize::from(c).min(HISTOGRAM_BINS - 1)] += 1;
    }
    let mut below = 0;
    let mut quartile = HISTOGRAM_BINS - 1;
    for (count, &cells) in histogram.iter().enumerate() {
        below += usize::from(cells);
        if below > nx * ny / 4 {
            quartile = count;
            break;
        }
    }
    let eps = f64::from(eps);
    quartile as f64 * core::f64::consts::PI * eps * eps * (nx * ny) as f64
}

/// The index of the cell of columns and rows off the sensor, past the grid.
const OFF: usize = BACKGROUND_CELLS[0] * BACKGROUND_CELLS[1];

/// Cells counted, a power of two above any index two table entries add up to (`2·OFF`), so
/// that a mask keeps every index in range.
const COUNT_SLOTS: usize = 2048;

/// Bins of the histogram of cell counts: cells with more events read as the last bin's (a
/// background of 63 events per cell is some 34 in a neighbourhood of a DAVIS346's 0.015).
const HISTOGRAM_BINS: usize = 64;

/// The core-point threshold over a background of `mean` expected events per neighbourhood:
/// `min_pts + ⌈mean + Z·√mean⌉` (saturating), `min_pts` itself for no background.
pub fn min_pts_above_background(min_pts: u16, mean: f64) -> u16 {
    if !(mean.is_finite() && mean > 0.0) {
        return min_pts;
    }
    // Float-to-integer casts saturate: no overflow for any mean.
    let extra = libm::ceil(mean + BACKGROUND_Z * libm::sqrt(mean)) as u16;
    min_pts.saturating_add(extra)
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::cluster::TABLE_CELLS;

    /// A linear congruential generator: the tests' noise, the same everywhere.
    fn lcg(s: &mut u64) -> u32 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*s >> 33) as u32
    }

    fn uniform(n: usize, sensor: SensorSize, seed: u64) -> impl Iterator<Item = WindowEvent> {
        let mut s = seed;
        (0..n).map(move |i| WindowEvent {
            x: (lcg(&mut s) % u32::from(sensor.width)) as u16,
            y: (lcg(&mut s) % u32::from(sensor.height)) as u16,
            dt_us: i as u32,
        })
    }

    #[test]
    fn uniform_noise_is_counted_at_its_density() {
        let sensor = SensorSize::new(346, 260);
        let mut cells = [0u16; TABLE_CELLS];
        for n in [1536usize, 3072, 6144] {
            let events: heapless::Vec<WindowEvent, 6144> = uniform(n, sensor, 7).collect();
            let got = background_per_neighbourhood(&events, sensor, 0.015, &mut cells);
            let want = n as f64 * core::f64::consts::PI * 0.015 * 0.015;
            // Per cell: the lower quartile of a Poisson count of mean λ lies about 0.67·√λ
            // below λ (an integer, so up to one lower still), never above it.
            let scale = core::f64::consts::PI * 0.015 * 0.015 * 768.0;
            let lambda = n as f64 / 768.0;
            let low = (lambda - 0.67 * libm::sqrt(lambda) - 1.0) * scale;
            assert!(got <= want && got >= low, "{n}: {got} vs {want} (at least {low})");
        }
    }

    #[test]
    fn a_sensor_too_large_for_the_tables_is_counted_alike() {
        // 4096 columns: the tables would need 2·4096 cells; each event's cell is computed.
        let mut cells = [0u16; TABLE_CELLS];
        for sensor in [SensorSize::new(4096, 3072), SensorSize::new(2048, 1536)] {
            let n = 6144;
            let events: heapless::Vec<WindowEvent, 6144> = uniform(n, sensor, 3).collect();
            let got = background_per_neighbourhood(&events, sensor, 0.015, &mut cells);
            let want = n as f64 * core::f64::consts::PI * 0.015 * 0.015;
            let (scale, lambda) = (core::f64::consts::PI * 0.015 * 0.015 * 768.0, n as f64 / 768.0);
            let low = (lambda - 0.67 * libm::sqrt(lambda) - 1.0) * scale;
            assert!(got <= want && got >= low, "{sensor:?}: {got} vs {want} (at least {low})");
        }
    }

    #[test]
    fn edges_on_a_clean_sensor_are_no_background() {
        // 40 rings of 100 events each, 8 px across, in a 8x5 lattice: a clean window.
        let sensor = SensorSize::new(346, 260);
        let mut events: heapless::Vec<WindowEvent, 4000> = heapless::Vec::new();
        for k in 0..40u16 {
            let (cx, cy) = (30 + 40 * (k % 8), 30 + 45 * (k / 8));
            for a in 0..100u16 {
                let t = f32::from(a) * core::f32::consts::TAU / 100.0;
                let x = (f32::from(cx) + 4.0 * libm::cosf(t)) as u16;
                let y = (f32::from(cy) + 4.0 * libm::sinf(t)) as u16;
                let _ = events.push(WindowEvent { x, y, dt_us: u32::from(a) });
            }
        }
        let mut cells = [0u16; TABLE_CELLS];
        let mean = background_per_neighbourhood(&events, sensor, 0.015, &mut cells);
        assert_eq!(mean, 0.0);
        assert_eq!(min_pts_above_background(10, mean), 10);
    }

    #[test]
    fn the_threshold_rises_by_the_mean_and_two_deviations() {
        assert_eq!(min_pts_above_background(10, 0.0), 10);
        assert_eq!(min_pts_above_background(10, 1.0), 13);
        assert_eq!(min_pts_above_background(10, 4.0), 18);
        assert_eq!(min_pts_above_background(10, f64::NAN), 10);
        assert_eq!(min_pts_above_background(10, f64::INFINITY), 10);
        assert_eq!(min_pts_above_background(10, 1e300), u16::MAX);
    }

    #[test]
    fn any_input_is_counted_without_panic() {
        let mut cells = [0u16; TABLE_CELLS];
        let wild = [WindowEvent { x: u16::MAX, y: u16::MAX, dt_us: 0 }, WindowEvent { x: 0, y: 0, dt_us: u32::MAX }];
        for sensor in [SensorSize::new(0, 0), SensorSize::new(1, 1), SensorSize::new(346, 260)] {
            for eps in [0.015, 0.0, -1.0, f32::NAN, f32::INFINITY, 1e30] {
                let m = background_per_neighbourhood(&wild, sensor, eps, &mut cells);
                let _ = min_pts_above_background(10, m);
            }
        }
    }
}
