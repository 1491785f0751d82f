//! The wire protocol between the device and the host.
//!
//! The device streams what it detects (a few hundred bytes per window) and the host may
//! stream a recording into it (hardware-in-the-loop replay), over a serial link or QEMU's
//! emulated UART at about 14 KB/s. Everything here is `no_std`, allocation-free and
//! deterministic: the same message always gives the same bytes, on every target.
//!
//! * [`frame`]: framing. `0x00 ‖ COBS(payload ‖ CRC-32C) ‖ 0x00`; why these.
//! * [`FrameAccumulator`]: reassembles frames from a byte stream in a fixed buffer and
//!   resynchronises after damage (postcard's `CobsAccumulator` is the model).
//! * [`DeviceMessage`], [`HostMessage`]: the messages and their layouts; a window's centres
//!   are packed per field ([`emit_detection`], [`DetectionFrame`]).
//! * [`fixed`]: the fixed-point form of centres (1/1024 px), shared with the host's output.
//! * [`events`]: compact event batches for replay.
//! * [`device`]: the device's side of the protocol as a state machine the firmware drives.
//!
//! Decoding never panics, whatever the bytes (property-tested and fuzzed): a damaged,
//! truncated or foreign frame is an [`Error`] and costs that frame only.
//!
//! # Protocol
//!
//! Version [`PROTOCOL_VERSION`], stated in every [`Hello`].
//!
//! 1. The device sends a [`Hello`] when it starts. The host sends nothing before it has
//!    heard one (some UARTs drop bytes that arrive before they are enabled), except after a
//!    time-out of silence.
//! 2. The host sends [`Config`] with a fresh session number; the device resets and answers
//!    with a [`Hello`] showing the configuration now in force. The host repeats the Config
//!    until that Hello arrives.
//! 3. The host streams event batches and finally an [`End`]: *sequenced* frames, numbered
//!    from 0 per session. The device handles them strictly in order and acknowledges them
//!    cumulatively with [`Ack`]s that also grant credit (`window`): the host never has more
//!    than `window` frames beyond the last acknowledged one outstanding, so input faster
//!    than the device processes it waits in the host, never overruns the device. A frame
//!    that arrives damaged or out of order is dropped, counted, and answered with a NAK;
//!    the host then sends again from the frame the device expects (go-back-N, with a
//!    time-out for lost acknowledgements). Replay over a noisy link is therefore lossless.
//! 4. The device sends a [`DetectionFrame`] per window as it completes, a [`Stats`] every
//!    few windows, and a final [`Stats`] and [`Ack`] after [`End`]. Detections are not
//!    repeated: one lost on the way shows as a gap in the window sequence numbers.
//!
//! A device with its own sensor simply streams Hello, detections and stats.
//!
//! # Messages
//!
//! Integers are LEB128 varints unless stated (`zz`: zigzag varint), `f32` little-endian
//! bits, bit fields least significant bit first, padded with zeros to a byte.
//!
//! | type | message | fields |
//! |---|---|---|
//! | `0x01` | [`Hello`] (device) | version `u8`, reply `u8` (0 boot, 1 applied, 2 rejected), session, config†, max events, max clusters, max frame, window, clock Hz |
//! | `0x02` | [`DetectionFrame`] (device) | seq, t_ref µs, events, noise, clusters, dropped clusters, rejected fits, count; if count > 0: for u, v (`zz`), r, spread, n: base and width `u8`; then count × (u, v, r, spread, n in their widths as offsets from base, converged 1 bit) |
//! | `0x03` | [`Stats`] (device) | end-of-stream `u8`, then the counters in declaration order |
//! | `0x04` | [`Ack`] (device) | next, window, nak `u8` |
//! | `0x81` | [`Config`] (host) | session, config† |
//! | `0x82` | [`EventBatch`] (host) | seq, t0 µs, count, Rice k `u8`, x bits `u8`, y bits `u8`, then the events (see [`events`]) |
//! | `0x83` | [`End`] (host) | seq |
//!
//! † config: sensor width, height, events per window, step µs, eps `f32`, min_pts, eps_t
//! (`u8` 0, or 1 and `f32`), fit method `u8` (0 centroid, 1 OLS, 2 eRWLS), max iterations
//! `u8`, min cluster events, fit flags `u8` (bit 0: filled discs, see
//! [`FitConfig::filled_discs`](crate::fit::FitConfig::filled_discs); other bits 0, else the
//! configuration is invalid). Version 2 added the flags byte; version 1 had none.
//!
//! Centres are quantised to 1/1024 px ([`fixed`]) and packed with a frame of reference per
//! field: a window's radii that span 3.2–9.8 px cost 13 bits each, not 32. Measured
//! (`cargo test -p evcal-tests --test end_to_end link::bytes -- --nocapture`): simulated DAVIS346 4x11
//! windows with clutter, 43 centres on average, take 428 bytes on average and 536 at most;
//! a full window of 96 centres spread over a whole 1280 x 720 sensor takes 998 bytes
//! (`a_full_window_is_under_1_kib_on_every_sensor`).
pub mod device;
pub mod events;
pub mod fixed;
pub mod frame;

mod codec;
mod detection;
mod message;
#[cfg(test)]
mod tests;

pub use detection::{
    detection_frame_max, detection_payload_max, emit_core_detection, emit_detection, Centres, DetectionFrame,
    DetectionHeader,
};
pub use device::{Device, DeviceOptions};
pub use events::{emit_events, events_that_fit, BatchEvents, BatchSizer, EventBatch, EventCursor};
pub use fixed::WireCentre;
pub use frame::{Feed, FrameAccumulator};
pub use message::{Ack, Config, DeviceMessage, End, Hello, HelloReply, HostMessage, Stats};

/// The protocol version this crate speaks, carried in [`Hello`].
pub const PROTOCOL_VERSION: u8 = 2;

/// Message type bytes, as the table of [messages](self#messages) lists them. Here rather than
/// beside any one message: every message's emitter writes its own, and the parsers of both
/// directions read them all.
pub(crate) mod kind {
    pub const HELLO: u8 = 0x01;
    pub const DETECTION: u8 = 0x02;
    pub const STATS: u8 = 0x03;
    pub const ACK: u8 = 0x04;
    pub const CONFIG: u8 = 0x81;
    pub const EVENTS: u8 = 0x82;
    pub const END: u8 = 0x83;
}

/// What went wrong with a frame or a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// The frame's byte stuffing is broken (a COBS block runs past the frame's end).
    Cobs,
    /// The frame's checksum does not match: damaged on the way, or not one of ours.
    Crc,
    /// The frame is too short to hold a message type and a checksum.
    TooShort,
    /// The frame is longer than the receive buffer.
    Overflow,
    /// The message type is not one this side of the link accepts.
    UnknownType(u8),
    /// The message ends inside a field.
    Truncated,
    /// Bytes follow the end of the message.
    Trailing,
    /// A field holds a value out of its range.
    Invalid,
    /// A Hello of another protocol version (this side speaks [`PROTOCOL_VERSION`]).
    Version(u8),
    /// The output buffer is too small for the frame.
    BufferTooSmall,
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Cobs => f.write_str("broken COBS framing"),
            Self::Crc => f.write_str("checksum mismatch (damaged or foreign frame)"),
            Self::TooShort => f.write_str("frame too short"),
            Self::Overflow => f.write_str("frame longer than the receive buffer"),
            Self::UnknownType(t) => write!(f, "unknown message type 0x{t:02x}"),
            Self::Truncated => f.write_str("message ends inside a field"),
            Self::Trailing => f.write_str("bytes after the end of the message"),
            Self::Invalid => f.write_str("field value out of range"),
            Self::Version(v) => write!(f, "protocol version {v}; this side speaks version {PROTOCOL_VERSION}"),
            Self::BufferTooSmall => f.write_str("output buffer too small for the frame"),
        }
    }
}

impl core::error::Error for Error {}

/// Results of this module.
pub type Result<T> = core::result::Result<T, Error>;
