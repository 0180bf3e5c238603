//! Hot loops compiled for AVX2 when the CPU has it (runtime detection), else for the baseline
//! target. The loops are written so that LLVM vectorises them (u8/u16 lanes, saturating
//! arithmetic, no branches inside); [`avx2_variant!`](crate::avx2_variant) compiles an `#[inline(always)]` body a
//! second time inside a `#[target_feature(enable = "avx2")]` function, which doubles the lane
//! count and gives the unsigned 16-bit min instructions that baseline SSE2 lacks.

/// Whether the CPU supports AVX2 (cached by the standard library).
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
    {
        false
    }
}

/// `avx2_variant!(fn name(args) -> R => body_fn)` defines `name`, which calls the
/// `#[inline(always)]` function `body_fn(args)` compiled with AVX2 when the CPU has it.
#[macro_export]
#[doc(hidden)]
macro_rules! avx2_variant {
    ($vis:vis fn $name:ident $(<$($lt:lifetime),+>)? ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? => $body:path) => {
        $vis fn $name $(<$($lt),+>)? ($($arg: $ty),*) $(-> $ret)? {
            #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn with_avx2 $(<$($lt),+>)? ($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                if $crate::stereo::simd::has_avx2() {
                    // SAFETY: the CPU supports AVX2 (checked just above).
                    return unsafe { with_avx2($($arg),*) };
                }
            }
            $body($($arg),*)
        }
    };
}

/// `e^(−x)` for `x ≥ 0` in arithmetic the compiler vectorises (the standard `exp` is a library
/// call, and a table lookup per lane is a gather, both of which leave a loop over lanes scalar):
/// `2^t` with `t = −x·log₂e` split into its nearest integer, placed in the exponent bits, and a
/// remainder in [−½, ½] by a degree-6 Taylor polynomial. Relative error below 5·10⁻⁶ (most of it the rounding of `t`); results
/// under 2⁻¹²⁶ come out as 2⁻¹²⁶ (a weight that small is nothing next to the centre's).
#[inline(always)]
pub(crate) fn exp_neg(x: f32) -> f32 {
    use std::f32::consts::{LN_2, LOG2_E};
    // Adding 1.5·2²³ rounds to the nearest integer in the mantissa bits: no float-to-int
    // conversion, whose saturating semantics would keep the loop scalar.
    const ROUND: f32 = 12_582_912.0;
    let t = (-x * LOG2_E).max(-126.0);
    let rounded = t + ROUND;
    let whole = (rounded.to_bits() as i32).wrapping_sub(ROUND.to_bits() as i32);
    let f = (t - (rounded - ROUND)) * LN_2;
    let poly = 1.0
        + f * (1.0
            + f * (0.5
                + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0))))));
    f32::from_bits(((whole + 127) as u32) << 23) * poly
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_matches_the_standard_exp() {
        assert_eq!(exp_neg(0.0), 1.0);
        for i in 0..=16_000 {
            let x = i as f32 * 0.005;
            let (got, want) = (exp_neg(x), (-x).exp());
            assert!((got - want).abs() <= 5e-6 * want, "e^-{x}: {got} vs {want}");
        }
        // Far below f32's normal range: the smallest normal, never 0 or NaN.
        assert_eq!(exp_neg(1e4), f32::MIN_POSITIVE);
        assert_eq!(exp_neg(f32::MAX), f32::MIN_POSITIVE);
    }
}
