//! The board's layout: an asymmetric circle grid of ROWSxCOLS and where each of its
//! circles lies on the board (the convention is in the [grid module's docs](super)).

/// An asymmetric circle grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pattern {
    /// Rows: circles per column (j < rows).
    pub rows: usize,
    /// Columns (i < cols).
    pub cols: usize,
    /// Spacing S, metres: circles on one column are 2·S apart, diagonal neighbours S·√2.
    pub spacing: f64,
}

/// Largest pattern side accepted (the wire carries at most 96 centres a window anyway).
pub const MAX_PATTERN_SIDE: usize = 64;

impl Pattern {
    /// A pattern of `rows` x `cols` circles, `spacing` metres.
    pub fn new(rows: usize, cols: usize, spacing: f64) -> Result<Self, String> {
        if !(2..=MAX_PATTERN_SIDE).contains(&rows) || !(3..=MAX_PATTERN_SIDE).contains(&cols) {
            return Err(format!(
                "pattern {rows}x{cols}: an asymmetric circle grid needs 2 to {MAX_PATTERN_SIDE} rows and 3 to {MAX_PATTERN_SIDE} columns"
            ));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(format!("spacing {spacing}: must be a positive length in metres (e.g. 0.024)"));
        }
        Ok(Self { rows, cols, spacing })
    }

    /// Parses `ROWSxCOLS` (e.g. `4x11`).
    pub fn parse(text: &str, spacing: f64) -> Result<Self, String> {
        let bad = || format!("pattern '{text}': expected ROWSxCOLS, e.g. 4x11 (4 circles per column, 11 columns)");
        let (r, c) = text.trim().split_once(['x', 'X']).ok_or_else(bad)?;
        let rows = r.trim().parse().map_err(|_| bad())?;
        let cols = c.trim().parse().map_err(|_| bad())?;
        Self::new(rows, cols, spacing)
    }

    /// Number of circles.
    pub fn len(&self) -> usize {
        self.rows * self.cols
    }

    /// Whether the pattern has no circles (never, for a pattern made by [`Pattern::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The board point of circle `index` (`i·rows + j`), metres.
    pub fn object_point(&self, index: usize) -> [f64; 3] {
        let (i, j) = (index / self.rows, index % self.rows);
        [i as f64 * self.spacing, (2 * j + i % 2) as f64 * self.spacing, 0.0]
    }

    /// Every board point, by index.
    pub fn object_points(&self) -> Vec<[f64; 3]> {
        (0..self.len()).map(|k| self.object_point(k)).collect()
    }

    /// The layout as text, to compare with the printed board: one line per board row
    /// (y = 0, S, 2S, ...), `o` a circle, index 0 at the top left and i growing to the right.
    pub fn picture(&self) -> String {
        let mut s = String::new();
        for k in 0..2 * self.rows {
            for i in 0..self.cols {
                s.push(if (k + i) % 2 == 0 { 'o' } else { ' ' });
                if i + 1 < self.cols {
                    s.push(' ');
                }
            }
            s.push('\n');
        }
        s
    }
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn pattern_text_and_points() {
        let p = Pattern::parse("4x11", 0.024).unwrap();
        assert_eq!((p.rows, p.cols, p.len()), (4, 11, 44));
        let o = p.object_point(5);
        assert!((o[0] - 0.024).abs() < 1e-12 && (o[1] - 0.072).abs() < 1e-12 && o[2] == 0.0);
        assert!(Pattern::parse("4-11", 0.02).unwrap_err().contains("ROWSxCOLS"));
        assert!(Pattern::parse("1x11", 0.02).is_err());
        assert!(Pattern::new(4, 11, -1.0).is_err());
        assert_eq!(p.picture().lines().next().unwrap(), "o   o   o   o   o   o");
    }
}
