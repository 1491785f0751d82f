//! The firmware benchmark: cost of the host's windows on a board's core, measured under QEMU.
//!
//! Run it through `scripts/bench-firmware.sh` (which builds the firmware and the instruction
//! counting plugin). It simulates a recording of the sensor, replays it into the firmware
//! from a bulk file, checks that every window equals the host-side run of the core bit for
//! bit, and reports instructions per window (exact, between the benchmark markers), per stage
//! (SysTick under `-icount shift=0`), the implied time at the board's clock and CPI, and the
//! firmware's memory. It ends with one line a script can read:
//!
//! `bench-summary: board=B sensor=S light=L events_per_window=N windows=W identical=I
//! mean_instr=X max_instr=Y budget_instr=Z static_ram=R stack_peak=K flash=F`
//!
//! Options: `--board m4f|m7` (the boards built: see [`Board`]), `--sensor davis346|genx320|
//! dvxplorer|imx636` (davis346), `--light good|low`, `--seconds S` (3.5), `--step-ms MS`
//! (33.333), `--events N` (the host's default window for the sensor), `--plugin LIB` (no
//! exact counts without it), `--cpi X` and `--mhz F` (the board's), `--dir DIR`
//! (target/bench-firmware), `--profile N` (also list the N functions that execute the most
//! instructions inside the windows; slower), `--paced` (the events arrive at the recording's
//! own pace on the board's clock, through the firmware's FIFO: what the device loses while it
//! works on a window, outside every window).

use anyhow::{bail, ensure, Context, Result};
use evcal_core::{detect::DetectConfig, event::SensorSize, window::ring_events_per_window};
use evcal_host::{
    eval::simulate,
    sim::{Camera, Light, SimConfig, Trajectory},
};
use evcal_tests::{
    firmware::{self, BenchRun, Counter, Emulated},
    link,
};
use std::path::PathBuf;

/// A board the firmware is built for, as the benchmark sees it.
struct Board {
    /// Its name on the command line and in the summary.
    name: &'static str,
    /// What QEMU emulates and what real part it stands for.
    title: &'static str,
    /// The emulated board the image is built for and booted on.
    emulated: Emulated,
    /// Core clock of the real part, MHz, and its cycles per instruction as the docs state
    /// them (docs/firmware.md, "Performance").
    mhz: f64,
    cpi: f64,
    /// Most instructions a window may take: 33.3 ms at the clock and CPI, rounded down as
    /// CI holds it.
    budget: u64,
    /// What the real part's memory is, for the report (the linker enforces it).
    memory: &'static str,
}

/// The boards built. The Cortex-M4F: QEMU's mps2-an386 standing for an STM32F405; the
/// Cortex-M7: QEMU's mps2-an500 standing for an STM32H743.
const BOARDS: [Board; 2] = [
    Board {
        name: "m4f",
        title: "QEMU mps2-an386, Cortex-M4F, standing for an STM32F405 at 168 MHz",
        emulated: Emulated::M4f,
        mhz: 168.0,
        cpi: 1.25,
        budget: firmware::M4F_INSTRUCTIONS_PER_WINDOW,
        memory: "flash 512 KiB, SRAM 128 KiB for the statics, CCM 64 KiB for the stack",
    },
    Board {
        name: "m7",
        title: "QEMU mps2-an500, Cortex-M7, standing for an STM32H743 at 480 MHz",
        emulated: Emulated::M7,
        mhz: 480.0,
        cpi: 1.0,
        budget: firmware::M7_INSTRUCTIONS_PER_WINDOW,
        memory: "flash 2 MiB, AXI SRAM 512 KiB for the statics, DTCM 128 KiB for the stack",
    },
];

struct Opts {
    board: &'static Board,
    sensor: &'static str,
    seconds: f64,
    step_ms: f64,
    events: usize,
    light: Light,
    plugin: Option<PathBuf>,
    cpi: f64,
    mhz: f64,
    dir: PathBuf,
    profile: usize,
    paced: bool,
}

fn opts() -> Result<Opts> {
    let mut o = Opts {
        board: &BOARDS[0],
        sensor: "davis346",
        seconds: 3.5,
        step_ms: 33.333,
        events: 0,
        light: Light::Good,
        plugin: None,
        cpi: 0.0,
        mhz: 0.0,
        dir: firmware::target_dir().join("bench-firmware"),
        profile: 0,
        paced: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut v = || args.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--board" => {
                let name = v()?;
                let names: Vec<&str> = BOARDS.iter().map(|b| b.name).collect();
                o.board = BOARDS.iter().find(|b| b.name == name).with_context(|| {
                    format!("--board: {name} is not a board built; the boards: {}", names.join(", "))
                })?;
            }
            "--sensor" => {
                let name = v()?;
                o.sensor = Camera::PRESETS.iter().copied().find(|p| *p == name).with_context(|| {
                    format!("--sensor: {name} is no simulator preset; the presets: {}", Camera::PRESETS.join(", "))
                })?;
            }
            "--seconds" => o.seconds = v()?.parse()?,
            "--step-ms" => o.step_ms = v()?.parse()?,
            "--events" => o.events = v()?.parse()?,
            "--light" => {
                o.light = match v()?.as_str() {
                    "good" => Light::Good,
                    "low" => Light::Low,
                    l => bail!("--light good or low, not {l}"),
                }
            }
            "--plugin" => o.plugin = Some(v()?.into()),
            "--cpi" => o.cpi = v()?.parse()?,
            "--mhz" => o.mhz = v()?.parse()?,
            "--dir" => o.dir = v()?.into(),
            "--profile" => o.profile = v()?.parse()?,
            "--paced" => o.paced = true,
            _ => bail!("unknown option {a} (see the doc comment of tests/examples/bench_firmware.rs)"),
        }
    }
    if o.mhz == 0.0 {
        o.mhz = o.board.mhz;
    }
    if o.cpi == 0.0 {
        o.cpi = o.board.cpi;
    }
    Ok(o)
}

struct Summary {
    mean: f64,
    median: f64,
    min: f64,
    max: f64,
}

fn summary(v: &[f64]) -> Summary {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len().max(1) as f64;
    Summary {
        mean: s.iter().sum::<f64>() / n,
        median: s.get(s.len() / 2).copied().unwrap_or(0.0),
        min: s.first().copied().unwrap_or(0.0),
        max: s.last().copied().unwrap_or(0.0),
    }
}

fn m(x: f64) -> String {
    format!("{:.3} M", x / 1e6)
}

fn main() -> Result<()> {
    let o = opts()?;
    std::fs::create_dir_all(&o.dir)?;
    let elf = firmware::build_firmware_for(o.board.emulated)?;

    let sim_cfg = SimConfig::preset(o.sensor, "4x11", Trajectory::Cone, o.light, 11).context("preset")?;
    let sensor = SensorSize { width: sim_cfg.camera.width, height: sim_cfg.camera.height };
    let mut o = o;
    if o.events == 0 {
        o.events = ring_events_per_window(sensor);
    }
    ensure!(
        o.events <= o.board.emulated.capacity(),
        "the {} board holds {} events per window; {} needs {} (the host's window for it): a board that holds it is \
         needed",
        o.board.name,
        o.board.emulated.capacity(),
        o.sensor,
        o.events
    );
    eprintln!("bench: simulating {} s of {}, 4x11 grid, cone, {} light", o.seconds, o.sensor, o.light.name());
    let (events, _) = simulate(sim_cfg, o.seconds);
    let bulk = o.dir.join("events.bin");
    firmware::write_bulk(&bulk, sensor, &events)?;
    let step_us = (o.step_ms * 1000.0).round() as u64;
    let mut cfg = DetectConfig::new(sensor);
    cfg.window.events = o.events;
    cfg.window.step_us = step_us;
    let mut want = firmware::host_windows(&events, cfg);

    eprintln!("bench: replaying {} events ({} windows) in QEMU", events.len(), want.len());
    let t = std::time::Instant::now();
    let counter = o.plugin.as_deref().map(|plugin| Counter { plugin, profile: o.profile > 0 });
    let run: BenchRun = if o.paced {
        let run = firmware::run_bench_paced(&elf, &bulk, o.events, step_us, (o.mhz, o.cpi), counter)?;
        // The device's windows are the host's on the events it kept, told of each loss.
        want = firmware::host_windows_after_losses(&events, cfg, &run.losses);
        run
    } else {
        firmware::run_bench(&elf, &bulk, o.events, step_us, counter)?
    };
    let qemu_s = t.elapsed().as_secs_f64();

    // The figures mean nothing unless the device computed what the host computes.
    ensure!(run.windows.len() == want.len(), "{} windows on the device, {} on the host", run.windows.len(), want.len());
    let identical = run.windows.iter().zip(&want).filter(|(d, h)| d.without_times() == **h).count();
    if let Some((_, h)) = run.windows.iter().zip(&want).find(|(d, h)| d.without_times() != **h) {
        eprintln!("bench: window {} differs between device and host (the summary counts them)", h.seq);
    }
    let full: Vec<usize> = (0..run.windows.len()).filter(|&i| run.windows[i].counts[0] as usize == o.events).collect();

    let elf_size = size(&elf)?;
    println!("# evcal firmware benchmark ({}, -icount shift=0)", o.board.title);
    println!(
        "recording: simulated {} {}x{} 4x11 cone, {} light, {:.1} s, {} events; windows of {} events every {} ms: {} windows ({} full), {} identical to the host's core bit for bit",
        o.sensor,
        sensor.width,
        sensor.height,
        o.light.name(),
        o.seconds,
        events.len(),
        o.events,
        o.step_ms,
        want.len(),
        full.len(),
        identical
    );
    if o.paced {
        let get = |k: &str| run.paced.iter().find(|(n, _)| n == k).map_or(0, |(_, v)| *v);
        let span_s = events.last().zip(events.first()).map_or(0.0, |(l, f)| (l.t_us - f.t_us) as f64 * 1e-6);
        println!(
            "paced: the events at the recording's pace ({:.2} M events/s) into a FIFO of {} events, on a core at {} MHz, CPI {}: {} arrived, {} lost in {} losses (outside every window: the device's windows are the host's on the events kept), FIFO peak {}, idle {:.1} % of the time",
            events.len() as f64 / span_s.max(1e-9) / 1e6,
            evcal_firmware::paced::FIFO_EVENTS,
            o.mhz,
            o.cpi,
            get("arrived"),
            get("lost"),
            get("losses"),
            get("fifo_peak"),
            100.0 * get("idle_us") as f64 * 1e-6 / span_s.max(1e-9)
        );
    }
    let centres: usize = run.windows.iter().map(|w| w.centres.len()).sum();
    println!("centres per window: {:.1} mean", centres as f64 / run.windows.len().max(1) as f64);
    // The device's detection frames are these bytes exactly (tests/tests/end_to_end/firmware_qemu.rs).
    let frames = link::expected_frames(&events, cfg)?;
    let sizes: Vec<f64> = frames.iter().map(|(_, f)| f.len() as f64).collect();
    let s = summary(&sizes);
    println!(
        "link, device to host: detection frame (COBS, CRC, delimiters) mean {:.0} B, max {:.0} B per window; plus a Stats frame every 16 windows and the Acks of a replay (raw events: {} B per window)",
        s.mean,
        s.max,
        o.events * 8
    );
    let to_ms = |insns: f64| insns * o.cpi / (o.mhz * 1e3);
    if run.instructions.is_empty() {
        println!("instructions per window: not counted (no --plugin)");
    } else {
        ensure!(
            run.instructions.len() == run.windows.len(),
            "{} counted spans for {} windows",
            run.instructions.len(),
            run.windows.len()
        );
        let v: Vec<f64> = full.iter().map(|&i| run.instructions[i] as f64).collect();
        let s = summary(&v);
        println!(
            "instructions per window (exact, bench_start..bench_stop, {} full windows): mean {}, median {}, min {}, max {}",
            v.len(),
            m(s.mean),
            m(s.median),
            m(s.min),
            m(s.max)
        );
        println!(
            "implied time at {} MHz, {} cycles per instruction: mean {:.2} ms, max {:.2} ms (real time at 30 windows/s: 33.3 ms)",
            o.mhz,
            o.cpi,
            to_ms(s.mean),
            to_ms(s.max)
        );
        // The budget CI holds every window to (tests/tests/end_to_end/firmware_qemu.rs).
        let budget = o.board.budget as f64;
        println!(
            "targets: <= {} instructions per window (<= {:.0} per event), aim <= 400 per event ({})",
            m(budget),
            budget / o.events as f64,
            m(400.0 * o.events as f64)
        );
        // Paced, the source's own bookkeeping runs on the core too: the intake is measured
        // unpaced.
        if let Some(total) = run.total_instructions.filter(|_| !o.paced) {
            let inside: u64 = run.instructions.iter().sum();
            let fed = run.num("events")?;
            let per_event = (total - inside) as f64 / fed.max(1) as f64;
            println!(
                "outside the windows' processing (boot, bulk-file reads and decoding, input filter, windowing, result lines): {per_event:.0} instructions per event fed ({fed} events)"
            );
            // What the core can take in while it works on no window, and what is left of a
            // second once 30 windows of the mean cost are worked on.
            let per_second = o.mhz * 1e6 / o.cpi;
            let windows = 30.0 * summary(&run.instructions.iter().map(|&n| n as f64).collect::<Vec<_>>()).mean;
            println!(
                "intake at {} MHz, CPI {}: {:.2} M events/s while no window is worked on; {:.2} M events/s in the time 30 windows a second leave",
                o.mhz,
                o.cpi,
                per_second / per_event / 1e6,
                (per_second - windows).max(0.0) / per_event / 1e6
            );
        }
    }
    let per_tick = o.board.emulated.insns_per_tick();
    let cl: Vec<f64> = full.iter().map(|&i| f64::from(run.windows[i].cluster_ticks) * per_tick).collect();
    let fi: Vec<f64> = full.iter().map(|&i| f64::from(run.windows[i].fit_ticks) * per_tick).collect();
    let (cl, fi) = (summary(&cl), summary(&fi));
    println!(
        "per stage (SysTick x {per_tick} instructions/tick): clustering mean {} max {}; fitting mean {} max {}",
        m(cl.mean),
        m(cl.max),
        m(fi.mean),
        m(fi.max)
    );
    let events_fed = run.num("events")?;
    println!(
        "memory: flash {} B (text {} + rodata {} + data {}), static RAM {} B (data {} + bss {}), stack peak {} B, heap none",
        elf_size.flash(),
        elf_size.text,
        elf_size.rodata,
        elf_size.data,
        elf_size.ram(),
        elf_size.data,
        elf_size.bss,
        run.num("stack_peak")?
    );
    println!("budget: {} (linker-enforced)", o.board.memory);
    println!("qemu wall time: {qemu_s:.1} s for {events_fed} events");
    if o.profile > 0 {
        let all: u64 = run.profile.iter().map(|(_, n)| n).sum();
        println!("where the instructions inside the windows go (per window, by function; inlined code counts as its caller's):");
        for (name, n) in run.profile.iter().take(o.profile) {
            println!(
                "  {:>8.3} M  {:>5.1} %  {name}",
                *n as f64 / run.windows.len().max(1) as f64 / 1e6,
                100.0 * *n as f64 / all.max(1) as f64
            );
        }
    }
    let counted: Vec<u64> = full.iter().filter_map(|&i| run.instructions.get(i).copied()).collect();
    let mean = counted.iter().sum::<u64>() / (counted.len() as u64).max(1);
    println!(
        "bench-summary: board={} sensor={} light={} events_per_window={} windows={} identical={} mean_instr={} max_instr={} budget_instr={} static_ram={} stack_peak={} flash={}",
        o.board.name,
        o.sensor,
        o.light.name(),
        o.events,
        run.windows.len(),
        identical,
        mean,
        counted.iter().max().copied().unwrap_or(0),
        o.board.budget,
        elf_size.ram(),
        run.num("stack_peak")?,
        elf_size.flash()
    );
    ensure!(
        identical == run.windows.len(),
        "{} of {} windows differ from the host's",
        run.windows.len() - identical,
        run.windows.len()
    );
    Ok(())
}

/// Section sizes of an ELF, by the kind of memory they take.
struct ElfSize {
    text: u64,
    rodata: u64,
    data: u64,
    bss: u64,
}

impl ElfSize {
    fn flash(&self) -> u64 {
        self.text + self.rodata + self.data
    }
    fn ram(&self) -> u64 {
        self.data + self.bss
    }
}

/// Reads the section headers of a 32-bit little-endian ELF (no tool needed): allocated
/// sections, sorted into code, read-only data, initialised data and zeroed data.
fn size(elf: &std::path::Path) -> Result<ElfSize> {
    let b = std::fs::read(elf)?;
    ensure!(b.len() > 52 && &b[..4] == b"\x7fELF" && b[4] == 1 && b[5] == 1, "not a 32-bit little-endian ELF");
    let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]) as usize;
    let u32_at = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]) as u64;
    let (shoff, shentsize, shnum) = (u32_at(32) as usize, u16_at(46), u16_at(48));
    ensure!(shoff + shentsize * shnum <= b.len(), "section headers out of the file");
    let mut s = ElfSize { text: 0, rodata: 0, data: 0, bss: 0 };
    for i in 0..shnum {
        let h = shoff + i * shentsize;
        let (kind, flags, size) = (u32_at(h + 4), u32_at(h + 8), u32_at(h + 20));
        const ALLOC: u64 = 2;
        const WRITE: u64 = 1;
        const EXEC: u64 = 4;
        const NOBITS: u64 = 8;
        if flags & ALLOC == 0 {
            continue;
        }
        if kind == NOBITS {
            s.bss += size;
        } else if flags & WRITE != 0 {
            s.data += size;
        } else if flags & EXEC != 0 {
            s.text += size;
        } else {
            s.rodata += size;
        }
    }
    Ok(s)
}
