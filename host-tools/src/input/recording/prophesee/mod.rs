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
mod raw;
pub mod write;

pub use dat::DatReader;
pub use raw::RawReader;

use super::{
    bytes::quote,
    types::{stated_sensor, Format, Position, ReadError},
};
use evcal_core::{
    event::SensorSize,
    evt::{Encoding, Evt21Order},
};
use std::path::Path;

/// The most header bytes read; a longer `%` header is not a Prophesee header.
pub(crate) const MAX_HEADER: usize = 1 << 20;

/// A parsed `%` header.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Header {
    /// Bytes of the header, the offset of the data.
    pub len: u64,
    /// `key value` pairs in file order (`% key value...`).
    pub fields: Vec<(String, String)>,
}

impl Header {
    /// Parses the `%` lines at the start of `head`.
    pub fn parse(head: &[u8]) -> Header {
        let mut h = Header::default();
        let mut at = 0usize;
        while head.get(at) == Some(&b'%') {
            let Some(nl) = head[at..].iter().position(|&b| b == b'\n') else { break };
            let line = &head[at..at + nl];
            let Ok(text) = std::str::from_utf8(line) else { break };
            if text.chars().any(|c| c.is_control() && c != '\t' && c != '\r') {
                break;
            }
            at += nl + 1;
            let body = text[1..].trim();
            if body == "end" {
                break;
            }
            let (k, v) = body.split_once(char::is_whitespace).unwrap_or((body, ""));
            if !k.is_empty() {
                h.fields.push((k.to_string(), v.trim().to_string()));
            }
        }
        h.len = at as u64;
        h
    }

    /// The last value of `key` (case-insensitive), if any.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.fields.iter().rev().find(|(k, _)| k.eq_ignore_ascii_case(key)).map(|(_, v)| v.as_str())
    }

    /// The `;`-separated options of the `format` line (`height=720`, `endianness=legacy`).
    fn format_option(&self, name: &str) -> Option<&str> {
        self.get("format")?.split(';').skip(1).find_map(|kv| {
            let (k, v) = kv.split_once('=')?;
            k.trim().eq_ignore_ascii_case(name).then_some(v.trim())
        })
    }

    /// The RAW encoding the header names: `Ok(None)` if it names none, `Err` if it names one
    /// evcal does not read. EVT 2.1 without an explicit order gets `None` as its order.
    pub fn encoding(&self) -> Result<Option<(Encoding, bool)>, String> {
        if let Some(f) = self.get("format") {
            let name = f.split(';').next().unwrap_or("").trim().to_ascii_uppercase();
            let legacy = self.format_option("endianness").is_some_and(|v| v.eq_ignore_ascii_case("legacy"));
            return match name.as_str() {
                "EVT2" | "EVT2.0" | "EVT20" => Ok(Some((Encoding::Evt2, true))),
                "EVT21" | "EVT2.1" => {
                    let order = if legacy { Evt21Order::HighHalfFirst } else { Evt21Order::LowHalfFirst };
                    Ok(Some((Encoding::Evt21(order), true)))
                }
                "EVT3" | "EVT3.0" | "EVT30" => Ok(Some((Encoding::Evt3, true))),
                _ => Err(format!("format '{f}' is not one evcal reads (EVT2, EVT21, EVT3)")),
            };
        }
        match self.get("evt").map(str::trim) {
            None => Ok(None),
            Some("2.0" | "2") => Ok(Some((Encoding::Evt2, true))),
            Some("2.1") => Ok(Some((Encoding::Evt21(Evt21Order::HighHalfFirst), false))),
            Some("3.0" | "3") => Ok(Some((Encoding::Evt3, true))),
            Some(v) => Err(format!("'% evt {v}' is not an encoding evcal reads (2.0, 2.1, 3.0)")),
        }
    }

    /// The sensor size and where it came from (`None` for a size the header states); an
    /// error for a size stated that evcal cannot use (not whole numbers, outside 1 to 65535),
    /// saying what is stated.
    pub fn sensor(&self) -> Result<Option<(SensorSize, Option<String>)>, String> {
        let stated = |w: &str, h: &str, line: &str| -> Result<Option<SensorSize>, String> {
            match (w.trim().parse::<i128>(), h.trim().parse::<i128>()) {
                (Ok(w), Ok(h)) => stated_sensor(w, h).map_err(|m| format!("the header ({line}) {m}")),
                _ => Err(format!(
                    "the header ({line}) states a sensor size of \"{}\" by \"{}\", not whole numbers",
                    quote(w.trim().as_bytes(), 40),
                    quote(h.trim().as_bytes(), 40)
                )),
            }
        };
        if let (Some(w), Some(h)) = (self.format_option("width"), self.format_option("height")) {
            if let Some(s) = stated(w, h, "% format ...;width=W;height=H")? {
                return Ok(Some((s, None)));
            }
        }
        if let Some(g) = self.get("geometry") {
            let (w, h) = g.split_once(['x', 'X']).unwrap_or((g, ""));
            if let Some(s) = stated(w, h, "% geometry WxH")? {
                return Ok(Some((s, None)));
            }
        }
        if let (Some(w), Some(h)) = (self.get("Width"), self.get("Height")) {
            if let Some(s) = stated(w, h, "% Width, % Height")? {
                return Ok(Some((s, None)));
            }
        }
        let found = [("plugin_name", self.get("plugin_name")), ("sensor_generation", self.get("sensor_generation"))]
            .into_iter()
            .find_map(|(k, v)| v.map(|v| (k, v)));
        let Some((key, value)) = found else { return Ok(None) };
        Ok(camera_sensor(value).map(|size| (size, Some(format!("{key} {value}")))))
    }
}

/// The sensor of a Prophesee camera named by its HAL plugin (`hal_plugin_gen3_fx3`) or sensor
/// generation (`4.2`), after OpenEB's table of plugins: Gen3 / Gen3.1 VGA 640x480, Gen4 /
/// Gen4.1 / IMX636 / IMX646 HD 1280x720, GenX320 320x320.
fn camera_sensor(name: &str) -> Option<SensorSize> {
    let n = name.to_ascii_lowercase();
    if n.contains("genx320") || n.contains("gx320") || n == "320" {
        Some(SensorSize::new(320, 320))
    } else if n.contains("imx636") || n.contains("imx646") || n.contains("gen4") || n.starts_with('4') {
        Some(SensorSize::new(1280, 720))
    } else if n.contains("gen3") || n.starts_with('3') {
        Some(SensorSize::new(640, 480))
    } else {
        None
    }
}

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

/// Peeks at `input` until its `%` header has ended (with some bytes of data after it, for
/// [`sniff_evt21_order`]), the input has ended, or [`MAX_HEADER`] bytes: a live stream is not
/// held up for a megabyte, a short file costs its size. A header that goes on past
/// [`MAX_HEADER`] is an error: its remaining lines would be read as events.
pub(crate) fn peek_header(input: &mut crate::input::recording::bytes::Input) -> Result<(), ReadError> {
    let mut want = 1 << 16;
    loop {
        let got = input.peek(want)?.len();
        let header = Header::parse(&input.head).len as usize;
        if got < want || header + (1 << 16) <= got {
            return Ok(());
        }
        if want > MAX_HEADER {
            break;
        }
        // One byte past the limit: whether the input goes on after it.
        want = (want * 4).min(MAX_HEADER + 1);
    }
    let within = &input.head[..MAX_HEADER];
    let h = Header::parse(within);
    let rest = &within[h.len as usize..];
    // The header's last line, without its newline: `% end` closes it.
    let last = within[..h.len as usize].strip_suffix(b"\n").unwrap_or_default();
    let last = last.rsplit(|&b| b == b'\n').next().unwrap_or_default();
    let closed = std::str::from_utf8(last).is_ok_and(|l| l.strip_prefix('%').is_some_and(|l| l.trim() == "end"));
    let cut_line = rest.first() == Some(&b'%') && !rest.contains(&b'\n');
    if !h.fields.is_empty() && !closed && (rest.is_empty() || cut_line) {
        return Err(ReadError::new(
            &input.name,
            Position::Byte(h.len),
            format!(
                "the '%' header goes on past {MAX_HEADER} bytes, the most evcal reads of a Prophesee header \
                 (its remaining lines would be read as events): the file is corrupt, or not a Prophesee file"
            ),
        ));
    }
    Ok(())
}

/// Recognises a Prophesee file by its header (`head`: its first bytes, up to
/// [`MAX_HEADER`]), else by its extension: `Ok(None)` if it is not one.
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
