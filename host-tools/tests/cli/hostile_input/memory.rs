//! Bounded memory: endless input, decompression bombs and large simulations within limits.

use super::*;

#[test]
fn endless_nul_bytes_end_in_a_short_error_within_bounded_memory() {
    // Before: `info /dev/zero` grew by about 1 GB/s; now a line limit stops it at once.
    for args in [&["info", "/dev/zero"][..], &["detect", "/dev/zero", "--sensor", "346x260"], &["detect", "/dev/zero"]]
    {
        let (code, _, err) = evcal_limited(400_000, args);
        let cmd = args[0];
        assert_eq!(code, Some(1), "{cmd}: {err}");
        assert!(err.contains("/dev/zero:1:") && err.contains("longer than 4096 bytes"), "{err}");
        assert!(err.len() < 400, "the error quotes a few dozen bytes, not the line: {} bytes", err.len());
    }
    // A 64 MB file of NUL bytes, which took 890 MB and echoed itself into the error.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("zeros.txt");
    let f = std::fs::File::create(&p).unwrap();
    f.set_len(64 << 20).unwrap();
    let (code, _, err) = evcal_limited(400_000, &["info", s(&p)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("zeros.txt:1:") && err.contains("longer than 4096 bytes") && err.len() < 400, "{err}");
    // Detections: one endless line.
    let j = dir.path().join("d.jsonl");
    std::fs::write(&j, vec![b'{'; 3 << 20]).unwrap();
    let (code, _, err) =
        evcal_limited(400_000, &["calibrate", s(&j), "--sensor", "346x260", "--pattern", "4x11", "--spacing", "0.024"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("d.jsonl") && err.contains("line 1") && err.contains("longer than") && err.len() < 600,
        "{err}"
    );
}

#[test]
fn decompression_bombs_are_refused_in_bounded_memory() {
    // Before: a chunk declaring 1 GiB was allocated, then filled (1.06 GB of RSS for a 4 MB
    // bag); an AEDAT4 packet was decompressed up to 512 MiB (538 MB for 19 kB). Under a
    // 400 MB address space both died in the allocator.
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bomb.bag");
    bag_bomb(&bag, 1 << 30, 256 << 20);
    let (code, _, err) = evcal_limited(400_000, &["info", s(&bag)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("bomb.bag: byte") && err.contains("in the chunk's uncompressed data at offset 0"), "{err}");
    let aedat = dir.path().join("bomb.aedat4");
    aedat4_bomb(&aedat, 512 << 20);
    assert!(std::fs::metadata(&aedat).unwrap().len() < 100_000);
    let (code, _, err) = evcal_limited(400_000, &["info", s(&aedat)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("bomb.aedat4: byte") && err.contains("decompresses to more than 67108864 bytes"), "{err}");
}

/// Before: `simulate` held every event until the end (16 bytes each, 32 more for HDF5): a
/// leak of 10 kHz a pixel over 0.1 s took 1.4 GB. Now they are written as they come: these
/// 5 M events (80 MB held, 200 MB while the vector grew) fit in 150 MB of address space.
#[test]
fn simulate_writes_as_it_goes_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let mut counts = Vec::new();
    for name in ["rec.txt", "rec.h5"] {
        // A folder each: the truth.json beside a recording is that recording's.
        let folder = dir.path().join(name.replace('.', "-"));
        std::fs::create_dir(&folder).unwrap();
        let out = folder.join(name);
        let (code, _, err) = evcal_limited(
            150_000,
            &[
                "simulate",
                "--shot-noise-hz",
                "1e3",
                "--seconds",
                "0.1",
                "--out",
                s(&out),
                "--events-per-window",
                "30000",
            ],
        );
        assert_eq!(code, Some(0), "{name}: {err}");
        let n: u64 = err.split("evcal: ").nth(1).and_then(|l| l.split(' ').next()).unwrap().parse().unwrap();
        assert!(n > 4_000_000, "{name}: {n} events");
        counts.push(n);
    }
    assert_eq!(counts[0], counts[1], "the same events whatever the format");
    assert_eq!(Recording::open(&dir.path().join("rec-h5/rec.h5")).unwrap().len, Some(counts[1]));
}

/// Writes the two decompression bombs of issue 46, full size, into `$EVCAL_BOMB_DIR`, to
/// measure evcal's peak memory on them (`/usr/bin/time -v evcal info ...`).
#[test]
#[ignore = "writes files for a measurement"]
fn write_decompression_bombs() {
    let dir = PathBuf::from(std::env::var("EVCAL_BOMB_DIR").expect("EVCAL_BOMB_DIR"));
    bag_bomb(&dir.join("bomb.bag"), 1 << 30, 1 << 30);
    aedat4_bomb(&dir.join("bomb.aedat4"), 512 << 20);
}

#[test]
fn a_binary_file_read_as_text_names_line_and_cause() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bin.txt");
    std::fs::write(&p, b"0.1 1 2 1\n0.2 3\x004 1\n").unwrap();
    let err = Recording::open(&p).unwrap().find_map(Result::err).unwrap();
    assert_eq!(err.at, Position::Line(2));
    assert!(err.to_string().contains("bin.txt:2:") && err.message.contains("NUL byte"), "{err}");
}
