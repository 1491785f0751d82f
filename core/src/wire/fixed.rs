//! The fixed-point form of a circle centre on the wire: pixels in units of 1/1024.
//!
//! Every centre the host records passes through this quantisation, whether it came over the
//! link or from the core running on the host (`evcal detect`), so both print the same bytes.
//! Quantising is total: values are rounded half away from zero, saturate at the integer
//! range, and NaN becomes 0 (the fit never produces NaN; the rule makes the function total).

use crate::fit::Centre;

/// Fractional bits of the pixel quantities on the wire.
pub const FRAC_BITS: u32 = 10;
/// Wire units per pixel (1 << [`FRAC_BITS`]): the resolution is 1/1024 px.
pub const UNITS_PER_PX: f32 = (1u32 << FRAC_BITS) as f32;

/// Pixels to signed wire units.
pub fn px_to_signed(x: f32) -> i32 {
    // `as` saturates and maps NaN to 0; scaling by a power of two is exact.
    libm::roundf(x * UNITS_PER_PX) as i32
}

/// Pixels to unsigned wire units (negative values become 0).
pub fn px_to_unsigned(x: f32) -> u32 {
    libm::roundf(x * UNITS_PER_PX) as u32
}

/// Signed wire units to pixels.
pub fn signed_to_px(q: i32) -> f32 {
    q as f32 / UNITS_PER_PX
}

/// Unsigned wire units to pixels.
pub fn unsigned_to_px(q: u32) -> f32 {
    q as f32 / UNITS_PER_PX
}

/// A circle centre as it crosses the link. The cylinder's tilt (`vu`, `vv`) stays on the
/// device: the host needs only where the circle was at the window's reference time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireCentre {
    /// Centre column at `t_ref`, 1/1024 px.
    pub u: i32,
    /// Centre row at `t_ref`, 1/1024 px.
    pub v: i32,
    /// Radius, 1/1024 px.
    pub r: u32,
    /// Weighted RMS distance of the events from the circle, 1/1024 px.
    pub spread: u32,
    /// Events in the cluster.
    pub n: u16,
    /// Whether the fit converged.
    pub converged: bool,
}

impl WireCentre {
    /// The wire form of a fitted centre.
    pub fn from_centre(c: &Centre) -> Self {
        Self {
            u: px_to_signed(c.u),
            v: px_to_signed(c.v),
            r: px_to_unsigned(c.r),
            spread: px_to_unsigned(c.spread),
            n: c.n,
            converged: c.converged,
        }
    }

    /// Centre column, pixels.
    pub fn u_px(&self) -> f32 {
        signed_to_px(self.u)
    }

    /// Centre row, pixels.
    pub fn v_px(&self) -> f32 {
        signed_to_px(self.v)
    }

    /// Radius, pixels.
    pub fn r_px(&self) -> f32 {
        unsigned_to_px(self.r)
    }

    /// Spread, pixels.
    pub fn spread_px(&self) -> f32 {
        unsigned_to_px(self.spread)
    }
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn rounds_to_the_nearest_unit_and_saturates() {
        assert_eq!(px_to_signed(1.0), 1024);
        assert_eq!(px_to_signed(-0.5 / 1024.0), -1, "half away from zero");
        assert_eq!(px_to_signed(0.49 / 1024.0), 0);
        assert_eq!(px_to_signed(f32::NAN), 0);
        assert_eq!(px_to_signed(1e30), i32::MAX);
        assert_eq!(px_to_signed(-1e30), i32::MIN);
        assert_eq!(px_to_unsigned(-3.0), 0);
        assert_eq!(px_to_unsigned(f32::INFINITY), u32::MAX);
        assert_eq!(signed_to_px(px_to_signed(123.456)), 123.456_055);
    }

    #[test]
    fn quantisation_error_is_at_most_half_a_unit() {
        for i in 0..10_000 {
            let x = i as f32 * 0.0731 - 50.0;
            let back = signed_to_px(px_to_signed(x));
            assert!((back - x).abs() <= 0.5 / UNITS_PER_PX + 1e-5, "{x} -> {back}");
            // quantising a quantised value changes nothing
            assert_eq!(px_to_signed(back), px_to_signed(x));
        }
    }
}
