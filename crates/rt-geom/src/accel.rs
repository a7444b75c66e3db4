//! The one query interface every acceleration structure implements, its statistics, and the
//! errors builders return.

use crate::{Aabb, Hit, Primitive, Ray};
use std::fmt;

/// An acceleration structure: the two questions every renderer asks about a ray.
///
/// Everything downstream (shading, packets, benches, cross-checks, the ray-file tool) is written
/// once against this trait.
pub trait Accel: Send + Sync {
    /// Closest hit with `t` in `[ray.tmin, ray.tmax]`, or `None`. `Hit::prim` is the index of the
    /// primitive in the slice the structure was built from. Invalid rays (see [`Ray::is_valid`])
    /// miss.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// True if anything is hit with `t` in `[ray.tmin, ray.tmax]` (shadow rays; may stop early).
    fn occluded(&self, ray: &Ray) -> bool;

    /// Node/leaf counts, depth, bytes, primitives per leaf, SAH cost where it applies.
    fn stats(&self) -> AccelStats;

    /// Checks the structure's invariants (every primitive reachable, bounds contain what they
    /// bound, indices in range); the conformance suite calls it after every build.
    fn validate(&self) -> Result<(), String>;

    /// The same structure's filtered queries, where it has them (every rt structure; `None`
    /// by default): what a caller holding a `dyn Accel` asks before it filters, for example a
    /// renderer skipping the triangle a ray leaves.
    fn filtered(&self) -> Option<&dyn crate::FilteredAccel> {
        None
    }
}

/// Writes the two queries of an [`Accel`] impl from one walk written for both (a method
/// `traverse::<const ANY_HIT: bool, K: Keep>(&self, &Ray, impl FnOnce() -> K) -> Option<Hit>`,
/// which makes its [`Keep`](crate::Keep) inside the walk and offers its hits to it):
/// `intersect` is the walk for the closest hit, `occluded` the walk that stops at any hit,
/// both keeping hits in an `Option<Hit>` (no filter).
///
/// ```ignore
/// impl Accel for MyTree {
///     rt_geom::queries_from_walk!();
///     fn stats(&self) -> AccelStats { ... }
///     fn validate(&self) -> Result<(), String> { ... }
/// }
/// impl FilteredAccel for MyTree {
///     rt_geom::filtered_from_walk!();
/// }
/// ```
///
/// `queries_from_walk!(stats: compute_stats, validate: check)` also forwards `stats` and
/// `validate` to the inherent methods named. `queries_from_walk!(per_isa)` answers through
/// [`crate::isa::query`] instead: the walk is the structure's [`crate::Walk`], compiled per
/// instruction set. [`filtered_from_walk!`](crate::filtered_from_walk) takes the same forms
/// (without `stats` and `validate`) for [`FilteredAccel`](crate::FilteredAccel).
#[macro_export]
macro_rules! queries_from_walk {
    (per_isa) => {
        #[inline]
        fn intersect(&self, ray: &$crate::Ray) -> Option<$crate::Hit> {
            $crate::isa::query::<_, false, _>(self, ray, || None)
        }

        #[inline]
        fn occluded(&self, ray: &$crate::Ray) -> bool {
            $crate::isa::query::<_, true, _>(self, ray, || $crate::Occlusion(None)).is_some()
        }

        fn filtered(&self) -> Option<&dyn $crate::FilteredAccel> {
            Some(self)
        }
    };
    (stats: $stats:ident, validate: $validate:ident) => {
        $crate::queries_from_walk!();

        fn stats(&self) -> $crate::AccelStats {
            self.$stats()
        }

        fn validate(&self) -> Result<(), String> {
            self.$validate()
        }
    };
    () => {
        #[inline]
        fn intersect(&self, ray: &$crate::Ray) -> Option<$crate::Hit> {
            self.traverse::<false, _>(ray, || None)
        }

        #[inline]
        fn occluded(&self, ray: &$crate::Ray) -> bool {
            self.traverse::<true, _>(ray, || $crate::Occlusion(None))
                .is_some()
        }

        fn filtered(&self) -> Option<&dyn $crate::FilteredAccel> {
            Some(self)
        }
    };
}

/// Writes the two queries of a [`FilteredAccel`](crate::FilteredAccel) impl from the walk
/// [`queries_from_walk!`] uses, keeping hits in a [`Filtered`](crate::Filtered).
#[macro_export]
macro_rules! filtered_from_walk {
    (per_isa) => {
        fn intersect_filtered(
            &self,
            ray: &$crate::Ray,
            filter: &mut dyn $crate::HitFilter,
        ) -> Option<$crate::Hit> {
            $crate::isa::query::<_, false, _>(self, ray, || $crate::Filtered::new(filter))
        }

        fn occluded_filtered(&self, ray: &$crate::Ray, filter: &mut dyn $crate::HitFilter) -> bool {
            $crate::isa::query::<_, true, _>(self, ray, || $crate::Filtered::new(filter)).is_some()
        }

        fn intersect_leaving(&self, ray: &$crate::Ray, prim: u32) -> Option<$crate::Hit> {
            $crate::isa::query::<_, false, _>(self, ray, || $crate::Skipping::new(prim))
        }

        fn occluded_leaving(&self, ray: &$crate::Ray, prim: u32) -> bool {
            $crate::isa::query::<_, true, _>(self, ray, || {
                $crate::Occlusion($crate::Skipping::new(prim))
            })
            .is_some()
        }
    };
    () => {
        fn intersect_filtered(
            &self,
            ray: &$crate::Ray,
            filter: &mut dyn $crate::HitFilter,
        ) -> Option<$crate::Hit> {
            self.traverse::<false, _>(ray, || $crate::Filtered::new(filter))
        }

        fn occluded_filtered(&self, ray: &$crate::Ray, filter: &mut dyn $crate::HitFilter) -> bool {
            self.traverse::<true, _>(ray, || $crate::Filtered::new(filter))
                .is_some()
        }

        fn intersect_leaving(&self, ray: &$crate::Ray, prim: u32) -> Option<$crate::Hit> {
            self.traverse::<false, _>(ray, || $crate::Skipping::new(prim))
        }

        fn occluded_leaving(&self, ray: &$crate::Ray, prim: u32) -> bool {
            self.traverse::<true, _>(ray, || $crate::Occlusion($crate::Skipping::new(prim)))
                .is_some()
        }
    };
}

/// Boxed and shared structures answer as the structure they hold.
macro_rules! forward_accel {
    ($($ptr:ident)::+) => {
        impl<A: Accel + ?Sized> Accel for $($ptr)::+<A> {
            #[inline]
            fn intersect(&self, ray: &Ray) -> Option<Hit> {
                (**self).intersect(ray)
            }
            #[inline]
            fn occluded(&self, ray: &Ray) -> bool {
                (**self).occluded(ray)
            }
            fn stats(&self) -> AccelStats {
                (**self).stats()
            }
            fn validate(&self) -> Result<(), String> {
                (**self).validate()
            }
            fn filtered(&self) -> Option<&dyn crate::FilteredAccel> {
                (**self).filtered()
            }
        }
    };
}

forward_accel!(Box);
forward_accel!(std::sync::Arc);

/// What a structure reports about itself.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AccelStats {
    /// Primitives the structure was built from.
    pub primitives: usize,
    /// All nodes, inner and leaf (cells for grids).
    pub nodes: usize,
    /// Leaves (non-empty cells for grids).
    pub leaves: usize,
    /// Primitive references stored in leaves (more than `primitives` when a primitive is
    /// referenced from several leaves, as in kd-trees, grids and spatial-split BVHs).
    pub references: usize,
    /// Longest root-to-leaf path (0 for a single leaf).
    pub max_depth: usize,
    /// Memory held by nodes, indices and primitive data.
    pub bytes: usize,
    /// Surface area heuristic cost normalised by the root's area, where it applies.
    pub sah_cost: Option<f32>,
}

impl AccelStats {
    /// `references / leaves` (0 without leaves).
    pub fn mean_prims_per_leaf(&self) -> f32 {
        if self.leaves == 0 {
            0.0
        } else {
            self.references as f32 / self.leaves as f32
        }
    }

    /// Checks that the numbers agree with each other; `Err` says which do not.
    pub fn check_consistency(&self) -> Result<(), String> {
        if self.leaves > self.nodes.max(1) {
            return Err(format!("{} leaves but {} nodes", self.leaves, self.nodes));
        }
        if self.primitives > 0 && self.bytes == 0 {
            return Err("primitives but zero bytes".into());
        }
        if self.primitives > 0 && self.leaves == 0 {
            return Err("primitives but no leaf".into());
        }
        if self.references > 0 && self.leaves == 0 {
            return Err("references but no leaf".into());
        }
        if let Some(c) = self.sah_cost {
            if !(c.is_finite() && c >= 0.0) {
                return Err(format!("SAH cost {c}"));
            }
        }
        Ok(())
    }
}

impl fmt::Display for AccelStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "prims={} nodes={} leaves={} refs={} depth={} bytes={} ({:.1} B/prim) prims/leaf={:.2}",
            self.primitives,
            self.nodes,
            self.leaves,
            self.references,
            self.max_depth,
            self.bytes,
            self.bytes as f64 / self.primitives.max(1) as f64,
            self.mean_prims_per_leaf(),
        )?;
        if let Some(c) = self.sah_cost {
            write!(f, " sah={c:.2}")?;
        }
        Ok(())
    }
}

/// Why a structure could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum BuildError {
    /// A primitive has a NaN or infinite coordinate.
    NonFinite {
        /// Index of the first such primitive.
        prim: usize,
    },
    /// A primitive reaches beyond [`MAX_COORDINATE`] on some axis.
    OutOfRange {
        /// Index of the first such primitive.
        prim: usize,
    },
    /// More primitives than the structure's index type holds.
    TooManyPrimitives {
        /// Primitives given.
        count: usize,
        /// Primitives the structure can index.
        max: usize,
    },
    /// A build parameter is out of its range.
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: String,
        /// The range it must lie in.
        expected: &'static str,
    },
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::NonFinite { prim } => {
                write!(f, "primitive {prim} has a NaN or infinite coordinate")
            }
            BuildError::OutOfRange { prim } => write!(
                f,
                "primitive {prim} reaches beyond +-{MAX_COORDINATE:e} (2^60), the coordinate \
                 range in which rt's kernels are exact; scale the scene down"
            ),
            BuildError::TooManyPrimitives { count, max } => {
                write!(
                    f,
                    "{count} primitives, more than the {max} this structure can index"
                )
            }
            BuildError::InvalidParameter {
                name,
                value,
                expected,
            } => write!(f, "parameter {name} = {value}: expected {expected}"),
        }
    }
}

impl std::error::Error for BuildError {}

impl BuildError {
    /// The one-line parameter check: `Ok` if `ok`, else `InvalidParameter` naming the field,
    /// its value and what was expected.
    pub fn require(
        ok: bool,
        name: &'static str,
        value: impl fmt::Display,
        expected: &'static str,
    ) -> Result<(), BuildError> {
        if ok {
            Ok(())
        } else {
            Err(BuildError::InvalidParameter {
                name,
                value: value.to_string(),
                expected,
            })
        }
    }

    /// The check of a `reference_budget` parameter (references per primitive, 1 to 64), shared
    /// by the builders that duplicate references (kd-trees, BSP trees, octrees).
    pub fn require_reference_budget(budget: f32) -> Result<(), BuildError> {
        Self::require(
            (1.0..=64.0).contains(&budget),
            "reference_budget",
            budget,
            "1..=64",
        )
    }
}

/// Sums what a walk over a tree of cells sees into its [`AccelStats`]: depth, non-empty
/// leaves, references, and the SAH cost in the units every rt structure reports (1 per inner
/// node, 1 per primitive test, each weighted by its cell's area over the root's), so that the
/// `sah` column of `bench` compares across structures.
pub struct StatsSum {
    stats: AccelStats,
    root_area: f64,
    sah: f64,
}

impl StatsSum {
    /// Starts the sums for a structure whose root cell is `root`.
    pub fn new(stats: AccelStats, root: &Aabb) -> Self {
        Self {
            stats,
            root_area: root.half_area_f64(),
            sah: 0.0,
        }
    }

    /// One node: its cell, depth, and whether it is a leaf of `count` primitives.
    pub fn add(&mut self, cell: &Aabb, depth: usize, leaf: bool, count: usize) {
        let s = &mut self.stats;
        s.max_depth = s.max_depth.max(depth);
        let area = cell.half_area_f64();
        if leaf {
            if count > 0 {
                s.leaves += 1;
                s.references += count;
            }
            self.sah += area * count as f64;
        } else {
            self.sah += area;
        }
    }

    /// The stats with the SAH cost normalised by the root's area.
    pub fn finish(mut self) -> AccelStats {
        self.stats.sah_cost = Some(if self.root_area > 0.0 {
            (self.sah / self.root_area) as f32
        } else {
            0.0
        });
        self.stats
    }
}

/// The SAH constants every builder takes: a traversal cost that is finite and `>= 0`, an
/// intersection cost that is finite and `> 0`.
pub fn check_sah_costs(traversal: f32, intersection: f32) -> Result<(), BuildError> {
    let t_ok = traversal.is_finite() && traversal >= 0.0;
    BuildError::require(t_ok, "traversal_cost", traversal, "finite, >= 0")?;
    let i_ok = intersection.is_finite() && intersection > 0.0;
    BuildError::require(i_ok, "intersection_cost", intersection, "finite, > 0")
}

/// A per-ray mailbox (Amanatides & Woo 1987): the last `N` primitives a ray tested, so that a
/// structure listing a primitive in several cells tests it once per ray. Kept per ray (on the
/// stack), so threads share nothing.
#[derive(Clone, Copy, Debug)]
pub struct Mailbox<const N: usize> {
    ids: [u32; N],
    next: usize,
}

impl<const N: usize> Default for Mailbox<N> {
    fn default() -> Self {
        Self {
            ids: [u32::MAX; N],
            next: 0,
        }
    }
}

impl<const N: usize> Mailbox<N> {
    /// True if `id` was tested already; otherwise records it and returns false.
    #[inline]
    pub fn seen(&mut self, id: u32) -> bool {
        if self.ids.contains(&id) {
            return true;
        }
        self.ids[self.next] = id;
        self.next = (self.next + 1) % N;
        false
    }
}

/// For `validate()` of structures that cut primitives (kd-trees, grids, octrees, spatial
/// splits): `prim` touches `cell` grown by a relative 1e-6. Clipped bounds round outward, so
/// a builder may list a primitive that only touches a cell within rounding.
pub fn touches_cell<P: Primitive>(prim: &P, cell: &Aabb) -> bool {
    let pad = (cell.max - cell.min).max(cell.max.abs().max(cell.min.abs())) * 1e-6;
    !prim
        .clipped_bounds(&Aabb::new(cell.min - pad, cell.max + pad))
        .is_empty()
}

/// For `validate()`: `Err` naming the first primitive no leaf or cell holds.
pub fn all_referenced(seen: &[bool]) -> Result<(), String> {
    match seen.iter().position(|s| !s) {
        Some(p) => Err(format!("primitive {p} is in no leaf")),
        None => Ok(()),
    }
}

/// The largest coordinate magnitude of primitives and ray origins, `2^60` (about 1.15e18):
/// within it the `f32` edge functions of the watertight test (products of vertex-minus-origin
/// differences) cannot overflow, so every kernel stays exact. Builders reject primitives
/// beyond it ([`BuildError::OutOfRange`]); rays from beyond it are invalid and miss.
pub const MAX_COORDINATE: f32 = (1u64 << 60) as f32;

/// The input checks every builder starts with: all primitives finite, within
/// [`MAX_COORDINATE`], and at most `max_count`.
pub fn check_primitives<P: Primitive>(prims: &[P], max_count: usize) -> Result<(), BuildError> {
    if prims.len() > max_count {
        return Err(BuildError::TooManyPrimitives {
            count: prims.len(),
            max: max_count,
        });
    }
    if let Some(prim) = prims.iter().position(|p| !p.is_finite()) {
        return Err(BuildError::NonFinite { prim });
    }
    let within = |p: &P| {
        let b = p.bounds();
        b.min.abs().max_element() <= MAX_COORDINATE && b.max.abs().max_element() <= MAX_COORDINATE
    };
    match prims.iter().position(|p| !within(p)) {
        Some(prim) => Err(BuildError::OutOfRange { prim }),
        None => Ok(()),
    }
}
