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

/// `e^(v/s)` and `e^(−v/s)` of every grey level `v`, for similarity weights
/// `e^(−|a − b|/s) = min(rise[a]·fall[b], fall[a]·rise[b])`: with the factors looked up once per
/// pixel, a weight per pair of pixels is two products and a min, which vectorise, where an `exp`
/// per pair is a library call that keeps the loop scalar. Both products stay in `f32`'s normal
/// range for `s` above 255/87 ≈ 2.9.
pub(crate) struct GreyExponentials {
    pub rise: [f32; 256],
    pub fall: [f32; 256],
}

impl GreyExponentials {
    /// The factors for scale `s` (grey levels over which a weight falls by `e`).
    pub fn new(s: f32) -> Self {
        GreyExponentials {
            rise: std::array::from_fn(|v| (v as f32 / s).exp()),
            fall: std::array::from_fn(|v| (-(v as f32) / s).exp()),
        }
    }
}
