//! Events per second decoded by `evcal_core::evt` for each Prophesee encoding, one core: the
//! real EVK4 EVT 3.0 recording and the Gen3 EVT 2.0 one from faery (when fetched, see
//! scripts/fetch-faery.sh), and the same synthetic sensor-like events encoded in every
//! encoding by evcal's writers.
//!
//!     cargo bench -p evcal-host --bench evt

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use evcal_core::{
    event::Event,
    evt::{Decoder, Encoding, Evt21Order},
};
use evcal_host::input::recording::prophesee::{write::encode_evt, Header};
use std::hint::black_box;

/// Decodes all of `body` through a 4096-event output; returns the events.
fn decode(encoding: Encoding, body: &[u8], out: &mut [Event]) -> u64 {
    let mut dec = Decoder::new(encoding);
    let mut rest = body;
    let mut sum = 0u64;
    loop {
        let r = dec.decode(rest, out);
        rest = &rest[r.consumed..];
        for e in &out[..r.events] {
            sum = sum.wrapping_add(e.t_us);
        }
        if rest.is_empty() && r.events < out.len() {
            break;
        }
    }
    black_box(sum);
    dec.stats().events
}

/// Events like a sensor's under motion: rows of neighbouring pixels firing together.
fn synthetic() -> Vec<Event> {
    let mut v = Vec::new();
    let mut t = 0u64;
    for i in 0..200_000u64 {
        t += (i % 3 == 0) as u64;
        let y = (i * 13 % 720) as u16;
        let x0 = (i * 37 % 1200) as u16;
        for k in 0..[1u16, 3, 6, 10][(i % 4) as usize] {
            v.push(Event { t_us: t, x: x0 + 2 * k, y, polarity: i % 5 < 2 });
        }
    }
    v
}

fn bench(c: &mut Criterion) {
    let mut out = vec![Event::default(); 4096];
    let mut g = c.benchmark_group("evt decode");
    if let Ok(dir) = std::env::var("EVCAL_FAERY_DATA").or_else(|_| {
        let d = concat!(env!("CARGO_MANIFEST_DIR"), "/../target/test-data/faery-0.7.1/tests/data");
        std::path::Path::new(d).exists().then(|| d.to_string()).ok_or(())
    }) {
        for (file, enc) in [("evt3.raw", Encoding::Evt3), ("evt2.raw", Encoding::Evt2)] {
            let bytes = std::fs::read(format!("{dir}/{file}")).unwrap();
            let body = &bytes[Header::parse(&bytes).len as usize..];
            let n = decode(enc, body, &mut out);
            g.throughput(Throughput::Elements(n));
            g.bench_function(format!("faery {file} ({n} events, {} bytes)", body.len()), |b| {
                b.iter(|| decode(enc, body, &mut out))
            });
        }
    } else {
        eprintln!("faery's recordings not fetched (scripts/fetch-faery.sh): synthetic streams only");
    }
    let events = synthetic();
    for enc in [Encoding::Evt3, Encoding::Evt21(Evt21Order::HighHalfFirst), Encoding::Evt2] {
        let body = encode_evt(enc, &events);
        assert_eq!(decode(enc, &body, &mut out), events.len() as u64);
        g.throughput(Throughput::Elements(events.len() as u64));
        g.bench_function(format!("synthetic {} ({} events, {} bytes)", enc.name(), events.len(), body.len()), |b| {
            b.iter(|| decode(enc, &body, &mut out))
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
