//! Prophesee event-stream decoders: EVT 2.0, EVT 2.1 and EVT 3.0, as the sensors (IMX636,
//! GenX320, Gen3/Gen4) send them and as Prophesee RAW files store them after their `%` header.
//!
//! The decoders are streaming and fixed-memory: push byte chunks of any size (a word may
//! straddle two chunks), pull events into a slice the caller owns. Nothing allocates, nothing
//! panics, whatever the bytes.
//!
//! ```
//! use evcal_core::{event::Event, evt::{Decoder, Encoding}};
//!
//! let mut dec = Decoder::new(Encoding::Evt3);
//! let mut out = [Event::default(); 64];
//! // TIME_HIGH 1, TIME_LOW 5, ADDR_Y 7, ADDR_X x=3 ON: one event at t = 4096 + 5 µs.
//! let chunks: [&[u8]; 2] = [&[0x01, 0x80, 0x05, 0x60, 0x07], &[0x00, 0x03, 0x28]];
//! let mut got = 0;
//! for chunk in chunks {
//!     let mut rest = chunk;
//!     loop {
//!         let r = dec.decode(rest, &mut out);
//!         rest = &rest[r.consumed..];
//!         got += r.events; // out[..r.events] are the new events
//!         if r.events < out.len() && rest.is_empty() {
//!             break; // chunk used up and nothing held back
//!         }
//!     }
//! }
//! assert_eq!(got, 1);
//! assert_eq!(out[0], Event { t_us: 4101, x: 3, y: 7, polarity: true });
//! assert_eq!(dec.pending_bytes(), 0); // no partial word left over
//! ```
//!
//! [`Decoder::feed`] wraps the same loop as an iterator, one event at a time.
//!
//! ## The formats (Prophesee's published specifications)
//!
//! The four most significant bits of every word give its type. All words are little-endian.
//!
//! * **EVT 2.0**, 32-bit words: `CD_OFF`/`CD_ON` (type 0/1: 6 low time bits, 11-bit x, 11-bit
//!   y), `EVT_TIME_HIGH` (8: the 28 high bits of a 34-bit µs time), `EXT_TRIGGER` (0xA),
//!   `OTHERS` (0xE), `CONTINUED` (0xF).
//! * **EVT 2.1**, 64-bit words: as EVT 2.0, but a CD word carries a 32-bit validity mask: bit
//!   `i` is an event at `x + i`. The IMX636 sends the high 32-bit half first
//!   ([`Evt21Order::HighHalfFirst`], RAW `format EVT21;...;endianness=legacy`), the GenX320
//!   the whole word little-endian ([`Evt21Order::LowHalfFirst`], RAW `format EVT21`).
//! * **EVT 3.0**, 16-bit words holding state: `EVT_ADDR_Y` (0: row), `EVT_ADDR_X` (2: one
//!   event at x with polarity), `VECT_BASE_X` (3: x and polarity of following vectors),
//!   `VECT_12` / `VECT_8` (4 / 5: validity masks of 12 / 8 pixels from the base, which then
//!   advances by 12 / 8), `EVT_TIME_LOW` / `EVT_TIME_HIGH` (6 / 8: low and high 12 bits of a
//!   24-bit µs time), `CONTINUED_4` (7), `EXT_TRIGGER` (0xA), `OTHERS` (0xE), `CONTINUED_12`
//!   (0xF).
//!
//! Other type values are reserved: such words are counted in [`DecodeStats::unknown`] (with the
//! offset of the first) and skipped. Triggers and the other non-CD words are counted and
//! skipped.
//!
//! ## Time
//!
//! The sensors' clocks wrap (EVT 2.x: 2^34 µs, 4 h 46 min; EVT 3.0: 2^24 µs, 16.8 s). A
//! `TIME_HIGH` smaller than the previous one by more than half its range is a wrap and moves
//! the time on by the full range, so event times are 64-bit and monotonic across wraps; a
//! smaller step back is taken as it is and counted ([`DecodeStats::time_high_steps_back`]),
//! and so is one right after a `TIME_HIGH` that jumped ahead by more than half the range (a
//! stray value, which a wrap would turn into a lasting jump of the whole clock range).
//! In EVT 3.0, an `EVT_TIME_LOW` smaller than the one before within the same `TIME_HIGH`
//! period means the low counter wrapped, and the high part moves on by one, as the
//! specification says ([`DecodeStats::time_low_wraps`]): sensors send the new `TIME_HIGH`
//! first, but some writers (expelliarmus) leave it out.
//! As the specifications say, decoding starts at the first `TIME_HIGH`: CD words before it
//! (and, in EVT 3.0, before the first `EVT_ADDR_Y` or vector base) have no complete time or
//! address, so their events are dropped and counted in [`DecodeStats::unsynced`], never
//! invented.

mod evt2;
mod evt3;

use crate::event::Event;

/// Which Prophesee encoding a byte stream holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Encoding {
    /// EVT 2.0: 32-bit words, one event per CD word.
    Evt2,
    /// EVT 2.1: 64-bit words, up to 32 events per CD word; the order of the 32-bit halves.
    Evt21(Evt21Order),
    /// EVT 3.0: 16-bit words with decoder state, vectors of up to 12 events.
    Evt3,
}

/// How the two 32-bit halves of an EVT 2.1 word are laid out in the byte stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Evt21Order {
    /// The whole 64-bit word little-endian (GenX320; RAW header `format EVT21`).
    LowHalfFirst,
    /// The high half (type, time, x, y) first, then the validity mask, each little-endian
    /// (IMX636; RAW header `format EVT21;...;endianness=legacy`).
    HighHalfFirst,
}

impl Encoding {
    /// Bytes in one word.
    pub const fn word_bytes(self) -> usize {
        match self {
            Encoding::Evt2 => 4,
            Encoding::Evt21(_) => 8,
            Encoding::Evt3 => 2,
        }
    }

    /// The most events one word can carry.
    pub const fn max_events_per_word(self) -> usize {
        match self {
            Encoding::Evt2 => 1,
            Encoding::Evt21(_) => 32,
            Encoding::Evt3 => 12,
        }
    }

    /// The name Prophesee uses (`EVT 2.0`, `EVT 2.1`, `EVT 3.0`).
    pub const fn name(self) -> &'static str {
        match self {
            Encoding::Evt2 => "EVT 2.0",
            Encoding::Evt21(_) => "EVT 2.1",
            Encoding::Evt3 => "EVT 3.0",
        }
    }
}

/// What a decoder has seen so far. Counters only grow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecodeStats {
    /// Bytes consumed, a partial word held for the next chunk included.
    pub bytes: u64,
    /// Events produced.
    pub events: u64,
    /// CD events dropped because the stream had not yet given their time (no `TIME_HIGH`
    /// yet) or, in EVT 3.0, their row (`EVT_ADDR_Y`) or vector base (`VECT_BASE_X`).
    pub unsynced: u64,
    /// `EXT_TRIGGER` words (skipped).
    pub triggers: u64,
    /// `OTHERS` and `CONTINUED` words (skipped).
    pub others: u64,
    /// Words of a reserved type (skipped).
    pub unknown: u64,
    /// Byte offset in the stream of the first reserved word, if any.
    pub first_unknown_at: Option<u64>,
    /// Wraps of the sensor clock seen (`TIME_HIGH` going back by more than half its range).
    pub time_wraps: u64,
    /// `TIME_HIGH` words smaller than the previous one by less than half the range, or by
    /// more right after one that jumped ahead as far (that one was the stray): not a wrap,
    /// so time steps back (a corrupt or spliced stream; the detector's input filter drops
    /// the events of the stray period).
    pub time_high_steps_back: u64,
    /// EVT 3.0 `EVT_TIME_LOW` words smaller than the one before in the same `TIME_HIGH`
    /// period: the low counter wrapped without a new `TIME_HIGH`, so the high part was moved
    /// on by one.
    pub time_low_wraps: u64,
}

/// The result of one [`Decoder::decode`] call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decoded {
    /// Bytes of the input consumed. Less than the input only if the output slice filled up.
    pub consumed: usize,
    /// Events written to the front of the output slice.
    pub events: usize,
}

/// Events of a vector word not yet written out (the output slice filled up mid-vector).
#[derive(Debug, Clone, Copy, Default)]
struct Vector {
    mask: u32,
    x: u16,
    y: u16,
    t_us: u64,
    polarity: bool,
}

/// The sensor clock's high part, extended across wraps.
#[derive(Debug, Clone, Copy)]
struct TimeHigh {
    /// Added to the sensor time: a whole number of clock ranges.
    epoch: u64,
    last: u32,
    seen: bool,
    /// The last value jumped ahead of the one before by more than half the range: a step
    /// back as far after it is the stream going on from a stray value, not a wrap.
    jumped: bool,
}

impl TimeHigh {
    const fn new() -> Self {
        Self { epoch: 0, last: 0, seen: false, jumped: false }
    }

    /// Takes a new `TIME_HIGH` value of `bits` bits, for a clock of `clock_bits` bits; returns
    /// the epoch to add.
    #[inline(always)]
    fn update(&mut self, high: u32, bits: u32, clock_bits: u32, stats: &mut DecodeStats) -> u64 {
        let half = 1 << (bits - 1);
        if self.seen && high < self.last {
            if self.last - high > half && !self.jumped {
                self.epoch = self.epoch.wrapping_add(1 << clock_bits);
                stats.time_wraps += 1;
            } else {
                stats.time_high_steps_back += 1;
            }
        }
        self.jumped = self.seen && high > self.last && high - self.last > half;
        self.last = high;
        self.seen = true;
        self.epoch
    }
}

/// A streaming decoder of one [`Encoding`]: push bytes, pull [`Event`]s.
///
/// About 80 bytes of state; no allocation. See the [module docs](self) for the loop.
#[derive(Debug, Clone)]
pub struct Decoder {
    encoding: Encoding,
    /// Bytes of a word split across chunks.
    carry: [u8; 8],
    carry_len: u8,
    pending: Vector,
    high: TimeHigh,
    /// The current time base (EVT 2.x: epoch + high << 6; EVT 3.0: the full time).
    base: u64,
    // EVT 3.0 state.
    time_low: u16,
    y: u16,
    x_base: u16,
    polarity: bool,
    has_y: bool,
    has_x_base: bool,
    stats: DecodeStats,
}

impl Decoder {
    /// A decoder at the start of a stream of `encoding`.
    pub const fn new(encoding: Encoding) -> Self {
        Self {
            encoding,
            carry: [0; 8],
            carry_len: 0,
            pending: Vector { mask: 0, x: 0, y: 0, t_us: 0, polarity: false },
            high: TimeHigh::new(),
            base: 0,
            time_low: 0,
            y: 0,
            x_base: 0,
            polarity: false,
            has_y: false,
            has_x_base: false,
            stats: DecodeStats {
                bytes: 0,
                events: 0,
                unsynced: 0,
                triggers: 0,
                others: 0,
                unknown: 0,
                first_unknown_at: None,
                time_wraps: 0,
                time_high_steps_back: 0,
                time_low_wraps: 0,
            },
        }
    }

    /// The encoding this decoder reads.
    pub const fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// What has been decoded, dropped and skipped so far.
    pub const fn stats(&self) -> &DecodeStats {
        &self.stats
    }

    /// Bytes of an incomplete word held back, waiting for the rest. Non-zero at the end of a
    /// stream means the stream was cut inside a word.
    pub const fn pending_bytes(&self) -> usize {
        self.carry_len as usize
    }

    /// Whether events of a vector word are held back because the last output slice filled up:
    /// call [`decode`](Self::decode) again (with an empty input if need be) to get them.
    pub const fn has_pending_events(&self) -> bool {
        self.pending.mask != 0
    }

    /// Decodes bytes from `input` into `out` until the input is used up or `out` is full.
    ///
    /// Returns how many input bytes were consumed and how many events were written to the
    /// front of `out`. A word split at the end of `input` is consumed and held until the next
    /// call completes it. When `consumed < input.len()`, or all of `out` was written, call
    /// again (with the unconsumed rest) to go on: some events may be held back. An empty `out`
    /// consumes nothing.
    pub fn decode(&mut self, input: &[u8], out: &mut [Event]) -> Decoded {
        let d = self.decode_inner(input, out);
        self.stats.events += d.events as u64;
        d
    }

    fn decode_inner(&mut self, input: &[u8], out: &mut [Event]) -> Decoded {
        let mut n = 0;
        self.drain(out, &mut n);
        if self.pending.mask != 0 || out.is_empty() {
            return Decoded { consumed: 0, events: n };
        }
        let wb = self.encoding.word_bytes();
        let mut used = 0;
        if self.carry_len > 0 {
            if n >= out.len() {
                return Decoded { consumed: 0, events: n };
            }
            let have = usize::from(self.carry_len);
            let take = (wb - have).min(input.len());
            self.carry[have..have + take].copy_from_slice(&input[..take]);
            used = take;
            self.carry_len += take as u8;
            self.stats.bytes += take as u64;
            if usize::from(self.carry_len) < wb {
                return Decoded { consumed: used, events: n };
            }
            self.carry_len = 0;
            let word = self.carry;
            // The word's offset: it ended `bytes` into the stream.
            let at = self.stats.bytes - wb as u64;
            self.run(&word[..wb], at, out, &mut n);
        }
        let body = &input[used..];
        let whole = body.len() - body.len() % wb;
        let at = self.stats.bytes;
        let done = self.run(&body[..whole], at, out, &mut n);
        self.stats.bytes += done as u64;
        used += done;
        if done == whole {
            // Keep a trailing partial word for the next call.
            let tail = &body[whole..];
            self.carry[..tail.len()].copy_from_slice(tail);
            self.carry_len = tail.len() as u8;
            self.stats.bytes += tail.len() as u64;
            used += tail.len();
        }
        Decoded { consumed: used, events: n }
    }

    /// An iterator over the events of `input`, one at a time (for callers that handle events
    /// singly, such as a firmware event source). Events held back at its end stay in the
    /// decoder for the next chunk; a partial word at its end is kept too.
    pub fn feed<'a>(&'a mut self, input: &'a [u8]) -> Events<'a> {
        Events { decoder: self, input }
    }

    /// Decodes whole words of `words` (a multiple of the word size) starting at stream offset
    /// `at`, stopping when `out` is full; returns the bytes consumed.
    fn run(&mut self, words: &[u8], at: u64, out: &mut [Event], n: &mut usize) -> usize {
        match self.encoding {
            Encoding::Evt2 => self.run_evt2(words, at, out, n),
            Encoding::Evt21(order) => self.run_evt21(words, order, at, out, n),
            Encoding::Evt3 => self.run_evt3(words, at, out, n),
        }
    }

    /// Writes held-back vector events.
    #[inline(always)]
    fn drain(&mut self, out: &mut [Event], n: &mut usize) {
        let p = &mut self.pending;
        while p.mask != 0 {
            let Some(slot) = out.get_mut(*n) else { return };
            let i = p.mask.trailing_zeros() as u16;
            *slot = Event { t_us: p.t_us, x: p.x.saturating_add(i), y: p.y, polarity: p.polarity };
            *n += 1;
            p.mask &= p.mask - 1;
        }
    }

    #[inline(always)]
    fn unknown(&mut self, at: u64) {
        self.stats.unknown += 1;
        if self.stats.first_unknown_at.is_none() {
            self.stats.first_unknown_at = Some(at);
        }
    }
}

/// The events of one input chunk, one at a time: see [`Decoder::feed`].
#[derive(Debug)]
pub struct Events<'a> {
    decoder: &'a mut Decoder,
    input: &'a [u8],
}

impl Iterator for Events<'_> {
    type Item = Event;

    fn next(&mut self) -> Option<Event> {
        let mut one = [Event::default()];
        loop {
            let r = self.decoder.decode(self.input, &mut one);
            self.input = self.input.get(r.consumed..).unwrap_or(&[]);
            if r.events == 1 {
                return Some(one[0]);
            }
            // Nothing produced: the chunk is used up (a partial word may be held).
            if self.input.is_empty() || r.consumed == 0 {
                return None;
            }
        }
    }
}

#[cfg(test)]
mod test;
