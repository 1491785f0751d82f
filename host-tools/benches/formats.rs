//! Read throughput of the recording readers: events per second, file to `Event`s, for every
//! format of issue 5 written by its own tool (dv-processing, rosbags, h5py).
//!
//! Reads `target/test-data/formats-big/` when present, made by
//! `python3 scripts/make-format-fixtures.py target/test-data/formats-big 2000000` (2 M
//! events, 10–64 MB a file), else the committed 2000-event fixtures (where opening the file
//! dominates). The faery DAVIS346 recording is added when fetched (scripts/fetch-faery.sh).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use evcal_host::input::recording::Recording;
use std::path::{Path, PathBuf};

fn count(path: &Path) -> u64 {
    let mut n = 0;
    for e in Recording::open(path).unwrap() {
        e.unwrap();
        n += 1;
    }
    n
}

fn bench(c: &mut Criterion) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let big = root.join("target/test-data/formats-big");
    let dir = if big.join("events.txt").is_file() { big } else { root.join("host-tools/tests/fixtures/formats") };
    let mut files: Vec<PathBuf> = [
        "events.txt",
        "dv_none.aedat4",
        "dv_lz4.aedat4",
        "dv_zstd.aedat4",
        "ros_none.bag",
        "ros_bz2.bag",
        "ros_lz4.bag",
        "ecalib.h5",
        "dsec.h5",
        "events_ns.h5",
        "e2calib.h5",
    ]
    .iter()
    .map(|f| dir.join(f))
    .collect();
    let faery = root.join("target/test-data/faery-0.7.1/tests/data/davis346.aedat4");
    if faery.is_file() {
        files.push(faery);
    }
    let mut g = c.benchmark_group("read");
    g.sample_size(10);
    for f in files {
        let n = count(&f);
        g.throughput(Throughput::Elements(n));
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        g.bench_function(name, |b| b.iter(|| count(&f)));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
