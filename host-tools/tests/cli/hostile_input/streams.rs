//! Streams: pipes, FIFOs and standard input read as the file is.

use super::*;

#[test]
fn every_fixture_reads_the_same_through_a_pipe() {
    for name in [
        "events.txt",
        "dv_lz4.aedat4",
        "dv_zstd.aedat4",
        "ros_bz2.bag",
        "ros_lz4.bag",
        "ecalib.h5",
        "dsec.h5",
        "e2calib.h5",
    ] {
        same_through_a_pipe(&fixture(name));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

    /// Text (with and without a header), RAW in each encoding and DAT: the same events from
    /// a pipe as from the file.
    #[test]
    fn streamed_formats_read_the_same_through_a_pipe(n in 0u64..3000, seed in any::<u64>(), header in any::<bool>()) {
        let dir = tempfile::tempdir().unwrap();
        let sensor = SensorSize::new(640, 480);
        let ev = events(n, sensor, seed);
        let txt = dir.path().join("r.txt");
        write_text(&txt, header.then_some(sensor), &ev).unwrap();
        same_through_a_pipe(&txt);
        for (i, enc) in [Encoding::Evt2, Encoding::Evt3, Encoding::Evt21(Evt21Order::LowHalfFirst), Encoding::Evt21(Evt21Order::HighHalfFirst)].into_iter().enumerate() {
            let raw = dir.path().join(format!("r{i}.raw"));
            write_raw(&raw, enc, sensor, &ev).unwrap();
            same_through_a_pipe(&raw);
        }
        let dat = dir.path().join("r.dat");
        write_dat(&dat, sensor, &ev).unwrap();
        same_through_a_pipe(&dat);
    }
}

#[test]
fn standard_input_keeps_the_header_and_every_event() {
    // Before: the `640 480` header line was lost to format guessing (346x260 guessed, exit 0).
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rec.txt");
    let ev = events(5000, SensorSize::DVXPLORER, 3);
    write_text(&p, Some(SensorSize::DVXPLORER), &ev).unwrap();
    let data = std::fs::read(&p).unwrap();
    let (code, out, err) = evcal_stdin(&["info", "--json", "-"], &data);
    assert_eq!(code, Some(0), "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!((j["width"].as_u64(), j["height"].as_u64(), j["events"].as_u64()), (Some(640), Some(480), Some(5000)));
    assert_eq!(j["file"], "<stdin>");
    // detect on a stream without --sensor: the guessing pass reads a copy, nothing is lost
    // (before: a second open of the FIFO restarted some 2000 events in)
    std::fs::write(&p, data.splitn(2, |&b| b == b'\n').nth(1).unwrap()).unwrap();
    let args = ["detect", "--events-per-window", "500", "--min-pts", "3"];
    let (code, from_file, err) = evcal(&[&args[..], &[s(&p)]].concat());
    assert_eq!(code, Some(0), "{err}");
    let (code, from_pipe, err) = evcal_stdin(&[&args[..], &["-"]].concat(), &std::fs::read(&p).unwrap());
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("evcal: 5000 events") && err.contains("<stdin> does not state its sensor size"), "{err}");
    assert_eq!(from_pipe, from_file);
    // a binary format through standard input: copied to a temporary file, said in a note
    let (code, _, err) = evcal_stdin(
        &["detect", "-", "--events-per-window", "500", "-o", "/dev/null"],
        &std::fs::read(fixture("ros_lz4.bag")).unwrap(),
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("<stdin>: a stream: copied to a temporary file") && err.contains("2000 events"), "{err}");
}

#[test]
fn a_stream_read_twice_gives_the_same_events() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("r.txt");
    let ev = events(20_000, SensorSize::DAVIS346, 9);
    write_text(&p, None, &ev).unwrap();
    let (mut rec, writer, _d) = read_through_fifo(&p, &OpenOptions { rewindable: true, ..Default::default() });
    // the first pass stops half-way: the second still gets everything
    let first: Vec<Event> = rec.by_ref().take(7000).map(Result::unwrap).collect();
    assert_eq!(first[..], ev[..7000]);
    let again = read_all(rec.rewind().unwrap());
    writer.join().unwrap();
    assert!(again == ev);
    // without asking for a copy, a second pass over a stream is an error, never fewer events
    let (mut rec, writer, _d) = read_through_fifo(&p, &OpenOptions::default());
    assert!(rec.by_ref().all(|e| e.is_ok()));
    writer.join().unwrap();
    let e = rec.rewind().err().unwrap().to_string();
    assert!(e.contains("r.txt") && e.contains("cannot be read a second time"), "{e}");
}
