//! The device's side of the protocol: a state machine that the firmware (or the host's
//! virtual device) drives with received bytes, and that hands back frames to transmit.
//!
//! It owns the [`Detector`] and two fixed buffers: one for a received frame (`RX` bytes)
//! and one for a frame to transmit (`TX` bytes, at least the largest detection frame). It
//! does no I/O and keeps no time of its own, so it runs the same on the Cortex-M4F, on the
//! host, and in tests.
//!
//! # Driving it
//!
//! Two calls, in a loop:
//!
//! * [`poll`](Device::poll) does the next piece of work — feeding a received batch's events
//!   into the detector, processing a window that completed, answering the host — and returns
//!   the next frame to transmit, or `None` when there is nothing left to do. Write each frame
//!   out whole before calling again (the slice lives in the device's transmit buffer).
//! * [`receive`](Device::receive) takes received bytes and returns how many it took. It takes
//!   none while a batch of events is still being fed (the batch lives in the receive buffer):
//!   poll, then offer the rest again. That back-pressure is the flow control: bytes wait in
//!   the UART or the host, and the host's credit ([`Ack::window`]) bounds how many can wait.
//!
//! ```ignore
//! // firmware main loop (a blocking serial port, a SysTick clock)
//! let mut buf = [0u8; 64];
//! let (mut start, mut end) = (0, 0);
//! loop {
//!     while let Some(frame) = dev.poll(&mut clock) {
//!         serial.write_all(frame)?;
//!     }
//!     if start == end {
//!         end = serial.read(&mut buf)?; // blocks for at least one byte
//!         start = 0;
//!     }
//!     start += dev.receive(&buf[start..end]);
//! }
//! ```
//!
//! A device with its own sensor feeds events with [`push_event`](Device::push_event)
//! instead of (or as well as) receiving batches, and reports events its source lost with
//! [`count_dropped_events`](Device::count_dropped_events).
//!
//! # Memory
//!
//! `Device` is large: 102,776 bytes on the Cortex-M4F with the default capacities (the
//! detector's window buffer, clusterer and scratch, its input filter's hold of
//! [`MAX_HELD_EVENTS`] events, 600 bytes, plus `RX + TX`). Give it a `static` home, and build it at
//! compile time ([`Device::new`] and [`DetectConfig::for_sensor`] are `const fn`), so that no temporary
//! copy ever lands on the stack: with `static_cell`, as the firmware does, the image is
//! written into the static's memory in place:
//!
//! ```
//! use evcal_core::{detect::DetectConfig, event::SensorSize, wire::{Device, DeviceOptions}};
//! use static_cell::StaticCell;
//!
//! const IMAGE: Device = Device::new(
//!     DetectConfig::for_sensor(SensorSize::DAVIS346),
//!     DeviceOptions { clock_hz: 168_000_000, ..DeviceOptions::DEFAULT },
//! );
//! static DEVICE: StaticCell<Device> = StaticCell::new();
//!
//! // Once, at start-up: the only `&'static mut` to it there will be.
//! let dev: &'static mut Device = DEVICE.try_uninit().expect("first use").write(IMAGE);
//! assert!(DEVICE.try_uninit().is_none());
//! # let _ = dev;
//! ```
//!
//! A host's [`Config`] resets the detector in place (`Detector::reconfigure`); measured on
//! `thumbv7em-none-eabihf` (opt-level `s`), [`receive`](Device::receive) then needs under
//! 200 bytes of stack.

use super::{
    detection_frame_max, emit_core_detection, Ack, Config, Feed, FrameAccumulator, Hello, HelloReply, HostMessage,
    Stats,
};
use crate::{
    cluster::TABLE_CELLS,
    config::{MAX_CLUSTERS, MAX_EVENTS_PER_WINDOW},
    detect::{Clock, DetectConfig, Detector},
    event::Event,
    event::MAX_HELD_EVENTS,
    wire::EventCursor,
};

/// Default receive buffer: host frames of up to 512 bytes on the wire (about 190 events per
/// batch on DAVIS346 recordings).
pub const RX_FRAME: usize = 510;
/// Default transmit buffer: the largest detection frame with [`MAX_CLUSTERS`] centres.
pub const TX_FRAME: usize = detection_frame_max(MAX_CLUSTERS);

/// How a [`Device`] behaves on the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceOptions {
    /// Credit: how many sequenced frames the host may send beyond the last acknowledged one.
    /// One frame waits in the device's receive buffer; each further one must fit in what
    /// the firmware's receive path holds (a UART FIFO or DMA ring: frames of up to `RX + 2`
    /// bytes each). Under QEMU the emulated UART holds bytes back, so 2 keeps the link busy.
    pub window: u16,
    /// Send [`Stats`] after every this many windows (0: only at the end of a stream).
    pub stats_every: u16,
    /// Rate of the [`Clock`] given to [`Device::poll`], Hz, reported in [`Hello`] so that the
    /// host can turn the `*_ticks` counters into time (0: no clock).
    pub clock_hz: u32,
}

impl DeviceOptions {
    /// Window 2, stats every 16 windows, no clock.
    pub const DEFAULT: Self = Self { window: 2, stats_every: 16, clock_hz: 0 };
}

impl Default for DeviceOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What the host is owed, a NAK outranking an ACK.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum AckDue {
    None,
    Ack,
    Nak,
}

/// A received frame, once parsed (borrowing nothing).
enum Action {
    Bad,
    Config(Config),
    Batch { seq: u32, cursor: EventCursor },
    End(u32),
}

/// Where a sequenced frame stands against the expected sequence number.
enum Order {
    Next,
    Repeat,
    Ahead,
}

/// The device's side of the link: see the [module docs](self).
///
/// `N`, `C` are the detector's capacities (events per window, clusters),
/// `RX` the receive buffer (host frames of up to `RX + 2` bytes), `TX` the transmit buffer
/// (at least [`detection_frame_max`]`(C)`, checked at compile time), `CELLS` the detector's
/// scratch ([`Scratch`](crate::detect::Scratch)).
pub struct Device<
    const N: usize = MAX_EVENTS_PER_WINDOW,
    const C: usize = MAX_CLUSTERS,
    const RX: usize = RX_FRAME,
    const TX: usize = TX_FRAME,
    const CELLS: usize = TABLE_CELLS,
> {
    det: Detector<N, C, MAX_HELD_EVENTS, CELLS>,
    opts: DeviceOptions,
    rx: FrameAccumulator<RX>,
    tx: [u8; TX],
    /// A batch whose events are still being fed; its bytes are the receive buffer's frame.
    batch: Option<EventCursor>,
    /// Next sequence number expected from the host.
    expected: u32,
    session: u32,
    last_end: Option<u32>,
    hello_due: Option<HelloReply>,
    stats_due: bool,
    end_due: bool,
    ack_due: AckDue,
    stats: Stats,
}

impl<const N: usize, const C: usize, const RX: usize, const TX: usize, const CELLS: usize> Device<N, C, RX, TX, CELLS> {
    const CHECK: () = assert!(
        TX >= detection_frame_max(C) && RX >= 32 && RX + 2 <= u16::MAX as usize,
        "TX must hold a detection frame of C centres; RX must hold a useful frame"
    );

    /// A device running `config`, owing the host a [`Hello`].
    pub const fn new(config: DetectConfig, opts: DeviceOptions) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Self {
            det: Detector::new(config),
            opts,
            rx: FrameAccumulator::new(),
            tx: [0; TX],
            batch: None,
            expected: 0,
            session: 0,
            last_end: None,
            hello_due: Some(HelloReply::Boot),
            stats_due: false,
            end_due: false,
            ack_due: AckDue::None,
            stats: Stats::ZERO,
        }
    }

    /// The detector's configuration in force.
    pub const fn config(&self) -> DetectConfig {
        self.det.config()
    }

    /// The counters since the session started, as the next [`Stats`] frame will carry them.
    pub fn stats(&self) -> Stats {
        let input = self.det.input_stats();
        Stats {
            events_accepted: input.accepted,
            out_of_sensor: input.out_of_sensor,
            // The wire's one count of events dropped for their time: stray times too, so that
            // the counts still add up to the events received (see `Stats::time_backwards`).
            time_backwards: input.time_order(),
            pending_events: self.det.pending().min(u32::MAX as usize) as u32,
            ..self.stats
        }
    }

    /// Whether the device has nothing to do until more bytes arrive.
    pub fn is_idle(&self) -> bool {
        self.batch.is_none()
            && !self.end_due
            && !self.stats_due
            && self.hello_due.is_none()
            && self.ack_due == AckDue::None
    }

    /// Takes received bytes, up to the end of a frame that needs work (a batch of events or
    /// the end of the stream); returns how many it took. Offer the rest again after
    /// [`poll`](Self::poll). Damaged and foreign frames are counted and dropped here.
    pub fn receive(&mut self, bytes: &[u8]) -> usize {
        let mut input = bytes;
        while !self.busy() && !input.is_empty() {
            let (action, rest) = match self.rx.feed(input) {
                Feed::Consumed => return bytes.len(),
                Feed::Error { rest, .. } => (Action::Bad, rest),
                Feed::Frame { payload, rest } => (classify(payload), rest),
            };
            input = rest;
            self.apply(action);
        }
        bytes.len() - input.len()
    }

    /// Does the next piece of work and returns the next frame to transmit, or `None` when
    /// the device is idle. `clock` times the stages for [`Stats`].
    pub fn poll(&mut self, clock: &mut impl Clock) -> Option<&[u8]> {
        loop {
            match self.step(clock) {
                Step::Frame(n) => return self.tx.get(..n),
                Step::Again => continue,
                Step::Idle => return None,
            }
        }
    }

    /// Feeds one event from the device's own source; returns the detection frame to
    /// transmit when a window completes. Call [`poll`](Self::poll) too, for stats and
    /// replies, and [`end_events`](Self::end_events) when the source ends.
    pub fn push_event(&mut self, e: Event, clock: &mut impl Clock) -> Option<&[u8]> {
        self.stats.events_received += 1;
        if self.det.feed(e) {
            if let Some(n) = self.process_window(clock) {
                return self.tx.get(..n);
            }
        }
        None
    }

    /// The device's own source has ended: the events the input filter still holds (after
    /// a pause, see [`InputFilter`](crate::event::InputFilter)) are decided and windowed;
    /// returns a detection frame when they complete a window. Call until `None`.
    pub fn end_events(&mut self, clock: &mut impl Clock) -> Option<&[u8]> {
        while self.det.finish() {
            if let Some(n) = self.process_window(clock) {
                return self.tx.get(..n);
            }
        }
        None
    }

    /// Counts events the device's own source lost (a full FIFO), for [`Stats::events_dropped`],
    /// and keeps them out of every window ([`Detector::lost`]): the window filling is dropped.
    /// Call it where they were lost in the stream, before the next event is fed.
    pub fn count_dropped_events(&mut self, n: u64) {
        if n > 0 {
            self.det.lost();
        }
        self.stats.events_dropped = self.stats.events_dropped.saturating_add(n);
    }

    /// Counts bytes the receiver lost (a UART overrun), for [`Stats::rx_overrun`]. The frame
    /// they belonged to fails its check and is sent again.
    pub fn count_rx_overrun(&mut self, bytes: u32) {
        self.stats.rx_overrun = self.stats.rx_overrun.saturating_add(bytes);
    }

    fn busy(&self) -> bool {
        self.batch.is_some() || self.end_due
    }

    fn order(&self, seq: u32) -> Order {
        match seq.wrapping_sub(self.expected) as i32 {
            0 => Order::Next,
            d if d < 0 => Order::Repeat,
            _ => Order::Ahead,
        }
    }

    fn apply(&mut self, action: Action) {
        let owe = |s: &mut Self, a: AckDue| s.ack_due = s.ack_due.max(a);
        match action {
            Action::Bad => {
                self.stats.frames_bad = self.stats.frames_bad.saturating_add(1);
                owe(self, AckDue::Nak);
            }
            Action::Config(c) => {
                if c.session != 0 && c.session == self.session {
                    self.stats.frames_received += 1;
                    self.hello_due = Some(HelloReply::Applied);
                } else if valid(&c.config) {
                    // In place: the detector is too large for a temporary on a small stack.
                    self.det.reconfigure(c.config);
                    self.session = c.session;
                    self.expected = 0;
                    self.last_end = None;
                    self.stats = Stats::ZERO;
                    self.stats.frames_received = 1;
                    self.ack_due = AckDue::None;
                    self.stats_due = false;
                    self.hello_due = Some(HelloReply::Applied);
                } else {
                    self.stats.frames_received += 1;
                    self.hello_due = Some(HelloReply::Rejected);
                }
            }
            Action::Batch { seq, cursor } => {
                self.stats.frames_received += 1;
                match self.order(seq) {
                    Order::Next => {
                        self.expected = self.expected.wrapping_add(1);
                        self.batch = Some(cursor);
                    }
                    Order::Repeat => {
                        self.stats.frames_discarded += 1;
                        owe(self, AckDue::Ack);
                    }
                    Order::Ahead => {
                        self.stats.frames_discarded += 1;
                        owe(self, AckDue::Nak);
                    }
                }
            }
            Action::End(seq) => {
                self.stats.frames_received += 1;
                match self.order(seq) {
                    Order::Next => {
                        self.expected = self.expected.wrapping_add(1);
                        self.last_end = Some(seq);
                        self.end_due = true;
                    }
                    Order::Repeat if self.last_end == Some(seq) => {
                        // The host missed the final Stats or Ack: send both again.
                        self.stats.frames_discarded += 1;
                        self.end_due = true;
                    }
                    Order::Repeat => {
                        self.stats.frames_discarded += 1;
                        owe(self, AckDue::Ack);
                    }
                    Order::Ahead => {
                        self.stats.frames_discarded += 1;
                        owe(self, AckDue::Nak);
                    }
                }
            }
        }
    }

    fn step(&mut self, clock: &mut impl Clock) -> Step {
        if let Some(reply) = self.hello_due.take() {
            let hello = Hello {
                reply,
                session: self.session,
                config: self.det.config(),
                max_events: N.min(u32::MAX as usize) as u32,
                max_clusters: C.min(u16::MAX as usize) as u16,
                max_frame: (RX + 2) as u16,
                window: self.opts.window.max(1),
                clock_hz: self.opts.clock_hz,
            };
            let r = hello.emit(&mut self.tx);
            return self.sent(r);
        }
        if core::mem::take(&mut self.stats_due) {
            return self.send_stats(false, clock);
        }
        if let Some(cursor) = &mut self.batch {
            let t0 = clock.now();
            loop {
                match cursor.next(self.rx.frame()) {
                    Some(e) => {
                        self.stats.events_received += 1;
                        if self.det.feed(e) {
                            self.stats.input_ticks += u64::from(clock.now().wrapping_sub(t0));
                            return match self.process_window(clock) {
                                Some(n) => Step::Frame(n),
                                None => Step::Again,
                            };
                        }
                    }
                    None => {
                        self.batch = None;
                        self.ack_due = self.ack_due.max(AckDue::Ack);
                        break;
                    }
                }
            }
            self.stats.input_ticks += u64::from(clock.now().wrapping_sub(t0));
        }
        if self.end_due {
            // What the input filter holds goes first: the final Stats come after every window.
            if self.det.finish() {
                return match self.process_window(clock) {
                    Some(n) => Step::Frame(n),
                    None => Step::Again,
                };
            }
            self.end_due = false;
            self.ack_due = self.ack_due.max(AckDue::Ack);
            return self.send_stats(true, clock);
        }
        let due = core::mem::replace(&mut self.ack_due, AckDue::None);
        if due != AckDue::None {
            let ack = Ack { next: self.expected, window: self.opts.window.max(1), nak: due == AckDue::Nak };
            let r = ack.emit(&mut self.tx);
            return self.sent(r);
        }
        Step::Idle
    }

    fn send_stats(&mut self, end_of_stream: bool, clock: &mut impl Clock) -> Step {
        let t = clock.now();
        let s = Stats { end_of_stream, ..self.stats() };
        let r = s.emit(&mut self.tx);
        self.stats.encode_ticks += u64::from(clock.now().wrapping_sub(t));
        self.sent(r)
    }

    fn sent(&mut self, r: super::Result<usize>) -> Step {
        match r {
            Ok(n) => Step::Frame(n),
            Err(_) => {
                self.stats.frames_unsent = self.stats.frames_unsent.saturating_add(1);
                Step::Again
            }
        }
    }

    /// Clusters and fits the window the detector completed, encodes its detection frame;
    /// the frame's length in the transmit buffer.
    fn process_window(&mut self, clock: &mut impl Clock) -> Option<usize> {
        let d = self.det.process(clock);
        let s = &mut self.stats;
        s.windows = s.windows.wrapping_add(1);
        s.dropped_clusters += u64::from(d.stats.dropped_clusters);
        s.ticks_skipped += u64::from(d.stats.ticks_skipped);
        s.distance_checks += u64::from(d.stats.distance_checks);
        s.cluster_ticks += u64::from(d.stats.cluster_ticks);
        s.fit_ticks += u64::from(d.stats.fit_ticks);
        let t = clock.now();
        let r = emit_core_detection(d, &mut self.tx);
        self.stats.encode_ticks += u64::from(clock.now().wrapping_sub(t));
        let every = u32::from(self.opts.stats_every);
        if every > 0 && self.stats.windows % every == 0 {
            self.stats_due = true;
        }
        match r {
            Ok(n) => Some(n),
            Err(_) => {
                self.stats.frames_unsent = self.stats.frames_unsent.saturating_add(1);
                None
            }
        }
    }
}

enum Step {
    Frame(usize),
    Again,
    Idle,
}

fn classify(payload: &[u8]) -> Action {
    match HostMessage::parse(payload) {
        Ok(HostMessage::Config(c)) => Action::Config(c),
        Ok(HostMessage::Events(b)) => Action::Batch { seq: b.seq, cursor: b.cursor() },
        Ok(HostMessage::End(e)) => Action::End(e.seq),
        Err(_) => Action::Bad,
    }
}

/// Whether a host's configuration can run: the detector would misbehave on none of it.
fn valid(c: &DetectConfig) -> bool {
    c.sensor.width > 0
        && c.sensor.height > 0
        && c.window.events > 0
        && c.cluster.eps.is_finite()
        && c.cluster.eps > 0.0
        && c.cluster.eps < 1.0
        && c.cluster.min_pts > 0
        && c.cluster.eps_t.is_none_or(|t| t.is_finite() && t > 0.0)
}

#[cfg(test)]
mod tests;
