//! Hand-checked words for each format, and property tests: any chunking and any output size
//! give the events of a straightforward word-by-word reference decoder; random bytes never
//! panic.

use super::*;
use proptest::prelude::*;
use std::vec::Vec;

fn ev(t_us: u64, x: u16, y: u16, polarity: bool) -> Event {
    Event { t_us, x, y, polarity }
}

/// Decodes `bytes` in one go with a roomy output.
fn decode_all(encoding: Encoding, bytes: &[u8]) -> (Vec<Event>, Decoder) {
    decode_chunked(encoding, bytes, &[usize::MAX], 4096)
}

/// Decodes `bytes` cut into pieces of the given sizes (cycled), into an output of `out_len`.
fn decode_chunked(encoding: Encoding, bytes: &[u8], sizes: &[usize], out_len: usize) -> (Vec<Event>, Decoder) {
    let mut dec = Decoder::new(encoding);
    let mut out = std::vec![Event::default(); out_len];
    let mut got = Vec::new();
    let mut rest = bytes;
    let mut k = 0;
    loop {
        let take = sizes[k % sizes.len()].clamp(1, rest.len().max(1)).min(rest.len());
        k += 1;
        let mut chunk = &rest[..take];
        rest = &rest[take..];
        loop {
            let r = dec.decode(chunk, &mut out);
            got.extend_from_slice(&out[..r.events]);
            chunk = &chunk[r.consumed..];
            if chunk.is_empty() && r.events < out.len() {
                break;
            }
        }
        if rest.is_empty() {
            break;
        }
    }
    (got, dec)
}

fn words32(ws: &[u32]) -> Vec<u8> {
    ws.iter().flat_map(|w| w.to_le_bytes()).collect()
}

fn words16(ws: &[u16]) -> Vec<u8> {
    ws.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// EVT 2.1 words as the given order lays them out.
fn words64(ws: &[u64], order: Evt21Order) -> Vec<u8> {
    ws.iter()
        .flat_map(|&w| {
            let (hi, lo) = ((w >> 32) as u32, w as u32);
            let mut b = [0u8; 8];
            match order {
                Evt21Order::LowHalfFirst => b = w.to_le_bytes(),
                Evt21Order::HighHalfFirst => {
                    b[..4].copy_from_slice(&hi.to_le_bytes());
                    b[4..].copy_from_slice(&lo.to_le_bytes());
                }
            }
            b
        })
        .collect()
}

#[test]
fn evt2_hand_checked_words() {
    // TIME_HIGH 0x0000123 -> base 0x123 << 6 = 18624 µs.
    // CD_ON, t low 5, x 100, y 200: 0001 000101 00001100100 00011001000
    let on = (0x1 << 28) | (5 << 22) | (100 << 11) | 200;
    assert_eq!(on, 0x1143_20C8);
    let off = (7 << 22) | (639 << 11) | 479; // CD_OFF
    let bytes = words32(&[on, 0x8000_0123, on, 0xA000_0001, off, 0xE000_0000, 0xF000_0000, 0x3000_0000]);
    let (got, dec) = decode_all(Encoding::Evt2, &bytes);
    assert_eq!(got, [ev(18629, 100, 200, true), ev(18631, 639, 479, false)]);
    let s = dec.stats();
    assert_eq!((s.unsynced, s.triggers, s.others, s.unknown), (1, 1, 2, 1));
    assert_eq!(s.first_unknown_at, Some(28), "the reserved word 0x3 is the 8th word");
    assert_eq!((s.events, s.bytes), (2, 32));
}

#[test]
fn evt2_time_wraps_at_34_bits() {
    let cd = |t6: u32| (t6 << 22) | (1 << 11) | 2;
    let last_high = (1u32 << 28) - 1;
    let bytes = words32(&[0x8000_0000 | last_high, cd(63), 0x8000_0000, cd(0), 0x8000_0001, cd(1)]);
    let (got, dec) = decode_all(Encoding::Evt2, &bytes);
    let t: Vec<u64> = got.iter().map(|e| e.t_us).collect();
    assert_eq!(t, [(1 << 34) - 1, 1 << 34, (1 << 34) + 65]);
    assert_eq!(dec.stats().time_wraps, 1);
    // a small step back is not a wrap
    let bytes = words32(&[0x8000_0010, cd(0), 0x8000_000F, cd(0)]);
    let (got, dec) = decode_all(Encoding::Evt2, &bytes);
    assert_eq!((got[0].t_us, got[1].t_us), (16 << 6, 15 << 6));
    assert_eq!((dec.stats().time_wraps, dec.stats().time_high_steps_back), (0, 1));
}

/// A stray `TIME_HIGH` more than half the range ahead and then the stream going on: a step
/// back, not a wrap that would move every later event on by the whole clock range (the
/// input filter drops the stray period's events).
#[test]
fn a_stray_time_high_far_ahead_is_no_wrap() {
    let cd = |t6: u32| (t6 << 22) | (1 << 11) | 2;
    let stray = 0x10 + (1 << 27) + 5;
    let bytes = words32(&[0x8000_0010, cd(0), 0x8000_0000 | stray, cd(1), 0x8000_0010, cd(2), 0x8000_0011, cd(3)]);
    let (got, dec) = decode_all(Encoding::Evt2, &bytes);
    let t: Vec<u64> = got.iter().map(|e| e.t_us).collect();
    assert_eq!(t, [16 << 6, (u64::from(stray) << 6) + 1, (16 << 6) + 2, (17 << 6) + 3]);
    assert_eq!((dec.stats().time_wraps, dec.stats().time_high_steps_back), (0, 1));
}

#[test]
fn evt21_both_half_orders_from_the_spec_example() {
    // The specification's example: the 64-bit word 0x0102030405060708 is sent as bytes
    // 04 03 02 01 08 07 06 05 by the IMX636 and 08 07 .. 01 by the GenX320.
    assert_eq!(words64(&[0x0102_0304_0506_0708], Evt21Order::HighHalfFirst), [4, 3, 2, 1, 8, 7, 6, 5]);
    assert_eq!(words64(&[0x0102_0304_0506_0708], Evt21Order::LowHalfFirst), [8, 7, 6, 5, 4, 3, 2, 1]);
    // TIME_HIGH 2 (base 128 µs); EVT_POS t low 3, x 64, y 10, mask bits 0, 1, 31;
    // EVT_NEG t low 4, x 1248, y 719, mask bit 5; EXT_TRIGGER; OTHERS.
    let th: u64 = (0x8 << 60) | (2 << 32);
    let pos: u64 = (0x1 << 60) | (3 << 54) | (64 << 43) | (10 << 32) | 0x8000_0003;
    let neg: u64 = (4 << 54) | (1248 << 43) | (719 << 32) | (1 << 5);
    let trig: u64 = (0xA << 60) | (1 << 40) | (1 << 32);
    let others: u64 = 0xE << 60;
    let want = [ev(131, 64, 10, true), ev(131, 65, 10, true), ev(131, 95, 10, true), ev(132, 1253, 719, false)];
    for order in [Evt21Order::LowHalfFirst, Evt21Order::HighHalfFirst] {
        let bytes = words64(&[pos, th, pos, neg, trig, others], order);
        let (got, dec) = decode_all(Encoding::Evt21(order), &bytes);
        assert_eq!(got, want, "{order:?}");
        let s = dec.stats();
        assert_eq!((s.unsynced, s.triggers, s.others, s.events), (3, 1, 1, 4), "{order:?}");
    }
    // The wrong order does not give these events.
    let bytes = words64(&[th, pos, neg], Evt21Order::HighHalfFirst);
    let (got, _) = decode_all(Encoding::Evt21(Evt21Order::LowHalfFirst), &bytes);
    assert_ne!(got, want);
}

#[test]
fn evt3_hand_checked_words() {
    let w = |ty: u16, payload: u16| (ty << 12) | payload;
    let bytes = words16(&[
        w(0x2, 5),                // ADDR_X before any time: unsynced
        w(0x8, 0x0AB),            // TIME_HIGH 0xAB: base 0xAB000
        w(0x2, 5),                // ADDR_X before any row: unsynced
        w(0x0, 719),              // ADDR_Y 719
        w(0x6, 0x123),            // TIME_LOW 0x123
        w(0x2, 0x800 | 1279),     // ADDR_X 1279 ON
        w(0x3, 16),               // VECT_BASE_X 16 OFF
        w(0x4, 0b1000_0000_0101), // VECT_12: x 16, 18, 27; base -> 28
        w(0x5, 0b1000_0001),      // VECT_8: x 28, 35; base -> 36
        w(0x7, 3),                // CONTINUED_4
        w(0xE, 1),                // OTHERS
        w(0xF, 2),                // CONTINUED_12
        w(0xA, 0x101),            // EXT_TRIGGER
        w(0x8, 0x0AB),            // TIME_HIGH repeated: time unchanged
        w(0x2, 0x800 | 36),       // ADDR_X 36 ON
        w(0x8, 0x0AC),            // TIME_HIGH 0xAC: low bits restart at 0
        w(0x4, 1),                // VECT_12 at x 36 (the base moved on), OFF
        w(0x1, 0),                // reserved
        w(0x9, 0),                // reserved
    ]);
    let (got, dec) = decode_all(Encoding::Evt3, &bytes);
    let t = 0xAB123;
    assert_eq!(
        got,
        [
            ev(t, 1279, 719, true),
            ev(t, 16, 719, false),
            ev(t, 18, 719, false),
            ev(t, 27, 719, false),
            ev(t, 28, 719, false),
            ev(t, 35, 719, false),
            ev(t, 36, 719, true),
            ev(0xAC000, 36, 719, false),
        ]
    );
    let s = dec.stats();
    assert_eq!((s.unsynced, s.others, s.triggers, s.unknown), (2, 3, 1, 2));
    assert_eq!(s.first_unknown_at, Some(34));
}

#[test]
fn evt3_time_wraps_at_24_bits() {
    let bytes = words16(&[0x0001, 0x8FFF, 0x6FFF, 0x2001, 0x8000, 0x2002, 0x8001, 0x6001, 0x2003]);
    let (got, dec) = decode_all(Encoding::Evt3, &bytes);
    let t: Vec<u64> = got.iter().map(|e| e.t_us).collect();
    assert_eq!(t, [(1 << 24) - 1, 1 << 24, (1 << 24) + 4097]);
    assert_eq!(dec.stats().time_wraps, 1);
}

#[test]
fn evt3_time_low_wrap_moves_the_high_part_on() {
    // TIME_HIGH 4095, TIME_LOW 4000, event; TIME_LOW 10 without a TIME_HIGH: the low counter
    // wrapped, so TIME_HIGH is 0 of the next clock period; a later TIME_HIGH 0 changes nothing.
    let bytes = words16(&[0x0001, 0x8FFF, 0x6FA0, 0x2001, 0x600A, 0x2002, 0x8000, 0x2003, 0x6014, 0x2004]);
    let (got, dec) = decode_all(Encoding::Evt3, &bytes);
    let t: Vec<u64> = got.iter().map(|e| e.t_us).collect();
    assert_eq!(t, [0xFFFFA0, (1 << 24) + 10, (1 << 24) + 10, (1 << 24) + 20]);
    let s = dec.stats();
    assert_eq!((s.time_low_wraps, s.time_wraps, s.time_high_steps_back), (1, 1, 0));
}

#[test]
fn evt3_vector_without_base_is_unsynced() {
    let bytes = words16(&[0x8000, 0x0001, 0x4FFF, 0x5003]);
    let (got, dec) = decode_all(Encoding::Evt3, &bytes);
    assert!(got.is_empty());
    assert_eq!(dec.stats().unsynced, 14);
}

#[test]
fn feed_iterator_and_split_words() {
    let bytes = words16(&[0x8001, 0x0007, 0x3000, 0x4FFF, 0x2805]);
    let mut dec = Decoder::new(Encoding::Evt3);
    let mut got: Vec<Event> = Vec::new();
    // odd chunk sizes split words
    for chunk in bytes.chunks(3) {
        got.extend(dec.feed(chunk));
    }
    assert_eq!(got.len(), 13);
    assert_eq!(got[12], ev(4096, 5, 7, true));
    assert_eq!(dec.pending_bytes(), 0);
    // a cut word stays pending
    got.extend(dec.feed(&[0x05]));
    assert_eq!(dec.pending_bytes(), 1);
    assert_eq!(dec.stats().bytes, bytes.len() as u64 + 1);
}

#[test]
fn full_output_holds_vector_events_back() {
    let bytes = words16(&[0x8001, 0x0007, 0x3000, 0x4FFF]);
    let mut dec = Decoder::new(Encoding::Evt3);
    let mut out = [Event::default(); 5];
    let r = dec.decode(&bytes, &mut out);
    assert_eq!((r.consumed, r.events), (8, 5));
    assert!(dec.has_pending_events());
    let r = dec.decode(&[], &mut out);
    assert_eq!((r.consumed, r.events), (0, 5));
    let r = dec.decode(&[], &mut out);
    assert_eq!((r.consumed, r.events), (0, 2));
    assert!(!dec.has_pending_events());
    assert_eq!(out[1].x, 11);
    assert_eq!(dec.stats().events, 12);
    assert_eq!(dec.decode(&bytes, &mut []).consumed, 0, "an empty output consumes nothing");
}

/// A word-by-word reference decoder written straight from the specifications, allocating
/// freely; the real decoder must agree with it on any stream.
fn reference(encoding: Encoding, bytes: &[u8]) -> Vec<Event> {
    let mut out = Vec::new();
    let mut epoch = 0u64;
    let mut last_high: Option<u32> = None;
    // Whether the last high jumped ahead by more than half the range (a stray: the step
    // back after it is no wrap).
    let mut jumped = false;
    let mut wrap = |high: u32, bits: u32, clock: u32, epoch: &mut u64| {
        let half = 1 << (bits - 1);
        if let Some(l) = last_high {
            if high < l && l - high > half && !jumped {
                *epoch += 1 << clock;
            }
        }
        jumped = last_high.is_some_and(|l| high > l && high - l > half);
        last_high = Some(high);
    };
    match encoding {
        Encoding::Evt2 => {
            let mut base = None;
            for c in bytes.chunks_exact(4) {
                let w = u32::from_le_bytes(c.try_into().unwrap());
                match w >> 28 {
                    0 | 1 => {
                        if let Some(b) = base {
                            let t = b + u64::from((w >> 22) & 63);
                            out.push(ev(t, ((w >> 11) & 2047) as u16, (w & 2047) as u16, w >> 28 == 1));
                        }
                    }
                    8 => {
                        let h = w & 0xFFF_FFFF;
                        wrap(h, 28, 34, &mut epoch);
                        base = Some(epoch + (u64::from(h) << 6));
                    }
                    _ => {}
                }
            }
        }
        Encoding::Evt21(order) => {
            let mut base = None;
            for c in bytes.chunks_exact(8) {
                let a = u32::from_le_bytes(c[..4].try_into().unwrap());
                let b = u32::from_le_bytes(c[4..].try_into().unwrap());
                let w = match order {
                    Evt21Order::LowHalfFirst => (u64::from(b) << 32) | u64::from(a),
                    Evt21Order::HighHalfFirst => (u64::from(a) << 32) | u64::from(b),
                };
                match w >> 60 {
                    0 | 1 => {
                        if let Some(bt) = base {
                            let t = bt + ((w >> 54) & 63);
                            let (x, y) = (((w >> 43) & 2047) as u16, ((w >> 32) & 2047) as u16);
                            for i in 0..32 {
                                if w & (1 << i) != 0 {
                                    out.push(ev(t, x + i, y, w >> 60 == 1));
                                }
                            }
                        }
                    }
                    8 => {
                        let h = ((w >> 32) & 0xFFF_FFFF) as u32;
                        wrap(h, 28, 34, &mut epoch);
                        base = Some(epoch + (u64::from(h) << 6));
                    }
                    _ => {}
                }
            }
        }
        Encoding::Evt3 => {
            let (mut high, mut low, mut y, mut xb, mut pol) = (None::<u32>, 0u64, None, None::<u32>, false);
            for c in bytes.chunks_exact(2) {
                let w = u16::from_le_bytes([c[0], c[1]]);
                let p = w & 0xFFF;
                let t = high.map(|h| epoch + (u64::from(h) << 12) + low);
                match w >> 12 {
                    0 => y = Some(p & 2047),
                    2 => {
                        if let (Some(t), Some(y)) = (t, y) {
                            out.push(ev(t, p & 2047, y, p & 0x800 != 0));
                        }
                    }
                    3 => {
                        xb = Some(u32::from(p & 2047));
                        pol = p & 0x800 != 0;
                    }
                    4 | 5 => {
                        let width: u16 = if w >> 12 == 4 { 12 } else { 8 };
                        if let (Some(t), Some(y), Some(x)) = (t, y, xb) {
                            for i in 0..width {
                                if p & (1 << i) != 0 {
                                    out.push(ev(t, (x + u32::from(i)).min(65535) as u16, y, pol));
                                }
                            }
                        }
                        xb = xb.map(|x| (x + u32::from(width)).min(65535));
                    }
                    6 => {
                        if let Some(h) = high.filter(|_| u64::from(p) < low) {
                            let h = (h + 1) & 0xFFF;
                            wrap(h, 12, 24, &mut epoch);
                            high = Some(h);
                        }
                        low = u64::from(p);
                    }
                    8 => {
                        let h = u32::from(p);
                        if high != Some(h) {
                            wrap(h, 12, 24, &mut epoch);
                            high = Some(h);
                            low = 0;
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    out
}

fn encodings() -> impl Strategy<Value = Encoding> {
    prop_oneof![
        Just(Encoding::Evt2),
        Just(Encoding::Evt21(Evt21Order::LowHalfFirst)),
        Just(Encoding::Evt21(Evt21Order::HighHalfFirst)),
        Just(Encoding::Evt3),
    ]
}

/// Streams of plausible words: mostly the types that carry events and time, some of
/// everything else, time highs that step forward, wrap or jump back.
fn stream(encoding: Encoding) -> impl Strategy<Value = Vec<u8>> {
    let n = 0..300usize;
    match encoding {
        Encoding::Evt2 => prop::collection::vec(
            prop_oneof![
                6 => (0u32..2, any::<u32>()).prop_map(|(ty, r)| (ty << 28) | (r & 0x0FFF_FFFF)),
                2 => (0u32..64).prop_map(|h| 0x8000_0000 | h | (0x0FFF_FFC0 * u32::from(h > 60))),
                1 => any::<u32>(),
            ],
            n,
        )
        .prop_map(|ws| words32(&ws))
        .boxed(),
        Encoding::Evt21(order) => prop::collection::vec(
            prop_oneof![
                6 => (0u64..2, any::<u64>()).prop_map(|(ty, r)| (ty << 60) | (r & 0x0FFF_FFFF_FFFF_FFFF)),
                2 => (0u64..64).prop_map(|h| (0x8u64 << 60) | ((h | (0x0FFF_FFC0 * u64::from(h > 60))) << 32)),
                1 => any::<u64>(),
            ],
            n,
        )
        .prop_map(move |ws| words64(&ws, order))
        .boxed(),
        Encoding::Evt3 => prop::collection::vec(
            prop_oneof![
                3 => (0u16..0x1000).prop_map(|p| 0x2000 | p),
                2 => (0u16..0x1000).prop_map(|p| p & 0x7FF),
                2 => (0u16..0x1000).prop_map(|p| 0x3000 | p),
                3 => (4u16..6, 0u16..0x1000).prop_map(|(ty, p)| (ty << 12) | p),
                2 => (0u16..0x1000).prop_map(|p| 0x6000 | p),
                2 => (0u16..8).prop_map(|h| 0x8000 | h | (0xFF8 * u16::from(h > 5))),
                1 => any::<u16>(),
            ],
            n,
        )
        .prop_map(|ws| words16(&ws))
        .boxed(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn any_chunking_gives_the_reference_events(
        (encoding, bytes) in encodings().prop_flat_map(|e| (Just(e), stream(e))),
        sizes in prop::collection::vec(1usize..20, 1..8),
        out_len in 1usize..40,
    ) {
        let want = reference(encoding, &bytes);
        let (whole, d1) = decode_all(encoding, &bytes);
        prop_assert_eq!(&whole, &want);
        let (chunked, d2) = decode_chunked(encoding, &bytes, &sizes, out_len);
        prop_assert_eq!(&chunked, &want);
        prop_assert_eq!(d1.stats(), d2.stats());
        prop_assert_eq!(d2.stats().events, want.len() as u64);
        prop_assert_eq!(d2.stats().bytes, bytes.len() as u64);
        prop_assert_eq!(d2.pending_bytes(), bytes.len() % encoding.word_bytes());
    }

    #[test]
    fn random_bytes_never_panic(
        encoding in encodings(),
        bytes in prop::collection::vec(any::<u8>(), 0..2000),
        sizes in prop::collection::vec(1usize..64, 1..4),
        out_len in 1usize..70,
    ) {
        let (got, dec) = decode_chunked(encoding, &bytes, &sizes, out_len);
        prop_assert_eq!(got, reference(encoding, &bytes));
        let s = dec.stats();
        prop_assert_eq!(s.bytes, bytes.len() as u64);
        let words = (bytes.len() / encoding.word_bytes()) as u64;
        prop_assert!(s.triggers + s.others + s.unknown <= words);
        prop_assert!(s.events + s.unsynced <= words * encoding.max_events_per_word() as u64);
    }
}
