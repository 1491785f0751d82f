//! The host's side of the serial link to the firmware under QEMU, for the end-to-end tests:
//! boot the image with its UART on a TCP socket, replay events with the wire protocol
//! (go-back-N with the device's credit), collect what comes back, and optionally damage
//! the bytes on the way in either direction.

use crate::firmware::workspace_root;
use anyhow::{bail, ensure, Context, Result};
use evcal_core::{
    detect::{DetectConfig, Detector},
    event::Event,
    wire::{
        emit_core_detection, emit_events, events_that_fit, Ack, Config, DeviceMessage, End, Feed, FrameAccumulator,
        Hello, HelloReply, Stats,
    },
};
use evcal_host::input::detections::{HostDetector, WindowRecord};
use std::{
    collections::BTreeSet,
    io::{ErrorKind, Read, Write},
    net::{TcpListener, TcpStream},
    path::Path,
    process::{Child, Command, Stdio},
    time::{Duration, Instant},
};

/// QEMU running the firmware with its UART on a TCP socket; killed when dropped.
pub struct Qemu {
    child: Child,
    /// The UART, connected.
    pub stream: TcpStream,
}

impl Qemu {
    /// Boots `elf` (with QEMU's `-append` text `append`, if any) and connects to its UART.
    pub fn boot(elf: &Path, append: Option<&str>, timeout_s: u32) -> Result<Self> {
        // A free port: the OS picks one, QEMU takes it over.
        let port = TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
        let mut cmd = Command::new("bash");
        cmd.arg(workspace_root().join("scripts/qemu-run.sh")).arg(elf);
        if let Some(a) = append {
            cmd.args(["-append", a]);
        }
        cmd.env("EVCAL_QEMU_SERIAL", format!("tcp:127.0.0.1:{port},server=on,wait=on,nodelay=on"))
            .env("EVCAL_QEMU_TIMEOUT", timeout_s.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null());
        let mut child = cmd.spawn().context("starting QEMU (scripts/qemu-run.sh)")?;
        let t = Instant::now();
        let stream = loop {
            match TcpStream::connect(("127.0.0.1", port)) {
                Ok(s) => break s,
                Err(_) if t.elapsed() < Duration::from_secs(20) => {
                    if let Some(status) = child.try_wait()? {
                        bail!("QEMU ended before listening ({status})");
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(e) => {
                    let _ = child.kill();
                    return Err(e).context("connecting to QEMU's UART");
                }
            }
        };
        // QEMU.md: 3.5 ms per round trip with TCP_NODELAY on both ends, 47 ms without.
        stream.set_nodelay(true)?;
        Ok(Self { child, stream })
    }
}

impl Drop for Qemu {
    /// Stops QEMU: SIGTERM to the `timeout` wrapping it, which passes it on (a SIGKILL would
    /// stop the wrapper and leave QEMU running); SIGKILL if that did not end it in 5 s.
    fn drop(&mut self) {
        let _ = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).status();
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(5) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Damage done to the bytes of chosen frames, on their first passage only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damage {
    /// One bit of a byte in the frame's middle is flipped.
    FlipBit,
    /// A byte in the frame's middle is dropped.
    DropByte,
    /// A stray nonzero byte is inserted in the frame's middle.
    InsertByte,
}

impl Damage {
    /// `frame` (delimiters included) as it arrives after this damage.
    pub fn apply(self, frame: &[u8]) -> Vec<u8> {
        let mut f = frame.to_vec();
        let mid = f.len() / 2;
        match self {
            // A flip that cannot make a delimiter (a zero byte) out of a stuffed one.
            Self::FlipBit => f[mid] ^= if f[mid] == 0x04 { 0x08 } else { 0x04 },
            Self::DropByte => {
                f.remove(mid);
            }
            Self::InsertByte => f.insert(mid, 0x5A),
        }
        f
    }
}

/// What a replay got back from the device.
#[derive(Debug, Default)]
pub struct Replay {
    /// The detection frames received intact, whole (delimiters included), by window number.
    pub detections: Vec<(u32, Vec<u8>)>,
    /// The same detections as `evcal replay` writes them: one JSON line each, newline
    /// included.
    pub jsonl: String,
    /// Hellos received.
    pub hellos: Vec<Hello>,
    /// The device's final statistics (sent after the host's End).
    pub final_stats: Option<Stats>,
    /// Frames from the device that arrived damaged and were dropped by the host's reader.
    pub bad_frames: u32,
    /// Event-batch frames sent, first transmissions and repeats.
    pub frames_sent: u32,
    /// Bytes sent to the device, and received from it.
    pub bytes_out: u64,
    /// Bytes received from the device.
    pub bytes_in: u64,
    /// Detection frames' bytes (delimiters included).
    pub detection_bytes: u64,
}

impl Replay {
    /// Window numbers missing from the detections received, below the highest received.
    pub fn gaps(&self) -> BTreeSet<u32> {
        let got: BTreeSet<u32> = self.detections.iter().map(|(s, _)| *s).collect();
        let top = got.iter().next_back().copied().unwrap_or(0);
        (0..top).filter(|s| !got.contains(s)).collect()
    }
}

/// What to damage on the way.
#[derive(Debug, Default, Clone)]
pub struct Tamper {
    /// Device → host: detection frames of these windows, damaged once.
    pub detections: Vec<(u32, Damage)>,
    /// Host → device: these sequenced frames (event batches), damaged on their first
    /// transmission (repeats go through intact).
    pub batches: Vec<(u32, Damage)>,
}

/// Reads the device's frames from the socket, applying the device → host damage.
struct Reader {
    stream: TcpStream,
    /// Raw bytes of the frame being received (before damage).
    raw: Vec<u8>,
    acc: FrameAccumulator<8192>,
    tamper: Vec<(u32, Damage)>,
    bytes_in: u64,
}

/// One frame from the device.
enum Incoming {
    Frame { payload: Vec<u8>, whole: Vec<u8> },
    Bad,
}

impl Reader {
    /// The frames completed by the bytes available within `wait`.
    fn read(&mut self, wait: Duration) -> Result<Vec<Incoming>> {
        self.stream.set_read_timeout(Some(wait))?;
        let mut buf = [0u8; 4096];
        let n = match self.stream.read(&mut buf) {
            Ok(0) => bail!("the device closed the link"),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => return Ok(Vec::new()),
            Err(e) => return Err(e.into()),
        };
        self.bytes_in += n as u64;
        let mut out = Vec::new();
        for &b in &buf[..n] {
            self.raw.push(b);
            if b != 0 || self.raw.len() == 1 {
                continue;
            }
            // A whole frame from its opening to its closing delimiter.
            let whole = std::mem::replace(&mut self.raw, vec![0]);
            let wire = match self.damage_for(&whole) {
                Some(d) => d.apply(&whole),
                None => whole.clone(),
            };
            let mut input = &wire[..];
            while !input.is_empty() {
                match self.acc.feed(input) {
                    Feed::Consumed => break,
                    Feed::Frame { payload, rest } => {
                        out.push(Incoming::Frame { payload: payload.to_vec(), whole: whole.clone() });
                        input = rest;
                    }
                    Feed::Error { rest, .. } => {
                        out.push(Incoming::Bad);
                        input = rest;
                    }
                }
            }
        }
        Ok(out)
    }

    /// The damage planned for this frame, if it is a detection of a window to damage (decided
    /// on the intact bytes; the damage is then done to the bytes the reader sees).
    fn damage_for(&mut self, whole: &[u8]) -> Option<Damage> {
        let mut probe: FrameAccumulator<8192> = FrameAccumulator::new();
        let Feed::Frame { payload, .. } = probe.feed(whole) else { return None };
        let Ok(DeviceMessage::Detection(d)) = DeviceMessage::parse(payload) else { return None };
        let i = self.tamper.iter().position(|(s, _)| *s == d.header.seq)?;
        Some(self.tamper.remove(i).1)
    }
}

fn encode(f: impl FnOnce(&mut [u8]) -> evcal_core::wire::Result<usize>) -> Result<Vec<u8>> {
    let mut out = vec![0u8; 1 << 16];
    let n = f(&mut out).map_err(|e| anyhow::anyhow!("encoding a frame: {e}"))?;
    out.truncate(n);
    Ok(out)
}

/// Replays `events` into the device on `qemu`'s UART with configuration `cfg` (session 1),
/// then ends the stream; returns what came back. With `events` empty the device is expected
/// to have a local source (the emulator's `replay FILE` mode): the host then only configures
/// the session and ends it; the device reads the End only once its source is drained.
pub fn replay(qemu: &mut Qemu, cfg: DetectConfig, events: &[Event], tamper: Tamper, limit: Duration) -> Result<Replay> {
    let started = Instant::now();
    let mut out = Replay::default();
    let mut reader = Reader {
        stream: qemu.stream.try_clone()?,
        raw: Vec::new(),
        acc: FrameAccumulator::new(),
        tamper: tamper.detections.clone(),
        bytes_in: 0,
    };
    let mut w = qemu.stream.try_clone()?;
    let mut send = |bytes: &[u8], out: &mut Replay| -> Result<()> {
        out.bytes_out += bytes.len() as u64;
        w.write_all(bytes).context("writing to the device")
    };

    // 1. Nothing before the device's Hello.
    let boot = wait_hello(&mut reader, &mut out, |h| h.reply == HelloReply::Boot, Duration::from_secs(20))?;
    // 2. The session's configuration, repeated until applied.
    let config = encode(|o| Config { session: 1, config: cfg }.emit(o))?;
    let applied = loop {
        send(&config, &mut out)?;
        if let Ok(h) = wait_hello(&mut reader, &mut out, |h| h.session == 1, Duration::from_secs(2)) {
            break h;
        }
        ensure!(started.elapsed() < limit, "no Hello for the Config");
    };
    ensure!(applied.reply == HelloReply::Applied, "the device refused the configuration: {applied:?}");
    let max_frame = usize::from(boot.max_frame);

    // 3. Batches, then End, go-back-N within the device's credit.
    let mut frames: Vec<Vec<u8>> = Vec::new();
    let mut rest = events;
    while !rest.is_empty() {
        let seq = frames.len() as u32;
        let n = events_that_fit(seq, rest, max_frame);
        ensure!(n > 0, "an event does not fit in a frame of {max_frame} bytes");
        frames.push(encode(|o| emit_events(seq, &rest[..n], o))?);
        rest = &rest[n..];
    }
    let end_seq = frames.len() as u32;
    frames.push(encode(|o| End { seq: end_seq }.emit(o))?);
    let mut to_damage = tamper.batches.clone();
    let (mut acked, mut next, mut credit) = (0u32, 0u32, u32::from(applied.window.max(1)));
    let mut last_progress = Instant::now();
    while out.final_stats.is_none() {
        ensure!(started.elapsed() < limit, "replay took longer than {limit:?}: {} detections", out.detections.len());
        while next < acked + credit && (next as usize) < frames.len() {
            let f = &frames[next as usize];
            match to_damage.iter().position(|(s, _)| *s == next) {
                Some(i) => send(&to_damage.remove(i).1.apply(f), &mut out)?,
                None => send(f, &mut out)?,
            }
            out.frames_sent += 1;
            next += 1;
        }
        for m in reader.read(Duration::from_millis(200))? {
            let Incoming::Frame { payload, whole } = m else {
                out.bad_frames += 1;
                continue;
            };
            match DeviceMessage::parse(&payload) {
                Ok(DeviceMessage::Detection(d)) => {
                    out.detection_bytes += whole.len() as u64;
                    // As `evcal replay` writes it: with the sensor of the device's Hello.
                    let w = WindowRecord::from_frame(&d);
                    let w = match out.hellos.last() {
                        Some(h) => w.with_sensor(h.config.sensor),
                        None => w,
                    };
                    out.jsonl.push_str(&w.to_json_line());
                    out.jsonl.push('\n');
                    out.detections.push((d.header.seq, whole));
                }
                Ok(DeviceMessage::Ack(Ack { next: n, window, nak })) => {
                    if n > acked {
                        last_progress = Instant::now();
                    }
                    acked = acked.max(n);
                    credit = u32::from(window.max(1));
                    if nak {
                        next = acked;
                    }
                }
                Ok(DeviceMessage::Stats(s)) if s.end_of_stream => out.final_stats = Some(s),
                Ok(DeviceMessage::Stats(_)) => {}
                Ok(DeviceMessage::Hello(h)) => out.hellos.push(h),
                Err(e) => bail!("an intact frame that does not parse: {e}"),
            }
        }
        // A lost Ack or NAK: go back after a silence.
        if next > acked && last_progress.elapsed() > Duration::from_secs(2) {
            next = acked;
            last_progress = Instant::now();
        }
    }
    out.bytes_in = reader.bytes_in;
    Ok(out)
}

fn wait_hello(reader: &mut Reader, out: &mut Replay, want: impl Fn(&Hello) -> bool, wait: Duration) -> Result<Hello> {
    let t = Instant::now();
    while t.elapsed() < wait {
        for m in reader.read(Duration::from_millis(100))? {
            match m {
                Incoming::Frame { payload, .. } => {
                    if let Ok(DeviceMessage::Hello(h)) = DeviceMessage::parse(&payload) {
                        out.hellos.push(h);
                        if want(&h) {
                            return Ok(h);
                        }
                    }
                }
                Incoming::Bad => out.bad_frames += 1,
            }
        }
    }
    bail!("no Hello within {wait:?}")
}

/// The detection frames the host's run of the core gives for `events` (what the device
/// must send, byte for byte), by window number.
pub fn expected_frames(events: &[Event], cfg: DetectConfig) -> Result<Vec<(u32, Vec<u8>)>> {
    let mut det: Box<HostDetector> = Box::new(Detector::new(cfg));
    let mut out = Vec::new();
    for e in events {
        if let Some(d) = det.push(*e) {
            out.push((d.info.seq, encode(|o| emit_core_detection(d, o))?));
        }
    }
    // The events the input filter still holds at the end, as the device's End does.
    while let Some(d) = det.end() {
        out.push((d.info.seq, encode(|o| emit_core_detection(d, o))?));
    }
    Ok(out)
}
