//! HDF5 recordings stored as one dataset per field: the group `events/` with `x`, `y`, `t`, `p`
//! (DSEC, Prophesee-to-HDF5 converters, ...) and e2calib's `x`, `y`, `p`, `t` at the root.
//!
//! Fields may have any integer type (`p` also boolean, 0/1 or -1/1; `t` also float, in
//! seconds). The unit of an integer `t` is decided, in this order, by: the caller
//! (`--time-unit`); a `unit`/`units`/`time_unit` attribute on `t`, its group or the file;
//! DSEC's convention (a `t_offset` dataset beside the group: `t` in µs from it); then by
//! magnitude. Absolute times in ns (≥ 1e17, today's Unix time in ns) are told from those in µs
//! (≥ 1e14); for relative times, ns is chosen when µs would make the recording longer than a
//! day, or when every timestamp of the first block is a multiple of 1000 (ns from a µs
//! clock), µs otherwise. A guess is reported as a note, with its reason.
//! The sensor size is read from `width`/`height` (or `sensor_width`/`sensor_height`)
//! attributes of the group or the file when present.

use super::attrs::{size_attrs, unit_attr};
use super::chunks::Column;
use super::filters::check_filters;
use super::limits::READ_ROWS;
use crate::input::recording::types::{EventSource, Format, Position, ReadError, TimeUnit};
use evcal_core::event::{Event, SensorSize};
use hdf5::types::TypeDescriptor;
use std::path::{Path, PathBuf};

/// Which column layout a file has, by its datasets; `None` if neither.
pub(crate) fn layout(path: &Path) -> Option<Format> {
    let f = super::file::open(path).ok()?;
    let has_all = |prefix: &str| ["x", "y", "t", "p"].iter().all(|n| f.link_exists(&format!("{prefix}{n}")));
    if f.link_exists("events_data") {
        None
    } else if f.link_exists("events") && has_all("events/") {
        Some(Format::EventsGroupH5)
    } else if has_all("") {
        Some(Format::RootColumnsH5)
    } else {
        None
    }
}

/// Timestamps as stored: integers of a unit, or float seconds.
enum TimeColumn {
    Int(TimeUnit),
    FloatSeconds,
}

/// Streaming reader of the column layouts.
pub struct H5ColumnsReader {
    path: PathBuf,
    x: Column,
    y: Column,
    t: Column,
    p: Column,
    /// `t` is u64: read as such, since HDF5's conversion to i64 saturates values above
    /// i64::MAX to one value (every such event at the same time, silently).
    t_u64: bool,
    time: TimeColumn,
    offset_us: i64,
    rows: usize,
    next_row: usize,
    sensor: Option<SensorSize>,
    notes: Vec<String>,
    buf: Chunk,
    at: usize,
    failed: bool,
}

#[derive(Default)]
struct Chunk {
    x: Vec<i64>,
    y: Vec<i64>,
    p: Vec<i64>,
    t: Vec<i64>,
    tu: Vec<u64>,
    tf: Vec<f64>,
}

impl H5ColumnsReader {
    /// Opens `path` in `layout` ([`Format::EventsGroupH5`] or [`Format::RootColumnsH5`]),
    /// with the time unit `unit` if given, else decided as the module says.
    pub fn open(path: &Path, layout: Format, unit: Option<TimeUnit>) -> Result<Self, ReadError> {
        let err = |m: String| ReadError::new(path, Position::File, m);
        let file = super::file::open(path).map_err(err)?;
        let prefix = if layout == Format::EventsGroupH5 { "events/" } else { "" };
        let ds = |n: &str| -> Result<hdf5::Dataset, ReadError> {
            let d = file.dataset(&format!("{prefix}{n}")).map_err(|e| err(format!("no dataset '{prefix}{n}': {e}")))?;
            if d.ndim() != 1 {
                return Err(err(format!("'{prefix}{n}' has shape {:?}; expected one value per event", d.shape())));
            }
            Ok(d)
        };
        let (x, y, t, p) = (ds("x")?, ds("y")?, ds("t")?, ds("p")?);
        for (d, n) in [(&x, "x"), (&y, "y"), (&t, "t"), (&p, "p")] {
            check_filters(d).map_err(|m| err(format!("'{prefix}{n}': {m}")))?;
        }
        let lens = [x.size(), y.size(), t.size(), p.size()];
        if lens.iter().any(|&n| n != lens[0]) {
            return Err(err(format!(
                "the event fields differ in length (x {}, y {}, t {}, p {}): the file is damaged or incomplete",
                lens[0], lens[1], lens[2], lens[3]
            )));
        }
        let rows = lens[0];
        let kind = |d: &hdf5::Dataset, n: &str| -> Result<TypeDescriptor, ReadError> {
            d.dtype()
                .and_then(|t| t.to_descriptor())
                .map_err(|e| err(format!("'{prefix}{n}' has a type evcal cannot read: {e}")))
        };
        for (d, n) in [(&x, "x"), (&y, "y")] {
            if !matches!(kind(d, n)?, TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)) {
                return Err(err(format!("'{prefix}{n}' is not an integer pixel coordinate ({:?})", kind(d, n)?)));
            }
        }
        match kind(&p, "p")? {
            TypeDescriptor::Boolean | TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_) => {}
            other => return Err(err(format!("'{prefix}p' is not an integer or boolean polarity ({other:?})"))),
        };
        let group = if prefix.is_empty() { None } else { file.group("events").ok() };
        let mut notes = Vec::new();
        let mut offset_us = 0i64;
        let t_kind = kind(&t, "t")?;
        let column =
            |d: &hdf5::Dataset, n: &str| Column::open(d.clone()).map_err(|m| err(format!("'{prefix}{n}': {m}")));
        let mut t_column = column(&t, "t")?;
        let t_u64 = matches!(t_kind, TypeDescriptor::Unsigned(hdf5::types::IntSize::U8));
        let time = match t_kind {
            TypeDescriptor::Float(_) => {
                if unit.is_some_and(|u| u != TimeUnit::Seconds) {
                    return Err(err(format!("'{prefix}t' holds floats: evcal reads them as seconds only")));
                }
                TimeColumn::FloatSeconds
            }
            TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_) => {
                let (t_loc, file_loc): (&hdf5::Location, &hdf5::Location) = (&t, &file);
                let from_attr =
                    [Some(t_loc), group.as_deref(), Some(file_loc)].into_iter().flatten().find_map(unit_attr);
                let t_offset = if prefix.is_empty() { None } else { file.dataset("t_offset").ok() };
                if let Some(off) = &t_offset {
                    offset_us = off
                        .read_scalar::<i64>()
                        .map_err(|e| err(format!("cannot read 't_offset' (DSEC's time origin, µs): {e}")))?;
                }
                let u = if let Some(u) = unit {
                    u
                } else if let Some(u) = from_attr {
                    u.map_err(&err)?
                } else if t_offset.is_some() {
                    TimeUnit::Microseconds
                } else {
                    let (u, why) =
                        guess_unit(&mut t_column, rows).map_err(|m| err(format!("cannot read '{prefix}t': {m}")))?;
                    notes.push(format!(
                        "{}: '{prefix}t' taken as {} ({why}); set --time-unit to override",
                        path.display(),
                        u.name()
                    ));
                    u
                };
                TimeColumn::Int(u)
            }
            other => return Err(err(format!("'{prefix}t' is not a number ({other:?})"))),
        };
        let file_loc: &hdf5::Location = &file;
        let sensor = [group.as_deref(), Some(file_loc)]
            .into_iter()
            .flatten()
            .find_map(|loc| size_attrs(loc).transpose())
            .transpose()
            .map_err(&err)?;
        Ok(Self {
            path: path.to_path_buf(),
            x: column(&x, "x")?,
            y: column(&y, "y")?,
            t: t_column,
            p: column(&p, "p")?,
            t_u64,
            time,
            offset_us,
            rows,
            next_row: 0,
            sensor,
            notes,
            buf: Chunk::default(),
            at: 0,
            failed: false,
        })
    }

    /// Number of events in the file.
    pub fn len(&self) -> u64 {
        self.rows as u64
    }

    /// Whether the file holds no events.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// The sensor size, from the file's attributes.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    /// What the reader decided that the user should know (a guessed time unit).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    fn fill(&mut self) -> Result<(), ReadError> {
        let end = (self.next_row + READ_ROWS).min(self.rows);
        let r = self.next_row..end;
        let path = &self.path;
        let e = |n: &'static str| {
            move |m: String| ReadError::new(path, Position::Row(r.start as u64), format!("cannot read {n}: {m}"))
        };
        self.buf.x = self.x.read::<i64>(r.clone()).map_err(e("x"))?;
        self.buf.y = self.y.read::<i64>(r.clone()).map_err(e("y"))?;
        self.buf.p = self.p.read::<i64>(r.clone()).map_err(e("p"))?;
        match self.time {
            TimeColumn::Int(_) if self.t_u64 => self.buf.tu = self.t.read::<u64>(r.clone()).map_err(e("t"))?,
            TimeColumn::Int(_) => self.buf.t = self.t.read::<i64>(r.clone()).map_err(e("t"))?,
            TimeColumn::FloatSeconds => self.buf.tf = self.t.read::<f64>(r.clone()).map_err(e("t"))?,
        }
        self.at = 0;
        self.next_row = end;
        Ok(())
    }

    fn event(&self, i: usize) -> Result<Event, String> {
        let coord =
            |v: i64, n: &str| u16::try_from(v).map_err(|_| format!("bad {n} {v} (a pixel coordinate 0..65535)"));
        let x = coord(self.buf.x[i], "x")?;
        let y = coord(self.buf.y[i], "y")?;
        let polarity = match self.buf.p[i] {
            1 => true,
            0 | -1 => false,
            v => return Err(format!("bad polarity {v} (1/0 or 1/-1)")),
        };
        let t_us = match self.time {
            TimeColumn::Int(u) => {
                let v = if self.t_u64 {
                    let v = self.buf.tu[i];
                    i64::try_from(v).map_err(|_| {
                        format!("timestamp {v} {} is above the largest evcal reads ({})", u.name(), i64::MAX)
                    })?
                } else {
                    self.buf.t[i]
                };
                u.to_us(v)
                    .and_then(|t| t.checked_add(self.offset_us))
                    .ok_or(format!("timestamp {v} {} overflows", u.name()))?
            }
            TimeColumn::FloatSeconds => {
                let v = self.buf.tf[i];
                if !(v.is_finite() && v.abs() < 9e12) {
                    return Err(format!("bad timestamp {v} s"));
                }
                (v * 1e6).round() as i64 + self.offset_us
            }
        };
        let t_us = u64::try_from(t_us).map_err(|_| format!("negative timestamp ({t_us} µs)"))?;
        Ok(Event { t_us, x, y, polarity })
    }
}

impl EventSource for H5ColumnsReader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.failed {
            return None;
        }
        if self.at >= self.buf.x.len() {
            if self.next_row >= self.rows {
                return None;
            }
            if let Err(e) = self.fill() {
                self.failed = true;
                return Some(Err(e));
            }
        }
        let row = (self.next_row - self.buf.x.len() + self.at) as u64;
        let r = self.event(self.at).map_err(|m| ReadError::new(&self.path, Position::Row(row), m));
        self.at += 1;
        self.failed = r.is_err();
        Some(r)
    }

    fn progress_bytes(&self) -> u64 {
        // About 15 bytes a row (u16 x, y, u8 p, i64 t) against the file size.
        (self.next_row - self.buf.x.len() + self.at) as u64 * 15
    }

    fn notes(&self) -> Vec<String> {
        self.notes.clone()
    }
}

/// Guesses the unit of integer timestamps from their values (see the module's notes).
fn guess_unit(t: &mut Column, rows: usize) -> Result<(TimeUnit, String), String> {
    if rows == 0 {
        return Ok((TimeUnit::Microseconds, "no events; the usual unit".into()));
    }
    let head = t.read::<i64>(0..rows.min(READ_ROWS))?;
    let last = t.read::<i64>(rows - 1..rows)?[0];
    Ok(guess_from(&head, last))
}

fn guess_from(head: &[i64], last: i64) -> (TimeUnit, String) {
    let first = head[0];
    if first >= 100_000_000_000_000_000 {
        return (
            TimeUnit::Nanoseconds,
            format!("first timestamp {first}: Unix time in ns; in µs it would lie past the year 5000"),
        );
    }
    if first >= 100_000_000_000_000 {
        return (TimeUnit::Microseconds, format!("first timestamp {first}: Unix time in µs"));
    }
    // ns read as µs stretch a recording a thousandfold: a minute would look like 17 hours.
    let span = last.saturating_sub(first);
    if span > 86_400_000_000 {
        return (
            TimeUnit::Nanoseconds,
            format!("the times span {span} ticks: more than a day in µs, {:.0} s in ns", span as f64 * 1e-9),
        );
    }
    // Saturating: a damaged column can hold both i64 extremes (found by read_h5).
    let head_span = head.iter().max().unwrap_or(&first).saturating_sub(*head.iter().min().unwrap_or(&first));
    if head_span >= 1000 && head.iter().all(|v| v % 1000 == 0) {
        return (
            TimeUnit::Nanoseconds,
            format!("all of the first {} timestamps are multiples of 1000: ns from a µs clock", head.len()),
        );
    }
    (TimeUnit::Microseconds, "relative times with µs resolution: the event-camera convention".into())
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::input::recording::Recording;

    #[test]
    fn units_parse_and_convert() {
        assert_eq!(TimeUnit::parse("µs"), Some(TimeUnit::Microseconds));
        assert_eq!(TimeUnit::parse("NS"), Some(TimeUnit::Nanoseconds));
        assert_eq!(TimeUnit::parse("seconds"), Some(TimeUnit::Seconds));
        assert_eq!(TimeUnit::parse("fortnights"), None);
        assert_eq!(TimeUnit::Nanoseconds.to_us(1499), Some(1));
        assert_eq!(TimeUnit::Nanoseconds.to_us(1500), Some(2));
        assert_eq!(TimeUnit::Nanoseconds.to_us(-1500), Some(-1));
        assert_eq!(TimeUnit::Seconds.to_us(i64::MAX / 10), None);
        assert_eq!(TimeUnit::Milliseconds.to_us(3), Some(3000));
    }

    #[test]
    fn unit_guesses() {
        let us: Vec<i64> = (0..5000).map(|i| i * 37 + 5).collect();
        assert_eq!(guess_from(&us, 5000 * 37).0, TimeUnit::Microseconds);
        let ns: Vec<i64> = us.iter().map(|v| v * 1000).collect();
        assert_eq!(guess_from(&ns, 5000 * 37_000).0, TimeUnit::Nanoseconds, "multiples of 1000");
        let ns_fine: Vec<i64> = (0..5000).map(|i| i * 37 + 5).collect();
        let (u, why) = guess_from(&ns_fine, 100_000_000_000);
        assert_eq!(u, TimeUnit::Nanoseconds, "100 s in ns; in µs 28 hours");
        assert!(why.contains("more than a day"), "{why}");
        assert_eq!(guess_from(&ns_fine, 80_000_000_000).0, TimeUnit::Microseconds, "22 hours of µs");
        assert_eq!(guess_from(&[1_600_000_000_000_000_123], 0).0, TimeUnit::Nanoseconds);
        assert_eq!(guess_from(&[1_600_000_000_000_123], 1_600_000_000_000_124).0, TimeUnit::Microseconds);
        assert_eq!(guess_from(&[7], 7).0, TimeUnit::Microseconds, "one event");
        assert_eq!(guess_from(&[i64::MIN, i64::MAX], i64::MIN).0, TimeUnit::Microseconds, "extremes: no overflow");
    }

    fn write(path: &Path, group: bool, t: &[i64], p: &[i8], extra: impl FnOnce(&hdf5::Group)) {
        let f = hdf5::File::create(path).unwrap();
        let g: hdf5::Group = if group { f.create_group("events").unwrap() } else { (*f).clone() };
        let n = t.len();
        let xs: Vec<u16> = (0..n as u16).collect();
        g.new_dataset_builder().with_data(&xs).create("x").unwrap();
        g.new_dataset_builder().with_data(&xs).create("y").unwrap();
        g.new_dataset_builder().with_data(t).create("t").unwrap();
        g.new_dataset_builder().with_data(p).create("p").unwrap();
        extra(&g);
    }

    #[test]
    fn layouts_units_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.h5");
        write(&a, true, &[5, 7, 9], &[1, -1, 0], |_| {});
        assert_eq!(Format::detect(&a).unwrap(), Format::EventsGroupH5);
        let rec = Recording::open(&a).unwrap();
        assert_eq!((rec.len, rec.sensor), (Some(3), None));
        assert!(rec.notes()[0].contains("taken as us"), "{:?}", rec.notes());
        let ev: Vec<Event> = rec.map(Result::unwrap).collect();
        assert_eq!(ev[1], Event { t_us: 7, x: 1, y: 1, polarity: false });

        // a units attribute and a sensor size on the group; root layout
        let b = dir.path().join("b.h5");
        write(&b, false, &[5000, 7000, 9400], &[1, 1, 0], |g| {
            let u: hdf5::types::VarLenUnicode = "ms".parse().unwrap();
            g.dataset("t")
                .unwrap()
                .new_attr::<hdf5::types::VarLenUnicode>()
                .create("units")
                .unwrap()
                .write_scalar(&u)
                .unwrap();
            g.new_attr::<u32>().create("width").unwrap().write_scalar(&640u32).unwrap();
            g.new_attr::<u32>().create("height").unwrap().write_scalar(&480u32).unwrap();
        });
        assert_eq!(Format::detect(&b).unwrap(), Format::RootColumnsH5);
        let rec = Recording::open(&b).unwrap();
        assert_eq!(rec.sensor, Some(SensorSize::DVXPLORER));
        assert!(rec.notes().is_empty());
        let ev: Vec<Event> = rec.map(Result::unwrap).collect();
        assert_eq!(ev[2].t_us, 9_400_000);

        // the option overrides
        let opts =
            crate::input::recording::OpenOptions { time_unit: Some(TimeUnit::Nanoseconds), ..Default::default() };
        let ev: Vec<Event> = Recording::open_with(&b, &opts).unwrap().map(Result::unwrap).collect();
        assert_eq!(ev[2].t_us, 9);

        // fields of different lengths: an error naming them, never fewer events
        let c = dir.path().join("c.h5");
        write(&c, true, &[1, 2], &[1, 0, 1], |_| {});
        let e = Recording::open(&c).err().unwrap().to_string();
        assert!(e.contains("c.h5") && e.contains("t 2, p 3"), "{e}");

        // bad values: named by row
        let d = dir.path().join("d.h5");
        write(&d, true, &[1, 2, 3], &[1, 2, 1], |_| {});
        let errs: Vec<ReadError> = Recording::open(&d).unwrap().filter_map(Result::err).collect();
        assert_eq!(errs.len(), 1);
        assert_eq!(errs[0].at, Position::Row(1));
        assert!(errs[0].message.contains("polarity 2"));
        let n = dir.path().join("n.h5");
        write(&n, true, &[1, -2, 3], &[1, 1, 1], |_| {});
        let errs: Vec<ReadError> = Recording::open(&n).unwrap().filter_map(Result::err).collect();
        assert!(errs[0].message.contains("negative"), "{}", errs[0]);
    }
}
