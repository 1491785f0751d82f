//! Headers: DAT without a header, sensor sizes and time units evcal cannot use, RAW headers past the limit.

use super::*;

#[test]
fn dat_files_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    // random bytes named .dat (before: 1000 events, a 16k x 16k sensor, exit 0)
    let p = dir.path().join("random.dat");
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let bytes: Vec<u8> = (0..8000).map(|_| rng.random::<u8>()).collect();
    std::fs::write(&p, &bytes).unwrap();
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("random.dat: byte 0:") && err.contains("not a Prophesee .dat file"), "{err}");
    // a header, then random records: the first that breaks the header's sensor or the time
    // order is named by its offset
    let q = dir.path().join("bad.dat");
    let mut f = b"% Height 480\n% Version 2\n% Width 640\n\x0c\x08".to_vec();
    let data_at = f.len();
    for (t, x, y) in [(10u32, 5u32, 6u32), (12, 7, 8), (11, 1, 1)] {
        f.extend(t.to_le_bytes());
        f.extend((x | (y << 14)).to_le_bytes());
    }
    std::fs::write(&q, &f).unwrap();
    let (code, _, err) = evcal(&["info", s(&q)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains(&format!("bad.dat: byte {}:", data_at + 16)) && err.contains("time goes back"), "{err}");
    f.truncate(data_at + 8);
    f.extend(13u32.to_le_bytes());
    f.extend((700u32 | (9 << 14)).to_le_bytes());
    std::fs::write(&q, &f).unwrap();
    let (code, _, err) = evcal(&["info", s(&q)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains(&format!("bad.dat: byte {}:", data_at + 8)) && err.contains("outside the 640x480 sensor"),
        "{err}"
    );
}

/// Before: every reader took a sensor size outside 1..65535 (or not a whole number) as no
/// size at all ("does not state its sensor size"), an HDF5 width of 346.7 as 346, and an
/// unknown HDF5 time unit as none.
#[test]
fn stated_sizes_and_units_evcal_cannot_use_are_said() {
    let dir = tempfile::tempdir().unwrap();
    let open_err = |p: &Path| Recording::open(p).err().map(|e| e.to_string()).unwrap_or_default();
    let range = "evcal reads sizes of 1 to 65535 pixels a side";

    let p = dir.path().join("big.bag");
    bag_of_one_message(&p, 70_000, 260);
    let e = open_err(&p);
    assert!(e.contains("big.bag: byte") && e.contains("states a sensor size of 70000x260") && e.contains(range), "{e}");
    bag_of_one_message(&p, 346, 260);
    assert_eq!(Recording::open(&p).unwrap().sensor, Some(SensorSize::DAVIS346));

    let p = dir.path().join("big.dat");
    std::fs::write(&p, b"% Height 480\n% Version 2\n% Width 70000\n\x0c\x08").unwrap();
    let e = open_err(&p);
    assert!(e.contains("big.dat") && e.contains("70000x480") && e.contains(range), "{e}");
    let p = dir.path().join("big.raw");
    std::fs::write(&p, b"% evt 3.0\n% geometry 1280x100000\n% end\n").unwrap();
    let e = open_err(&p);
    assert!(e.contains("big.raw") && e.contains("% geometry") && e.contains("1280x100000"), "{e}");

    let p = dir.path().join("big.aedat4");
    let mut b = std::fs::read(fixture("dv_lz4.aedat4")).unwrap();
    let at = b.windows(5).position(|w| w == b">346<").unwrap();
    b[at + 1..at + 4].copy_from_slice(b"-34");
    std::fs::write(&p, b).unwrap();
    let e = open_err(&p);
    assert!(e.contains("big.aedat4") && e.contains("-34x260") && e.contains(range), "{e}");

    let p = dir.path().join("frac.h5");
    h5_with_attrs(&p, |f| {
        f.new_attr::<f64>().create("width").unwrap().write_scalar(&346.7).unwrap();
        f.new_attr::<f64>().create("height").unwrap().write_scalar(&260.0).unwrap();
    });
    let e = open_err(&p);
    assert!(e.contains("frac.h5") && e.contains("width = 346.7 on the file is not a whole number"), "{e}");
    let p = dir.path().join("big.h5");
    h5_with_attrs(&p, |f| {
        f.new_attr::<i64>().create("width").unwrap().write_scalar(&-346i64).unwrap();
        f.new_attr::<f64>().create("height").unwrap().write_scalar(&260.0).unwrap();
    });
    let e = open_err(&p);
    assert!(e.contains("big.h5") && e.contains("-346x260") && e.contains(range), "{e}");
    let p = dir.path().join("ok.h5");
    h5_with_attrs(&p, |f| {
        f.new_attr::<f64>().create("width").unwrap().write_scalar(&346.0).unwrap();
        f.new_attr::<u32>().create("height").unwrap().write_scalar(&260u32).unwrap();
    });
    assert_eq!(Recording::open(&p).unwrap().sensor, Some(SensorSize::DAVIS346));

    let p = dir.path().join("furlongs.h5");
    h5_with_attrs(&p, |f| {
        let unit: hdf5::types::VarLenUnicode = "furlongs".parse().unwrap();
        f.new_attr::<hdf5::types::VarLenUnicode>().create("unit").unwrap().write_scalar(&unit).unwrap();
    });
    let e = open_err(&p);
    assert!(e.contains("furlongs.h5") && e.contains("unit=\"furlongs\"") && e.contains("--time-unit"), "{e}");
    let opts = OpenOptions { time_unit: Some(TimeUnit::Microseconds), ..Default::default() };
    assert_eq!(read_all(Recording::open_with(&p, &opts).unwrap()).len(), 3, "--time-unit decides");
}

/// Before: the `%` lines past the first MiB of a RAW header were decoded as events.
#[test]
fn a_prophesee_header_past_the_limit_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("long.raw");
    let mut b = b"% evt 2.0\n% geometry 640x480\n".to_vec();
    while b.len() < 1_100_000 {
        b.extend(b"% comment a long header line of a long header\n");
    }
    b.extend(b"% end\n");
    b.extend([0u8; 64]);
    std::fs::write(&p, &b).unwrap();
    let e = Recording::open(&p).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("long.raw") && e.contains("goes on past 1048576 bytes"), "{e}");
    // A header just under the limit is read.
    b.truncate(1_000_000);
    let cut = b.iter().rposition(|&c| c == b'\n').unwrap() + 1;
    b.truncate(cut);
    b.extend(b"% end\n");
    std::fs::write(&p, &b).unwrap();
    assert!(Recording::open(&p).is_ok());
}

/// Before: `--time-unit` was ignored without a word for formats whose times have their own
/// unit.
#[test]
fn a_time_unit_that_cannot_apply_is_refused() {
    for (name, unit) in [("dv_lz4.aedat4", "ns"), ("ros_lz4.bag", "us"), ("ecalib.h5", "us")] {
        let (code, _, err) = evcal(&["info", "--time-unit", unit, s(&fixture(name))]);
        assert_eq!(code, Some(1), "{name}: {err}");
        assert!(err.contains(name) && err.contains(&format!("--time-unit {unit} does not apply")), "{err}");
    }
    let e = evcal(&["info", "--time-unit", "ns", s(&fixture("dv_lz4.aedat4"))]).2;
    assert!(e.contains("AEDAT4 timestamps are µs by the format"), "{e}");
    // the format's own unit is no contradiction
    let (code, _, err) = evcal(&["info", "--time-unit", "us", s(&fixture("dv_lz4.aedat4"))]);
    assert_eq!(code, Some(0), "{err}");
}
