//! The calibration solver on many views: 700 views of the 4x11 grid (30 800 points), all
//! nine intrinsics free, plain least squares and the robust default.
//!
//! `cargo bench -p evcal-host --bench calib`

use criterion::{criterion_group, criterion_main, Criterion};
use evcal_host::calib::{calibrate, synthetic_views, Intrinsics, Options};

fn bench(c: &mut Criterion) {
    let truth =
        Intrinsics { fx: 352.4, fy: 351.1, cx: 171.3, cy: 128.6, k1: -0.31, k2: 0.12, p1: 4e-4, p2: -3e-4, k3: 0.0 };
    let views = synthetic_views(&truth, 700, 0.2, 700);
    let mut g = c.benchmark_group("calibrate");
    g.sample_size(10);
    g.bench_function("700 views, plain", |b| {
        b.iter(|| calibrate(&views, [346, 260], &Options { robust: false, ..Options::default() }).unwrap())
    });
    g.bench_function("700 views, robust", |b| b.iter(|| calibrate(&views, [346, 260], &Options::default()).unwrap()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
