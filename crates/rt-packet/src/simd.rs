//! The eight-lane vectors the packet kernels run on ([`F8`]), chosen per instruction set:
//! `wide::f32x8` at the baseline (two SSE registers in a plain build), one AVX register at
//! the AVX2 level. A packet query picks the level of its structure ([`rt_geom::Isa`]) once,
//! through [`rt_geom::isa::run`], and runs the whole traversal compiled for it with that
//! level's vectors. Every operation is the same IEEE operation on either, so the
//! answers are the same bit for bit.

use crate::RayPacket;
use rt_geom::Hit;
use rt_geom::isa::{Isa, Kernel, Level};

/// Eight `f32` lanes with the operations the packet kernels use. A comparison gives a mask:
/// every bit of a lane set where it holds, none where it does not (false for NaN). Sealed:
/// implemented by `wide::f32x8` and by the AVX register of the AVX2 level, which only the
/// packet kernels make.
pub trait F8:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::BitAnd<Output = Self>
    + std::ops::BitOr<Output = Self>
    + sealed::Sealed
{
    /// Every lane `x`.
    fn splat(x: f32) -> Self;
    /// The lanes of `a`.
    fn new(a: [f32; 8]) -> Self;
    /// The first eight floats of `s`.
    #[inline(always)]
    fn load(s: &[f32]) -> Self {
        Self::new(s[..8].try_into().expect("eight floats"))
    }
    /// The lanes as an array.
    fn to_array(self) -> [f32; 8];
    /// `self < o` per lane.
    fn lt(self, o: Self) -> Self;
    /// `self > o` per lane.
    fn gt(self, o: Self) -> Self;
    /// `self <= o` per lane.
    fn le(self, o: Self) -> Self;
    /// `self == o` per lane.
    fn eq(self, o: Self) -> Self;
    /// Bit `l` set where lane `l` of the mask `self` is set.
    fn bits(self) -> u32;
    /// `a` where the mask `self` is set, `b` elsewhere.
    fn select(self, a: Self, b: Self) -> Self;
    /// `self & !o`: the mask `self` without the lanes of the mask `o`.
    fn and_not(self, o: Self) -> Self;
    /// Lane-wise absolute value.
    fn abs(self) -> Self;
    /// Lane-wise minimum, the other lane where one is NaN (`wide::f32x8::min`).
    fn min(self, o: Self) -> Self;
    /// Lane-wise maximum, the other lane where one is NaN (`wide::f32x8::max`).
    fn max(self, o: Self) -> Self;
    /// The mask with lane `l` set where bit `l` of `bits` is.
    fn from_bits(bits: u32) -> Self;
    /// Every lane zero.
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }
}

mod sealed {
    /// Only the packet kernels' vectors implement [`super::F8`].
    pub trait Sealed {}
    impl Sealed for wide::f32x8 {}
    #[cfg(target_arch = "x86_64")]
    impl Sealed for super::avx::Avx8 {}
}

impl F8 for wide::f32x8 {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        wide::f32x8::splat(x)
    }
    #[inline(always)]
    fn new(a: [f32; 8]) -> Self {
        wide::f32x8::new(a)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        wide::f32x8::to_array(self)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self {
        wide::CmpLt::cmp_lt(self, o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self {
        wide::CmpGt::cmp_gt(self, o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self {
        wide::CmpLe::cmp_le(self, o)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> Self {
        wide::CmpEq::cmp_eq(self, o)
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        self.move_mask() as u32
    }
    #[inline(always)]
    fn select(self, a: Self, b: Self) -> Self {
        self.blend(a, b)
    }
    #[inline(always)]
    fn and_not(self, o: Self) -> Self {
        self & !o
    }
    #[inline(always)]
    fn abs(self) -> Self {
        wide::f32x8::abs(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        wide::f32x8::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        wide::f32x8::max(self, o)
    }
    #[inline(always)]
    fn from_bits(bits: u32) -> Self {
        use wide::{CmpEq, CmpNe, i32x8};
        let lane = i32x8::new([1, 2, 4, 8, 16, 32, 64, 128]);
        let on = (i32x8::splat(bits as i32) & lane).cmp_eq(lane);
        wide::f32x8::from_i32x8(on).cmp_ne(wide::f32x8::ZERO)
    }
}

/// Work compiled once per instruction set with that level's vectors ([`run`]); its `run` is
/// `#[inline(always)]` down to the kernels, so that each copy is compiled for its level.
pub(crate) trait PacketKernel {
    /// What the work returns.
    type Output;
    /// Does the work on the vectors `V`.
    fn run<V: F8>(self) -> Self::Output;
}

/// A packet query of a structure `T` as work compiled per instruction set: the structure,
/// the packet and the lanes' answers.
pub(crate) struct Query<'a, 'r, T, const N: usize, const ANY_HIT: bool>(
    pub(crate) &'a T,
    pub(crate) &'a mut RayPacket<'r, N>,
    pub(crate) &'a mut [Option<Hit>; N],
);

/// `k.run::<V>()` compiled for `isa` (or the best level below it this CPU runs), `V` that
/// level's vectors.
#[inline]
pub(crate) fn run<K: PacketKernel>(isa: Isa, k: K) -> K::Output {
    rt_geom::isa::run(isa, OnLevel(k))
}

/// A [`PacketKernel`] as rt-geom's [`Kernel`]: the level's value picks the vectors.
struct OnLevel<K>(K);

impl<K: PacketKernel> Kernel for OnLevel<K> {
    type Output = K::Output;
    #[inline(always)]
    fn run<L: Level>(self, _level: L) -> K::Output {
        match L::ISA {
            // The level's value exists, so this CPU runs AVX2 (`rt_geom::isa::run` made it).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => self.0.run::<avx::Avx8>(),
            _ => self.0.run::<wide::f32x8>(),
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    //! [`Avx8`]: eight lanes in one AVX register. Private to this crate and made only inside
    //! kernels that [`super::run`] runs at the AVX2 level, which `rt_geom::isa::run` enters
    //! only after finding AVX2 and FMA on the CPU: every `unsafe` intrinsic below relies on
    //! that. Measured reason: the plain build's packets ran about 30% slower on `wide`'s
    //! SSE pairs than the same code compiled for x86-64-v3.
    use super::F8;
    use std::arch::x86_64::*;

    /// Eight `f32` lanes in one AVX register.
    #[derive(Clone, Copy, Debug)]
    pub struct Avx8(__m256);

    macro_rules! binary {
        ($tr:ident, $f:ident, $op:ident) => {
            impl std::ops::$tr for Avx8 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: Self) -> Self {
                    // SAFETY: an `Avx8` exists only at the AVX2 level (module documentation).
                    Self(unsafe { $op(self.0, o.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_ps);
    binary!(Sub, sub, _mm256_sub_ps);
    binary!(Mul, mul, _mm256_mul_ps);
    binary!(BitAnd, bitand, _mm256_and_ps);
    binary!(BitOr, bitor, _mm256_or_ps);

    impl F8 for Avx8 {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: as for the operators (module documentation).
            Self(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn new(a: [f32; 8]) -> Self {
            Self::load(&a)
        }
        #[inline(always)]
        fn load(s: &[f32]) -> Self {
            let s: &[f32; 8] = s[..8].try_into().expect("eight floats");
            // SAFETY: the AVX2 level; `s` is eight readable floats, and the load takes any
            // alignment.
            Self(unsafe { _mm256_loadu_ps(s.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            // SAFETY: the AVX2 level; `a` has room for eight floats, any alignment.
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Self {
            // SAFETY: as for the operators.
            Self(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> Self {
            // SAFETY: as for the operators.
            Self(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> Self {
            // SAFETY: as for the operators.
            Self(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn eq(self, o: Self) -> Self {
            // SAFETY: as for the operators.
            Self(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn bits(self) -> u32 {
            // SAFETY: as for the operators.
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }
        #[inline(always)]
        fn select(self, a: Self, b: Self) -> Self {
            // SAFETY: as for the operators (`blendv` takes each lane's sign bit, which a mask
            // sets with every other bit).
            Self(unsafe { _mm256_blendv_ps(b.0, a.0, self.0) })
        }
        #[inline(always)]
        fn and_not(self, o: Self) -> Self {
            // SAFETY: as for the operators.
            Self(unsafe { _mm256_andnot_ps(o.0, self.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: as for the operators.
            Self(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            // SAFETY: as for the operators. `minps` gives its second operand where either is
            // NaN: `o`'s NaN lanes take `self`, as `wide`'s `min` does.
            unsafe {
                let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(o.0, o.0);
                Self(_mm256_blendv_ps(_mm256_min_ps(self.0, o.0), self.0, nan))
            }
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            // SAFETY: as in `min`.
            unsafe {
                let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(o.0, o.0);
                Self(_mm256_blendv_ps(_mm256_max_ps(self.0, o.0), self.0, nan))
            }
        }
        #[inline(always)]
        fn from_bits(bits: u32) -> Self {
            // SAFETY: as for the operators (AVX2 integer operations: the level has AVX2).
            unsafe {
                let lane = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                let on = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane);
                Self(_mm256_castsi256_ps(_mm256_cmpeq_epi32(on, lane)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every operation of each level's vectors gives what `wide::f32x8` gives, bit for bit,
    /// on values with NaN, infinities, signed zeros and subnormals (a NaN result as any NaN:
    /// its sign and payload are not part of IEEE's answer, and constant folding differs from
    /// the hardware there).
    #[test]
    fn every_level_computes_what_wide_computes() {
        struct Ops;
        impl PacketKernel for Ops {
            type Output = Vec<[u32; 8]>;
            #[inline(always)]
            fn run<V: F8>(self) -> Vec<[u32; 8]> {
                let a = [0.0, -0.0, 1.5, f32::NAN, f32::INFINITY, -3.0, 1e-40, 2.0];
                let b = [
                    -0.0,
                    0.0,
                    1.5,
                    1.0,
                    f32::NEG_INFINITY,
                    f32::NAN,
                    1e-40,
                    -7.25,
                ];
                let (x, y) = (V::new(a), V::load(&b));
                let words = |v: V| v.to_array().map(f32::to_bits);
                let value = |v: V| {
                    v.to_array()
                        .map(|x| if x.is_nan() { 1 } else { x.to_bits() })
                };
                let m = x.lt(y) | x.eq(y);
                vec![
                    value(x + y),
                    value(x - y),
                    value(x * y),
                    words(x.lt(y)),
                    words(x.gt(y)),
                    words(x.le(y)),
                    words(x.eq(y)),
                    words(m & x.gt(V::zero())),
                    words(m.and_not(x.gt(y))),
                    words(m.select(x, y)),
                    words(x.abs()),
                    words(x.min(y)),
                    words(x.max(y)),
                    words(y.min(x)),
                    words(y.max(x)),
                    words(V::from_bits(0b1011_0010)),
                    words(V::splat(-0.5)),
                    [m.bits(), x.gt(y).bits(), 0, 0, 0, 0, 0, 0],
                ]
            }
        }
        let base = Ops.run::<wide::f32x8>();
        for isa in Isa::available() {
            assert_eq!(run(isa, Ops), base, "{isa}");
        }
    }
}
