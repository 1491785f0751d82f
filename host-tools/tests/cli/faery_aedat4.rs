//! A real DAVIS346 recording, read by evcal and checked against what faery's own tests
//! publish for it (`tests/assets.py` of faery's source distribution): the SHA3-224 digests of
//! the t, x, y and polarity fields, the sensor size and the time range, and the event count
//! (78,830) named in issue 5.
//!
//! The data are LGPL-3.0 and not committed: `bash scripts/fetch-faery.sh` fetches them into
//! `target/test-data/` (this test runs it when they are missing; `EVCAL_FAERY_DATA=DIR` names
//! another copy of faery's `tests/data`). If they cannot be had, the test says so loudly and
//! passes, unless `EVCAL_REQUIRE_TEST_DATA=1` (set by `scripts/test.sh`) makes that a failure.

use evcal_core::event::SensorSize;
use evcal_host::input::recording::{Format, Recording};
use sha3::{Digest, Sha3_224};
use std::path::PathBuf;

/// faery's `tests/data` directory (assets.py is beside it).
fn faery_data() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("EVCAL_FAERY_DATA") {
        return Some(PathBuf::from(d));
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let fetched = std::process::Command::new("bash")
        .arg(root.join("scripts/fetch-faery.sh"))
        .current_dir(&root)
        .output()
        .map_err(|e| e.to_string())
        .and_then(|o| {
            if o.status.success() {
                Ok(PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()))
            } else {
                Err(String::from_utf8_lossy(&o.stderr).into_owned())
            }
        });
    match fetched {
        Ok(d) => Some(d),
        Err(why) if std::env::var("EVCAL_REQUIRE_TEST_DATA").is_ok_and(|v| v == "1") => {
            panic!("faery's recordings could not be fetched: {why}")
        }
        Err(why) => {
            eprintln!(
                "\n!!!!!!!! SKIPPED: faery's recordings could not be fetched ({why}); run scripts/fetch-faery.sh\n"
            );
            None
        }
    }
}

/// What assets.py says of one file: field digests, dimensions, time range (first, last + 1).
struct Asset {
    digests: Vec<(String, String)>,
    dimensions: (u16, u16),
    time_range_us: (u64, u64),
}

/// Reads the `File(path=dirname / "data" / NAME, ...)` entry of assets.py. A small scan
/// rather than a Python parser: the entries are regular, and a mismatch fails loudly.
fn asset(assets_py: &str, name: &str) -> Asset {
    let start = assets_py.find(&format!("\"{name}\"")).unwrap_or_else(|| panic!("{name} not in assets.py"));
    let block = &assets_py[start..];
    let block = &block[..block.find("    File(").unwrap_or(block.len())];
    let quoted_after = |key: &str, from: &str| -> Vec<String> {
        let at = from.find(key).unwrap_or_else(|| panic!("no {key} for {name}")) + key.len();
        from[at..].split('"').skip(1).step_by(2).take(2).map(str::to_string).collect()
    };
    let digest_block = &block[block.find("field_to_digest").unwrap()..block.find("dimensions").unwrap()];
    let digests = digest_block
        .lines()
        .filter_map(|l| {
            let parts: Vec<&str> = l.split('"').collect();
            (parts.len() >= 4).then(|| (parts[1].to_string(), parts[3].to_string()))
        })
        .collect();
    let dims = &block[block.find("dimensions=(").unwrap() + 12..];
    let dims: Vec<u16> = dims[..dims.find(')').unwrap()].split(',').map(|v| v.trim().parse().unwrap()).collect();
    let range = quoted_after("time_range=(", block);
    Asset { digests, dimensions: (dims[0], dims[1]), time_range_us: (parse_time(&range[0]), parse_time(&range[1])) }
}

/// faery's `H:MM:SS.ffffff` to microseconds.
fn parse_time(s: &str) -> u64 {
    let p: Vec<&str> = s.split(':').collect();
    let (sec, us) = p[2].split_once('.').unwrap();
    (p[0].parse::<u64>().unwrap() * 3600 + p[1].parse::<u64>().unwrap() * 60 + sec.parse::<u64>().unwrap()) * 1_000_000
        + us.parse::<u64>().unwrap()
}

#[test]
fn davis346_aedat4_matches_faery() {
    let Some(data) = faery_data() else { return };
    let assets_py = std::fs::read_to_string(data.join("../assets.py")).unwrap();
    let want = asset(&assets_py, "davis346.aedat4");
    let path = data.join("davis346.aedat4");

    assert_eq!(Format::detect(&path).unwrap(), Format::Aedat4);
    let rec = Recording::open(&path).unwrap();
    assert_eq!(rec.sensor, Some(SensorSize::new(want.dimensions.0, want.dimensions.1)));
    assert_eq!(rec.len, Some(78_830), "the data table's count");
    assert!(rec.notes().is_empty(), "{:?}", rec.notes());

    let (mut ht, mut hx, mut hy, mut hp) = (Sha3_224::new(), Sha3_224::new(), Sha3_224::new(), Sha3_224::new());
    let (mut n, mut first, mut last) = (0u64, None, 0u64);
    for e in rec {
        let e = e.unwrap();
        ht.update(e.t_us.to_le_bytes());
        hx.update(e.x.to_le_bytes());
        hy.update(e.y.to_le_bytes());
        hp.update([u8::from(e.polarity)]);
        first.get_or_insert(e.t_us);
        last = e.t_us;
        n += 1;
    }
    assert_eq!(n, 78_830);
    // faery's time range ends one microsecond after the last event.
    assert_eq!((first.unwrap(), last + 1), want.time_range_us);
    eprintln!(
        "davis346.aedat4: {n} events, t {} .. {} µs, sensor {}x{}",
        first.unwrap(),
        last,
        want.dimensions.0,
        want.dimensions.1
    );
    for (field, h) in [("t", ht), ("x", hx), ("y", hy), ("on", hp)] {
        let want_digest = &want.digests.iter().find(|(f, _)| f == field).unwrap().1;
        let got: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(&got, want_digest, "SHA3-224 of field {field}");
    }
}

/// faery's frame-only AEDAT4 files: no event stream, said with the streams the file has.
#[test]
fn frame_only_aedat4_is_a_clear_error() {
    let Some(data) = faery_data() else { return };
    for name in ["test_data_gray16.aedat4", "test_data_unknown_then_gray16.aedat4"] {
        let e = Recording::open(&data.join(name)).err().unwrap().to_string();
        assert!(e.contains(name) && e.contains("no event stream") && e.contains("(FRME)"), "{e}");
    }
}

#[test]
fn time_strings_parse() {
    assert_eq!(parse_time("441434:12:27.368868"), 1_589_163_147_368_868);
    assert_eq!(parse_time("00:00:00.999001"), 999_001);
}
