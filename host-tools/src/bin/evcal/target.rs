//! `evcal target`: the asymmetric circle grid to print, at true scale.

use crate::{common::check_output, ranges};
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use evcal_host::export::{
    atomic::AtomicFile,
    board::{Paper, Sheet, RADIUS_SHARE},
};
use evcal_host::views::grid::Pattern;
use std::{io::Write, path::PathBuf};

#[derive(Args)]
pub struct TargetArgs {
    /// The grid, ROWSxCOLS: circles per column x columns, as `evcal calibrate --pattern`
    /// takes it (4x11 is OpenCV's acircles pattern, patternSize (4, 11)).
    #[arg(long, value_name = "ROWSxCOLS")]
    pub pattern: String,
    /// Spacing S in metres: neighbouring columns are S apart, circles in one column 2·S
    /// apart (each column a spacing lower than the one before), diagonal neighbours S·√2.
    /// The same S as OpenCV's squareSize for an asymmetric grid and Kalibr's spacingMeters
    /// with asymmetricGrid: true; give `evcal calibrate` the same --spacing.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    pub spacing: f64,
    /// The file to write, at true scale: an SVG (.svg; its size in mm) or a PDF (.pdf; one
    /// page the paper's size), or `-` for the SVG on standard output. Replaced only once
    /// written whole.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Radius of the circles, metres. Default: 0.3·S (a diameter of 0.6·S, as the
    /// simulator's boards), rounded to 0.01 mm. From a twentieth of S to below half the
    /// diagonal spacing (0.707·S), where neighbours would touch.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    pub radius: Option<f64>,
    /// The paper. Default: A4, portrait if it fits, else landscape, else A3 likewise.
    /// `fit`: a page just the size of the grid, its margin and caption (for a print shop).
    #[arg(long, value_enum)]
    pub paper: Option<PaperArg>,
}

/// `--paper`.
#[derive(Clone, Copy, ValueEnum)]
pub enum PaperArg {
    /// ISO A4, 210 x 297 mm.
    A4,
    /// US Letter, 215.9 x 279.4 mm.
    Letter,
    /// ISO A3, 297 x 420 mm.
    A3,
    /// A page of the target's own size.
    Fit,
}

impl From<PaperArg> for Paper {
    fn from(p: PaperArg) -> Self {
        match p {
            PaperArg::A4 => Paper::A4,
            PaperArg::Letter => Paper::Letter,
            PaperArg::A3 => Paper::A3,
            PaperArg::Fit => Paper::Fit,
        }
    }
}

pub fn run(a: TargetArgs) -> Result<()> {
    let pattern = Pattern::parse(&a.pattern, a.spacing).map_err(anyhow::Error::msg)?;
    ranges::check_spacing(a.spacing)?;
    if let Some(r) = a.radius {
        ranges::check_radius(r, a.spacing)?;
    }
    check_output(&a.out, "--out", &[])?;
    let stdout = a.out.as_os_str() == "-";
    let ext = a.out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let pdf = match ext.as_deref() {
        _ if stdout => false,
        Some("svg") => false,
        Some("pdf") => true,
        _ => bail!(
            "--out {}: the target is written as SVG or PDF: give a name ending in .svg or .pdf (or - for SVG on standard output)",
            a.out.display()
        ),
    };
    let sheet = Sheet::new(pattern, a.radius, a.paper.map(Paper::from)).map_err(anyhow::Error::from)?;
    let bytes = if pdf { sheet.pdf() } else { sheet.svg().into_bytes() };
    if stdout {
        let mut o = std::io::stdout().lock();
        o.write_all(&bytes).and_then(|()| o.flush()).map_err(crate::common::stdout_error)?;
    } else {
        let mut f = AtomicFile::create(&a.out)?;
        f.write_all(&bytes).with_context(|| format!("writing {}", a.out.display()))?;
        f.commit()?;
    }
    let [w, h] = sheet.size_mm();
    let default = if a.radius.is_none() { format!(" (the default {RADIUS_SHARE}·S)") } else { String::new() };
    eprintln!(
        "evcal: wrote {}: {}x{} asymmetric circle grid, spacing {} m, circle radius {} m{default}, on {} ({} x {} mm); print it at 100 % (no fit-to-page) and check its 50 mm scale bar with a ruler",
        if stdout { "standard output".into() } else { a.out.display().to_string() },
        pattern.rows,
        pattern.cols,
        pattern.spacing,
        sheet.radius(),
        sheet.paper_name(),
        round2(w),
        round2(h),
    );
    Ok(())
}

/// `v` to 0.01, as printed.
fn round2(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}
