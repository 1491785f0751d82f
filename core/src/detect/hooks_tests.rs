//! In-place reconfiguration and the clock's window hooks.

use super::*;
use crate::window::WindowConfig;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Two rings of radius 6 that drift, plus scattered pixels: windows with circles.
fn events(n: u64, seed: u64) -> Vec<Event> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let h = rng.random::<u64>() >> 40;
            let (cx, cy) = if i % 2 == 0 { (18.0 + i as f32 / 900.0, 16.0) } else { (42.0, 26.0 + i as f32 / 1000.0) };
            let a = (h % 360) as f32 * core::f32::consts::PI / 180.0;
            let (x, y) = if h % 9 == 0 {
                ((h % 60) as f32, ((h >> 8) % 40) as f32)
            } else {
                (cx + 6.0 * a.cos(), cy + 6.0 * a.sin())
            };
            Event { t_us: i * 3, x: x.round() as u16, y: y.round() as u16, polarity: h % 2 == 0 }
        })
        .collect()
}

fn run(det: &mut Detector<256, 16>, evs: &[Event]) -> Vec<Detection<16>> {
    evs.iter().filter_map(|e| det.push(*e).cloned()).collect()
}

/// Counts the hooks and readings of a clock, checking the hooks bracket the readings.
#[derive(Default)]
struct Probe {
    begins: u32,
    ends: u32,
    readings_inside: u32,
}

impl Clock for Probe {
    fn now(&mut self) -> u32 {
        assert_eq!(self.begins, self.ends + 1, "read outside a window's processing");
        self.readings_inside += 1;
        self.readings_inside
    }
    fn window_begins(&mut self) {
        assert_eq!(self.begins, self.ends);
        self.begins += 1;
    }
    fn window_ends(&mut self) {
        self.ends += 1;
        assert_eq!(self.begins, self.ends);
    }
}

#[test]
fn hooks_bracket_each_processed_window_once() {
    let mut cfg = DetectConfig::new(SensorSize::new(64, 48));
    cfg.window = WindowConfig { events: 200, step_us: 0 };
    cfg.cluster.eps = 0.06;
    let mut det: Box<Detector<256, 16>> = Box::new(Detector::new(cfg));
    let mut probe = Probe::default();
    let mut windows = 0;
    for e in events(1000, 3) {
        if det.feed(e) {
            det.process(&mut probe);
            // a second call without a new window processes nothing
            det.process(&mut probe);
            windows += 1;
        }
    }
    assert_eq!((windows, probe.begins, probe.ends), (5, 5, 5));
    assert!(probe.readings_inside >= 10);
}

#[test]
fn reconfigure_is_the_same_as_new() {
    let mut a = DetectConfig::new(SensorSize::new(64, 48));
    a.window = WindowConfig { events: 200, step_us: 700 };
    a.cluster.eps = 0.06;
    let mut b = DetectConfig::new(SensorSize::new(60, 40));
    b.window = WindowConfig { events: 250, step_us: 0 };
    b.cluster.eps = 0.07;
    b.cluster.min_pts = 6;
    let (ea, eb) = (events(3000, 1), events(2500, 2));

    let mut reused: Box<Detector<256, 16>> = Box::new(Detector::new(a));
    let first = run(&mut reused, &ea);
    assert!(first.len() >= 5 && first.iter().any(|d| !d.centres.is_empty()), "the data make detections");
    reused.reconfigure(b);
    assert_eq!(reused.config(), b);
    assert_eq!((reused.pending(), reused.input_stats()), (0, InputStats::default()));
    let again = run(&mut reused, &eb);

    let mut fresh: Box<Detector<256, 16>> = Box::new(Detector::new(b));
    let want = run(&mut fresh, &eb);
    assert!(want.len() >= 5);
    assert_eq!(again, want);
    assert_eq!(reused.input_stats(), fresh.input_stats());
}
