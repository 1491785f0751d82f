//! The few floating-point functions the hot loops need, in plain `f32` arithmetic: fast on
//! the Cortex-M4F (whose FPU has no exponential, and whose `libm` square root is done in
//! software), and bit-identical on every machine, since they are only IEEE additions,
//! multiplications and bit operations in a fixed order.

/// `1/√x` for finite `x > 0`, to about 5e-6 relative (5e-5 px on a circle of 10 px, a
/// hundredth of what the fit resolves): the classic bit-level estimate (within 3.5 %) refined
/// by two Newton steps, each of which roughly squares the relative error (1.7e-3, then 4e-6).
#[inline]
pub(crate) fn inv_sqrt(x: f32) -> f32 {
    let mut y = f32::from_bits(0x5f37_5a86u32.wrapping_sub(x.to_bits() >> 1));
    let half = 0.5 * x;
    y *= 1.5 - half * y * y;
    y *= 1.5 - half * y * y;
    y
}

/// `√x` for finite `x ≥ 0` (0 gives 0), from [`inv_sqrt`]: to 5 parts in a million, not
/// correctly rounded ([`sqrt_exact`] is).
#[inline]
pub(crate) fn sqrt_approx(x: f32) -> f32 {
    if x > 0.0 {
        x * inv_sqrt(x)
    } else {
        0.0
    }
}

/// `√x` correctly rounded, as IEEE 754 defines it (`sqrt_exact(x)` equals libm's `sqrtf(x)`
/// bit for bit): the FPU's `vsqrt.f32` on an ARM hard-float target, where libm's is done in
/// software (some 60 instructions a call), and libm's elsewhere.
#[inline]
pub(crate) fn sqrt_exact(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        // Through a core register and s0 (declared clobbered): Rust's checker allows the FPU's
        // register classes only with double precision (vfp2), which the M4F lacks, though its
        // single-precision `vsqrt.f32` is all this needs.
        let r: u32;
        // SAFETY: FPU instructions on registers only, s0 declared clobbered; the hard-float
        // ABI guarantees the FPU is there and enabled.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {r}, s0",
                x = in(reg) x.to_bits(),
                r = lateout(reg) r,
                out("s0") _,
                options(pure, nomem, nostack),
            );
        }
        f32::from_bits(r)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// `x.max(y)` as libm's `fmaxf` takes it (`y` when `x` is NaN or below it, else `x`), inline:
/// the M4F has no instruction for it, and `f32::max` was a call into libm every time.
#[inline(always)]
pub(crate) fn max(x: f32, y: f32) -> f32 {
    if x.is_nan() || x < y {
        y
    } else {
        x
    }
}

/// `exp(−z)` for `0 ≤ z ≤ 26`, to about 4e-6 relative: `2^(−m)`, `m = z·log₂e`, split into an
/// integer power (built in the exponent bits) and a polynomial for the fraction. A tenth of
/// libm's `expf` on the M4F.
#[inline]
pub(crate) fn exp_neg(z: f32) -> f32 {
    // In [0, 38].
    let m = z * core::f32::consts::LOG2_E;
    // Truncation is the floor for m ≥ 0. 2^(−m) = 2^(−k−1) · 2^g with g = (k + 1) − m in
    // (0, 1]: the same g, to the bit, as the fraction −m − ⌊−m⌋ of a floor taken below zero,
    // and for an integer m (g = 1) the polynomial gives exactly 2, so that the result is
    // exactly 2^(−m) either way; no comparison is needed to correct a truncation.
    let k = m as i32;
    // k + 1 added as a float (exactly, k being small): the integer k converted back from its
    // float register, where (k + 1) as f32 took it through a core register and back.
    let g = (k as f32 + 1.0) - m;
    // 2^g on [0, 1]: a degree-4 polynomial fitted to it for the least largest relative error
    // (3.5e-6) with p(0) = 1 and p(1) = 2 (exactly, in f32), so that the pieces join at the
    // integers.
    let poly = 1.0 + g * (0.693_032_7 + g * (0.241_378_17 + g * (0.052_032_858 + g * 0.013_556_263)));
    let scale = f32::from_bits(((126 - k) as u32) << 23);
    poly * scale
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn inverse_square_root_is_accurate() {
        let mut x = 1e-6f32;
        while x < 1e9 {
            let (got, want) = (f64::from(inv_sqrt(x)), 1.0 / f64::from(x).sqrt());
            assert!(((got - want) / want).abs() < 5e-6, "x {x}: {got} vs {want}");
            let (got, want) = (f64::from(sqrt_approx(x)), f64::from(x).sqrt());
            assert!(((got - want) / want).abs() < 5e-6, "x {x}: {got} vs {want}");
            x *= 1.37;
        }
        assert_eq!(sqrt_approx(0.0), 0.0);
    }

    #[test]
    fn exact_square_root_is_correctly_rounded() {
        // f64's square root rounded to f32 is the correctly rounded one (53 ≥ 2·24 + 2 bits).
        for b in (0..0x7f80_0000u32).step_by(4099) {
            let x = f32::from_bits(b);
            assert_eq!(sqrt_exact(x).to_bits(), (f64::from(x).sqrt() as f32).to_bits(), "x {x:e}");
        }
    }

    /// The exponential as it was computed before (a floor of −m by truncation and a
    /// correction): the present one must give the same bits.
    fn exp_neg_by_floor(z: f32) -> f32 {
        let y = -z * core::f32::consts::LOG2_E;
        let trunc = y as i32;
        let k = if (trunc as f32) > y { trunc - 1 } else { trunc };
        let f = y - k as f32;
        let poly = 1.0 + f * (0.693_032_7 + f * (0.241_378_17 + f * (0.052_032_858 + f * 0.013_556_263)));
        poly * f32::from_bits(((k + 127) as u32) << 23)
    }

    #[test]
    fn exponential_equals_the_floor_form_bit_for_bit() {
        // Every 97th float in [0, 26] (some 11 million), and every z whose m = z·log₂e is
        // within a few ulps of an integer.
        let top = 26.0f32.to_bits();
        for b in (0..=top).step_by(97) {
            let z = f32::from_bits(b);
            assert_eq!(exp_neg(z).to_bits(), exp_neg_by_floor(z).to_bits(), "z {z:e}");
        }
        for k in 0..=38 {
            let z0 = k as f32 / core::f32::consts::LOG2_E;
            for d in -8i32..=8 {
                let z = f32::from_bits(z0.to_bits().wrapping_add_signed(d));
                if (0.0..=26.0).contains(&z) {
                    assert_eq!(exp_neg(z).to_bits(), exp_neg_by_floor(z).to_bits(), "z {z:e}");
                }
            }
        }
    }

    #[test]
    fn fast_exponential_matches() {
        for i in 0..=1800 {
            let z = i as f32 * 0.01;
            let (got, want) = (f64::from(exp_neg(z)), (-(f64::from(z))).exp());
            assert!(((got - want) / want).abs() < 1e-5, "z {z}: {got} vs {want}");
        }
    }
}
