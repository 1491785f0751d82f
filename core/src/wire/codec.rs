//! Fields inside a frame: LEB128 varints, zigzag integers, little-endian `f32`, and LSB-first
//! bit fields.
//!
//! Reading never panics: every read checks the bounds and returns [`Error::Truncated`] past
//! the end, and [`Error::Invalid`] for an overlong or overflowing varint (so that every value
//! has exactly one varint encoding). Writing goes through [`Sink`], which the frame writer
//! implements; the sink reports a full buffer once, at the end.

use super::{Error, Result};

/// Where encoded fields go: the frame writer (COBS and CRC on the fly) or a byte counter.
pub(crate) trait Sink {
    /// Appends one byte.
    fn put(&mut self, b: u8);

    /// Appends bytes.
    fn put_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.put(b);
        }
    }

    /// Appends `v` as an LEB128 varint: 7 bits per byte, least significant first, high bit
    /// set on every byte but the last.
    fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.put((v as u8) | 0x80);
            v >>= 7;
        }
        self.put(v as u8);
    }

    /// Appends a signed value as a zigzag varint (0, -1, 1, -2, ... → 0, 1, 2, 3, ...).
    fn zigzag(&mut self, v: i64) {
        self.varint(((v << 1) ^ (v >> 63)) as u64);
    }

    /// Appends an `f32` by its bits, little-endian (exact, whatever the value).
    fn f32(&mut self, v: f32) {
        self.put_all(&v.to_le_bytes());
    }
}

/// Counts bytes instead of writing them: the payload size of a message.
#[derive(Debug, Default)]
pub(crate) struct Counter(pub usize);

impl Sink for Counter {
    fn put(&mut self, _b: u8) {
        self.0 += 1;
    }
}

/// Bytes of `v` as a varint.
pub(crate) const fn varint_len(v: u64) -> usize {
    let bits = 64 - v.leading_zeros() as usize;
    if bits == 0 {
        1
    } else {
        bits.div_ceil(7)
    }
}

/// Reads fields from a frame's payload, front to back.
#[derive(Debug, Clone)]
pub(crate) struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    pub(crate) const fn new(buf: &'a [u8]) -> Self {
        Self { buf, pos: 0 }
    }

    pub(crate) fn u8(&mut self) -> Result<u8> {
        let b = *self.buf.get(self.pos).ok_or(Error::Truncated)?;
        self.pos += 1;
        Ok(b)
    }

    pub(crate) fn varint(&mut self) -> Result<u64> {
        let mut v = 0u64;
        for i in 0..10 {
            let b = self.u8()?;
            let low = u64::from(b & 0x7F);
            // The tenth byte holds bit 63 only.
            if i == 9 && b > 1 {
                return Err(Error::Invalid);
            }
            v |= low << (7 * i);
            if b & 0x80 == 0 {
                // A last byte of zero after others is an overlong encoding.
                if b == 0 && i > 0 {
                    return Err(Error::Invalid);
                }
                return Ok(v);
            }
        }
        Err(Error::Invalid)
    }

    pub(crate) fn varint_u32(&mut self) -> Result<u32> {
        u32::try_from(self.varint()?).map_err(|_| Error::Invalid)
    }

    pub(crate) fn varint_u16(&mut self) -> Result<u16> {
        u16::try_from(self.varint()?).map_err(|_| Error::Invalid)
    }

    pub(crate) fn zigzag_i32(&mut self) -> Result<i32> {
        let z = self.varint()?;
        let v = ((z >> 1) as i64) ^ -((z & 1) as i64);
        i32::try_from(v).map_err(|_| Error::Invalid)
    }

    pub(crate) fn f32(&mut self) -> Result<f32> {
        let b = self.buf.get(self.pos..self.pos + 4).ok_or(Error::Truncated)?;
        self.pos += 4;
        Ok(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// Bytes read so far.
    pub(crate) const fn position(&self) -> usize {
        self.pos
    }

    /// Everything, read or not.
    pub(crate) const fn whole(&self) -> &'a [u8] {
        self.buf
    }

    /// The bytes not read yet (a message's trailing bit field), consuming them.
    pub(crate) fn rest(&mut self) -> &'a [u8] {
        let r = self.buf.get(self.pos..).unwrap_or(&[]);
        self.pos = self.buf.len();
        r
    }

    /// Ends reading: bytes left over make the message invalid.
    pub(crate) fn finish(&self) -> Result<()> {
        if self.pos == self.buf.len() {
            Ok(())
        } else {
            Err(Error::Trailing)
        }
    }
}

/// Packs bit fields least significant bit first into a [`Sink`].
#[derive(Debug, Default)]
pub(crate) struct BitWriter {
    acc: u64,
    bits: u32,
}

impl BitWriter {
    /// Appends the low `n` bits of `v` (`n` ≤ 32).
    pub(crate) fn put(&mut self, sink: &mut impl Sink, v: u64, n: u32) {
        debug_assert!(n <= 32);
        let v = if n >= 64 { v } else { v & ((1u64 << n) - 1) };
        self.acc |= v << self.bits;
        self.bits += n;
        while self.bits >= 8 {
            sink.put(self.acc as u8);
            self.acc >>= 8;
            self.bits -= 8;
        }
    }

    /// Flushes a partial last byte, padded with zero bits.
    pub(crate) fn finish(self, sink: &mut impl Sink) {
        if self.bits > 0 {
            sink.put(self.acc as u8);
        }
    }
}

/// Bytes that `bits` bits occupy.
pub(crate) const fn bytes_for_bits(bits: u64) -> u64 {
    bits.div_ceil(8)
}

/// A read position in a bit field: a plain index, so that a caller can keep it between
/// calls (the device decodes an event batch a few events at a time).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct BitCursor {
    bit: usize,
}

impl BitCursor {
    /// A cursor at bit `bit`.
    pub(crate) const fn at(bit: usize) -> Self {
        Self { bit }
    }

    /// Bits read so far.
    pub(crate) const fn position(&self) -> usize {
        self.bit
    }

    /// Reads `n` bits (`n` ≤ 32), least significant first.
    pub(crate) fn take(&mut self, buf: &[u8], n: u32) -> Result<u32> {
        let v = self.peek(buf, n)?;
        self.bit += n as usize;
        Ok(v)
    }

    /// The next `n` bits (`n` ≤ 32) without consuming them.
    pub(crate) fn peek(&self, buf: &[u8], n: u32) -> Result<u32> {
        if n == 0 {
            return Ok(0);
        }
        if n > 32 || self.bit + n as usize > buf.len() * 8 {
            return Err(Error::Truncated);
        }
        let first = self.bit / 8;
        let shift = (self.bit % 8) as u32;
        let mut acc = 0u64;
        // n + shift ≤ 39 bits: at most 5 bytes.
        for (i, b) in buf.iter().skip(first).take(5).enumerate() {
            acc |= u64::from(*b) << (8 * i);
        }
        Ok(((acc >> shift) & ((1u64 << n) - 1)) as u32)
    }

    /// Bits left in `buf` after the cursor.
    pub(crate) fn remaining(&self, buf: &[u8]) -> usize {
        (buf.len() * 8).saturating_sub(self.bit)
    }

    /// Ends a bit field: only the zero padding of the last byte may remain.
    pub(crate) fn finish(&self, buf: &[u8]) -> Result<()> {
        let left = self.remaining(buf);
        if left >= 8 {
            return Err(Error::Trailing);
        }
        if left > 0 && self.peek(buf, left as u32)? != 0 {
            return Err(Error::Invalid);
        }
        Ok(())
    }
}

/// Bits needed to hold `v` (0 for 0).
pub(crate) const fn bit_len(v: u64) -> u32 {
    64 - v.leading_zeros()
}

#[cfg(test)]
mod test {
    use super::*;

    struct Vec8(std::vec::Vec<u8>);
    impl Sink for Vec8 {
        fn put(&mut self, b: u8) {
            self.0.push(b);
        }
    }

    fn varint_bytes(v: u64) -> std::vec::Vec<u8> {
        let mut s = Vec8(std::vec::Vec::new());
        s.varint(v);
        s.0
    }

    #[test]
    fn varint_golden_and_round_trip() {
        assert_eq!(varint_bytes(0), [0x00]);
        assert_eq!(varint_bytes(127), [0x7F]);
        assert_eq!(varint_bytes(128), [0x80, 0x01]);
        assert_eq!(varint_bytes(300), [0xAC, 0x02]);
        assert_eq!(varint_bytes(u32::MAX.into()), [0xFF, 0xFF, 0xFF, 0xFF, 0x0F]);
        for v in [0, 1, 127, 128, 16383, 16384, u64::from(u32::MAX), u64::MAX - 1, u64::MAX] {
            let b = varint_bytes(v);
            assert_eq!(b.len(), varint_len(v));
            let mut r = Reader::new(&b);
            assert_eq!(r.varint(), Ok(v));
            assert_eq!(r.finish(), Ok(()));
        }
    }

    #[test]
    fn varint_rejects_overlong_overflow_and_truncation() {
        assert_eq!(Reader::new(&[0x80, 0x00]).varint(), Err(Error::Invalid));
        assert_eq!(
            Reader::new(&[0xFF; 9].iter().copied().chain([0x02]).collect::<std::vec::Vec<_>>()).varint(),
            Err(Error::Invalid)
        );
        assert_eq!(Reader::new(&[0xFF; 11]).varint(), Err(Error::Invalid));
        assert_eq!(Reader::new(&[0x80]).varint(), Err(Error::Truncated));
        assert_eq!(Reader::new(&[0x80, 0x80, 0x80, 0x80, 0x10]).varint_u32(), Err(Error::Invalid));
    }

    #[test]
    fn zigzag_round_trips() {
        for v in [0i32, -1, 1, -2, 2, i32::MIN, i32::MAX] {
            let mut s = Vec8(std::vec::Vec::new());
            s.zigzag(v.into());
            assert_eq!(Reader::new(&s.0).zigzag_i32(), Ok(v));
        }
        let mut s = Vec8(std::vec::Vec::new());
        s.zigzag(-3);
        assert_eq!(s.0, [5]);
    }

    #[test]
    fn bits_pack_lsb_first_and_read_back() {
        let mut s = Vec8(std::vec::Vec::new());
        let mut w = BitWriter::default();
        w.put(&mut s, 0b101, 3);
        w.put(&mut s, 0xABCD_EF01, 32);
        w.put(&mut s, 1, 1);
        w.finish(&mut s);
        assert_eq!(s.0.len(), 5);
        assert_eq!(s.0[0] & 0b111, 0b101);
        let mut c = BitCursor::default();
        assert_eq!(c.take(&s.0, 3), Ok(0b101));
        assert_eq!(c.take(&s.0, 32), Ok(0xABCD_EF01));
        assert_eq!(c.take(&s.0, 1), Ok(1));
        assert_eq!(c.finish(&s.0), Ok(()));
        assert_eq!(c.take(&s.0, 5), Err(Error::Truncated));
        // nonzero padding is rejected
        let mut bad = s.0.clone();
        bad[4] |= 0x80;
        let mut c = BitCursor::default();
        assert!(c.take(&bad, 32).is_ok() && c.take(&bad, 4).is_ok());
        assert_eq!(c.finish(&bad), Err(Error::Invalid));
    }
}
