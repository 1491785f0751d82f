//! The messages, their layouts, and parsing and emitting them.
//!
//! Every payload starts with a type byte; device → host types have the high bit clear, host →
//! device types have it set, so a frame that comes back the wrong way (an echoing line) is
//! rejected, not misread. Layouts are listed in the [module docs](super#messages).
//!
//! Parsing checks the whole message before returning it (smoltcp's `new_checked`
//! contract): once [`DeviceMessage::parse`] or [`HostMessage::parse`] returned `Ok`, no
//! accessor or iterator of the message can fail or panic.

use super::{
    codec::{bit_len, bytes_for_bits, BitCursor, BitWriter, Counter, Reader, Sink},
    events::EventBatch,
    fixed::WireCentre,
    frame::{emit_frame, frame_len_max},
    kind, Error, Result, PROTOCOL_VERSION,
};
use crate::{
    cluster::ClusterConfig,
    detect::{DetectConfig, Detection},
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

/// The counts of one window (the centres follow in the message).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectionHeader {
    /// Window sequence number (from 0 per session): gaps show lost frames.
    pub seq: u32,
    /// The window's reference time (the middle of its events' span; its centres are given at it), µs.
    pub t_ref_us: u64,
    /// Events in the window.
    pub events: u16,
    /// Events left as noise by clustering.
    pub noise: u16,
    /// Clusters kept.
    pub clusters: u16,
    /// Clusters beyond the device's capacity, dropped.
    pub dropped_clusters: u16,
    /// Clusters the fit rejected.
    pub rejected_fits: u16,
}

impl DetectionHeader {
    /// The header of a core detection.
    pub fn from_detection<const C: usize>(d: &Detection<C>) -> Self {
        Self {
            seq: d.info.seq,
            t_ref_us: d.info.t_ref_us,
            events: d.stats.events,
            noise: d.stats.noise,
            clusters: d.stats.clusters,
            dropped_clusters: d.stats.dropped_clusters,
            rejected_fits: d.stats.rejected_fits,
        }
    }
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
    /// Events dropped by the input filter: time went backwards.
    pub time_backwards: u64,
    /// Events lost for lack of buffer (the device's own event source overran).
    pub events_dropped: u64,
    /// Events of the window still filling (left out at the end of a stream).
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
}

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
    let fit = FitConfig { method, max_iterations: r.u8()?, min_events: r.varint_u16()? };
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

// ---- detections ------------------------------------------------------------------------

/// The packed fields of a centre, in order, with their widest bit width.
const FIELDS: usize = 5;
const MAX_WIDTH: [u8; FIELDS] = [32, 32, 32, 32, 16];

/// The fields of a centre as integers, in the packed order.
fn fields(c: &WireCentre) -> [i64; FIELDS] {
    [c.u.into(), c.v.into(), c.r.into(), c.spread.into(), c.n.into()]
}

/// Frame-of-reference code of one field over a window's centres: every value is
/// `base + offset`, offset in `width` bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct FieldCode {
    base: i64,
    width: u8,
}

/// A detection message as parsed: the window's counts and its centres, unpacked on the fly.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectionFrame<'a> {
    /// The window's counts.
    pub header: DetectionHeader,
    count: u16,
    codes: [FieldCode; FIELDS],
    bits: &'a [u8],
}

impl<'a> DetectionFrame<'a> {
    /// Number of centres.
    pub const fn len(&self) -> usize {
        self.count as usize
    }

    /// Whether the window has no centres.
    pub const fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The centres, in the order the device found them.
    pub fn centres(&self) -> Centres<'a> {
        Centres { left: self.count, codes: self.codes, bits: self.bits, cursor: BitCursor::default() }
    }

    fn read(r: &mut Reader<'a>) -> Result<Self> {
        let header = DetectionHeader {
            seq: r.varint_u32()?,
            t_ref_us: r.varint()?,
            events: r.varint_u16()?,
            noise: r.varint_u16()?,
            clusters: r.varint_u16()?,
            dropped_clusters: r.varint_u16()?,
            rejected_fits: r.varint_u16()?,
        };
        let count = r.varint_u16()?;
        let mut codes = [FieldCode::default(); FIELDS];
        if count > 0 {
            for (i, c) in codes.iter_mut().enumerate() {
                c.base = match i {
                    0 | 1 => r.zigzag_i32()?.into(),
                    4 => r.varint_u16()?.into(),
                    _ => r.varint_u32()?.into(),
                };
                c.width = r.u8()?;
                if c.width > MAX_WIDTH[i] {
                    return Err(Error::Invalid);
                }
            }
        }
        let per_centre: u64 = codes.iter().map(|c| u64::from(c.width)).sum::<u64>() + 1;
        let bits = r.rest();
        let need = bytes_for_bits(per_centre * u64::from(count));
        if (bits.len() as u64) < need {
            return Err(Error::Truncated);
        }
        if bits.len() as u64 > need {
            return Err(Error::Trailing);
        }
        let frame = Self { header, count, codes, bits };
        // Check every value now, so that iterating cannot fail.
        let mut cursor = BitCursor::default();
        for _ in 0..count {
            for (i, c) in codes.iter().enumerate() {
                let v = c.base + i64::from(cursor.take(bits, c.width.into())?);
                let ok = match i {
                    0 | 1 => i32::try_from(v).is_ok(),
                    4 => u16::try_from(v).is_ok(),
                    _ => u32::try_from(v).is_ok(),
                };
                if !ok {
                    return Err(Error::Invalid);
                }
            }
            cursor.take(bits, 1)?;
        }
        cursor.finish(bits)?;
        Ok(frame)
    }
}

/// Iterator over a [`DetectionFrame`]'s centres.
#[derive(Debug, Clone)]
pub struct Centres<'a> {
    left: u16,
    codes: [FieldCode; FIELDS],
    bits: &'a [u8],
    cursor: BitCursor,
}

impl Iterator for Centres<'_> {
    type Item = WireCentre;

    fn next(&mut self) -> Option<WireCentre> {
        self.left = self.left.checked_sub(1)?;
        let mut f = [0i64; FIELDS];
        for (v, c) in f.iter_mut().zip(self.codes) {
            *v = c.base + i64::from(self.cursor.take(self.bits, c.width.into()).ok()?);
        }
        let converged = self.cursor.take(self.bits, 1).ok()? == 1;
        // Parsing checked every value's range; the fallbacks are never taken.
        Some(WireCentre {
            u: i32::try_from(f[0]).unwrap_or_default(),
            v: i32::try_from(f[1]).unwrap_or_default(),
            r: u32::try_from(f[2]).unwrap_or_default(),
            spread: u32::try_from(f[3]).unwrap_or_default(),
            n: u16::try_from(f[4]).unwrap_or_default(),
            converged,
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.left.into(), Some(self.left.into()))
    }
}

impl ExactSizeIterator for Centres<'_> {}

/// Writes a detection message as a frame into `out`: the header, then the centres packed
/// per field with a frame of reference (each field's minimum, then every value's offset
/// from it in as few bits as the window's largest offset needs). `centres` is walked twice.
/// Centres beyond 65,535 are left out (no device holds that many).
pub fn emit_detection<I>(header: &DetectionHeader, centres: I, out: &mut [u8]) -> Result<usize>
where
    I: Iterator<Item = WireCentre> + Clone,
{
    let codes = field_codes(centres.clone());
    let count = centres.clone().take(usize::from(u16::MAX)).count();
    emit_frame(out, |w| {
        w.put(kind::DETECTION);
        w.varint(header.seq.into());
        w.varint(header.t_ref_us);
        for v in [header.events, header.noise, header.clusters, header.dropped_clusters, header.rejected_fits] {
            w.varint(v.into());
        }
        w.varint(count as u64);
        if count == 0 {
            return;
        }
        for (i, c) in codes.iter().enumerate() {
            match i {
                0 | 1 => w.zigzag(c.base),
                _ => w.varint(c.base as u64),
            }
            w.put(c.width);
        }
        let mut bw = BitWriter::default();
        for c in centres.take(count) {
            for (v, code) in fields(&c).into_iter().zip(codes) {
                bw.put(w, (v - code.base) as u64, code.width.into());
            }
            bw.put(w, c.converged.into(), 1);
        }
        bw.finish(w);
    })
}

fn field_codes(centres: impl Iterator<Item = WireCentre>) -> [FieldCode; FIELDS] {
    let mut lo = [i64::MAX; FIELDS];
    let mut hi = [i64::MIN; FIELDS];
    for c in centres.take(usize::from(u16::MAX)) {
        for (i, v) in fields(&c).into_iter().enumerate() {
            lo[i] = lo[i].min(v);
            hi[i] = hi[i].max(v);
        }
    }
    let mut codes = [FieldCode::default(); FIELDS];
    for i in 0..FIELDS {
        if lo[i] <= hi[i] {
            codes[i] = FieldCode { base: lo[i], width: bit_len((hi[i] - lo[i]) as u64) as u8 };
        }
    }
    codes
}

/// Writes a core detection as a detection message, quantising its centres
/// ([`WireCentre::from_centre`]); the frame's length.
pub fn emit_core_detection<const C: usize>(d: &Detection<C>, out: &mut [u8]) -> Result<usize> {
    emit_detection(&DetectionHeader::from_detection(d), d.centres.iter().map(WireCentre::from_centre), out)
}

/// Longest payload of a detection message with `c` centres.
pub const fn detection_payload_max(c: usize) -> usize {
    // type, seq, t_ref, five u16 counts, count, five (base, width) pairs
    let header = 1 + 5 + 10 + 5 * 3 + 3 + (5 + 1) * 4 + (3 + 1);
    let per_centre_bits = 32 * 4 + 16 + 1;
    header + (c * per_centre_bits).div_ceil(8)
}

/// Longest detection frame with `c` centres on the wire, delimiters included: the size of
/// the device's transmit buffer.
pub const fn detection_frame_max(c: usize) -> usize {
    frame_len_max(detection_payload_max(c))
}

/// Payload bytes of a message, for tests and size reports.
#[allow(dead_code)]
pub(crate) fn payload_len(body: impl FnOnce(&mut Counter)) -> usize {
    let mut c = Counter::default();
    body(&mut c);
    c.0
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::wire::{frame::decode_in_place, FrameAccumulator};
    use std::vec::Vec;

    /// The payload of a frame (COBS undone, CRC checked and removed).
    fn payload(frame: &[u8]) -> Vec<u8> {
        assert_eq!(frame.first(), Some(&0));
        assert_eq!(frame.last(), Some(&0));
        let mut body = frame[1..frame.len() - 1].to_vec();
        let n = decode_in_place(&mut body).expect("a valid frame");
        body.truncate(n);
        body
    }

    fn emit(f: impl FnOnce(&mut [u8]) -> Result<usize>) -> Vec<u8> {
        let mut out = vec![0u8; 4096];
        let n = f(&mut out).unwrap();
        out.truncate(n);
        out
    }

    /// postcard's `test_one`: the exact payload bytes, then the parse gives the value back.
    fn device_one(frame: &[u8], expected_payload: &[u8], check: impl FnOnce(DeviceMessage<'_>)) {
        let p = payload(frame);
        assert_eq!(p, expected_payload, "payload bytes");
        check(DeviceMessage::parse(&p).unwrap());
    }

    const DAVIS_CONFIG: [u8; 18] = [
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
        let c = Config { session: 1, config: cfg };
        let f = emit(|o| c.emit(o));
        let mut expected = vec![0x81, 0x01];
        expected.extend(&DAVIS_CONFIG[..14]);
        expected.extend([0x01, 0x00, 0x00, 0x00, 0x3F, 0x02, 0x06, 0x14]);
        let p = payload(&f);
        assert_eq!(p, expected);
        assert_eq!(HostMessage::parse(&p), Ok(HostMessage::Config(c)));
    }

    #[test]
    fn golden_detection() {
        let header = DetectionHeader {
            seq: 5,
            t_ref_us: 1000,
            events: 4000,
            noise: 100,
            clusters: 2,
            dropped_clusters: 0,
            rejected_fits: 0,
        };
        let centres = [
            WireCentre { u: 1024, v: 2048, r: 5120, spread: 100, n: 30, converged: true },
            WireCentre { u: 1030, v: 2040, r: 5121, spread: 90, n: 31, converged: false },
        ];
        let f = emit(|o| emit_detection(&header, centres.iter().copied(), o));
        let expected = [
            0x02, 0x05, 0xE8, 0x07, 0xA0, 0x1F, 0x64, 0x02, 0x00, 0x00, // header
            0x02, // two centres
            0x80, 0x10, 0x03, // u: base 1024 (zigzag 2048), 3 bits
            0xF0, 0x1F, 0x04, // v: base 2040 (zigzag 4080), 4 bits
            0x80, 0x28, 0x01, // r: base 5120, 1 bit
            0x5A, 0x04, // spread: base 90, 4 bits
            0x1E, 0x01, // n: base 30, 1 bit
            0x40, 0xAA, 0x21, 0x04, // 2 × 14 bits, LSB first, zero-padded
        ];
        device_one(&f, &expected, |m| match m {
            DeviceMessage::Detection(d) => {
                assert_eq!(d.header, header);
                assert_eq!(d.centres().collect::<Vec<_>>(), centres);
                assert_eq!(d.centres().len(), 2);
            }
            other => panic!("{other:?}"),
        });
    }

    #[test]
    fn golden_empty_detection() {
        let header = DetectionHeader { seq: 1, ..Default::default() };
        let f = emit(|o| emit_detection(&header, core::iter::empty(), o));
        device_one(&f, &[0x02, 0x01, 0, 0, 0, 0, 0, 0, 0], |m| match m {
            DeviceMessage::Detection(d) => assert!(d.is_empty() && d.header == header),
            other => panic!("{other:?}"),
        });
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
        // detection: width above 32
        let mut d = vec![0x02, 0, 0, 0, 0, 0, 0, 0, 1];
        d.extend([0, 33, 0, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(DeviceMessage::parse(&d), Err(Error::Invalid));
        // detection: bit field one byte short, one byte long
        let header = DetectionHeader::default();
        let c = [WireCentre { u: -5, v: 7, r: 3, spread: 1, n: 9, converged: true }; 3];
        let p = payload(&emit(|o| emit_detection(&header, c.iter().copied(), o)));
        assert_eq!(DeviceMessage::parse(&p[..p.len() - 1]), Err(Error::Truncated));
        let mut long = p.clone();
        long.push(0);
        assert_eq!(DeviceMessage::parse(&long), Err(Error::Trailing));
        // nonzero padding bits
        let mut pad = p.clone();
        *pad.last_mut().unwrap() |= 0x80;
        assert_eq!(DeviceMessage::parse(&pad), Err(Error::Invalid));
    }

    /// A full window (96 centres, the capacity) with centres spread over the whole sensor,
    /// radii from 2 px to a third of the height, spreads up to 3 px, clusters of up to 1000
    /// events: under 1 KiB even on the largest sensor we support (Prophesee, 1280 x 720).
    #[test]
    fn a_full_window_is_under_1_kib_on_every_sensor() {
        for (w, h) in [(346u32, 260u32), (640, 480), (1280, 720)] {
            let header = DetectionHeader {
                seq: 123_456,
                t_ref_us: 3_600_000_000,
                events: 4000,
                noise: 900,
                clusters: 96,
                ..Default::default()
            };
            let c: Vec<WireCentre> = (0..96u32)
                .map(|i| WireCentre {
                    u: (((i * 7919) % w) << 10) as i32 + (i * 37 % 1024) as i32,
                    v: (((i * 104_729) % h) << 10) as i32 + (i * 91 % 1024) as i32,
                    r: (2 << 10) + (i * 409) % ((h / 3 - 2) << 10),
                    spread: (i * 331) % (3 << 10),
                    n: 20 + (i * 97 % 980) as u16,
                    converged: i % 5 != 0,
                })
                .collect();
            let f = emit(|o| emit_detection(&header, c.iter().copied(), o));
            assert!(f.len() <= 1024, "{w} x {h}: {} B", f.len());
            eprintln!("96 centres on {w} x {h}: {} B", f.len());
        }
    }

    #[test]
    fn detection_frame_fits_the_bound_in_the_worst_case() {
        let header = DetectionHeader {
            seq: u32::MAX,
            t_ref_us: u64::MAX,
            events: u16::MAX,
            noise: u16::MAX,
            clusters: u16::MAX,
            dropped_clusters: u16::MAX,
            rejected_fits: u16::MAX,
        };
        let mut c = vec![WireCentre { u: i32::MIN, v: i32::MIN, r: 0, spread: 0, n: 0, converged: false }; 96];
        c[1] = WireCentre { u: i32::MAX, v: i32::MAX, r: u32::MAX, spread: u32::MAX, n: u16::MAX, converged: true };
        let f = emit(|o| emit_detection(&header, c.iter().copied(), o));
        assert!(f.len() <= detection_frame_max(96), "{} > {}", f.len(), detection_frame_max(96));
        assert!(payload(&f).len() <= detection_payload_max(96));
        let p = payload(&f);
        match DeviceMessage::parse(&p).unwrap() {
            DeviceMessage::Detection(d) => assert_eq!(d.centres().collect::<Vec<_>>(), c),
            other => panic!("{other:?}"),
        }
        let mut acc: FrameAccumulator<2048> = FrameAccumulator::new();
        assert!(matches!(acc.feed(&f), crate::wire::Feed::Frame { .. }));
    }
}
