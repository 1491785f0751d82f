//! Properties of the whole codec: arbitrary messages round trip; damaged frames are
//! rejected or resynchronised, never a panic, never accepted as a different message.

use super::*;
use crate::{
    cluster::ClusterConfig,
    detect::DetectConfig,
    event::{Event, SensorSize},
    fit::{Centre, FitConfig, FitMethod},
    window::WindowConfig,
};
use proptest::prelude::*;
use std::vec::Vec;

/// A message of either direction in owned form, for comparing what was sent with what was
/// received.
#[derive(Debug, Clone, PartialEq)]
enum Owned {
    Hello(Hello),
    Detection(DetectionHeader, Vec<WireCentre>),
    Stats(Stats),
    Ack(Ack),
    Config(Config),
    Events(u32, Vec<Event>),
    End(End),
}

impl Owned {
    fn emit(&self) -> Vec<u8> {
        let mut out = vec![0u8; 64 * 1024];
        let n = match self {
            Self::Hello(m) => m.emit(&mut out),
            Self::Detection(h, c) => emit_detection(h, c.iter().copied(), &mut out),
            Self::Stats(m) => m.emit(&mut out),
            Self::Ack(m) => m.emit(&mut out),
            Self::Config(m) => m.emit(&mut out),
            Self::Events(seq, e) => emit_events(*seq, e, &mut out),
            Self::End(m) => m.emit(&mut out),
        }
        .unwrap();
        out.truncate(n);
        out
    }

    /// Parses a payload as whichever direction its type byte says.
    fn parse(p: &[u8]) -> Result<Self> {
        if p.first().is_some_and(|t| t & 0x80 != 0) {
            Ok(match HostMessage::parse(p)? {
                HostMessage::Config(c) => Self::Config(c),
                HostMessage::Events(b) => Self::Events(b.seq, b.events().collect()),
                HostMessage::End(e) => Self::End(e),
            })
        } else {
            Ok(match DeviceMessage::parse(p)? {
                DeviceMessage::Hello(h) => Self::Hello(h),
                DeviceMessage::Detection(d) => Self::Detection(d.header, d.centres().collect()),
                DeviceMessage::Stats(s) => Self::Stats(s),
                DeviceMessage::Ack(a) => Self::Ack(a),
            })
        }
    }
}

/// Every message a byte stream yields, and how many frames were rejected.
fn read_all(stream: &[u8]) -> (Vec<Owned>, usize) {
    let mut acc: FrameAccumulator<{ 64 * 1024 }> = FrameAccumulator::new();
    let (mut got, mut bad) = (Vec::new(), 0);
    let mut input = stream;
    loop {
        match acc.feed(input) {
            Feed::Consumed => return (got, bad),
            Feed::Frame { payload, rest } => {
                match Owned::parse(payload) {
                    Ok(m) => got.push(m),
                    Err(_) => bad += 1,
                }
                input = rest;
            }
            Feed::Error { rest, .. } => {
                bad += 1;
                input = rest;
            }
        }
    }
}

fn finite() -> impl Strategy<Value = f32> {
    prop_oneof![-1e6f32..1e6, Just(0.015f32), Just(f32::MAX), Just(f32::MIN_POSITIVE)]
}

fn detect_config() -> impl Strategy<Value = DetectConfig> {
    (
        (any::<u16>(), any::<u16>(), 0usize..=u32::MAX as usize, any::<u64>()),
        (finite(), any::<u16>(), proptest::option::of(finite())),
        (0u8..3, any::<u8>(), any::<u16>(), any::<bool>()),
    )
        .prop_map(
            |((w, h, events, step_us), (eps, min_pts, eps_t), (m, max_iterations, min_events, filled_discs))| {
                DetectConfig {
                    sensor: SensorSize::new(w, h),
                    window: WindowConfig { events, step_us },
                    cluster: ClusterConfig { eps, min_pts, eps_t },
                    fit: FitConfig {
                        method: [FitMethod::Centroid, FitMethod::Ols, FitMethod::Erwls][usize::from(m)],
                        max_iterations,
                        min_events,
                        filled_discs,
                    },
                }
            },
        )
}

fn centre() -> impl Strategy<Value = WireCentre> {
    prop_oneof![
        // realistic: on a sensor, a few px radius
        (0i32..1300 << 10, 0i32..800 << 10, 1u32..60 << 10, 0u32..4 << 10, 10u16..2000, any::<bool>()),
        // anything
        (any::<i32>(), any::<i32>(), any::<u32>(), any::<u32>(), any::<u16>(), any::<bool>()),
    ]
    .prop_map(|(u, v, r, spread, n, converged)| WireCentre { u, v, r, spread, n, converged })
}

fn event() -> impl Strategy<Value = Event> {
    (any::<u64>(), any::<u16>(), any::<u16>(), any::<bool>()).prop_map(|(t_us, x, y, polarity)| Event {
        t_us,
        x,
        y,
        polarity,
    })
}

/// Events as a camera gives them: small forward steps, coordinates on a sensor, now and
/// then a step back or a gap.
fn event_stream() -> impl Strategy<Value = Vec<Event>> {
    (any::<u32>(), proptest::collection::vec((0u64..50, 0u16..640, 0u16..480, any::<bool>(), 0u8..100), 0..400))
        .prop_map(|(start, steps)| {
            let mut t = u64::from(start);
            steps
                .into_iter()
                .map(|(dt, x, y, polarity, odd)| {
                    t = match odd {
                        0 => t.saturating_sub(dt * 3),
                        1 => t + (1 << 33),
                        _ => t + dt,
                    };
                    Event { t_us: t, x, y, polarity }
                })
                .collect()
        })
}

fn stats() -> impl Strategy<Value = Stats> {
    (any::<bool>(), proptest::array::uniform16(any::<u64>()), proptest::array::uniform8(any::<u32>())).prop_map(
        |(end_of_stream, a, b)| Stats {
            end_of_stream,
            events_received: a[0],
            events_accepted: a[1],
            out_of_sensor: a[2],
            time_backwards: a[3],
            events_dropped: a[4],
            pending_events: b[0],
            windows: b[1],
            dropped_clusters: a[5],
            ticks_skipped: a[6],
            frames_received: b[2],
            frames_bad: b[3],
            frames_discarded: b[4],
            rx_overrun: b[5],
            frames_unsent: b[6],
            distance_checks: a[7],
            input_ticks: a[8],
            cluster_ticks: a[9],
            fit_ticks: a[10],
            encode_ticks: a[11],
        },
    )
}

fn header() -> impl Strategy<Value = DetectionHeader> {
    (any::<u32>(), any::<u64>(), proptest::array::uniform5(any::<u16>())).prop_map(|(seq, t_ref_us, c)| {
        DetectionHeader {
            seq,
            t_ref_us,
            events: c[0],
            noise: c[1],
            clusters: c[2],
            dropped_clusters: c[3],
            rejected_fits: c[4],
        }
    })
}

fn message() -> impl Strategy<Value = Owned> {
    let reply = prop_oneof![Just(HelloReply::Boot), Just(HelloReply::Applied), Just(HelloReply::Rejected)];
    prop_oneof![
        (reply, any::<u32>(), detect_config(), any::<u32>(), any::<u16>(), any::<u16>(), any::<u16>(), any::<u32>())
            .prop_map(|(reply, session, config, max_events, max_clusters, max_frame, window, clock_hz)| {
                Owned::Hello(Hello { reply, session, config, max_events, max_clusters, max_frame, window, clock_hz })
            }),
        (header(), proptest::collection::vec(centre(), 0..=96)).prop_map(|(h, c)| Owned::Detection(h, c)),
        stats().prop_map(Owned::Stats),
        (any::<u32>(), any::<u16>(), any::<bool>()).prop_map(|(next, window, nak)| Owned::Ack(Ack {
            next,
            window,
            nak
        })),
        (any::<u32>(), detect_config()).prop_map(|(session, config)| Owned::Config(Config { session, config })),
        (any::<u32>(), prop_oneof![event_stream(), proptest::collection::vec(event(), 0..40)])
            .prop_map(|(s, e)| Owned::Events(s, e)),
        any::<u32>().prop_map(|seq| Owned::End(End { seq })),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn arbitrary_messages_round_trip(m in message()) {
        let f = m.emit();
        prop_assert_eq!(f.first(), Some(&0));
        prop_assert_eq!(f.last(), Some(&0));
        prop_assert!(f[1..f.len() - 1].iter().all(|&b| b != 0), "no zero inside a frame");
        let (got, bad) = read_all(&f);
        prop_assert_eq!(bad, 0);
        prop_assert_eq!(got, vec![m.clone()]);
        // encoding is deterministic
        prop_assert_eq!(m.emit(), f);
    }

    #[test]
    fn detections_fit_their_bound(h in header(), c in proptest::collection::vec(centre(), 0..=96)) {
        let f = Owned::Detection(h, c.clone()).emit();
        prop_assert!(f.len() <= detection_frame_max(c.len()));
    }

    #[test]
    fn quantised_centres_are_within_half_a_unit(u in -1e5f32..1e5, v in -1e5f32..1e5, r in 0f32..1e4) {
        let c = WireCentre::from_centre(&Centre { u, v, r, spread: r / 10.0, n: 5, converged: true, ..Default::default() });
        prop_assert!((c.u_px() - u).abs() <= 0.5 / 1024.0 + u.abs() * 1e-7);
        prop_assert!((c.v_px() - v).abs() <= 0.5 / 1024.0 + v.abs() * 1e-7);
        prop_assert!((c.r_px() - r).abs() <= 0.5 / 1024.0 + r * 1e-7);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Every truncation of a frame, followed by an intact frame: the intact frame is read,
    /// and the cut one is dropped (only a cut that removes nothing but the closing delimiter
    /// leaves the message whole, and then it is the same message).
    #[test]
    fn every_truncation_is_rejected_and_the_next_frame_read(a in message(), b in message()) {
        let fa = a.emit();
        let fb = b.emit();
        for cut in 0..fa.len() {
            let mut stream = fa[..cut].to_vec();
            stream.extend(&fb);
            let (got, _) = read_all(&stream);
            if cut == fa.len() - 1 {
                prop_assert_eq!(&got, &vec![a.clone(), b.clone()]);
            } else {
                prop_assert_eq!(&got, &vec![b.clone()], "cut at {} of {}", cut, fa.len());
            }
        }
    }

    /// Every single-bit flip of a frame, followed by an intact frame: the damaged frame is
    /// never accepted (as itself or as anything else), the intact one always is.
    #[test]
    fn every_bit_flip_is_rejected_and_the_next_frame_read(a in message(), b in message()) {
        let fa = a.emit();
        let fb = b.emit();
        for bit in 0..fa.len() * 8 {
            let mut stream = fa.clone();
            stream[bit / 8] ^= 1 << (bit % 8);
            stream.extend(&fb);
            let (got, bad) = read_all(&stream);
            prop_assert_eq!(&got, &vec![b.clone()], "bit {} of {}", bit, fa.len() * 8);
            prop_assert!(bad >= 1, "the damage is reported");
        }
    }

    /// Arbitrary bytes never panic the reader or the device, and the device stays usable.
    #[test]
    fn garbage_never_panics(soup in proptest::collection::vec(any::<u8>(), 0..3000), good in message()) {
        let _ = read_all(&soup);
        let mut dev: Device = Device::new(DetectConfig::new(SensorSize::DAVIS346), DeviceOptions::DEFAULT);
        let mut input = soup.clone();
        input.extend(Owned::End(End { seq: 0 }).emit());
        input.extend(good.emit());
        let mut start = 0;
        let mut sent = Vec::new();
        for _ in 0..100_000 {
            while let Some(f) = dev.poll(&mut ()) {
                sent.extend_from_slice(f);
            }
            if start == input.len() {
                break;
            }
            start += dev.receive(&input[start..]);
        }
        prop_assert_eq!(start, input.len());
        // everything the device said is well-formed
        let (_, bad) = read_all(&sent);
        prop_assert_eq!(bad, 0);
    }
}
