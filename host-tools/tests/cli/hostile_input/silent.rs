//! Silent wrong results: integer times, times beyond range, sensors that disagree, detections repeated or out of order.

use super::*;

#[test]
fn integer_text_times_are_ticks_and_the_unit_option_is_honoured() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("us.txt");
    std::fs::write(&p, "0 1 2 1\n1000 3 4 0\n214919 5 6 1\n").unwrap();
    let rec = Recording::open(&p).unwrap();
    let notes_and_events = {
        let mut rec = rec;
        let ev: Vec<Event> = rec.by_ref().map(Result::unwrap).collect();
        (rec.notes(), ev)
    };
    let (notes, ev) = notes_and_events;
    assert_eq!(ev.iter().map(|e| e.t_us).collect::<Vec<_>>(), [0, 1000, 214_919]);
    assert!(
        notes.iter().any(|n| n.contains("us.txt") && n.contains("taken as us") && n.contains("line 2")),
        "{notes:?}"
    );
    // the CLI says so, and --time-unit is obeyed for text
    let (code, out, err) = evcal(&["info", "--json", "--time-unit", "ms", s(&p)]);
    assert_eq!(code, Some(0), "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["t_last_us"].as_u64(), Some(214_919_000));
    let opts = OpenOptions { time_unit: Some(TimeUnit::Nanoseconds), ..Default::default() };
    let ev = read_all(Recording::open_with(&p, &opts).unwrap());
    assert_eq!(ev[2].t_us, 215);
    // integers after decimals would be a unit change: an error, not a silent mix
    std::fs::write(&p, "5 1 2 1\n5.5 3 4 0\n").unwrap();
    let err = Recording::open(&p).unwrap().find_map(Result::err).unwrap();
    assert_eq!(err.at, Position::Line(2));
    assert!(err.message.contains("not an integer") && err.message.contains("--time-unit"), "{err}");
}

#[test]
fn hdf5_times_above_i64_max_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("u64.h5");
    {
        let f = hdf5::File::create(&p).unwrap();
        let g = f.create_group("events").unwrap();
        g.new_dataset_builder().with_data(&[1u16, 2, 3]).create("x").unwrap();
        g.new_dataset_builder().with_data(&[1u16, 2, 3]).create("y").unwrap();
        g.new_dataset_builder().with_data(&[1u8, 0, 1]).create("p").unwrap();
        g.new_dataset_builder().with_data(&[5u64, 1 << 63, u64::MAX]).create("t").unwrap();
    }
    let (code, _, err) = evcal(&["info", "--time-unit", "us", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("u64.h5: event 1:") && err.contains("above the largest"), "{err}");
}

#[test]
fn sensor_disagreements_are_said() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("hdr.txt");
    write_text(&p, Some(SensorSize::DVXPLORER), &events(3000, SensorSize::DVXPLORER, 1)).unwrap();
    // a header overridden by --sensor: a note
    let (code, _, err) =
        evcal(&["detect", s(&p), "--sensor", "346x260", "--events-per-window", "500", "-o", "/dev/null"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("hdr.txt states a 640x480 sensor; --sensor 346x260 is used instead"), "{err}");
    // most events outside the sensor: a warning, not only a count
    assert!(
        err.contains("warning: ") && err.contains("lie outside the 346x260 sensor") && err.contains("probably wrong"),
        "{err}"
    );
    let q = dir.path().join("small.txt");
    write_text(&q, Some(SensorSize::DAVIS346), &events(1000, SensorSize::DVXPLORER, 2)).unwrap();
    let (code, out, err) = evcal(&["info", s(&q)]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("warning") && out.contains("probably wrong"), "{out}");
}

/// Before: centres listed twice reached the grid finder, which blamed `--pattern`; detections
/// piped in were read as a text recording ("not a text recording"); a 300-digit option value
/// was quoted back in full.
#[test]
fn detections_repeated_piped_and_numbers_too_long_to_quote() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let calib = |input: &str| {
        vec!["calibrate", input, "--sensor", "346x260", "--pattern", "4x11", "--spacing", "0.024", "--out", s(&out)]
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>()
    };
    let c = r#"{"u":10.5,"v":20.25,"r":3,"spread":0.2,"n":40,"converged":true}"#;
    let twice = format!(r#"{{"seq":1,"t_ref_us":200,"events":4000,"noise":10,"centers":[{c},{c}]}}"#);
    let p = dir.path().join("det.jsonl");
    std::fs::write(&p, [window(0, 100), twice.clone()].join("\n")).unwrap();
    let args = calib(s(&p));
    let (code, _, err) = evcal(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("det.jsonl") && err.contains("line 2: window 1 lists the centre (10.5, 20.25) 2 times"),
        "{err}"
    );
    assert!(!err.contains("--pattern"), "{err}");

    // The same, piped: read as detections, the line named as in the file.
    let args = calib("-");
    let (code, _, err) = evcal_stdin(&args.iter().map(String::as_str).collect::<Vec<_>>(), twice.as_bytes());
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("<stdin>") && err.contains("line 1: window 1 lists the centre"), "{err}");
    assert!(!err.contains("text recording"), "{err}");
    // A recording piped in that cannot be read is said to be read as one.
    let (code, _, err) = evcal_stdin(&args.iter().map(String::as_str).collect::<Vec<_>>(), b"#ROSBAG V2.0\n\x01\x02");
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("standard input is read as a recording"), "{err}");

    // Numbers too long to quote: at most 40 bytes of them.
    let long = format!("1{}", "0".repeat(300));
    for args in [
        vec!["calibrate", s(&p), "--pattern", "4x11", "--spacing", "0.024", "--events-per-window", &long],
        vec!["calibrate", s(&p), "--pattern", "4x11", "--spacing", "1e300"],
        vec!["detect", s(&p), "--sensor", &long],
    ] {
        let (code, _, err) = evcal(&args);
        assert_ne!(code, Some(0), "{args:?}: {err}");
        assert!(!err.contains(&"0".repeat(41)), "{args:?}: {err}");
    }
}

#[test]
fn detections_out_of_order_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("det.jsonl");
    for (lines, line, cause) in [
        (vec![window(0, 100), window(1, 200), window(2, 300)].into_iter().rev().collect::<Vec<_>>(), 2, "out of order"),
        (vec![window(0, 100), window(1, 200), window(1, 200)], 3, "repeated window"),
        (vec![window(0, 100), window(1, 100)], 2, "all alike"),
    ] {
        std::fs::write(&p, lines.join("\n")).unwrap();
        let (code, _, err) = evcal(&[
            "calibrate",
            s(&p),
            "--sensor",
            "346x260",
            "--pattern",
            "4x11",
            "--spacing",
            "0.024",
            "--out",
            s(&dir.path().join("o")),
        ]);
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains("det.jsonl") && err.contains(&format!("line {line}:")) && err.contains(cause), "{err}");
    }
    // options that make no sense are refused for detections too (before: ignored)
    std::fs::write(&p, window(0, 100)).unwrap();
    for bad in [["--eps", "nan"], ["--step-ms", "inf"], ["--eps-t", "0"]] {
        let (code, _, err) = evcal(
            &[&["calibrate", s(&p), "--sensor", "346x260", "--pattern", "4x11", "--spacing", "0.024"][..], &bad]
                .concat(),
        );
        // refused as the command line is read (status 2)
        assert_eq!(code, Some(2), "{bad:?}: {err}");
        assert!(err.contains(bad[0]), "{err}");
    }
}
