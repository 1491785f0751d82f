//! `evcal info`: what a recording holds (format, sensor, events, time span, event rate over
//! time, polarity balance), read in one streaming pass.

use crate::common::{outln, progress_bar, ReadArgs};
use anyhow::Result;
use clap::Args;
use evcal_core::event::SensorSize;
use evcal_host::input::recording::{guess_sensor, ReadError, Recording};
use std::path::PathBuf;

#[derive(Args)]
pub struct InfoArgs {
    /// The recording (any format evcal reads; see the README's table); `-` for standard input.
    pub recording: PathBuf,
    #[command(flatten)]
    pub read: ReadArgs,
    /// Print one JSON object instead of the table. Keys kept stable for other programs:
    /// "format", "width", "height", "events", "t_first_us", "t_last_us" (and more).
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Most bins of the rate histogram; past it, neighbours merge and the bin width doubles, so
/// memory stays fixed however long the recording.
const MAX_BINS: usize = 4096;
/// Columns of the rate sparkline.
const SPARK_COLUMNS: usize = 48;

/// Events per time bin from the first event's time, with a bin width that doubles as needed.
struct RateHistogram {
    t0: u64,
    bin_us: u64,
    bins: Vec<u64>,
}

impl RateHistogram {
    fn new(t0: u64) -> Self {
        Self { t0, bin_us: 1000, bins: Vec::new() }
    }

    fn add(&mut self, t: u64) {
        let mut i = (t.saturating_sub(self.t0) / self.bin_us) as usize;
        while i >= MAX_BINS {
            self.bins = self.bins.chunks(2).map(|c| c.iter().sum()).collect();
            self.bin_us *= 2;
            i = (t.saturating_sub(self.t0) / self.bin_us) as usize;
        }
        if i >= self.bins.len() {
            self.bins.resize(i + 1, 0);
        }
        self.bins[i] += 1;
    }

    /// Mean events per second in each of `n` equal parts of [t0, t_last].
    fn rates(&self, t_last: u64, n: usize) -> Vec<f64> {
        let span = (t_last - self.t0 + 1).max(1) as f64;
        let mut counts = vec![0u64; n];
        for (i, &c) in self.bins.iter().enumerate() {
            // A bin goes to the part its start falls in (bins are small against the parts).
            let start = (i as u64 * self.bin_us) as f64;
            counts[((start / span * n as f64) as usize).min(n - 1)] += c;
        }
        counts.iter().map(|&c| c as f64 / (span / n as f64 * 1e-6)).collect()
    }
}

/// What one pass over the events gathers.
struct Summary {
    events: u64,
    on: u64,
    t_first: Option<u64>,
    t_last: u64,
    steps_back: u64,
    max_x: u16,
    max_y: u16,
    /// Events outside the sensor the file states.
    outside: u64,
    hist: Option<RateHistogram>,
}

pub fn run(a: InfoArgs) -> Result<()> {
    // The reader's notes are printed with the summary, not when opening.
    let mut rec = Recording::open_with(&a.recording, &a.read.options())?;
    let pb = progress_bar(rec.file_bytes, a.quiet || a.json, "reading");
    let mut s = Summary {
        events: 0,
        on: 0,
        t_first: None,
        t_last: 0,
        steps_back: 0,
        max_x: 0,
        max_y: 0,
        outside: 0,
        hist: None,
    };
    let stated = rec.sensor;
    let mut error: Option<ReadError> = None;
    while let Some(e) = rec.next() {
        let e = match e {
            Ok(e) => e,
            Err(err) => {
                error = Some(err);
                break;
            }
        };
        if s.t_first.is_none() {
            s.t_first = Some(e.t_us);
            s.hist = Some(RateHistogram::new(e.t_us));
        } else if e.t_us < s.t_last {
            s.steps_back += 1;
        }
        s.t_last = s.t_last.max(e.t_us);
        s.events += 1;
        s.on += u64::from(e.polarity);
        s.max_x = s.max_x.max(e.x);
        s.max_y = s.max_y.max(e.y);
        s.outside += u64::from(stated.is_some_and(|z| e.x >= z.width || e.y >= z.height));
        if let Some(h) = &mut s.hist {
            h.add(e.t_us);
        }
        if s.events % (1 << 16) == 0 {
            pb.set_position(rec.progress_bytes());
        }
    }
    pb.finish_and_clear();
    let (sensor, sensor_from) = match rec.sensor {
        Some(size) => (Some(size), "file"),
        None if s.events > 0 => (Some(guess_sensor(s.max_x, s.max_y)), "guess"),
        None => (None, "unknown"),
    };
    let notes = rec.notes();
    let printed = if a.json {
        outln!("{}", json(&rec, &s, sensor, sensor_from, &notes, error.as_ref()))
    } else {
        print_table(&rec, &s, sensor, sensor_from, &notes)
    };
    // A damaged file is said even when standard output has closed.
    match error {
        Some(e) => Err(e.into()),
        None => printed,
    }
}

fn outside(s: &Summary, sensor: Option<SensorSize>) -> bool {
    sensor.is_some_and(|z| s.events > 0 && (s.max_x >= z.width || s.max_y >= z.height))
}

fn json(
    rec: &Recording,
    s: &Summary,
    sensor: Option<SensorSize>,
    sensor_from: &str,
    notes: &[String],
    error: Option<&ReadError>,
) -> serde_json::Value {
    let duration_us = s.t_first.map(|t| s.t_last - t);
    let rates = match (&s.hist, s.events) {
        (Some(h), n) if n > 0 => h.rates(s.t_last, 10),
        _ => Vec::new(),
    };
    serde_json::json!({
        "file": rec.name().display().to_string(),
        "format": rec.format.name(),
        "width": sensor.map(|z| z.width),
        "height": sensor.map(|z| z.height),
        "sensor_from": sensor_from,
        "events": s.events,
        "t_first_us": s.t_first,
        "t_last_us": s.t_first.map(|_| s.t_last),
        "duration_s": duration_us.map(|d| d as f64 * 1e-6),
        "mean_rate_per_s": duration_us.filter(|&d| d > 0).map(|d| s.events as f64 / (d as f64 * 1e-6)),
        "rate_per_s_by_tenth": rates.iter().map(|r| r.round()).collect::<Vec<_>>(),
        "on": s.on,
        "off": s.events - s.on,
        "max_x": (s.events > 0).then_some(s.max_x),
        "max_y": (s.events > 0).then_some(s.max_y),
        "outside_sensor": outside(s, sensor),
        "events_outside_sensor": s.outside,
        "time_steps_back": s.steps_back,
        "notes": notes,
        "error": error.map(|e| e.to_string()),
    })
}

fn thousands(n: u64) -> String {
    let d = n.to_string();
    let mut out = String::new();
    for (i, c) in d.chars().enumerate() {
        if i > 0 && (d.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn rate(r: f64) -> String {
    if r >= 1e6 {
        format!("{:.2} M/s", r / 1e6)
    } else if r >= 1e3 {
        format!("{:.1} k/s", r / 1e3)
    } else {
        format!("{r:.0} /s")
    }
}

fn seconds(us: u64) -> String {
    format!("{}.{:06} s", us / 1_000_000, us % 1_000_000)
}

fn print_table(rec: &Recording, s: &Summary, sensor: Option<SensorSize>, from: &str, notes: &[String]) -> Result<()> {
    outln!("file       {}", rec.name().display())?;
    outln!("format     {}", rec.format.name())?;
    match sensor {
        Some(z) if from == "file" => outln!("sensor     {}x{}", z.width, z.height)?,
        Some(z) => outln!(
            "sensor     {}x{} (guessed from the largest x {} and y {}: the file does not say)",
            z.width,
            z.height,
            s.max_x,
            s.max_y
        )?,
        None => outln!("sensor     unknown")?,
    }
    outln!("events     {}", thousands(s.events))?;
    let (Some(t0), Some(h)) = (s.t_first, &s.hist) else { return print_notes(notes) };
    let d = s.t_last - t0;
    outln!("time       {} .. {} ({} long)", seconds(t0), seconds(s.t_last), seconds(d))?;
    if d > 0 {
        let tenths = h.rates(s.t_last, 10);
        let peak = tenths.iter().cloned().fold(0.0, f64::max);
        outln!("rate       {} mean, {} in the busiest tenth", rate(s.events as f64 / (d as f64 * 1e-6)), rate(peak))?;
        let cols = h.rates(s.t_last, SPARK_COLUMNS);
        let top = cols.iter().cloned().fold(0.0, f64::max).max(1e-9);
        const BARS: [char; 8] = ['▁', '▂', '▃', '▄', '▅', '▆', '▇', '█'];
        let spark: String = cols.iter().map(|r| BARS[((r / top) * 7.0).round() as usize]).collect();
        outln!("over time  {spark}  (first to last event, {} a column)", seconds(d / SPARK_COLUMNS as u64))?;
        outln!("by tenth   {}", tenths.iter().map(|r| rate(*r)).collect::<Vec<_>>().join("  "))?;
    }
    let on_pct = 100.0 * s.on as f64 / s.events as f64;
    outln!(
        "polarity   ON {} ({on_pct:.1} %), OFF {} ({:.1} %)",
        thousands(s.on),
        thousands(s.events - s.on),
        100.0 - on_pct
    )?;
    outln!("pixels     x 0..={}, y 0..={}", s.max_x, s.max_y)?;
    if let Some(w) = sensor.and_then(|z| crate::common::outside_warning(s.outside, s.events, z)) {
        outln!("warning    {w}")?;
    } else if outside(s, sensor) {
        outln!("warning    {} events lie outside the sensor: the detector will drop them", thousands(s.outside))?;
    }
    if s.steps_back > 0 {
        outln!("order      {} events earlier than the one before (the detector drops them)", thousands(s.steps_back))?;
    }
    print_notes(notes)
}

fn print_notes(notes: &[String]) -> Result<()> {
    for n in notes {
        outln!("note       {n}")?;
    }
    Ok(())
}
