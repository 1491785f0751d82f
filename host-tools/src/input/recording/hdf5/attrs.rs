//! What an HDF5 event file's attributes say about its events: the unit of integer times and
//! the sensor size. A value evcal cannot use is an error saying what is stated, never taken
//! as no value (a time unit guessed, a size guessed from the events) or rounded.

use crate::input::recording::{bytes::quote, types::stated_sensor, types::TimeUnit};
use evcal_core::event::SensorSize;
use hdf5::types::TypeDescriptor;

/// A time unit stated by a `unit`, `units` or `time_unit` string attribute of `loc`; an
/// error naming one that is no time unit evcal knows (taking it as µs would be a guess).
pub(super) fn unit_attr(loc: &hdf5::Location) -> Option<Result<TimeUnit, String>> {
    ["unit", "units", "time_unit"].into_iter().find_map(|n| {
        let a = loc.attr(n).ok()?;
        let s = a
            .read_scalar::<hdf5::types::VarLenUnicode>()
            .map(|s| s.to_string())
            .or_else(|_| a.read_scalar::<hdf5::types::VarLenAscii>().map(|s| s.to_string()))
            .ok()?;
        Some(TimeUnit::parse(&s).ok_or_else(|| {
            format!(
                "the attribute {n}=\"{}\" on {} is not a time unit evcal knows (s, ms, us, ns): set --time-unit",
                quote(s.as_bytes(), 40),
                loc_name(loc)
            )
        }))
    })
}

/// `loc`'s name in messages.
fn loc_name(loc: &hdf5::Location) -> String {
    match loc.name().as_str() {
        "/" | "" => "the file".into(),
        n => format!("'{}'", n.trim_start_matches('/')),
    }
}

/// A sensor size from `width`/`height` (or `sensor_width`/`sensor_height`) attributes:
/// `Ok(None)` if `loc` has neither pair; an error for a size evcal cannot use (not whole
/// numbers, outside 1 to 65535), saying what is stated.
pub(super) fn size_attrs(loc: &hdf5::Location) -> Result<Option<SensorSize>, String> {
    // Read as floats first: HDF5 converts 346.7 to the integer 346 without a word.
    let value = |n: &str| -> Option<Result<i128, String>> {
        let a = loc.attr(n).ok()?;
        let unreadable = |e: hdf5::Error| format!("cannot read the attribute {n} on {}: {e}", loc_name(loc));
        Some(match a.dtype().and_then(|t| t.to_descriptor()) {
            Ok(TypeDescriptor::Float(_)) => a.read_scalar::<f64>().map_err(unreadable).and_then(|v| {
                if v.fract() == 0.0 && v.abs() < 1e30 {
                    Ok(v as i128)
                } else {
                    Err(format!("the attribute {n} = {v} on {} is not a whole number of pixels", loc_name(loc)))
                }
            }),
            Ok(TypeDescriptor::Unsigned(_)) => a.read_scalar::<u64>().map(i128::from).map_err(unreadable),
            _ => a.read_scalar::<i64>().map(i128::from).map_err(unreadable),
        })
    };
    let (names, w, h) = match (value("width"), value("height")) {
        (Some(w), Some(h)) => ("width, height", w, h),
        _ => match (value("sensor_width"), value("sensor_height")) {
            (Some(w), Some(h)) => ("sensor_width, sensor_height", w, h),
            _ => return Ok(None),
        },
    };
    let (w, h) = (w?, h?);
    stated_sensor(w, h).map_err(|m| format!("{} ({names}) {m}", loc_name(loc)))
}
