//! [`Isa`]: the instruction sets the hot loops are compiled for, chosen at run time.
//!
//! A dependent crate's plain `cargo build --release` compiles for the baseline of its target
//! (SSE2 on x86-64). The walks and leaf tests are therefore compiled once more inside a
//! function that enables AVX2 and FMA (x86-64-v3), and a query runs the level its structure
//! asks for where the CPU has it, as Embree picks its kernels when a scene is committed. The
//! choice is made once per query, never per node: a function compiled for an instruction set
//! does not inline into a caller without it. The kernels work on eight lanes, which one AVX2
//! register holds; the AVX-512 level ([`Isa::Avx512`]) runs the same eight-lane code with
//! AVX-512's 32 vector registers and mask registers, and only for the work that gains from
//! them ([`Kernel::AVX512`]: any-hit walks, and the closest-hit walks of the triangle BVHs,
//! whose exact leaf tests spill vectors at AVX2); all other work runs its AVX2 copy there,
//! which ran faster than an AVX-512 one.
//!
//! Work to compile per level implements [`Kernel`] and runs through [`run`]; a structure
//! implements [`Walk`] (its whole query, `#[inline(always)]`, and the level it asks for) and
//! answers through [`query`]. Either runs at the requested level, or at the best one below it
//! that the CPU has. `RT_ISA=baseline|avx2|avx512` sets the request ([`Isa::selected`]) for
//! tests and measurements.
//!
//! Inside, the work is handed the level it runs at as a value ([`Level`]), which the walk's
//! node tests and the leaf tests
//! ([`TriangleSoa::intersect_range`](crate::TriangleSoa::intersect_range)) pick their
//! eight-lane vectors by: `wide`'s (SSE pairs in a plain build) at the baseline, one
//! AVX register at the AVX2 level. Only [`run`] makes an AVX2 level value, after
//! checking the CPU, so the AVX instructions never run where they are missing.

use crate::triangle::{AxisVertices, ShearedLanes, SimdLanes, Triangle};
use crate::{Hit, Keep, PrimHit, Ray, TriangleSoa};
use std::sync::atomic::{AtomicU8, Ordering};

/// An instruction-set level the kernels are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// What the crate itself is compiled for (SSE2 in a plain x86-64 build; the only level on
    /// other targets).
    Baseline,
    /// x86-64-v3: AVX2, FMA, BMI1, BMI2, LZCNT, POPCNT.
    Avx2,
    /// x86-64-v3 with AVX-512 F, VL, BW, DQ and CD: the AVX2 level's eight-lane kernels with
    /// 32 vector registers, for the work that gains from them ([`Kernel::AVX512`]); other
    /// work runs its AVX2 copy.
    Avx512,
}

impl Isa {
    /// Every level, lowest first.
    pub const ALL: [Isa; 3] = [Isa::Baseline, Isa::Avx2, Isa::Avx512];

    /// The name `RT_ISA` takes.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// The level named `s` (`baseline`, `avx2`, `avx512`).
    pub fn parse(s: &str) -> Result<Isa, String> {
        Isa::ALL
            .into_iter()
            .find(|i| i.name() == s.trim())
            .ok_or_else(|| format!("unknown instruction set {s:?} (baseline, avx2, avx512)"))
    }

    /// Whether this CPU runs this level.
    pub fn supported(self) -> bool {
        self <= Isa::best()
    }

    /// The highest level this CPU runs (detected once; inlined into each query's dispatch).
    #[inline]
    pub fn best() -> Isa {
        match BEST.load(Ordering::Relaxed) {
            0 => Isa::Baseline,
            1 => Isa::Avx2,
            2 => Isa::Avx512,
            _ => detect_once(),
        }
    }

    /// The levels this CPU runs, lowest first.
    pub fn available() -> Vec<Isa> {
        Isa::ALL.into_iter().filter(|i| i.supported()).collect()
    }

    /// The level structures use unless told otherwise: `RT_ISA` when it names a level this CPU
    /// runs, else [`Isa::best`] (a warning on standard error once when `RT_ISA` names
    /// something else).
    pub fn selected() -> Isa {
        static SELECTED: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *SELECTED.get_or_init(|| {
            let Ok(v) = std::env::var("RT_ISA") else {
                return Isa::best();
            };
            match Isa::parse(&v) {
                Ok(isa) if isa.supported() => isa,
                Ok(isa) => {
                    let p = Isa::best();
                    eprintln!("RT_ISA={}: this CPU lacks it; using {p}", isa.name());
                    p
                }
                Err(e) => {
                    eprintln!("RT_ISA: {e}; using {}", Isa::best());
                    Isa::best()
                }
            }
        })
    }

    /// `self` if this CPU runs it, else the best level it runs.
    #[inline]
    pub fn or_best(self) -> Isa {
        self.min(Isa::best())
    }
}

impl std::fmt::Display for Isa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// [`Isa::best`] as a number once detected; `u8::MAX` before.
static BEST: AtomicU8 = AtomicU8::new(u8::MAX);

/// Detects the CPU's best level and records it for [`Isa::best`].
#[cold]
#[inline(never)]
fn detect_once() -> Isa {
    let best = detect();
    BEST.store(best as u8, Ordering::Relaxed);
    best
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Isa {
    use std::arch::is_x86_feature_detected as has;
    let v3 = has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt");
    let v4 = has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq");
    match (v3, v4 && has!("avx512cd")) {
        (true, true) => Isa::Avx512,
        (true, false) => Isa::Avx2,
        _ => Isa::Baseline,
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Isa {
    Isa::Baseline
}

/// The level a [`Kernel`] runs at, as a value it hands to the node and leaf tests:
/// [`BaseLevel`], or [`Avx2Level`] (made only by [`run`], on a CPU it checked). The value is
/// the proof that the CPU runs the level: every operation that uses its instructions takes it.
pub trait Level: Copy + Send + Sync + std::fmt::Debug + sealed::Sealed {
    /// The instruction set of this level, for kernels outside rt-geom that pick their own
    /// vectors by it (a compile-time constant in each level's copy).
    const ISA: Isa;
    /// Whether the level multiplies and adds with one rounding (`f32::mul_add` is one
    /// instruction here, where the baseline would call a library routine).
    const FMA: bool;

    /// Bit `l` set where `a[l] <= b[l]` as signed integers: one integer compare of the
    /// level's eight-lane vectors (the wide walk's hit mask, on the bits of non-negative
    /// floats, which order as their integers do, or on a float compare's answers).
    #[inline(always)]
    fn le_bits8_i32(self, a: &[i32; 8], b: &[i32; 8]) -> u32 {
        sealed::Sealed::le8_i32(self, a, b)
    }

    /// The lanes of `hit` ordered far to near by their entry `t` (ties: the higher lane
    /// nearer), then the other lanes: per position, its lane's `child`, `count` and `t`
    /// (the wide walk's push of three or more children, with no branch on the distances).
    /// The order is by distance where the entries of `hit` are non-negative (their bits
    /// compared as integers; the three lowest bits left out), some order otherwise; `None`
    /// at the baseline level, which has no permute across eight lanes.
    #[inline(always)]
    fn far_to_near8(
        self,
        hit: u32,
        t: &[f32; 8],
        child: &[u32; 8],
        count: &[u32; 8],
    ) -> Option<SortedLanes> {
        sealed::Sealed::sort8(self, hit, t, child, count)
    }

    /// A copy of `ray` for a walk to work on: a plain one, or [`Ray::copy_narrow`] (eight
    /// 8-byte moves) in the AVX-512 level's copy on a CPU whose 512-bit moves slow the code
    /// around them ([`Isa::Avx512`]).
    #[inline(always)]
    fn copy_ray(self, ray: &Ray) -> Ray {
        if sealed::Sealed::narrow_copies(self) {
            ray.copy_narrow()
        } else {
            *ray
        }
    }
}

/// Eight lanes in an order ([`Level::far_to_near8`]): per position, a lane's child, count and
/// entry distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SortedLanes {
    /// The lane's child (node index or first primitive).
    pub child: [u32; 8],
    /// The lane's primitive count (0 for an inner child).
    pub count: [u32; 8],
    /// The lane's entry distance.
    pub t: [f32; 8],
}

/// The baseline level: `wide`'s eight-lane vectors.
#[derive(Clone, Copy, Debug)]
pub struct BaseLevel;

/// The AVX2 level: eight lanes in one AVX register. Its field is
/// private: only [`run`] makes one, after finding AVX2 and FMA on the CPU (the field: whether
/// the walks copy rays in words, [`Level::copy_ray`]).
#[derive(Clone, Copy, Debug)]
pub struct Avx2Level(bool);

impl Level for BaseLevel {
    const ISA: Isa = Isa::Baseline;
    const FMA: bool = false;
}
impl Level for Avx2Level {
    const ISA: Isa = Isa::Avx2;
    const FMA: bool = true;
}

/// The hooks behind [`Level`]: not nameable outside rt-geom.
pub(crate) mod sealed {
    use crate::triangle::{AxisVertices, ShearedLanes, SimdLanes};
    use crate::{Keep, PrimHit, Ray, TriangleSoa};

    /// What a level gives the leaf tests (see [`Level`](super::Level)). Every hook takes the
    /// level's value, the proof that the CPU runs it.
    pub trait Sealed {
        /// Triangles `k .. k + 8` of a leaf of `soa` ([`TriangleSoa::test_window`]) on the
        /// level's eight-lane vectors.
        #[allow(clippy::too_many_arguments)]
        fn window8<const ANY_HIT: bool>(
            self,
            soa: &TriangleSoa,
            leaf: (usize, usize),
            k: usize,
            ids: &[u32],
            r: &mut Ray,
            skip: &mut impl FnMut(u32) -> bool,
            best: &mut impl Keep,
        ) -> bool;
        /// [`Level::le_bits8_i32`](super::Level::le_bits8_i32).
        fn le8_i32(self, a: &[i32; 8], b: &[i32; 8]) -> u32;
        /// [`Level::far_to_near8`](super::Level::far_to_near8).
        fn sort8(
            self,
            hit: u32,
            t: &[f32; 8],
            child: &[u32; 8],
            count: &[u32; 8],
        ) -> Option<super::SortedLanes>;
        /// Whether [`Level::copy_ray`](super::Level::copy_ray) copies in words.
        fn narrow_copies(self) -> bool;
        /// [`hits_outside`](crate::triangle::hits_outside), and the lanes
        /// [`proven_hit`](crate::triangle::proven_hit) proves, compiled for the level (out of
        /// line at the baseline, inlined into the AVX2 level's copy).
        fn outside<L: SimdLanes>(self, t: &ShearedLanes<L>, tmin: f32, tmax: f32) -> (u32, u32);
        /// The `f64` refinement of an accepted triangle of nonzero area (the caller drops
        /// zero-area ones), given by its vertices along the ray's axes, compiled for the level
        /// (out of line at the baseline, inlined into the AVX2 level's copy).
        fn finish(self, p: &AxisVertices, ray: &Ray, e: (f32, f32, f32)) -> Option<PrimHit>;
    }
}

/// [`sealed::Sealed::window8`] on the eight-lane vectors `$lanes`.
macro_rules! window8_on {
    ($lanes:ty) => {
        #[inline(always)]
        fn window8<const ANY_HIT: bool>(
            self,
            soa: &TriangleSoa,
            leaf: (usize, usize),
            k: usize,
            ids: &[u32],
            r: &mut Ray,
            skip: &mut impl FnMut(u32) -> bool,
            best: &mut impl Keep,
        ) -> bool {
            soa.test_window::<$lanes, Self, _, ANY_HIT>(self, leaf, k, ids, r, skip, best)
        }
    };
}

impl sealed::Sealed for BaseLevel {
    #[inline(always)]
    fn sort8(self, _: u32, _: &[f32; 8], _: &[u32; 8], _: &[u32; 8]) -> Option<SortedLanes> {
        None
    }

    #[inline(always)]
    fn le8_i32(self, a: &[i32; 8], b: &[i32; 8]) -> u32 {
        use wide::{CmpGt, i32x8};
        !(i32x8::from(*a).cmp_gt(i32x8::from(*b)).move_mask() as u32) & 0xff
    }

    #[inline(always)]
    fn narrow_copies(self) -> bool {
        false
    }

    window8_on!(wide::f32x8);

    #[inline(always)]
    fn outside<L: SimdLanes>(self, t: &ShearedLanes<L>, tmin: f32, tmax: f32) -> (u32, u32) {
        crate::triangle::hits_outside_and_proven(t, tmin, tmax)
    }

    #[inline(always)]
    fn finish(self, p: &AxisVertices, ray: &Ray, e: (f32, f32, f32)) -> Option<PrimHit> {
        Triangle::finish_nondegenerate(p, ray, e)
    }
}

#[cfg(target_arch = "x86_64")]
impl sealed::Sealed for Avx2Level {
    #[inline(always)]
    fn sort8(
        self,
        hit: u32,
        t: &[f32; 8],
        child: &[u32; 8],
        count: &[u32; 8],
    ) -> Option<SortedLanes> {
        Some(crate::triangle::Avx8::far_to_near8(hit, t, child, count))
    }

    #[inline(always)]
    fn le8_i32(self, a: &[i32; 8], b: &[i32; 8]) -> u32 {
        crate::triangle::Avx8::le_bits8_i32(a, b)
    }

    #[inline(always)]
    fn narrow_copies(self) -> bool {
        self.0
    }

    window8_on!(crate::triangle::Avx8);

    // The bounds and the refinement inlined into the level's copy of the leaf test (compiled
    // for AVX2 with it): a call per candidate lane cost more than the code it keeps out of
    // the loop.
    #[inline(always)]
    fn outside<L: SimdLanes>(self, t: &ShearedLanes<L>, tmin: f32, tmax: f32) -> (u32, u32) {
        crate::triangle::outside_and_proven_lanes(t, tmin, tmax)
    }

    #[inline(always)]
    fn finish(self, p: &AxisVertices, ray: &Ray, e: (f32, f32, f32)) -> Option<PrimHit> {
        Triangle::finish_nondegenerate_inline(p, ray, e)
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl sealed::Sealed for Avx2Level {
    #[inline(always)]
    fn sort8(self, _: u32, _: &[f32; 8], _: &[u32; 8], _: &[u32; 8]) -> Option<SortedLanes> {
        None
    }

    #[inline(always)]
    fn le8_i32(self, a: &[i32; 8], b: &[i32; 8]) -> u32 {
        BaseLevel.le8_i32(a, b)
    }

    #[inline(always)]
    fn narrow_copies(self) -> bool {
        self.0
    }

    window8_on!(wide::f32x8);

    #[inline(always)]
    fn outside<L: SimdLanes>(self, t: &ShearedLanes<L>, tmin: f32, tmax: f32) -> (u32, u32) {
        BaseLevel.outside(t, tmin, tmax)
    }

    #[inline(always)]
    fn finish(self, p: &AxisVertices, ray: &Ray, e: (f32, f32, f32)) -> Option<PrimHit> {
        BaseLevel.finish(p, ray, e)
    }
}

/// Work to run compiled for an instruction set ([`run`]): its `run` is `#[inline(always)]`,
/// down to the leaf kernels, so that each level's copy is compiled for that level.
pub trait Kernel {
    /// What the work returns.
    type Output;
    /// Whether [`Isa::Avx512`] runs this work compiled with AVX-512 enabled (else its AVX2
    /// copy runs there): only for work measured faster so.
    const AVX512: bool = false;
    /// Does the work at `level`.
    fn run<L: Level>(self, level: L) -> Self::Output;
}

/// Asks the cache for `lines` cache lines from `p` (64 bytes each): a hint, which reads
/// nothing and cannot fault, whatever the address (nothing off x86-64).
#[inline(always)]
pub fn prefetch(p: *const u8, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    for line in 0..lines {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: a prefetch only hints the cache: it reads nothing the program sees and does
        // not fault. Measured reason: the walks of scenes larger than the cache ran 4-5%
        // faster with the leaves and nodes they enter asked for early.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line).cast::<i8>()) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, lines);
}

/// `k.run(level)` compiled for `isa`, or for the best level below it that this CPU runs, with
/// that level's value.
#[inline]
pub fn run<K: Kernel>(isa: Isa, k: K) -> K::Output {
    match isa.or_best() {
        Isa::Baseline => run_base(k),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `or_best` returned AVX-512, so this CPU has every feature the function
        // enables. Measured reason: any-hit walks ran 2-3% faster with AVX-512's registers.
        Isa::Avx512 if K::AVX512 => unsafe { x86::run_v4(k, x86::slow_wide_moves()) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `or_best` returned AVX2 or above, so this CPU has every feature the function
        // enables.
        Isa::Avx2 | Isa::Avx512 => unsafe { x86::run_v3(k) },
        #[cfg(not(target_arch = "x86_64"))]
        _ => k.run(BaseLevel),
    }
}

/// `k.run(BaseLevel)` out of line: the caller of [`run`] then holds only the dispatch, not a
/// whole baseline copy of the work with its stack frame set up on every call.
#[inline(never)]
fn run_base<K: Kernel>(k: K) -> K::Output {
    k.run(BaseLevel)
}

/// A structure's whole query, written once and compiled per instruction set by [`query`].
/// Implementations are `#[inline(always)]`, down to the leaf kernels, so that each copy is
/// compiled for its level.
pub trait Walk {
    /// Whether closest-hit queries run the AVX-512 level's copy where the CPU has it, as
    /// any-hit queries always do ([`Kernel::AVX512`]): for walks measured faster so.
    const CLOSEST_AVX512: bool = false;

    /// The level [`query`] runs the walk compiled for.
    fn isa(&self) -> Isa;

    /// The closest hit, or with `ANY_HIT` any hit, at `level` (handed to the leaf tests),
    /// its candidates offered to `best` ([`Keep`]: plain, or through a filter).
    fn walk<const ANY_HIT: bool, L: Level, K: Keep>(
        &self,
        ray: &Ray,
        level: L,
        best: K,
    ) -> Option<Hit>;
}

/// `w.walk::<ANY_HIT, _, _>(ray, level, best())` compiled for `w.isa()`, or for the best
/// level below it that this CPU runs: the answers are the same on every level (the kernels'
/// arithmetic is the same sequence of IEEE operations; only the width of the instructions
/// differs). The keeper is made inside the compiled walk (`|| None` for plain queries), so
/// that the walk starts from a known empty one.
#[inline]
pub fn query<W: Walk + ?Sized, const ANY_HIT: bool, K: Keep>(
    w: &W,
    ray: &Ray,
    best: impl FnOnce() -> K,
) -> Option<Hit> {
    run(w.isa(), Query::<W, _, ANY_HIT> { w, ray, best })
}

/// One query as [`Kernel`] work.
struct Query<'a, W: ?Sized, B, const ANY_HIT: bool> {
    w: &'a W,
    ray: &'a Ray,
    best: B,
}

impl<W: Walk + ?Sized, K: Keep, B: FnOnce() -> K, const ANY_HIT: bool> Kernel
    for Query<'_, W, B, ANY_HIT>
{
    type Output = Option<Hit>;
    const AVX512: bool = ANY_HIT || W::CLOSEST_AVX512;
    #[inline(always)]
    fn run<L: Level>(self, level: L) -> Option<Hit> {
        self.w.walk::<ANY_HIT, L, K>(self.ray, level, (self.best)())
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Avx2Level, Kernel};

    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    pub(super) fn run_v3<K: Kernel>(k: K) -> K::Output {
        k.run(Avx2Level(false))
    }

    /// The AVX2 level's code with AVX-512's registers (the level's value stays the AVX2 one:
    /// the same eight-lane vectors), copying rays in words where `narrow`.
    #[target_feature(
        enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq,avx512cd"
    )]
    pub(super) fn run_v4<K: Kernel>(k: K, narrow: bool) -> K::Output {
        k.run(Avx2Level(narrow))
    }

    /// Whether one 512-bit move slows the 256-bit code around it on this CPU: Intel's cores
    /// lower their clock and close vector ports for 512-bit work (the AVX-512 walks ran
    /// faster on a Xeon with rays copied in words), AMD's do not (a Zen 4 ran them faster with
    /// the plain copy).
    #[inline]
    pub(super) fn slow_wide_moves() -> bool {
        static INTEL: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *INTEL.get_or_init(|| {
            let id = std::arch::x86_64::__cpuid(0);
            // "GenuineIntel" in EBX, EDX, ECX.
            (id.ebx, id.edx, id.ecx) == (0x756e_6547, 0x4965_6e69, 0x6c65_746e)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_levels_are_ordered() {
        for isa in Isa::ALL {
            assert_eq!(Isa::parse(isa.name()), Ok(isa));
        }
        assert!(Isa::parse("sse9").is_err());
        assert!(Isa::Baseline.supported());
        assert!(Isa::available().contains(&Isa::best()));
        assert!(Isa::Avx2.or_best() <= Isa::best());
    }

    /// `Level::far_to_near8` at every level this CPU runs, as `isa`'s work (the AVX-512
    /// level's copy included).
    struct Sort<'a>(u32, &'a [f32; 8]);

    impl Kernel for Sort<'_> {
        type Output = Option<(Isa, SortedLanes)>;
        const AVX512: bool = true;
        fn run<L: Level>(self, level: L) -> Self::Output {
            let child = std::array::from_fn(|l| 100 + l as u32);
            let count = std::array::from_fn(|l| l as u32 % 3);
            level
                .far_to_near8(self.0, self.1, &child, &count)
                .map(|s| (L::ISA, s))
        }
    }

    #[test]
    fn far_to_near_puts_the_hit_lanes_first_by_distance() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut sorted = 0;
        for case in 0..4000 {
            let hit = next() as u32 & 0xff;
            // Distinct distances, ties, zeros, infinity; negative ones in the last quarter.
            let t: [f32; 8] = std::array::from_fn(|_| match next() % 6 {
                0 => 0.0,
                1 => 1.5,
                2 => f32::INFINITY,
                _ if case >= 3000 => (next() % 2000) as f32 / 100.0 - 10.0,
                _ => (next() % 100_000) as f32 / 7.0,
            });
            for isa in Isa::available() {
                let Some((level, s)) = run(isa, Sort(hit, &t)) else {
                    assert_eq!(isa, Isa::Baseline, "only the baseline has no sort");
                    continue;
                };
                assert_ne!(level, Isa::Baseline);
                sorted += 1;
                let n = hit.count_ones() as usize;
                let lanes: Vec<usize> = s.child.iter().map(|&c| c as usize - 100).collect();
                for (i, &l) in lanes.iter().enumerate() {
                    assert_eq!(
                        (s.count[i], s.t[i].to_bits()),
                        (l as u32 % 3, t[l].to_bits())
                    );
                }
                let mut first: Vec<usize> = lanes[..n].to_vec();
                first.sort_unstable();
                let want: Vec<usize> = (0..8).filter(|&l| hit & 1 << l != 0).collect();
                assert_eq!(first, want, "hit {hit:08b} t {t:?}: {lanes:?}");
                if case < 3000 {
                    // Far to near, ties (to the three lowest bits) with the higher lane nearer.
                    let key = |l: usize| ((t[l].to_bits() & !7) as i64, -(l as i64));
                    assert!(lanes[..n].windows(2).all(|w| key(w[0]) > key(w[1])));
                }
            }
        }
        if Isa::best() > Isa::Baseline {
            assert!(sorted > 0);
        }
    }
}
