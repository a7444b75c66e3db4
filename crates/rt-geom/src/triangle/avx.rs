//! [`Avx8`]: eight `f32` lanes in one AVX register, the leaf test's vectors at the AVX2 level
//! ([`crate::isa::Avx2Level`]). `wide::f32x8` is chosen when rt-geom is compiled: two SSE
//! registers in a plain build even where the walk runs in a function compiled for AVX2.
//!
//! The operations are `std::arch` intrinsics in `unsafe` blocks: the type is private to
//! rt-geom, and made only inside the hooks of [`crate::isa::Avx2Level`], which take its value,
//! made only by [`crate::isa::run`] after checking the CPU for AVX2 and FMA. Each operation is
//! what `wide::f32x8`'s SSE form computes, lane by lane, so the answers are the same bit for
//! bit. Measured reason: the plain build's queries ran 8-16% slower on `wide`'s SSE pairs.

use super::simd::SimdLanes;
use std::arch::x86_64::*;

/// Eight `f32` lanes in one AVX register.
#[derive(Clone, Copy, Debug)]
pub struct Avx8(__m256);

impl std::ops::Add for Avx8 {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        // SAFETY: an `Avx8` exists only at the AVX2 level (module documentation).
        Self(unsafe { _mm256_add_ps(self.0, o.0) })
    }
}

impl std::ops::Sub for Avx8 {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_sub_ps(self.0, o.0) })
    }
}

impl std::ops::Mul for Avx8 {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_mul_ps(self.0, o.0) })
    }
}

impl std::ops::Div for Avx8 {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_div_ps(self.0, o.0) })
    }
}

impl Avx8 {
    /// Bit `l` set where `a[l] <= b[l]` as signed integers.
    #[inline(always)]
    pub(crate) fn le_bits8_i32(a: &[i32; 8], b: &[i32; 8]) -> u32 {
        // SAFETY: as in `add` (AVX2 is checked with the level); the loads read the two
        // arrays, 32 bytes each, unaligned.
        let gt = unsafe {
            let (a, b) = (
                _mm256_loadu_si256(a.as_ptr().cast()),
                _mm256_loadu_si256(b.as_ptr().cast()),
            );
            _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(a, b)))
        };
        !(gt as u32) & 0xff
    }
}

/// The lanes of a compare result as bits.
#[inline(always)]
fn bits(m: __m256) -> u32 {
    // SAFETY: as in `add` (the mask comes from an `Avx8` operation).
    unsafe { _mm256_movemask_ps(m) as u32 }
}

impl SimdLanes for Avx8 {
    const WIDTH: usize = 8;
    type Array = [f32; 8];

    #[inline(always)]
    fn splat(x: f32) -> Self {
        // SAFETY: called only at the AVX2 level (module documentation).
        Self(unsafe { _mm256_set1_ps(x) })
    }

    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        let a: &[f32; 8] = src[..8].try_into().expect("WIDTH floats");
        // SAFETY: the AVX2 level (as in `splat`); `a` is eight readable floats, and the load
        // takes any alignment.
        Self(unsafe { _mm256_loadu_ps(a.as_ptr()) })
    }

    #[inline(always)]
    fn to_lanes(self) -> [f32; 8] {
        let mut a = [0.0; 8];
        // SAFETY: the AVX2 level; `a` has room for eight floats, any alignment.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
        a
    }

    #[inline(always)]
    fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32) {
        // SAFETY: as in `add`.
        unsafe {
            let z = _mm256_setzero_ps();
            let any = |p: fn(__m256, __m256) -> __m256| {
                bits(_mm256_or_ps(_mm256_or_ps(p(a.0, z), p(b.0, z)), p(c.0, z)))
            };
            (
                any(|x, z| _mm256_cmp_ps::<_CMP_LT_OQ>(x, z)),
                any(|x, z| _mm256_cmp_ps::<_CMP_GT_OQ>(x, z)),
                any(|x, z| _mm256_cmp_ps::<_CMP_EQ_OQ>(x, z)),
            )
        }
    }

    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_max_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn min(self, other: Self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_min_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn less_bits(a: Self, b: Self) -> u32 {
        // SAFETY: as in `add`.
        bits(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(a.0, b.0) })
    }

    #[inline(always)]
    fn le_bits(a: Self, b: Self) -> u32 {
        // SAFETY: as in `add`.
        bits(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(a.0, b.0) })
    }
}
