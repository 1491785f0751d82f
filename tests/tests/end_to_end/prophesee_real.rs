//! Real Prophesee recordings (faery's test data: a Gen3 EVT 2.0 RAW, an EVK4 / IMX636 EVT 3.0
//! RAW, and the same EVK4 recording as a CD .dat) read by evcal must give exactly the events
//! faery's `assets.py` describes: the SHA3-224 of every field as faery decodes it, the sensor
//! size, and the time range.

use evcal_core::event::Event;
use evcal_host::input::recording::{Format, Recording};
use evcal_tests::faery::{asset, data_dir, Asset};
use sha3::{Digest, Sha3_224};
use std::path::Path;

fn hex(d: &[u8]) -> String {
    d.iter().map(|b| format!("{b:02x}")).collect()
}

/// Reads `file` to the end (no error allowed) and checks it against its `assets.py` entry.
fn check(data: &Path, file: &str, format: Format) -> Vec<Event> {
    let path = data.join(file);
    let a: Asset = asset(data, file);
    let mut rec = Recording::open(&path).unwrap();
    assert_eq!(rec.format, format, "{file}");
    let (w, h) = a.dimensions.unwrap();
    assert_eq!(rec.sensor.map(|s| (s.width, s.height)), Some((w, h)), "{file}: sensor size");
    let mut events = Vec::new();
    for e in rec.by_ref() {
        events.push(e.unwrap_or_else(|e| panic!("{e}")));
    }
    let (mut t, mut x, mut y, mut on) = (Sha3_224::new(), Sha3_224::new(), Sha3_224::new(), Sha3_224::new());
    for e in &events {
        t.update(e.t_us.to_le_bytes());
        x.update(e.x.to_le_bytes());
        y.update(e.y.to_le_bytes());
        on.update([u8::from(e.polarity)]);
    }
    let got =
        [("t", hex(&t.finalize())), ("x", hex(&x.finalize())), ("y", hex(&y.finalize())), ("on", hex(&on.finalize()))];
    for (field, digest) in got {
        let want = a.digests.iter().find(|(f, _)| f == field).map(|(_, d)| d.as_str());
        assert_eq!(Some(digest.as_str()), want, "{file}: SHA3-224 of field {field}");
    }
    // faery's time ranges end one µs after the last event (an exclusive end).
    assert_eq!(events.first().map(|e| e.t_us), Some(a.time_range.0), "{file}: first time");
    assert_eq!(events.last().map(|e| e.t_us + 1), Some(a.time_range.1), "{file}: time range end");
    eprintln!(
        "{file}: {} events, t {}..={} µs, {}x{}, notes: {:?}",
        events.len(),
        events[0].t_us,
        events.last().unwrap().t_us,
        w,
        h,
        rec.notes()
    );
    events
}

#[test]
fn faery_prophesee_recordings_are_read_exactly() {
    let Some(data) = data_dir() else { return };
    use evcal_core::evt::Encoding;
    let evt2 = check(&data, "evt2.raw", Format::PropheseeRaw(Encoding::Evt2));
    assert_eq!(evt2.len(), 521_252);
    let evt3 = check(&data, "evt3.raw", Format::PropheseeRaw(Encoding::Evt3));
    assert_eq!(evt3.len(), 1_218_618, "the EVK4 recording's event count");
    let dat = check(&data, "gen4.dat", Format::PropheseeDat);

    // The .dat is the same recording: the same events in the same order, with times shifted
    // by one constant (Metavision's time shift when it wrote the .dat).
    assert_eq!(dat.len(), evt3.len());
    let shift = evt3[0].t_us - dat[0].t_us;
    for (i, (r, d)) in evt3.iter().zip(&dat).enumerate() {
        assert_eq!(*r, Event { t_us: d.t_us + shift, ..*d }, "event {i}");
    }
    assert_eq!(shift, 11_194_368);
}
