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
//! [`MAX_HELD_EVENTS`](crate::event::MAX_HELD_EVENTS) events, 600 bytes, plus `RX + TX`). Give it a `static` home, and build it at
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
    config::{MAX_CLUSTERS, MAX_EVENTS_PER_WINDOW},
    detect::{Clock, DetectConfig, Detector},
    event::Event,
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
/// (at least [`detection_frame_max`]`(C)`, checked at compile time).
pub struct Device<
    const N: usize = MAX_EVENTS_PER_WINDOW,
    const C: usize = MAX_CLUSTERS,
    const RX: usize = RX_FRAME,
    const TX: usize = TX_FRAME,
> {
    det: Detector<N, C>,
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

impl<const N: usize, const C: usize, const RX: usize, const TX: usize> Device<N, C, RX, TX> {
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

    /// Counts events the device's own source lost (a full FIFO), for [`Stats::events_dropped`].
    pub fn count_dropped_events(&mut self, n: u64) {
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
mod test {
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
}
