//! Writers of Prophesee RAW (EVT 2.0 / 2.1 / 3.0) and CD `.dat` files, for tests, benchmarks
//! and converting recordings. Encoders vectorise as the sensors do: EVT 2.1 packs events of one
//! time, row and polarity within a 32-pixel block into one word, EVT 3.0 runs of them within 12
//! or 8 pixels into `VECT_12` / `VECT_8` words.

use evcal_core::{
    event::{Event, SensorSize},
    evt::{Encoding, Evt21Order},
};
use std::{io::Write, path::Path};

/// The EVT byte stream of `events` (which must be in time order; times wrap with the sensor
/// clock and the decoder unwraps them).
pub fn encode_evt(encoding: Encoding, events: &[Event]) -> Vec<u8> {
    match encoding {
        Encoding::Evt2 => encode_evt2(events),
        Encoding::Evt21(order) => encode_evt21(events, order),
        Encoding::Evt3 => encode_evt3(events),
    }
}

fn encode_evt2(events: &[Event]) -> Vec<u8> {
    let mut out = Vec::with_capacity(events.len() * 4 + 64);
    let mut high = None;
    for e in events {
        let h = ((e.t_us >> 6) & 0x0FFF_FFFF) as u32;
        if high != Some(h) {
            out.extend((0x8000_0000 | h).to_le_bytes());
            high = Some(h);
        }
        let w = (u32::from(e.polarity) << 28)
            | (((e.t_us & 0x3F) as u32) << 22)
            | ((u32::from(e.x) & 0x7FF) << 11)
            | (u32::from(e.y) & 0x7FF);
        out.extend(w.to_le_bytes());
    }
    out
}

fn push64(out: &mut Vec<u8>, w: u64, order: Evt21Order) {
    match order {
        Evt21Order::LowHalfFirst => out.extend(w.to_le_bytes()),
        Evt21Order::HighHalfFirst => {
            out.extend(((w >> 32) as u32).to_le_bytes());
            out.extend((w as u32).to_le_bytes());
        }
    }
}

fn encode_evt21(events: &[Event], order: Evt21Order) -> Vec<u8> {
    let mut out = Vec::with_capacity(events.len() * 8 + 64);
    let mut high = None;
    let mut i = 0;
    while i < events.len() {
        let e = events[i];
        let h = (e.t_us >> 6) & 0x0FFF_FFFF;
        if high != Some(h) {
            push64(&mut out, (0x8 << 60) | (h << 32), order);
            high = Some(h);
        }
        // One word for this event and the following ones of the same time, row, polarity and
        // 32-pixel block, in increasing x.
        let x0 = e.x & !31;
        let mut mask = 0u32;
        let mut last_x = None;
        while let Some(f) = events.get(i) {
            let same = f.t_us == e.t_us && f.y == e.y && f.polarity == e.polarity && f.x & !31 == x0;
            if !same || last_x.is_some_and(|l| f.x <= l) {
                break;
            }
            mask |= 1 << (f.x - x0);
            last_x = Some(f.x);
            i += 1;
        }
        let w = (u64::from(e.polarity) << 60)
            | ((e.t_us & 0x3F) << 54)
            | ((u64::from(x0) & 0x7FF) << 43)
            | ((u64::from(e.y) & 0x7FF) << 32)
            | u64::from(mask);
        push64(&mut out, w, order);
    }
    out
}

fn encode_evt3(events: &[Event]) -> Vec<u8> {
    let mut out = Vec::with_capacity(events.len() * 2 + 64);
    let mut push = |w: u16| out.extend(w.to_le_bytes());
    let (mut high, mut low, mut row) = (None, None, None);
    let mut i = 0;
    while i < events.len() {
        let e = events[i];
        let h = ((e.t_us >> 12) & 0xFFF) as u16;
        let l = (e.t_us & 0xFFF) as u16;
        if high != Some(h) {
            push(0x8000 | h);
            high = Some(h);
            low = Some(0);
        }
        if low != Some(l) {
            push(0x6000 | l);
            low = Some(l);
        }
        if row != Some(e.y) {
            push(e.y & 0x7FF);
            row = Some(e.y);
        }
        // The run of events of this time, row and polarity at increasing x.
        let mut j = i + 1;
        while let Some(f) = events.get(j) {
            if f.t_us != e.t_us || f.y != e.y || f.polarity != e.polarity || f.x <= events[j - 1].x {
                break;
            }
            j += 1;
        }
        let pol = u16::from(e.polarity) << 11;
        if j - i == 1 {
            push(0x2000 | pol | (e.x & 0x7FF));
            i = j;
            continue;
        }
        // Vectors from the first x: VECT_12 while more than 8 pixels remain, then VECT_8.
        push(0x3000 | pol | (e.x & 0x7FF));
        let mut base = e.x;
        while i < j {
            let span = events[j - 1].x - base + 1;
            let width = if span > 8 { 12 } else { 8 };
            let mut mask = 0u16;
            while i < j && events[i].x < base + width {
                mask |= 1 << (events[i].x - base);
                i += 1;
            }
            push(if width == 12 { 0x4000 | mask } else { 0x5000 | mask });
            base += width;
        }
    }
    out
}

/// The `%` header evcal writes: the encoding (both the old `evt` line and the `format` line
/// with the size) and the geometry.
fn raw_header(encoding: Encoding, sensor: SensorSize) -> String {
    let (evt, format) = match encoding {
        Encoding::Evt2 => ("2.0", "EVT2".to_string()),
        Encoding::Evt21(Evt21Order::LowHalfFirst) => ("2.1", "EVT21".to_string()),
        Encoding::Evt21(Evt21Order::HighHalfFirst) => ("2.1", "EVT21".to_string()),
        Encoding::Evt3 => ("3.0", "EVT3".to_string()),
    };
    let legacy = if encoding == Encoding::Evt21(Evt21Order::HighHalfFirst) { ";endianness=legacy" } else { "" };
    let (w, h) = (sensor.width, sensor.height);
    format!("% evt {evt}\n% format {format};height={h};width={w}{legacy}\n% geometry {w}x{h}\n% integrator_name evcal\n% end\n")
}

/// Writes a Prophesee RAW file of `events`.
pub fn write_raw(path: &Path, encoding: Encoding, sensor: SensorSize, events: &[Event]) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    f.write_all(raw_header(encoding, sensor).as_bytes())?;
    f.write_all(&encode_evt(encoding, events))?;
    f.flush()
}

/// Writes a Prophesee `.dat` file of CD events (version 2, type 12, 8-byte records).
pub fn write_dat(path: &Path, sensor: SensorSize, events: &[Event]) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(f, "% Height {}\n% Version 2\n% Width {}\n", sensor.height, sensor.width)?;
    f.write_all(&[12, 8])?;
    for e in events {
        f.write_all(&(e.t_us as u32).to_le_bytes())?;
        let d = (u32::from(e.x) & 0x3FFF) | ((u32::from(e.y) & 0x3FFF) << 14) | (u32::from(e.polarity) << 28);
        f.write_all(&d.to_le_bytes())?;
    }
    f.flush()
}
