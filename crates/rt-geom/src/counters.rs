//! The cost of a ray, counted: bounding-volume (node, cell) tests and primitive tests, per
//! thread. The counters exist only with the `counters` cargo feature; without it every call
//! here compiles to nothing, so the structures' code is the same code either way.
//!
//! ```
//! use rt_geom::{Accel, BruteForce, Ray, Triangle, Vec3, counters};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let brute = BruteForce::build(&tris).unwrap();
//! counters::take();
//! brute.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z));
//! let counts = counters::take();
//! assert_eq!(counts.prims, if counters::ENABLED { 1 } else { 0 });
//! ```

/// Whether this build counts (the `counters` feature).
pub const ENABLED: bool = cfg!(feature = "counters");

/// Tests counted on one thread since the last [`take`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Bounding-volume tests: a box per child a BVH node tests, a kd-tree or octree node
    /// visited, a grid cell visited.
    pub nodes: u64,
    /// Primitive tests (each triangle of a SIMD batch counts once).
    pub prims: u64,
}

impl std::ops::AddAssign for Counts {
    fn add_assign(&mut self, o: Counts) {
        self.nodes += o.nodes;
        self.prims += o.prims;
    }
}

#[cfg(feature = "counters")]
thread_local! {
    static COUNTS: std::cell::Cell<Counts> = const { std::cell::Cell::new(Counts { nodes: 0, prims: 0 }) };
}

/// Counts `n` bounding-volume tests.
#[inline(always)]
pub fn nodes(n: u32) {
    add(Counts {
        nodes: n as u64,
        prims: 0,
    });
}

/// Counts `n` primitive tests.
#[inline(always)]
pub fn prims(n: u32) {
    add(Counts {
        nodes: 0,
        prims: n as u64,
    });
}

#[inline(always)]
fn add(counts: Counts) {
    #[cfg(feature = "counters")]
    COUNTS.with(|c| {
        let mut v = c.get();
        v += counts;
        c.set(v);
    });
    let _ = counts;
}

/// This thread's counts since the last call, and resets them (zeros without the feature).
pub fn take() -> Counts {
    #[cfg(feature = "counters")]
    return COUNTS.with(|c| c.replace(Counts::default()));
    #[cfg(not(feature = "counters"))]
    Counts::default()
}
