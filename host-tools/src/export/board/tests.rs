//! The printed target read back from its SVG: circles where the calibration puts the board
//! points, at true scale, laid out as `Pattern::picture` says, with the caption and scale bar
//! clear of the grid's white margin.

use super::*;
use std::collections::HashMap;

/// Every `<name ...>` element's attributes, in document order: a reader that knows nothing
/// of the writer's formatting (attribute order, spacing).
fn elements(svg: &str, name: &str) -> Vec<HashMap<String, String>> {
    let open = format!("<{name}");
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(at) = rest.find(&open) {
        let after = &rest[at + open.len()..];
        let end = after.find('>').expect("an element's end");
        rest = &after[end..];
        if !after.starts_with(|c: char| c.is_whitespace() || c == '/' || c == '>') {
            continue; // another element whose name starts alike
        }
        let mut attrs = HashMap::new();
        let mut body = &after[..end];
        while let Some(eq) = body.find("=\"") {
            let key = body[..eq].trim().to_string();
            let value_end = body[eq + 2..].find('"').expect("a closing quote");
            attrs.insert(key, body[eq + 2..eq + 2 + value_end].to_string());
            body = &body[eq + 2 + value_end + 1..];
        }
        out.push(attrs);
    }
    out
}

fn f(attrs: &HashMap<String, String>, key: &str) -> f64 {
    attrs.get(key).unwrap_or_else(|| panic!("no {key} in {attrs:?}")).parse().unwrap()
}

fn sheet(pattern: &str, spacing: f64) -> Sheet {
    Sheet::new(Pattern::parse(pattern, spacing).unwrap(), None, None).unwrap()
}

#[test]
fn circles_are_the_board_points_in_millimetres() {
    for (pattern, spacing) in [("4x11", 0.02), ("3x7", 0.034), ("4x6", 0.0125), ("2x3", 0.005)] {
        let s = sheet(pattern, spacing);
        let circles = elements(&s.svg(), "circle");
        let p = s.pattern();
        assert_eq!(circles.len(), p.len(), "{pattern}");
        let o = s.origin_mm();
        for (k, c) in circles.iter().enumerate() {
            let b = p.object_point(k);
            let want = [b[0] * 1000.0 + o[0], b[1] * 1000.0 + o[1]];
            let got = [f(c, "cx"), f(c, "cy")];
            assert!(
                (got[0] - want[0]).abs() < 1e-4 && (got[1] - want[1]).abs() < 1e-4,
                "{pattern} #{k}: {got:?} {want:?}"
            );
            assert_eq!(s.centre_mm(k), want);
            assert!((f(c, "r") - 0.3 * spacing * 1e3).abs() < 0.006, "{pattern}: r {}", f(c, "r"));
        }
        // Points on one column 2·S apart, diagonal neighbours S·√2.
        let d = |a: usize, b: usize| {
            let (a, b) = ([f(&circles[a], "cx"), f(&circles[a], "cy")], [f(&circles[b], "cx"), f(&circles[b], "cy")]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        };
        let s_mm = spacing * 1e3;
        assert!((d(0, 1) - 2.0 * s_mm).abs() < 1e-3);
        assert!((d(0, p.rows) - s_mm * std::f64::consts::SQRT_2).abs() < 1e-3);
    }
}

#[test]
fn the_page_is_its_paper_at_true_scale() {
    // The issue's example fits A4 turned; E-Calib's 24 mm 4x11 needs A3.
    for (pattern, spacing, paper, size) in [
        ("4x11", 0.02, "A4 landscape", [297.0, 210.0]),
        ("4x11", 0.024, "A3 landscape", [420.0, 297.0]),
        ("3x5", 0.01, "A4 portrait", [210.0, 297.0]),
    ] {
        let s = sheet(pattern, spacing);
        assert_eq!(s.paper_name(), paper, "{pattern} {spacing}");
        assert_eq!(s.size_mm(), size);
        let svg = s.svg();
        let root = &elements(&svg, "svg")[0];
        assert_eq!(root["width"], format!("{}mm", size[0]));
        assert_eq!(root["height"], format!("{}mm", size[1]));
        assert_eq!(root["viewBox"], format!("0 0 {} {}", size[0], size[1]));
    }
    let letter = Sheet::new(Pattern::parse("3x5", 0.01).unwrap(), None, Some(Paper::Letter)).unwrap();
    assert_eq!((letter.size_mm(), letter.paper_name().as_str()), ([215.9, 279.4], "Letter portrait"));
    let svg = letter.svg();
    assert_eq!(elements(&svg, "svg")[0]["width"], "215.9mm");
}

/// The page seen from the front is `Pattern::picture`: index 0 at the top left, i to the
/// right, the odd columns a spacing lower.
#[test]
fn the_page_looks_like_the_patterns_picture() {
    for (pattern, spacing) in [("4x11", 0.02), ("3x7", 0.034), ("4x6", 0.015)] {
        let s = sheet(pattern, spacing);
        let p = s.pattern();
        let circles: Vec<[f64; 2]> = elements(&s.svg(), "circle").iter().map(|c| [f(c, "cx"), f(c, "cy")]).collect();
        let x0 = circles.iter().map(|c| c[0]).fold(f64::INFINITY, f64::min);
        let y0 = circles.iter().map(|c| c[1]).fold(f64::INFINITY, f64::min);
        let s_mm = spacing * 1e3;
        let mut lines = vec![vec![b' '; 2 * p.cols - 1]; 2 * p.rows];
        for c in &circles {
            let (col, line) = (((c[0] - x0) / s_mm).round() as usize, ((c[1] - y0) / s_mm).round() as usize);
            lines[line][2 * col] = b'o';
        }
        let drawn: String = lines.into_iter().map(|l| String::from_utf8(l).unwrap() + "\n").collect();
        assert_eq!(drawn, p.picture(), "{pattern}");
        // And circle 0 is the top left one.
        assert_eq!(circles[0], [x0, y0]);
    }
}

#[test]
fn caption_and_scale_bar_are_printed_clear_of_the_grid() {
    let s = sheet("4x11", 0.02);
    let svg = s.svg();
    assert!(svg.contains(
        "evcal 4x11 asymmetric circle grid, spacing 20 mm, circle diameter 12 mm: print at 100 %, no fit-to-page"
    ));
    assert!(svg.contains("--pattern 4x11 --spacing 0.02 --radius 0.006"), "{svg}");
    let [w, h] = s.size_mm();
    let circles = elements(&svg, "circle");
    let r = f(&circles[0], "r");
    let bottom = circles.iter().map(|c| f(c, "cy") + r).fold(0.0, f64::max);
    let margin = 20.0;
    for c in &circles {
        let (x, y) = (f(c, "cx"), f(c, "cy"));
        assert!(x - r >= margin - 1e-9 && x + r <= w - margin + 1e-9 && y - r >= margin - 1e-9, "{c:?}");
    }
    // The text and the bar begin a spacing below the circles and end 5 mm above the paper's edge.
    let texts = elements(&svg, "text");
    assert!(texts.len() >= 3);
    for t in &texts {
        assert!(f(t, "y") - f(t, "font-size") >= bottom + margin - 1e-9 && f(t, "y") <= h - 5.0, "{t:?}");
    }
    // The bar: five 10 mm segments, end to end, 50 mm in all, black and white by turns.
    let bar: Vec<_> = elements(&svg, "rect").into_iter().filter(|r| f(r, "height") == 2.0).collect();
    assert_eq!(bar.len(), 5);
    for (k, seg) in bar.iter().enumerate() {
        assert_eq!(f(seg, "width"), 10.0);
        assert!((f(seg, "x") - f(&bar[0], "x") - 10.0 * k as f64).abs() < 1e-9);
        assert_eq!(seg["fill"], if k % 2 == 0 { "#000" } else { "#fff" });
        assert!(f(seg, "y") >= bottom + margin && f(seg, "y") + 2.0 <= h - 5.0);
    }
    let labels: Vec<String> = texts.iter().filter(|t| t.get("text-anchor").is_some()).map(|t| t["x"].clone()).collect();
    assert_eq!(labels.len(), 6, "a number at each tick");
}

#[test]
fn the_default_radius_is_the_simulators() {
    let board = crate::sim::Board::preset("4x11").unwrap();
    assert_eq!(board.radius / board.spacing, RADIUS_SHARE);
    assert_eq!(sheet("4x11", 0.024).radius(), 0.0072);
    // Rounded to 0.01 mm, so that the caption states what is drawn.
    assert_eq!(sheet("4x11", 0.0123).radius(), 0.00369);
    let given = Sheet::new(Pattern::parse("4x11", 0.02).unwrap(), Some(0.005), None).unwrap();
    assert!(given.svg().contains("circle diameter 10 mm"));
}

#[test]
fn bad_radii_are_refused() {
    let p = Pattern::parse("4x11", 0.02).unwrap();
    for r in [0.0, -0.001, f64::NAN, f64::INFINITY, 0.02 * std::f64::consts::FRAC_1_SQRT_2] {
        let e = Sheet::new(p, Some(r), None).unwrap_err();
        assert!(matches!(e, TargetError::Radius { .. }), "{r}: {e}");
        assert!(e.to_string().contains("half the diagonal spacing"), "{e}");
    }
}

/// A board too large for every paper says which spacing fits, and that spacing does fit
/// while 0.1 mm more does not.
#[test]
fn a_board_too_large_says_the_spacing_that_fits() {
    let p = Pattern::parse("4x11", 0.05).unwrap();
    let e = Sheet::new(p, None, None).unwrap_err();
    let TargetError::DoesNotFit { paper, largest_spacing: Some(sp), .. } = e.clone() else { panic!("{e:?}") };
    assert_eq!(paper, Paper::A3);
    let text = e.to_string();
    assert!(text.contains(&format!("--spacing {}", metres(sp))) && text.contains("--paper fit"), "{text}");
    let fits = |s: f64| Sheet::new(Pattern { spacing: s, ..p }, None, Some(Paper::A3)).is_ok();
    assert!(fits(sp) && !fits(sp + 1e-4), "{sp}");
    assert!(!text.contains("--radius"), "no radius was given: {text}");
    // A radius given is scaled with the spacing, and that fits too.
    let e = Sheet::new(p, Some(0.01), None).unwrap_err();
    let TargetError::DoesNotFit { largest_spacing: Some(sp), .. } = e.clone() else { panic!("{e:?}") };
    assert!(e.to_string().contains(&format!("--radius {} or less", metres(0.2 * sp))), "{e}");
    assert!(Sheet::new(Pattern { spacing: sp, ..p }, Some(0.2 * sp), None).is_ok());
    // On a named paper, the spacing for that paper, and a larger paper suggested.
    let e = Sheet::new(p, None, Some(Paper::A4)).unwrap_err().to_string();
    assert!(e.contains("A4 (210 x 297 mm)") && e.contains("--paper (a3)"), "{e}");
    // A page of its own size holds anything.
    let own = Sheet::new(p, None, Some(Paper::Fit)).unwrap();
    assert_eq!(own.paper_name(), "a page of its own size");
    assert!(own.size_mm()[0] > 500.0 + 100.0);
}

/// The PDF's page is the paper in points, and each circle's path starts a radius right of
/// its board point (read back from the uncompressed content stream).
#[test]
fn the_pdf_is_the_same_page_at_true_scale() {
    let s = sheet("4x11", 0.02);
    let pdf = s.pdf();
    let text = String::from_utf8_lossy(&pdf);
    assert!(text.starts_with("%PDF-"));
    let pt = 72.0 / 25.4;
    let media = text.split("/MediaBox [").nth(1).expect("a MediaBox").split(']').next().unwrap();
    let media: Vec<f64> = media.split_whitespace().map(|v| v.parse().unwrap()).collect();
    assert_eq!(media.len(), 4);
    assert!(media[0] == 0.0 && media[1] == 0.0);
    assert!((media[2] - 297.0 * pt).abs() < 0.01 && (media[3] - 210.0 * pt).abs() < 0.01, "{media:?}");
    // Path starts: `x y m`, one per circle, in the order of the board points.
    let starts: Vec<[f64; 2]> = text
        .lines()
        .filter_map(|l| l.strip_suffix(" m"))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|v| v.parse().unwrap()).collect();
            [v[0], v[1]]
        })
        .collect();
    assert_eq!(starts.len(), s.pattern().len());
    for (k, p) in starts.iter().enumerate() {
        let [cx, cy] = s.centre_mm(k);
        let want = [(cx + 6.0) * pt, (210.0 - cy) * pt];
        assert!((p[0] - want[0]).abs() < 0.01 && (p[1] - want[1]).abs() < 0.01, "#{k}: {p:?} {want:?}");
    }
    assert!(text.contains("/BaseFont /Helvetica"));
    assert!(text.contains(
        "(evcal 4x11 asymmetric circle grid, spacing 20 mm, circle diameter 12 mm: print at 100 %, no fit-to-page) Tj"
    ));
}
