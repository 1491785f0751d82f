//! Prophesee files written by tools other than evcal (expelliarmus for EVT 2.0, EVT 3.0 and
//! .dat; EVT 2.1 encoded from the published specification by tests/fixtures/prophesee/make.py)
//! and by evcal's own writers, read back to the same events; damaged files give errors that
//! name the file and the byte, never a panic and never silently fewer events.

use evcal_core::{
    event::{Event, SensorSize},
    evt::{Encoding, Evt21Order},
};
use evcal_host::input::recording::{
    prophesee::write::{write_dat, write_raw},
    Format, Position, ReadError, Recording,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/prophesee").join(name)
}

/// The events make.py gives expelliarmus: the same LCG, the same order of draws (a
/// hand-written generator on purpose: Python must draw the same numbers).
fn known_events() -> Vec<Event> {
    let mut state: u64 = 12345;
    let mut rnd = |n: u64| {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 33) % n
    };
    let mut t = 1000;
    (0..12000)
        .map(|_| {
            t += [0, 1, 60, 2000, 4000, 4000][rnd(6) as usize];
            Event { t_us: t, x: rnd(640) as u16, y: rnd(480) as u16, polarity: rnd(2) == 1 }
        })
        .collect()
}

fn read_all(path: &Path) -> (Recording, Result<Vec<Event>, ReadError>) {
    let mut rec = Recording::open(path).unwrap_or_else(|e| panic!("{e}"));
    let events: Result<Vec<Event>, ReadError> = rec.by_ref().collect();
    (rec, events)
}

#[test]
fn expelliarmus_files_give_the_known_events() {
    let want = known_events();
    assert_eq!(want.last().unwrap().t_us, 20_097_196, "the LCG agrees with make.py");
    for (name, format, sensor) in [
        ("expelliarmus_evt2.raw", Format::PropheseeRaw(Encoding::Evt2), Some(SensorSize::new(640, 480))),
        ("expelliarmus_evt3.raw", Format::PropheseeRaw(Encoding::Evt3), Some(SensorSize::new(1280, 720))),
        ("expelliarmus.dat", Format::PropheseeDat, None),
    ] {
        let (rec, got) = read_all(&fixture(name));
        assert_eq!(rec.format, format, "{name}");
        assert_eq!(rec.sensor, sensor, "{name}: the size of the camera its header names, or none");
        same(&got.unwrap(), &want, name);
    }
}

/// Equal event lists, else the first difference (not thousands of events).
fn same(got: &[Event], want: &[Event], what: &str) {
    if let Some(i) = (0..got.len().min(want.len())).find(|&i| got[i] != want[i]) {
        panic!("{what}: event {i} is {:?}, expected {:?}", got[i], want[i]);
    }
    assert_eq!(got.len(), want.len(), "{what}: number of events");
}

#[test]
fn evt21_from_the_specification_in_both_half_orders() {
    let csv = std::fs::read_to_string(fixture("evt21_decoded.csv")).unwrap();
    let want: Vec<Event> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<u64> = l.split(',').map(|f| f.parse().unwrap()).collect();
            Event { t_us: v[0], x: v[1] as u16, y: v[2] as u16, polarity: v[3] == 1 }
        })
        .collect();
    assert!(want.len() > 300);
    for (name, order) in
        [("evt21_imx636.raw", Evt21Order::HighHalfFirst), ("evt21_genx320.raw", Evt21Order::LowHalfFirst)]
    {
        let (rec, got) = read_all(&fixture(name));
        assert_eq!(rec.format, Format::PropheseeRaw(Encoding::Evt21(order)), "{name}");
        assert_eq!(rec.sensor, Some(SensorSize::new(640, 480)));
        same(&got.unwrap(), &want, name);
        let notes = rec.notes().join("; ");
        assert!(notes.contains("1 trigger words, 1 other"), "{name}: {notes}");
    }
}

#[test]
fn evt21_half_order_is_found_from_the_stream_when_the_header_does_not_say() {
    let dir = tempfile::tempdir().unwrap();
    for (name, order) in
        [("evt21_imx636.raw", Evt21Order::HighHalfFirst), ("evt21_genx320.raw", Evt21Order::LowHalfFirst)]
    {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let body = &bytes[bytes.windows(6).position(|w| w == b"% end\n").unwrap() + 6..];
        let p = dir.path().join(name);
        std::fs::write(&p, [b"% evt 2.1\n".as_slice(), body].concat()).unwrap();
        assert_eq!(Recording::open(&p).unwrap().format, Format::PropheseeRaw(Encoding::Evt21(order)), "{name}");
    }
}

/// Events the way a sensor gives them: bursts of neighbours on one row at one time (which the
/// writers vectorise), single events, gaps, and a run past EVT 3.0's 16.8 s clock wrap.
fn sensor_like_events() -> Vec<Event> {
    let mut v = Vec::new();
    let mut t = 5_000u64;
    for i in 0..20_000u64 {
        t += [0, 3, 17, 900, 4000][(i * 7 % 5) as usize];
        let y = (i * 13 % 720) as u16;
        let x0 = (i * 37 % 1200) as u16;
        let run = [1, 1, 2, 5, 13, 30][(i % 6) as usize];
        for k in 0..run {
            if (i + k) % 4 != 1 {
                v.push(Event { t_us: t, x: x0 + k as u16 * (1 + (i % 2) as u16), y, polarity: i % 3 == 0 });
            }
        }
    }
    v
}

#[test]
fn evcal_writers_round_trip_every_encoding() {
    let events = sensor_like_events();
    assert!(events.last().unwrap().t_us > 1 << 24);
    let dir = tempfile::tempdir().unwrap();
    let sensor = SensorSize::new(1280, 720);
    for enc in [
        Encoding::Evt2,
        Encoding::Evt21(Evt21Order::LowHalfFirst),
        Encoding::Evt21(Evt21Order::HighHalfFirst),
        Encoding::Evt3,
    ] {
        let p = dir.path().join("rec.raw");
        write_raw(&p, enc, sensor, &events).unwrap();
        let (rec, got) = read_all(&p);
        assert_eq!(rec.format, Format::PropheseeRaw(enc));
        assert_eq!(rec.sensor, Some(sensor));
        same(&got.unwrap(), &events, &format!("{enc:?}"));
    }
    let p = dir.path().join("rec.dat");
    write_dat(&p, sensor, &events).unwrap();
    let (rec, got) = read_all(&p);
    assert_eq!((rec.format, rec.sensor, rec.len), (Format::PropheseeDat, Some(sensor), Some(events.len() as u64)));
    same(&got.unwrap(), &events, "dat");
}

#[test]
fn format_is_chosen_by_content_then_extension() {
    let dir = tempfile::tempdir().unwrap();
    for (src, want) in [
        ("expelliarmus_evt3.raw", Format::PropheseeRaw(Encoding::Evt3)),
        ("expelliarmus_evt2.raw", Format::PropheseeRaw(Encoding::Evt2)),
        ("expelliarmus.dat", Format::PropheseeDat),
    ] {
        let p = dir.path().join("renamed.bin");
        std::fs::copy(fixture(src), &p).unwrap();
        assert_eq!(Format::detect(&p).unwrap(), want, "{src} renamed");
    }
    // a text recording with % comments stays text
    let p = dir.path().join("rec.txt");
    std::fs::write(&p, "% a comment\n0.5 1 2 1\n").unwrap();
    assert_eq!(Format::detect(&p).unwrap(), Format::Text);
}

/// The error of reading `path` to the end (at open or at an event).
fn first_error(path: &Path) -> ReadError {
    match Recording::open(path) {
        Err(e) => e,
        Ok(mut rec) => rec.by_ref().find_map(Result::err).expect("an error"),
    }
}

#[test]
fn damaged_files_name_the_file_and_the_byte() {
    let dir = tempfile::tempdir().unwrap();
    let events = sensor_like_events();
    let sensor = SensorSize::new(1280, 720);

    // RAW cut inside a word: every whole word's events come first, then the error at the cut.
    let p = dir.path().join("cut.raw");
    write_raw(&p, Encoding::Evt3, sensor, &events).unwrap();
    let full = std::fs::read(&p).unwrap();
    std::fs::write(&p, &full[..full.len() - 1]).unwrap();
    let mut rec = Recording::open(&p).unwrap();
    let mut n = 0;
    let err = loop {
        match rec.next().expect("an error before the end") {
            Ok(_) => n += 1,
            Err(e) => break e,
        }
    };
    assert!(n >= events.len() - 1, "{n}");
    assert_eq!(err.at, Position::Byte(full.len() as u64 - 2));
    let msg = err.to_string();
    assert!(msg.contains("cut.raw") && msg.contains("ends inside an EVT 3.0 word"), "{msg}");
    assert!(rec.next().is_none(), "nothing after the error");

    // .dat cut inside a record: the whole records, then the error at the cut.
    let p = dir.path().join("cut.dat");
    write_dat(&p, sensor, &events[..100]).unwrap();
    let full = std::fs::read(&p).unwrap();
    std::fs::write(&p, &full[..full.len() - 3]).unwrap();
    let mut rec = Recording::open(&p).unwrap();
    assert_eq!(rec.len, Some(99));
    assert_eq!(rec.by_ref().take_while(Result::is_ok).count(), 99);
    let err = first_error(&p);
    assert_eq!(err.at, Position::Byte(full.len() as u64 - 8));
    assert!(err.to_string().contains("cut.dat") && err.to_string().contains("99 whole events"), "{err}");

    // .dat of another event type, and one with nothing after its header
    let p = dir.path().join("trigger.dat");
    std::fs::write(&p, b"% Version 2\n\x0e\x18").unwrap();
    let err = first_error(&p);
    assert_eq!(err.at, Position::Byte(12));
    assert!(err.to_string().contains("EventExtTrigger"), "{err}");
    std::fs::write(&p, b"% Height 720\n% Width 1280\n").unwrap();
    assert!(first_error(&p).to_string().contains("ends after its header"));

    // empty files and headers without an encoding
    let p = dir.path().join("empty.raw");
    std::fs::write(&p, b"").unwrap();
    let err = first_error(&p);
    assert!(err.to_string().contains("empty.raw") && err.to_string().contains("% evt"), "{err}");
    std::fs::write(&p, b"% date 2024-01-01\n% geometry 640x480\n\x01\x02").unwrap();
    assert!(first_error(&p).to_string().contains("cannot tell its encoding"));
    std::fs::write(&p, b"% evt 5.0\n").unwrap();
    assert!(first_error(&p).to_string().contains("5.0"));
    let p = dir.path().join("empty.dat");
    std::fs::write(&p, b"").unwrap();
    let (rec, got) = read_all(&p);
    assert_eq!((rec.len, got.unwrap().len()), (Some(0), 0), "an empty .dat holds no events");
    // a RAW file with a header and no data holds no events
    let p = dir.path().join("header-only.raw");
    std::fs::write(&p, b"% evt 3.0\n% geometry 640x480\n").unwrap();
    assert_eq!(read_all(&p).1.unwrap().len(), 0);
}

#[test]
fn corrupt_raw_data_is_counted_and_said() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("corrupt.raw");
    write_raw(&p, Encoding::Evt2, SensorSize::new(1280, 720), &sensor_like_events()[..1000]).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    let header = bytes.windows(6).position(|w| w == b"% end\n").unwrap() + 6;
    // a word of reserved type 0x3 in the middle
    let at = header + 4 * 100;
    bytes[at + 3] = 0x30;
    std::fs::write(&p, &bytes).unwrap();
    let (rec, got) = read_all(&p);
    assert!(got.is_ok());
    let notes = rec.notes().join("; ");
    assert!(notes.contains(&format!("1 words of a reserved type skipped, the first at byte {at}")), "{notes}");

    // random bytes after a header: whatever comes out, no panic, a definite answer
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for len in [0usize, 1, 7, 1000, 65_537] {
        for enc in ["2.0", "2.1", "3.0"] {
            let mut b = format!("% evt {enc}\n").into_bytes();
            b.extend((0..len).map(|_| rng.random::<u8>()));
            std::fs::write(&p, &b).unwrap();
            let (rec, got) = read_all(&p);
            let _ = (rec.notes(), got);
        }
    }
}
