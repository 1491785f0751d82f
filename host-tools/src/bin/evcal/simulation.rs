//! Simulating with a progress bar, for `evcal simulate` and `evcal demo`.

use crate::{common::progress_bar, ranges};
use anyhow::Result;
use evcal_core::{event::Event, window::WindowConfig};
use evcal_host::sim::{SimConfig, Simulator};

/// Simulates with a progress bar, handing `sink` the events in order, batch by batch (they are
/// not kept: memory does not grow with them); the number of events, and the simulator.
pub fn run_simulation(
    cfg: SimConfig,
    seconds: f64,
    quiet: bool,
    bytes_per_event: f64,
    mut sink: impl FnMut(&[Event]) -> Result<()>,
) -> Result<(u64, Simulator)> {
    ranges::SIM_SECONDS.check(seconds).map_err(|e| anyhow::anyhow!("--seconds {}: {e}", ranges::number(seconds)))?;
    let mut sim = Simulator::new(cfg);
    let pb = progress_bar((seconds * 1000.0) as u64, quiet, "simulating");
    let (mut n, mut failed) = (0u64, None);
    let mut t = 0.0;
    let started = std::time::Instant::now();
    let mut estimated = quiet || seconds <= ESTIMATE_AFTER_S;
    while t < seconds {
        t = (t + 0.05).min(seconds);
        // In pieces for the progress bar; the same events, in order, as in one go.
        sim.run_part(t, seconds, |b| {
            if failed.is_none() {
                n += b.len() as u64;
                failed = sink(b).err();
            }
        });
        if let Some(e) = failed {
            pb.finish_and_clear();
            return Err(e);
        }
        pb.set_position((t * 1000.0) as u64);
        pb.set_prefix(format!("{n} events"));
        if !estimated && t >= ESTIMATE_AFTER_S {
            estimated = true;
            let scale = seconds / t;
            let (events, wall) = (n as f64 * scale, started.elapsed().as_secs_f64() * scale);
            pb.suspend(|| {
                eprintln!(
                    "evcal: at the rate of the first {t:.2} s: about {:.1} M events, {:.0} MB, about {:.0} s to simulate (Ctrl-C stops)",
                    events * 1e-6,
                    events * bytes_per_event * 1e-6,
                    wall
                )
            });
        }
    }
    pb.finish_and_clear();
    Ok((n, sim))
}

/// Simulated seconds after which [`run_simulation`] says how many events, bytes and seconds
/// the whole run will take: a tenth of the cone's motion, and nothing to say of shorter runs.
const ESTIMATE_AFTER_S: f64 = 0.5;

/// Simulates only what the windows of `window` need ([`evcal_host::eval::simulate_windows`]),
/// with a progress bar.
pub fn run_windowed_simulation(
    cfg: SimConfig,
    seconds: f64,
    window: WindowConfig,
    quiet: bool,
) -> Result<(Vec<Event>, Simulator)> {
    ranges::SIM_SECONDS.check(seconds).map_err(|e| anyhow::anyhow!("--seconds {}: {e}", ranges::number(seconds)))?;
    let pb = progress_bar((seconds * 1000.0) as u64, quiet, "simulating");
    let out = evcal_host::eval::simulate_windows(cfg, seconds, window, |t| pb.set_position((t * 1000.0) as u64));
    pb.finish_and_clear();
    Ok(out)
}
