//! Rays and hit records.

use glam::Vec3;

/// A ray `origin + t * dir` restricted to `t` in `[tmin, tmax]`.
///
/// The direction is not normalised: `t` is measured in units of `dir`'s length. A ray caches what
/// the kernels need per ray (the axis permutation and shear of the watertight triangle test), so
/// `origin` and `dir` are read-only after construction; `tmin` and `tmax` may be changed freely.
///
/// A ray whose origin or direction is not finite, or whose direction is zero, is *invalid*: every
/// kernel and every [`Accel`](crate::Accel) reports it as a miss (and never produces a NaN hit).
///
/// Layout: 64 bytes, aligned to 64, so that a ray is one cache line. Traversals that stream rays
/// from memory (packets filled from a large image's rays) read a line per ray instead of the
/// 1.6 of the earlier 100-byte layout, which also stored the reciprocal direction (now computed
/// by [`Self::inv_dir`], once per traversal) and the shear three times over.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Ray {
    origin: Vec3,
    dir: Vec3,
    /// Start of the valid interval (inclusive).
    pub tmin: f32,
    /// End of the valid interval (inclusive); may be `f32::INFINITY`.
    pub tmax: f32,
    /// The watertight test's shear as two row vectors, `p . rows[0] = p[kx] - Sx p[kz]` and
    /// `p . rows[1] = p[ky] - Sy p[kz]` (`Sx = dir[kx]/dir[kz]`, `Sy = dir[ky]/dir[kz]`): the
    /// sheared coordinates without indexing by a run-time axis (the other terms are exact
    /// zeros), for the scalar kernel and for SIMD lanes of rays whose axes differ (packets).
    /// Component `kz` holds `-Sx` and `-Sy` exactly (signed zeros included).
    shear_rows: [Vec3; 2],
    /// `Sz = 1/dir[kz]` of the watertight test.
    shear_z: f32,
    /// Watertight test: `kz` is the dominant axis of `dir`; `kx`, `ky` follow it (swapped when
    /// `dir[kz] < 0`, which keeps the winding of the projected triangle).
    axes: [u8; 3],
    valid: bool,
}

const _: () = assert!(std::mem::size_of::<Ray>() == 64);
// No padding (`Ray::copy_narrow` copies every byte as a word): the fields end to end.
const _: () = {
    use std::mem::offset_of;
    assert!(offset_of!(Ray, origin) == 0 && offset_of!(Ray, dir) == 12);
    assert!(offset_of!(Ray, tmin) == 24 && offset_of!(Ray, tmax) == 28);
    assert!(offset_of!(Ray, shear_rows) == 32 && offset_of!(Ray, shear_z) == 56);
    assert!(offset_of!(Ray, axes) == 60 && offset_of!(Ray, valid) == 63);
};

/// The shortest ray direction (its largest component), `2^-100`: shorter directions make
/// invalid rays. Components of a valid direction below 2^-48 of its largest are flushed to
/// zero when the ray is made.
pub const MIN_DIRECTION: f32 = 7.888609e-31;

const _: () = assert!(MIN_DIRECTION == 1.0 / (1u128 << 100) as f32);

/// Direction components below this fraction (2^-48) of the largest are flushed to zero.
const FLUSH_BELOW: f32 = 1.0 / (1u64 << 48) as f32;

impl Ray {
    /// A copy of this ray made of eight 8-byte moves that the compiler keeps apart, for the
    /// wide walks, which copy the ray they are asked about ([`crate::Level::copy_ray`]).
    /// Inside code compiled with AVX-512 enabled (the walks of [`crate::Isa::Avx512`]) a
    /// plain copy of the 64-byte ray becomes one 512-bit move, and on Intel CPUs one 512-bit
    /// instruction per query slows the 256-bit code around it (the core's frequency and its
    /// vector ports step down for 512-bit work).
    #[inline(always)]
    pub fn copy_narrow(&self) -> Ray {
        let mut out = std::mem::MaybeUninit::<Ray>::uninit();
        let src = (self as *const Ray).cast::<u64>();
        let dst = out.as_mut_ptr().cast::<u64>();
        for k in 0..8 {
            // SAFETY: `Ray` is 64 bytes, aligned to 64, with no padding (checked after its
            // definition): `src` and `dst` point to eight aligned words, initialised (source)
            // or writable (destination). Volatile reads keep the compiler from merging them
            // into one 512-bit move. Measured reason: the any-hit walks at the AVX-512 level
            // ran slower on an Intel Xeon with the merged move than at the AVX2 level, and
            // faster without it.
            unsafe { dst.add(k).write(src.add(k).read_volatile()) };
        }
        // SAFETY: all 64 bytes are written, each a byte of a valid `Ray` (the `bool` one
        // included).
        unsafe { out.assume_init() }
    }

    /// A ray over `[0, +inf]`.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self::segment(origin, dir, 0.0, f32::INFINITY)
    }

    /// A ray over `[tmin, tmax]`.
    pub fn segment(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        // Directions shorter than `MIN_DIRECTION` (zero among them) and origins beyond
        // `MAX_COORDINATE` make invalid rays, which miss. Components below 2^-48 of the
        // largest (so all whose reciprocals overflow) move the ray by less than any `f32`
        // position can show: they are flushed to zero, so that every kernel and every cell
        // walk sees the same ray.
        let abs = dir.abs();
        let largest = abs.max_element();
        let valid = origin.is_finite()
            && origin.abs().max_element() <= crate::MAX_COORDINATE
            && dir.is_finite()
            && largest >= MIN_DIRECTION;
        let floor = (largest * FLUSH_BELOW).max(1.0 / f32::MAX);
        let dir = Vec3::select(abs.cmplt(Vec3::splat(floor)), dir * 0.0, dir);
        let abs = dir.abs();
        let kz = if abs.x >= abs.y && abs.x >= abs.z {
            0
        } else if abs.y >= abs.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let shear = if valid {
            Vec3::new(dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz])
        } else {
            Vec3::ZERO
        };
        // `unit(k) - unit(kz) * s`, with `-s` itself at `kz` (`0 - s` would lose the sign of
        // a zero `s`, which `watertight_shear` gives back).
        let row = |k: usize, s: f32| {
            let mut r = Vec3::AXES[k];
            r[kz] = -s;
            r
        };
        Self {
            origin,
            dir,
            tmin,
            tmax,
            shear_rows: [row(kx, shear.x), row(ky, shear.y)],
            shear_z: shear.z,
            axes: [kx as u8, ky as u8, kz as u8],
            valid,
        }
    }

    /// The same ray over another interval.
    #[inline]
    pub fn with_range(mut self, tmin: f32, tmax: f32) -> Self {
        self.tmin = tmin;
        self.tmax = tmax;
        self
    }

    /// The origin.
    #[inline]
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// The direction (not normalised).
    #[inline]
    pub fn dir(&self) -> Vec3 {
        self.dir
    }

    /// `1 / dir` per component; `+-inf` for zero components (sign of the zero). Computed on
    /// each call (three divisions): traversals take it once per ray.
    #[inline]
    pub fn inv_dir(&self) -> Vec3 {
        Vec3::ONE / self.dir
    }

    /// Finite origin within [`crate::MAX_COORDINATE`], finite direction whose largest
    /// component is at least [`MIN_DIRECTION`], and an interval that is not NaN.
    #[inline]
    pub fn is_valid(&self) -> bool {
        self.valid && !self.tmin.is_nan() && !self.tmax.is_nan()
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// `[kx, ky, kz]` of the watertight test.
    #[inline]
    pub fn watertight_axes(&self) -> [usize; 3] {
        [
            self.axes[0] as usize,
            self.axes[1] as usize,
            self.axes[2] as usize,
        ]
    }

    /// `(Sx, Sy, Sz)` of the watertight test (zero for invalid rays).
    #[inline]
    pub fn watertight_shear(&self) -> Vec3 {
        let kz = self.axes[2] as usize;
        let [mx, my] = self.shear_rows.map(|r| r.to_array());
        Vec3::new(-mx[kz], -my[kz], self.shear_z)
    }

    /// The shear of the watertight test as row vectors (see the field's documentation).
    #[inline]
    pub fn watertight_rows(&self) -> &[Vec3; 2] {
        &self.shear_rows
    }

    /// Whether `t` lies in `[tmin, tmax]`.
    #[inline]
    pub fn in_range(&self, t: f32) -> bool {
        t >= self.tmin && t <= self.tmax
    }
}

/// What a primitive's kernel reports: distance and surface coordinates.
///
/// For triangles `(u, v)` are barycentric: the hit point is `(1-u-v)*v0 + u*v1 + v*v2`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrimHit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// First barycentric coordinate (or surface parameter).
    pub u: f32,
    /// Second barycentric coordinate (or surface parameter).
    pub v: f32,
}

/// The closest hit of a ray in a scene: [`PrimHit`] plus the index of the primitive in the slice
/// the structure was built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// First barycentric coordinate (or surface parameter).
    pub u: f32,
    /// Second barycentric coordinate (or surface parameter).
    pub v: f32,
    /// The primitive hit, as the caller's index.
    pub prim: u32,
}

/// rt's order of closest hits: a hit at `t` on primitive `prim` replaces the best hit so far
/// (`(t, prim)`) when it is closer, or as close and on a lower primitive id. Every structure
/// applies it, so that all of them report the same primitive even when two primitives are hit at
/// the same `t` (duplicates, shared edges, touching spheres), and renders agree bit for bit.
#[inline(always)]
pub fn replaces(t: f32, prim: u32, best: Option<(f32, u32)>) -> bool {
    match best {
        None => true,
        Some((bt, bp)) => t < bt || (t == bt && prim < bp),
    }
}

/// Records hit `h` of primitive `prim` in `best`, the one way every rt structure keeps its
/// closest hit: with `ANY_HIT` the hit is kept and the search is over (true); otherwise it
/// replaces `best` when [`replaces`] says so, and `tmax` (the ray's or a lane's) shrinks to it.
#[inline(always)]
pub fn keep_hit<const ANY_HIT: bool>(
    h: PrimHit,
    prim: u32,
    tmax: &mut f32,
    best: &mut Option<Hit>,
) -> bool {
    if ANY_HIT {
        *best = Some(Hit::new(h, prim));
        return true;
    }
    if replaces(h.t, prim, best.as_ref().map(Hit::key)) {
        *best = Some(Hit::new(h, prim));
        *tmax = h.t;
    }
    false
}

/// Tests primitives `ids` of `prims` against `ray` in order, skipping ids for which `skip`
/// says so (mailboxes), offering each hit to `best` ([`crate::Keep`]: by [`replaces`],
/// through its filter if it has one) and shrinking `ray.tmax` to the kept one. With
/// `ANY_HIT`, stops at the first hit and returns true. The leaf test of every structure that
/// lists primitive ids in its cells; [`Primitive::test_all`](crate::Primitive::test_all),
/// so that a primitive with a SIMD kernel (triangles) runs it.
#[inline(always)]
pub fn test_primitives<P: crate::Primitive, const ANY_HIT: bool>(
    prims: &[P],
    ids: &[u32],
    ray: &mut Ray,
    best: &mut impl crate::Keep,
    skip: impl FnMut(u32) -> bool,
) -> bool {
    P::test_all::<ANY_HIT>(prims, ids, ray, best, skip)
}

/// [`test_primitives`] one primitive at a time, with [`Primitive::intersect`](crate::Primitive::intersect).
#[inline(always)]
pub fn test_each<P: crate::Primitive, const ANY_HIT: bool>(
    prims: &[P],
    ids: &[u32],
    ray: &mut Ray,
    best: &mut impl crate::Keep,
    mut skip: impl FnMut(u32) -> bool,
) -> bool {
    for &p in ids {
        if skip(p) || best.skips(p) {
            continue;
        }
        if let Some(h) = prims[p as usize].intersect(ray) {
            if best.keep::<ANY_HIT>(h, p, &mut ray.tmax) {
                return true;
            }
        }
    }
    false
}

impl Hit {
    /// `(t, prim)`, the key of [`replaces`].
    #[inline(always)]
    pub fn key(&self) -> (f32, u32) {
        (self.t, self.prim)
    }

    /// The hit of primitive `prim`.
    #[inline]
    pub fn new(h: PrimHit, prim: u32) -> Self {
        Self {
            t: h.t,
            u: h.u,
            v: h.v,
            prim,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_rays_are_flagged() {
        assert!(Ray::new(Vec3::ZERO, Vec3::X).is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::ZERO).is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0)).is_valid());
        assert!(!Ray::new(Vec3::new(f32::INFINITY, 0.0, 0.0), Vec3::X).is_valid());
        assert!(!Ray::segment(Vec3::ZERO, Vec3::X, f32::NAN, 1.0).is_valid());
    }

    #[test]
    fn watertight_axes_follow_dominant_component() {
        let r = Ray::new(Vec3::ZERO, Vec3::new(0.1, -3.0, 0.5));
        let [kx, ky, kz] = r.watertight_axes();
        assert_eq!(kz, 1);
        // dir[kz] < 0: kx and ky swapped.
        assert_eq!((kx, ky), (0, 2));
        assert_eq!(r.inv_dir().y, 1.0 / -3.0);
        let axis = Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(axis.inv_dir().x, f32::INFINITY);
    }
}
