//! Arbitrary events and centres, built from the fuzzer's bytes, through the encoders and
//! back: what comes out is what went in, and frames respect their size bounds.
#![no_main]

use evcal_core::{
    event::Event,
    wire::{
        detection_frame_max, emit_detection, emit_events, events_that_fit, DetectionHeader, DeviceMessage, Feed,
        FrameAccumulator, HostMessage, WireCentre,
    },
};
use libfuzzer_sys::fuzz_target;

fn u64_at(d: &[u8], i: usize) -> u64 {
    let mut b = [0u8; 8];
    for (k, x) in b.iter_mut().enumerate() {
        *x = d.get(i + k).copied().unwrap_or(0);
    }
    u64::from_le_bytes(b)
}

fuzz_target!(|data: &[u8]| {
    let mut acc: FrameAccumulator<65536> = FrameAccumulator::new();
    let mut out = vec![0u8; 65536];
    // events: 7 bytes each, times as small steps with now and then a big one or a step back
    let mut t = u64_at(data, 0) >> 20;
    let events: Vec<Event> = data
        .chunks_exact(7)
        .map(|c| {
            let step = u64::from(c[0]);
            t = match c[1] % 16 {
                0 => t.wrapping_sub(step),
                1 => t.wrapping_add(u64::from(c[2]) << 30),
                _ => t.wrapping_add(step >> 4),
            };
            Event {
                t_us: t,
                x: u16::from_le_bytes([c[2], c[3]]),
                y: u16::from_le_bytes([c[4], c[5]]),
                polarity: c[6] & 1 == 1,
            }
        })
        .collect();
    let n = emit_events(7, &events, &mut out).expect("fits the buffer");
    let Feed::Frame { payload, .. } = acc.feed(&out[..n]) else { panic!("frame does not read back") };
    let Ok(HostMessage::Events(b)) = HostMessage::parse(payload) else { panic!("batch does not parse") };
    assert!(b.events().eq(events.iter().copied()));
    // sizing: the batch that fits 512 bytes does
    let k = events_that_fit(9, &events, 512);
    let n = emit_events(9, &events[..k], &mut out).expect("fits the buffer");
    assert!(n <= 512 || k == 0);
    // centres: 22 bytes each, at most 96
    let centres: Vec<WireCentre> = data
        .chunks_exact(22)
        .take(96)
        .map(|c| WireCentre {
            u: u64_at(c, 0) as i32,
            v: u64_at(c, 4) as i32,
            r: u64_at(c, 8) as u32,
            spread: u64_at(c, 12) as u32,
            n: u64_at(c, 16) as u16,
            converged: c[21] & 1 == 1,
        })
        .collect();
    let header = DetectionHeader { seq: t as u32, t_ref_us: t, events: data.len() as u16, ..Default::default() };
    let n = emit_detection(&header, centres.iter().copied(), &mut out).expect("fits the buffer");
    assert!(n <= detection_frame_max(centres.len()));
    let Feed::Frame { payload, .. } = acc.feed(&out[..n]) else { panic!("frame does not read back") };
    let Ok(DeviceMessage::Detection(d)) = DeviceMessage::parse(payload) else { panic!("detection does not parse") };
    assert_eq!(d.header, header);
    assert!(d.centres().eq(centres.iter().copied()));
});
