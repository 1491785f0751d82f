//! A printable asymmetric circle grid at true scale (`evcal target`): the board evcal's grid
//! finder expects, on a page with the pattern, spacing and radius printed beside it and a
//! scale bar to check the print with a ruler.
//!
//! The layout is the [grid module's](crate::views::grid) convention, seen from the front:
//! board point (i, j) at (i·S, (2j + i mod 2)·S) from the top left circle, x to the right and
//! y down the page, so that the page looks like [`Pattern::picture`]. Units on the page are
//! millimetres: the SVG's `viewBox` is in mm and its `width`/`height` say `mm`, and the PDF's
//! page is the paper in points ([`Sheet::pdf`]), so a viewer or printer at 100 % puts every
//! circle where the calibration assumes it.
//!
//! ```
//! use evcal_host::export::board::Sheet;
//! use evcal_host::views::grid::Pattern;
//! let sheet = Sheet::new(Pattern::parse("4x11", 0.02).unwrap(), None, None).unwrap();
//! assert_eq!(sheet.paper_name(), "A4 landscape");
//! assert!(sheet.svg().contains(r#"width="297mm""#));
//! ```

use crate::views::grid::Pattern;
use std::fmt::Write as _;

/// The circles' radius as a share of the spacing S when none is given: a diameter of 0.6·S,
/// what the simulator's boards have (`sim::scene::Board::preset`) and common printed grids
/// do. Large enough to image many pixels across, small enough to leave the white between
/// diagonal neighbours (S·√2 apart) wider than a circle's radius.
pub const RADIUS_SHARE: f64 = 0.3;

/// Nearest a mark comes to the paper's edge, mm: most printers leave 3 to 5 mm unprinted.
const EDGE_MM: f64 = 5.0;
/// Height of the caption under the grid (title, scale bar and its labels), mm.
const CAPTION_MM: f64 = 12.0;
/// The scale bar's length and its ticks, mm.
const BAR_MM: f64 = 50.0;
const TICK_MM: f64 = 10.0;
/// Font sizes, mm: the title, the line beside the bar, the bar's numbers.
const TITLE_FONT: f64 = 3.0;
const NOTE_FONT: f64 = 2.8;
const LABEL_FONT: f64 = 2.5;
/// A wide guess of a line's width per character and mm of font size (Helvetica's letters
/// average about 0.5 em): the page is chosen so that the caption fits.
const CHAR_EM: f64 = 0.6;

/// A paper size to lay the target out on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paper {
    /// ISO A4, 210 x 297 mm.
    A4,
    /// US Letter, 8.5 x 11 in (215.9 x 279.4 mm).
    Letter,
    /// ISO A3, 297 x 420 mm.
    A3,
    /// A page just the size of the grid, its margin and caption: for a print shop or plotter.
    Fit,
}

impl Paper {
    /// The papers tried when none is given, smallest first. Letter is left to `--paper
    /// letter`: neither it nor A4 holds the other, and an A4 page printed on Letter at 100 %
    /// loses its bottom edge (and the reverse its sides).
    pub const DEFAULTS: [Paper; 2] = [Paper::A4, Paper::A3];

    /// Width and height in portrait, mm (`None` for [`Paper::Fit`]).
    pub fn portrait_mm(self) -> Option<[f64; 2]> {
        match self {
            Paper::A4 => Some([210.0, 297.0]),
            Paper::Letter => Some([215.9, 279.4]),
            Paper::A3 => Some([297.0, 420.0]),
            Paper::Fit => None,
        }
    }

    /// Its name, as printed.
    pub fn name(self) -> &'static str {
        match self {
            Paper::A4 => "A4",
            Paper::Letter => "Letter",
            Paper::A3 => "A3",
            Paper::Fit => "a page of its own size",
        }
    }
}

/// Why no target was laid out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TargetError {
    /// The radius is not a length between 0 and half the diagonal spacing.
    #[error("radius {radius} m: a circle's radius must be above 0 and below half the diagonal spacing, {:.4} m with spacing {spacing} m (neighbouring circles would touch)", spacing * std::f64::consts::FRAC_1_SQRT_2)]
    Radius {
        /// The radius given, metres.
        radius: f64,
        /// The pattern's spacing, metres.
        spacing: f64,
    },
    /// The target does not fit the paper in either orientation.
    #[error("{}", does_not_fit(*pattern, *radius, *radius_given, *paper, *needs_mm, *largest_spacing))]
    DoesNotFit {
        /// The pattern.
        pattern: Pattern,
        /// The circles' radius, metres.
        radius: f64,
        /// Whether the radius was given (else the default share of the spacing).
        radius_given: bool,
        /// The largest paper tried.
        paper: Paper,
        /// The page the target needs (grid, margins, caption), mm.
        needs_mm: [f64; 2],
        /// The largest spacing (metres, in 0.1 mm steps) whose target fits that paper, the
        /// radius scaled alike; `None` if not even 1 mm does.
        largest_spacing: Option<f64>,
    },
}

fn does_not_fit(
    pattern: Pattern,
    radius: f64,
    given: bool,
    paper: Paper,
    needs: [f64; 2],
    largest: Option<f64>,
) -> String {
    let dims = paper.portrait_mm().unwrap_or_default();
    let mut s = format!(
        "a {}x{} grid with spacing {} mm and circle diameter {} mm needs {} x {} mm with its white margin and caption; {} ({} x {} mm) holds it in neither orientation",
        pattern.rows,
        pattern.cols,
        mm(pattern.spacing * 1e3),
        mm(2e3 * radius),
        mm(needs[0]),
        mm(needs[1]),
        paper.name(),
        mm(dims[0]),
        mm(dims[1]),
    );
    if let Some(sp) = largest {
        let _ = write!(s, ": give --spacing {} or less", metres(sp));
        if given {
            let _ = write!(s, " (and --radius {} or less alike)", metres(radius / pattern.spacing * sp));
        }
    }
    if paper != Paper::A3 {
        s.push_str(", a larger --paper (a3)");
    }
    s.push_str(", or --paper fit for a page of its own size");
    s
}

/// A target laid out on a page.
#[derive(Debug, Clone, PartialEq)]
pub struct Sheet {
    pattern: Pattern,
    radius: f64,
    paper: Paper,
    landscape: bool,
    size_mm: [f64; 2],
    /// Where board point (0, 0) lies on the page, mm from its top left corner.
    origin_mm: [f64; 2],
    /// The caption's top left corner, mm.
    caption_mm: [f64; 2],
}

/// The page a target needs and where its parts go, before it is put on a paper.
struct Block {
    size: [f64; 2],
    /// The grid's first circle's centre and the caption's corner, from the block's corner.
    origin: [f64; 2],
    caption: [f64; 2],
}

impl Sheet {
    /// Lays out `pattern` with circles of `radius` metres (default [`default_radius`]) on
    /// `paper`, or on the first of [`Paper::DEFAULTS`] that holds it.
    /// Portrait is taken when it holds the target, else landscape.
    pub fn new(pattern: Pattern, radius: Option<f64>, paper: Option<Paper>) -> Result<Self, TargetError> {
        let spacing = pattern.spacing;
        let radius_given = radius.is_some();
        let radius = radius.unwrap_or(default_radius(spacing));
        if !(radius.is_finite() && radius > 0.0 && radius < spacing * std::f64::consts::FRAC_1_SQRT_2) {
            return Err(TargetError::Radius { radius, spacing });
        }
        let block = block(&pattern, radius);
        let papers: &[Paper] = match &paper {
            Some(p) => std::slice::from_ref(p),
            None => &Paper::DEFAULTS,
        };
        for &p in papers {
            if let Some((size, landscape)) = place(p, block.size) {
                // The block in the middle of the page.
                let off = [(size[0] - block.size[0]) / 2.0, (size[1] - block.size[1]) / 2.0];
                let at = |v: [f64; 2]| [off[0] + v[0], off[1] + v[1]];
                return Ok(Self {
                    pattern,
                    radius,
                    paper: p,
                    landscape,
                    size_mm: size,
                    origin_mm: at(block.origin),
                    caption_mm: at(block.caption),
                });
            }
        }
        let paper = *papers.last().unwrap_or(&Paper::A3);
        Err(TargetError::DoesNotFit {
            pattern,
            radius,
            radius_given,
            paper,
            needs_mm: block.size,
            largest_spacing: largest_spacing(&pattern, radius_given.then_some(radius / spacing), paper),
        })
    }

    /// The pattern.
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// The circles' radius, metres.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The paper and whether the page is in landscape.
    pub fn paper(&self) -> (Paper, bool) {
        (self.paper, self.landscape)
    }

    /// The paper as said to the user: "A4 portrait", "A3 landscape", "a page of its own size".
    pub fn paper_name(&self) -> String {
        match self.paper {
            Paper::Fit => Paper::Fit.name().to_string(),
            p => format!("{} {}", p.name(), if self.landscape { "landscape" } else { "portrait" }),
        }
    }

    /// Width and height of the page, mm.
    pub fn size_mm(&self) -> [f64; 2] {
        self.size_mm
    }

    /// Where board point (0, 0) lies on the page, mm from its top left corner (y down).
    pub fn origin_mm(&self) -> [f64; 2] {
        self.origin_mm
    }

    /// Where the centre of circle `index` (`i·rows + j`) lies on the page, mm from its top
    /// left corner: its board point in mm plus [`Sheet::origin_mm`].
    pub fn centre_mm(&self, index: usize) -> [f64; 2] {
        let p = self.pattern.object_point(index);
        [self.origin_mm[0] + p[0] * 1e3, self.origin_mm[1] + p[1] * 1e3]
    }

    /// The line printed under the grid: pattern, spacing, diameter and how to print.
    pub fn title(&self) -> String {
        title(&self.pattern, self.radius)
    }

    /// The line beside the scale bar: what to check, and the options that match the board.
    pub fn note(&self) -> String {
        note(&self.pattern, self.radius)
    }

    /// The page as an SVG document at true scale (units mm).
    pub fn svg(&self) -> String {
        let [w, h] = self.size_mm;
        let mut s = String::with_capacity(4096 + 60 * self.pattern.len());
        let _ = writeln!(s, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}mm" height="{}mm" viewBox="0 0 {} {}">"#,
            num(w),
            num(h),
            num(w),
            num(h)
        );
        let _ = writeln!(s, "<title>{}</title>", escape(&self.title()));
        let _ = writeln!(s, r##"<rect width="{}" height="{}" fill="#fff"/>"##, num(w), num(h));
        let _ = writeln!(s, r##"<g id="grid" fill="#000">"##);
        for k in 0..self.pattern.len() {
            let [x, y] = self.centre_mm(k);
            let _ = writeln!(s, r#"<circle cx="{}" cy="{}" r="{}"/>"#, num(x), num(y), num(self.radius * 1e3));
        }
        s.push_str("</g>\n");
        let font = r##"font-family="Helvetica, Arial, sans-serif" fill="#000""##;
        for t in self.texts() {
            let anchor = if t.centred { r#" text-anchor="middle""# } else { "" };
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" font-size="{}" {font}{anchor}>{}</text>"#,
                num(t.at[0]),
                num(t.at[1]),
                num(t.size),
                escape(&t.text)
            );
        }
        let _ = writeln!(s, r##"<g id="scale-bar" stroke="#000" stroke-width="0.2">"##);
        for b in self.bar() {
            let fill = if b.filled { "#000" } else { "#fff" };
            let _ = writeln!(
                s,
                r#"<rect x="{}" y="{}" width="{}" height="{}" fill="{fill}"/>"#,
                num(b.x),
                num(b.y),
                num(b.w),
                num(b.h)
            );
        }
        s.push_str("</g>\n</svg>\n");
        s
    }

    /// The caption's lines of text: baseline position (mm), font size (mm), whether centred
    /// on the position.
    fn texts(&self) -> Vec<Text> {
        let [cx, cy] = self.caption_mm;
        let mut t = vec![Text { at: [cx, cy + 3.0], size: TITLE_FONT, text: self.title(), centred: false }];
        let ticks = (BAR_MM / TICK_MM).round() as usize;
        for k in 0..=ticks {
            let v = k as f64 * TICK_MM;
            t.push(Text { at: [cx + v, cy + 7.0], size: LABEL_FONT, text: mm(v), centred: true });
        }
        t.push(Text { at: [cx + BAR_MM + 4.0, cy + 11.0], size: NOTE_FONT, text: self.note(), centred: false });
        t
    }

    /// The scale bar: [`BAR_MM`] in [`TICK_MM`] segments, black and white by turns, and a
    /// tick above each segment's ends.
    fn bar(&self) -> Vec<Rect> {
        let [cx, cy] = self.caption_mm;
        let ticks = (BAR_MM / TICK_MM).round() as usize;
        let mut r: Vec<Rect> = (0..ticks)
            .map(|k| Rect { x: cx + k as f64 * TICK_MM, y: cy + 9.0, w: TICK_MM, h: 2.0, filled: k % 2 == 0 })
            .collect();
        // Ticks: thin filled rectangles centred on each division.
        r.extend((0..=ticks).map(|k| Rect {
            x: cx + k as f64 * TICK_MM - 0.1,
            y: cy + 7.6,
            w: 0.2,
            h: 1.4,
            filled: true,
        }));
        r
    }
}

struct Text {
    at: [f64; 2],
    size: f64,
    text: String,
    centred: bool,
}

struct Rect {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    filled: bool,
}

fn title(pattern: &Pattern, radius: f64) -> String {
    format!(
        "evcal {}x{} asymmetric circle grid, spacing {} mm, circle diameter {} mm: print at 100 %, no fit-to-page",
        pattern.rows,
        pattern.cols,
        mm(pattern.spacing * 1e3),
        mm(radius * 2e3),
    )
}

fn note(pattern: &Pattern, radius: f64) -> String {
    format!(
        "mm: check with a ruler. Calibrate with --pattern {}x{} --spacing {} --radius {}",
        pattern.rows,
        pattern.cols,
        metres(pattern.spacing),
        metres(radius)
    )
}

/// The target's parts on a block of its own size: a white margin of max(S, [`EDGE_MM`])
/// around the circles (the finder needs white around the grid, and a printer cannot print
/// the edge), the caption under it, [`EDGE_MM`] from the block's edges.
fn block(pattern: &Pattern, radius: f64) -> Block {
    let (s, r) = (pattern.spacing * 1e3, radius * 1e3);
    let q = s.max(EDGE_MM);
    let grid = [(pattern.cols - 1) as f64 * s + 2.0 * r, (2 * pattern.rows - 1) as f64 * s + 2.0 * r];
    let title = width(&title(pattern, radius), TITLE_FONT);
    let line2 = BAR_MM + 4.0 + width(&note(pattern, radius), NOTE_FONT);
    let caption_w = title.max(line2);
    // The caption is no circle: it may reach into the margin beside the grid, not the edge.
    let w = (grid[0] + 2.0 * q).max(caption_w + 2.0 * EDGE_MM);
    let size = [w, q + grid[1] + q + CAPTION_MM + EDGE_MM];
    Block { size, origin: [(w - grid[0]) / 2.0 + r, q + r], caption: [(w - caption_w) / 2.0, q + grid[1] + q] }
}

/// A line's width at `font` mm, by [`CHAR_EM`].
fn width(text: &str, font: f64) -> f64 {
    text.chars().count() as f64 * CHAR_EM * font
}

/// The page of `paper` that holds a block of `need` mm, portrait first, and whether it is in
/// landscape.
fn place(paper: Paper, need: [f64; 2]) -> Option<([f64; 2], bool)> {
    let Some([w, h]) = paper.portrait_mm() else {
        return Some((need, need[0] > need[1]));
    };
    if need[0] <= w && need[1] <= h {
        Some(([w, h], false))
    } else if need[0] <= h && need[1] <= w {
        Some(([h, w], true))
    } else {
        None
    }
}

/// The radius drawn when none is given: [`RADIUS_SHARE`]·`spacing` rounded to 0.01 mm, so
/// that the caption states what is drawn.
pub fn default_radius(spacing: f64) -> f64 {
    (RADIUS_SHARE * spacing * 1e5).round() / 1e5
}

/// The largest spacing, in 0.1 mm steps from 1 mm, whose target fits `paper`: radius
/// `share`·S, or the default radius.
fn largest_spacing(pattern: &Pattern, share: Option<f64>, paper: Paper) -> Option<f64> {
    let fits = |tenths: u32| {
        let s = f64::from(tenths) * 1e-4;
        let r = share.map_or_else(|| default_radius(s), |k| k * s);
        place(paper, block(&Pattern { spacing: s, ..*pattern }, r).size).is_some()
    };
    // The given spacing does not fit (nor, as every size grows with it, any larger one).
    let (mut lo, mut hi) = (10u32, (pattern.spacing * 1e4).ceil().clamp(11.0, 1e7) as u32);
    if !fits(lo) {
        return None;
    }
    // Every size grows with the spacing, so the fit is lost once: bisect for that point.
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(f64::from(lo) * 1e-4)
}

/// Millimetres as printed: to 0.01 mm, no trailing zeros.
fn mm(v: f64) -> String {
    trim(format!("{v:.2}"))
}

/// Metres as given on the command line: to 0.1 µm, no trailing zeros.
fn metres(v: f64) -> String {
    trim(format!("{v:.7}"))
}

/// A coordinate in the SVG, mm: to 0.1 µm.
fn num(v: f64) -> String {
    trim(format!("{v:.4}"))
}

fn trim(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

mod pdf;
#[cfg(test)]
mod tests;
