//! Time per 4000-event window through the detection core, per stage, on simulated windows
//! (DAVIS346, 4x11 grid, cone motion, good and low light).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use evcal_core::{
    cluster::Clusterer,
    config::{MAX_CLUSTERS, MAX_EVENTS_PER_WINDOW},
    detect::{process, DetectConfig, Detection},
    event::SensorSize,
    fit::fit,
    window::{WindowEvent, WindowInfo, Windower},
};
use evcal_host::{
    eval::simulate,
    sim::{Light, SimConfig, Trajectory},
};

/// A window's events grouped by cluster, and the clusters' ranges.
type Prepared = (Vec<WindowEvent>, Vec<(usize, usize)>);

type Cl = Clusterer<MAX_EVENTS_PER_WINDOW, MAX_CLUSTERS>;

fn windows(light: Light) -> (DetectConfig, Vec<Vec<WindowEvent>>) {
    let cfg = SimConfig::preset("davis346", "4x11", Trajectory::Cone, light, 3).unwrap();
    let det = DetectConfig::new(SensorSize { width: cfg.camera.width, height: cfg.camera.height });
    let (events, _) = simulate(cfg, 0.7);
    let mut w: Box<Windower<MAX_EVENTS_PER_WINDOW>> = Box::new(Windower::new(det.window));
    let mut out = Vec::new();
    for e in events {
        if w.push(e).is_some() {
            out.push(w.events().to_vec());
        }
    }
    (det, out)
}

fn bench(c: &mut Criterion) {
    for light in [Light::Good, Light::Low] {
        let (det, wins) = windows(light);
        let mut clusterer: Box<Cl> = Box::new(Clusterer::new());
        let mut k = 0usize;
        let mut next = || {
            k = (k + 1) % wins.len();
            wins[k].clone()
        };
        let name = light.name();
        c.bench_function(&format!("{name}/cluster+group per window"), |b| {
            b.iter_batched_ref(
                &mut next,
                |ev| {
                    clusterer.cluster(ev, det.sensor, &det.cluster);
                    clusterer.group(ev).len()
                },
                BatchSize::SmallInput,
            )
        });
        // Fit alone: clusters prepared once per window.
        let prepared: Vec<Prepared> = wins
            .iter()
            .map(|w| {
                let mut ev = w.clone();
                clusterer.cluster(&mut ev, det.sensor, &det.cluster);
                let r = clusterer.group(&mut ev).iter().map(|r| (usize::from(r.start), usize::from(r.end))).collect();
                (ev, r)
            })
            .collect();
        let mut j = 0usize;
        c.bench_function(&format!("{name}/fit all clusters per window"), |b| {
            b.iter(|| {
                j = (j + 1) % prepared.len();
                let (ev, ranges) = &prepared[j];
                ranges.iter().filter_map(|&(s, e)| fit(&ev[s..e], 0, &det.fit)).count()
            })
        });
        let mut out: Detection<MAX_CLUSTERS> = Detection {
            info: WindowInfo { seq: 0, t_first_us: 0, t_ref_us: 0, t_last_us: 0, ticks_skipped: 0 },
            stats: Default::default(),
            centres: heapless::Vec::new(),
        };
        c.bench_function(&format!("{name}/total per window"), |b| {
            b.iter_batched_ref(
                &mut next,
                |ev| process(&mut clusterer, ev, &det, &mut out, &mut ()),
                BatchSize::SmallInput,
            )
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
