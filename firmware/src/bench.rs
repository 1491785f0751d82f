//! Benchmark replay, emulator only (QEMU `-append "bench FILE [EVENTS [STEP_US]]"`): events
//! from a bulk file on the host, every window processed between the benchmark markers, one
//! line per window on the emulator's standard output (stage ticks and the detection, floats
//! as their bit patterns), then a summary line with the counts and the memory used.

use crate::{
    board::{self, Board},
    markers::MarkedClock,
    role::bench_detector,
    stack,
};
use core::fmt::Write;
use evcal_core::{
    detect::{DetectConfig, Detection},
    event::SensorSize,
};
use evcal_firmware::{runner::Runner, source::SourceError};

/// Buffers formatted text for a semihosting stream: one host call per 512 bytes rather than
/// one per field.
struct HostOut {
    out: cortex_m_semihosting::hio::HostStream,
    buf: [u8; 512],
    len: usize,
}

impl HostOut {
    fn flush(&mut self) -> core::fmt::Result {
        let r = self.out.write_all(&self.buf[..self.len]).map_err(|_| core::fmt::Error);
        self.len = 0;
        r
    }
}

impl Write for HostOut {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for chunk in s.as_bytes().chunks(self.buf.len()) {
            if self.len + chunk.len() > self.buf.len() {
                self.flush()?;
            }
            self.buf[self.len..self.len + chunk.len()].copy_from_slice(chunk);
            self.len += chunk.len();
        }
        Ok(())
    }
}

/// One window as a line: `W seq t_ref_us events noise clusters dropped_clusters rejected
/// merged cluster_ticks fit_ticks ncentres` then per centre `u v r spread` (f32 bits, hex),
/// `n converged`.
fn write_window<const C: usize>(w: &mut impl Write, d: &Detection<C>) -> core::fmt::Result {
    let s = &d.stats;
    write!(
        w,
        "W {} {} {} {} {} {} {} {} {} {} {}",
        d.info.seq,
        d.info.t_ref_us,
        s.events,
        s.noise,
        s.clusters,
        s.dropped_clusters,
        s.rejected_fits,
        s.merged_clusters,
        s.cluster_ticks,
        s.fit_ticks,
        d.centres.len()
    )?;
    for c in &d.centres {
        write!(
            w,
            " {:08x} {:08x} {:08x} {:08x} {} {}",
            c.u.to_bits(),
            c.v.to_bits(),
            c.r.to_bits(),
            c.spread.to_bits(),
            c.n,
            u8::from(c.converged)
        )?;
    }
    w.write_str("\n")
}

/// The benchmark replay (see the module's doc).
pub fn run<B: Board>(board: &mut B, args: &str) -> bool {
    use evcal_firmware::bulk::BulkSource;
    let mut words = args.split_ascii_whitespace();
    let Some(path) = words.next() else {
        board::report(format_args!("evcal firmware: bench needs a file: bench FILE [EVENTS [STEP_US]]"));
        return false;
    };
    let Some(file) = crate::hostfs::HostFile::open(path) else {
        board::report(format_args!("evcal firmware: cannot open {path}"));
        return false;
    };
    let mut src = match BulkSource::open(file) {
        Ok(s) => s,
        Err(e) => {
            board::report(format_args!("evcal firmware: {path}: {e}"));
            return false;
        }
    };
    let mut cfg = DetectConfig::new(src.sensor());
    if let Some(n) = words.next().and_then(|w| w.parse().ok()) {
        cfg.window.events = n;
    }
    if let Some(s) = words.next().and_then(|w| w.parse().ok()) {
        cfg.window.step_us = s;
    }
    let Ok(out) = cortex_m_semihosting::hio::hstdout() else { return false };
    let mut out = HostOut { out, buf: [0; 512], len: 0 };
    let Some(det) = bench_detector(cfg) else { return false };
    let ticks = board.clock();
    let (_, led) = board.io();
    let mut runner = Runner::new(det, MarkedClock::new(ticks, led));
    let mut write_ok = true;
    let end = runner.drain(&mut src, |d| write_ok &= write_window(&mut out, d).is_ok());
    let input = runner.detector().input_stats();
    let SensorSize { width, height } = cfg.sensor;
    write_ok &= writeln!(
        out,
        "S events {} windows {} out_of_sensor {} time_backwards {} pending {} end {:?} sensor {}x{} window {} step_us {} clock_hz {} static_ram {} stack_peak {}",
        runner.events(),
        runner.windows(),
        input.out_of_sensor,
        // Stray times too: one count of events dropped for their time, as on the wire.
        input.time_order(),
        runner.detector().pending(),
        end,
        width,
        height,
        runner.detector().config().window.events,
        cfg.window.step_us,
        board::CLOCK_HZ,
        stack::statics(),
        stack::high_water(),
    )
    .is_ok();
    write_ok &= out.flush().is_ok();
    write_ok && end == SourceError::End
}
