//! Primitives stored leaf by leaf for the leaf test: [`TriangleSoa`], triangles as structure
//! of arrays tested four or eight at a time
//! ([`watertight_rows`](crate::triangle::watertight_rows)) with exactly the answers of the
//! scalar kernel (the leaves of rt's wide BVHs over triangles), and [`LeafPrims`], the same
//! for structures whose leaves list primitives by id (kd-trees, BSP trees, octrees, grids):
//! a copy of each listed primitive in listing order, so that a leaf test reads its leaf's
//! bytes in a row instead of gathering primitives through the ids.
//!
//! [`TriangleSoa`] layout: one `f32` array holding, leaf after leaf, each leaf's triangles as
//! structure of arrays in blocks of up to eight. A leaf `(first, count)` (triangles `first ..
//! first + count` in leaf order) occupies `9 * count` floats from `9 * first`; its block `b`
//! (triangles `8 b .. 8 b + m` of the leaf, `m = min(8, count - 8 b)`) the `9 * m` floats from
//! `9 * (first + 8 b)`: the `m` values of `v0.x`, then of `v0.y`, ... `v2.z`. A leaf's bytes
//! are as contiguous as an array of triangles (the same cache lines), and the window of
//! triangles `k .. k + 8` (or `k + 4`), `i = k - 8 b` lanes into its block, reads coordinate
//! `j` at `9 * (first + 8 b) + j * m + i`; lanes past the block read its next row (or the next
//! block, or the padding at the end) and are masked off. Every window lies in one fixed-size
//! span of the array, taken with one bounds check, in which the rows' offsets are provably in
//! range (a block is at most eight wide): no check per row. At the AVX2 level every window is
//! eight lanes wide (one register, as cheap as four); at the baseline, eight-lane windows are
//! taken while more than four triangles remain and four-lane ones after.

use crate::isa::{BaseLevel, Isa, Kernel, Level};
use crate::pages::Pages;
use crate::triangle::{
    AxisVertices, SimdLanes, lane_edges, moller_trumbore_held, moller_trumbore_rows,
    moller_trumbore_span, signs_agree, watertight_rows_at, woop_hit,
};
use crate::{Keep, Primitive, Ray, Triangle, TriangleKernel, Vec3};
use wide::f32x4;

/// Triangles tested together in the narrow window.
pub const LANES: usize = 4;

/// The span of floats a window reads, from its block's first float: the last row's start
/// (eight rows of up to eight floats), the window's offset in its block (below eight) and a
/// row's eight lanes, `64 + 7 + 8`, rounded up.
const WINDOW: usize = 80;

/// Floats of padding after the last leaf: the window of a leaf's last block stays inside
/// the data.
pub const PADDING: usize = WINDOW;

/// Rows of this many bytes or more are prefetched leaf by leaf as a walk enters them, and the
/// walk's nodes with them ([`TriangleSoa::prefetches`]).
pub const PREFETCH_BYTES: usize = 8 << 20;

/// Leaf-ordered triangles, each leaf as structure of arrays (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct TriangleSoa {
    data: Pages<f32>,
    len: usize,
    /// Bit `i` set where triangle `i` (leaf order) has zero area ([`Triangle::is_degenerate`]):
    /// never hit, but one of its edge functions is exactly zero for every ray (two coincident
    /// vertices, common in scanned meshes), which sends its lane to the scalar path each
    /// time. Empty when no triangle is degenerate; else one spare word at the end.
    degenerate: Vec<u64>,
    /// See [`Self::prefetches`].
    prefetch: bool,
    /// See [`Self::kernel`].
    kernel: TriangleKernel,
}

impl TriangleSoa {
    /// Lays out the leaf-ordered `tris`; `leaves` are the `(first, count)` ranges that cover
    /// them (each triangle in exactly one).
    pub fn new(tris: &[Triangle], leaves: impl IntoIterator<Item = (u32, u32)>) -> Self {
        let mut data = Pages::filled(9 * tris.len() + PADDING, 0.0);
        for (first, count) in leaves {
            let (first, count) = (first as usize, count as usize);
            for k in 0..count {
                let (base, m, i) = block_of(first, count, k);
                for j in 0..9 {
                    data[base + j * m + i] = tris[first + k].v[j / 3][j % 3];
                }
            }
        }
        let mut degenerate = vec![0u64; tris.len() / 64 + 2];
        for (i, t) in tris.iter().enumerate() {
            degenerate[i / 64] |= (t.is_degenerate() as u64) << (i % 64);
        }
        if degenerate.iter().all(|&w| w == 0) {
            degenerate = Vec::new();
        }
        Self {
            prefetch: data.len() * 4 >= PREFETCH_BYTES,
            data,
            len: tris.len(),
            degenerate,
            kernel: TriangleKernel::Watertight,
        }
    }

    /// Bits of the degenerate triangles among `i .. i + 32` (leaf order; bits past the end
    /// are zero).
    #[inline(always)]
    fn degenerate_bits(&self, i: usize) -> u32 {
        let (w, s) = (i / 64, i % 64);
        let lo = self.degenerate[w] >> s;
        // `<< 1 << (63 - s)`: no shift by 64 when `s` is 0.
        let hi = (self.degenerate[w + 1] << 1) << (63 - s);
        (lo | hi) as u32
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no triangle is stored.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Triangle `k` of the leaf `(first, count)`.
    #[inline]
    pub fn get(&self, first: usize, count: usize, k: usize) -> Triangle {
        assert!(k < count, "triangle {k} of a leaf of {count}");
        let (base, m, i) = block_of(first, count, k);
        triangle_at(self.window(base), m, i)
    }

    /// The span of floats from `base` that a window starting there reads.
    #[inline(always)]
    fn window(&self, base: usize) -> &[f32; WINDOW] {
        self.data[base..]
            .first_chunk()
            .expect("every window lies inside the data and its padding")
    }

    /// The layout's floats, leaf after leaf (see the module documentation), with the
    /// padding at the end: leaf `(first, count)` is `rows()[9 * first..9 * (first + count)]`.
    pub fn rows(&self) -> &[f32] {
        &self.data
    }

    /// Bytes of the triangle data.
    pub fn bytes(&self) -> usize {
        self.data.len() * 4 + self.degenerate.len() * 8
    }

    /// Whether walks ask for the children a node's test enters (the nodes, and the rows of
    /// the leaves at [`Self::leaf_address`]) at once, before they reach them: by default for
    /// large scenes ([`PREFETCH_BYTES`] of rows or more), whose walks reach past the caches
    /// often enough for early requests to pay. In smaller scenes the requests only add
    /// instructions.
    pub fn prefetches(&self) -> bool {
        self.prefetch
    }

    /// Sets [`Self::prefetches`] (the answers stay the same either way).
    pub fn set_prefetch(&mut self, on: bool) {
        self.prefetch = on;
    }

    /// The ray/triangle kernel the leaf tests run: the watertight one by default, or
    /// Möller–Trumbore's ([`Triangle::intersect_moller_trumbore`]: faster, not watertight).
    /// Either way a range answers what testing each of its triangles with that kernel does.
    pub fn kernel(&self) -> TriangleKernel {
        self.kernel
    }

    /// Sets [`Self::kernel`].
    pub fn set_kernel(&mut self, kernel: TriangleKernel) {
        self.kernel = kernel;
    }

    /// Where the rows of the leaf starting at triangle `first` (leaf order) begin: an address
    /// for a walk to ask the cache for ([`crate::isa::prefetch`]), never read through.
    #[inline(always)]
    pub fn leaf_address(&self, first: usize) -> *const u8 {
        self.data.as_slice().as_ptr().wrapping_add(9 * first).cast()
    }

    /// Tests triangles `first .. first + count` against the ray, in order: the edge functions
    /// and their sign test for eight triangles at once (at the baseline level: while more
    /// than four remain, then four; SIMD lanes, one bit mask), then the scalar kernel's own
    /// [`Triangle::finish_watertight`] for the lanes that may hit, each hit offered to
    /// `best` ([`Keep::keep`], ids from `ids[first..]`), which records it and says whether the
    /// search is over. Triangles whose id `skip` names (mailboxes: asked in order, before
    /// their window is tested) are not tested. Returns true when `best` did. With
    /// Möller–Trumbore's kernel ([`Self::kernel`]) the windows run that test instead, with
    /// the answers of [`Triangle::intersect_moller_trumbore`].
    ///
    /// With `ANY_HIT` (queries that stop at the first hit) and no filter, a triangle whose
    /// hit [`proven_hit`](crate::triangle::proven_hit) proves inside the ray's interval
    /// (proved for the window's lanes at once) is handed over with Woop's `f32` estimates of
    /// `t`, `u`, `v` instead of the refined ones: the same answer, without the `f64`
    /// refinement; to a keeper that does not read them ([`Keep::ANY_HIT_VALUES`]), as a hit
    /// at `tmin`.
    ///
    /// The eight-lane windows run on `level`'s vectors ([`Level`]: one AVX register at the
    /// AVX2 level, inside a walk [`crate::isa::run`] runs there).
    #[inline(always)]
    pub fn test_range<const ANY_HIT: bool, V: Level>(
        &self,
        level: V,
        (first, count): (usize, usize),
        ids: &[u32],
        r: &mut Ray,
        mut skip: impl FnMut(u32) -> bool,
        best: &mut impl Keep,
    ) -> bool {
        let leaf = (first, count);
        let ids = &ids[first..first + count];
        let mut k = 0;
        while k < count {
            // At the AVX2 level (a constant in each level's copy) eight lanes cost what four
            // do, and one window covers a leaf of up to eight: no branch on the leaf's size.
            let eight = V::ISA == Isa::Avx2 || count - k > LANES;
            let over = if eight {
                level.window8::<ANY_HIT>(self, leaf, k, ids, r, &mut skip, best)
            } else {
                self.test_window::<f32x4, V, _, ANY_HIT>(level, leaf, k, ids, r, &mut skip, best)
            };
            if over {
                return true;
            }
            k += if eight { 8 } else { LANES };
        }
        false
    }

    /// Triangles `k .. k + L::WIDTH` of leaf `(first, count)` (those in the leaf), as
    /// [`Self::test_range`] tests them. Any window stays inside the leaf's rows, the next
    /// leaf's and the padding.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn test_window<L: SimdLanes, V: Level, K: Keep, const ANY_HIT: bool>(
        &self,
        level: V,
        (first, count): (usize, usize),
        k: usize,
        ids: &[u32],
        r: &mut Ray,
        skip: &mut impl FnMut(u32) -> bool,
        best: &mut K,
    ) -> bool {
        // The window's block: `m` triangles wide, the window `off` lanes into it. Lanes past
        // the block belong to the next block, or leaf.
        let (base, m, off) = block_of(first, count, k);
        let win = self.window(base);
        let mut lanes = (1u32 << (m - off).min(L::WIDTH)) - 1;
        for (l, &id) in ids[k..].iter().take(L::WIDTH).enumerate() {
            if skip(id) {
                lanes &= !(1 << l);
            }
        }
        crate::counters::prims(lanes.count_ones());
        if self.kernel == TriangleKernel::MollerTrumbore {
            return self.moller_window::<L, K, ANY_HIT>(
                #[inline(always)]
                |j| L::load(&win[j * m + off..]),
                (win, m, off),
                &ids[k..],
                lanes,
                r,
                best,
            );
        }
        // Any-hit queries leaving a surface: the lanes whose hit `proven_hit` proves, all at
        // once with the window's other bounds, rather than one lane at a time (a long chain
        // of dependent operations on the way to the query's end).
        let prove = ANY_HIT && !K::FILTERED && r.tmin > 0.0;
        // Row `j` straight from the block (the ray's axes pick which rows are read).
        let (may_hit, proven, sheared) = watertight_rows_at(
            level,
            #[inline(always)]
            |j| L::load(&win[j * m + off..]),
            r,
            prove,
        );
        let mut may_hit = may_hit & lanes;
        if !self.degenerate.is_empty() {
            // `finish_watertight` returns `None` for them: not asked. (Masked whether or not
            // a lane may hit: a branch on the scene, not on the ray.)
            may_hit &= !self.degenerate_bits(first + k);
        }
        while may_hit != 0 {
            // Below eight (the lanes' bits): the window's reads stay in its span.
            let l = may_hit.trailing_zeros() as usize & 7;
            may_hit &= may_hit - 1;
            // Skipped primitives (masks, the one a ray leaves) are dropped here, among the
            // few lanes whose edge signs may hit: all eight lanes are computed together
            // anyway, and none of them goes further.
            if K::SKIPS && best.skips(ids[k + l]) {
                continue;
            }
            if proven & (1 << l) != 0 && !K::ANY_HIT_VALUES {
                // Only whether there is a hit is asked, and this one is proven.
                let h = crate::PrimHit {
                    t: r.tmin,
                    u: 0.0,
                    v: 0.0,
                };
                if best.keep::<ANY_HIT>(h, ids[k + l], &mut r.tmax) {
                    return true;
                }
                continue;
            }
            let edges = lane_edges(&sheared, l);
            if proven & (1 << l) != 0 {
                // Woop's numbers for the lane, as `proven_hit` computes them.
                let [_, _, kz] = r.watertight_axes();
                let oz = r.origin().to_array()[kz];
                let sz = r.watertight_shear().z;
                let z = |v: usize| (win[(3 * v + kz) * m + off + l] - oz) * sz;
                let e = [edges.0.abs(), edges.1.abs(), edges.2.abs()];
                let num = e[0] * z(0) + e[1] * z(1) + e[2] * z(2);
                let den = e[0] + e[1] + e[2];
                if let Some(h) = woop_hit(num, den, edges, r) {
                    if best.keep::<ANY_HIT>(h, ids[k + l], &mut r.tmax) {
                        return true;
                    }
                    continue;
                }
            }
            if !signs_agree(edges) {
                continue;
            }
            // The vertices along the ray's axes, straight from the rows (in the span: a
            // block is at most eight wide, the axes below three).
            let p: AxisVertices = {
                let (m, i) = (m.min(8), (off + l) & 7);
                let axes = r.watertight_axes().map(|a| a.min(2));
                std::array::from_fn(|v| axes.map(|a| win[(3 * v + a) * m + i]))
            };
            if let Some(h) = level.finish(&p, r, edges) {
                if best.keep::<ANY_HIT>(h, ids[k + l], &mut r.tmax) {
                    return true;
                }
            }
        }
        false
    }

    /// [`Self::test_window`] with Möller–Trumbore's kernel: the window's `lanes` (rows from
    /// `row`; `win`, `m`, `off` as there; `ids` the ids of the window's first triangle
    /// onwards) tested at once, then each lane whose barycentrics pass finished
    /// one by one, as [`Triangle::intersect_moller_trumbore`] finishes it (its depth held in
    /// its box, then checked against the ray's interval as it stands), but for the lanes the
    /// window's vector tests decide ([`moller_trumbore_held`], [`moller_trumbore_span`]).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn moller_window<L: SimdLanes, K: Keep, const ANY_HIT: bool>(
        &self,
        row: impl Fn(usize) -> L + Copy,
        (win, m, off): (&[f32; WINDOW], usize, usize),
        ids: &[u32],
        lanes: u32,
        r: &mut Ray,
        best: &mut K,
    ) -> bool {
        // Zero-area triangles need no mask here (the watertight test keeps one): their `f32`
        // cross product, the normal this kernel computes with the same operations, is zero
        // ([`Triangle::is_degenerate`]), so their determinant is zero and no lane accepts.
        let (inside, numbers) = moller_trumbore_rows(row, r);
        let mut hit = inside & lanes;
        if hit == 0 {
            return false;
        }
        let [t, u, v] = numbers.values();
        // Lanes whose depth lies outside the interval hit only where the depth moves into it
        // (not held in the box): those whose box surely holds it do not, and many others are
        // ruled out by the span of their vertices' parameters along the axes. Where these
        // tests run, the lanes in the interval whose box surely holds the depth need no check
        // of their own.
        let inside = L::le_bits(L::splat(r.tmin), t) & L::le_bits(t, L::splat(r.tmax));
        let mut sure = 0;
        if hit & !inside != 0 {
            let held = moller_trumbore_held(row, r, t);
            hit &= inside | !held;
            if hit & !inside != 0 {
                hit &= !moller_trumbore_span(row, r) | inside;
            }
            sure = held & inside;
        }
        let (t, u, v) = (t.to_lanes(), u.to_lanes(), v.to_lanes());
        while hit != 0 {
            let l = hit.trailing_zeros() as usize & 7;
            hit &= hit - 1;
            if K::SKIPS && best.skips(ids[l]) {
                continue;
            }
            let h = if sure & (1 << l) != 0 {
                // Surely held, and in the interval as it stood at the window's test: still
                // in it unless a hit of this window since lowered `tmax` below it.
                if t[l] > r.tmax {
                    continue;
                }
                crate::PrimHit {
                    t: t[l],
                    u: u[l],
                    v: v[l],
                }
            } else {
                match triangle_at(win, m, off + l).moller_trumbore_hit(r, t[l], u[l], v[l]) {
                    Some(h) => h,
                    None => continue,
                }
            };
            if best.keep::<ANY_HIT>(h, ids[l], &mut r.tmax) {
                return true;
            }
        }
        false
    }

    /// [`Self::test_range`] of every triangle of the range: the closest hit kept in `best`
    /// (ties by [`crate::replaces`]) and `r.tmax` lowered to it; with `ANY_HIT`, the first
    /// hit ends the search (true).
    #[inline(always)]
    pub fn intersect_range<const ANY_HIT: bool, V: Level>(
        &self,
        level: V,
        first: usize,
        count: usize,
        r: &mut Ray,
        ids: &[u32],
        best: &mut impl Keep,
    ) -> bool {
        self.test_range::<ANY_HIT, V>(level, (first, count), ids, r, |_| false, best)
    }
}

/// Where triangle `k` of leaf `(first, count)` lies: the first float of its block, the
/// block's width `m` (1 to 8) and the triangle's lane `i` in it (below eight; coordinate `j`
/// at `base + j * m + i`).
#[inline(always)]
fn block_of(first: usize, count: usize, k: usize) -> (usize, usize, usize) {
    let block = k & !7;
    ((first + block) * 9, (count - block).min(8), k & 7)
}

/// Triangle `i` of the block of width `m` (at most eight) whose rows start at `win[0]`
/// (inlined into the leaf tests, which compile per level; in range by the span's size).
#[inline(always)]
fn triangle_at(win: &[f32; WINDOW], m: usize, i: usize) -> Triangle {
    let (m, i) = (m.min(8), i & 7);
    let c: [f32; 9] = std::array::from_fn(|j| win[j * m + i]);
    Triangle::new(
        Vec3::new(c[0], c[1], c[2]),
        Vec3::new(c[3], c[4], c[5]),
        Vec3::new(c[6], c[7], c[8]),
    )
}

/// The primitives of a structure whose leaves list them by id (ranges of an index array):
/// a copy of each listed primitive at its place in the list, laid out for the leaf test.
/// Triangles ([`Primitive::as_triangle`]) are stored as [`TriangleSoa`] and tested four at a
/// time with no gathering; other primitives as an array, tested one by one. Either way a
/// leaf's primitives are contiguous, and every answer is the primitive's own kernel's.
///
/// Costs a copy of each primitive per listing (36 bytes per reference for triangles) on top
/// of the index array; buys a leaf test that reads its leaf in a row instead of gathering
/// through the ids.
#[derive(Clone, Debug, Default)]
pub struct LeafPrims<P> {
    soa: Option<TriangleSoa>,
    listed: Pages<P>,
}

impl<P: Primitive> LeafPrims<P> {
    /// Lays out `prims[indices[i]]` at place `i`, for leaves that test the ranges `lists` of
    /// `indices` (`(first, count)`, disjoint); places outside every list are never tested.
    pub fn new(prims: &[P], indices: &[u32], lists: impl IntoIterator<Item = (u32, u32)>) -> Self {
        let listed: Vec<P> = indices.iter().map(|&i| prims[i as usize].clone()).collect();
        let tris: Option<Vec<Triangle>> = listed.iter().map(|p| p.as_triangle().copied()).collect();
        match tris {
            Some(tris) if !tris.is_empty() => Self {
                soa: Some(TriangleSoa::new(&tris, lists)),
                listed: Pages::default(),
            },
            _ => Self {
                soa: None,
                listed: listed.into(),
            },
        }
    }

    /// Tests the primitives at places `first .. first + count` (ids `indices[first..]`),
    /// skipping the ids `skip` names, keeping the closest hit in `best` (ties by
    /// [`crate::replaces`]) and lowering `ray.tmax` to it: what [`crate::test_primitives`] does with
    /// the ids `indices[first..first + count]`. With `ANY_HIT`, stops at the first hit (true).
    #[inline(always)]
    pub fn test<const ANY_HIT: bool>(
        &self,
        places: (usize, usize),
        indices: &[u32],
        ray: &mut Ray,
        best: &mut impl Keep,
        skip: impl FnMut(u32) -> bool,
    ) -> bool {
        self.test_at::<ANY_HIT, _>(BaseLevel, places, indices, ray, best, skip)
    }

    /// [`Self::test`] with the triangles' windows compiled for `isa` (or for the best level
    /// below it this CPU runs), one dispatch per call ([`crate::isa::run`]): for walks that
    /// cannot run per level themselves (recursive ones), at the cost of a call per leaf.
    #[inline]
    pub fn test_on<const ANY_HIT: bool, K: Keep>(
        &self,
        isa: Isa,
        places: (usize, usize),
        indices: &[u32],
        ray: &mut Ray,
        best: &mut K,
        skip: impl FnMut(u32) -> bool,
    ) -> bool {
        if self.soa.is_none() || isa == Isa::Baseline {
            return self.test_at::<ANY_HIT, _>(BaseLevel, places, indices, ray, best, skip);
        }
        /// One leaf test as [`crate::isa::Kernel`] work.
        struct Leaf<'a, P, K, S, const ANY_HIT: bool> {
            prims: &'a LeafPrims<P>,
            places: (usize, usize),
            indices: &'a [u32],
            ray: &'a mut Ray,
            best: &'a mut K,
            skip: S,
        }
        impl<P: Primitive, K: Keep, S: FnMut(u32) -> bool, const ANY_HIT: bool> Kernel
            for Leaf<'_, P, K, S, ANY_HIT>
        {
            type Output = bool;
            #[inline(always)]
            fn run<L: Level>(self, level: L) -> bool {
                let (places, indices) = (self.places, self.indices);
                let (ray, best, skip) = (self.ray, self.best, self.skip);
                self.prims
                    .test_at::<ANY_HIT, L>(level, places, indices, ray, best, skip)
            }
        }
        let leaf = Leaf::<P, K, _, ANY_HIT> {
            prims: self,
            places,
            indices,
            ray,
            best,
            skip,
        };
        crate::isa::run(isa, leaf)
    }

    /// [`Self::test`] with the triangles' windows on `level`'s vectors ([`Level`]: inside a
    /// walk [`crate::isa::run`] runs, the level it runs at).
    #[inline(always)]
    pub fn test_at<const ANY_HIT: bool, V: Level>(
        &self,
        level: V,
        (first, count): (usize, usize),
        indices: &[u32],
        ray: &mut Ray,
        best: &mut impl Keep,
        mut skip: impl FnMut(u32) -> bool,
    ) -> bool {
        if let Some(soa) = &self.soa {
            return soa.test_range::<ANY_HIT, V>(level, (first, count), indices, ray, skip, best);
        }
        let ids = &indices[first..first + count];
        for (p, &id) in self.listed[first..first + count].iter().zip(ids) {
            if skip(id) || best.skips(id) {
                continue;
            }
            if let Some(h) = p.intersect(ray) {
                if best.keep::<ANY_HIT>(h, id, &mut ray.tmax) {
                    return true;
                }
            }
        }
        false
    }

    /// Checks that the copies at places `first .. first + count` are `prims[indices[i]]`
    /// (for the structures' `validate`): the same triangles, or primitives with the same
    /// bounds.
    pub fn check_list(
        &self,
        prims: &[P],
        indices: &[u32],
        (first, count): (u32, u32),
    ) -> Result<(), String> {
        let (first, count) = (first as usize, count as usize);
        let Some(ids) = indices.get(first..first + count) else {
            return Err(format!("list {first}+{count} runs past the index array"));
        };
        for (k, &id) in ids.iter().enumerate() {
            let Some(p) = prims.get(id as usize) else {
                return Err(format!(
                    "list {first}+{count} names primitive {id}, out of range"
                ));
            };
            let same = match &self.soa {
                Some(soa) => {
                    first + count <= soa.len() && p.as_triangle() == Some(&soa.get(first, count, k))
                }
                None => self.listed.get(first + k).map(Primitive::bounds) == Some(p.bounds()),
            };
            if !same {
                return Err(format!(
                    "the copy at place {} is not primitive {id}",
                    first + k
                ));
            }
        }
        Ok(())
    }

    /// Bytes of the copies.
    pub fn bytes(&self) -> usize {
        self.soa.as_ref().map_or(0, TriangleSoa::bytes)
            + std::mem::size_of_val(self.listed.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (rt-geom has no test-kit dependency).
    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A point of `[0, 1)^3` from [`lcg`].
    fn point(seed: &mut u64) -> Vec3 {
        Vec3::new(lcg(seed), lcg(seed), lcg(seed))
    }

    /// `n` triangles with a corner in `[-1, 1)^3` and edges up to `size` along each axis.
    fn random_triangles(n: usize, size: f32, seed: &mut u64) -> Vec<Triangle> {
        (0..n)
            .map(|_| {
                let a = point(seed) * 2.0 - 1.0;
                Triangle::new(a, a + point(seed) * size, a + point(seed) * size)
            })
            .collect()
    }

    /// `LeafPrims::test` against `test_primitives` over the same ids: same hit, same `tmax`,
    /// same answer, closest and any hit, with and without skipped ids.
    fn same_as_by_id<P: Primitive + std::fmt::Debug>(prims: &[P], seed: &mut u64) {
        // Lists of 1 to 9 references, ids repeating across lists (as cells share primitives).
        let mut indices = Vec::new();
        let mut lists = Vec::new();
        while indices.len() < 200 {
            let count = 1 + (lcg(seed) * 9.0) as u32;
            lists.push((indices.len() as u32, count));
            for _ in 0..count {
                indices.push((lcg(seed) * prims.len() as f32) as u32 % prims.len() as u32);
            }
        }
        let leaf = LeafPrims::new(prims, &indices, lists.iter().copied());
        let mut v = || Vec3::new(lcg(seed), lcg(seed), lcg(seed));
        for k in 0..300 {
            let o = v() * 4.0 - 2.0;
            let ray = Ray::segment(
                o,
                v() - o,
                0.0,
                if k % 3 == 0 { 0.8 } else { f32::INFINITY },
            );
            for &(first, count) in &lists {
                let ids = &indices[first as usize..(first + count) as usize];
                for skip_every in [0, 3] {
                    let skip = |p: u32| skip_every != 0 && p % skip_every == 0;
                    let (mut r1, mut r2) = (ray, ray);
                    let (mut b1, mut b2) = (None, None);
                    let places = (first as usize, count as usize);
                    let a1 = leaf.test::<false>(places, &indices, &mut r1, &mut b1, skip);
                    let a2 = crate::test_primitives::<P, false>(prims, ids, &mut r2, &mut b2, skip);
                    assert_eq!((a1, b1, r1.tmax), (a2, b2, r2.tmax), "{ray:?} {ids:?}");
                    let (mut b1, mut b2) = (None, None);
                    let a1 = leaf.test::<true>(places, &indices, &mut ray.clone(), &mut b1, skip);
                    let a2 = crate::test_primitives::<P, true>(
                        prims,
                        ids,
                        &mut ray.clone(),
                        &mut b2,
                        skip,
                    );
                    assert_eq!((a1, b1.is_some()), (a2, b2.is_some()), "{ray:?} {ids:?}");
                }
            }
        }
    }

    #[test]
    fn listed_triangles_and_spheres_answer_as_by_id() {
        let mut seed = 7;
        let tris = random_triangles(30, 0.8, &mut seed);
        same_as_by_id(&tris, &mut seed);
        let spheres: Vec<crate::Sphere> = (0..30)
            .map(|_| crate::Sphere::new(point(&mut seed) * 2.0 - 1.0, 0.05 + lcg(&mut seed) * 0.3))
            .collect();
        same_as_by_id(&spheres, &mut seed);
        // Triangles among other shapes: no SoA, the listed copies answer.
        let shapes: Vec<crate::Shape> = tris
            .iter()
            .map(|&t| crate::Shape::Triangle(t))
            .chain(spheres.iter().map(|&s| crate::Shape::Sphere(s)))
            .collect();
        same_as_by_id(&shapes, &mut seed);
        // `check_list` finds copies that are not the primitives named.
        let indices = [3, 1, 4, 1];
        let leaf = LeafPrims::new(&tris, &indices, [(0, 2), (2, 2)]);
        assert!(leaf.check_list(&tris, &indices, (0, 2)).is_ok());
        assert!(leaf.check_list(&tris, &[3, 2, 4, 1], (0, 2)).is_err());
        assert!(leaf.check_list(&tris, &indices, (3, 2)).is_err());
    }

    /// Zero-area triangles (two coincident vertices, or three in a line) among the others:
    /// their bits found across word boundaries, and the leaf tests, which skip them, answer
    /// as the scalar kernel does.
    #[test]
    fn degenerate_triangles_answer_as_by_id() {
        let mut seed = 11;
        let tris: Vec<Triangle> = random_triangles(150, 0.8, &mut seed)
            .into_iter()
            .enumerate()
            .map(|(i, t)| {
                let [a, b, _] = t.v;
                match i % 5 {
                    0 => Triangle::new(a, b, b),
                    1 => Triangle::new(a, b, a + (b - a) * 0.5),
                    _ => t,
                }
            })
            .collect();
        let soa = TriangleSoa::new(&tris, [(0, 150)]);
        for i in 0..150 {
            for l in 0..32 {
                let expected = tris.get(i + l).is_some_and(Triangle::is_degenerate);
                assert_eq!(soa.degenerate_bits(i) >> l & 1 == 1, expected, "{i} + {l}");
            }
        }
        assert!(
            TriangleSoa::new(&tris[2..5], [(0, 3)])
                .degenerate
                .is_empty()
        );
        same_as_by_id(&tris, &mut seed);
    }

    /// The leaf `leaf` of `soa` asked at `isa`'s level by `ray`: its closest hit (and the ray's
    /// `tmax` after), its any hit, and its occlusion query's hit.
    fn leaf_queries(
        soa: &TriangleSoa,
        leaf: (usize, usize),
        ids: &[u32],
        ray: Ray,
        isa: Isa,
    ) -> (
        (Option<crate::Hit>, f32),
        Option<crate::Hit>,
        Option<crate::Hit>,
    ) {
        struct Queries<'a> {
            soa: &'a TriangleSoa,
            leaf: (usize, usize),
            ids: &'a [u32],
            ray: Ray,
        }
        impl Kernel for Queries<'_> {
            type Output = (
                (Option<crate::Hit>, f32),
                Option<crate::Hit>,
                Option<crate::Hit>,
            );
            fn run<L: Level>(self, level: L) -> Self::Output {
                let (mut closest, mut any, mut occ) = (None, None, crate::Occlusion(None));
                let mut r = self.ray;
                let (soa, leaf, ids) = (self.soa, self.leaf, self.ids);
                soa.test_range::<false, L>(level, leaf, ids, &mut r, |_| false, &mut closest);
                let tmax = r.tmax;
                let mut r = self.ray;
                soa.test_range::<true, L>(level, leaf, ids, &mut r, |_| false, &mut any);
                let mut r = self.ray;
                soa.test_range::<true, L>(level, leaf, ids, &mut r, |_| false, &mut occ);
                ((closest, tmax), any, occ.best())
            }
        }
        let queries = Queries {
            soa,
            leaf,
            ids,
            ray,
        };
        crate::isa::run(isa, queries)
    }

    /// Occlusion queries ([`crate::Occlusion`]) end on a proven hit without its `t`, `u`, `v`:
    /// the same answer and the same primitive as the plain any-hit keeper, leaf by leaf, at
    /// both levels, for rays that leave a triangle of the leaf (`tmin > 0`) and rays that
    /// pass through, with the shortcut taken (a hit reported at `tmin`) in most of them.
    #[test]
    fn occlusion_answers_as_any_hit() {
        let mut seed = 5;
        let tris = random_triangles(60, 0.9, &mut seed);
        let leaves = [(0, 5), (5, 8), (13, 12), (25, 35)];
        let soa = TriangleSoa::new(&tris, leaves);
        let ids: Vec<u32> = (0..60).collect();
        let (mut hits, mut shortcut) = (0, 0);
        for k in 0..3000 {
            // From a point of a triangle (a shadow ray), or from anywhere.
            let t = &tris[k % 60];
            let (u, w) = (lcg(&mut seed) * 0.5, lcg(&mut seed) * 0.5);
            let on = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * w;
            let o = if k % 2 == 0 {
                on
            } else {
                point(&mut seed) * 4.0 - 2.0
            };
            let ray = Ray::segment(o, point(&mut seed) - o, 1e-4, 0.5 + lcg(&mut seed) * 4.0);
            for &(first, count) in &leaves {
                let leaf = (first as usize, count as usize);
                for isa in Isa::available() {
                    let (_, plain, occ) = leaf_queries(&soa, leaf, &ids, ray, isa);
                    assert_eq!(
                        plain.map(|h| h.prim),
                        occ.map(|h| h.prim),
                        "{ray:?} leaf {leaf:?} at {isa}"
                    );
                    hits += occ.is_some() as u32;
                    shortcut +=
                        occ.is_some_and(|h| h.t == ray.tmin && plain.unwrap().t != ray.tmin) as u32;
                }
            }
        }
        assert!(
            hits > 2000 && shortcut * 10 > hits * 5,
            "{shortcut} of {hits} hits by the shortcut"
        );
    }

    /// Möller–Trumbore leaves answer, at every level, what its scalar kernel answers
    /// triangle by triangle, closest and any hit (and occlusion queries, on the same
    /// triangle): on small triangles, on slivers far from the
    /// rays, and on large flat ones met a hair from their surface, whose `f32` depths the box
    /// often does not hold (some of them moved into the ray's interval from outside it); and
    /// the scalar kernel's closest hit does not depend on the order the triangles are tried
    /// in.
    #[test]
    fn moller_trumbore_leaves_answer_as_the_scalar_kernel() {
        let mut seed = 23;
        let mut tris = random_triangles(48, 0.9, &mut seed);
        for i in 0..24 {
            // Slivers 1e4 away, seen along their length from near the origin.
            let a = Vec3::new(1.0e4 + lcg(&mut seed), lcg(&mut seed), lcg(&mut seed));
            let b = a + Vec3::new(-2.0e4, 1e-3 * (1 + i % 5) as f32, lcg(&mut seed) * 1e-3);
            let (b, c) = if i % 2 == 0 {
                (b, a + Vec3::new(0.0, 1e-3, 2e-3))
            } else {
                // Along a diagonal, the third vertex a hair from the long edge: the `f32`
                // normal's products cancel, and the plane it gives tilts.
                let b = a + Vec3::new(-2.0e4, -1.3e4, 1e-3 * (1 + i % 5) as f32);
                (b, (a + b) * 0.5 + Vec3::new(0.0, 0.0, 2e-3))
            };
            tris.push(Triangle::new(a, b, c));
        }
        for i in 0..12 {
            // Large triangles in planes of constant z (flat boxes, as a floor's) or tilted a
            // little (thin boxes, whose plane the `f32` normal places less well), met a hair
            // from their surface (a shadow ray's occluder).
            let a = point(&mut seed) * 200.0 - 100.0;
            let flat = Vec3::new(200.0, 200.0, 0.0);
            let tilt = Vec3::new(0.0, 0.0, [0.0, 1e-3, 3e-2][i % 3]);
            tris.push(Triangle::new(
                a,
                a + point(&mut seed) * flat + tilt,
                a + point(&mut seed) * flat - tilt * 0.5,
            ));
        }
        // Zero area: a repeated vertex, and three points on a line whose `f32` cross product
        // is exactly zero (the window has no mask for them: their determinant rejects them).
        tris[7] = Triangle::new(tris[7].v[0], tris[7].v[1], tris[7].v[1]);
        let a = Vec3::new(0.25, 0.5, 0.75);
        tris[8] = Triangle::new(a, a * 2.0, a * 3.0);
        assert!(tris[7].is_degenerate() && tris[8].is_degenerate());
        let n = tris.len() as u32;
        let leaves = [
            (0, 5),
            (5, 8),
            (13, 12),
            (25, 23),
            (48, 9),
            (57, 15),
            (72, 12),
        ];
        let mut soa = TriangleSoa::new(&tris, leaves);
        soa.set_kernel(TriangleKernel::MollerTrumbore);
        let ids: Vec<u32> = (0..n).rev().collect();
        let (mut hits, mut moved, mut rescued) = (0, 0, 0);
        for k in 0..12000 {
            let t = &tris[k % tris.len()];
            let (u, w) = (lcg(&mut seed) * 0.5, lcg(&mut seed) * 0.5);
            let on = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * w;
            let big = &tris[72 + k % 12];
            let near = big.v[0] + (big.v[1] - big.v[0]) * u + (big.v[2] - big.v[0]) * w;
            let lift = big.normal() * (0.001 + lcg(&mut seed) * 0.3);
            let sliver = (48..72).contains(&(k % tris.len()));
            let o = match k % 4 {
                0 => on,
                // A sliver met from close by: where its normal's products cancel, the plane
                // its `f32` depth lies on tilts.
                1 if sliver => on + (point(&mut seed) - 0.5) * 0.5,
                1 => point(&mut seed) * 4.0 - 2.0,
                2 => Vec3::new(-1.0e4, lcg(&mut seed) * 1e-2, lcg(&mut seed) * 1e-2),
                _ => near + lift,
            };
            let to = match k % 4 {
                1 if sliver => on * 2.0 - o,
                2 => on,
                3 => near - lift * (0.2 + lcg(&mut seed)) + (point(&mut seed) - 0.5) * 3.0,
                _ => point(&mut seed),
            };
            let tmax = if k % 5 == 0 {
                f32::INFINITY
            } else {
                0.5 + lcg(&mut seed) * 3e4
            };
            // Rays a hair from a large triangle: the interval ends where they cross its plane,
            // where the `f32` depth and the one held in the box may part.
            let cross = ((o.z - near.z) as f64 / (o.z - to.z) as f64) as f32;
            let (tmin, tmax) = match (k % 4, k % 8) {
                (0, _) => (1e-4, tmax),
                // Through the sliver's point halfway: the interval ends there.
                (1, 1) if sliver => (0.0, 0.5),
                (1, _) if sliver => (0.5, tmax),
                (3, 3) => (0.0, cross),
                (3, _) => (cross, tmax),
                _ => (0.0, tmax),
            };
            let ray = Ray::segment(o, to - o, tmin, tmax);
            // Every triangle in turn, forwards and backwards: the same closest hit.
            let mut scalar = |order: &mut dyn Iterator<Item = usize>, any: bool| {
                let (mut r, mut best) = (ray, None);
                for i in order {
                    if let Some(h) = tris[i].intersect_moller_trumbore(&r) {
                        let c = |j: usize| tris[i].v[j / 3][j % 3];
                        let [t, _, _] = crate::triangle::moller_trumbore_rows::<f32>(c, &r)
                            .1
                            .values();
                        moved += (t != h.t) as u32;
                        rescued += !r.in_range(t) as u32;
                        let done = if any {
                            best.keep::<true>(h, ids[i], &mut r.tmax)
                        } else {
                            best.keep::<false>(h, ids[i], &mut r.tmax)
                        };
                        if done {
                            break;
                        }
                    }
                }
                best
            };
            for &(first, count) in &leaves {
                let range = first as usize..(first + count) as usize;
                let closest = scalar(&mut range.clone(), false);
                let backwards = scalar(&mut range.clone().rev(), false);
                assert_eq!(closest, backwards, "{ray:?} leaf {first}+{count}");
                let any = scalar(&mut range.clone(), true);
                hits += closest.is_some() as u32;
                for isa in Isa::available() {
                    let leaf = (first as usize, count as usize);
                    let ((c, tmax), a, occ) = leaf_queries(&soa, leaf, &ids, ray, isa);
                    let occ = occ.map(|h| h.prim);
                    assert_eq!(c, closest, "{ray:?} leaf {leaf:?} at {isa}");
                    assert_eq!(tmax, closest.map_or(ray.tmax, |h| h.t));
                    assert_eq!(a, any, "{ray:?} leaf {leaf:?} at {isa}");
                    assert_eq!(occ, any.map(|h| h.prim), "{ray:?} leaf {leaf:?} at {isa}");
                }
            }
        }
        assert!(
            hits > 4500 && moved > 20 && rescued > 3,
            "{hits} hits, {moved} depths moved, {rescued} into the interval"
        );
    }

    /// Zero-area triangles never pass the Möller–Trumbore lanes' test (the window masks none
    /// of them): their `f32` cross product, the kernel's normal, is zero, and with it the
    /// determinant. Repeated vertices, and three points on a line with exact edges.
    #[test]
    fn moller_trumbore_lanes_reject_zero_area_triangles() {
        let mut seed = 5;
        let mut tested = 0;
        for k in 0..3000 {
            let (a, b) = (point(&mut seed) * 8.0 - 4.0, point(&mut seed) * 8.0 - 4.0);
            let t = match k % 3 {
                0 => Triangle::new(a, b, b),
                1 => Triangle::new(a, a, b),
                _ => {
                    let (a, e) = ((a * 4.0).round() * 0.25, (b * 4.0).round() * 0.25);
                    Triangle::new(a, a + e, a + e * 2.0)
                }
            };
            if !t.is_degenerate() {
                continue;
            }
            tested += 1;
            let on = t.v[0] + (t.v[2] - t.v[0]) * lcg(&mut seed);
            let o = point(&mut seed) * 8.0 - 4.0;
            let ray = Ray::segment(o, on - o, 0.0, f32::INFINITY);
            let c = |j: usize| t.v[j / 3][j % 3];
            let (inside, _) = crate::triangle::moller_trumbore_rows::<f32>(c, &ray);
            assert_eq!(inside, 0, "{t:?} {ray:?}");
        }
        assert!(tested > 2900, "{tested} zero-area triangles");
    }

    /// The span filter never rules out a hit: each depth the Möller–Trumbore kernel
    /// reports (held in its box, moved there or not) lies within its triangle's span, even
    /// with the ray's interval shrunk to that depth alone. Floors (flat boxes), slivers along
    /// a diagonal (whose `f32` normal tilts) and small triangles, met from near and far.
    #[test]
    fn moller_trumbore_span_never_rules_out_a_hit() {
        let mut seed = 41;
        let mut tris = random_triangles(40, 0.9, &mut seed);
        for i in 0..40 {
            let a = point(&mut seed) * 200.0 - 100.0;
            if i % 2 == 0 {
                let flat = Vec3::new(200.0, 200.0, 0.0);
                let (b, c) = (point(&mut seed) * flat, point(&mut seed) * flat);
                tris.push(Triangle::new(a, a + b, a + c));
            } else {
                let a = a + Vec3::new(1.0e4, 0.0, 0.0);
                let b = a + Vec3::new(-2.0e4, -1.3e4, lcg(&mut seed) * 1e-2);
                tris.push(Triangle::new(
                    a,
                    b,
                    (a + b) * 0.5 + Vec3::new(0.0, 0.0, 2e-3),
                ));
            }
        }
        let (mut hits, mut moved) = (0, 0);
        for k in 0..40_000 {
            let t = &tris[k % tris.len()];
            let (u, w) = (lcg(&mut seed) * 0.5, lcg(&mut seed) * 0.5);
            let on = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * w;
            let o = on + (point(&mut seed) - 0.5) * [1e-3, 0.5, 100.0][k % 3];
            let Some(h) = t.intersect_moller_trumbore(&Ray::segment(o, on - o, 0.0, f32::INFINITY))
            else {
                continue;
            };
            let c = |j: usize| t.v[j / 3][j % 3];
            let ray = Ray::segment(o, on - o, h.t, h.t);
            let [f32_t, _, _] = crate::triangle::moller_trumbore_rows::<f32>(c, &ray)
                .1
                .values();
            hits += 1;
            moved += (f32_t != h.t) as u32;
            assert_eq!(
                crate::triangle::moller_trumbore_span::<f32>(c, &ray),
                0,
                "{t:?} {ray:?}"
            );
            assert_eq!(t.intersect_moller_trumbore(&ray), Some(h), "{t:?} {ray:?}");
        }
        assert!(
            hits > 20_000 && moved > 50,
            "{hits} hits, {moved} depths moved"
        );
    }

    /// Rows of `PREFETCH_BYTES` or more are prefetched by default, smaller ones not.
    #[test]
    fn large_rows_prefetch() {
        let t = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
        let n = PREFETCH_BYTES / 36;
        let small = TriangleSoa::new(&vec![t; n - 100], [(0, (n - 100) as u32)]);
        let mut large = TriangleSoa::new(&vec![t; n], [(0, n as u32)]);
        assert!(!small.prefetches() && large.prefetches());
        large.set_prefetch(false);
        assert!(!large.prefetches());
    }

    #[test]
    fn soa_round_trips() {
        let tris: Vec<Triangle> = (0..10)
            .map(|i| {
                let f = i as f32;
                Triangle::new(
                    Vec3::new(f, 1.0, 2.0),
                    Vec3::new(3.0, f, 4.0),
                    Vec3::new(5.0, 6.0, -f),
                )
            })
            .collect();
        let leaves = [(0, 3), (3, 1), (4, 6)];
        let soa = TriangleSoa::new(&tris, leaves);
        assert_eq!(soa.len(), 10);
        for (first, count) in leaves {
            for k in 0..count {
                let t = tris[(first + k) as usize];
                assert_eq!(soa.get(first as usize, count as usize, k as usize), t);
            }
        }
    }
}
