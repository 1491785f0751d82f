//! Damaging frames on their way, to show that a damaged frame costs only itself.
//!
//! [`FrameTap`] wraps a writer and hands every frame (from its leading to its closing
//! delimiter) to a closure that may flip or drop bytes before it is passed on.

use evcal_core::wire::{DeviceMessage, Feed, FrameAccumulator, HostMessage};
use std::io::{self, Write};

/// A writer that lets `damage(index, frame)` change every frame before passing it on.
/// Frames are counted from 0 in the order written.
pub struct FrameTap<W: Write, F: FnMut(usize, &mut Vec<u8>)> {
    inner: W,
    frame: Vec<u8>,
    index: usize,
    damage: F,
}

impl<W: Write, F: FnMut(usize, &mut Vec<u8>)> FrameTap<W, F> {
    /// Taps `inner`.
    pub fn new(inner: W, damage: F) -> Self {
        Self { inner, frame: Vec::new(), index: 0, damage }
    }
}

impl<W: Write, F: FnMut(usize, &mut Vec<u8>)> Write for FrameTap<W, F> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        for &b in buf {
            self.frame.push(b);
            if b == 0 && self.frame.iter().any(|&x| x != 0) {
                let mut f = std::mem::take(&mut self.frame);
                (self.damage)(self.index, &mut f);
                self.index += 1;
                self.inner.write_all(&f)?;
            }
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// What a whole, intact frame holds, for choosing which frames to damage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FrameKind {
    /// Hello.
    Hello,
    /// A window's detections, with its sequence number.
    Detection(u32),
    /// Stats.
    Stats,
    /// Ack.
    Ack,
    /// Config.
    Config,
    /// An event batch, with its sequence number.
    Events(u32),
    /// End.
    End,
    /// Not a valid frame.
    Invalid,
}

/// Parses one whole frame as written (delimiters included).
pub fn describe(frame: &[u8]) -> FrameKind {
    let mut acc: Box<FrameAccumulator<{ super::HOST_RX_FRAME }>> = Box::new(FrameAccumulator::new());
    let Feed::Frame { payload, .. } = acc.feed(frame) else { return FrameKind::Invalid };
    if let Ok(m) = DeviceMessage::parse(payload) {
        return match m {
            DeviceMessage::Hello(_) => FrameKind::Hello,
            DeviceMessage::Detection(d) => FrameKind::Detection(d.header.seq),
            DeviceMessage::Stats(_) => FrameKind::Stats,
            DeviceMessage::Ack(_) => FrameKind::Ack,
        };
    }
    match HostMessage::parse(payload) {
        Ok(HostMessage::Config(_)) => FrameKind::Config,
        Ok(HostMessage::Events(b)) => FrameKind::Events(b.seq),
        Ok(HostMessage::End(_)) => FrameKind::End,
        Err(_) => FrameKind::Invalid,
    }
}
