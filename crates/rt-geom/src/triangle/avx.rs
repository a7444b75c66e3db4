//! [`Avx8`]: eight `f32` lanes in one AVX register, the leaf test's vectors at the AVX2 level
//! ([`crate::isa::Avx2Level`]), and the wide walk's sorting network of eight lanes
//! ([`crate::Level::far_to_near8`]). `wide::f32x8` is chosen when rt-geom is compiled: two SSE
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

impl Avx8 {
    /// [`crate::Level::far_to_near8`] on AVX2: a bitonic sorting network of six compare and
    /// exchange layers over one register of integer keys, then each row permuted by it.
    #[inline(always)]
    pub(crate) fn far_to_near8(
        hit: u32,
        t: &[f32; 8],
        child: &[u32; 8],
        count: &[u32; 8],
    ) -> crate::SortedLanes {
        let mut out = crate::SortedLanes {
            child: [0; 8],
            count: [0; 8],
            t: [0.0; 8],
        };
        // SAFETY: as in `add` (AVX2 is checked with the level); every load and store covers
        // one eight-lane array, unaligned. Measured reason: the closest-hit walks of diffuse
        // rays ran 1-4% faster than with the insertion's branches on the distances.
        unsafe {
            // Key: the entry's bits (as a signed integer: the order of non-negative floats)
            // with its low three bits replaced by `7 - lane`, so that keys are distinct and
            // the key names its lane; the lanes not hit take the least key.
            let sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let set = _mm256_and_si256(_mm256_set1_epi32(hit as i32), sel);
            let is_hit = _mm256_cmpeq_epi32(set, sel);
            let tv = _mm256_loadu_ps(t.as_ptr());
            let key = _mm256_or_si256(
                _mm256_and_si256(_mm256_castps_si256(tv), _mm256_set1_epi32(!7)),
                _mm256_setr_epi32(7, 6, 5, 4, 3, 2, 1, 0),
            );
            let mut k = _mm256_blendv_epi8(_mm256_set1_epi32(i32::MIN), key, is_hit);
            // Each layer: every lane against its partner (`lane ^ j`), the larger key kept
            // where the mask's bit is set. Layers of 2 and 4 form sorted runs of four in
            // alternating directions; the last three merge them into one decreasing run.
            macro_rules! layer {
                ($partner:expr, $larger:literal) => {{
                    let p = $partner;
                    let (lo, hi) = (_mm256_min_epi32(k, p), _mm256_max_epi32(k, p));
                    k = _mm256_blend_epi32::<$larger>(lo, hi);
                }};
            }
            layer!(_mm256_shuffle_epi32::<0b10_11_00_01>(k), 0x99);
            layer!(_mm256_shuffle_epi32::<0b01_00_11_10>(k), 0xC3);
            layer!(_mm256_shuffle_epi32::<0b10_11_00_01>(k), 0xA5);
            layer!(_mm256_permute4x64_epi64::<0b01_00_11_10>(k), 0x0F);
            layer!(_mm256_shuffle_epi32::<0b01_00_11_10>(k), 0x33);
            layer!(_mm256_shuffle_epi32::<0b10_11_00_01>(k), 0x55);
            // The permutes read the low three bits: the lane.
            let lane = _mm256_xor_si256(k, _mm256_set1_epi32(7));
            let row = |r: &[u32; 8]| {
                _mm256_permutevar8x32_epi32(_mm256_loadu_si256(r.as_ptr().cast()), lane)
            };
            _mm256_storeu_si256(out.child.as_mut_ptr().cast(), row(child));
            _mm256_storeu_si256(out.count.as_mut_ptr().cast(), row(count));
            _mm256_storeu_ps(out.t.as_mut_ptr(), _mm256_permutevar8x32_ps(tv, lane));
        }
        out
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
    fn sign_of(self, s: Self) -> Self {
        // SAFETY: as in `add`.
        Self(unsafe { _mm256_xor_ps(self.0, _mm256_and_ps(s.0, _mm256_set1_ps(-0.0))) })
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
