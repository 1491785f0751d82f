//! Hostile but realistic input (issue 17): every case ends in a clear error or note naming
//! the file, where in it and why; never unbounded memory, never fewer events silently. The
//! files are made here; nothing large is committed.

use evcal_core::{
    event::{Event, SensorSize},
    evt::{Encoding, Evt21Order},
};
use evcal_host::input::recording::{
    prophesee::write::{write_dat, write_raw},
    write_text, OpenOptions, Position, Recording, TimeUnit,
};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::{
    io::Write,
    path::{Path, PathBuf},
    process::{Command, Stdio},
};

// Issue 46's cases, in files of their own.
mod link;
mod options;
mod stray_time;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/formats").join(name)
}

/// evcal, as a test runs it. Tests here write HDF5 files while others run evcal, and a child
/// inherits the writer's open file (HDF5 opens files without close-on-exec) with its
/// exclusive lock, which would keep another test's evcal from opening that file once written:
/// the children leave HDF5's file locks alone.
fn evcal_command() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_evcal"));
    c.env("HDF5_USE_FILE_LOCKING", "FALSE");
    c
}

/// Runs evcal: (exit code, stdout, stderr).
fn evcal(args: &[&str]) -> (Option<i32>, String, String) {
    let o = evcal_command().args(args).output().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// Runs evcal with `stdin` piped in.
fn evcal_stdin(args: &[&str], stdin: &[u8]) -> (Option<i32>, String, String) {
    let mut c =
        evcal_command().args(args).stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut w = c.stdin.take().unwrap();
    let data = stdin.to_vec();
    // A reader that stops early closes the pipe: not an error of the test.
    let writer = std::thread::spawn(move || {
        let _ = w.write_all(&data);
    });
    let o = c.wait_with_output().unwrap();
    writer.join().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// Asserts that `evcal calibrate` gave a calibration: exit status 0 (`verdict: good`) or 4
/// (`verdict: usable, but ...`, as a short test recording's is), the one its JSON result
/// `json` says (`null` when the run wrote none).
#[track_caller]
fn assert_calibrated(code: Option<i32>, json: &serde_json::Value, err: &str) {
    let verdict = json["verdict"].as_str();
    assert!(
        matches!((code, verdict), (Some(0), Some("good")) | (Some(4), Some("usable"))),
        "status {code:?}, verdict {verdict:?}: {err}"
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn events(n: u64, sensor: SensorSize, seed: u64) -> Vec<Event> {
    let mut t = 1_000_000 + seed % 1000;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let k = rng.random::<u64>();
            t += k % 40;
            Event {
                t_us: t,
                x: (k % u64::from(sensor.width)) as u16,
                y: ((k / 7) % u64::from(sensor.height)) as u16,
                polarity: k % 3 == 0,
            }
        })
        .collect()
}

fn read_all(rec: Recording) -> Vec<Event> {
    rec.map(|e| e.unwrap_or_else(|e| panic!("{e}"))).collect()
}

/// Reads `file` through a FIFO named like it (so the extension says the same): a stream that
/// cannot seek, as `<(zcat ...)` gives.
fn read_through_fifo(file: &Path, opts: &OpenOptions) -> (Recording, std::thread::JoinHandle<()>, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join(file.file_name().unwrap());
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let (src, dst) = (file.to_path_buf(), fifo.clone());
    let writer = std::thread::spawn(move || {
        let data = std::fs::read(&src).unwrap();
        let mut f = std::fs::OpenOptions::new().write(true).open(&dst).unwrap();
        // A reader that stops at an error closes the FIFO early.
        let _ = f.write_all(&data);
    });
    let rec = Recording::open_with(&fifo, opts).unwrap_or_else(|e| panic!("{e}"));
    (rec, writer, dir)
}

fn same_through_a_pipe(file: &Path) {
    let want = read_all(Recording::open(file).unwrap());
    let (rec, writer, _dir) = read_through_fifo(file, &OpenOptions::default());
    let opened = Recording::open(file).unwrap();
    assert_eq!(rec.format, opened.format, "{}", file.display());
    assert_eq!(rec.sensor, opened.sensor, "{}", file.display());
    let got = read_all(rec);
    writer.join().unwrap();
    assert_eq!(got.len(), want.len(), "{}", file.display());
    assert!(got == want, "{}: other events through a pipe", file.display());
}

/// Runs evcal under an address-space limit (`ulimit -v`, KiB) and a time limit.
fn evcal_limited(kib: u64, args: &[&str]) -> (Option<i32>, String, String) {
    let cmd = format!("ulimit -v {kib}; exec timeout 60 \"$0\" \"$@\"");
    let o = Command::new("sh")
        .arg("-c")
        .arg(cmd)
        .arg(env!("CARGO_BIN_EXE_evcal"))
        .args(args)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        // The limit counts address space, and glibc reserves 64 MiB of it for each arena of a
        // thread that allocates. The simulator's threads start and end at every step, and under
        // load one may start before the last one's arena is free again, so one more arena (and
        // a failed allocation at 150 MB) came and went with the machine's load (CI, 2026-12-07).
        // Two arenas at most: what is measured is evcal's own memory, not glibc's reservations.
        .env("MALLOC_ARENA_MAX", "2")
        .output()
        .unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// A ROS bag record: header fields `name=value`, then `data`.
fn bag_record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let mut h = Vec::new();
    for (k, v) in fields {
        h.extend(((k.len() + 1 + v.len()) as u32).to_le_bytes());
        h.extend(k.as_bytes());
        h.push(b'=');
        h.extend(*v);
    }
    let mut r = Vec::new();
    r.extend((h.len() as u32).to_le_bytes());
    r.extend(h);
    r.extend((data.len() as u32).to_le_bytes());
    r.extend(data);
    r
}

/// `zeros` zero bytes through `w`, a compressor, in pieces (the test never holds them).
fn write_zeros(w: &mut impl Write, zeros: u64) {
    let block = vec![0u8; 1 << 20];
    for _ in 0..zeros >> 20 {
        w.write_all(&block).unwrap();
    }
}

/// An unindexed ROS bag of one LZ4 chunk that declares `declared` bytes and decompresses to
/// `zeros` zero bytes (about 1/250 of that in the file).
fn bag_bomb(path: &Path, declared: u32, zeros: u64) {
    let mut lz = lz4_flex::frame::FrameEncoder::new(Vec::new());
    write_zeros(&mut lz, zeros);
    let lz = lz.finish().unwrap();
    let mut b = b"#ROSBAG V2.0\n".to_vec();
    b.extend(bag_record(
        &[("op", &[3]), ("index_pos", &0u64.to_le_bytes()), ("conn_count", &[0; 4]), ("chunk_count", &[1, 0, 0, 0])],
        &[],
    ));
    b.extend(bag_record(&[("op", &[5]), ("compression", b"lz4"), ("size", &declared.to_le_bytes())], &lz));
    std::fs::write(path, b).unwrap();
}

/// The committed AEDAT4 fixture `name` (dv-processing's) up to its first packet, its data
/// table position set to none (-1): packets appended to it are read to the end of the file.
fn aedat4_header(name: &str) -> Vec<u8> {
    let mut b = std::fs::read(fixture(name)).unwrap();
    let header_end = 18 + u32::from_le_bytes(b[14..18].try_into().unwrap()) as usize;
    // the data table's position: the only i64 in the header that points into the file's tail
    let table = (header_end as u64..b.len() as u64)
        .rev()
        .find_map(|v| b[18..header_end].windows(8).position(|w| w == v.to_le_bytes()))
        .unwrap()
        + 18;
    b[table..table + 8].copy_from_slice(&(-1i64).to_le_bytes());
    b.truncate(header_end);
    b
}

/// dv-processing's Zstandard AEDAT4 file, its packets replaced by one packet of its event
/// stream that decompresses to `zeros` zero bytes (a few kB in the file), and no data table.
fn aedat4_bomb(path: &Path, zeros: u64) {
    let mut b = aedat4_header("dv_zstd.aedat4");
    let mut z = zstd::stream::Encoder::new(Vec::new(), 3).unwrap();
    write_zeros(&mut z, zeros);
    let z = z.finish().unwrap();
    b.extend(0i32.to_le_bytes()); // the event stream, id 0
    b.extend((z.len() as i32).to_le_bytes());
    b.extend(z);
    std::fs::write(path, b).unwrap();
}

/// An AEDAT4 file of `events` on a 346x260 sensor: the header of dv-processing's uncompressed
/// fixture (streams 0 events, 1 IMU, 2 triggers), no data table, and uncompressed `EVTS`
/// packets of up to 2500 events on stream 0, laid out as dv-processing lays them.
fn aedat4_of_events(path: &Path, events: &[Event]) {
    let mut b = aedat4_header("dv_none.aedat4");
    for packet in events.chunks(2500) {
        // A size-prefixed FlatBuffer: the root table's offset, 'EVTS', padding, the vtable
        // (6 bytes; a table of 8; field 0 at 4), the table (its vtable 6 back; the events
        // vector 4 on), the vector's length and its 16-byte structs.
        let mut fb = Vec::new();
        fb.extend(16u32.to_le_bytes());
        fb.extend(b"EVTS");
        fb.extend([0, 0, 6, 0, 8, 0, 4, 0]);
        fb.extend(6i32.to_le_bytes());
        fb.extend(4u32.to_le_bytes());
        fb.extend((packet.len() as u32).to_le_bytes());
        for e in packet {
            fb.extend((e.t_us as i64).to_le_bytes());
            fb.extend((e.x as i16).to_le_bytes());
            fb.extend((e.y as i16).to_le_bytes());
            fb.extend([u8::from(e.polarity), 0, 0, 0]);
        }
        b.extend(0i32.to_le_bytes()); // the event stream, id 0
        b.extend((fb.len() as i32 + 4).to_le_bytes());
        b.extend((fb.len() as u32).to_le_bytes());
        b.extend(fb);
    }
    std::fs::write(path, b).unwrap();
}

/// A ROS bag, unindexed, of one uncompressed chunk: the connection of `/dvs/events` and an
/// EventArray message stating `width` x `height` for each of `messages`.
fn bag_of_messages(path: &Path, width: u32, height: u32, messages: &[&[Event]]) {
    let conn_header = [bag_record(&[("topic", b"/dvs/events"), ("type", b"dvs_msgs/EventArray")], &[])].concat();
    // the connection header is the record's data: fields without the record's lengths
    let conn_data = conn_header[4..conn_header.len() - 4].to_vec();
    let mut chunk = bag_record(&[("op", &[7]), ("conn", &[0; 4]), ("topic", b"/dvs/events")], &conn_data);
    for events in messages {
        let mut msg = Vec::new();
        msg.extend([0u8; 12]); // seq, stamp
        msg.extend(0u32.to_le_bytes()); // frame_id
        msg.extend(height.to_le_bytes());
        msg.extend(width.to_le_bytes());
        msg.extend((events.len() as u32).to_le_bytes());
        for e in *events {
            msg.extend(e.x.to_le_bytes());
            msg.extend(e.y.to_le_bytes());
            msg.extend(((e.t_us / 1_000_000) as u32).to_le_bytes());
            msg.extend(((e.t_us % 1_000_000 * 1000) as u32).to_le_bytes());
            msg.push(u8::from(e.polarity));
        }
        chunk.extend(bag_record(&[("op", &[2]), ("conn", &[0; 4]), ("time", &[0; 8])], &msg));
    }
    let mut b = b"#ROSBAG V2.0\n".to_vec();
    b.extend(bag_record(
        &[
            ("op", &[3]),
            ("index_pos", &0u64.to_le_bytes()),
            ("conn_count", &[1, 0, 0, 0]),
            ("chunk_count", &[1, 0, 0, 0]),
        ],
        &[],
    ));
    b.extend(bag_record(
        &[("op", &[5]), ("compression", b"none"), ("size", &(chunk.len() as u32).to_le_bytes())],
        &chunk,
    ));
    std::fs::write(path, b).unwrap();
}

/// [`bag_of_messages`] of one message of one event.
fn bag_of_one_message(path: &Path, width: u32, height: u32) {
    bag_of_messages(path, width, height, &[&[Event { t_us: 1_000_000, x: 5, y: 6, polarity: true }]]);
}

/// Root-column HDF5 (x, y, t, p) with attributes on the file.
fn h5_with_attrs(path: &Path, attrs: impl FnOnce(&hdf5::File)) {
    let f = hdf5::File::create(path).unwrap();
    f.new_dataset_builder().with_data(&[1u16, 2, 3]).create("x").unwrap();
    f.new_dataset_builder().with_data(&[1u16, 2, 3]).create("y").unwrap();
    f.new_dataset_builder().with_data(&[1u8, 0, 1]).create("p").unwrap();
    f.new_dataset_builder().with_data(&[5i64, 6, 7]).create("t").unwrap();
    attrs(&f);
}

fn window(seq: u32, t: u64) -> String {
    format!(r#"{{"seq":{seq},"t_ref_us":{t},"events":4000,"noise":10,"centers":[]}}"#)
}

// The cases by kind, in files of their own; the helpers that make their files are above.
mod headers;
mod memory;
mod messages;
mod silent;
mod streams;

// ---- outputs that would clobber something (issue 46) ----------------------------------------

mod outputs;

// ---- far-off times and crowded windows end within seconds; square pixels (issue 46) ------

mod bounded;
