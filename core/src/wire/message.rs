//! The messages, their layouts, and parsing and emitting them: the envelope that parses
//! either direction's payloads, and the small fixed-layout messages. A window's detections
//! ([`DetectionFrame`]) and event batches ([`EventBatch`]) have files of their own: each
//! packs a variable number of values into bit fields.
//!
//! Every payload starts with a type byte; device → host types have the high bit clear, host →
//! device types have it set, so a frame that comes back the wrong way (an echoing line) is
//! rejected, not misread. Layouts are listed in the [module docs](super#messages).
//!
//! Parsing checks the whole message before returning it (smoltcp's `new_checked`
//! contract): once [`DeviceMessage::parse`] or [`HostMessage::parse`] returned `Ok`, no
//! accessor or iterator of the message can fail or panic.

use super::{
    codec::{Counter, Reader, Sink},
    detection::DetectionFrame,
    events::EventBatch,
    frame::emit_frame,
    kind, Error, Result, PROTOCOL_VERSION,
};
use crate::{
    cluster::ClusterConfig,
    detect::DetectConfig,
    event::SensorSize,
    fit::{FitConfig, FitMethod},
    window::WindowConfig,
};

/// Why the device sent a [`Hello`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HelloReply {
    /// The device started (or restarted): its own configuration is in force.
    Boot = 0,
    /// A host's [`Config`] was applied: the configuration shown is in force (events per
    /// window clamped to the device's capacity).
    Applied = 1,
    /// A host's [`Config`] was refused (a value out of range): the configuration shown, the
    /// one before, stays in force.
    Rejected = 2,
}

/// The device introduces itself: protocol version (implicit: a Hello of another version does
/// not parse, see [`Error::Version`]), the detector's configuration, and what the host may
/// send it. Sent at start-up and in reply to every [`Config`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Hello {
    /// Why this Hello was sent.
    pub reply: HelloReply,
    /// The session of the host's `Config` this replies to (0 before any).
    pub session: u32,
    /// The configuration in force, sensor size included.
    pub config: DetectConfig,
    /// Most events one window can hold on this device.
    pub max_events: u32,
    /// Most clusters (and so centres) per window on this device.
    pub max_clusters: u16,
    /// Longest host → device frame the device accepts, delimiters included, in bytes.
    pub max_frame: u16,
    /// Sequenced frames the host may send beyond the last acknowledged one.
    pub window: u16,
    /// Rate of the clock behind the `*_ticks` counters of [`Stats`], Hz (0: no clock).
    pub clock_hz: u32,
}

/// Host → device: start a session with this configuration. The device resets its detector
/// (window numbering restarts at 0) and its expected sequence number (to 0), and answers with
/// a [`Hello`]. A Config repeating the current session is answered without a reset, so the
/// host can safely repeat it until the Hello arrives.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Session number chosen by the host; nonzero, new for every session.
    pub session: u32,
    /// The detector's configuration.
    pub config: DetectConfig,
}

/// Device → host, periodically and at the end of a stream: cumulative counters since the
/// session started (a lost Stats frame loses nothing: the next one has the totals).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// This is the final Stats of a stream, sent after the host's [`End`].
    pub end_of_stream: bool,
    /// Events received (decoded from batches, or from the device's own sensor).
    pub events_received: u64,
    /// Events the input filter passed.
    pub events_accepted: u64,
    /// Events dropped by the input filter: pixel outside the sensor.
    pub out_of_sensor: u64,
    /// Events dropped by the input filter for their time: time went backwards, or a stray
    /// time far ahead of the events around it ([`InputStats::time_order`]; the two are one
    /// count on the wire, whose layout predates the second).
    ///
    /// [`InputStats::time_order`]: crate::event::InputStats::time_order
    pub time_backwards: u64,
    /// Events lost for lack of buffer (the device's own event source overran).
    pub events_dropped: u64,
    /// Events of the window still filling, or held by the input filter (left out at the
    /// end of a stream).
    pub pending_events: u32,
    /// Windows completed.
    pub windows: u32,
    /// Clusters dropped for lack of capacity, over all windows.
    pub dropped_clusters: u64,
    /// Window ticks skipped because a window was still filling.
    pub ticks_skipped: u64,
    /// Intact frames received from the host.
    pub frames_received: u32,
    /// Frames from the host that were damaged, foreign or too long, and dropped.
    pub frames_bad: u32,
    /// Intact sequenced frames dropped because one before them was missing, or repeated;
    /// the host sends them again.
    pub frames_discarded: u32,
    /// Bytes the device's receiver lost (overrun), as the firmware reported them.
    pub rx_overrun: u32,
    /// Frames the device could not encode (buffer too small; zero by construction).
    pub frames_unsent: u32,
    /// Clustering work: pairwise distance checks.
    pub distance_checks: u64,
    /// Clock ticks decoding and windowing events.
    pub input_ticks: u64,
    /// Clock ticks clustering.
    pub cluster_ticks: u64,
    /// Clock ticks fitting circles.
    pub fit_ticks: u64,
    /// Clock ticks encoding outgoing frames.
    pub encode_ticks: u64,
}

/// Device → host: flow control. The host may have sent sequenced frames (event batches,
/// [`End`]) numbered below `next + window`; everything below `next` has been handled.
/// Cumulative, so a lost Ack loses nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ack {
    /// The next sequence number the device expects.
    pub next: u32,
    /// How many frames from `next` on the host may send.
    pub window: u16,
    /// A frame was damaged or missing: send again from `next` (go-back-N).
    pub nak: bool,
}

/// Host → device: the stream ends after the frames before this one. A sequenced frame. The
/// device answers with a final [`Stats`] and an [`Ack`] past it. The window still filling is
/// not processed, as in `evcal detect`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct End {
    /// Sequence number of this frame.
    pub seq: u32,
}

/// A message from the device to the host.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeviceMessage<'a> {
    /// The device introduces itself.
    Hello(Hello),
    /// One window's centres.
    Detection(DetectionFrame<'a>),
    /// Counters.
    Stats(Stats),
    /// Flow control.
    Ack(Ack),
}

/// A message from the host to the device.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HostMessage<'a> {
    /// Start a session with a configuration.
    Config(Config),
    /// A batch of events.
    Events(EventBatch<'a>),
    /// End of the stream.
    End(End),
}

impl<'a> DeviceMessage<'a> {
    /// Parses a frame's payload (as [`FrameAccumulator`](super::FrameAccumulator) returns it).
    pub fn parse(payload: &'a [u8]) -> Result<Self> {
        let mut r = Reader::new(payload);
        let m = match r.u8()? {
            kind::HELLO => Self::Hello(read_hello(&mut r)?),
            kind::DETECTION => Self::Detection(DetectionFrame::read(&mut r)?),
            kind::STATS => Self::Stats(read_stats(&mut r)?),
            kind::ACK => Self::Ack(read_ack(&mut r)?),
            t => return Err(Error::UnknownType(t)),
        };
        r.finish()?;
        Ok(m)
    }
}

impl<'a> HostMessage<'a> {
    /// Parses a frame's payload (as [`FrameAccumulator`](super::FrameAccumulator) returns it).
    pub fn parse(payload: &'a [u8]) -> Result<Self> {
        let mut r = Reader::new(payload);
        let m = match r.u8()? {
            kind::CONFIG => Self::Config(Config { session: r.varint_u32()?, config: read_config(&mut r)? }),
            kind::EVENTS => Self::Events(EventBatch::read(&mut r)?),
            kind::END => Self::End(End { seq: r.varint_u32()? }),
            t => return Err(Error::UnknownType(t)),
        };
        r.finish()?;
        Ok(m)
    }
}

fn put_config(s: &mut impl Sink, c: &DetectConfig) {
    s.varint(c.sensor.width.into());
    s.varint(c.sensor.height.into());
    s.varint(c.window.events.min(u32::MAX as usize) as u64);
    s.varint(c.window.step_us);
    s.f32(c.cluster.eps);
    s.varint(c.cluster.min_pts.into());
    match c.cluster.eps_t {
        None => s.put(0),
        Some(t) => {
            s.put(1);
            s.f32(t);
        }
    }
    s.put(match c.fit.method {
        FitMethod::Centroid => 0,
        FitMethod::Ols => 1,
        FitMethod::Erwls => 2,
    });
    s.put(c.fit.max_iterations);
    s.varint(c.fit.min_events.into());
    s.put(u8::from(c.fit.filled_discs) * FIT_FILLED_DISCS);
}

/// The fit's flags byte of a configuration: bit 0, [`FitConfig::filled_discs`]; the other
/// bits are reserved and must be 0.
const FIT_FILLED_DISCS: u8 = 1;

fn read_config(r: &mut Reader<'_>) -> Result<DetectConfig> {
    let sensor = SensorSize::new(r.varint_u16()?, r.varint_u16()?);
    let window = WindowConfig { events: r.varint_u32()? as usize, step_us: r.varint()? };
    let eps = r.f32()?;
    let min_pts = r.varint_u16()?;
    let eps_t = match r.u8()? {
        0 => None,
        1 => Some(r.f32()?),
        _ => return Err(Error::Invalid),
    };
    let method = match r.u8()? {
        0 => FitMethod::Centroid,
        1 => FitMethod::Ols,
        2 => FitMethod::Erwls,
        _ => return Err(Error::Invalid),
    };
    let (max_iterations, min_events) = (r.u8()?, r.varint_u16()?);
    let flags = r.u8()?;
    if flags & !FIT_FILLED_DISCS != 0 {
        return Err(Error::Invalid);
    }
    let fit = FitConfig { method, max_iterations, min_events, filled_discs: flags & FIT_FILLED_DISCS != 0 };
    Ok(DetectConfig { sensor, window, cluster: ClusterConfig { eps, min_pts, eps_t }, fit })
}

impl Hello {
    /// Writes the Hello as a frame into `out`; the frame's length.
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        emit_frame(out, |w| {
            w.put(kind::HELLO);
            w.put(PROTOCOL_VERSION);
            w.put(self.reply as u8);
            w.varint(self.session.into());
            put_config(w, &self.config);
            w.varint(self.max_events.into());
            w.varint(self.max_clusters.into());
            w.varint(self.max_frame.into());
            w.varint(self.window.into());
            w.varint(self.clock_hz.into());
        })
    }
}

fn read_hello(r: &mut Reader<'_>) -> Result<Hello> {
    let version = r.u8()?;
    if version != PROTOCOL_VERSION {
        return Err(Error::Version(version));
    }
    let reply = match r.u8()? {
        0 => HelloReply::Boot,
        1 => HelloReply::Applied,
        2 => HelloReply::Rejected,
        _ => return Err(Error::Invalid),
    };
    Ok(Hello {
        reply,
        session: r.varint_u32()?,
        config: read_config(r)?,
        max_events: r.varint_u32()?,
        max_clusters: r.varint_u16()?,
        max_frame: r.varint_u16()?,
        window: r.varint_u16()?,
        clock_hz: r.varint_u32()?,
    })
}

impl Config {
    /// Writes the Config as a frame into `out`; the frame's length.
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        emit_frame(out, |w| {
            w.put(kind::CONFIG);
            w.varint(self.session.into());
            put_config(w, &self.config);
        })
    }
}

impl End {
    /// Writes the End as a frame into `out`; the frame's length.
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        emit_frame(out, |w| {
            w.put(kind::END);
            w.varint(self.seq.into());
        })
    }
}

impl Ack {
    /// Writes the Ack as a frame into `out`; the frame's length.
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        emit_frame(out, |w| {
            w.put(kind::ACK);
            w.varint(self.next.into());
            w.varint(self.window.into());
            w.put(u8::from(self.nak));
        })
    }
}

fn read_ack(r: &mut Reader<'_>) -> Result<Ack> {
    let next = r.varint_u32()?;
    let window = r.varint_u16()?;
    let nak = match r.u8()? {
        0 => false,
        1 => true,
        _ => return Err(Error::Invalid),
    };
    Ok(Ack { next, window, nak })
}

impl Stats {
    /// Writes the Stats as a frame into `out`; the frame's length.
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        emit_frame(out, |w| {
            w.put(kind::STATS);
            w.put(u8::from(self.end_of_stream));
            for v in [self.events_received, self.events_accepted, self.out_of_sensor, self.time_backwards] {
                w.varint(v);
            }
            w.varint(self.events_dropped);
            w.varint(self.pending_events.into());
            w.varint(self.windows.into());
            w.varint(self.dropped_clusters);
            w.varint(self.ticks_skipped);
            for v in [self.frames_received, self.frames_bad, self.frames_discarded, self.rx_overrun, self.frames_unsent]
            {
                w.varint(v.into());
            }
            for v in [self.distance_checks, self.input_ticks, self.cluster_ticks, self.fit_ticks, self.encode_ticks] {
                w.varint(v);
            }
        })
    }
}

impl Stats {
    /// All counters zero.
    pub const ZERO: Self = Self {
        end_of_stream: false,
        events_received: 0,
        events_accepted: 0,
        out_of_sensor: 0,
        time_backwards: 0,
        events_dropped: 0,
        pending_events: 0,
        windows: 0,
        dropped_clusters: 0,
        ticks_skipped: 0,
        frames_received: 0,
        frames_bad: 0,
        frames_discarded: 0,
        rx_overrun: 0,
        frames_unsent: 0,
        distance_checks: 0,
        input_ticks: 0,
        cluster_ticks: 0,
        fit_ticks: 0,
        encode_ticks: 0,
    };
}

fn read_stats(r: &mut Reader<'_>) -> Result<Stats> {
    let end_of_stream = match r.u8()? {
        0 => false,
        1 => true,
        _ => return Err(Error::Invalid),
    };
    Ok(Stats {
        end_of_stream,
        events_received: r.varint()?,
        events_accepted: r.varint()?,
        out_of_sensor: r.varint()?,
        time_backwards: r.varint()?,
        events_dropped: r.varint()?,
        pending_events: r.varint_u32()?,
        windows: r.varint_u32()?,
        dropped_clusters: r.varint()?,
        ticks_skipped: r.varint()?,
        frames_received: r.varint_u32()?,
        frames_bad: r.varint_u32()?,
        frames_discarded: r.varint_u32()?,
        rx_overrun: r.varint_u32()?,
        frames_unsent: r.varint_u32()?,
        distance_checks: r.varint()?,
        input_ticks: r.varint()?,
        cluster_ticks: r.varint()?,
        fit_ticks: r.varint()?,
        encode_ticks: r.varint()?,
    })
}

/// Payload bytes of a message, for tests and size reports.
#[allow(dead_code)]
pub(crate) fn payload_len(body: impl FnOnce(&mut Counter)) -> usize {
    let mut c = Counter::default();
    body(&mut c);
    c.0
}

#[cfg(test)]
pub(super) mod test {
    use super::*;
    use crate::wire::frame::decode_in_place;
    use std::vec::Vec;

    /// The payload of a frame (COBS undone, CRC checked and removed).
    pub(crate) fn payload(frame: &[u8]) -> Vec<u8> {
        assert_eq!(frame.first(), Some(&0));
        assert_eq!(frame.last(), Some(&0));
        let mut body = frame[1..frame.len() - 1].to_vec();
        let n = decode_in_place(&mut body).expect("a valid frame");
        body.truncate(n);
        body
    }

    pub(crate) fn emit(f: impl FnOnce(&mut [u8]) -> Result<usize>) -> Vec<u8> {
        let mut out = vec![0u8; 4096];
        let n = f(&mut out).unwrap();
        out.truncate(n);
        out
    }

    /// postcard's `test_one`: the exact payload bytes, then the parse gives the value back.
    pub(crate) fn device_one(frame: &[u8], expected_payload: &[u8], check: impl FnOnce(DeviceMessage<'_>)) {
        let p = payload(frame);
        assert_eq!(p, expected_payload, "payload bytes");
        check(DeviceMessage::parse(&p).unwrap());
    }

    const DAVIS_CONFIG: [u8; 19] = [
        0xDA, 0x02, // width 346
        0x84, 0x02, // height 260
        0xA0, 0x1F, // 4000 events per window
        0xB5, 0x84, 0x02, // step 33 333 µs
        0x8F, 0xC2, 0x75, 0x3C, // eps 0.015
        0x0A, // min_pts 10
        0x00, // eps_t none
        0x02, // eRWLS
        0x06, // 6 iterations (main's DEFAULT_MAX_ITERATIONS since 9c3fd89)
        0x14, // min 20 events
        0x00, // fit flags: rings only (protocol version 2)
    ];

    fn davis() -> DetectConfig {
        DetectConfig::new(SensorSize::DAVIS346)
    }

    #[test]
    fn golden_ack_whole_frame() {
        let f = emit(|o| Ack { next: 7, window: 2, nak: false }.emit(o));
        // 0x00, COBS(04 07 02 00 ‖ CRC-32C LE b3 2e f0 60), 0x00
        assert_eq!(f, [0x00, 0x04, 0x04, 0x07, 0x02, 0x05, 0xB3, 0x2E, 0xF0, 0x60, 0x00]);
        device_one(&f, &[0x04, 0x07, 0x02, 0x00], |m| {
            assert_eq!(m, DeviceMessage::Ack(Ack { next: 7, window: 2, nak: false }));
        });
    }

    #[test]
    fn golden_end_whole_frame() {
        let f = emit(|o| End { seq: 300 }.emit(o));
        assert_eq!(f, [0x00, 0x08, 0x83, 0xAC, 0x02, 0x22, 0xDF, 0x80, 0xB7, 0x00]);
        let p = payload(&f);
        assert_eq!(HostMessage::parse(&p), Ok(HostMessage::End(End { seq: 300 })));
    }

    #[test]
    fn golden_hello() {
        let h = Hello {
            reply: HelloReply::Boot,
            session: 0,
            config: davis(),
            max_events: 4000,
            max_clusters: 96,
            max_frame: 512,
            window: 2,
            clock_hz: 0,
        };
        let mut expected = vec![0x01, PROTOCOL_VERSION, 0x00, 0x00];
        expected.extend(DAVIS_CONFIG);
        expected.extend([0xA0, 0x1F, 0x60, 0x80, 0x04, 0x02, 0x00]);
        device_one(&emit(|o| h.emit(o)), &expected, |m| assert_eq!(m, DeviceMessage::Hello(h)));
    }

    #[test]
    fn golden_config() {
        let mut cfg = davis();
        cfg.cluster.eps_t = Some(0.5);
        cfg.fit.filled_discs = true;
        let c = Config { session: 1, config: cfg };
        let f = emit(|o| c.emit(o));
        let mut expected = vec![0x81, 0x01];
        expected.extend(&DAVIS_CONFIG[..14]);
        expected.extend([0x01, 0x00, 0x00, 0x00, 0x3F, 0x02, 0x06, 0x14, 0x01]);
        let p = payload(&f);
        assert_eq!(p, expected);
        assert_eq!(HostMessage::parse(&p), Ok(HostMessage::Config(c)));
        // A fit flag this version does not know is refused, not ignored.
        let mut unknown = p.clone();
        *unknown.last_mut().unwrap() = 0x03;
        assert_eq!(HostMessage::parse(&unknown), Err(Error::Invalid));
    }

    #[test]
    fn golden_stats() {
        let s = Stats { end_of_stream: true, events_received: 300, ..Stats::ZERO };
        let mut expected = vec![0x03, 0x01, 0xAC, 0x02];
        expected.extend([0u8; 18]);
        device_one(&emit(|o| s.emit(o)), &expected, |m| assert_eq!(m, DeviceMessage::Stats(s)));
    }

    #[test]
    fn other_version_and_other_direction_are_errors() {
        let h = Hello {
            reply: HelloReply::Applied,
            session: 9,
            config: davis(),
            max_events: 1,
            max_clusters: 1,
            max_frame: 64,
            window: 1,
            clock_hz: 1,
        };
        let mut p = payload(&emit(|o| h.emit(o)));
        p[1] = PROTOCOL_VERSION + 1;
        assert_eq!(DeviceMessage::parse(&p), Err(Error::Version(PROTOCOL_VERSION + 1)));
        // a host message read as a device message, and the reverse
        let end = payload(&emit(|o| End { seq: 1 }.emit(o)));
        assert_eq!(DeviceMessage::parse(&end), Err(Error::UnknownType(0x83)));
        let ack = payload(&emit(|o| Ack { next: 1, window: 1, nak: true }.emit(o)));
        assert_eq!(HostMessage::parse(&ack), Err(Error::UnknownType(0x04)));
        assert_eq!(DeviceMessage::parse(&[]), Err(Error::Truncated));
    }

    #[test]
    fn malformed_fields_are_rejected() {
        // trailing byte
        assert_eq!(DeviceMessage::parse(&[0x04, 0x07, 0x02, 0x00, 0x00]), Err(Error::Trailing));
        // nak flag out of range
        assert_eq!(DeviceMessage::parse(&[0x04, 0x07, 0x02, 0x02]), Err(Error::Invalid));
    }
}
