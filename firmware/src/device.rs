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
//!   - `fault`, `panic`: for the test that both end QEMU with a failure status.

use crate::{
    board::{self, Board, BoardImpl},
    markers::MarkedClock,
    role::{protocol_device, FwDevice},
};
use embedded_io::{Read, Write};
use evcal_firmware::{
    runner::READ_BATCH,
    source::{EventSource, SourceError},
};

/// Runs the firmware; `true` if it ended cleanly (the protocol runs until reset).
pub fn run(mut board: BoardImpl) -> bool {
    #[cfg(not(feature = "board-stm32f405"))]
    {
        let mut buf = [0u8; crate::hostfs::CMDLINE_MAX];
        let cmd = crate::hostfs::cmdline(&mut buf);
        if let Some(args) = cmd.strip_prefix("bench") {
            return crate::bench::run(&mut board, args);
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
                "evcal firmware: unknown command line {cmd:?}; expected none, `replay FILE`, `bench FILE [EVENTS [STEP_US]]`, `fault` or `panic`"
            ));
            return false;
        }
    }
    protocol(&mut board, None::<evcal_firmware::source::SliceSource<'static>>)
}

/// Bytes taken from the UART at a time.
const RX_CHUNK: usize = 64;

/// The protocol over the UART. With `local`, events come from it (once a host has started a
/// session) rather than from the host's event batches.
fn protocol(board: &mut BoardImpl, mut local: Option<impl EventSource>) -> bool {
    let Some(dev) = protocol_device() else { return false };
    log_info!("protocol over the UART: {=usize} events per window at most", evcal_core::config::MAX_EVENTS_PER_WINDOW);
    let mut clock = MarkedClock(board.clock());
    let mut rx = [0u8; RX_CHUNK];
    let (mut start, mut end) = (0, 0);
    let mut overruns = 0u32;
    loop {
        while let Some(frame) = dev.poll(&mut clock) {
            // The UART's writes cannot fail (`Infallible`).
            let _ = board.serial().write_all(frame);
        }
        // A local source runs once a host has configured a session (a Config counts as the
        // session's first frame received) and the device has answered it.
        if local.is_some() && dev.stats().frames_received > 0 && dev.is_idle() {
            if let Some(src) = local.take() {
                log_info!("session configured: reading the local event source");
                let end = drain(dev, src, board, &mut clock);
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
        let o = board.serial_overruns();
        if o != overruns {
            dev.count_rx_overrun(o.wrapping_sub(overruns));
            overruns = o;
        }
        if start == end {
            // Blocks (asleep) until at least one byte arrives.
            end = board.serial().read(&mut rx).unwrap_or(0);
            start = 0;
        }
        start += dev.receive(&rx[start..end]);
    }
}

/// Feeds every event of `src` to the device, sending detections (and the stats the device
/// owes) as they come. Returns how the source ended.
fn drain(dev: &mut FwDevice, mut src: impl EventSource, board: &mut BoardImpl, clock: &mut MarkedClock) -> SourceError {
    let mut buf = [evcal_core::event::Event::default(); READ_BATCH];
    loop {
        let n = match src.read_events(&mut buf) {
            Ok(n) => n,
            Err(e) => return e,
        };
        for e in &buf[..n] {
            if let Some(frame) = dev.push_event(*e, clock) {
                let _ = board.serial().write_all(frame);
                while let Some(frame) = dev.poll(clock) {
                    let _ = board.serial().write_all(frame);
                }
            }
        }
    }
}
