//! Arbitrary bytes, cut into arbitrary chunks, through the frame accumulator and both
//! message parsers: never a panic; every message that parses re-encodes to a frame that
//! parses to the same message. The bytes are also parsed directly as a payload, so that
//! the parsers are explored past the CRC, which random frames almost never pass.
#![no_main]

use evcal_core::wire::{emit_detection, emit_events, DeviceMessage, Feed, FrameAccumulator, HostMessage, WireCentre};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    check(data);
    let Some((&chunk, stream)) = data.split_first() else { return };
    let chunk = usize::from(chunk % 64) + 1;
    let mut acc: FrameAccumulator<2048> = FrameAccumulator::new();
    for piece in stream.chunks(chunk) {
        let mut input = piece;
        loop {
            match acc.feed(input) {
                Feed::Consumed => break,
                Feed::Error { rest, .. } => input = rest,
                Feed::Frame { payload, rest } => {
                    check(payload);
                    input = rest;
                }
            }
        }
    }
});

/// A frame that parses must survive a re-encoding unchanged.
fn check(payload: &[u8]) {
    let mut out = [0u8; 8192];
    if let Ok(m) = DeviceMessage::parse(payload) {
        let n = match &m {
            DeviceMessage::Hello(h) => h.emit(&mut out),
            DeviceMessage::Detection(d) => {
                let c: Vec<WireCentre> = d.centres().collect();
                assert_eq!(c.len(), d.len());
                emit_detection(&d.header, c.iter().copied(), &mut out)
            }
            DeviceMessage::Stats(s) => s.emit(&mut out),
            DeviceMessage::Ack(a) => a.emit(&mut out),
        }
        .expect("a parsed message encodes");
        let again = reparse(&mut out[..n]);
        let m2 = DeviceMessage::parse(&again).expect("a re-encoded message parses");
        match (&m, &m2) {
            (DeviceMessage::Detection(a), DeviceMessage::Detection(b)) => {
                assert_eq!(a.header, b.header);
                assert!(a.centres().eq(b.centres()));
            }
            (DeviceMessage::Hello(a), DeviceMessage::Hello(b)) => assert_eq!(format!("{a:?}"), format!("{b:?}")),
            _ => assert_eq!(m, m2),
        }
    }
    if let Ok(m) = HostMessage::parse(payload) {
        let n = match &m {
            HostMessage::Config(c) => c.emit(&mut out),
            HostMessage::End(e) => e.emit(&mut out),
            HostMessage::Events(b) => {
                let ev: Vec<_> = b.events().collect();
                assert_eq!(ev.len(), b.len());
                emit_events(b.seq, &ev, &mut out)
            }
        }
        .expect("a parsed message encodes");
        let again = reparse(&mut out[..n]);
        let m2 = HostMessage::parse(&again).expect("a re-encoded message parses");
        match (&m, &m2) {
            (HostMessage::Events(a), HostMessage::Events(b)) => {
                assert_eq!(a.seq, b.seq);
                assert!(a.events().eq(b.events()));
            }
            // configs may hold NaN: compare their bits through Debug
            (HostMessage::Config(a), HostMessage::Config(b)) => assert_eq!(format!("{a:?}"), format!("{b:?}")),
            _ => assert_eq!(m, m2),
        }
    }
}

/// The payload of a whole frame.
fn reparse(frame: &mut [u8]) -> Vec<u8> {
    let mut acc: FrameAccumulator<8192> = FrameAccumulator::new();
    match acc.feed(frame) {
        Feed::Frame { payload, rest } => {
            assert!(rest.is_empty());
            payload.to_vec()
        }
        other => panic!("an encoded frame does not read back: {other:?}"),
    }
}
