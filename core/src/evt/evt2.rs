//! EVT 2.0 (32-bit words) and EVT 2.1 (64-bit vector words): the same time scheme, a 34-bit
//! µs clock split into 28 high bits (`EVT_TIME_HIGH`) and 6 low bits carried by each event.

use super::{Decoder, Evt21Order, Vector};
use crate::event::Event;

/// Word types (the top four bits).
const CD_OFF: u32 = 0x0;
const CD_ON: u32 = 0x1;
const TIME_HIGH: u32 = 0x8;
const EXT_TRIGGER: u32 = 0xA;
const OTHERS: u32 = 0xE;
const CONTINUED: u32 = 0xF;

/// Bits of the `TIME_HIGH` field and of the whole clock.
const HIGH_BITS: u32 = 28;
const CLOCK_BITS: u32 = 34;
const HIGH_MASK: u32 = (1 << HIGH_BITS) - 1;

impl Decoder {
    #[inline(always)]
    fn time_high_2(&mut self, high: u32) {
        let epoch = self.high.update(high, HIGH_BITS, CLOCK_BITS, &mut self.stats);
        self.base = epoch + (u64::from(high) << 6);
    }

    /// EVT 2.0: see [`Decoder::run`].
    pub(super) fn run_evt2(&mut self, words: &[u8], at: u64, out: &mut [Event], n: &mut usize) -> usize {
        let mut i = 0;
        while let Some(&[a, b, c, d]) = words.get(i..i + 4) {
            let Some(slot) = out.get_mut(*n) else { break };
            let w = u32::from_le_bytes([a, b, c, d]);
            match w >> 28 {
                CD_OFF | CD_ON => {
                    if self.high.seen {
                        *slot = Event {
                            t_us: self.base | u64::from((w >> 22) & 0x3F),
                            x: ((w >> 11) & 0x7FF) as u16,
                            y: (w & 0x7FF) as u16,
                            polarity: w >> 28 == CD_ON,
                        };
                        *n += 1;
                    } else {
                        self.stats.unsynced += 1;
                    }
                }
                TIME_HIGH => self.time_high_2(w & HIGH_MASK),
                EXT_TRIGGER => self.stats.triggers += 1,
                OTHERS | CONTINUED => self.stats.others += 1,
                _ => self.unknown(at + i as u64),
            }
            i += 4;
        }
        i
    }

    /// EVT 2.1: see [`Decoder::run`].
    pub(super) fn run_evt21(
        &mut self,
        words: &[u8],
        order: Evt21Order,
        at: u64,
        out: &mut [Event],
        n: &mut usize,
    ) -> usize {
        let mut i = 0;
        while let Some(&[b0, b1, b2, b3, b4, b5, b6, b7]) = words.get(i..i + 8) {
            if *n >= out.len() {
                break;
            }
            let first = u32::from_le_bytes([b0, b1, b2, b3]);
            let second = u32::from_le_bytes([b4, b5, b6, b7]);
            // `head` holds type, time, x and y; `mask` the validity bits.
            let (head, mask) = match order {
                Evt21Order::LowHalfFirst => (second, first),
                Evt21Order::HighHalfFirst => (first, second),
            };
            match head >> 28 {
                CD_OFF | CD_ON => {
                    if !self.high.seen {
                        self.stats.unsynced += u64::from(mask.count_ones());
                    } else if mask != 0 {
                        self.pending = Vector {
                            mask,
                            x: ((head >> 11) & 0x7FF) as u16,
                            y: (head & 0x7FF) as u16,
                            t_us: self.base | u64::from((head >> 22) & 0x3F),
                            polarity: head >> 28 == CD_ON,
                        };
                        self.drain(out, n);
                    }
                }
                TIME_HIGH => self.time_high_2(head & HIGH_MASK),
                EXT_TRIGGER => self.stats.triggers += 1,
                OTHERS | CONTINUED => self.stats.others += 1,
                _ => self.unknown(at + i as u64),
            }
            i += 8;
        }
        i
    }
}
