//! tinybvh's `BVH8_CPU` behind the `Accel` trait, through the `tinybvh-rs` crate (feature
//! `tinybvh`): a speed peer as its users run it, built with tinybvh's default builder, leaves
//! split to four triangles and converted to its AVX2 layout, traced by its own kernels
//! (compiled by the crate with `-march=native`).
//!
//! Not exact, and not held to be: tinybvh's triangle test is Möller and Trumbore's (not
//! watertight) and its rays have no `tmin` (hits at `t > 0` count: a ray's origin is moved to
//! its `tmin`). `tinybvh-rs` 0.1 offers `BVH8_CPU`'s closest-hit query only, and only in
//! builds with AVX2 enabled (`bench --native`); shadow rays therefore ask for the closest hit
//! before `tmax` rather than tinybvh's `IsOccluded`, which stops at the first one.

use rt_geom::{Accel, AccelStats, BuildError, Hit, Ray, Triangle, check_primitives};

fn unavailable() -> BuildError {
    BuildError::InvalidParameter {
        name: "tinybvh",
        value: "a build without AVX2".into(),
        expected: "a build with AVX2 enabled (bench/trace --native): tinybvh-rs offers BVH8_CPU only there",
    }
}

/// tinybvh's 8-wide CPU BVH over a triangle soup.
pub struct TinyBvh8 {
    #[cfg(target_feature = "avx2")]
    bvh: Option<Shared>,
    prims: usize,
}

/// The built BVH, shared by the tracing threads.
#[cfg(target_feature = "avx2")]
struct Shared(tinybvh_rs::bvh8_cpu::BVH);

// SAFETY: after its build the BVH is only read: `BVH8_CPU::Intersect` is a `const` member that
// keeps its traversal state on its own stack (tinybvh's own examples trace from many threads),
// and the value is dropped by one owner.
#[cfg(target_feature = "avx2")]
unsafe impl Send for Shared {}
// SAFETY: as for `Send`: shared references only reach the `const` query.
#[cfg(target_feature = "avx2")]
unsafe impl Sync for Shared {}

impl TinyBvh8 {
    pub fn build(tris: &[Triangle]) -> Result<Self, BuildError> {
        check_primitives(tris, u32::MAX as usize - 1)?;
        if !cfg!(target_feature = "avx2") {
            return Err(unavailable());
        }
        Ok(Self {
            #[cfg(target_feature = "avx2")]
            bvh: build8(tris)?,
            prims: tris.len(),
        })
    }

    /// The nearest hit before `ray.tmax` by tinybvh's closest-hit query.
    #[cfg(target_feature = "avx2")]
    fn closest(&self, ray: &Ray) -> Option<Hit> {
        use tinybvh_rs::Intersector;
        let bvh = self.bvh.as_ref().filter(|_| ray.is_valid())?;
        // No `tmin` in tinybvh: the origin moves to it, as its users offset secondary rays.
        let start = ray.tmin.max(0.0);
        let tmax = (ray.tmax - start).min(tinybvh_rs::INFINITE);
        let mut buf = RaySlot::new(ray, start, tmax);
        bvh.0.intersect(&mut buf.ray);
        let r = buf.ray;
        (r.hit.t < tmax).then_some(Hit {
            t: r.hit.t + start,
            u: r.hit.u,
            v: r.hit.v,
            prim: r.hit.prim,
        })
    }

    #[cfg(not(target_feature = "avx2"))]
    fn closest(&self, _ray: &Ray) -> Option<Hit> {
        None
    }
}

/// A ray as tinybvh 1.6.8 lays it out: `tinybvh-rs` 0.1's `Ray` is its first 64 bytes (origin,
/// direction, reciprocal, hit), where tinybvh's is 128 bytes aligned to 64 (a hit record with
/// user data after them). The ray is written here, not by `Ray::new`, whose C++ constructor
/// clears all 128 bytes of a 64-byte Rust value (and normalises the direction, which rt's `t`
/// does not).
#[cfg(target_feature = "avx2")]
#[repr(C, align(64))]
struct RaySlot {
    ray: tinybvh_rs::Ray,
    /// tinybvh's user data after the hit record.
    _rest: [u8; 64],
}

#[cfg(target_feature = "avx2")]
impl RaySlot {
    fn new(ray: &Ray, start: f32, tmax: f32) -> Self {
        // tinybvh's reciprocal: components within 1e-12 of zero become +-1e30.
        let rcp = |x: f32| match x {
            x if x.abs() > 1e-12 => 1.0 / x,
            x if x >= 0.0 => tinybvh_rs::INFINITE,
            _ => -tinybvh_rs::INFINITE,
        };
        let d = ray.dir().to_array();
        let mut r = tinybvh_rs::Ray {
            origin: ray.at(start).to_array(),
            dir: d,
            r_d: d.map(rcp),
            ..Default::default()
        };
        r.hit.t = tmax;
        Self {
            ray: r,
            _rest: [0; 64],
        }
    }
}

#[cfg(target_feature = "avx2")]
fn build8(tris: &[Triangle]) -> Result<Option<Shared>, BuildError> {
    use tinybvh_rs::{bvh, bvh8_cpu, mbvh};
    if tris.is_empty() {
        return Ok(None);
    }
    let positions: Vec<[f32; 4]> = tris
        .iter()
        .flat_map(|t| t.v.map(|v| [v.x, v.y, v.z, 0.0]))
        .collect();
    let fail = |e: tinybvh_rs::Error| BuildError::InvalidParameter {
        name: "tinybvh",
        value: format!("{e:?}"),
        expected: "a BVH tinybvh can convert to BVH8_CPU",
    };
    let mut bvh2 = bvh::BVH::new(positions.as_slice().into()).map_err(fail)?;
    bvh2.split_leaves(4);
    let wide = mbvh::BVH::new(&bvh2);
    // BVH8_CPU keeps its own copy of the triangles: the borrowed builds end here.
    bvh8_cpu::BVH::new(&wide)
        .map(|b| Some(Shared(b)))
        .map_err(fail)
}

impl Accel for TinyBvh8 {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.closest(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.closest(ray).is_some()
    }

    fn stats(&self) -> AccelStats {
        crate::registry::opaque_peer_stats(self.prims)
    }

    fn validate(&self) -> Result<(), String> {
        Ok(())
    }
}
