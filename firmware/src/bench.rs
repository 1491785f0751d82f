//! Benchmark replay, emulator only (QEMU `-append "bench FILE [EVENTS [STEP_US [paced MHZ
//! CPI_PERCENT]]]"`): events from a bulk file on the host, every window processed between
//! the benchmark markers, one line per window on the emulator's standard output (stage ticks
//! and the detection, floats as their bit patterns), then a summary line with the counts and
//! the memory used.
//!
//! `paced`: the events arrive at the recording's own pace on the device's clock (instructions
//! under `-icount shift=0`, as a core at `MHZ` with `CPI_PERCENT`/100 cycles per instruction
//! would run them) through the FIFO of [`PacedSource`]; each loss is a line
//! `L KEPT LOST` (events read before it, events lost) where it happens, and a line `P ...`
//! with the source's counts comes before the summary.

use crate::{
    board::{self, Board},
    markers::MarkedClock,
    role::bench_detector,
    stack,
};
use core::cell::RefCell;
use core::fmt::Write;
use evcal_core::{
    detect::{DetectConfig, Detection},
    event::{Event, SensorSize},
};
use evcal_firmware::{
    paced::{PacedSource, FIFO_EVENTS},
    runner::Runner,
    source::{EventSource, SourceError},
};

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

/// A source whose losses are written where they happen, as `L KEPT LOST` lines.
struct Logged<'o, S> {
    inner: S,
    out: &'o RefCell<HostOut>,
    read: u64,
    ok: bool,
}

impl<S: EventSource> EventSource for Logged<'_, S> {
    fn read_events(&mut self, buf: &mut [Event]) -> Result<usize, SourceError> {
        let n = self.inner.read_events(buf)?;
        self.read += n as u64;
        Ok(n)
    }

    fn take_lost(&mut self) -> u64 {
        let lost = self.inner.take_lost();
        if lost > 0 {
            self.ok &= writeln!(self.out.borrow_mut(), "L {} {lost}", self.read).is_ok();
        }
        lost
    }
}

/// Microseconds on a core at `mhz` running `cpi_percent`/100 cycles per instruction, from
/// the board's tick counter under `-icount shift=0` (one instruction a nanosecond: a tick of
/// `CLOCK_HZ` is 10⁹/`CLOCK_HZ` instructions), as a 32.32 fixed-point scale.
fn device_us_scale(mhz: u64, cpi_percent: u64) -> u64 {
    let den = u64::from(board::CLOCK_HZ) * mhz.max(1);
    // 2³² · 10⁷ · CPI% / (CLOCK_HZ · MHz): below 2⁶⁴ for any clock of 1 MHz and more and a
    // CPI below 100.
    (((1u128 << 32) * 10_000_000 * u128::from(cpi_percent)) / u128::from(den)).min(u128::from(u64::MAX)) as u64
}

/// The paced run of [`run`]: `src` through a [`PacedSource`] on the device's clock (`ticks`
/// at `scale`, see [`device_us_scale`]), its losses and counts written to `out`. Returns how
/// the source ended and whether every line was written. Out of line, so that its FIFO takes
/// stack only in a paced run.
#[inline(never)]
fn drain_paced<
    S: EventSource,
    K: evcal_core::detect::Clock,
    const N: usize,
    const C: usize,
    const H: usize,
    const CELLS: usize,
>(
    runner: &mut Runner<'_, K, N, C, H, CELLS>,
    src: S,
    ticks: board::SysTickClock,
    scale: u64,
    out: &RefCell<HostOut>,
    on_window: &mut impl FnMut(&Detection<C>),
) -> (SourceError, bool) {
    // The tick counter extended past its 32 bits (read often enough: every batch).
    let (mut last, mut high) = (ticks.now(), 0u64);
    let now_us = || {
        let t = ticks.now();
        if t < last {
            high += 1 << 32;
        }
        last = t;
        ((u128::from(high | u64::from(t)) * u128::from(scale)) >> 32) as u64
    };
    let inner: PacedSource<_, _, FIFO_EVENTS> = PacedSource::new(src, now_us);
    let mut paced = Logged { inner, out, read: 0, ok: true };
    let end = runner.drain(&mut paced, on_window);
    let st = paced.inner.stats();
    let ok = paced.ok
        && writeln!(
            out.borrow_mut(),
            "P arrived {} lost {} losses {} idle_us {} fifo_peak {}",
            st.arrived,
            st.lost,
            st.losses,
            st.idle_us,
            st.fifo_peak
        )
        .is_ok();
    (end, ok)
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
    let pace = match (words.next(), words.next().and_then(|w| w.parse::<u64>().ok()), words.next()) {
        (Some("paced"), Some(mhz), Some(cpi)) => cpi.parse::<u64>().ok().map(|cpi| device_us_scale(mhz, cpi)),
        (None, ..) => None,
        _ => {
            board::report(format_args!("evcal firmware: bench FILE EVENTS STEP_US paced MHZ CPI_PERCENT"));
            return false;
        }
    };
    let Ok(out) = cortex_m_semihosting::hio::hstdout() else { return false };
    let out = RefCell::new(HostOut { out, buf: [0; 512], len: 0 });
    let Some(det) = bench_detector(cfg) else { return false };
    let ticks = board.clock();
    let (_, led) = board.io();
    let mut runner = Runner::new(det, MarkedClock::new(ticks, led));
    let mut write_ok = true;
    let mut on_window = |d: &Detection<{ evcal_core::config::MAX_CLUSTERS }>| {
        write_ok &= write_window(&mut *out.borrow_mut(), d).is_ok();
    };
    let end = match pace {
        None => runner.drain(&mut src, &mut on_window),
        Some(scale) => {
            let (end, ok) = drain_paced(&mut runner, &mut src, ticks, scale, &out, &mut on_window);
            write_ok &= ok;
            end
        }
    };
    let input = runner.detector().input_stats();
    let SensorSize { width, height } = cfg.sensor;
    let mut out = out.into_inner();
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
