//! The median, one definition for the whole host library: the grid finder's radii, the
//! views' circle radius, the edge-shift's thickness and the solver's errors all take it.

/// The median of `x` (reordered): for an even count the upper of the two middle values, so
/// that the median is always one of the values (a radius, an error that was measured), never
/// a mean of two. NaNs are left out (moved to the end of `x`); `None` when no value is left.
pub(crate) fn median(x: &mut [f64]) -> Option<f64> {
    // The numbers to the front, in place: a NaN has no place in an order of values.
    let mut n = 0;
    for i in 0..x.len() {
        if !x[i].is_nan() {
            x.swap(n, i);
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    let (_, m, _) = x[..n].select_nth_unstable_by(n / 2, f64::total_cmp);
    Some(*m)
}

/// The median of `x` and the median absolute deviation from it, as [`median`] takes them
/// (NaNs left out); `None` when `x` holds no number.
pub(crate) fn median_mad(x: &[f64]) -> Option<(f64, f64)> {
    let mut s = x.to_vec();
    let m = median(&mut s)?;
    let mut d: Vec<f64> = s.iter().filter(|v| !v.is_nan()).map(|v| (v - m).abs()).collect();
    Some((m, median(&mut d)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_is_the_middle_value_or_the_upper_middle_one_and_leaves_nans_out() {
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [f64::NAN, f64::NAN]), None);
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        // An even count: the upper middle value, one of those given.
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), Some(3.0));
        // NaNs anywhere, of either sign, count for nothing.
        assert_eq!(median(&mut [f64::NAN, 5.0, -f64::NAN, 1.0, 3.0]), Some(3.0));
        assert_eq!(median(&mut [f64::INFINITY, 0.0, f64::NEG_INFINITY]), Some(0.0));
        // As sorting and taking the middle does.
        let mut x: Vec<f64> = (0..101).map(|i| ((i * 37) % 101) as f64 * 0.5).collect();
        let mut sorted = x.clone();
        sorted.sort_by(f64::total_cmp);
        assert_eq!(median(&mut x), Some(sorted[50]));
    }

    #[test]
    fn median_mad_gives_the_spread_about_the_median() {
        assert_eq!(median_mad(&[]), None);
        assert_eq!(median_mad(&[1.0, 2.0, 4.0, 8.0, f64::NAN]), Some((4.0, 3.0)));
        assert_eq!(median_mad(&[7.0]), Some((7.0, 0.0)));
    }
}
