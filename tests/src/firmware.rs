//! Driving the firmware under QEMU from the host: build the image, write a bulk replay
//! file, boot the emulated board, read back what the firmware printed.
//!
//! Used by the QEMU end-to-end tests (`tests/tests/firmware.rs`) and by the firmware
//! benchmark (`examples/bench_firmware.rs`, run by `scripts/bench-firmware.sh`).

use anyhow::{bail, ensure, Context, Result};
use evcal_core::{
    detect::{DetectConfig, Detection, Detector},
    event::{Event, SensorSize},
};
use evcal_firmware::bulk;
use evcal_host::input::detections::HostDetector;
use std::{
    io::{BufWriter, Write},
    path::{Path, PathBuf},
    process::{Command, Stdio},
};

/// The firmware's target.
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// The cargo profile the firmware is built with (`cargo fw`).
pub const PROFILE: &str = "firmware";

/// Most instructions one window (8000 events) may take on the emulated board (QEMU
/// `mps2-an386`, a Cortex-M4F), between the benchmark markers: 33 ms, a window's share of
/// real time at 30 windows a second, at 168 MHz (the STM32F405's clock) and 1.25 cycles per
/// instruction is 4.435 M; docs/firmware.md's target rounds it down.
pub const M4F_INSTRUCTIONS_PER_WINDOW: u64 = 4_400_000;

/// Most instructions one window may take on the emulated Cortex-M7 (QEMU `mps2-an500`),
/// standing for an STM32H743: 33.3 ms at 480 MHz and 1.0 cycle per instruction is 16.0 M.
pub const M7_INSTRUCTIONS_PER_WINDOW: u64 = 16_000_000;

/// The instruction-counting QEMU plugin (`firmware/tools/insn_count.c`), built with `gcc`
/// into the target directory when missing or older than its source; returns its path.
pub fn build_counter_plugin() -> Result<PathBuf> {
    let source = workspace_root().join("firmware/tools/insn_count.c");
    let dir = target_dir().join("bench-firmware");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let plugin = dir.join("libinsn_count.so");
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    if modified(&plugin).is_none() || modified(&plugin) < modified(&source) {
        let status = Command::new("gcc")
            .args(["-shared", "-fPIC", "-O2", "-Wall", "-o"])
            .arg(&plugin)
            .arg(&source)
            .status()
            .context("running gcc to build the instruction-counting plugin (scripts/setup.sh installs gcc)")?;
        ensure!(status.success(), "building {} failed ({status})", plugin.display());
    }
    Ok(plugin)
}

/// The workspace's root directory.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// Where cargo puts build output.
pub fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| workspace_root().join("target"))
}

/// An emulated board the firmware is built for and booted on (`scripts/qemu-run.sh` picks
/// the QEMU machine from the image's CPU).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Emulated {
    /// QEMU `mps2-an386`, a Cortex-M4F, standing for an STM32F405: the default image.
    M4f,
    /// QEMU `mps2-an500`, a Cortex-M7, standing for an STM32H743 (feature `board-mps2-an500`,
    /// built with `-C target-cpu=cortex-m7` in a target directory of its own).
    M7,
}

impl Emulated {
    /// Most events a window holds on the board (the firmware's capacity for it).
    pub const fn capacity(self) -> usize {
        match self {
            Self::M4f => evcal_firmware::boards::M4F_EVENTS_PER_WINDOW,
            Self::M7 => evcal_firmware::boards::M7_EVENTS_PER_WINDOW,
        }
    }

    /// Instructions per SysTick tick under `-icount shift=0` (1 ns per instruction): the
    /// board's system clock is 25 MHz on both machines (QEMU's `mps2.c`), measured against the
    /// counting plugin.
    pub const fn insns_per_tick(self) -> f64 {
        match self {
            Self::M4f | Self::M7 => 40.0,
        }
    }

    /// The target directory the board's image is built in: the M7's has its own, as its
    /// flags differ (`-C target-cpu=cortex-m7`), so that building one board's image does not
    /// rebuild the other's dependencies.
    fn target_dir(self) -> PathBuf {
        match self {
            Self::M4f => target_dir(),
            Self::M7 => target_dir().join("m7"),
        }
    }

    /// The board's firmware image (where [`build_firmware_for`] puts it).
    pub fn elf_path(self) -> PathBuf {
        self.target_dir().join(TARGET).join(PROFILE).join("evcal-firmware")
    }
}

/// The firmware image `cargo fw` builds (the Cortex-M4F's).
pub fn elf_path() -> PathBuf {
    Emulated::M4f.elf_path()
}

/// Builds the firmware image for the emulated Cortex-M4F (`cargo fw`; quick when it is up
/// to date) and returns its path.
pub fn build_firmware() -> Result<PathBuf> {
    build_firmware_for(Emulated::M4f)
}

/// Builds the firmware image for `board` (as `scripts/firmware-build.sh` does; quick when
/// it is up to date) and returns its path.
pub fn build_firmware_for(board: Emulated) -> Result<PathBuf> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(workspace_root()).args([
        "build",
        "-q",
        "-p",
        "evcal-firmware",
        "--target",
        TARGET,
        "--profile",
        PROFILE,
    ]);
    if board == Emulated::M7 {
        cmd.args(["--features", "board-mps2-an500"])
            .env("CARGO_TARGET_DIR", board.target_dir())
            .env("CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS", "-C target-cpu=cortex-m7");
    }
    let status = cmd.status().context("running cargo to build the firmware")?;
    ensure!(status.success(), "building the firmware for {board:?} failed ({status})");
    Ok(board.elf_path())
}

/// Whether QEMU can be run here; if not, why (what to install).
pub fn qemu_missing() -> Option<String> {
    match Command::new("qemu-system-arm").arg("--version").stdout(Stdio::null()).status() {
        Ok(s) if s.success() => None,
        _ => Some("qemu-system-arm is not installed: run scripts/setup.sh".into()),
    }
}

/// Writes `events` as a bulk replay file for a sensor of `sensor`'s size.
pub fn write_bulk(path: &Path, sensor: SensorSize, events: &[Event]) -> Result<()> {
    let f = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = BufWriter::new(f);
    w.write_all(&bulk::encode_header(sensor))?;
    for e in events {
        let Some(r) = bulk::encode_event(e) else { bail!("row {} does not fit the bulk format", e.y) };
        w.write_all(&r)?;
    }
    w.flush()?;
    Ok(())
}

/// One window as the firmware's benchmark mode printed it.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchWindow {
    /// Sequence number.
    pub seq: u32,
    /// Reference time, µs.
    pub t_ref_us: u64,
    /// Events, noise, clusters, dropped clusters, rejected fits, merged clusters.
    pub counts: [u32; 6],
    /// SysTick ticks clustering took.
    pub cluster_ticks: u32,
    /// SysTick ticks fitting took.
    pub fit_ticks: u32,
    /// Per centre: bit patterns of u, v, r, spread; then n and converged.
    pub centres: Vec<([u32; 4], u16, bool)>,
}

impl BenchWindow {
    /// The same fields of a host-side detection, for exact comparison.
    pub fn of_detection<const C: usize>(d: &Detection<C>) -> Self {
        let s = &d.stats;
        Self {
            seq: d.info.seq,
            t_ref_us: d.info.t_ref_us,
            counts: [s.events, s.noise, s.clusters, s.dropped_clusters, s.rejected_fits, s.merged_clusters]
                .map(u32::from),
            cluster_ticks: 0,
            fit_ticks: 0,
            centres: d
                .centres
                .iter()
                .map(|c| ([c.u.to_bits(), c.v.to_bits(), c.r.to_bits(), c.spread.to_bits()], c.n, c.converged))
                .collect(),
        }
    }

    /// Everything but the stage times (which only the device has).
    pub fn without_times(&self) -> Self {
        Self { cluster_ticks: 0, fit_ticks: 0, ..self.clone() }
    }

    /// The window as the firmware's benchmark mode prints it (`firmware/src/bench.rs`'s
    /// `write_window`), newline included; parsing it gives it back.
    pub fn line(&self) -> String {
        use std::fmt::Write as _;
        let c = &self.counts;
        let mut s = format!(
            "W {} {} {} {} {} {} {} {} {} {} {}",
            self.seq,
            self.t_ref_us,
            c[0],
            c[1],
            c[2],
            c[3],
            c[4],
            c[5],
            self.cluster_ticks,
            self.fit_ticks,
            self.centres.len()
        );
        for ([u, v, r, spread], n, converged) in &self.centres {
            // Writing to a String cannot fail.
            let _ = write!(s, " {u:08x} {v:08x} {r:08x} {spread:08x} {n} {}", u8::from(*converged));
        }
        s.push('\n');
        s
    }

    fn parse(line: &str) -> Result<Self> {
        let f: Vec<&str> = line.split_ascii_whitespace().collect();
        ensure!(f.len() >= 12 && f[0] == "W", "not a window line: {line}");
        let n: usize = f[11].parse()?;
        ensure!(f.len() == 12 + 6 * n, "window line with {} fields for {n} centres", f.len());
        let mut counts = [0u32; 6];
        for (c, s) in counts.iter_mut().zip(&f[3..9]) {
            *c = s.parse()?;
        }
        let centres = f[12..]
            .chunks_exact(6)
            .map(|c| -> Result<_> {
                let mut bits = [0u32; 4];
                for (b, s) in bits.iter_mut().zip(c) {
                    *b = u32::from_str_radix(s, 16)?;
                }
                Ok((bits, c[4].parse()?, c[5] == "1"))
            })
            .collect::<Result<_>>()?;
        Ok(Self {
            seq: f[1].parse()?,
            t_ref_us: f[2].parse()?,
            counts,
            cluster_ticks: f[9].parse()?,
            fit_ticks: f[10].parse()?,
            centres,
        })
    }
}

/// What one benchmark-mode run printed.
#[derive(Debug, Clone, Default)]
pub struct BenchRun {
    /// The windows, in order.
    pub windows: Vec<BenchWindow>,
    /// The summary line's `key value` pairs.
    pub summary: Vec<(String, String)>,
    /// Instruction counts between the markers, one per window, when the counting plugin ran.
    pub instructions: Vec<u64>,
    /// Instructions of the whole run, when the counting plugin ran.
    pub total_instructions: Option<u64>,
    /// With profiling: instructions executed inside the spans, by function, most first.
    pub profile: Vec<(String, u64)>,
    /// Paced runs ([`run_bench_paced`]): each loss at the source, as (events read before
    /// it, events lost), in order.
    pub losses: Vec<(u64, u64)>,
    /// Paced runs: the source's counts (`arrived`, `lost`, `losses`, `idle_us`,
    /// `fifo_peak`).
    pub paced: Vec<(String, u64)>,
}

impl BenchRun {
    /// A summary value.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.summary.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// A numeric summary value.
    pub fn num(&self, key: &str) -> Result<u64> {
        self.get(key).with_context(|| format!("summary has no {key}"))?.parse().with_context(|| key.to_string())
    }
}

/// The instruction-counting QEMU plugin (`firmware/tools/insn_count.c`) and what to ask of it.
#[derive(Debug, Clone, Copy)]
pub struct Counter<'a> {
    /// The plugin library.
    pub plugin: &'a Path,
    /// Also attribute the instructions inside the spans to functions.
    pub profile: bool,
}

/// Boots the firmware in benchmark mode on `bulk_file`. With `counter`, also counts the
/// instructions between the benchmark markers.
pub fn run_bench(
    elf: &Path,
    bulk_file: &Path,
    events_per_window: usize,
    step_us: u64,
    counter: Option<Counter>,
) -> Result<BenchRun> {
    run_bench_with(elf, bulk_file, &format!("bench {} {events_per_window} {step_us}", bulk_file.display()), counter)
}

/// [`run_bench`] with the events arriving at the recording's own pace on the device's clock,
/// as on a core at `mhz` with `cpi` cycles per instruction, through the firmware's FIFO
/// (`evcal_firmware::paced`): what arrives while it is full is lost, and each loss is in
/// [`BenchRun::losses`].
pub fn run_bench_paced(
    elf: &Path,
    bulk_file: &Path,
    events_per_window: usize,
    step_us: u64,
    (mhz, cpi): (f64, f64),
    counter: Option<Counter>,
) -> Result<BenchRun> {
    let cpi_percent = (cpi * 100.0).round() as u64;
    let append =
        format!("bench {} {events_per_window} {step_us} paced {} {cpi_percent}", bulk_file.display(), mhz.round());
    run_bench_with(elf, bulk_file, &append, counter)
}

fn run_bench_with(elf: &Path, bulk_file: &Path, append: &str, counter: Option<Counter>) -> Result<BenchRun> {
    let mut cmd = Command::new("bash");
    cmd.arg(workspace_root().join("scripts/qemu-run.sh")).arg(elf);
    cmd.arg("-append").arg(append);
    let log = bulk_file.with_extension("insn.log");
    if let Some(c) = counter {
        let (start, stop) = (symbol(elf, "bench_start")?, symbol(elf, "bench_stop")?);
        let profile = if c.profile { ",profile=on" } else { "" };
        cmd.arg("-plugin").arg(format!("{},start=0x{start:x},stop=0x{stop:x}{profile}", c.plugin.display()));
        cmd.args(["-d", "plugin", "-D"]).arg(&log);
    }
    let out = cmd.stderr(Stdio::inherit()).output().context("running QEMU (scripts/qemu-run.sh)")?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    ensure!(out.status.success(), "the firmware failed ({}); it printed:\n{}", out.status, tail(&stdout));
    let mut run = BenchRun::default();
    for line in stdout.lines() {
        if line.starts_with("W ") {
            run.windows.push(BenchWindow::parse(line)?);
        } else if let Some(rest) = line.strip_prefix("S ") {
            let w: Vec<&str> = rest.split_ascii_whitespace().collect();
            run.summary = w.chunks_exact(2).map(|p| (p[0].to_string(), p[1].to_string())).collect();
        } else if let Some(rest) = line.strip_prefix("L ") {
            let (read, lost) = rest.split_once(' ').with_context(|| format!("loss line {line:?}"))?;
            run.losses.push((read.parse()?, lost.parse()?));
        } else if let Some(rest) = line.strip_prefix("P ") {
            let w: Vec<&str> = rest.split_ascii_whitespace().collect();
            run.paced = w.chunks_exact(2).map(|p| Ok((p[0].to_string(), p[1].parse()?))).collect::<Result<_>>()?;
        }
    }
    ensure!(!run.summary.is_empty(), "no summary line; the firmware printed:\n{}", tail(&stdout));
    if let Some(c) = counter {
        let text = std::fs::read_to_string(&log).with_context(|| format!("reading {}", log.display()))?;
        run.instructions = text
            .lines()
            .filter_map(|l| l.strip_prefix("bench[")?.split_once("]: ")?.1.strip_suffix(" insns")?.parse().ok())
            .collect();
        run.total_instructions =
            text.lines().find_map(|l| l.strip_prefix("total: ")?.strip_suffix(" insns")?.parse().ok());
        if c.profile {
            let blocks = text.lines().filter_map(|l| {
                let mut w = l.strip_prefix("tb 0x")?.split_ascii_whitespace();
                Some((u64::from_str_radix(w.next()?, 16).ok()?, w.next()?.parse::<u64>().ok()?))
            });
            run.profile = by_function(elf, blocks)?;
        }
    }
    Ok(run)
}

fn tail(s: &str) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(20)..].join("\n")
}

/// The address of `name` in the ELF's symbol table (the host's `nm` reads ARM ELFs).
pub fn symbol(elf: &Path, name: &str) -> Result<u64> {
    let out = Command::new("nm").arg(elf).output().context("running nm")?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.split_ascii_whitespace().nth(2) == Some(name))
        .with_context(|| format!("{name} not in {}", elf.display()))?;
    Ok(u64::from_str_radix(line.split_ascii_whitespace().next().unwrap_or(""), 16)?)
}

/// Sums counts by address into counts by the function holding the address (the ELF's
/// symbol table, demangled by `nm`), most first.
fn by_function(elf: &Path, counts: impl Iterator<Item = (u64, u64)>) -> Result<Vec<(String, u64)>> {
    let out = Command::new("nm").args(["-C", "-n", "--defined-only"]).arg(elf).output().context("running nm")?;
    let text = String::from_utf8_lossy(&out.stdout);
    // Function symbols, by address (Thumb addresses have bit 0 set; instructions do not).
    let funcs: Vec<(u64, &str)> = text
        .lines()
        .filter_map(|l| {
            let (addr, rest) = l.split_once(' ')?;
            let (kind, name) = rest.split_once(' ')?;
            // `$t`, `$d`: ARM mapping symbols, not functions.
            (matches!(kind, "t" | "T" | "W" | "w") && !name.starts_with('$'))
                .then_some((u64::from_str_radix(addr, 16).ok()? & !1, name))
        })
        .collect();
    let mut sums: std::collections::HashMap<&str, u64> = std::collections::HashMap::new();
    for (pc, n) in counts {
        let i = funcs.partition_point(|(a, _)| *a <= pc);
        let name = if i == 0 { "?" } else { funcs[i - 1].1 };
        *sums.entry(name).or_default() += n;
    }
    let mut v: Vec<(String, u64)> = sums.into_iter().map(|(k, n)| (k.to_string(), n)).collect();
    v.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    Ok(v)
}

/// The host-side run of the core over the events a paced run kept: `events` without those
/// each loss in `losses` took ((events read before it, events lost), as
/// [`BenchRun::losses`]), the detector told of each loss in its place.
pub fn host_windows_after_losses(events: &[Event], cfg: DetectConfig, losses: &[(u64, u64)]) -> Vec<BenchWindow> {
    let mut det: Box<HostDetector> = Box::new(Detector::new(cfg));
    let mut out = Vec::new();
    let (mut read, mut next) = (0u64, losses.iter().peekable());
    let mut i = 0usize;
    loop {
        // A loss after the last event kept is told too, before the end.
        if let Some(&&(_, lost)) = next.peek().filter(|(at, _)| *at == read) {
            det.lost();
            i += lost as usize;
            next.next();
            continue;
        }
        let Some(e) = events.get(i) else { break };
        if let Some(d) = det.push(*e) {
            out.push(BenchWindow::of_detection(d));
        }
        read += 1;
        i += 1;
    }
    while let Some(d) = det.end() {
        out.push(BenchWindow::of_detection(d));
    }
    out
}

/// The host-side run of the core over `events` (what `evcal detect` computes).
pub fn host_windows(events: &[Event], cfg: DetectConfig) -> Vec<BenchWindow> {
    let mut det: Box<HostDetector> = Box::new(Detector::new(cfg));
    let mut out: Vec<BenchWindow> = events.iter().filter_map(|e| det.push(*e).map(BenchWindow::of_detection)).collect();
    // The events the input filter still holds at the end, as the firmware's runner does.
    while let Some(d) = det.end() {
        out.push(BenchWindow::of_detection(d));
    }
    out
}
