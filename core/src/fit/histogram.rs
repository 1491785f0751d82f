//! The histogram of absolute residuals that gives the robust scale of the weights.

/// Histogram of absolute residuals for the robust scale: bin width (px) and count.
const HIST_BIN: f32 = 0.125;
const HIST_BINS: usize = 64;

/// Histogram of absolute residuals, for their median without a sort or a buffer.
pub(super) struct Histogram {
    bins: [u16; HIST_BINS],
    pub(super) count: u32,
}

impl Histogram {
    pub(super) const fn new() -> Self {
        Self { bins: [0; HIST_BINS], count: 0 }
    }

    /// Counts one residual in its bin; `count` is set once the pass is done (a store per
    /// event saved).
    #[inline]
    pub(super) fn add(&mut self, abs_residual: f32) {
        // The last bin collects everything beyond the histogram (a NaN casts to bin 0).
        let k = ((abs_residual * (1.0 / HIST_BIN)) as usize).min(HIST_BINS - 1);
        // A fit takes at most `u16::MAX` events (see `fit_from`): no bin overflows.
        debug_assert!(self.bins[k] < u16::MAX, "more residuals in one pass than a fit takes events");
        self.bins[k] = self.bins[k].wrapping_add(1);
    }

    /// The median, interpolated within its bin.
    pub(super) fn median(&self) -> f32 {
        let half = self.count as f32 * 0.5;
        let mut acc = 0.0f32;
        for (k, &c) in self.bins.iter().enumerate() {
            let c = f32::from(c);
            if acc + c >= half && c > 0.0 {
                return (k as f32 + (half - acc) / c) * HIST_BIN;
            }
            acc += c;
        }
        HIST_BINS as f32 * HIST_BIN
    }
}
