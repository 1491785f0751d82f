//! Detection messages: one window's counts, then its centres packed per field with a frame
//! of reference.
//!
//! Centres arrive quantised to 1/1024 px ([`fixed`](super::fixed)). Each of their five fields
//! (u, v, r, spread, n) is written as the window's minimum, then every centre's offset from
//! it in as few bits as the window's largest offset needs: no field needs its whole range
//! within one window (radii that span 3.2–9.8 px cost 13 bits each, not 32). The layout is
//! in the [module docs](super#messages).

use super::{
    codec::{bit_len, bytes_for_bits, BitCursor, BitWriter, Reader, Sink},
    fixed::WireCentre,
    frame::{emit_frame, frame_len_max},
    kind, Error, Result,
};
use crate::detect::Detection;

/// The counts of one window (the centres follow in the message).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectionHeader {
    /// Window sequence number (from 0 per session): gaps show lost frames.
    pub seq: u32,
    /// The window's reference time (the middle of its events' span; its centres are given at it), µs.
    pub t_ref_us: u64,
    /// Events in the window.
    pub events: u16,
    /// Events left as noise by clustering.
    pub noise: u16,
    /// Clusters kept.
    pub clusters: u16,
    /// Clusters beyond the device's capacity, dropped.
    pub dropped_clusters: u16,
    /// Clusters the fit rejected.
    pub rejected_fits: u16,
}

impl DetectionHeader {
    /// The header of a core detection.
    pub fn from_detection<const C: usize>(d: &Detection<C>) -> Self {
        Self {
            seq: d.info.seq,
            t_ref_us: d.info.t_ref_us,
            events: d.stats.events,
            noise: d.stats.noise,
            clusters: d.stats.clusters,
            dropped_clusters: d.stats.dropped_clusters,
            rejected_fits: d.stats.rejected_fits,
        }
    }
}

/// The packed fields of a centre, in order, with their widest bit width.
const FIELDS: usize = 5;
const MAX_WIDTH: [u8; FIELDS] = [32, 32, 32, 32, 16];

/// The fields of a centre as integers, in the packed order.
fn fields(c: &WireCentre) -> [i64; FIELDS] {
    [c.u.into(), c.v.into(), c.r.into(), c.spread.into(), c.n.into()]
}

/// Frame-of-reference code of one field over a window's centres: every value is
/// `base + offset`, offset in `width` bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct FieldCode {
    base: i64,
    width: u8,
}

/// A detection message as parsed: the window's counts and its centres, unpacked on the fly.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectionFrame<'a> {
    /// The window's counts.
    pub header: DetectionHeader,
    count: u16,
    codes: [FieldCode; FIELDS],
    bits: &'a [u8],
}

impl<'a> DetectionFrame<'a> {
    /// Number of centres.
    pub const fn len(&self) -> usize {
        self.count as usize
    }

    /// Whether the window has no centres.
    pub const fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The centres, in the order the device found them.
    pub fn centres(&self) -> Centres<'a> {
        Centres { left: self.count, codes: self.codes, bits: self.bits, cursor: BitCursor::default() }
    }

    pub(super) fn read(r: &mut Reader<'a>) -> Result<Self> {
        let header = DetectionHeader {
            seq: r.varint_u32()?,
            t_ref_us: r.varint()?,
            events: r.varint_u16()?,
            noise: r.varint_u16()?,
            clusters: r.varint_u16()?,
            dropped_clusters: r.varint_u16()?,
            rejected_fits: r.varint_u16()?,
        };
        let count = r.varint_u16()?;
        let mut codes = [FieldCode::default(); FIELDS];
        if count > 0 {
            for (i, c) in codes.iter_mut().enumerate() {
                c.base = match i {
                    0 | 1 => r.zigzag_i32()?.into(),
                    4 => r.varint_u16()?.into(),
                    _ => r.varint_u32()?.into(),
                };
                c.width = r.u8()?;
                if c.width > MAX_WIDTH[i] {
                    return Err(Error::Invalid);
                }
            }
        }
        let per_centre: u64 = codes.iter().map(|c| u64::from(c.width)).sum::<u64>() + 1;
        let bits = r.rest();
        let need = bytes_for_bits(per_centre * u64::from(count));
        if (bits.len() as u64) < need {
            return Err(Error::Truncated);
        }
        if bits.len() as u64 > need {
            return Err(Error::Trailing);
        }
        let frame = Self { header, count, codes, bits };
        // Check every value now, so that iterating cannot fail.
        let mut cursor = BitCursor::default();
        for _ in 0..count {
            for (i, c) in codes.iter().enumerate() {
                let v = c.base + i64::from(cursor.take(bits, c.width.into())?);
                let ok = match i {
                    0 | 1 => i32::try_from(v).is_ok(),
                    4 => u16::try_from(v).is_ok(),
                    _ => u32::try_from(v).is_ok(),
                };
                if !ok {
                    return Err(Error::Invalid);
                }
            }
            cursor.take(bits, 1)?;
        }
        cursor.finish(bits)?;
        Ok(frame)
    }
}

/// Iterator over a [`DetectionFrame`]'s centres.
#[derive(Debug, Clone)]
pub struct Centres<'a> {
    left: u16,
    codes: [FieldCode; FIELDS],
    bits: &'a [u8],
    cursor: BitCursor,
}

impl Iterator for Centres<'_> {
    type Item = WireCentre;

    fn next(&mut self) -> Option<WireCentre> {
        self.left = self.left.checked_sub(1)?;
        let mut f = [0i64; FIELDS];
        for (v, c) in f.iter_mut().zip(self.codes) {
            *v = c.base + i64::from(self.cursor.take(self.bits, c.width.into()).ok()?);
        }
        let converged = self.cursor.take(self.bits, 1).ok()? == 1;
        // Parsing checked every value's range; the fallbacks are never taken.
        Some(WireCentre {
            u: i32::try_from(f[0]).unwrap_or_default(),
            v: i32::try_from(f[1]).unwrap_or_default(),
            r: u32::try_from(f[2]).unwrap_or_default(),
            spread: u32::try_from(f[3]).unwrap_or_default(),
            n: u16::try_from(f[4]).unwrap_or_default(),
            converged,
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.left.into(), Some(self.left.into()))
    }
}

impl ExactSizeIterator for Centres<'_> {}

/// Writes a detection message as a frame into `out`: the header, then the centres packed
/// per field with a frame of reference (each field's minimum, then every value's offset
/// from it in as few bits as the window's largest offset needs). `centres` is walked twice.
/// Centres beyond 65,535 are left out (no device holds that many).
pub fn emit_detection<I>(header: &DetectionHeader, centres: I, out: &mut [u8]) -> Result<usize>
where
    I: Iterator<Item = WireCentre> + Clone,
{
    let codes = field_codes(centres.clone());
    let count = centres.clone().take(usize::from(u16::MAX)).count();
    emit_frame(out, |w| {
        w.put(kind::DETECTION);
        w.varint(header.seq.into());
        w.varint(header.t_ref_us);
        for v in [header.events, header.noise, header.clusters, header.dropped_clusters, header.rejected_fits] {
            w.varint(v.into());
        }
        w.varint(count as u64);
        if count == 0 {
            return;
        }
        for (i, c) in codes.iter().enumerate() {
            match i {
                0 | 1 => w.zigzag(c.base),
                _ => w.varint(c.base as u64),
            }
            w.put(c.width);
        }
        let mut bw = BitWriter::default();
        for c in centres.take(count) {
            for (v, code) in fields(&c).into_iter().zip(codes) {
                bw.put(w, (v - code.base) as u64, code.width.into());
            }
            bw.put(w, c.converged.into(), 1);
        }
        bw.finish(w);
    })
}

fn field_codes(centres: impl Iterator<Item = WireCentre>) -> [FieldCode; FIELDS] {
    let mut lo = [i64::MAX; FIELDS];
    let mut hi = [i64::MIN; FIELDS];
    for c in centres.take(usize::from(u16::MAX)) {
        for (i, v) in fields(&c).into_iter().enumerate() {
            lo[i] = lo[i].min(v);
            hi[i] = hi[i].max(v);
        }
    }
    let mut codes = [FieldCode::default(); FIELDS];
    for i in 0..FIELDS {
        if lo[i] <= hi[i] {
            codes[i] = FieldCode { base: lo[i], width: bit_len((hi[i] - lo[i]) as u64) as u8 };
        }
    }
    codes
}

/// Writes a core detection as a detection message, quantising its centres
/// ([`WireCentre::from_centre`]); the frame's length.
pub fn emit_core_detection<const C: usize>(d: &Detection<C>, out: &mut [u8]) -> Result<usize> {
    emit_detection(&DetectionHeader::from_detection(d), d.centres.iter().map(WireCentre::from_centre), out)
}

/// Longest payload of a detection message with `c` centres.
pub const fn detection_payload_max(c: usize) -> usize {
    // type, seq, t_ref, five u16 counts, count, five (base, width) pairs
    let header = 1 + 5 + 10 + 5 * 3 + 3 + (5 + 1) * 4 + (3 + 1);
    let per_centre_bits = 32 * 4 + 16 + 1;
    header + (c * per_centre_bits).div_ceil(8)
}

/// Longest detection frame with `c` centres on the wire, delimiters included: the size of
/// the device's transmit buffer.
pub const fn detection_frame_max(c: usize) -> usize {
    frame_len_max(detection_payload_max(c))
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::wire::message::test::{device_one, emit, payload};
    use crate::wire::{DeviceMessage, Feed, FrameAccumulator};
    use std::vec::Vec;

    #[test]
    fn golden_detection() {
        let header = DetectionHeader {
            seq: 5,
            t_ref_us: 1000,
            events: 4000,
            noise: 100,
            clusters: 2,
            dropped_clusters: 0,
            rejected_fits: 0,
        };
        let centres = [
            WireCentre { u: 1024, v: 2048, r: 5120, spread: 100, n: 30, converged: true },
            WireCentre { u: 1030, v: 2040, r: 5121, spread: 90, n: 31, converged: false },
        ];
        let f = emit(|o| emit_detection(&header, centres.iter().copied(), o));
        let expected = [
            0x02, 0x05, 0xE8, 0x07, 0xA0, 0x1F, 0x64, 0x02, 0x00, 0x00, // header
            0x02, // two centres
            0x80, 0x10, 0x03, // u: base 1024 (zigzag 2048), 3 bits
            0xF0, 0x1F, 0x04, // v: base 2040 (zigzag 4080), 4 bits
            0x80, 0x28, 0x01, // r: base 5120, 1 bit
            0x5A, 0x04, // spread: base 90, 4 bits
            0x1E, 0x01, // n: base 30, 1 bit
            0x40, 0xAA, 0x21, 0x04, // 2 × 14 bits, LSB first, zero-padded
        ];
        device_one(&f, &expected, |m| match m {
            DeviceMessage::Detection(d) => {
                assert_eq!(d.header, header);
                assert_eq!(d.centres().collect::<Vec<_>>(), centres);
                assert_eq!(d.centres().len(), 2);
            }
            other => panic!("{other:?}"),
        });
    }

    #[test]
    fn golden_empty_detection() {
        let header = DetectionHeader { seq: 1, ..Default::default() };
        let f = emit(|o| emit_detection(&header, core::iter::empty(), o));
        device_one(&f, &[0x02, 0x01, 0, 0, 0, 0, 0, 0, 0], |m| match m {
            DeviceMessage::Detection(d) => assert!(d.is_empty() && d.header == header),
            other => panic!("{other:?}"),
        });
    }

    #[test]
    fn malformed_detections_are_rejected() {
        // width above 32
        let mut d = vec![0x02, 0, 0, 0, 0, 0, 0, 0, 1];
        d.extend([0, 33, 0, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(DeviceMessage::parse(&d), Err(Error::Invalid));
        // bit field one byte short, one byte long
        let header = DetectionHeader::default();
        let c = [WireCentre { u: -5, v: 7, r: 3, spread: 1, n: 9, converged: true }; 3];
        let p = payload(&emit(|o| emit_detection(&header, c.iter().copied(), o)));
        assert_eq!(DeviceMessage::parse(&p[..p.len() - 1]), Err(Error::Truncated));
        let mut long = p.clone();
        long.push(0);
        assert_eq!(DeviceMessage::parse(&long), Err(Error::Trailing));
        // nonzero padding bits
        let mut pad = p.clone();
        *pad.last_mut().unwrap() |= 0x80;
        assert_eq!(DeviceMessage::parse(&pad), Err(Error::Invalid));
    }

    /// A full window (96 centres, the capacity) with centres spread over the whole sensor,
    /// radii from 2 px to a third of the height, spreads up to 3 px, clusters of up to 1000
    /// events: under 1 KiB even on the largest sensor we support (Prophesee, 1280 x 720).
    #[test]
    fn a_full_window_is_under_1_kib_on_every_sensor() {
        for (w, h) in [(346u32, 260u32), (640, 480), (1280, 720)] {
            let header = DetectionHeader {
                seq: 123_456,
                t_ref_us: 3_600_000_000,
                events: 4000,
                noise: 900,
                clusters: 96,
                ..Default::default()
            };
            let c: Vec<WireCentre> = (0..96u32)
                .map(|i| WireCentre {
                    u: (((i * 7919) % w) << 10) as i32 + (i * 37 % 1024) as i32,
                    v: (((i * 104_729) % h) << 10) as i32 + (i * 91 % 1024) as i32,
                    r: (2 << 10) + (i * 409) % ((h / 3 - 2) << 10),
                    spread: (i * 331) % (3 << 10),
                    n: 20 + (i * 97 % 980) as u16,
                    converged: i % 5 != 0,
                })
                .collect();
            let f = emit(|o| emit_detection(&header, c.iter().copied(), o));
            assert!(f.len() <= 1024, "{w} x {h}: {} B", f.len());
            eprintln!("96 centres on {w} x {h}: {} B", f.len());
        }
    }

    #[test]
    fn detection_frame_fits_the_bound_in_the_worst_case() {
        let header = DetectionHeader {
            seq: u32::MAX,
            t_ref_us: u64::MAX,
            events: u16::MAX,
            noise: u16::MAX,
            clusters: u16::MAX,
            dropped_clusters: u16::MAX,
            rejected_fits: u16::MAX,
        };
        let mut c = vec![WireCentre { u: i32::MIN, v: i32::MIN, r: 0, spread: 0, n: 0, converged: false }; 96];
        c[1] = WireCentre { u: i32::MAX, v: i32::MAX, r: u32::MAX, spread: u32::MAX, n: u16::MAX, converged: true };
        let f = emit(|o| emit_detection(&header, c.iter().copied(), o));
        assert!(f.len() <= detection_frame_max(96), "{} > {}", f.len(), detection_frame_max(96));
        assert!(payload(&f).len() <= detection_payload_max(96));
        let p = payload(&f);
        match DeviceMessage::parse(&p).unwrap() {
            DeviceMessage::Detection(d) => assert_eq!(d.centres().collect::<Vec<_>>(), c),
            other => panic!("{other:?}"),
        }
        let mut acc: FrameAccumulator<2048> = FrameAccumulator::new();
        assert!(matches!(acc.feed(&f), Feed::Frame { .. }));
    }
}
