//! The SIMD vectors of the lane kernel ([`SimdLanes`]: four or eight `f32` lanes, or one),
//! and the lanes' data: triangles ([`TriangleLanes`]) and their sheared frame
//! ([`ShearedLanes`]).

use wide::f32x4;

/// The SIMD vectors the triangle lane kernel runs on: four lanes (`wide::f32x4`, SSE) or
/// eight (`wide::f32x8`: one AVX register in builds for such CPUs, two SSE registers
/// elsewhere). Only what [`watertight_lanes`](super::watertight_lanes) needs.
pub trait SimdLanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    /// Number of lanes.
    const WIDTH: usize;
    /// The lanes as an array.
    type Array: Copy + std::ops::Index<usize, Output = f32>;
    /// Every lane `x`.
    fn splat(x: f32) -> Self;
    /// Lanes from `WIDTH` consecutive floats.
    fn load(src: &[f32]) -> Self;
    /// The lanes as an array.
    fn to_lanes(self) -> Self::Array;
    /// Bits of the lanes where some of `a`, `b`, `c` is below zero, above zero, zero.
    fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32);
    /// Lane-wise absolute value.
    fn abs(self) -> Self;
    /// Each lane with its sign flipped where `s`'s lane has its sign bit set (an exact
    /// negation: `self` times the sign of `s`).
    fn sign_of(self, s: Self) -> Self;
    /// Lane-wise maximum (either lane when one is NaN).
    fn max(self, other: Self) -> Self;
    /// Lane-wise minimum (either lane when one is NaN).
    fn min(self, other: Self) -> Self;
    /// Bits of the lanes where `a < b` (false for NaN).
    fn less_bits(a: Self, b: Self) -> u32;
    /// Bits of the lanes where `a <= b` (false for NaN).
    fn le_bits(a: Self, b: Self) -> u32;
}

macro_rules! simd_lanes {
    ($t:ty, $n:expr) => {
        impl SimdLanes for $t {
            const WIDTH: usize = $n;
            type Array = [f32; $n];
            #[inline(always)]
            fn splat(x: f32) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn load(src: &[f32]) -> Self {
                let a: [f32; $n] = src[..$n].try_into().expect("WIDTH floats");
                <$t>::from(a)
            }
            #[inline(always)]
            fn to_lanes(self) -> [f32; $n] {
                self.to_array()
            }
            #[inline(always)]
            fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32) {
                use wide::{CmpEq, CmpGt, CmpLt};
                let z = <$t>::ZERO;
                (
                    (a.cmp_lt(z) | b.cmp_lt(z) | c.cmp_lt(z)).move_mask() as u32,
                    (a.cmp_gt(z) | b.cmp_gt(z) | c.cmp_gt(z)).move_mask() as u32,
                    (a.cmp_eq(z) | b.cmp_eq(z) | c.cmp_eq(z)).move_mask() as u32,
                )
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn sign_of(self, s: Self) -> Self {
                self ^ (s & <$t>::splat(-0.0))
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                self.fast_max(other)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                self.fast_min(other)
            }
            #[inline(always)]
            fn less_bits(a: Self, b: Self) -> u32 {
                use wide::CmpLt;
                a.cmp_lt(b).move_mask() as u32
            }
            #[inline(always)]
            fn le_bits(a: Self, b: Self) -> u32 {
                use wide::CmpLe;
                a.cmp_le(b).move_mask() as u32
            }
        }
    };
}
simd_lanes!(f32x4, 4);

/// One lane: the scalar form of the lane kernels' bounds ([`proven_hit`](super::proven_hit)).
impl SimdLanes for f32 {
    const WIDTH: usize = 1;
    type Array = [f32; 1];
    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        src[0]
    }
    #[inline(always)]
    fn to_lanes(self) -> [f32; 1] {
        [self]
    }
    #[inline(always)]
    fn sign_bits(a: Self, b: Self, c: Self) -> (u32, u32, u32) {
        (
            (a < 0.0 || b < 0.0 || c < 0.0) as u32,
            (a > 0.0 || b > 0.0 || c > 0.0) as u32,
            (a == 0.0 || b == 0.0 || c == 0.0) as u32,
        )
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn sign_of(self, s: Self) -> Self {
        f32::from_bits(self.to_bits() ^ (s.to_bits() & 0x8000_0000))
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        f32::max(self, other)
    }
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        f32::min(self, other)
    }
    #[inline(always)]
    fn less_bits(a: Self, b: Self) -> u32 {
        (a < b) as u32
    }
    #[inline(always)]
    fn le_bits(a: Self, b: Self) -> u32 {
        (a <= b) as u32
    }
}
simd_lanes!(wide::f32x8, 8);

/// Triangles in SIMD lanes (four by default): coordinate `j` of `[v0.x, v0.y, v0.z, v1.x,
/// .., v2.z]` in vector `j`, lane `l` holding triangle `l`.
pub type TriangleLanes<L = f32x4> = [L; 9];

/// A triangle per lane in the watertight test's sheared frame: per vertex the sheared `x`
/// and `y`, the depth `v[kz] - o[kz]` before and after scaling by the shear's `sz` (`dz`,
/// `z`), the absolute edge functions (`|U|`, `|V|`, `|W|`), and Woop's depth estimate
/// `num / den` from them (`num = |U| za + |V| zb + |W| zc`, `den = |U| + |V| + |W|`), all as
/// computed in `f32`.
pub struct ShearedLanes<L> {
    /// Sheared `x` per vertex.
    pub x: [L; 3],
    /// Sheared `y` per vertex.
    pub y: [L; 3],
    /// Depth `v[kz] - o[kz]` per vertex, before scaling.
    pub dz: [L; 3],
    /// Depth per vertex scaled by the shear's `sz`.
    pub z: [L; 3],
    /// Absolute edge functions `|U|`, `|V|`, `|W|`.
    pub edges: [L; 3],
    /// Numerator of Woop's depth estimate.
    pub num: L,
    /// Denominator of Woop's depth estimate.
    pub den: L,
}
