//! `evcal info --json` on a written RAW file: the keys other programs read, with the file's
//! true values; a truncated file still reports, then fails naming the byte.

use evcal_core::{
    event::{Event, SensorSize},
    evt::Encoding,
};
use evcal_host::input::recording::prophesee::write::write_raw;
use std::process::Command;

#[test]
fn info_json_has_the_stable_keys_and_true_values() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rec.raw");
    let events: Vec<Event> = (0..5000u64)
        .map(|i| Event { t_us: 1_000_000 + i * 400, x: (i % 640) as u16, y: (i % 480) as u16, polarity: i % 4 == 0 })
        .collect();
    write_raw(&p, Encoding::Evt3, SensorSize::new(640, 480), &events).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_evcal")).args(["info", "--json"]).arg(&p).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["format"], "Prophesee RAW EVT 3.0");
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(640), Some(480)));
    assert_eq!(v["events"].as_u64(), Some(5000));
    assert_eq!(v["t_first_us"].as_u64(), Some(1_000_000));
    assert_eq!(v["t_last_us"].as_u64(), Some(1_000_000 + 4999 * 400));
    assert_eq!((v["on"].as_u64(), v["off"].as_u64()), (Some(1250), Some(3750)));
    let tenths = v["rate_per_s_by_tenth"].as_array().unwrap();
    assert_eq!(tenths.len(), 10);
    for r in tenths {
        assert!((r.as_f64().unwrap() - 2500.0).abs() < 30.0, "{r}: 1 event per 400 µs");
    }

    // cut inside a word: the JSON says what was read and the error; the exit status fails
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 1]).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_evcal")).args(["info", "--json"]).arg(&p).output().unwrap();
    assert!(!out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let err = v["error"].as_str().unwrap();
    assert!(err.contains("rec.raw") && err.contains(&format!("byte {}", bytes.len() - 2)), "{err}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("ends inside an EVT 3.0 word"));
}
