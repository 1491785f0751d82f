//! The host's side of the serial link to a device running the detection core.
//!
//! * [`Link`]: a byte transport (serial port, TCP socket such as QEMU's `-serial tcp:...`,
//!   or an in-memory pipe) with a reader thread that reassembles frames, resynchronises after
//!   damage, and hands over [`Incoming`] messages.
//! * [`replay`]: streams a recording into a device under its flow control and collects the
//!   detections (hardware-in-the-loop).
//! * [`collect`]: records the detections of a device that has its own sensor.
//! * [`virtual_device`]: the firmware's protocol loop running on the host, for tests, for
//!   `evcal demo` and `evcal device`.
//! * [`fault`]: damages frames on their way, to test that only damaged frames are lost.
//!
//! The wire format itself is [`evcal_core::wire`].

pub mod collect;
pub mod fault;
pub mod replay;
pub mod virtual_device;

use crate::input::detections::WindowRecord;
use evcal_core::wire::{self, DeviceMessage, Feed, FrameAccumulator, Hello, Stats};
use std::{
    io::{ErrorKind, Read, Write},
    net::{TcpStream, ToSocketAddrs},
    sync::{
        atomic::{AtomicBool, AtomicU64, Ordering},
        mpsc::{self, Receiver, RecvTimeoutError},
        Arc,
    },
    time::{Duration, Instant},
};

/// Why the link to a device, or a session over it, failed. The messages name what was being
/// done; the system's error, where there is one, is the [`source`](std::error::Error::source).
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// A `--port` that names no transport evcal has.
    #[error("{0}")]
    Port(String),
    /// The transport failed.
    #[error("{what}")]
    Io {
        /// What was being done.
        what: String,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// A serial port could not be opened or shared with the reader thread.
    #[error("{what}")]
    Serial {
        /// What was being done.
        what: String,
        /// The serial port library's error.
        #[source]
        source: serialport::Error,
    },
    /// The device broke the protocol, refused the configuration, restarted or stopped
    /// answering, or the link closed.
    #[error("{0}")]
    Device(String),
    /// A frame could not be encoded (a value out of the wire format's range).
    #[error("encoding a frame: {0}")]
    Encode(wire::Error),
    /// Stopped by the caller (Ctrl-C) before the link was open.
    #[error("interrupted")]
    Interrupted,
}

impl From<wire::Error> for LinkError {
    fn from(e: wire::Error) -> Self {
        Self::Encode(e)
    }
}

/// Returns a [`LinkError::Device`] with a formatted message.
macro_rules! refuse {
    ($($arg:tt)*) => {
        return Err($crate::input::link::LinkError::Device(format!($($arg)*)))
    };
}
pub(crate) use refuse;

/// The link's results.
pub type Result<T, E = LinkError> = std::result::Result<T, E>;

/// An I/O error while doing `what`.
fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> LinkError {
    let what = what.into();
    move |source| LinkError::Io { what, source }
}

/// Largest frame the host accepts from a device (a detection of 96 centres is under 2 KiB).
pub const HOST_RX_FRAME: usize = 16 * 1024;

/// Where the device is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Port {
    /// A TCP endpoint, `tcp:HOST:PORT` (QEMU's `-serial tcp:HOST:PORT,server=on`).
    Tcp(String),
    /// A serial device such as `/dev/ttyACM0`.
    Serial(String),
}

impl Port {
    /// Parses `tcp:HOST:PORT` or a serial device path.
    pub fn parse(s: &str) -> Result<Self> {
        if let Some(addr) = s.strip_prefix("tcp:") {
            if addr.rsplit_once(':').is_none_or(|(h, p)| h.is_empty() || p.parse::<u16>().is_err()) {
                return Err(LinkError::Port(format!("--port {s}: expected tcp:HOST:PORT, e.g. tcp:127.0.0.1:7878")));
            }
            Ok(Self::Tcp(addr.to_string()))
        } else if s.is_empty() {
            Err(LinkError::Port("--port is empty: give a serial device (e.g. /dev/ttyACM0) or tcp:HOST:PORT".into()))
        } else {
            Ok(Self::Serial(s.to_string()))
        }
    }
}

/// What the reader thread hands over.
#[derive(Debug, Clone, PartialEq)]
pub enum Incoming {
    /// The device introduced itself.
    Hello(Hello),
    /// One window's detections (centres already in the host's record form).
    Window(WindowRecord),
    /// The device's counters.
    Stats(Stats),
    /// Flow control.
    Ack(wire::Ack),
    /// A frame was damaged, foreign or too long, and dropped.
    Bad(wire::Error),
    /// The link closed (end of file, or an error, described).
    Closed(Option<String>),
}

/// Byte counts of a link, shared with its reader thread.
#[derive(Debug, Default)]
pub struct Traffic {
    /// Bytes written to the device.
    pub sent: AtomicU64,
    /// Bytes read from the device.
    pub received: AtomicU64,
    /// The link was dropped: the reader thread stops at its next read time-out.
    dropped: AtomicBool,
}

/// A link to a device: a writer, and a reader thread turning bytes into [`Incoming`].
pub struct Link {
    rx: Receiver<Incoming>,
    tx: Box<dyn Write + Send>,
    traffic: Arc<Traffic>,
}

impl Link {
    /// A link over any byte transport. The reader thread ends when the transport closes or
    /// fails, or (at its next read time-out) when the link is dropped.
    pub fn new(reader: impl Read + Send + 'static, writer: impl Write + Send + 'static) -> Self {
        let (send, rx) = mpsc::channel();
        let traffic = Arc::new(Traffic::default());
        let t = Arc::clone(&traffic);
        std::thread::Builder::new()
            .name("evcal-link-reader".into())
            .spawn(move || read_frames(reader, &t, |m| send.send(m).is_ok()))
            .expect("spawning the link's reader thread");
        Self { rx, tx: Box::new(writer), traffic }
    }

    /// Opens a serial port (at `baud`) or a TCP endpoint (retrying a refused connection for
    /// up to `connect_timeout`: QEMU may still be starting). [`LinkError::Interrupted`] if
    /// `stop` is set while connecting: it is heard within [`STOP_POLL`].
    pub fn open(port: &Port, baud: u32, connect_timeout: Duration, stop: &AtomicBool) -> Result<Self> {
        match port {
            Port::Tcp(addr) => {
                let stream = connect_tcp(addr, connect_timeout, stop)?;
                // QEMU answers in ~3.5 ms per round trip with Nagle off, ~47 ms with it on.
                stream.set_nodelay(true).map_err(io("setting TCP_NODELAY"))?;
                stream.set_read_timeout(Some(Duration::from_millis(200))).map_err(io("setting a read time-out"))?;
                let reader = stream.try_clone().map_err(io("cloning the TCP stream"))?;
                Ok(Self::new(reader, stream))
            }
            Port::Serial(path) => {
                let port =
                    serialport::new(path, baud).timeout(Duration::from_millis(200)).open().map_err(|source| {
                        LinkError::Serial { what: format!("cannot open serial port {path} at {baud} baud"), source }
                    })?;
                let reader = port
                    .try_clone()
                    .map_err(|source| LinkError::Serial { what: format!("cannot clone serial port {path}"), source })?;
                Ok(Self::new(reader, port))
            }
        }
    }

    /// Writes one whole frame.
    pub fn send(&mut self, frame: &[u8]) -> Result<()> {
        self.tx.write_all(frame).map_err(io("writing to the device"))?;
        self.tx.flush().map_err(io("writing to the device"))?;
        self.traffic.sent.fetch_add(frame.len() as u64, Ordering::Relaxed);
        Ok(())
    }

    /// The next message, waiting at most `timeout`; `None` on time-out.
    pub fn recv(&self, timeout: Duration) -> Option<Incoming> {
        match self.rx.recv_timeout(timeout) {
            Ok(m) => Some(m),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => Some(Incoming::Closed(None)),
        }
    }

    /// Bytes sent and received so far.
    pub fn traffic(&self) -> (u64, u64) {
        (self.traffic.sent.load(Ordering::Relaxed), self.traffic.received.load(Ordering::Relaxed))
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        self.traffic.dropped.store(true, Ordering::Relaxed);
    }
}

/// How often a wait that the caller may stop looks at the stop flag.
pub const STOP_POLL: Duration = Duration::from_millis(50);
/// The longest one attempt to connect to one address takes (an address that drops packets);
/// a refused connection fails at once.
const CONNECT_ATTEMPT: Duration = Duration::from_secs(2);
/// The pause between rounds of attempts.
const CONNECT_PAUSE: Duration = Duration::from_millis(100);

/// Connects to `addr`, retrying for up to `timeout`, until `stop` is set.
fn connect_tcp(addr: &str, timeout: Duration, stop: &AtomicBool) -> Result<TcpStream> {
    let started = Instant::now();
    loop {
        let e = match attempt_connect(addr, stop)? {
            Ok(s) => return Ok(s),
            Err(e) => e,
        };
        if started.elapsed() >= timeout {
            return Err(LinkError::Device(format!(
                "cannot connect to tcp:{addr} within {:.1} s: {e}",
                timeout.as_secs_f64()
            )));
        }
        let paused = Instant::now();
        while paused.elapsed() < CONNECT_PAUSE {
            if stop.load(Ordering::Relaxed) {
                return Err(LinkError::Interrupted);
            }
            std::thread::sleep(STOP_POLL.min(CONNECT_PAUSE));
        }
    }
}

/// One round of attempts at each of `addr`'s addresses: the stream, or why none connected
/// (a name that does not resolve is an error at once). On a thread of its own, so that
/// `stop` is heard while a name resolves or a connection hangs: the thread is left to end
/// by itself (within [`CONNECT_ATTEMPT`] per address).
fn attempt_connect(addr: &str, stop: &AtomicBool) -> Result<Result<TcpStream, String>> {
    let (send, done) = mpsc::channel();
    let target = addr.to_string();
    std::thread::Builder::new()
        .name("evcal-connect".into())
        .spawn(move || {
            let r = target.to_socket_addrs().map(|addrs| {
                let mut last = None;
                for a in addrs {
                    match TcpStream::connect_timeout(&a, CONNECT_ATTEMPT) {
                        Ok(s) => return Ok(s),
                        Err(e) => last = Some(e.to_string()),
                    }
                }
                Err(last.unwrap_or_else(|| "no address".into()))
            });
            let _ = send.send(r);
        })
        .map_err(io("starting a thread to connect"))?;
    loop {
        if stop.load(Ordering::Relaxed) {
            return Err(LinkError::Interrupted);
        }
        match done.recv_timeout(STOP_POLL) {
            Ok(r) => return r.map_err(io(format!("cannot resolve {addr}"))),
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                return Ok(Err("the thread connecting ended without a result".into()))
            }
        }
    }
}

/// Reads frames until the transport closes or `deliver` returns false.
fn read_frames(mut reader: impl Read, traffic: &Traffic, mut deliver: impl FnMut(Incoming) -> bool) {
    let mut acc: Box<FrameAccumulator<HOST_RX_FRAME>> = Box::new(FrameAccumulator::new());
    let mut buf = vec![0u8; 4096];
    // The sensor of the device's latest Hello, written with each window's detections.
    let mut sensor = None;
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => {
                deliver(Incoming::Closed(None));
                return;
            }
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) => {
                if traffic.dropped.load(Ordering::Relaxed) {
                    return;
                }
                continue;
            }
            Err(e) => {
                deliver(Incoming::Closed(Some(e.to_string())));
                return;
            }
        };
        traffic.received.fetch_add(n as u64, Ordering::Relaxed);
        let mut input = buf.get(..n).unwrap_or(&[]);
        loop {
            let m = match acc.feed(input) {
                Feed::Consumed => break,
                Feed::Frame { payload, rest } => {
                    input = rest;
                    match DeviceMessage::parse(payload) {
                        Ok(DeviceMessage::Hello(h)) => {
                            sensor = Some(h.config.sensor);
                            Incoming::Hello(h)
                        }
                        Ok(DeviceMessage::Detection(d)) => {
                            let w = WindowRecord::from_frame(&d);
                            Incoming::Window(match sensor {
                                Some(s) => w.with_sensor(s),
                                None => w,
                            })
                        }
                        Ok(DeviceMessage::Stats(s)) => Incoming::Stats(s),
                        Ok(DeviceMessage::Ack(a)) => Incoming::Ack(a),
                        Err(e) => Incoming::Bad(e),
                    }
                }
                Feed::Error { error, rest } => {
                    input = rest;
                    Incoming::Bad(error)
                }
            };
            if !deliver(m) {
                return;
            }
        }
    }
}

/// What a long-running link operation reports as it goes.
#[derive(Debug)]
pub enum Progress<'a, R> {
    /// A window's detections arrived (in order of arrival).
    Window(&'a WindowRecord),
    /// The counts so far (a few times a second).
    Status(&'a R),
}

/// Follows window sequence numbers to count windows lost on the way.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WindowSeq {
    next: Option<u32>,
}

/// What one window's sequence number says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seen {
    /// The window after the last one (or the first).
    InOrder,
    /// Windows before this one never arrived.
    AfterLoss(u32),
    /// The sequence went back: the device started a new stream.
    Restart,
}

impl WindowSeq {
    /// Expecting window `first` next (a replay session starts at 0), so that losing the
    /// very first windows is counted too.
    pub const fn starting_at(first: u32) -> Self {
        Self { next: Some(first) }
    }

    /// Notes window `seq`.
    pub fn see(&mut self, seq: u32) -> Seen {
        let seen = match self.next {
            None => Seen::InOrder,
            Some(n) if seq == n => Seen::InOrder,
            Some(n) if seq > n => Seen::AfterLoss(seq - n),
            Some(_) => Seen::Restart,
        };
        self.next = Some(seq.wrapping_add(1));
        seen
    }

    /// Windows seen up to now, as the device numbers them (one past the last sequence number).
    pub fn expected(&self) -> u32 {
        self.next.unwrap_or(0)
    }
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn ports_parse_and_explain_mistakes() {
        assert_eq!(Port::parse("tcp:127.0.0.1:7878").unwrap(), Port::Tcp("127.0.0.1:7878".into()));
        assert_eq!(Port::parse("tcp:localhost:1").unwrap(), Port::Tcp("localhost:1".into()));
        assert_eq!(Port::parse("/dev/ttyACM0").unwrap(), Port::Serial("/dev/ttyACM0".into()));
        for bad in ["tcp:", "tcp:host", "tcp::80", "tcp:host:99999", ""] {
            let e = Port::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--port"), "{bad}: {e}");
        }
    }

    #[test]
    fn window_numbers_show_losses_and_restarts() {
        let mut s = WindowSeq::starting_at(0);
        assert_eq!(s.see(0), Seen::InOrder);
        assert_eq!(s.see(3), Seen::AfterLoss(2));
        assert_eq!(s.see(4), Seen::InOrder);
        assert_eq!(s.see(1), Seen::Restart);
        assert_eq!(s.expected(), 2);
        let mut late = WindowSeq::default();
        assert_eq!(late.see(17), Seen::InOrder, "listening mid-stream loses nothing");
        assert_eq!(WindowSeq::starting_at(0).see(2), Seen::AfterLoss(2));
    }

    #[test]
    fn reader_resyncs_after_garbage_and_counts_it() {
        use evcal_core::wire::Ack;
        let mut stream = b"boot banner from a foreign program\r\n".to_vec();
        stream.push(0);
        let mut f = [0u8; 32];
        let n = Ack { next: 3, window: 2, nak: false }.emit(&mut f).unwrap();
        stream.extend(&f[..n]);
        let traffic = Traffic::default();
        let mut got = Vec::new();
        read_frames(&stream[..], &traffic, |m| {
            got.push(m);
            true
        });
        assert_eq!(got.len(), 3, "{got:?}");
        assert!(matches!(got[0], Incoming::Bad(_)));
        assert_eq!(got[1], Incoming::Ack(Ack { next: 3, window: 2, nak: false }));
        assert_eq!(got[2], Incoming::Closed(None));
        assert_eq!(traffic.received.load(Ordering::Relaxed), stream.len() as u64);
    }

    #[test]
    fn connecting_stops_when_asked_while_retrying() {
        // A port nobody listens on: every attempt is refused, and the retries would go on
        // for a minute.
        let closed = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
        let port = Port::Tcp(closed.to_string());
        let stop = Arc::new(AtomicBool::new(false));
        let s = Arc::clone(&stop);
        let setter = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            s.store(true, Ordering::Relaxed);
        });
        let started = Instant::now();
        let r = Link::open(&port, 0, Duration::from_secs(60), &stop);
        setter.join().unwrap();
        assert!(matches!(r, Err(LinkError::Interrupted)), "{:?}", r.err());
        let took = started.elapsed();
        assert!(took < Duration::from_millis(600), "{took:?}");
        // Not asked to stop: the time-out, with the reason.
        let e = Link::open(&port, 0, Duration::from_millis(200), &AtomicBool::new(false)).err().unwrap();
        assert!(e.to_string().contains("cannot connect") && e.to_string().contains("within 0.2 s"), "{e}");
    }
}
