//! Misleading messages and damaged HDF5/Blosc structure: each named, none read past.

use super::*;

#[test]
fn a_byte_order_mark_is_skipped_and_shown_when_quoted() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bom.txt");
    std::fs::write(&p, "\u{feff}346 260\n0.1 1 2 1\n").unwrap();
    let mut rec = Recording::open(&p).unwrap();
    assert_eq!(rec.sensor, Some(SensorSize::DAVIS346));
    assert_eq!(rec.by_ref().count(), 1);
    assert!(rec.notes().iter().any(|n| n.contains("byte-order mark")), "{:?}", rec.notes());
    std::fs::write(&p, "0.1 1 2 1\n\u{feff}0.2 1 2 1\n").unwrap();
    let err = Recording::open(&p).unwrap().find_map(Result::err).unwrap().to_string();
    assert!(err.contains("bom.txt:2:") && err.contains("\\u{feff}"), "{err}");
}

#[test]
fn absurd_spacings_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("det.jsonl");
    std::fs::write(&p, window(0, 100)).unwrap();
    for (spacing, cause) in [("1e-9", "0.001 to 1 m"), ("1e30", "0.001 to 1 m"), ("24", "not millimetres")] {
        let (code, _, err) =
            evcal(&["calibrate", s(&p), "--sensor", "346x260", "--pattern", "4x11", "--spacing", spacing]);
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains("--spacing") && err.contains(cause), "{spacing}: {err}");
    }
    // a grid never found: the sensor size is named beside the pattern
    let out = dir.path().join("o");
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
        s(&out),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("det.jsonl: no grid found on a 346x260 sensor") && err.contains("--sensor"), "{err}");
}

#[test]
fn events_all_back_in_time_are_not_an_empty_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("back.txt");
    let mut ev = events(9000, SensorSize::DAVIS346, 4);
    ev.iter_mut().enumerate().for_each(|(i, e)| e.t_us = 1_000_000 + 10 * i as u64);
    ev.reverse();
    let mut f = std::io::BufWriter::new(std::fs::File::create(&p).unwrap());
    for e in &ev {
        writeln!(f, "{}.{:06} {} {} {}", e.t_us / 1_000_000, e.t_us % 1_000_000, e.x, e.y, u8::from(e.polarity))
            .unwrap();
    }
    drop(f);
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
    assert!(
        err.contains("back.txt") && err.contains("8999 earlier than the one before") && !err.contains("empty"),
        "{err}"
    );
}

#[test]
fn outputs_are_checked_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let (code, _, err) = evcal(&[
        "calibrate",
        s(&fixture("events.txt")),
        "--pattern",
        "4x11",
        "--spacing",
        "0.024",
        "--out",
        s(&out),
        "--json",
        s(dir.path()),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--json") && err.contains("is a directory"), "{err}");
    assert!(!out.exists(), "nothing written before the failure");
    let (code, _, err) = evcal(&["detect", s(&fixture("events.txt")), "-o", s(&dir.path().join("no/such/x.jsonl"))]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("does not exist") && !err.contains("windows:"), "{err}");
}

#[test]
fn replay_of_no_events_prints_no_rate() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("none.txt");
    std::fs::write(&p, "346 260\n").unwrap();
    let mut dev = evcal_command().args(["device", "--listen", "127.0.0.1:0"]).stderr(Stdio::piped()).spawn().unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(dev.stderr.as_mut().unwrap()), &mut line).unwrap();
    let port = line.split("tcp:").nth(1).unwrap().split_whitespace().next().unwrap().to_string();
    let (code, _, err) = evcal(&["replay", s(&p), "--port", &format!("tcp:{port}"), "-o", "/dev/null"]);
    dev.kill().unwrap();
    dev.wait().unwrap();
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("bytes/event") && err.contains("no event"), "{err}");
}

#[test]
fn hdf5_chunks_beyond_the_limit_are_refused_before_reading() {
    // A chunk is read whole: a corrupt or absurd chunk size would cost that much memory. The
    // file itself is small (the chunk compresses to almost nothing).
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge_chunk.h5");
    {
        let f = hdf5::File::create(&p).unwrap();
        let g = f.create_group("events").unwrap();
        for name in ["x", "y"] {
            g.new_dataset_builder().with_data(&[1u16, 2, 3]).create(name).unwrap();
        }
        g.new_dataset_builder().with_data(&[1u8, 0, 1]).create("p").unwrap();
        // 10 M i64 per chunk: 80 MB, beyond the 64 MB limit.
        let t = g.new_dataset::<i64>().chunk(10_000_000).deflate(1).shape(3..).create("t").unwrap();
        t.write(&[5i64, 6, 7]).unwrap();
    }
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("huge_chunk.h5") && err.contains("chunks of 80000000 bytes"), "{err}");
}

#[test]
fn a_non_numeric_events_table_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("strings.h5");
    {
        let f = hdf5::File::create(&p).unwrap();
        let rows: Vec<hdf5::types::FixedAscii<8>> =
            (0..8).map(|i| hdf5::types::FixedAscii::from_ascii(format!("e{i}").as_bytes()).unwrap()).collect();
        let a = ndarray::Array2::from_shape_vec((2, 4), rows).unwrap();
        f.new_dataset_builder().with_data(&a).create("events_data").unwrap();
    }
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("strings.h5") && err.contains("'events_data' holds") && err.contains("not numbers"), "{err}");
}

#[test]
fn calibrate_reads_a_fifo_as_it_reads_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.txt");
    let (code, _, err) = evcal(&["simulate", "--seed", "5", "--seconds", "2.5", "--quiet", "-o", s(&rec)]);
    assert_eq!(code, Some(0), "{err}");
    let calibrate = |input: &Path, out: &str| {
        let json = dir.path().join(format!("{out}.json"));
        let (code, _, err) = evcal(&[
            "calibrate",
            s(input),
            "--pattern",
            "4x11",
            "--spacing",
            "0.024",
            "--out",
            s(&dir.path().join(out)),
            "--json",
            s(&json),
        ]);
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&json).unwrap_or_default()).unwrap_or_default();
        (code, err, v)
    };
    let (code, err, file) = calibrate(&rec, "file");
    assert_calibrated(code, &file, &err);
    let fifo = dir.path().join("fifo.txt");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let (src, dst) = (rec.clone(), fifo.clone());
    let writer = std::thread::spawn(move || {
        let data = std::fs::read(&src).unwrap();
        let _ = std::fs::OpenOptions::new().write(true).open(&dst).unwrap().write_all(&data);
    });
    let (code, err, piped) = calibrate(&fifo, "fifo");
    writer.join().unwrap();
    assert_calibrated(code, &piped, &err);
    for key in ["verdict", "fx", "fy", "cx", "cy", "k1", "rms_px", "views_used", "windows", "detections"] {
        assert_eq!(file[key], piped[key], "{key}: file {} vs FIFO {}", file[key], piped[key]);
        assert!(!file[key].is_null(), "{key} missing: {file}");
    }
}

#[test]
fn a_blosc_chunk_claiming_more_bytes_than_it_has_is_refused() {
    // c-blosc trusts the compressed size in a chunk's own header; HDF5's Blosc filter as the
    // hdf5 crate registers it passed that on unchecked, and a header claiming more than the
    // chunk holds made the decoder read past the buffer (found by the read_h5 fuzz target).
    // evcal now decodes chunks itself (input/recording/hdf5/chunks.rs) and checks the header.
    // Here the first chunk of the DSEC fixture (Blosc-zstd) claims 100 bytes more than it has.
    let mut bytes = std::fs::read(fixture("dsec.h5")).unwrap();
    let header = |b: &[u8], i: usize| {
        let w = |k: usize| u32::from_le_bytes(b[i + k..i + k + 4].try_into().unwrap()) as usize;
        (b[i] == 2 && b[i + 1] == 1, w(4), w(8), w(12))
    };
    let at = (0..bytes.len() - 16)
        .find(|&i| {
            let (magic, decoded, block, compressed) = header(&bytes, i);
            // The next chunk follows right after: a real header, not bytes that look like one.
            magic && decoded > 0 && block > 0 && (16..4096).contains(&compressed) && header(&bytes, i + compressed).0
        })
        .expect("a Blosc chunk in the fixture");
    let compressed = header(&bytes, at).3;
    bytes[at + 12..at + 16].copy_from_slice(&(compressed as u32 + 100).to_le_bytes());
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("overstated.h5");
    std::fs::write(&p, &bytes).unwrap();
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("overstated.h5") && err.contains("does not decode (a Blosc header claiming"), "{err}");
    // The intact file still reads whole.
    let (code, _, err) = evcal(&["info", s(&fixture("dsec.h5"))]);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn hdf5_metadata_declared_beyond_the_file_is_refused_in_bounded_memory() {
    // Each made HDF5 allocate and zero-fill over 2 GB while opening it (the first found by
    // the read_h5 fuzz target): a superblock whose data start far beyond the 69-byte file,
    // and one with a true end but 2 GB of driver information.
    let sig = b"\x89HDF\r\n\x1a\n";
    let v0 = |base: u64, end: u64, driver: u64| {
        let mut b = sig.to_vec();
        b.extend_from_slice(&[0, 0, 0, 0, 0, 8, 8, 0, 4, 0, 16, 0, 0, 0, 0, 0]);
        for a in [base, u64::MAX, end, driver] {
            b.extend_from_slice(&a.to_le_bytes());
        }
        // The root group's symbol table entry.
        b.extend_from_slice(&0u64.to_le_bytes());
        b.extend_from_slice(&200u64.to_le_bytes());
        b.resize(96, 0);
        b
    };
    let mut far = v0(662_026, 662_026, 57);
    far.resize(69, 0);
    let mut driver = v0(0, 176, 96);
    driver.extend_from_slice(&[0, 0, 0, 0]);
    driver.extend_from_slice(&0x8000_0000u32.to_le_bytes());
    driver.extend_from_slice(b"NCSAfami");
    driver.resize(176, 0);
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, cause) in [
        ("far.h5", far, "puts its data from byte 662026"),
        ("driver.h5", driver, "2147483648 bytes of driver information"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let (code, _, err) = evcal_limited(400_000, &["info", s(&p)]);
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains(name) && err.contains("truncated or corrupt") && err.contains(cause), "{err}");
    }
}

#[test]
fn an_hdf5_local_heap_whose_free_list_loops_is_refused_in_bounded_memory() {
    // The read_h5 fuzz target's 40 kB file made evcal take 24 GB in two minutes: HDF5 2.2
    // follows a local heap's free list until it ends, a node per step. The fixture's root
    // group heap, its free list made to name itself.
    let mut b = std::fs::read(fixture("ecalib.h5")).unwrap();
    let at = b.windows(8).position(|w| w == b"HEAP\0\0\0\0").expect("the root group's local heap");
    let word = |b: &[u8], i: usize| u64::from_le_bytes(b[i..i + 8].try_into().unwrap());
    let (size, first, block) = (word(&b, at + 8), word(&b, at + 16), word(&b, at + 24) as usize);
    assert!(first > 1 && first + 16 <= size, "h5py leaves free space in the heap: {first} of {size}");
    let free = block + first as usize;
    b[free..free + 8].copy_from_slice(&first.to_le_bytes());
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("loop.h5");
    std::fs::write(&p, b).unwrap();
    let (code, _, err) = evcal_limited(400_000, &["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("loop.h5") && err.contains(&format!("local heap at byte {at}")) && err.contains("forever"),
        "{err}"
    );
}

#[test]
fn blosc_parameters_that_misstate_the_chunk_size_are_refused() {
    // HDF5 1.10 copies a whole chunk from whatever a filter returns; the Blosc filter holds
    // each decoded chunk to the size its parameters state, so that size must be the chunk's.
    // In the DSEC fixture x and y (u16, 512 per chunk) state 1024 bytes; make them say 1000.
    let bytes = std::fs::read(fixture("dsec.h5")).unwrap();
    let stated = |n: u32| [2u32, 2, 2, n, 5, 1, 5].iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    let (good, bad) = (stated(1024), stated(1000));
    let mut patched = bytes.clone();
    let mut found = 0;
    for i in 0..bytes.len() - good.len() {
        if bytes[i..i + good.len()] == good[..] {
            patched[i..i + bad.len()].copy_from_slice(&bad);
            found += 1;
        }
    }
    assert_eq!(found, 2, "x's and y's filter parameters");
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("misstated.h5");
    std::fs::write(&p, patched).unwrap();
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("misstated.h5") && err.contains("state chunks of 1000 bytes, but its chunks hold 1024"),
        "{err}"
    );
}

#[test]
fn hdf5_chunks_short_of_their_size_are_refused_not_read_past() {
    // HDF5 1.10 copies a whole chunk from whatever a chunk's stored bytes or filters give;
    // valgrind showed reads past the buffer on both files below (a gzip chunk that inflates to
    // 100 of its 1024 bytes; an unfiltered chunk stored in 188 of its 512). evcal reads chunks
    // raw and decodes them itself, each held to its size.
    let dir = tempfile::tempdir().unwrap();
    let n = 2048usize;
    let write = |name: &str, gzip: bool| -> (PathBuf, u64, u64) {
        let p = dir.path().join(name);
        let f = hdf5::File::create(&p).unwrap();
        let g = f.create_group("events").unwrap();
        let xs: Vec<u16> = (0..n).map(|i| (i % 300) as u16).collect();
        let ts: Vec<i64> = (0..n as i64).map(|i| 1000 + i).collect();
        let ps: Vec<u8> = (0..n).map(|i| (i % 2) as u8).collect();
        let b = || {
            let d = g.new_dataset_builder().chunk(512);
            if gzip {
                d.deflate(1)
            } else {
                d
            }
        };
        b().with_data(&xs).create("x").unwrap();
        b().with_data(&xs).create("y").unwrap();
        b().with_data(&ts).create("t").unwrap();
        b().with_data(&ps).create("p").unwrap();
        let x = g.dataset("x").unwrap();
        let mut offset = [0u64];
        let (mut mask, mut addr, mut size) = (0u32, 0u64, 0u64);
        // SAFETY: plain query of an open dataset.
        unsafe {
            hdf5_sys::h5d::H5Dget_chunk_info_by_coord(x.id(), offset.as_mut_ptr(), &mut mask, &mut addr, &mut size);
        }
        (p, addr, size)
    };
    // gzip: the first chunk of x replaced by a zlib stream of 100 zero bytes.
    let (p, addr, size) = write("gzip_short.h5", true);
    let mut bytes = std::fs::read(&p).unwrap();
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(&[0u8; 100]).unwrap();
    let short = z.finish().unwrap();
    assert!(short.len() as u64 <= size);
    bytes[addr as usize..addr as usize + short.len()].copy_from_slice(&short);
    std::fs::write(&p, &bytes).unwrap();
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("gzip_short.h5")
            && err.contains("cannot read x")
            && err.contains("gzip gave 100 bytes where 1024"),
        "{err}"
    );
    // Unfiltered: the chunk index says x's first chunk (1024 bytes) is stored in 188.
    let (p, _, size) = write("stored_short.h5", false);
    assert_eq!(size, 1024);
    let mut bytes = std::fs::read(&p).unwrap();
    // The v1 B-tree's entry for the chunk: its size (u32) then the filter mask, before the
    // chunk's offset; find it by the 1024 that starts it, followed by mask 0 and offset 0.
    let entry: Vec<u8> = [1024u32.to_le_bytes(), 0u32.to_le_bytes()].concat();
    let at = (0..bytes.len() - 16)
        .find(|&i| bytes[i..i + 8] == entry[..] && bytes[i + 8..i + 16] == [0; 8])
        .expect("the chunk's index entry");
    bytes[at..at + 4].copy_from_slice(&188u32.to_le_bytes());
    std::fs::write(&p, &bytes).unwrap();
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("stored_short.h5") && err.contains("188 bytes stored where the chunk takes 1024"), "{err}");
}

#[test]
fn a_file_that_killed_hdf5_1_10_is_an_error() {
    // Found by the read_h5 fuzz target (a mutated h5py file, minimised by libFuzzer): HDF5
    // 1.10, the system library evcal linked before, died of SIGFPE (a division by zero in
    // H5D__chunk_set_info) opening one of its datasets, and evcal with it (exit status 136).
    // HDF5 2.x, which evcal now builds from source, refuses the file.
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hostile/hdf5_chunk_sigfpe.h5");
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("hdf5_chunk_sigfpe.h5") && err.contains("not a readable HDF5 file"), "{err}");
}

#[test]
fn a_chunk_dimension_of_zero_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("zero_chunk.h5");
    {
        // The earliest format (as h5py writes by default): object headers without checksums.
        let f = hdf5::File::with_options().with_fapl(|a| a.libver_earliest()).create(&p).unwrap();
        let g = f.create_group("events").unwrap();
        let v: Vec<u16> = (0..2000).map(|i| (i % 300) as u16).collect();
        g.new_dataset_builder().chunk(700).with_data(&v).create("x").unwrap();
        g.new_dataset_builder().chunk(700).with_data(&v).create("y").unwrap();
        g.new_dataset_builder().chunk(700).with_data(&(0..2000i64).collect::<Vec<_>>()).create("t").unwrap();
        g.new_dataset_builder().chunk(700).with_data(&vec![1u8; 2000]).create("p").unwrap();
    }
    let mut bytes = std::fs::read(&p).unwrap();
    // The layout message of x: version 3, chunked, 2 dimensions (700 values of 2 bytes).
    let dims: Vec<u8> = [700u32.to_le_bytes(), 2u32.to_le_bytes()].concat();
    let at = (11..bytes.len() - 8)
        .find(|&i| bytes[i..i + 8] == dims[..] && bytes[i - 11..i - 8] == [3, 2, 2])
        .expect("x's layout message");
    bytes[at..at + 4].copy_from_slice(&0u32.to_le_bytes());
    std::fs::write(&p, &bytes).unwrap();
    let (code, _, err) = evcal(&["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("zero_chunk.h5") && err.contains("'events/x'") && err.contains("chunk dimension"), "{err}");
}

#[test]
fn simulate_follows_recorded_poses_and_refuses_bad_ones() {
    let dir = tempfile::tempdir().unwrap();
    // The board 0.5 m ahead, sliding 5 cm to the left over 0.5 s; a DAVIS346-like camera and
    // a 3x7 grid of 34 mm, as an emulator's truth.json gives them.
    let frames: Vec<_> = (0..=5)
        .map(|k| {
            let t = 0.1 * f64::from(k);
            serde_json::json!({ "t": t, "rvec": [0.0, 0.0, 0.0], "tvec": [-0.1 - 0.1 * t, -0.06, 0.5] })
        })
        .collect();
    let file = serde_json::json!({
        "K": { "fx": 355.0, "fy": 354.3, "cx": 160.4, "cy": 125.3 },
        "dist": { "k1": -0.34, "k2": 0.12, "p1": -0.0005, "p2": -0.0005, "k3": 0.0 },
        "sensor": { "width": 346, "height": 260 },
        "pattern": { "rows": 3, "cols": 7, "spacing_m": 0.034, "radius_m": 0.0119 },
        "frames30": { "frames": frames },
    });
    let poses = dir.path().join("truth.json");
    std::fs::write(&poses, file.to_string()).unwrap();
    // Into a folder that does not exist yet.
    let out = dir.path().join("new").join("rec.txt");
    let (code, _, err) =
        evcal(&["simulate", "--poses", s(&poses), "--seconds", "0.5", "--step-ms", "100", "-o", s(&out)]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("motion, camera, sensor size, grid from"), "{err}");
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("new").join("truth.json")).unwrap()).unwrap();
    assert_eq!((truth["board"]["rows"].as_u64(), truth["board"]["cols"].as_u64()), (Some(3), Some(7)));
    assert_eq!(truth["camera"]["fx"].as_f64(), Some(355.0));
    let windows = truth["windows"].as_array().unwrap();
    assert!(!windows.is_empty());
    for w in windows {
        // The poses between the file's are its poses' line.
        let t = w["t_ref_us"].as_f64().unwrap() * 1e-6;
        let x = w["tvec"][0].as_f64().unwrap();
        assert!((x - (-0.1 - 0.1 * t)).abs() < 1e-9, "at {t} s the board is at x {x}");
    }
    // Beyond the poses, a file of none, and a file that is not a motion: refused, with why.
    let (code, _, err) = evcal(&["simulate", "--poses", s(&poses), "--seconds", "2", "-o", s(&out)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("goes beyond them"), "{err}");
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"frames": [{"t": 0, "rvec": [0, 0, 0], "tvec": [0, 0, 0.5]}]}"#).unwrap();
    let (code, _, err) = evcal(&["simulate", "--poses", s(&bad), "-o", s(&dir.path().join("x.txt"))]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("bad.json holds no motion to follow") && err.contains("at least 2"), "{err}");
    assert!(!dir.path().join("x.txt").exists());
    let (code, _, err) = evcal(&["simulate", "--poses", s(&poses), "--trajectory", "spiral", "-o", s(&out)]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("cannot be used with"), "{err}");
}

/// Before: a pattern given with its rows and columns the other way round (`--pattern 11x4`
/// for a 4x11 board) ended in "no grid found" after detecting the recording again with filled
/// discs; now the run tries the swapped pattern on a sample of windows and names it.
#[test]
fn a_pattern_the_other_way_round_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("cone.txt");
    let out = dir.path().join("out");
    let (code, _, err) = evcal(&[
        "simulate",
        "--sensor",
        "davis346",
        "--pattern",
        "4x11",
        "--seconds",
        "0.4",
        "--out",
        s(&rec),
        "--truth",
        s(&dir.path().join("truth.json")),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let (code, _, err) = evcal(&["calibrate", s(&rec), "--pattern", "11x4", "--spacing", "0.024", "--out", s(&out)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("run again with --pattern 4x11"), "{err}");
    assert!(!err.contains("filled discs"), "the discs were tried first: {err}");
    // A square pattern has no other way round: the usual error.
    let (code, _, err) = evcal(&["calibrate", s(&rec), "--pattern", "5x5", "--spacing", "0.024", "--out", s(&out)]);
    assert_ne!(code, Some(0), "{err}");
    assert!(!err.contains("other way round"), "{err}");
}

/// Before (issue 44): `simulate` said nothing of how large or long a run would be until it
/// ended (a leak of 10 kHz a pixel makes gigabytes). Now, half a second into the simulated
/// time, it says the events, megabytes and seconds the whole run will take at that rate.
#[test]
fn simulate_says_how_large_and_long_before_the_end() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.txt");
    let (code, _, err) =
        evcal(&["simulate", "--seconds", "0.8", "--out", s(&rec), "--truth", s(&dir.path().join("t.json"))]);
    assert_eq!(code, Some(0), "{err}");
    let line = err.lines().find(|l| l.contains("at the rate of the first")).unwrap_or_else(|| panic!("{err}"));
    // "... about 0.7 M events, 12 MB, about ..." against what was written.
    let number_before = |unit: &str| -> f64 {
        let head = &line[..line.find(unit).unwrap_or_else(|| panic!("{line}"))];
        head.trim_end().rsplit(' ').next().unwrap().parse().unwrap_or_else(|_| panic!("{line}"))
    };
    let (events, mb) = (number_before(" M events") * 1e6, number_before(" MB") * 1e6);
    let written = std::fs::read_to_string(&rec).unwrap();
    let (n, bytes) = (written.lines().count() as f64 - 1.0, written.len() as f64);
    assert!((events / n - 1.0).abs() < 0.5, "{line}: {n} events written");
    assert!((mb / bytes - 1.0).abs() < 0.5, "{line}: {bytes} bytes written");
    // Short runs are not worth the line.
    let (code, _, err) = evcal(&[
        "simulate",
        "--seconds",
        "0.3",
        "--out",
        s(&dir.path().join("short.txt")),
        "--truth",
        s(&dir.path().join("t2.json")),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("at the rate of the first"), "{err}");
}
