//! A device on the host: the firmware's protocol loop ([`evcal_core::wire::Device`], with
//! the firmware's capacities) on a thread, behind an in-memory pipe or a TCP socket.
//!
//! It runs every window through the same core and the same encoder as the firmware, and its
//! frames cross the same decoder, so what the host gets from it is what it would get from a
//! device; only the transport differs.

use super::Link;
use evcal_core::{
    detect::{Clock, DetectConfig},
    wire::{Device, DeviceOptions, Stats},
};
use std::{
    collections::VecDeque,
    io::{self, ErrorKind, Read, Write},
    net::{Shutdown, SocketAddr, TcpListener},
    sync::{Arc, Condvar, Mutex},
    thread::JoinHandle,
    time::{Duration, Instant},
};

/// Microseconds since the device started: the virtual device's stage clock.
struct Micros(Instant);

impl Clock for Micros {
    fn now(&mut self) -> u32 {
        self.0.elapsed().as_micros() as u32
    }
}

/// A running virtual device.
pub struct VirtualDevice {
    thread: JoinHandle<Stats>,
}

impl VirtualDevice {
    /// Starts a device with `config` that reads host frames from `reader` and writes its
    /// frames to `writer`, until `reader` ends or `writer` fails.
    pub fn spawn(
        config: DetectConfig,
        opts: DeviceOptions,
        reader: impl Read + Send + 'static,
        writer: impl Write + Send + 'static,
    ) -> Self {
        let thread = std::thread::Builder::new()
            .name("evcal-virtual-device".into())
            .spawn(move || serve(config, opts, reader, writer, None).0)
            .expect("spawning the virtual device's thread");
        Self { thread }
    }

    /// Waits for the device to stop (its input closed); its last counters.
    pub fn join(self) -> Stats {
        self.thread.join().unwrap_or_default()
    }
}

/// The options the virtual device runs with: the firmware's defaults, a microsecond clock.
pub fn options() -> DeviceOptions {
    DeviceOptions { clock_hz: 1_000_000, ..DeviceOptions::DEFAULT }
}

/// Why a host's session with the device ended.
#[derive(Debug)]
pub enum SessionEnd {
    /// The host closed the connection.
    Closed,
    /// The host sent nothing for the idle time-out, with nothing left for the device to do.
    Idle,
    /// Reading from or writing to the host failed (a host that stopped reading fails a write
    /// after the idle time-out).
    Failed(io::Error),
}

/// The firmware's main loop, on the host, until the host closes the input, a transfer fails,
/// or the device has waited `idle` for a byte with nothing to do (`reader` must time out
/// its reads to be heard).
fn serve(
    config: DetectConfig,
    opts: DeviceOptions,
    mut reader: impl Read,
    mut writer: impl Write,
    idle: Option<Duration>,
) -> (Stats, SessionEnd) {
    let mut dev: Box<Device> = Box::new(Device::new(config, opts));
    let mut clock = Micros(Instant::now());
    let mut buf = [0u8; 256];
    let (mut start, mut end) = (0usize, 0usize);
    let mut heard = Instant::now();
    loop {
        while let Some(frame) = dev.poll(&mut clock) {
            if let Err(e) = writer.write_all(frame) {
                return (dev.stats(), SessionEnd::Failed(e));
            }
        }
        if let Err(e) = writer.flush() {
            return (dev.stats(), SessionEnd::Failed(e));
        }
        if start == end {
            match reader.read(&mut buf) {
                Ok(0) => return (dev.stats(), SessionEnd::Closed),
                Ok(n) => {
                    (start, end) = (0, n);
                    heard = Instant::now();
                }
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) => {
                    if idle.is_some_and(|t| heard.elapsed() >= t) {
                        return (dev.stats(), SessionEnd::Idle);
                    }
                    continue;
                }
                Err(e) => return (dev.stats(), SessionEnd::Failed(e)),
            }
        }
        start += dev.receive(buf.get(start..end).unwrap_or(&[]));
    }
}

/// A link to a new in-process virtual device over in-memory pipes. `to_device` and
/// `to_host` wrap the two directions (for fault injection: [`super::fault::FrameTap`]);
/// pass [`std::convert::identity`]-like closures to leave them alone.
pub fn loopback<D, H>(
    config: DetectConfig,
    opts: DeviceOptions,
    to_device: impl FnOnce(PipeWriter) -> D,
    to_host: impl FnOnce(PipeWriter) -> H,
) -> (Link, VirtualDevice)
where
    D: Write + Send + 'static,
    H: Write + Send + 'static,
{
    let (host_w, dev_r) = pipe();
    let (dev_w, host_r) = pipe();
    let device = VirtualDevice::spawn(config, opts, dev_r, to_host(dev_w));
    (Link::new(host_r, to_device(host_w)), device)
}

/// What [`serve_tcp`] tells its caller, as it happens.
#[derive(Debug)]
pub enum DeviceEvent {
    /// A host connected and is served.
    Connected(SocketAddr),
    /// A host connected while `serving` was served, and its connection was closed at once.
    Busy {
        /// The host turned away.
        refused: SocketAddr,
        /// The host being served.
        serving: SocketAddr,
    },
    /// A host's session ended, and why.
    Ended(SocketAddr, SessionEnd),
}

/// How often a TCP session's device looks at the idle time-out while it waits for bytes.
const IDLE_POLL: Duration = Duration::from_millis(100);

/// Serves one TCP connection at a time, each with a fresh device (as a board reset between
/// sessions would give), until `accept` fails. A board has one serial line: a host that
/// connects while another is served is closed at once, before a byte, which the host's
/// `replay` reports as a busy device. A host that sends nothing for `idle` while the device
/// has nothing to do, or does not read what the device sends for as long, is dropped, so
/// that a silent or vanished host does not keep the device. `on` hears each of these.
pub fn serve_tcp(
    listener: &TcpListener,
    config: DetectConfig,
    idle: Duration,
    on: impl Fn(DeviceEvent) + Send + Sync + 'static,
) -> io::Result<()> {
    let on = Arc::new(on);
    // The host being served, if any; cleared by its session's thread as it ends.
    let serving: Arc<Mutex<Option<SocketAddr>>> = Arc::default();
    loop {
        let (stream, addr) = listener.accept()?;
        let busy_with = *serving.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(other) = busy_with {
            let _ = stream.shutdown(Shutdown::Both);
            on(DeviceEvent::Busy { refused: addr, serving: other });
            continue;
        }
        // A connection that fails its set-up already is the host's loss, not the device's end.
        let session = stream
            .set_nodelay(true)
            .and_then(|()| stream.set_read_timeout(Some(IDLE_POLL.min(idle).max(Duration::from_millis(1)))))
            .and_then(|()| stream.set_write_timeout(Some(idle.max(Duration::from_millis(1)))))
            .and_then(|()| stream.try_clone());
        let reader = match session {
            Ok(r) => r,
            Err(e) => {
                on(DeviceEvent::Ended(addr, SessionEnd::Failed(e)));
                continue;
            }
        };
        *serving.lock().unwrap_or_else(|p| p.into_inner()) = Some(addr);
        on(DeviceEvent::Connected(addr));
        let (on, serving) = (Arc::clone(&on), Arc::clone(&serving));
        let spawned = std::thread::Builder::new().name("evcal-virtual-device".into()).spawn(move || {
            let (_, end) = serve(config, options(), reader, stream, Some(idle));
            *serving.lock().unwrap_or_else(|p| p.into_inner()) = None;
            on(DeviceEvent::Ended(addr, end));
        });
        spawned?;
    }
}

#[derive(Default)]
struct PipeState {
    bytes: VecDeque<u8>,
    writer_gone: bool,
    reader_gone: bool,
}

#[derive(Default)]
struct Shared {
    state: Mutex<PipeState>,
    ready: Condvar,
}

/// The writing end of an in-memory byte pipe; dropping it ends the reader's input.
pub struct PipeWriter(Arc<Shared>);

/// The reading end of an in-memory byte pipe. Reads wait up to 200 ms, then time out
/// (as a serial port does), so that a reader thread can notice it is no longer wanted.
pub struct PipeReader(Arc<Shared>);

/// A one-way in-memory byte pipe, unbounded.
pub fn pipe() -> (PipeWriter, PipeReader) {
    let s = Arc::new(Shared::default());
    (PipeWriter(Arc::clone(&s)), PipeReader(s))
}

impl Write for PipeWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut st = self.0.state.lock().map_err(|_| io::Error::other("pipe poisoned"))?;
        if st.reader_gone {
            return Err(io::Error::new(ErrorKind::BrokenPipe, "the reading end is gone"));
        }
        st.bytes.extend(buf);
        self.0.ready.notify_all();
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Drop for PipeWriter {
    fn drop(&mut self) {
        if let Ok(mut st) = self.0.state.lock() {
            st.writer_gone = true;
        }
        self.0.ready.notify_all();
    }
}

impl Read for PipeReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let st = self.0.state.lock().map_err(|_| io::Error::other("pipe poisoned"))?;
        let (mut st, _) = self
            .0
            .ready
            .wait_timeout_while(st, Duration::from_millis(200), |s| s.bytes.is_empty() && !s.writer_gone)
            .map_err(|_| io::Error::other("pipe poisoned"))?;
        if st.bytes.is_empty() {
            return if st.writer_gone { Ok(0) } else { Err(ErrorKind::TimedOut.into()) };
        }
        let n = buf.len().min(st.bytes.len());
        for (d, s) in buf.iter_mut().zip(st.bytes.drain(..n)) {
            *d = s;
        }
        Ok(n)
    }
}

impl Drop for PipeReader {
    fn drop(&mut self) {
        if let Ok(mut st) = self.0.state.lock() {
            st.reader_gone = true;
        }
    }
}
