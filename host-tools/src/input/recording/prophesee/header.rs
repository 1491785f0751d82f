//! The `%` header that Prophesee RAW and `.dat` files begin with: read from a stream (peeked,
//! so the reader still gets it) and parsed into its fields, the encoding and the sensor size.
//!
//! Kept out of `mod.rs` (which recognises the format and re-exports [`Header`]) so that the
//! readers beside it take the header from here, not from the module that re-exports them.

use crate::input::recording::{
    bytes::{quote, Input},
    types::{stated_sensor, Position, ReadError},
};
use evcal_core::{
    event::SensorSize,
    evt::{Encoding, Evt21Order},
};

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

/// Peeks at `input` until its `%` header has ended (with some bytes of data after it, for
/// [`sniff_evt21_order`](super::sniff_evt21_order)), the input has ended, or [`MAX_HEADER`] bytes: a live stream is not
/// held up for a megabyte, a short file costs its size. A header that goes on past
/// [`MAX_HEADER`] is an error: its remaining lines would be read as events.
pub(crate) fn peek_header(input: &mut Input) -> Result<(), ReadError> {
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
