//! Files written by other people's tools (dv-processing, rosbags, h5py) from one event list,
//! read by evcal: every format must give exactly the events of the text list.
//!
//! The fixtures were made by `scripts/make-format-fixtures.py` and are committed in
//! `tests/fixtures/formats/`; `EVCAL_FORMAT_FIXTURES=DIR` points the tests at a fresh set
//! (scripts/test.sh makes one with the writers installed by scripts/setup.sh).

use evcal_core::event::{Event, SensorSize};
use evcal_host::recording::{Format, OpenOptions, Position, ReadError, Recording, TimeUnit};
use std::path::PathBuf;

fn dir() -> PathBuf {
    std::env::var_os("EVCAL_FORMAT_FIXTURES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/formats"))
}

fn read_all(rec: Recording) -> Vec<Event> {
    rec.map(|e| e.unwrap_or_else(|e| panic!("{e}"))).collect()
}

fn reference() -> Vec<Event> {
    let rec = Recording::open(&dir().join("events.txt")).unwrap();
    assert_eq!(rec.format, Format::Text);
    assert_eq!(rec.sensor, Some(SensorSize::DAVIS346));
    let ev = read_all(rec);
    assert_eq!(ev.len(), 2000);
    ev
}

/// (file, format, sensor size stated by the file, count known at open, note expected)
const FILES: &[(&str, Format, Option<SensorSize>, bool)] = &[
    ("dv_none.aedat4", Format::Aedat4, Some(SensorSize::DAVIS346), true),
    ("dv_lz4.aedat4", Format::Aedat4, Some(SensorSize::DAVIS346), true),
    ("dv_lz4_high.aedat4", Format::Aedat4, Some(SensorSize::DAVIS346), true),
    ("dv_zstd.aedat4", Format::Aedat4, Some(SensorSize::DAVIS346), true),
    ("dv_zstd_high.aedat4", Format::Aedat4, Some(SensorSize::DAVIS346), true),
    ("ros_none.bag", Format::RosBag, Some(SensorSize::DAVIS346), false),
    ("ros_bz2.bag", Format::RosBag, Some(SensorSize::DAVIS346), false),
    ("ros_lz4.bag", Format::RosBag, Some(SensorSize::DAVIS346), false),
    ("ecalib.h5", Format::EcalibH5, None, true),
    ("dsec.h5", Format::EventsGroupH5, None, true),
    ("events_ns.h5", Format::EventsGroupH5, Some(SensorSize::DAVIS346), true),
    ("e2calib.h5", Format::RootColumnsH5, None, true),
];

#[test]
fn every_format_gives_the_reference_events() {
    let want = reference();
    for &(name, format, sensor, counted) in FILES {
        let path = dir().join(name);
        assert_eq!(Format::detect(&path).unwrap(), format, "{name}");
        let rec = Recording::open(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(rec.format, format, "{name}");
        assert_eq!(rec.sensor, sensor, "{name}");
        assert_eq!(rec.len, counted.then_some(2000), "{name}");
        for n in &rec.notes {
            eprintln!("note: {n}");
        }
        let got = read_all(rec);
        assert_eq!(got.len(), want.len(), "{name}");
        if let Some(i) = (0..got.len()).find(|&i| got[i] != want[i]) {
            panic!("{name}: event {i} is {:?}, the list has {:?}", got[i], want[i]);
        }
    }
}

#[test]
fn time_unit_guesses_are_reported() {
    // ns in the e2calib and events_ns files: guessed from the magnitude, and said so
    for name in ["e2calib.h5", "events_ns.h5"] {
        let rec = Recording::open(&dir().join(name)).unwrap();
        assert_eq!(rec.notes.len(), 1, "{name}: {:?}", rec.notes);
        assert!(rec.notes[0].contains("taken as ns") && rec.notes[0].contains("--time-unit"), "{}", rec.notes[0]);
    }
    // DSEC's t_offset settles the unit: no guess
    assert!(Recording::open(&dir().join("dsec.h5")).unwrap().notes.is_empty());
    // a wrong override is obeyed (the user knows best), 1000 times off
    let opts = OpenOptions { time_unit: Some(TimeUnit::Microseconds), ..Default::default() };
    let rec = Recording::open_with(&dir().join("e2calib.h5"), &opts).unwrap();
    assert!(rec.notes.is_empty());
    let first = read_all(rec)[0];
    assert_eq!(first.t_us, reference()[0].t_us * 1000);
}

#[test]
fn bag_topics() {
    let path = dir().join("ros_lz4.bag");
    // the second event topic holds the first 100 events
    let opts = OpenOptions { topic: Some("/right/events".into()), ..Default::default() };
    let got = read_all(Recording::open_with(&path, &opts).unwrap());
    assert_eq!(got[..], reference()[..100]);

    let opts = OpenOptions { topic: Some("/cam0/events".into()), ..Default::default() };
    let e = Recording::open_with(&path, &opts).err().unwrap().to_string();
    assert!(
        e.contains("ros_lz4.bag")
            && e.contains("no topic '/cam0/events'")
            && e.contains("/dvs/events (dvs_msgs/EventArray)")
            && e.contains("/dvs/imu (sensor_msgs/Imu)")
            && e.contains("/right/events"),
        "{e}"
    );
    let opts = OpenOptions { topic: Some("/dvs/imu".into()), ..Default::default() };
    let e = Recording::open_with(&path, &opts).err().unwrap().to_string();
    assert!(e.contains("has type sensor_msgs/Imu"), "{e}");
}

#[test]
fn aedat4_streams() {
    let path = dir().join("dv_lz4.aedat4");
    let opts = OpenOptions { topic: Some("events".into()), ..Default::default() };
    assert_eq!(read_all(Recording::open_with(&path, &opts).unwrap()).len(), 2000);
    let opts = OpenOptions { topic: Some("frames".into()), ..Default::default() };
    let e = Recording::open_with(&path, &opts).err().unwrap().to_string();
    assert!(e.contains("holds no events") && e.contains("'imu' (IMUS)") && e.contains("'triggers' (TRIG)"), "{e}");
}

/// Reads a whole file: the events read, the first error (at open or after), the notes.
fn outcome(path: &std::path::Path) -> (usize, Option<ReadError>, Vec<String>) {
    match Recording::open(path) {
        Err(e) => (0, Some(e), Vec::new()),
        Ok(mut rec) => {
            let notes = std::mem::take(&mut rec.notes);
            let mut n = 0;
            for e in rec {
                match e {
                    Ok(_) => n += 1,
                    Err(e) => return (n, Some(e), notes),
                }
            }
            (n, None, notes)
        }
    }
}

/// Every truncation of every binary fixture: an error naming the file and where, never a
/// panic, never fewer events without an error. (A cut through AEDAT4's data table, after
/// the last packet, loses no event: all are read, with a note that the count is unchecked.)
#[test]
fn truncated_files_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    for &(name, _, _, _) in FILES {
        let started = std::time::Instant::now();
        let bytes = std::fs::read(dir().join(name)).unwrap();
        let cut_path = tmp.path().join(name);
        // every length in the first 600 bytes (headers), then a spread through the rest; HDF5
        // files are opened by the HDF5 library, slower: fewer cuts.
        let (head, step) = if name.ends_with(".h5") { (7, 499) } else { (1, 97) };
        let mut cuts: Vec<usize> = (0..600.min(bytes.len())).step_by(head).collect();
        cuts.extend((600..bytes.len()).step_by(step));
        cuts.push(bytes.len() - 1);
        for cut in cuts {
            std::fs::write(&cut_path, &bytes[..cut]).unwrap();
            let (n, err, notes) = outcome(&cut_path);
            let Some(e) = err else {
                assert!(n == 2000 && !notes.is_empty(), "{name} cut at {cut}: {n} events, no error, notes {notes:?}");
                continue;
            };
            let msg = e.to_string();
            assert!(msg.contains(name), "{name} cut at {cut}: {msg}");
            if !name.ends_with(".h5") {
                assert!(matches!(e.at, Position::Byte(_)), "{name} cut at {cut}: {msg}");
            }
        }
        eprintln!("{name}: truncations checked in {:.1} s", started.elapsed().as_secs_f64());
    }
}

/// Single-byte corruptions of the AEDAT4 and bag fixtures: never a panic; either an error
/// naming the file and byte, or all 2000 events (a corrupted value, not a lost event).
#[test]
fn corrupted_files_never_lose_events_silently() {
    let tmp = tempfile::tempdir().unwrap();
    let mut errors = 0;
    let mut clean = 0;
    for &(name, _, _, _) in FILES.iter().filter(|f| !f.0.ends_with(".h5")) {
        let bytes = std::fs::read(dir().join(name)).unwrap();
        let path = tmp.path().join(name);
        for at in (0..bytes.len()).step_by(41) {
            for v in [0x00u8, 0xff, bytes[at] ^ 0x10] {
                if v == bytes[at] {
                    continue;
                }
                let mut b = bytes.clone();
                b[at] = v;
                std::fs::write(&path, &b).unwrap();
                match outcome(&path) {
                    (n, None, _) => {
                        assert_eq!(n, 2000, "{name}, byte {at} set to {v:#04x}: {n} events and no error");
                        clean += 1;
                    }
                    (_, Some(e), _) => {
                        assert!(e.to_string().contains(name), "{e}");
                        errors += 1;
                    }
                }
            }
        }
    }
    eprintln!("single-byte corruptions: {errors} errors, {clean} read whole (a changed value)");
}

#[test]
fn empty_files_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    for name in ["empty.aedat4", "empty.bag", "empty.h5"] {
        let p = tmp.path().join(name);
        std::fs::write(&p, b"").unwrap();
        let e = Recording::open(&p).err().unwrap_or_else(|| panic!("{name} opened"));
        let msg = e.to_string();
        assert!(msg.contains(name), "{msg}");
        eprintln!("{msg}");
    }
}
