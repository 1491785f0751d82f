//! HDF5 recordings: this module reads and writes E-Calib's layout (a dataset `events_data`,
//! N x 4 rows of `[x, y, p, t_seconds]`); [`cols`] reads the layouts of one dataset per field.
//!
//! The pieces are layered so that imports go one way, from the readers down:
//!
//! * this module and [`cols`] (with [`attrs`], what a file's attributes say) open a file
//!   through [`file`](mod@file) and read its datasets through [`chunks`];
//! * [`chunks`] finds chunks in [`index`] and undoes their filters, naming a missing one
//!   with [`filters`];
//! * [`filters`] checks a dataset's parameters, Blosc's through [`blosc`] (whose decoder
//!   [`file`](mod@file) installs before any file is opened);
//! * [`limits`], the bounds every piece shares, imports none of them.
//!
//! Only [`blosc`], [`chunks`] and [`index`] call HDF5's C library directly, so only they may
//! use `unsafe` (the crate denies it elsewhere); each says why a call is sound.

mod attrs;
#[allow(unsafe_code)] // HDF5's C library: see the module's SAFETY notes
mod blosc;
#[allow(unsafe_code)] // HDF5's C library: see the module's SAFETY notes
mod chunks;
mod cols;
mod file;
mod filters;
#[allow(unsafe_code)] // HDF5's C library: see the module's SAFETY notes
mod index;
mod limits;

pub(super) use cols::layout;
pub use cols::H5ColumnsReader;

use super::types::{EventSource, Position, ReadError};
use evcal_core::event::{Event, SensorSize};
use limits::READ_ROWS;
use std::path::{Path, PathBuf};

/// Streaming reader of E-Calib HDF5 recordings.
pub struct H5Reader {
    path: PathBuf,
    ds: chunks::Column,
    rows: usize,
    next_row: usize,
    chunk: Vec<[f64; 4]>,
    at: usize,
    failed: bool,
    sensor: Option<SensorSize>,
}

impl H5Reader {
    /// Opens `path` and checks that `events_data` is an N x 4 numeric table.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let err = |m: String| ReadError::new(path, Position::File, m);
        let file = file::open(path).map_err(err)?;
        let ds = file.dataset("events_data").map_err(|_| {
            let names = file.member_names().unwrap_or_default().join(", ");
            err(format!(
                "no event layout evcal knows: neither 'events_data' (E-Calib: N x 4 [x, y, p, t]) nor \
                 datasets x, y, t, p in 'events/' or at the root; the file has: [{names}]"
            ))
        })?;
        filters::check_filters(&ds).map_err(|m| err(format!("'events_data': {m}")))?;
        // Any other type (strings, compounds of kilobytes) would make HDF5 allocate a
        // conversion buffer of rows times its size before finding anything wrong (a corrupt
        // file took 4 GB that way).
        match ds.dtype().and_then(|t| t.to_descriptor()) {
            Ok(
                hdf5::types::TypeDescriptor::Float(_)
                | hdf5::types::TypeDescriptor::Integer(_)
                | hdf5::types::TypeDescriptor::Unsigned(_),
            ) => {}
            Ok(other) => return Err(err(format!("'events_data' holds {other:?}, not numbers"))),
            Err(e) => return Err(err(format!("'events_data' has a type evcal cannot read: {e}"))),
        }
        let shape = ds.shape();
        if shape.len() != 2 || shape[1] != 4 {
            return Err(err(format!("'events_data' has shape {shape:?}; expected N x 4 [x, y, p, t_seconds]")));
        }
        let ds = chunks::Column::open(ds).map_err(|m| err(format!("'events_data': {m}")))?;
        // E-Calib's layout states no size; evcal's writer adds `width` and `height` to the file.
        let root: &hdf5::Location = &file;
        let sensor = attrs::size_attrs(root).map_err(err)?;
        Ok(Self {
            path: path.to_path_buf(),
            ds,
            rows: shape[0],
            next_row: 0,
            chunk: Vec::new(),
            at: 0,
            failed: false,
            sensor,
        })
    }

    /// The sensor size the file's `width` and `height` attributes state, if they do.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    /// Number of events in the file.
    pub fn len(&self) -> u64 {
        self.rows as u64
    }

    /// Whether the file holds no events.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    fn fill(&mut self) -> Result<(), ReadError> {
        let end = (self.next_row + READ_ROWS).min(self.rows);
        let a = self.ds.read::<f64>(self.next_row..end).map_err(|m| {
            ReadError::new(&self.path, Position::Row(self.next_row as u64), format!("cannot read events_data: {m}"))
        })?;
        self.chunk.clear();
        self.chunk.extend(a.chunks_exact(4).map(|r| [r[0], r[1], r[2], r[3]]));
        self.at = 0;
        self.next_row = end;
        Ok(())
    }
}

impl EventSource for H5Reader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.failed {
            return None;
        }
        if self.at >= self.chunk.len() {
            if self.next_row >= self.rows {
                return None;
            }
            if let Err(e) = self.fill() {
                self.failed = true;
                return Some(Err(e));
            }
        }
        let row = (self.next_row - self.chunk.len() + self.at) as u64;
        let [x, y, p, t] = self.chunk[self.at];
        self.at += 1;
        let r = row_to_event(x, y, p, t).map_err(|m| ReadError::new(&self.path, Position::Row(row), m));
        self.failed = r.is_err();
        Some(r)
    }

    fn progress_bytes(&self) -> u64 {
        // 32 bytes a row as f64: a fair scale against the file size.
        (self.next_row - self.chunk.len() + self.at) as u64 * 32
    }
}

fn row_to_event(x: f64, y: f64, p: f64, t: f64) -> Result<Event, String> {
    let coord = |v: f64, name: &str| -> Result<u16, String> {
        if (0.0..=65535.0).contains(&v) && v.fract() == 0.0 {
            Ok(v as u16)
        } else {
            Err(format!("bad {name} {v} (an integer pixel coordinate)"))
        }
    };
    let x = coord(x, "x")?;
    let y = coord(y, "y")?;
    let polarity = if p == 1.0 {
        true
    } else if p == 0.0 || p == -1.0 {
        false
    } else {
        return Err(format!("bad polarity {p} (1/0 or 1/-1)"));
    };
    if !(t.is_finite() && (0.0..1.8e13).contains(&t)) {
        return Err(format!("bad timestamp {t} s"));
    }
    Ok(Event { t_us: (t * 1e6).round() as u64, x, y, polarity })
}

/// Writes events in E-Calib's layout (`events_data`, N x 4 f64 `[x, y, p, t_seconds]`).
/// The HDF5 library writes a temporary file beside `path`, renamed over it at the end
/// ([`crate::export::atomic`]): a failure leaves `path` as it was.
pub fn write_ecalib_h5(path: &Path, events: &[Event]) -> Result<(), String> {
    let mut w = EcalibH5Writer::create(path)?;
    w.write(events)?;
    w.finish()
}

/// Rows of `events_data` a writer holds before it writes them (and the dataset's chunk):
/// 2 MiB, whatever the recording's length.
const WRITE_ROWS: usize = 1 << 16;

/// Writes events in E-Calib's layout as they come, `WRITE_ROWS` (65 536) rows at a time, into a dataset
/// that grows: memory does not grow with the recording.
pub struct EcalibH5Writer {
    path: std::path::PathBuf,
    staged: crate::export::atomic::AtomicFile,
    file: hdf5::File,
    data: hdf5::Dataset,
    rows: usize,
    held: Vec<f64>,
}

impl EcalibH5Writer {
    /// Starts `path` with an empty `events_data`: the HDF5 library writes a temporary file
    /// beside it, renamed over it by [`EcalibH5Writer::finish`]; dropped before, `path` is left
    /// as it was.
    pub fn create(path: &Path) -> Result<Self, String> {
        let fail = |e: hdf5::Error| format!("{}: cannot write events_data: {e}", path.display());
        let staged = crate::export::atomic::AtomicFile::create(path).map_err(|e| e.to_string())?;
        let file = hdf5::File::create(staged.path()).map_err(|e| format!("{}: {e}", path.display()))?;
        let shape = hdf5::SimpleExtents::from_vec(vec![hdf5::Extent::resizable(0), hdf5::Extent::from(4)]);
        let data = file.new_dataset::<f64>().shape(shape).chunk((WRITE_ROWS, 4)).create("events_data").map_err(fail)?;
        Ok(Self { path: path.to_path_buf(), staged, file, data, rows: 0, held: Vec::with_capacity(WRITE_ROWS * 4) })
    }

    /// States the sensor's size in the file (`width` and `height` attributes of its root, as
    /// DSEC's files state theirs), so that a reader needs no `--sensor`.
    pub fn with_sensor(self, sensor: SensorSize) -> Result<Self, String> {
        let fail = |e: hdf5::Error| format!("{}: cannot write the sensor size: {e}", self.path.display());
        for (name, v) in [("width", sensor.width), ("height", sensor.height)] {
            let a = self.file.new_attr::<u32>().create(name).map_err(fail)?;
            a.write_scalar(&u32::from(v)).map_err(fail)?;
        }
        Ok(self)
    }

    /// Appends `events`.
    pub fn write(&mut self, events: &[Event]) -> Result<(), String> {
        for e in events {
            self.held.extend([f64::from(e.x), f64::from(e.y), f64::from(u8::from(e.polarity)), e.t_us as f64 * 1e-6]);
            if self.held.len() == WRITE_ROWS * 4 {
                self.flush()?;
            }
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), String> {
        let n = self.held.len() / 4;
        if n == 0 {
            return Ok(());
        }
        let fail = |e: String| format!("{}: cannot write events_data: {e}", self.path.display());
        let arr = ndarray::ArrayView2::from_shape((n, 4), &self.held).map_err(|e| fail(e.to_string()))?;
        self.data.resize((self.rows + n, 4)).map_err(|e| fail(e.to_string()))?;
        self.data.write_slice(&arr, ndarray::s![self.rows..self.rows + n, ..]).map_err(|e| fail(e.to_string()))?;
        self.rows += n;
        self.held.clear();
        Ok(())
    }

    /// Writes what is held, closes the file and puts it in place.
    pub fn finish(mut self) -> Result<(), String> {
        self.flush()?;
        let Self { path, staged, file, data, .. } = self;
        drop(data);
        // Closed here, with its error, not on a drop that would swallow it.
        file.close().map_err(|e| format!("{}: {e}", path.display()))?;
        staged.commit().map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod test {
    use super::chunks::Column;
    use super::*;
    use crate::input::recording::{types::Format, Recording};

    #[test]
    fn round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rec.h5");
        let events: Vec<Event> = (0..70_000u64)
            .map(|i| Event { t_us: i * 13 + 1_000_000, x: (i % 640) as u16, y: (i % 480) as u16, polarity: i % 2 == 0 })
            .collect();
        write_ecalib_h5(&p, &events).unwrap();
        assert_eq!(Format::detect(&p).unwrap(), Format::EcalibH5);
        let rec = Recording::open(&p).unwrap();
        assert_eq!(rec.len, Some(70_000));
        let back: Vec<Event> = rec.map(Result::unwrap).collect();
        assert_eq!(back, events);

        // a foreign HDF5 file: named, with what it holds
        let q = dir.path().join("other.h5");
        let f = hdf5::File::create(&q).unwrap();
        f.new_dataset_builder().with_data(&ndarray::arr2(&[[1.0f64, 2.0], [3.0, 4.0]])).create("x").unwrap();
        drop(f);
        let msg = Recording::open(&q).err().unwrap().to_string();
        assert!(msg.contains("other.h5") && msg.contains("events_data") && msg.contains("[x]"), "{msg}");

        // a bad row: named by its index
        let r = dir.path().join("badrow.h5");
        let f = hdf5::File::create(&r).unwrap();
        let a = ndarray::arr2(&[[1.0f64, 2.0, 1.0, 0.1], [1.5, 2.0, 1.0, 0.2]]);
        f.new_dataset_builder().with_data(&a).create("events_data").unwrap();
        drop(f);
        let errs: Vec<_> = Recording::open(&r).unwrap().filter_map(Result::err).collect();
        assert_eq!(errs.len(), 1);
        assert_eq!(errs[0].at, Position::Row(1));

        // not HDF5 at all, but named .h5
        let s = dir.path().join("fake.h5");
        std::fs::write(&s, "hello").unwrap();
        let msg = Recording::open(&s).err().unwrap().to_string();
        assert!(msg.contains("fake.h5") && msg.contains("HDF5"), "{msg}");
    }

    /// evcal's writer states the sensor's size (`simulate --out rec.h5`), its reader takes
    /// it; E-Calib's own files state none; a size evcal cannot use is an error that says it.
    #[test]
    fn the_sensor_size_is_written_and_read() {
        let dir = tempfile::tempdir().unwrap();
        let events = [Event { t_us: 1_000_000, x: 5, y: 6, polarity: true }];
        let sized = dir.path().join("sized.h5");
        let sensor = SensorSize { width: 640, height: 480 };
        let mut w = EcalibH5Writer::create(&sized).unwrap().with_sensor(sensor).unwrap();
        w.write(&events).unwrap();
        w.finish().unwrap();
        let rec = Recording::open(&sized).unwrap();
        assert_eq!(rec.sensor, Some(sensor));
        assert_eq!(rec.map(Result::unwrap).collect::<Vec<_>>(), events);
        let plain = dir.path().join("plain.h5");
        write_ecalib_h5(&plain, &events).unwrap();
        assert_eq!(Recording::open(&plain).unwrap().sensor, None);
        let odd = dir.path().join("odd.h5");
        let f = hdf5::File::create(&odd).unwrap();
        f.new_dataset_builder().with_data(&ndarray::arr2(&[[5.0f64, 6.0, 1.0, 1.0]])).create("events_data").unwrap();
        f.new_attr::<f64>().create("width").unwrap().write_scalar(&346.7).unwrap();
        f.new_attr::<f64>().create("height").unwrap().write_scalar(&260.0).unwrap();
        drop(f);
        let msg = Recording::open(&odd).err().unwrap().to_string();
        assert!(msg.contains("346.7") && msg.contains("not a whole number"), "{msg}");
    }

    /// 40 000 chunks of 4 rows, plain and gzip: every row read, in the order written, and the
    /// listing made once (the lookup per chunk walked them all: 40 000² / 2 steps, some 40 s).
    #[test]
    fn many_small_chunks_read_fully_and_a_chunk_never_written_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("small_chunks.h5");
        let n = 160_000usize;
        let ts: Vec<i64> = (0..n).map(|i| 1_000_000 + 3 * i as i64).collect();
        let rows = ndarray::Array2::from_shape_fn((n / 4, 2), |(i, j)| (2 * i + j) as u16);
        {
            let f = hdf5::File::create(&path).unwrap();
            f.new_dataset_builder().chunk(4).with_data(&ts).create("plain").unwrap();
            f.new_dataset_builder().chunk(4).deflate(1).with_data(&ts).create("gzip").unwrap();
            f.new_dataset_builder().chunk((2, 1)).with_data(&rows).create("rows").unwrap();
            // Rows 0..50 of 100 written: chunks from row 50 on are not stored.
            let part = f.new_dataset::<i64>().chunk(10).shape(100).create("part").unwrap();
            part.write_slice(&ts[..50], 0..50).unwrap();
        }
        let f = hdf5::File::open(&path).unwrap();
        for name in ["plain", "gzip"] {
            let mut c = Column::open(f.dataset(name).unwrap()).unwrap();
            let started = std::time::Instant::now();
            assert_eq!(c.read::<i64>(0..n).unwrap(), ts, "{name}");
            // Correctness is the test; this bound, far above the listing's milliseconds, only
            // catches a return to a walk per chunk.
            assert!(started.elapsed().as_secs_f64() < 5.0, "{name}: {:?}", started.elapsed());
        }
        let mut c = Column::open(f.dataset("rows").unwrap()).unwrap();
        assert_eq!(
            c.read::<i64>(3..n / 4).unwrap(),
            rows.slice(ndarray::s![3.., ..]).iter().map(|&v| i64::from(v)).collect::<Vec<_>>()
        );
        let mut c = Column::open(f.dataset("part").unwrap()).unwrap();
        assert_eq!(c.read::<i64>(0..50).unwrap(), ts[..50]);
        let err = c.read::<i64>(45..60).unwrap_err();
        assert!(err.contains("the chunk from row 50 is not stored"), "{err}");
    }
}
