//! Time per 4000-event window through the detection core, per stage, on simulated windows:
//! DAVIS346 with a 4x11 grid (cone motion, good and low light) and DVXplorer with a 3x9 grid
//! (spiral motion, good light).
//!
//! Criterion times DBSCAN alone and the whole window (DBSCAN, joining crescents, fitting);
//! the split between clustering (DBSCAN and joining) and fitting is then read off the
//! detector's own stage clock over every window, and printed.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use evcal_core::{
    cluster::{Clusterer, TABLE_CELLS},
    config::{MAX_CLUSTERS, MAX_EVENTS_PER_WINDOW},
    detect::{process, Clock, DetectConfig, Detection, Scratch},
    event::SensorSize,
    window::{WindowEvent, WindowInfo, Windower},
};
use evcal_host::{
    eval::simulate,
    sim::{Light, SimConfig, Trajectory},
};

type Cl = Clusterer<MAX_EVENTS_PER_WINDOW, MAX_CLUSTERS>;

/// Nanoseconds since a start, for the detector's stage clock.
struct Nanos(std::time::Instant);

impl Clock for Nanos {
    fn now(&mut self) -> u32 {
        self.0.elapsed().as_nanos() as u32
    }
}

fn windows(
    sensor: &str,
    pattern: &str,
    traj: Trajectory,
    light: Light,
) -> (DetectConfig, Vec<(WindowInfo, Vec<WindowEvent>)>) {
    let cfg = SimConfig::preset(sensor, pattern, traj, light, 3).unwrap();
    let det = DetectConfig::new(SensorSize { width: cfg.camera.width, height: cfg.camera.height });
    let (events, _) = simulate(cfg, 0.7);
    let mut w: Box<Windower<MAX_EVENTS_PER_WINDOW>> = Box::new(Windower::new(det.window));
    let mut out = Vec::new();
    for e in events {
        if let Some(info) = w.push(e) {
            out.push((info, w.events().to_vec()));
        }
    }
    (det, out)
}

fn bench(c: &mut Criterion) {
    let cases = [
        ("davis346-4x11-good", "davis346", "4x11", Trajectory::Cone, Light::Good),
        ("davis346-4x11-low", "davis346", "4x11", Trajectory::Cone, Light::Low),
        ("dvxplorer-3x9-good", "dvxplorer", "3x9", Trajectory::Spiral, Light::Good),
    ];
    let mut splits = Vec::new();
    for (name, sensor, pattern, traj, light) in cases {
        let (det, wins) = windows(sensor, pattern, traj, light);
        let mut clusterer: Box<Cl> = Box::new(Clusterer::new());
        let mut scratch: Box<Scratch> = Box::default();
        let mut scratch_tables: Box<[u16; TABLE_CELLS]> = Box::new([0; TABLE_CELLS]);
        let mut out: Detection<MAX_CLUSTERS> =
            Detection { info: wins[0].0, stats: Default::default(), centres: heapless::Vec::new() };
        let mut k = 0usize;
        let mut next = || {
            k = (k + 1) % wins.len();
            wins[k].clone()
        };
        c.bench_function(&format!("{name}/dbscan per window"), |b| {
            b.iter_batched_ref(
                &mut next,
                |(_, ev)| clusterer.cluster(ev, det.sensor, &det.cluster, &mut scratch_tables).clusters,
                BatchSize::SmallInput,
            )
        });
        c.bench_function(&format!("{name}/total per window"), |b| {
            b.iter_batched_ref(
                &mut next,
                |(info, ev)| {
                    out.info = *info;
                    process(&mut clusterer, &mut scratch, ev, &det, &mut out, &mut ());
                    out.centres.len()
                },
                BatchSize::SmallInput,
            )
        });
        // The stage split, from the detector's clock over every window, best of three runs.
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for _ in 0..3 {
            let (mut cl, mut fit) = (0u64, 0u64);
            for (info, ev) in &wins {
                let mut ev = ev.clone();
                out.info = *info;
                process(&mut clusterer, &mut scratch, &mut ev, &det, &mut out, &mut Nanos(std::time::Instant::now()));
                cl += u64::from(out.stats.cluster_ticks);
                fit += u64::from(out.stats.fit_ticks);
            }
            let n = wins.len() as f64;
            let (cl, fit) = (cl as f64 / n / 1e3, fit as f64 / n / 1e3);
            if cl + fit < best.0 {
                best = (cl + fit, cl, fit);
            }
        }
        splits.push((name, best));
    }
    println!("\nstage split per 4000-event window (detector clock, mean over the windows, best of 3):");
    for (name, (total, cl, fit)) in splits {
        println!("  {name:20} clustering (DBSCAN + joining) {cl:7.1} µs   fitting {fit:7.1} µs   total {total:7.1} µs");
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
