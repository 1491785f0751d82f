//! Event batches: how a recording crosses the slow link into the device.
//!
//! A batch holds consecutive events as a bit field after a small header. Per event:
//!
//! * the time step from the previous event (the first event's from the batch's `t0`),
//!   Rice-coded with the batch's parameter `k`: `q = dt >> k` as `q` one bits and a zero,
//!   then the low `k` bits of `dt`. A quotient of [`RICE_ESCAPE`] or more, and any step back
//!   in time, is escaped: [`RICE_ESCAPE`] one bits, a sign bit (1: backwards), 6 bits of
//!   `L − 1`, and the `L`-bit magnitude;
//! * `x` in `x_bits` and `y` in `y_bits` bits (the widths the batch's largest coordinates
//!   need, so any `u16` fits and the device's input filter sees events exactly as recorded);
//! * the polarity bit.
//!
//! The encoder picks the `k` that makes the batch shortest. On simulated DAVIS346 recordings
//! this comes to 2.7 bytes per event in 512-byte frames, everything included (the
//! `bytes_per_window_and_per_event` test); raw events are 8 bytes or more.
//!
//! Batches are self-contained (absolute `t0`), so a lost batch costs only its own events.

use super::{
    codec::{bit_len, bytes_for_bits, varint_len, BitCursor, BitWriter, Reader, Sink},
    frame::{emit_frame, frame_len_max},
    kind, Error, Result,
};
use crate::event::Event;

/// Quotients from this on are escaped (and the escape code starts with this many ones).
pub const RICE_ESCAPE: u32 = 16;
/// Largest Rice parameter.
pub const MAX_RICE_K: u8 = 32;
const LEN_BITS: u32 = 6;

/// A batch of events as parsed. [`events`](Self::events) decodes them on the fly.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EventBatch<'a> {
    /// Sequence number of this frame (see [`Ack`](super::Ack)).
    pub seq: u32,
    cursor: EventCursor,
    payload: &'a [u8],
}

/// A position in a parsed batch that borrows nothing, so that the device can keep it while
/// the batch's bytes stay in its receive buffer: call [`next`](Self::next) with the same
/// payload the batch was parsed from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EventCursor {
    /// Byte offset of the bit field in the frame's payload.
    start: u32,
    left: u32,
    t: u64,
    k: u8,
    x_bits: u8,
    y_bits: u8,
    /// Bit position in the bit field.
    bit: u32,
}

impl EventCursor {
    /// Events not yet decoded.
    pub const fn remaining(&self) -> u32 {
        self.left
    }

    /// The next event, or `None` at the end of the batch. `payload` must be the payload the
    /// batch was parsed from; with any other bytes this returns `None` early rather than fail.
    pub fn next(&mut self, payload: &[u8]) -> Option<Event> {
        if self.left == 0 {
            return None;
        }
        let bits = payload.get(self.start as usize..)?;
        let mut c = BitCursor::at(self.bit as usize);
        let e = decode_one(&mut c, bits, self.t, self.k, self.x_bits, self.y_bits).ok()?;
        self.bit = c.position() as u32;
        self.t = e.t_us;
        self.left -= 1;
        Some(e)
    }
}

impl<'a> EventBatch<'a> {
    /// Number of events.
    pub const fn len(&self) -> usize {
        self.cursor.left as usize
    }

    /// Whether the batch has no events.
    pub const fn is_empty(&self) -> bool {
        self.cursor.left == 0
    }

    /// The events, decoded on the fly.
    pub fn events(&self) -> BatchEvents<'a> {
        BatchEvents { cursor: self.cursor, payload: self.payload }
    }

    /// A detached position at the first event, for [`EventCursor::next`].
    pub const fn cursor(&self) -> EventCursor {
        self.cursor
    }

    pub(crate) fn read(r: &mut Reader<'a>) -> Result<Self> {
        let seq = r.varint_u32()?;
        let t0 = r.varint()?;
        let count = r.varint_u32()?;
        let k = r.u8()?;
        let x_bits = r.u8()?;
        let y_bits = r.u8()?;
        if k > MAX_RICE_K || x_bits > 16 || y_bits > 16 {
            return Err(Error::Invalid);
        }
        let payload = r.whole();
        let start = r.position();
        let bits = r.rest();
        // Decode everything once, so that iterating later cannot fail.
        let mut c = BitCursor::default();
        let mut t = t0;
        for _ in 0..count {
            t = decode_one(&mut c, bits, t, k, x_bits, y_bits)?.t_us;
        }
        c.finish(bits)?;
        let cursor = EventCursor { start: start as u32, left: count, t: t0, k, x_bits, y_bits, bit: 0 };
        Ok(Self { seq, cursor, payload })
    }
}

/// Iterator over a batch's events.
#[derive(Debug, Clone)]
pub struct BatchEvents<'a> {
    cursor: EventCursor,
    payload: &'a [u8],
}

impl Iterator for BatchEvents<'_> {
    type Item = Event;

    fn next(&mut self) -> Option<Event> {
        self.cursor.next(self.payload)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.cursor.left as usize, Some(self.cursor.left as usize))
    }
}

fn decode_one(c: &mut BitCursor, bits: &[u8], t_prev: u64, k: u8, xb: u8, yb: u8) -> Result<Event> {
    let avail = c.remaining(bits).min(32) as u32;
    let w = c.peek(bits, avail)?;
    let ones = (!w).trailing_zeros().min(avail);
    let t_us = if ones >= RICE_ESCAPE {
        c.take(bits, RICE_ESCAPE)?;
        let back = c.take(bits, 1)? == 1;
        let len = c.take(bits, LEN_BITS)? + 1;
        let mag = take_wide(c, bits, len)?;
        if back { t_prev.checked_sub(mag) } else { t_prev.checked_add(mag) }.ok_or(Error::Invalid)?
    } else {
        if ones == avail {
            return Err(Error::Truncated);
        }
        c.take(bits, ones + 1)?;
        let low = take_wide(c, bits, k.into())?;
        t_prev.checked_add((u64::from(ones) << k) | low).ok_or(Error::Invalid)?
    };
    let x = c.take(bits, xb.into())? as u16;
    let y = c.take(bits, yb.into())? as u16;
    let polarity = c.take(bits, 1)? == 1;
    Ok(Event { t_us, x, y, polarity })
}

/// Reads up to 64 bits.
fn take_wide(c: &mut BitCursor, bits: &[u8], n: u32) -> Result<u64> {
    if n <= 32 {
        return Ok(c.take(bits, n)?.into());
    }
    let low = u64::from(c.take(bits, 32)?);
    Ok(low | (u64::from(c.take(bits, n - 32)?) << 32))
}

fn put_wide(w: &mut BitWriter, s: &mut impl Sink, v: u64, n: u32) {
    if n <= 32 {
        w.put(s, v, n);
    } else {
        w.put(s, v & 0xFFFF_FFFF, 32);
        w.put(s, v >> 32, n - 32);
    }
}

/// A time step as the encoder sees it.
#[derive(Clone, Copy)]
enum Step {
    Forward(u64),
    Back(u64),
}

fn step(t_prev: u64, t: u64) -> Step {
    if t >= t_prev {
        Step::Forward(t - t_prev)
    } else {
        Step::Back(t_prev - t)
    }
}

/// Bits of one time step with Rice parameter `k`.
fn step_bits(s: Step, k: u32) -> u64 {
    match s {
        Step::Forward(dt) if (dt >> k) < u64::from(RICE_ESCAPE) => (dt >> k) + 1 + u64::from(k),
        Step::Forward(m) | Step::Back(m) => u64::from(RICE_ESCAPE + 1 + LEN_BITS + bit_len(m).max(1)),
    }
}

fn put_step(w: &mut BitWriter, s: &mut impl Sink, st: Step, k: u32) {
    match st {
        Step::Forward(dt) if (dt >> k) < u64::from(RICE_ESCAPE) => {
            let q = (dt >> k) as u32;
            // q ones, then a zero
            w.put(s, (1u64 << q) - 1, q + 1);
            put_wide(w, s, dt, k);
        }
        Step::Forward(m) | Step::Back(m) => {
            w.put(s, (1u64 << RICE_ESCAPE) - 1, RICE_ESCAPE);
            w.put(s, matches!(st, Step::Back(_)).into(), 1);
            let len = bit_len(m).max(1);
            w.put(s, u64::from(len - 1), LEN_BITS);
            put_wide(w, s, m, len);
        }
    }
}

/// Sizes a batch as events are added, for every Rice parameter at once, so that the host can
/// fill frames to the device's limit in one pass.
#[derive(Debug, Clone)]
pub struct BatchSizer {
    seq: u32,
    t0: u64,
    t_prev: u64,
    count: u32,
    max_x: u16,
    max_y: u16,
    step_bits: [u64; MAX_RICE_K as usize + 1],
}

impl BatchSizer {
    /// An empty batch with sequence number `seq`.
    pub const fn new(seq: u32) -> Self {
        Self { seq, t0: 0, t_prev: 0, count: 0, max_x: 0, max_y: 0, step_bits: [0; MAX_RICE_K as usize + 1] }
    }

    /// Adds an event.
    pub fn add(&mut self, e: &Event) {
        if self.count == 0 {
            self.t0 = e.t_us;
            self.t_prev = e.t_us;
        }
        let s = step(self.t_prev, e.t_us);
        for (k, b) in self.step_bits.iter_mut().enumerate() {
            *b += step_bits(s, k as u32);
        }
        self.t_prev = e.t_us;
        self.max_x = self.max_x.max(e.x);
        self.max_y = self.max_y.max(e.y);
        self.count += 1;
    }

    /// Events added.
    pub const fn count(&self) -> u32 {
        self.count
    }

    /// The best Rice parameter (the smallest of equals).
    fn best_k(&self) -> (u8, u64) {
        let mut best = (0u8, u64::MAX);
        for (k, &b) in self.step_bits.iter().enumerate() {
            if b < best.1 {
                best = (k as u8, b);
            }
        }
        best
    }

    /// Payload bytes of the batch so far.
    pub fn payload_len(&self) -> usize {
        let (_, steps) = self.best_k();
        let xy = u64::from(bit_len(self.max_x.into()) + bit_len(self.max_y.into()) + 1);
        let bits = steps + xy * u64::from(self.count);
        1 + varint_len(self.seq.into())
            + varint_len(self.t0)
            + varint_len(self.count.into())
            + 3
            + bytes_for_bits(bits) as usize
    }

    /// Longest the batch's frame can be on the wire, delimiters included.
    pub fn frame_len_max(&self) -> usize {
        frame_len_max(self.payload_len())
    }
}

/// How many of `events`, from the first, fit in one batch frame of at most `max_frame` bytes
/// on the wire (at least one if any, as long as one event fits at all).
pub fn events_that_fit(seq: u32, events: &[Event], max_frame: usize) -> usize {
    let mut s = BatchSizer::new(seq);
    for (i, e) in events.iter().enumerate() {
        s.add(e);
        if s.frame_len_max() > max_frame {
            return i;
        }
    }
    events.len()
}

/// Writes `events` as one batch frame with sequence number `seq` into `out`; the frame's
/// length. Use [`events_that_fit`] to size batches to the device's frame limit.
pub fn emit_events(seq: u32, events: &[Event], out: &mut [u8]) -> Result<usize> {
    let count = u32::try_from(events.len()).map_err(|_| Error::Invalid)?;
    let mut sizer = BatchSizer::new(seq);
    for e in events {
        sizer.add(e);
    }
    let (k, _) = sizer.best_k();
    let xb = bit_len(sizer.max_x.into());
    let yb = bit_len(sizer.max_y.into());
    emit_frame(out, |w| {
        w.put(kind::EVENTS);
        w.varint(seq.into());
        w.varint(sizer.t0);
        w.varint(count.into());
        w.put(k);
        w.put(xb as u8);
        w.put(yb as u8);
        let mut bw = BitWriter::default();
        let mut t_prev = sizer.t0;
        for e in events {
            put_step(&mut bw, w, step(t_prev, e.t_us), k.into());
            t_prev = e.t_us;
            bw.put(w, e.x.into(), xb);
            bw.put(w, e.y.into(), yb);
            bw.put(w, e.polarity.into(), 1);
        }
        bw.finish(w);
    })
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::wire::{frame::decode_in_place, HostMessage};
    use std::vec::Vec;

    fn ev(t_us: u64, x: u16, y: u16, polarity: bool) -> Event {
        Event { t_us, x, y, polarity }
    }

    fn payload(events: &[Event], seq: u32) -> Vec<u8> {
        let mut out = vec![0u8; 64 + events.len() * 40];
        let n = emit_events(seq, events, &mut out).unwrap();
        let mut body = out[1..n - 1].to_vec();
        let m = decode_in_place(&mut body).unwrap();
        body.truncate(m);
        body
    }

    fn decode(p: &[u8]) -> (u32, Vec<Event>) {
        match HostMessage::parse(p).unwrap() {
            HostMessage::Events(b) => (b.seq, b.events().collect()),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn golden_batch() {
        let events = [ev(100, 3, 2, true), ev(101, 1, 0, false), ev(103, 2, 1, true)];
        let p = payload(&events, 0);
        // type, seq 0, t0 100, 3 events, k 0, x 2 bits, y 2 bits, then
        // (dt 0: "0") x=3 y=2 p=1 | (dt 1: "10") x=1 y=0 p=0 | (dt 2: "110") x=2 y=1 p=1
        assert_eq!(p, [0x82, 0x00, 0x64, 0x03, 0x00, 0x02, 0x02, 0x76, 0x61, 0x16]);
        assert_eq!(decode(&p), (0, events.to_vec()));
    }

    #[test]
    fn round_trips_steps_back_big_gaps_and_wide_coordinates() {
        let events = [
            ev(5_000_000_000, 0, 0, false),
            ev(5_000_000_000, 65535, 65535, true),
            ev(4_999_999_990, 1, 2, true),              // back in time: escaped
            ev(4_999_999_990 + (1 << 40), 7, 7, false), // a 12-day gap: escaped
            ev(u64::MAX, 3, 3, true),
            ev(0, 3, 3, true), // back to zero
        ];
        let p = payload(&events, 77);
        assert_eq!(decode(&p), (77, events.to_vec()));
    }

    #[test]
    fn empty_batch_round_trips() {
        let p = payload(&[], 3);
        assert_eq!(decode(&p), (3, Vec::new()));
    }

    #[test]
    fn picks_the_shortest_rice_parameter() {
        // steps of about 40 µs: k around 5 beats k = 0 (40 ones per event)
        let events: Vec<Event> = (0..200).map(|i| ev(i * 40 + (i % 7), (i % 300) as u16, 10, i % 2 == 0)).collect();
        let p = payload(&events, 1);
        let k = p[1 + 1 + varint_len(0) + varint_len(200)];
        assert!((4..=6).contains(&k), "k = {k}");
        assert_eq!(decode(&p).1, events);
        let mut s = BatchSizer::new(1);
        events.iter().for_each(|e| s.add(e));
        assert_eq!(s.payload_len(), p.len());
    }

    #[test]
    fn batches_fill_frames_to_the_limit_and_never_beyond() {
        let events: Vec<Event> = (0..5000u64)
            .map(|i| ev(i * 3 + (i * i) % 5, (i * 37 % 346) as u16, (i * 11 % 260) as u16, i % 3 == 0))
            .collect();
        let mut out = [0u8; 600];
        let mut rest = &events[..];
        let mut seq = 0;
        while !rest.is_empty() {
            let n = events_that_fit(seq, rest, 512);
            assert!(n > 0);
            let len = emit_events(seq, &rest[..n], &mut out).unwrap();
            assert!(len <= 512, "{len}");
            if n < rest.len() {
                // one more event would not have fitted
                let mut s = BatchSizer::new(seq);
                rest[..=n].iter().for_each(|e| s.add(e));
                assert!(s.frame_len_max() > 512);
            }
            rest = &rest[n..];
            seq += 1;
        }
        assert!(seq > 20 && seq < 40, "{seq} batches");
    }

    #[test]
    fn malformed_batches_are_rejected() {
        let events = [ev(1, 1, 1, true), ev(2, 2, 2, false)];
        let p = payload(&events, 0);
        // k out of range
        let mut bad = p.clone();
        bad[4] = MAX_RICE_K + 1;
        assert_eq!(HostMessage::parse(&bad).err(), Some(Error::Invalid));
        // one event too many announced
        let mut bad = p.clone();
        bad[3] = 3;
        assert_eq!(HostMessage::parse(&bad).err(), Some(Error::Truncated));
        // a byte too many
        let mut bad = p.clone();
        bad.push(0);
        assert_eq!(HostMessage::parse(&bad).err(), Some(Error::Trailing));
        // time running below zero
        let mut back = vec![0x82, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00];
        // escape (16 ones), sign 1, length-1 = 0 (1 bit), magnitude 1, x, y none, p 0
        back.extend([0xFF, 0xFF, 0x81, 0x00]);
        assert_eq!(HostMessage::parse(&back).err(), Some(Error::Invalid));
    }

    #[test]
    fn cursor_resumes_where_it_stopped() {
        let events: Vec<Event> = (0..50).map(|i| ev(10 + i * 3, i as u16, 2 * i as u16, i % 2 == 1)).collect();
        let p = payload(&events, 4);
        let mut cur = match HostMessage::parse(&p).unwrap() {
            HostMessage::Events(b) => b.cursor(),
            other => panic!("{other:?}"),
        };
        let mut got = Vec::new();
        while let Some(e) = cur.next(&p) {
            got.push(e);
            let copy = cur; // a cursor is plain data: copying it keeps the place
            assert_eq!(copy.remaining(), cur.remaining());
        }
        assert_eq!(got, events);
        assert_eq!(cur.next(&p), None);
    }
}
