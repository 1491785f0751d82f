//! DBSCAN against a textbook reference, and the clusterer's API.

use super::{tables::Tables, *};
use crate::{event::SensorSize, window::WindowEvent};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::vec::Vec;

/// Textbook DBSCAN, O(n^2), breadth-first expansion: the reference the hashed version
/// must equal. Same conventions: core when |N_eps| (self included) >= min_pts; border
/// points join the lowest-index core neighbour's cluster; clusters numbered by their
/// lowest-index core point.
fn brute_force(events: &[WindowEvent], sensor: SensorSize, cfg: &ClusterConfig) -> Vec<u16> {
    let n = events.len();
    let duration = events.iter().map(|e| e.dt_us).max().unwrap_or(0);
    let metric = Metric::new(sensor, cfg, duration);
    let near = |a: &WindowEvent, b: &WindowEvent| metric.neighbours(a, b);
    let core: Vec<bool> =
        (0..n).map(|i| (0..n).filter(|&j| near(&events[i], &events[j])).count() >= cfg.min_pts as usize).collect();
    let mut comp = vec![u16::MAX; n];
    let mut next = 0u16;
    for i in 0..n {
        if !core[i] || comp[i] != u16::MAX {
            continue;
        }
        let mut queue = std::collections::VecDeque::from([i]);
        comp[i] = next;
        while let Some(p) = queue.pop_front() {
            for q in 0..n {
                if core[q] && comp[q] == u16::MAX && near(&events[p], &events[q]) {
                    comp[q] = next;
                    queue.push_back(q);
                }
            }
        }
        next += 1;
    }
    (0..n)
        .map(|i| {
            if core[i] {
                comp[i]
            } else {
                (0..n).find(|&j| core[j] && near(&events[i], &events[j])).map_or(NOISE, |j| comp[j])
            }
        })
        .collect()
}

fn ring(cx: f32, cy: f32, r: f32, k: usize, t0: u32, seed: u32) -> Vec<WindowEvent> {
    let mut rng = ChaCha8Rng::seed_from_u64(u64::from(seed));
    (0..k)
        .map(|i| {
            let a = i as f32 * 0.37 + rng.random_range(0.0..1.6f32);
            WindowEvent {
                x: (cx + r * libm::cosf(a)).round() as u16,
                y: (cy + r * libm::sinf(a)).round() as u16,
                dt_us: t0 + i as u32 * 7,
            }
        })
        .collect()
}

fn check_equal<const N: usize, const C: usize>(
    input: &[WindowEvent],
    sensor: SensorSize,
    cfg: &ClusterConfig,
) -> ClusterStats {
    let mut events = input.to_vec();
    let mut c: Clusterer<N, C> = Clusterer::new();
    let stats = c.cluster(&mut events, sensor, cfg, &mut [0; TABLE_CELLS]);
    // Reordering is a permutation of the input.
    let mut a = input.to_vec();
    let mut b = events.clone();
    let key = |e: &WindowEvent| (e.x, e.y, e.dt_us);
    a.sort_by_key(key);
    b.sort_by_key(key);
    assert_eq!(a, b);
    let reference = brute_force(&events, sensor, cfg);
    let got: Vec<u16> = c.labels().to_vec();
    let clamp = |l: u16| if l != NOISE && usize::from(l) >= C { DROPPED } else { l };
    let reference: Vec<u16> = reference.into_iter().map(clamp).collect();
    assert_eq!(got, reference);
    stats
}

#[test]
fn two_rings_and_noise() {
    let sensor = SensorSize::DAVIS346;
    let mut ev = ring(50.0, 60.0, 6.0, 80, 0, 1);
    ev.extend(ring(150.0, 60.0, 6.0, 80, 3, 2));
    ev.extend([WindowEvent { x: 300, y: 200, dt_us: 9 }, WindowEvent { x: 5, y: 250, dt_us: 11 }]);
    let stats = check_equal::<256, 8>(&ev, sensor, &ClusterConfig::default());
    assert_eq!((stats.clusters, stats.noise, stats.dropped_clusters), (2, 2, 0));
}

#[test]
fn capacity_overflow_is_counted() {
    let sensor = SensorSize::DAVIS346;
    let mut ev = Vec::new();
    for k in 0..5u16 {
        // a dense 5 x 8 blob: one cluster each
        ev.extend((0..40u16).map(|i| WindowEvent { x: 30 + 60 * k + i % 5, y: 100 + i / 5, dt_us: u32::from(i) }));
    }
    let stats = check_equal::<512, 3>(&ev, sensor, &ClusterConfig::default());
    assert_eq!((stats.clusters, stats.dropped_clusters), (3, 2));

    let mut small = ev.clone();
    let mut c: Clusterer<100, 8> = Clusterer::new();
    let s = c.cluster(&mut small, sensor, &ClusterConfig::default(), &mut [0; TABLE_CELLS]);
    assert_eq!((s.events, s.overflow), (100, 100));
}

#[test]
fn spatio_temporal_splits_in_time() {
    let sensor = SensorSize::DAVIS346;
    // The same place visited early and late in the window: one cluster in space, two in
    // space-time.
    let mut ev = ring(100.0, 100.0, 5.0, 60, 0, 3);
    ev.extend(ring(100.0, 100.0, 5.0, 60, 30_000, 4));
    let plain = check_equal::<256, 8>(&ev, sensor, &ClusterConfig::default());
    assert_eq!(plain.clusters, 1);
    let st = ClusterConfig { eps_t: Some(0.1), ..Default::default() };
    let split = check_equal::<256, 8>(&ev, sensor, &st);
    assert_eq!(split.clusters, 2);
}

#[test]
fn default_neighbourhood_on_a_davis346_takes_the_tables() {
    let m = Metric::new(SensorSize::DAVIS346, &ClusterConfig::default(), 1000);
    let mut cells = [0u16; TABLE_CELLS];
    let reach = m.reach_y as usize;
    assert!(Tables::new(&mut cells, reach, 0, 346, m.span(0) as usize, 259).is_some());
}

/// A 640x480 sensor's neighbourhoods (7 rows either side) need some 14 500 cells of tables:
/// in the default scratch the sweep walks cursors along the rows, in a larger one it takes
/// the tables; both give exactly the labels of textbook DBSCAN, and the tables far fewer
/// queries.
#[test]
fn larger_scratch_takes_the_tables_on_a_wide_sensor_to_the_same_result() {
    let sensor = SensorSize::DVXPLORER;
    let mut ev = Vec::new();
    for (k, (cx, cy)) in [(60.0, 50.0), (320.0, 240.0), (600.0, 430.0), (330.0, 250.0)].iter().enumerate() {
        ev.extend(ring(*cx, *cy, 9.0, 120, 0, k as u32 + 1));
    }
    ev.extend((0..200u32).map(|i| WindowEvent { x: (i * 37 % 640) as u16, y: (i * 53 % 480) as u16, dt_us: i }));
    ev.sort_by_key(|e| e.dt_us);
    let cfg = ClusterConfig::default();
    let m = Metric::new(sensor, &cfg, 1000);
    let reach = m.reach_y as usize;
    let (mut small, mut large) = ([0u16; TABLE_CELLS], [0u16; MAX_TABLE_CELLS]);
    assert!(Tables::new(&mut small, reach, 0, 640, m.span(0) as usize, 479).is_none());
    assert!(Tables::new(&mut large, reach, 0, 640, m.span(0) as usize, 479).is_some());
    let mut runs = Vec::new();
    for big in [false, true] {
        let mut events = ev.clone();
        let mut c: Clusterer<1024, 16> = Clusterer::new();
        let stats = if big {
            c.cluster(&mut events, sensor, &cfg, &mut [0u16; MAX_TABLE_CELLS])
        } else {
            c.cluster(&mut events, sensor, &cfg, &mut [0u16; TABLE_CELLS])
        };
        assert_eq!(c.labels(), &brute_force(&events, sensor, &cfg)[..], "tables {big}");
        runs.push((stats, events, c.labels().to_vec()));
    }
    assert_eq!((runs[0].1.clone(), runs[0].2.clone()), (runs[1].1.clone(), runs[1].2.clone()));
    let (cursors, tables) = (runs[0].0, runs[1].0);
    assert_eq!(ClusterStats { distance_checks: 0, ..cursors }, ClusterStats { distance_checks: 0, ..tables });
    assert!(tables.clusters >= 3, "{tables:?}");
    assert!(tables.distance_checks < cursors.distance_checks, "tables {tables:?}, cursors {cursors:?}");
}

#[test]
fn group_makes_clusters_contiguous() {
    let sensor = SensorSize::DAVIS346;
    let mut ev = ring(50.0, 60.0, 6.0, 70, 0, 5);
    ev.extend(ring(150.0, 160.0, 8.0, 90, 0, 6));
    ev.extend(ring(250.0, 60.0, 4.0, 50, 0, 7));
    ev.push(WindowEvent { x: 340, y: 5, dt_us: 0 });
    let mut c: Clusterer<512, 8> = Clusterer::new();
    let stats = c.cluster(&mut ev, sensor, &ClusterConfig::default(), &mut [0; TABLE_CELLS]);
    let labels_before: Vec<u16> = c.labels().to_vec();
    let ranges = c.group(&mut ev).to_vec();
    assert_eq!(ranges.len(), usize::from(stats.clusters));
    let mut covered = 0;
    for (k, r) in ranges.iter().enumerate() {
        for l in &c.labels()[usize::from(r.start)..usize::from(r.end)] {
            assert_eq!(usize::from(*l), k);
        }
        covered += r.end - r.start;
    }
    for l in &c.labels()[usize::from(covered)..] {
        assert!(*l == NOISE || *l == DROPPED);
    }
    let mut a = labels_before.clone();
    let mut b = c.labels().to_vec();
    a.sort();
    b.sort();
    assert_eq!(a, b, "grouping is a permutation");
}

fn arb_events(max_len: usize, w: u16, h: u16) -> impl Strategy<Value = Vec<WindowEvent>> {
    // Clumps around a few centres so that clusters, borders and noise all occur.
    let centres = prop::collection::vec((0..w, 0..h), 1..6);
    (centres, prop::collection::vec((any::<u8>(), -9i16..=9, -9i16..=9, 0u32..40_000), 0..max_len)).prop_map(
        move |(cs, pts)| {
            pts.into_iter()
                .map(|(k, dx, dy, t)| {
                    let (cx, cy) = cs[usize::from(k) % cs.len()];
                    WindowEvent {
                        x: (cx as i32 + dx as i32).clamp(0, w as i32 - 1) as u16,
                        y: (cy as i32 + dy as i32).clamp(0, h as i32 - 1) as u16,
                        dt_us: t,
                    }
                })
                .collect()
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn wide_neighbourhoods_equal_brute_force(
        ev in arb_events(150, 346, 260),
        eps in 0.12f32..0.6,
        min_pts in 1u16..30,
        st in prop::option::of(0.01f32..0.5),
    ) {
        let cfg = ClusterConfig { eps, min_pts, eps_t: st };
        check_equal::<150, 16>(&ev, SensorSize::DAVIS346, &cfg);
    }

    #[test]
    fn sweep_equals_brute_force(
        ev in arb_events(400, 346, 260),
        eps in 0.005f32..0.05,
        min_pts in 1u16..15,
        st in prop::option::of(0.01f32..0.5),
    ) {
        let cfg = ClusterConfig { eps, min_pts, eps_t: st };
        // Few cluster slots force dropped clusters; more keep them all.
        check_equal::<400, 16>(&ev, SensorSize::DAVIS346, &cfg);
        check_equal::<400, 64>(&ev, SensorSize::DAVIS346, &cfg);
        // In time order, as windows come, the events take the counting sort.
        let mut timed = ev.clone();
        timed.sort_by_key(|e| e.dt_us);
        check_equal::<400, 64>(&timed, SensorSize::DAVIS346, &cfg);
    }

    #[test]
    fn sweep_equals_brute_force_large_sensor(ev in arb_events(300, 1280, 720), min_pts in 1u16..12) {
        let cfg = ClusterConfig { min_pts, ..Default::default() };
        check_equal::<300, 64>(&ev, SensorSize::new(1280, 720), &cfg);
    }

    #[test]
    fn arbitrary_input_never_panics(
        raw in prop::collection::vec((any::<u16>(), any::<u16>(), any::<u32>()), 0..300),
        w in any::<u16>(), h in any::<u16>(),
        eps in any::<f32>(), min_pts in any::<u16>(), st in prop::option::of(any::<f32>()),
    ) {
        let mut ev: Vec<WindowEvent> = raw.into_iter().map(|(x, y, dt_us)| WindowEvent { x, y, dt_us }).collect();
        let mut c: Clusterer<256, 8> = Clusterer::new();
        let stats = c.cluster(&mut ev, SensorSize::new(w, h), &ClusterConfig { eps, min_pts, eps_t: st }, &mut [0; TABLE_CELLS]);
        prop_assert_eq!(usize::from(stats.events) + usize::from(stats.overflow), ev.len());
        let ranges = c.group(&mut ev).to_vec();
        prop_assert_eq!(ranges.len(), usize::from(stats.clusters));
    }
}
