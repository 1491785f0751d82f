//! Prophesee recordings: RAW files (a `%` text header, then the sensor's EVT 2.0 / 2.1 / 3.0
//! byte stream, decoded by `evcal_core::evt`) and `.dat` files (a `%` header, then fixed-size
//! CD event records).
//!
//! Both start with lines `% key value`. What evcal takes from them:
//!
//! * the encoding of a RAW file: `% evt 2.0|2.1|3.0` or `% format EVT2|EVT21|EVT3;...`;
//! * the sensor size: `% format ...;height=H;width=W`, `% geometry WxH`, `% Width` /
//!   `% Height` (`.dat`), else the camera named by `% plugin_name` or `% sensor_generation`
//!   (older RAW files from Gen3 / Gen4 / IMX636 cameras carry no size), said so in a note;
//! * the order of EVT 2.1's 32-bit halves: `endianness=legacy` in the format line is the
//!   IMX636's (high half first), a format line without it the GenX320's; a bare `% evt 2.1`
//!   is decided from the stream itself (which order gives well-formed `TIME_HIGH` words).
//!
//! The header ends at `% end`, or at the first line that does not start with `%` or is not
//! text (binary data may well begin with the byte `%`).

mod dat;
mod header;
mod raw;
pub mod write;

pub use dat::DatReader;
pub use header::Header;
pub use raw::RawReader;

pub(crate) use header::peek_header;

use super::types::{Format, Position, ReadError};
use evcal_core::evt::{Encoding, Evt21Order};
use std::path::Path;

/// Which of the two EVT 2.1 half orders `body` (the first bytes of a stream) is written in,
/// from its `TIME_HIGH` words: in the right order their type nibble is 8 and their unused 32
/// bits are zero; read in the wrong order they look like CD words. `None` if the sample has
/// no `TIME_HIGH` either way.
pub fn sniff_evt21_order(body: &[u8]) -> Option<Evt21Order> {
    let (mut low_first, mut high_first) = (0u32, 0u32);
    for w in body.chunks_exact(8) {
        let a = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
        let b = u32::from_le_bytes([w[4], w[5], w[6], w[7]]);
        low_first += u32::from(b >> 28 == 0x8 && a == 0);
        high_first += u32::from(a >> 28 == 0x8 && b == 0);
    }
    match low_first.cmp(&high_first) {
        std::cmp::Ordering::Greater => Some(Evt21Order::LowHalfFirst),
        std::cmp::Ordering::Less => Some(Evt21Order::HighHalfFirst),
        std::cmp::Ordering::Equal => None,
    }
}

/// Recognises a Prophesee file by its header (`head`: its first bytes, up to
/// [`MAX_HEADER`](header::MAX_HEADER)), else by its extension: `Ok(None)` if it is not one.
pub(super) fn sniff(path: &Path, head: &[u8], ext: Option<&str>) -> Result<Option<Format>, ReadError> {
    let h = Header::parse(head);
    let body = &head[(h.len as usize).min(head.len())..];
    let enc = h.encoding().map_err(|m| ReadError::new(path, Position::File, m))?;
    if let Some((enc, explicit)) = enc {
        return Ok(Some(Format::PropheseeRaw(settle_order(enc, explicit, body))));
    }
    // A .dat header (`% Height`, `% Version`...) is followed by the event type and size bytes.
    let dat_like = !h.fields.is_empty() && matches!(body, [0x00 | 0x0C, 8, ..]);
    match ext {
        Some("dat") => Ok(Some(Format::PropheseeDat)),
        _ if dat_like => Ok(Some(Format::PropheseeDat)),
        Some("raw") => Err(ReadError::new(
            path,
            Position::File,
            "a .raw file without a Prophesee header line '% evt 2.0|2.1|3.0' or '% format EVT2|EVT21|EVT3': \
             cannot tell its encoding",
        )),
        _ => Ok(None),
    }
}

/// The EVT 2.1 half order: as the header says, else from the stream, else the IMX636's (the
/// sensor of the Metavision versions that wrote `% evt 2.1` without a format line).
fn settle_order(enc: Encoding, explicit: bool, body: &[u8]) -> Encoding {
    match enc {
        Encoding::Evt21(order) if !explicit => Encoding::Evt21(sniff_evt21_order(body).unwrap_or(order)),
        e => e,
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use evcal_core::event::SensorSize;

    #[test]
    fn header_lines_and_end() {
        let h = Header::parse(
            b"% date 2023-10-19 03:51:23\n% evt 3.0\n% format EVT3;height=720;width=1280\n% end\n%\x01\x02",
        );
        assert_eq!(h.len, 27 + 10 + 36 + 6, "the header ends after its `% end` line");
        assert_eq!(h.get("EVT"), Some("3.0"));
        assert_eq!(h.encoding(), Ok(Some((Encoding::Evt3, true))));
        assert_eq!(h.sensor(), Ok(Some((SensorSize::new(1280, 720), None))));
        // binary data that starts with '%' is not a header line
        let h = Header::parse(b"% evt 2.0\n%\x00\x80\x11\n");
        assert_eq!(h.len, 10);
        // no newline: not a header line
        assert_eq!(Header::parse(b"% evt 2.0").len, 0);
    }

    #[test]
    fn encodings_and_orders() {
        let enc = |s: &str| Header::parse(s.as_bytes()).encoding();
        assert_eq!(
            enc("% format EVT21;height=720;width=1280;endianness=legacy\n"),
            Ok(Some((Encoding::Evt21(Evt21Order::HighHalfFirst), true)))
        );
        assert_eq!(
            enc("% format EVT21;height=320;width=320\n"),
            Ok(Some((Encoding::Evt21(Evt21Order::LowHalfFirst), true)))
        );
        assert_eq!(enc("% evt 2.1\n"), Ok(Some((Encoding::Evt21(Evt21Order::HighHalfFirst), false))));
        assert_eq!(enc("% evt 2.0\n"), Ok(Some((Encoding::Evt2, true))));
        assert!(enc("% evt 4.0\n").unwrap_err().contains("4.0"));
        assert!(enc("% format HISTO3D\n").unwrap_err().contains("HISTO3D"));
        assert_eq!(enc("% Width 640\n"), Ok(None));
        // a TIME_HIGH in each order
        let th_low_first = [0, 0, 0, 0, 5, 0, 0, 0x80];
        let th_high_first = [5, 0, 0, 0x80, 0, 0, 0, 0];
        assert_eq!(sniff_evt21_order(&th_low_first), Some(Evt21Order::LowHalfFirst));
        assert_eq!(sniff_evt21_order(&th_high_first), Some(Evt21Order::HighHalfFirst));
        assert_eq!(sniff_evt21_order(&[]), None);
    }

    #[test]
    fn sensor_sizes() {
        let s = |t: &str| Header::parse(t.as_bytes()).sensor().unwrap();
        assert_eq!(s("% geometry 1280x720\n"), Some((SensorSize::new(1280, 720), None)));
        assert_eq!(s("% Height 480\n% Width 640\n"), Some((SensorSize::new(640, 480), None)));
        assert_eq!(s("% geometry 0x0\n% Height 480\n% Width 640\n"), Some((SensorSize::new(640, 480), None)));
        let (size, from) = s("% plugin_name hal_plugin_gen3_fx3\n% system_ID 21\n").unwrap();
        assert_eq!(size, SensorSize::new(640, 480));
        assert_eq!(from.as_deref(), Some("plugin_name hal_plugin_gen3_fx3"));
        assert_eq!(s("% plugin_name hal_plugin_imx636_evk4\n").unwrap().0, SensorSize::new(1280, 720));
        assert_eq!(s("% sensor_generation 320\n").unwrap().0, SensorSize::new(320, 320));
        assert_eq!(s("% plugin_name mystery\n"), None);
        // Stated sizes evcal cannot use: said, with the value and the range, not taken as
        // "no size".
        let e = |t: &str| Header::parse(t.as_bytes()).sensor().unwrap_err();
        let m = e("% geometry 0x720\n");
        assert!(m.contains("% geometry") && m.contains("0x720; evcal reads sizes of 1 to 65535"), "{m}");
        let m = e("% format EVT3;height=720;width=70000\n");
        assert!(m.contains("70000x720; evcal reads sizes of 1 to 65535"), "{m}");
        let m = e("% Width 640.5\n% Height 480\n");
        assert!(m.contains("\"640.5\" by \"480\", not whole numbers"), "{m}");
    }
}
