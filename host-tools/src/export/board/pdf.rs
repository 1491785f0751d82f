//! The sheet as a one-page PDF at true scale: the same circles, text and scale bar as the
//! SVG, in points (1/72 in) from the page's bottom left corner, the text in Helvetica, one
//! of the standard fonts every PDF reader has (nothing embedded).

use super::{Rect as Box, Sheet};
use pdf_writer::{Content, Finish, Name, Pdf, Rect, Ref, Str, TextStr};

/// Points per millimetre.
const PT: f64 = 72.0 / 25.4;
/// A quarter circle's Bézier handle, as a share of the radius (its midpoint on the circle).
const KAPPA: f64 = 0.552_284_749_8;
/// Helvetica's digits are 556/1000 em wide: the bar's numbers are centred on their ticks by it.
const DIGIT_EM: f64 = 0.556;

impl Sheet {
    /// The page as a PDF document at true scale (its MediaBox the paper's size in points).
    pub fn pdf(&self) -> Vec<u8> {
        let [w, h] = self.size_mm;
        // Page coordinates: mm from the top left (the SVG's) to points from the bottom left.
        let x = |v: f64| (v * PT) as f32;
        let y = |v: f64| ((h - v) * PT) as f32;
        let mut c = Content::new();
        c.set_fill_gray(0.0);
        let r = self.radius * 1e3;
        let k = r * KAPPA;
        for i in 0..self.pattern.len() {
            let [cx, cy] = self.centre_mm(i);
            // Four quarter arcs, counter-clockwise on the page from the rightmost point.
            c.move_to(x(cx + r), y(cy));
            c.cubic_to(x(cx + r), y(cy - k), x(cx + k), y(cy - r), x(cx), y(cy - r));
            c.cubic_to(x(cx - k), y(cy - r), x(cx - r), y(cy - k), x(cx - r), y(cy));
            c.cubic_to(x(cx - r), y(cy + k), x(cx - k), y(cy + r), x(cx), y(cy + r));
            c.cubic_to(x(cx + k), y(cy + r), x(cx + r), y(cy + k), x(cx + r), y(cy));
            c.close_path();
        }
        c.fill_nonzero();
        let font = Name(b"F1");
        for t in self.texts() {
            let dx = if t.centred { t.text.len() as f64 * DIGIT_EM * t.size / 2.0 } else { 0.0 };
            c.begin_text();
            c.set_font(font, (t.size * PT) as f32);
            c.next_line(x(t.at[0] - dx), y(t.at[1]));
            c.show(Str(t.text.as_bytes()));
            c.end_text();
        }
        c.set_line_width((0.2 * PT) as f32);
        for Box { x: bx, y: by, w: bw, h: bh, filled } in self.bar() {
            c.set_fill_gray(if filled { 0.0 } else { 1.0 });
            c.rect(x(bx), y(by + bh), (bw * PT) as f32, (bh * PT) as f32);
            c.fill_nonzero_and_stroke();
        }

        let (catalog, pages, page, font_id, content, info) =
            (Ref::new(1), Ref::new(2), Ref::new(3), Ref::new(4), Ref::new(5), Ref::new(6));
        let mut pdf = Pdf::new();
        pdf.catalog(catalog).pages(pages);
        pdf.pages(pages).kids([page]).count(1);
        let mut p = pdf.page(page);
        p.media_box(Rect::new(0.0, 0.0, (w * PT) as f32, (h * PT) as f32));
        p.parent(pages);
        p.contents(content);
        p.resources().fonts().pair(font, font_id);
        p.finish();
        pdf.type1_font(font_id).base_font(Name(b"Helvetica"));
        pdf.stream(content, &c.finish());
        pdf.document_info(info).title(TextStr(&self.title())).creator(TextStr("evcal target"));
        pdf.finish()
    }
}
