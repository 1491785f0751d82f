//! Host traffic into the device's protocol loop, in arbitrary chunks: never a panic, never
//! stuck, and everything the device sends is a well-formed frame.
//!
//! The fuzzer's bytes are a script of what the host sends: configurations, event batches
//! and ends with any sequence numbers (in order, repeated, skipped), frames with a bit
//! flipped, and raw garbage; random bytes alone would almost never pass a frame's CRC.
#![no_main]

use evcal_core::{
    detect::DetectConfig,
    event::{Event, SensorSize},
    wire::{
        detection_frame_max, emit_events, Config, Device, DeviceMessage, DeviceOptions, End, Feed, FrameAccumulator,
    },
};
use libfuzzer_sys::fuzz_target;

const TX: usize = detection_frame_max(16);
/// The device's receive buffer: host frames of up to 256 bytes.
const RX: usize = 254;

fn config(events: u8) -> DetectConfig {
    let mut cfg = DetectConfig::new(SensorSize::new(64, 48));
    cfg.window.events = usize::from(events % 80);
    cfg.window.step_us = 0;
    cfg
}

/// The host's bytes, from the script.
fn script(mut d: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut frame = [0u8; 4096];
    let mut seq = 0u32;
    let mut t = 0u64;
    while let Some((&op, rest)) = d.split_first() {
        d = rest;
        let arg = d.first().copied().unwrap_or(0);
        let n = match op % 6 {
            0 => {
                // garbage
                let len = usize::from(arg % 64).min(d.len());
                out.extend_from_slice(&d[..len]);
                d = &d[len..];
                continue;
            }
            1 | 2 => {
                // a batch: the next sequence number, or one nearby
                let s = match arg % 8 {
                    0 => seq.wrapping_sub(1),
                    1 => seq.wrapping_add(1),
                    _ => seq,
                };
                let count = usize::from(arg >> 3).min(d.len().saturating_sub(1) / 3);
                let events: Vec<Event> = d
                    .get(1..1 + 3 * count)
                    .unwrap_or(&[])
                    .chunks_exact(3)
                    .map(|c| {
                        t += u64::from(c[0] % 8);
                        Event { t_us: t, x: u16::from(c[1] % 70), y: u16::from(c[2] % 50), polarity: c[0] & 1 == 1 }
                    })
                    .collect();
                d = d.get(1 + 3 * count..).unwrap_or(&[]);
                let fit = evcal_core::wire::events_that_fit(s, &events, RX + 2);
                if s == seq {
                    seq = seq.wrapping_add(1);
                }
                emit_events(s, &events[..fit], &mut frame)
            }
            3 => {
                d = d.get(1..).unwrap_or(&[]);
                let s = if arg & 1 == 0 { seq } else { seq.wrapping_sub(1) };
                if s == seq {
                    seq = seq.wrapping_add(1);
                }
                End { seq: s }.emit(&mut frame)
            }
            4 => {
                d = d.get(1..).unwrap_or(&[]);
                if arg & 0x80 == 0 {
                    seq = 0;
                }
                Config { session: u32::from(arg & 0x83), config: config(arg) }.emit(&mut frame)
            }
            _ => {
                // the last frame again with one bit flipped
                d = d.get(1..).unwrap_or(&[]);
                if let Some(last) = out.len().checked_sub(1 + usize::from(arg % 16)) {
                    out[last] ^= 1 << (arg % 8);
                }
                continue;
            }
        };
        if let Ok(n) = n {
            out.extend_from_slice(&frame[..n]);
        }
    }
    out
}

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, rest)) = data.split_first() else { return };
    let chunk = usize::from(chunk % 32) + 1;
    let stream = script(rest);
    // Small capacities keep each run fast; the logic is the same for every size.
    let mut dev: Box<Device<128, 16, RX, TX>> =
        Box::new(Device::new(config(40), DeviceOptions { window: 2, stats_every: 3, clock_hz: 0 }));
    let mut acc: FrameAccumulator<4096> = FrameAccumulator::new();
    let mut sent = 0usize;
    let mut check = |frame: &[u8]| {
        sent += 1;
        match acc.feed(frame) {
            Feed::Frame { payload, rest } => {
                assert!(rest.is_empty());
                DeviceMessage::parse(payload).expect("the device sends well-formed messages");
            }
            other => panic!("the device sent a broken frame: {other:?}"),
        }
    };
    for piece in stream.chunks(chunk) {
        let mut start = 0;
        let mut rounds = 0;
        loop {
            while let Some(f) = dev.poll(&mut ()) {
                check(f);
            }
            if start == piece.len() {
                break;
            }
            start += dev.receive(&piece[start..]);
            rounds += 1;
            assert!(rounds <= piece.len() + 1, "the device stopped taking input");
        }
    }
    while let Some(f) = dev.poll(&mut ()) {
        check(f);
    }
    assert!(dev.is_idle());
    assert!(sent >= 1, "the device always says Hello");
    let s = dev.stats();
    // Every event received is accepted, dropped, or still held by the input filter (a
    // stream may stop while it waits on a possible stray time); held ones are pending.
    let decided = s.events_accepted + s.out_of_sensor + s.time_backwards;
    assert!(decided <= s.events_received);
    let held = s.events_received - decided;
    assert!(held <= u64::from(s.pending_events) && held <= evcal_core::event::MAX_HELD_EVENTS as u64);
});
