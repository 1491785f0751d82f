//! The device's tests: sessions, flow control, damage on the link, and its own sensor.

use super::*;
use crate::event::SensorSize;
use crate::wire::{detection_frame_max, emit_events, events_that_fit, DeviceMessage, End};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::vec::Vec;

const TXS: usize = detection_frame_max(16);
type Small = Device<600, 16, 126, TXS>;

fn cfg() -> DetectConfig {
    let mut c = DetectConfig::new(SensorSize::new(120, 90));
    c.window.events = 500;
    c.window.step_us = 0;
    c
}

/// Events of a few moving circles and some noise, from a seeded generator.
fn scene(n: usize) -> Vec<Event> {
    let mut rng = ChaCha8Rng::seed_from_u64(12345);
    let mut rnd = move || rng.random::<u32>();
    (0..n as u64)
        .map(|i| {
            let t_us = i * 4 + u64::from(rnd() % 3);
            let r = rnd();
            let (x, y) = if r % 10 == 0 {
                (rnd() % 120, rnd() % 90)
            } else {
                let k = (r / 10) % 3;
                let (cx, cy) = (20.0 + 35.0 * k as f32 + t_us as f32 * 1e-4, 25.0 + 20.0 * k as f32);
                let a = (rnd() % 6283) as f32 * 1e-3;
                ((cx + 6.0 * libm::cosf(a)) as u32, (cy + 6.0 * libm::sinf(a)) as u32)
            };
            Event { t_us, x: x as u16, y: y as u16, polarity: r % 2 == 0 }
        })
        .collect()
}

fn frame<F: FnOnce(&mut [u8]) -> crate::wire::Result<usize>>(f: F) -> Vec<u8> {
    let mut out = vec![0u8; 4096];
    let n = f(&mut out).unwrap();
    out.truncate(n);
    out
}

fn batches(events: &[Event], max_frame: usize, first_seq: u32) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut rest = events;
    let mut seq = first_seq;
    while !rest.is_empty() {
        let n = events_that_fit(seq, rest, max_frame);
        out.push(frame(|o| emit_events(seq, &rest[..n], o)));
        rest = &rest[n..];
        seq += 1;
    }
    out
}

/// Feeds `input` to the device in chunks of `chunk` bytes the way firmware would, and
/// returns every frame it sent.
fn drive(dev: &mut Small, input: &[u8], chunk: usize) -> Vec<Vec<u8>> {
    let mut sent = Vec::new();
    for piece in input.chunks(chunk.max(1)) {
        let mut start = 0;
        loop {
            while let Some(f) = dev.poll(&mut ()) {
                sent.push(f.to_vec());
            }
            if start == piece.len() {
                break;
            }
            start += dev.receive(&piece[start..]);
        }
    }
    while let Some(f) = dev.poll(&mut ()) {
        sent.push(f.to_vec());
    }
    sent
}

fn payload(frame: &[u8]) -> Vec<u8> {
    let mut acc: FrameAccumulator<4096> = FrameAccumulator::new();
    match acc.feed(frame) {
        Feed::Frame { payload, .. } => payload.to_vec(),
        other => panic!("{other:?}"),
    }
}

fn kinds(frames: &[Vec<u8>]) -> Vec<u8> {
    frames.iter().map(|f| payload(f)[0]).collect()
}

#[test]
fn a_reconfigured_detector_is_a_new_one() {
    let events = scene(3000);
    let mut other = cfg();
    other.window.events = 77;
    other.sensor = SensorSize::new(50, 50);
    let mut used: Detector<600, 16> = Detector::new(other);
    for e in &events[..1234] {
        used.push(*e);
    }
    used.reconfigure(cfg());
    let mut fresh: Detector<600, 16> = Detector::new(cfg());
    assert_eq!(used.config(), fresh.config());
    let mut windows = 0;
    for e in &events {
        let a = used.push(*e).cloned();
        let b = fresh.push(*e).cloned();
        assert_eq!(a, b);
        windows += usize::from(a.is_some());
    }
    assert!(windows >= 5);
    assert_eq!(used.input_stats(), fresh.input_stats());
    assert_eq!(used.pending(), fresh.pending());
}

#[test]
fn says_hello_first_and_then_nothing() {
    let mut dev = Small::new(cfg(), DeviceOptions::DEFAULT);
    let f = dev.poll(&mut ()).unwrap().to_vec();
    match DeviceMessage::parse(&payload(&f)).unwrap() {
        DeviceMessage::Hello(h) => {
            assert_eq!(
                (h.reply, h.session, h.max_events, h.max_clusters, h.max_frame),
                (HelloReply::Boot, 0, 600, 16, 128)
            );
            assert_eq!(h.config, cfg());
        }
        other => panic!("{other:?}"),
    }
    assert!(dev.poll(&mut ()).is_none());
    assert!(dev.is_idle());
}

#[test]
fn replay_gives_the_frames_the_core_gives() {
    let events = scene(4000);
    // what the core alone produces, encoded
    let mut det: Detector<600, 16> = Detector::new(cfg());
    let mut expected = Vec::new();
    for e in &events {
        if let Some(d) = det.push(*e) {
            expected.push(frame(|o| emit_core_detection(d, o)));
        }
    }
    assert!(expected.len() >= 6, "{} windows", expected.len());
    let centres: usize = expected
        .iter()
        .map(|f| match DeviceMessage::parse(&payload(f)).unwrap() {
            DeviceMessage::Detection(d) => d.len(),
            _ => 0,
        })
        .sum();
    assert!(centres >= 3 * expected.len(), "{centres} centres: the scene's circles are found");
    // the device, fed the same events as batches, in awkward chunk sizes
    for chunk in [1usize, 7, 128, 100_000] {
        let mut dev = Small::new(cfg(), DeviceOptions { stats_every: 3, ..DeviceOptions::DEFAULT });
        let mut input = frame(|o| Config { session: 5, config: cfg() }.emit(o));
        let b = batches(&events, 128, 0);
        let end = b.len() as u32;
        b.iter().for_each(|f| input.extend(f));
        input.extend(frame(|o| End { seq: end }.emit(o)));
        let sent = drive(&mut dev, &input, chunk);
        let detections: Vec<&Vec<u8>> = sent.iter().filter(|f| payload(f)[0] == 0x02).collect();
        assert_eq!(detections.len(), expected.len());
        for (got, want) in detections.iter().zip(&expected) {
            assert_eq!(*got, want, "chunk {chunk}");
        }
        // Hello(boot), Hello(applied), then detections with stats every 3 windows and
        // acks, then the final stats and ack
        let k = kinds(&sent);
        assert_eq!(&k[..2], &[0x01, 0x01]);
        assert_eq!(&k[k.len() - 2..], &[0x03, 0x04]);
        assert_eq!(k.iter().filter(|&&t| t == 0x03).count(), expected.len() / 3 + 1);
        let last_stats = sent.iter().rev().find(|f| payload(f)[0] == 0x03).unwrap();
        match DeviceMessage::parse(&payload(last_stats)).unwrap() {
            DeviceMessage::Stats(s) => {
                assert!(s.end_of_stream);
                assert_eq!(s.events_received, events.len() as u64);
                assert_eq!(s.windows as usize, expected.len());
                assert_eq!(s.frames_received, end + 2);
                assert_eq!((s.frames_bad, s.frames_discarded), (0, 0));
                assert_eq!(s.events_accepted + s.out_of_sensor + s.time_backwards, s.events_received);
            }
            other => panic!("{other:?}"),
        }
        match DeviceMessage::parse(&payload(sent.last().unwrap())).unwrap() {
            DeviceMessage::Ack(a) => assert_eq!(a, Ack { next: end + 1, window: 2, nak: false }),
            other => panic!("{other:?}"),
        }
    }
}

/// A stray time is dropped (and counted) on the device too, and a window that only the
/// end of the stream completes (its last event after a pause, held by the input filter)
/// is sent before the final stats.
#[test]
fn a_stray_time_is_dropped_and_held_events_are_windowed_at_the_end() {
    let mut clean = scene(4000);
    // The last event after a 10 s pause: it completes the eighth window of 500.
    clean.last_mut().unwrap().t_us += 10_000_000;
    let mut det: Detector<600, 16> = Detector::new(cfg());
    let mut expected = Vec::new();
    for e in &clean {
        if let Some(d) = det.push(*e) {
            expected.push(frame(|o| emit_core_detection(d, o)));
        }
    }
    while let Some(d) = det.end() {
        expected.push(frame(|o| emit_core_detection(d, o)));
    }
    assert_eq!(expected.len(), 8);
    let mut events = clean.clone();
    events.insert(1000, Event { t_us: 3_600_000_000, x: 5, y: 5, polarity: true });
    let mut dev = Small::new(cfg(), DeviceOptions { stats_every: 0, ..DeviceOptions::DEFAULT });
    let mut input = frame(|o| Config { session: 5, config: cfg() }.emit(o));
    let b = batches(&events, 128, 0);
    let end = b.len() as u32;
    b.iter().for_each(|f| input.extend(f));
    input.extend(frame(|o| End { seq: end }.emit(o)));
    let sent = drive(&mut dev, &input, 100);
    let detections: Vec<&Vec<u8>> = sent.iter().filter(|f| payload(f)[0] == 0x02).collect();
    assert_eq!(detections, expected.iter().collect::<Vec<_>>());
    let k = kinds(&sent);
    assert_eq!(&k[k.len() - 2..], &[0x03, 0x04], "the final stats come after every window");
    match DeviceMessage::parse(&payload(&sent[sent.len() - 2])).unwrap() {
        DeviceMessage::Stats(s) => {
            assert_eq!((s.events_received, s.windows, s.pending_events), (4001, 8, 0));
            assert_eq!((s.time_backwards, s.events_accepted + s.out_of_sensor), (1, 4000));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn holds_back_input_while_a_batch_is_fed() {
    let events = scene(300);
    let b = batches(&events, 128, 0);
    let mut dev = Small::new(cfg(), DeviceOptions::DEFAULT);
    let mut input = b[0].clone();
    input.extend(&b[1]);
    let took = dev.receive(&input);
    assert_eq!(took, b[0].len(), "stops after the first batch");
    assert_eq!(dev.receive(&input[took..]), 0, "and takes nothing until it is fed");
    while dev.poll(&mut ()).is_some() {}
    assert_eq!(dev.receive(&input[took..]), b[1].len());
}

fn acks(frames: &[Vec<u8>]) -> Vec<Ack> {
    frames
        .iter()
        .filter_map(|f| match DeviceMessage::parse(&payload(f)) {
            Ok(DeviceMessage::Ack(a)) => Some(a),
            _ => None,
        })
        .collect()
}

#[test]
fn go_back_n_drops_out_of_order_and_damaged_frames_and_says_so() {
    let events = scene(600);
    let b = batches(&events, 128, 0);
    assert!(b.len() >= 4);
    let mut dev = Small::new(cfg(), DeviceOptions::DEFAULT);
    drive(&mut dev, &b[0], 1000);
    // batch 1 is damaged on the way, batch 2 arrives: both dropped, NAK asks for 1
    let mut damaged = b[1].clone();
    damaged[5] ^= 0x04;
    let mut input = damaged;
    input.extend(&b[2]);
    let sent = drive(&mut dev, &input, 1000);
    assert_eq!(acks(&sent), [Ack { next: 1, window: 2, nak: true }]);
    // the host goes back: 1 and 2 again, then a repeat of 2 (acknowledged, dropped)
    let mut input = b[1].clone();
    input.extend(&b[2]);
    input.extend(&b[2]);
    let sent = drive(&mut dev, &input, 1000);
    assert_eq!(acks(&sent).last(), Some(&Ack { next: 3, window: 2, nak: false }));
    let s = dev.stats();
    assert_eq!((s.frames_bad, s.frames_discarded, s.frames_received), (1, 2, 5));
    assert_eq!(s.events_received as usize, events.len() - rest_len(&events, &b), "batches 0 to 2, once each");
}

/// Events in batches 3.. (not sent in the test above).
fn rest_len(events: &[Event], b: &[Vec<u8>]) -> usize {
    let sent: usize = b[..3]
        .iter()
        .map(|f| match HostMessage::parse(&payload(f)).unwrap() {
            HostMessage::Events(e) => e.len(),
            _ => 0,
        })
        .sum();
    events.len() - sent
}

#[test]
fn repeated_end_repeats_the_final_stats() {
    let mut dev = Small::new(cfg(), DeviceOptions::DEFAULT);
    let end = frame(|o| End { seq: 0 }.emit(o));
    let k1 = kinds(&drive(&mut dev, &end, 100));
    assert_eq!(k1, [0x01, 0x03, 0x04]);
    let k2 = kinds(&drive(&mut dev, &end, 100));
    assert_eq!(k2, [0x03, 0x04]);
}

#[test]
fn config_starts_a_session_once_and_rejects_nonsense() {
    let mut dev = Small::new(cfg(), DeviceOptions::DEFAULT);
    drive(&mut dev, &[], 1);
    let events = scene(100);
    let b = batches(&events, 128, 0);
    drive(&mut dev, &b[0], 100);
    assert!(dev.stats().events_received > 0);
    let mut c2 = cfg();
    c2.window.events = 100_000; // clamped to the capacity
    let hello = |sent: &[Vec<u8>]| match DeviceMessage::parse(&payload(&sent[0])).unwrap() {
        DeviceMessage::Hello(h) => h,
        other => panic!("{other:?}"),
    };
    let sent = drive(&mut dev, &frame(|o| Config { session: 9, config: c2 }.emit(o)), 100);
    let h = hello(&sent);
    assert_eq!((h.reply, h.session, h.config.window.events), (HelloReply::Applied, 9, 600));
    assert_eq!(dev.stats().events_received, 0, "a new session starts from zero");
    // the same session again: answered, nothing reset
    drive(&mut dev, &b[0], 100);
    let sent = drive(&mut dev, &frame(|o| Config { session: 9, config: c2 }.emit(o)), 100);
    assert_eq!(hello(&sent).reply, HelloReply::Applied);
    assert!(dev.stats().events_received > 0);
    // nonsense is refused and the configuration stays
    let mut bad = cfg();
    bad.cluster.eps = f32::NAN;
    let sent = drive(&mut dev, &frame(|o| Config { session: 10, config: bad }.emit(o)), 100);
    let h = hello(&sent);
    assert_eq!((h.reply, h.session, h.config.window.events), (HelloReply::Rejected, 9, 600));
}

#[test]
fn own_sensor_events_make_detections_too() {
    let events = scene(2000);
    let mut dev = Small::new(cfg(), DeviceOptions { stats_every: 0, ..DeviceOptions::DEFAULT });
    drive(&mut dev, &[], 1);
    let mut n = 0;
    for e in &events {
        if let Some(f) = dev.push_event(*e, &mut ()) {
            assert_eq!(payload(f)[0], 0x02);
            n += 1;
        }
    }
    assert!(n >= 3);
    dev.count_dropped_events(7);
    dev.count_rx_overrun(3);
    let s = dev.stats();
    assert_eq!((s.windows, s.events_dropped, s.rx_overrun, s.events_received), (n, 7, 3, 2000));
}

/// Events the device's own source lost in the middle of a window cost that window, not
/// a window that holds their place: the device's windows are the host's on the events
/// it got, with the window the loss fell in dropped.
#[test]
fn events_lost_at_the_source_drop_the_window_they_fell_in() {
    let events = scene(2000);
    let mut c = cfg();
    c.window.step_us = 100;
    let run = |loss_at: Option<usize>| {
        let mut dev = Small::new(c, DeviceOptions { stats_every: 0, ..DeviceOptions::DEFAULT });
        drive(&mut dev, &[], 1);
        let mut firsts = Vec::new();
        for (i, e) in events.iter().enumerate() {
            if loss_at == Some(i) {
                dev.count_dropped_events(40);
            }
            if let Some(f) = dev.push_event(*e, &mut ()) {
                if let Ok(DeviceMessage::Detection(d)) = DeviceMessage::parse(&payload(f)) {
                    firsts.push(d.header.t_ref_us);
                }
            }
        }
        (firsts, dev.stats())
    };
    let (all, _) = run(None);
    assert!(all.len() >= 3, "{} windows", all.len());
    // Lost 250 events into the second window (500 events, the first at about 2 ms).
    let (some, stats) = run(Some(750));
    assert_eq!(stats.events_dropped, 40);
    assert_eq!(some[0], all[0], "the window before the loss is kept");
    assert!(!some.contains(&all[1]), "the window the loss fell in is dropped");
    assert!(some[1] > all[1], "the next window starts after the loss");
    assert!(stats.ticks_skipped >= 1, "its tick counted as skipped: {stats:?}");
}
