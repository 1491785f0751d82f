//! The `evcal` command and the host library's readers, end to end: one test binary, since
//! each links HDF5 and the command (a binary per file cost CI a link each).
//!
//! The slow tier (`bash scripts/test-slow.sh`, docs/testing.md) runs the tests ignored here
//! under a `slow` module; CI runs a smoke case of each.

mod closed_stdout;
mod faery_aedat4;
mod filled_discs_fallback;
mod formats;
mod golden_detect;
mod hostile_input;
mod info_cli;
mod projection_sigma;
mod read_options;
mod report_frames;
mod target;
mod verdict;

/// Detections as a perfect detector would give them: the true circle centres of 3 s of a
/// simulated DAVIS346 cone (90 windows, 33 ms apart; no event simulated), as JSON lines.
fn true_centre_detections() -> String {
    use evcal_host::input::detections::{CenterRecord, WindowRecord};
    use evcal_host::sim::{Light, SimConfig, Simulator, Trajectory};
    let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, Light::Good, 1).unwrap();
    let sim = Simulator::new(cfg);
    let lines: Vec<String> = (0..90u32)
        .map(|seq| {
            let t_ref_us = 20_000 + u64::from(seq) * 33_333;
            let centers = sim
                .truth_at(t_ref_us)
                .circles
                .iter()
                .filter(|c| c.in_view)
                .map(|c| CenterRecord {
                    u: c.ellipse_centre[0] as f32,
                    v: c.ellipse_centre[1] as f32,
                    r: c.radius_px as f32,
                    spread: 0.1,
                    n: 60,
                    converged: true,
                })
                .collect();
            WindowRecord { seq, t_ref_us, events: 4000, noise: 100, centers, sensor: None }.to_json_line()
        })
        .collect();
    lines.join("\n") + "\n"
}
