//! Fuzzes the whole detection pipeline (input filter, windower, DBSCAN, joining, fits) on
//! event streams made from arbitrary bytes: nothing may panic, and every window's counts and
//! centres must be consistent with the configuration.
#![no_main]

use evcal_core::{
    cluster::ClusterConfig,
    detect::{DetectConfig, Detection, Detector},
    event::{Event, SensorSize},
    fit::{FitConfig, FitMethod},
    window::WindowConfig,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((head, body)) = data.split_first_chunk::<8>() else { return };
    // The first bytes choose the configuration, the rest are events of 6 bytes each:
    // x (u16), y (u16), time step (u8), polarity (u8); polarity bytes with bit 7 set say
    // events were lost at the source just before that event (`Detector::lost`).
    let sensor = SensorSize::new(u16::from(head[0]) * 4 + 1, u16::from(head[1]) * 3 + 1);
    let cfg = DetectConfig {
        sensor,
        window: WindowConfig { events: usize::from(head[2]) * 8 + 1, step_us: u64::from(head[3]) * 100 },
        cluster: ClusterConfig {
            eps: f32::from(head[4]) / 1024.0,
            min_pts: u16::from(head[5] % 16),
            eps_t: (head[6] & 1 == 1).then(|| f32::from(head[6]) / 255.0),
        },
        fit: FitConfig {
            method: [FitMethod::Erwls, FitMethod::Ols, FitMethod::Centroid][usize::from(head[7] % 3)],
            max_iterations: head[7] / 3 % 12,
            min_events: 1 + u16::from(head[7] % 7),
            filled_discs: head[6] & 2 == 2,
        },
    };
    let mut det: Box<Detector<2048, 32>> = Box::new(Detector::new(cfg));
    let capacity = det.config().window.events;
    let mut t = 0u64;
    for e in body.chunks_exact(6) {
        t += u64::from(e[4]);
        let ev = Event {
            t_us: t,
            x: u16::from_le_bytes([e[0], e[1]]) % (sensor.width + 8),
            y: u16::from_le_bytes([e[2], e[3]]) % (sensor.height + 8),
            polarity: e[5] & 1 == 1,
        };
        if e[5] & 0x80 != 0 {
            det.lost();
        }
        if let Some(d) = det.push(ev) {
            check(d, capacity);
        }
    }
    while let Some(d) = det.end() {
        check(d, capacity);
    }
});

fn check(d: &Detection<32>, capacity: usize) {
    assert!(usize::from(d.stats.events) <= capacity);
    assert!(d.info.t_first_us <= d.info.t_ref_us && d.info.t_ref_us <= d.info.t_last_us);
    for c in &d.centres {
        assert!(c.u.is_finite() && c.v.is_finite() && c.r > 0.0 && c.spread.is_finite());
    }
}
