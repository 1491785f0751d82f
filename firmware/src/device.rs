//! What the firmware does once the board is up.
//!
//! * The protocol over the UART (the default, and all a real board does): the core's
//!   [`wire::Device`](evcal_core::wire::Device) state machine, fed the bytes the UART
//!   receives, its frames written back. The host replays a recording in event batches (flow
//!   controlled: the device acknowledges and grants credit), or a device with its own sensor
//!   streams detections.
//! * Emulator only, chosen by QEMU's `-append`:
//!   - `replay FILE`: the protocol as above, but once the host has configured a session the
//!     events come from a bulk file on the host (semihosting) instead of event batches, for
//!     replays longer than QEMU's UART carries in reasonable time;
//!   - `bench FILE [EVENTS [STEP_US]]`: the benchmark replay of `crate::bench`;
//!   - `sensor`: the sensor's bring-up (reset, then which addresses answer on its bus),
//!     printed; for the test of the board's I2C driver;
//!   - `fault`, `panic`: for the test that both end QEMU with a failure status.
//!
//! In the protocol the sensor is brought up first (reset, bus scanned; logged), the hook a
//! sensor-fed device starts from.

use crate::{
    board::{self, Board, CycleDelay, WaitForByte},
    markers::MarkedClock,
    role::{protocol_device, FwDevice},
};
use embedded_hal::{digital::OutputPin, i2c::I2c};
use embedded_hal_nb::{nb, serial};
use evcal_core::detect::Clock;
use evcal_firmware::{
    runner::READ_BATCH,
    sensor::{AddressSet, ResetTiming, SensorControl},
    source::{EventSource, SourceError},
};

/// Runs the firmware; `true` if it ended cleanly (the protocol runs until reset).
pub fn run<B: Board>(mut board: B) -> bool {
    #[cfg(emulated)]
    {
        let mut buf = [0u8; crate::hostfs::CMDLINE_MAX];
        let cmd = crate::hostfs::cmdline(&mut buf);
        if let Some(args) = cmd.strip_prefix("bench") {
            return crate::bench::run(&mut board, args);
        }
        if cmd == "sensor" {
            return report_sensor(&mut board);
        }
        if let Some(path) = cmd.strip_prefix("replay ") {
            return match crate::hostfs::HostFile::open(path.trim()).map(evcal_firmware::bulk::BulkSource::open) {
                Some(Ok(src)) => protocol(&mut board, Some(src)),
                Some(Err(e)) => {
                    board::report(format_args!("evcal firmware: {}: {e}", path.trim()));
                    false
                }
                None => {
                    board::report(format_args!("evcal firmware: cannot open {}", path.trim()));
                    false
                }
            };
        }
        if cmd == "fault" {
            cortex_m::asm::udf();
        }
        if cmd == "panic" {
            panic!("as the command line asked");
        }
        if !cmd.is_empty() {
            board::report(format_args!(
                "evcal firmware: unknown command line {cmd:?}; expected none, `replay FILE`, `bench FILE [EVENTS [STEP_US]]`, `sensor`, `fault` or `panic`"
            ));
            return false;
        }
    }
    protocol(&mut board, None::<evcal_firmware::source::SliceSource<'static>>)
}

/// Resets the sensor and finds which addresses answer on its bus: the bring-up a
/// sensor-fed device starts from (see `evcal_firmware::sensor`). `None` if the board's
/// sensor lines were taken already or could not be driven.
fn bring_up_sensor<B: Board>(board: &mut B) -> Option<AddressSet> {
    let (reset, bus) = board.take_sensor()?;
    bring_up(reset, bus)
}

fn bring_up<P: OutputPin, I: I2c>(reset: P, bus: I) -> Option<AddressSet> {
    let mut sensor = SensorControl::new(reset, bus);
    sensor.reset(&mut CycleDelay, ResetTiming::default()).ok()?;
    sensor.scan().ok()
}

/// Emulator only (`-append sensor`): the sensor's bring-up, its answer on standard output
/// (`sensor bus: ADDR ...` in hex, or `sensor bus: none`); `true` if it ran.
#[cfg(emulated)]
fn report_sensor<B: Board>(board: &mut B) -> bool {
    use core::fmt::Write;
    let Some(found) = bring_up_sensor(board) else {
        board::report(format_args!("evcal firmware: the sensor's lines could not be driven"));
        return false;
    };
    let Ok(mut out) = cortex_m_semihosting::hio::hstdout() else { return false };
    let mut ok = out.write_str("sensor bus:").is_ok();
    for a in found.iter() {
        ok &= write!(out, " {a:#04x}").is_ok();
    }
    if found.is_empty() {
        ok &= out.write_str(" none").is_ok();
    }
    ok && out.write_str("\n").is_ok()
}

/// Bytes taken from the UART at a time.
const RX_CHUNK: usize = 64;

/// Writes a frame whole, waiting for the transmitter as it goes.
fn send<S: serial::Write<u8>>(serial: &mut S, frame: &[u8]) {
    for &b in frame {
        // A transmitter that fails loses the frame; the host's reader notices the damage.
        let _ = nb::block!(serial.write(b));
    }
}

/// Fills the front of `buf` with received bytes: waits (the port's way) for the first, then
/// takes those that have arrived, up to `buf.len()`. A receive error (overrun, framing,
/// noise) is a byte lost, counted in `dev`'s stats.
fn receive<S>(serial: &mut S, buf: &mut [u8], dev: &mut FwDevice) -> usize
where
    S: serial::Read<u8> + WaitForByte,
{
    let mut n = 0;
    while n < buf.len() {
        match serial.read() {
            Ok(b) => {
                buf[n] = b;
                n += 1;
            }
            Err(nb::Error::WouldBlock) if n > 0 => break,
            Err(nb::Error::WouldBlock) => serial.wait_for_byte(),
            Err(nb::Error::Other(_)) => dev.count_rx_overrun(1),
        }
    }
    n
}

/// The protocol over the UART. With `local`, events come from it (once a host has started a
/// session) rather than from the host's event batches.
fn protocol<B: Board>(board: &mut B, mut local: Option<impl EventSource>) -> bool {
    let Some(dev) = protocol_device() else { return false };
    // How many devices answer on the sensor's bus (`None`: its lines could not be driven).
    let answering = bring_up_sensor(board).map(|found| found.len());
    log_info!("sensor bus: devices answering: {}", answering);
    log_info!("protocol over the UART: {=usize} events per window at most", evcal_firmware::boards::EVENTS_PER_WINDOW);
    let ticks = board.clock();
    let (serial, led) = board.io();
    let mut clock = MarkedClock::new(ticks, led);
    let mut rx = [0u8; RX_CHUNK];
    let (mut start, mut end) = (0, 0);
    loop {
        while let Some(frame) = dev.poll(&mut clock) {
            send(serial, frame);
        }
        // A local source runs once a host has configured a session (a Config counts as the
        // session's first frame received) and the device has answered it.
        if local.is_some() && dev.stats().frames_received > 0 && dev.is_idle() {
            if let Some(src) = local.take() {
                log_info!("session configured: reading the local event source");
                let end = drain(dev, src, serial, &mut clock);
                log_info!(
                    "local event source done: {=u64} events, {=u32} windows",
                    dev.stats().events_received,
                    dev.stats().windows
                );
                if end != SourceError::End {
                    board::report(format_args!("evcal firmware: local event source: {end}"));
                }
            }
            continue;
        }
        if start == end {
            // Waits (asleep on the emulated board) until at least one byte arrives.
            end = receive(serial, &mut rx, dev);
            start = 0;
        }
        start += dev.receive(&rx[start..end]);
    }
}

/// Feeds every event of `src` to the device, sending detections (and the stats the device
/// owes) as they come. Returns how the source ended.
fn drain<S: serial::Write<u8>>(
    dev: &mut FwDevice,
    mut src: impl EventSource,
    serial: &mut S,
    clock: &mut impl Clock,
) -> SourceError {
    let mut buf = [evcal_core::event::Event::default(); READ_BATCH];
    loop {
        let n = match src.read_events(&mut buf) {
            Ok(n) => n,
            Err(e) => {
                // What the input filter still holds (events after a pause) is windowed too.
                while let Some(frame) = dev.end_events(clock) {
                    send(serial, frame);
                }
                return e;
            }
        };
        for e in &buf[..n] {
            if let Some(frame) = dev.push_event(*e, clock) {
                send(serial, frame);
                while let Some(frame) = dev.poll(clock) {
                    send(serial, frame);
                }
            }
        }
    }
}
