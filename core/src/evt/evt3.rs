//! EVT 3.0: 16-bit words that update decoder state (row, vector base, time) and emit events
//! singly (`EVT_ADDR_X`) or as 12- and 8-pixel vectors.

use super::{Decoder, Vector};
use crate::event::Event;

/// Word types (the top four bits).
const ADDR_Y: u16 = 0x0;
const ADDR_X: u16 = 0x2;
const VECT_BASE_X: u16 = 0x3;
const VECT_12: u16 = 0x4;
const VECT_8: u16 = 0x5;
const TIME_LOW: u16 = 0x6;
const CONTINUED_4: u16 = 0x7;
const TIME_HIGH: u16 = 0x8;
const EXT_TRIGGER: u16 = 0xA;
const OTHERS: u16 = 0xE;
const CONTINUED_12: u16 = 0xF;

/// Bits of the `TIME_HIGH` field and of the whole clock.
const HIGH_BITS: u32 = 12;
const CLOCK_BITS: u32 = 24;

impl Decoder {
    /// EVT 3.0: see [`Decoder::run`].
    pub(super) fn run_evt3(&mut self, words: &[u8], at: u64, out: &mut [Event], n: &mut usize) -> usize {
        let mut i = 0;
        while let Some(&[lo, hi]) = words.get(i..i + 2) {
            let Some(slot) = out.get_mut(*n) else { break };
            let w = u16::from_le_bytes([lo, hi]);
            match w >> 12 {
                ADDR_X => {
                    if self.high.seen && self.has_y {
                        *slot = Event { t_us: self.base, x: w & 0x7FF, y: self.y, polarity: w & 0x800 != 0 };
                        *n += 1;
                    } else {
                        self.stats.unsynced += 1;
                    }
                }
                ADDR_Y => {
                    self.y = w & 0x7FF;
                    self.has_y = true;
                }
                VECT_BASE_X => {
                    self.x_base = w & 0x7FF;
                    self.polarity = w & 0x800 != 0;
                    self.has_x_base = true;
                }
                VECT_12 => self.vector(u32::from(w & 0xFFF), 12, out, n),
                VECT_8 => self.vector(u32::from(w & 0xFF), 8, out, n),
                TIME_LOW => {
                    let low = w & 0xFFF;
                    if low < self.time_low && self.high.seen {
                        // The low counter wrapped within one TIME_HIGH period: as the
                        // specification says, the high part moves on by one. (Sensors send a
                        // new TIME_HIGH first, so this only acts on streams that leave it out,
                        // such as expelliarmus's.)
                        let high = (self.high.last + 1) & 0xFFF;
                        let epoch = self.high.update(high, HIGH_BITS, CLOCK_BITS, &mut self.stats);
                        self.base = epoch + (u64::from(high) << 12);
                        self.stats.time_low_wraps += 1;
                    }
                    self.time_low = low;
                    self.base = (self.base & !0xFFF) | u64::from(low);
                }
                TIME_HIGH => {
                    let high = u32::from(w & 0xFFF);
                    // The sensor repeats TIME_HIGH every 16 µs; only a new value starts a new
                    // 4096 µs period (low bits from zero until the next TIME_LOW).
                    if !self.high.seen || high != self.high.last {
                        let epoch = self.high.update(high, HIGH_BITS, CLOCK_BITS, &mut self.stats);
                        self.time_low = 0;
                        self.base = epoch + (u64::from(high) << 12);
                    }
                }
                EXT_TRIGGER => self.stats.triggers += 1,
                CONTINUED_4 | OTHERS | CONTINUED_12 => self.stats.others += 1,
                _ => self.unknown(at + i as u64),
            }
            i += 2;
        }
        i
    }

    /// A `VECT_12` / `VECT_8` word: events at the base x plus each set bit, then the base moves
    /// on by the vector's width.
    #[inline(always)]
    fn vector(&mut self, mask: u32, width: u16, out: &mut [Event], n: &mut usize) {
        if self.high.seen && self.has_y && self.has_x_base {
            self.pending = Vector { mask, x: self.x_base, y: self.y, t_us: self.base, polarity: self.polarity };
            self.drain(out, n);
        } else {
            self.stats.unsynced += u64::from(mask.count_ones());
        }
        // Saturating: a corrupt stream of vectors without a new base must not overflow.
        self.x_base = self.x_base.saturating_add(width);
    }
}
