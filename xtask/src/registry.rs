//! The one registry of structures by name. `verify`, `bench`, `trace` (and `render`) cover
//! every entry here; a new structure is one more line in [`REGISTRY`].

use crate::obvhs_accel::{ObvhsBvh2, ObvhsCwBvh, ObvhsCwBvhRtKernel};
use rt_accel_bvh::{
    BvList, BvListParams, Bvh, Bvh4, Bvh8, BvhBuilder, BvhParams, CompressedBvh8,
    CompressedTriBvh8, TriBvh4, TriBvh8, WideCollapse,
};
use rt_accel_grid::{Grid, GridParams};
use rt_accel_kd::{BspParams, BspTree, KdParams, KdTraversal, KdTree};
use rt_accel_octree::{Octree, OctreeParams, OctreeTraversal};
use rt_geom::{
    Aabb, Accel, BoundingSphere, BruteForce, BuildError, Kdop7, Shape, Triangle, TriangleKernel,
};
use rt_packet::{MlrtaKdTree, PacketAccel, WithSingleRays};

/// A packet path (boxed as a `PacketAccel`).
/// The kd-tree for packets (Wald & Havran's constants) and the one for single rays.
fn kd_packets(p: &[Triangle]) -> Result<(KdTree<Triangle>, KdTree<Triangle>), BuildError> {
    Ok((
        KdTree::build(p, KdParams::wald_havran())?,
        KdTree::build(p, KdParams::sah())?,
    ))
}

fn packets_of<A: PacketAccel + 'static>(
    r: Result<A, BuildError>,
) -> Result<Box<dyn PacketAccel>, BuildError> {
    r.map(|b| Box::new(b) as Box<dyn PacketAccel>)
}
use rt_testkit::Tolerance;

/// A structure that can be built from triangles.
#[derive(Clone, Copy)]
pub struct AccelEntry {
    /// The name users type (`--accel NAME`).
    pub name: &'static str,
    /// One line: what it is and how it is built.
    pub about: &'static str,
    pub build: fn(&[Triangle]) -> Result<Box<dyn Accel>, BuildError>,
    /// The same structure over mixed shapes (triangles, spheres, cones: NFF scenes); `None`
    /// for structures that hold triangles only.
    pub build_shapes: Option<fn(&[Shape]) -> Result<Box<dyn Accel>, BuildError>>,
    /// How closely it must agree with brute force (rt's own structures: exactly).
    pub tolerance: Tolerance,
    /// A reference implementation from another crate (not rt's own work).
    pub external: bool,
    /// Largest scene `bench` and `verify` run it on (brute force and flat volume lists are
    /// O(n) per ray).
    pub bench_max_prims: usize,
    /// Its packet path (`rt-packet`), when it has one: `trace --packet`, `accels --packet`.
    pub packets: Option<fn(&[Triangle]) -> Result<Box<dyn PacketAccel>, BuildError>>,
    /// Whether `verify` runs it on the adversarial conformance scenes (peers that answer
    /// differently by design there are checked on the meshes' camera, shadow and diffuse rays).
    pub conformance: bool,
    /// `Some(entry)` when its single rays are that entry's (it exists for its packet path):
    /// `bench` measures only its packets (and compares them with that entry's), and `verify`
    /// only checks its packets against its single rays.
    pub packet_only: Option<&'static str>,
    /// The ray/triangle kernel whose brute force it must agree with (`verify`).
    pub kernel: TriangleKernel,
}

fn boxed<A: Accel + 'static>(r: Result<A, BuildError>) -> Result<Box<dyn Accel>, BuildError> {
    r.map(|a| Box::new(a) as Box<dyn Accel>)
}

/// obvhs's CWBVH drops hits closer than this (its traversal ignores `tmin` below it).
pub const CWBVH_NEAR_T: f32 = 1e-4;

/// What obvhs is held to. Its box test (`(b - o) * inv_dir`, with `1/0` replaced by
/// `1/EPSILON`, no padding) is exact on camera, shadow and diffuse rays, but loses hits of rays
/// that lie in a box face (zero direction components) or graze a box boundary, and can cull a
/// box whose entry rounds an ulp past a hit; and it walks forward from the origin only, so an
/// interval that starts behind it (`tmin < 0`) loses the hits there; far from the origin it
/// loses a few hits on triangle edges and vertices: `verify` counts those as tolerated, and
/// holds it exact on every other ray.
pub const OBVHS_TOLERANCE: Tolerance = Tolerance {
    rel_t: 1e-6,
    near_t: 0.0,
    boundary_misses: true,
    behind_origin_misses: true,
    lowest_on_ties: false,
    // Far from the origin (the conformance scenes at 5e6) its unpadded boxes cull a few hits
    // on a triangle's edge or vertex.
    edge_band: 1e-4,
};

/// An rt structure: exact agreement with brute force, benched on every scene.
const fn own(
    name: &'static str,
    about: &'static str,
    build: fn(&[Triangle]) -> Result<Box<dyn Accel>, BuildError>,
) -> AccelEntry {
    AccelEntry {
        name,
        about,
        build,
        build_shapes: None,
        tolerance: Tolerance::EXACT,
        external: false,
        bench_max_prims: usize::MAX,
        conformance: true,
        packets: None,
        packet_only: None,
        kernel: TriangleKernel::Watertight,
    }
}

/// An rt structure generic over `Primitive`: `generic!("name", "about", |p| build(p))` registers
/// the same builder expression over triangles and over shapes.
macro_rules! generic {
    ($name:expr, $about:expr, |$p:ident| $body:expr $(,)?) => {
        own($name, $about, |$p: &[Triangle]| $body).with_shapes(|$p: &[Shape]| $body)
    };
}

impl AccelEntry {
    /// Limits the scenes `bench` runs the entry on by default.
    const fn bench_up_to(mut self, prims: usize) -> Self {
        self.bench_max_prims = prims;
        self
    }

    /// Registers a packet path whose single rays are those of the entry `single`.
    const fn packet_only(mut self, single: &'static str) -> Self {
        self.packet_only = Some(single);
        self
    }

    /// Its leaves run Möller–Trumbore's kernel: `verify` holds it to brute force with that
    /// kernel.
    const fn moller_trumbore(mut self) -> Self {
        self.kernel = TriangleKernel::MollerTrumbore;
        self
    }

    const fn with_packets(
        mut self,
        build: fn(&[Triangle]) -> Result<Box<dyn PacketAccel>, BuildError>,
    ) -> Self {
        self.packets = Some(build);
        self
    }

    const fn with_shapes(
        mut self,
        build: fn(&[Shape]) -> Result<Box<dyn Accel>, BuildError>,
    ) -> Self {
        self.build_shapes = Some(build);
        self
    }

    /// [`conformance::check_scene`](rt_testkit::conformance::check_scene) of the entry on a
    /// triangle scene, against brute force with the entry's kernel.
    pub fn check_triangle_scene(
        &self,
        scene: &rt_testkit::Scene<Triangle>,
    ) -> Result<rt_testkit::Report, String> {
        use rt_testkit::conformance::{MollerTrumbore, check_scene};
        match self.kernel {
            TriangleKernel::Watertight => check_scene(scene, self.build, self.tolerance),
            TriangleKernel::MollerTrumbore => {
                let mt = rt_testkit::Scene::new(
                    scene.name.clone(),
                    scene.prims.iter().copied().map(MollerTrumbore).collect(),
                );
                let build =
                    |p: &[MollerTrumbore]| (self.build)(&p.iter().map(|m| m.0).collect::<Vec<_>>());
                check_scene(&mt, build, self.tolerance)
            }
        }
    }

    /// Builds over a scene's shapes: with the shape builder, or with the triangle builder when
    /// every shape is a triangle (same primitive ids).
    pub fn build_any(&self, shapes: &[Shape]) -> Result<Box<dyn Accel>, String> {
        if let Some(tris) = shapes
            .iter()
            .map(|s| s.as_triangle().copied())
            .collect::<Option<Vec<_>>>()
        {
            return (self.build)(&tris).map_err(|e| format!("{}: {e}", self.name));
        }
        match self.build_shapes {
            Some(build) => build(shapes).map_err(|e| format!("{}: {e}", self.name)),
            None => Err(format!(
                "{} holds triangles only, and this scene has spheres or cones; structures that \
                 take any shape: {}",
                self.name,
                REGISTRY
                    .iter()
                    .filter(|e| e.build_shapes.is_some())
                    .map(|e| e.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        }
    }
}

/// Flat bounding-volume lists test every volume per ray: benched up to this size.
const BVLIST_BENCH_MAX: usize = 100_000;

fn bvlist_two_level() -> BvListParams {
    BvListParams {
        two_level: Some(32),
        ..BvListParams::default()
    }
}

/// Every registered structure: rt's own and the references, then the optional peers.
pub static REGISTRY: [AccelEntry; BASE.len() + OPTIONAL.len() + TINYBVH.len()] =
    concat(&[BASE, OPTIONAL, TINYBVH]);

/// The lists one after the other, as one array (entries are plain data: names, function
/// pointers, numbers).
const fn concat<const N: usize>(lists: &[&[AccelEntry]]) -> [AccelEntry; N] {
    let mut out = [BASE[0]; N];
    let (mut k, mut n) = (0, 0);
    while k < lists.len() {
        let mut i = 0;
        while i < lists[k].len() {
            out[n] = lists[k][i];
            (i, n) = (i + 1, n + 1);
        }
        k += 1;
    }
    out
}

/// Intel Embree 3 (`--features embree`, Debian's `libembree-dev`): high-quality build,
/// `rtcIntersect1` / `rtcOccluded1`, as many build threads as the pool it is built in.
#[cfg(feature = "embree")]
use crate::embree::{EmbreeMode, EmbreeScene};

#[cfg(feature = "embree")]
const EMBREE: AccelEntry = AccelEntry {
    name: "embree",
    about: "Intel Embree 3 (system library), high-quality robust build, rtcIntersect1/rtcOccluded1",
    build: |p| boxed(EmbreeScene::build(p, 0, EmbreeMode::Robust)),
    build_shapes: None,
    tolerance: EMBREE_TOLERANCE,
    external: true,
    bench_max_prims: usize::MAX,
    // On the adversarial scenes Embree answers differently by design: a ray that starts on a
    // triangle hits it at t = 0, and a hit exactly at `tmax` may be dropped or kept.
    conformance: false,
    packets: None,
    packet_only: None,
    kernel: TriangleKernel::Watertight,
};

#[cfg(feature = "embree")]
const OPTIONAL: &[AccelEntry] = &[
    EMBREE,
    // Embree as most of its users run it: default scene flags, not robust.
    AccelEntry {
        name: "embree-fast",
        about: "Intel Embree 3 (system library), high-quality build, default scene flags (not robust), rtcIntersect1/rtcOccluded1",
        build: |p| boxed(EmbreeScene::build(p, 0, EmbreeMode::Default)),
        ..EMBREE
    },
    // Embree's own default build quality: the reference for build times.
    AccelEntry {
        name: "embree-medium",
        about: "Intel Embree 3 (system library), medium-quality build (its default), default scene flags, rtcIntersect1/rtcOccluded1",
        build: |p| boxed(EmbreeScene::build(p, 0, EmbreeMode::Medium)),
        ..EMBREE
    },
    // Embree's packet path for the packet comparisons, in its default mode; its single rays
    // are `embree-fast`'s, so bench and verify do not run them twice.
    AccelEntry {
        name: "embree-packet8",
        about: "the default-flags Embree scene traced by rtcIntersect8/rtcOccluded8, 8 rays per packet (trace --packet 4x2)",
        build: |p| boxed(EmbreeScene::build(p, 0, EmbreeMode::Default)),
        bench_max_prims: 0,
        packets: Some(|p| {
            EmbreeScene::build(p, 0, EmbreeMode::Default)
                .map(|s| Box::new(s) as Box<dyn PacketAccel>)
        }),
        ..EMBREE
    },
];

#[cfg(not(feature = "embree"))]
const OPTIONAL: &[AccelEntry] = &[];

/// tinybvh's BVH8_CPU (`--features tinybvh`; its queries need an AVX2 build: `--native`).
#[cfg(feature = "tinybvh")]
const TINYBVH: &[AccelEntry] = &[AccelEntry {
    name: "tinybvh",
    about: "tinybvh 1.6.8 BVH8_CPU (tinybvh-rs, C++ built with -march=native): default build, leaves of 4, its own AVX2 walk and Moeller-Trumbore test; no tmin, closest hit only",
    build: |p| boxed(crate::tinybvh::TinyBvh8::build(p)),
    build_shapes: None,
    tolerance: MOLLER_TOLERANCE,
    external: true,
    bench_max_prims: usize::MAX,
    conformance: false,
    packets: None,
    packet_only: None,
    kernel: TriangleKernel::Watertight,
}];

#[cfg(not(feature = "tinybvh"))]
const TINYBVH: &[AccelEntry] = &[];

/// What Embree is held to: `t` within 1e-4 relative; rays of the boundary families may lose
/// hits (its watertight test differs from rt's in which of two triangles a shared edge or
/// vertex belongs to); it takes no interval starting behind the origin (`tnear >= 0`).
pub const EMBREE_TOLERANCE: Tolerance = Tolerance {
    rel_t: 1e-4,
    near_t: 0.0,
    boundary_misses: true,
    behind_origin_misses: true,
    lowest_on_ties: false,
    edge_band: 0.0,
};

/// The statistics of a peer that does not report its tree (Embree, tinybvh): its input copy
/// of the triangles (48 bytes each) as a lower bound of its memory, one node.
#[cfg(any(feature = "embree", feature = "tinybvh"))]
pub fn opaque_peer_stats(prims: usize) -> rt_geom::AccelStats {
    rt_geom::AccelStats {
        primitives: prims,
        bytes: prims * 48,
        nodes: 1,
        leaves: 1,
        references: prims,
        ..rt_geom::AccelStats::default()
    }
}

/// What the peers with their own Möller-Trumbore test are held to on the meshes (obvhs's
/// CwBvh, tinybvh): Embree's tolerance (neither is watertight), and no hits below
/// [`CWBVH_NEAR_T`] (CwBvh's walk drops them; tinybvh has no `tmin`).
pub const MOLLER_TOLERANCE: Tolerance = Tolerance {
    near_t: CWBVH_NEAR_T,
    ..EMBREE_TOLERANCE
};

const BASE: &[AccelEntry] = &[
    AccelEntry {
        name: "brute",
        about: "brute force: every ray against every primitive (the reference on small scenes)",
        build: |p| boxed(BruteForce::build(p)),
        build_shapes: Some(|p| boxed(BruteForce::build(p))),
        tolerance: Tolerance::EXACT,
        external: false,
        bench_max_prims: 10_000,
        conformance: true,
        packets: None,
        packet_only: None,
        kernel: TriangleKernel::Watertight,
    },
    generic!(
        "bvh",
        "rt BVH2, binned SAH (16 bins), leaves of up to 4, parallel build (BvhParams::balanced)",
        |p| boxed(Bvh::build(p, BvhParams::balanced())),
    )
    .with_packets(|p| packets_of(Bvh::build(p, BvhParams::balanced()))),
    generic!(
        "bvh4",
        "rt BVH4 collapsed from the balanced BVH2 (largest child opened first), 4 boxes per test",
        |p| boxed(Bvh4::build(p, BvhParams::balanced())),
    )
    .with_packets(|p| packets_of(Bvh4::build(p, BvhParams::balanced()))),
    generic!(
        "bvh8",
        "rt BVH8 collapsed from the balanced BVH2 (largest child opened first), 8 boxes per test",
        |p| boxed(Bvh8::build(p, BvhParams::balanced())),
    )
    .with_packets(|p| packets_of(Bvh8::build(p, BvhParams::balanced()))),
    own(
        "bvh4-tri",
        "rt BVH4 over SoA triangles, four watertight triangle tests at once (BvhParams::fastest_trace: binned SAH, leaf costs in blocks of four, reinsertion 0.25)",
        |p| boxed(TriBvh4::build_for_tracing(p)),
    ),
    own(
        "bvh8-tri",
        "rt BVH8 over SoA triangles, four watertight triangle tests at once (BvhParams::fastest_trace: binned SAH, leaf costs in blocks of four, reinsertion 0.25)",
        |p| boxed(TriBvh8::build_for_tracing(p)),
    ),
    own(
        "bvh8-tri-mt",
        "bvh8-tri with Möller–Trumbore leaf tests (TriangleKernel::MollerTrumbore: not watertight, as Embree's default mode; depths held in the triangle's box)",
        |p| boxed(TriBvh8::build_for_tracing(p).map(|b| b.with_kernel(TriangleKernel::MollerTrumbore))),
    )
    .moller_trumbore(),
    own(
        "bvh8-tri-spatial",
        "rt BVH8 over SoA triangles from the spatial-split BVH2 (BvhParams::fastest_trace_spatial: SBVH, per-triangle leaf costs, reinsertion 0.25, SAH collapse)",
        |p| boxed(TriBvh8::build(p, BvhParams::fastest_trace_spatial())),
    ),
    own(
        "bvh8-tri-spatial-mt",
        "bvh8-tri-spatial with Möller–Trumbore leaf tests (as bvh8-tri-mt)",
        |p| {
            boxed(
                TriBvh8::build(p, BvhParams::fastest_trace_spatial())
                    .map(|b| b.with_kernel(TriangleKernel::MollerTrumbore)),
            )
        },
    )
    .moller_trumbore(),
    own(
        "bvh8c-tri",
        "rt BVH8 with quantized child boxes over SoA triangles (bvh8c's nodes, bvh8-tri's leaves and build)",
        |p| boxed(CompressedTriBvh8::build(p, BvhParams::fastest_trace())),
    ),
    own(
        "bvh8c-tri-spatial",
        "rt BVH8 with quantized child boxes over SoA triangles, from the spatial-split BVH2",
        |p| boxed(CompressedTriBvh8::build(p, BvhParams::spatial().for_soa_leaves())),
    ),
    own(
        "bvh8-tri-greedy",
        "bvh8-tri collapsed by the greedy rule alone (open the child of largest area; WideCollapse::LargestArea)",
        |p| {
            let params = BvhParams::fastest_trace().with_collapse(WideCollapse::LargestArea);
            boxed(TriBvh8::build(p, params))
        },
    ),
    own(
        "bvh8-tri-sah",
        "bvh8-tri collapsed by the SAH-optimal plan alone (Ylitie et al. 2017; WideCollapse::Sah)",
        |p| {
            let params = BvhParams::fastest_trace().with_collapse(WideCollapse::Sah);
            boxed(TriBvh8::build(p, params))
        },
    ),
    own(
        "bvh8-tri-fast",
        "rt BVH8 over SoA triangles, binned SAH with 8 bins and leaves of up to 8 (two 4-lane tests)",
        |p| boxed(TriBvh8::build(p, BvhParams::fast())),
    ),
    generic!(
        "bvh-reinsertion",
        "rt BVH2, binned SAH (16 bins) then reinsertion of every node's subtree where it lowers the SAH (BvhParams::balanced, reinsertion 1.0)",
        |p| boxed(Bvh::build(p, BvhParams::balanced().with_reinsertion(1.0))),
    )
    .with_packets(|p| packets_of(Bvh::build(p, BvhParams::balanced().with_reinsertion(1.0)))),
    generic!(
        "bvh-fast",
        "rt BVH2, binned SAH (8 bins), leaves of up to 8 (BvhParams::fast)",
        |p| boxed(Bvh::build(p, BvhParams::fast())),
    )
    .with_packets(|p| packets_of(Bvh::build(p, BvhParams::fast()))),
    generic!(
        "bvh-sweep",
        "rt BVH2, full sweep SAH, leaves of up to 4 (BvhParams::quality)",
        |p| boxed(Bvh::build(p, BvhParams::quality())),
    )
    .with_packets(|p| packets_of(Bvh::build(p, BvhParams::quality()))),
    generic!(
        "bvh-spatial",
        "rt BVH2, binned SAH with spatial splits (SBVH, alpha 1e-5, up to one extra reference per primitive)",
        |p| boxed(Bvh::build(p, BvhParams::spatial())),
    )
    .with_packets(|p| packets_of(Bvh::build(p, BvhParams::spatial()))),
    generic!(
        "bvh8-spatial",
        "rt BVH8 collapsed from the spatial-split BVH2",
        |p| boxed(Bvh8::build(p, BvhParams::spatial())),
    )
    .with_packets(|p| packets_of(Bvh8::build(p, BvhParams::spatial()))),
    generic!(
        "bvh8c",
        "rt BVH8 with child boxes quantized to 8 bits per plane (128-byte nodes, half of bvh8's), balanced build",
        |p| boxed(CompressedBvh8::build(p, BvhParams::balanced())),
    ),
    generic!(
        "bvh8c-spatial",
        "rt BVH8 with quantized child boxes, from the spatial-split BVH2",
        |p| boxed(CompressedBvh8::build(p, BvhParams::spatial())),
    ),
    generic!(
        "bvh-midpoint",
        "rt BVH2, naive: largest centroid extent split at its middle, leaves of up to 4",
        |p| {
            boxed(Bvh::build(
                p,
                BvhParams::balanced().with_builder(BvhBuilder::Midpoint),
            ))
        },
    ),
    generic!(
        "bvh-median",
        "rt BVH2, naive: object median along the largest centroid extent, leaves of up to 4",
        |p| {
            boxed(Bvh::build(
                p,
                BvhParams::balanced().with_builder(BvhBuilder::Median),
            ))
        },
    ),
    generic!(
        "bvlist-sphere",
        "flat list of bounding spheres, one per Morton cluster of 32 primitives, front to back",
        |p| {
            boxed(BvList::<_, BoundingSphere>::build(
                p,
                BvListParams::default(),
            ))
        },
    )
    .bench_up_to(BVLIST_BENCH_MAX),
    generic!(
        "bvlist-box",
        "flat list of bounding boxes, one per Morton cluster of 32 primitives, front to back",
        |p| boxed(BvList::<_, Aabb>::build(p, BvListParams::default())),
    )
    .bench_up_to(BVLIST_BENCH_MAX),
    generic!(
        "bvlist-kdop",
        "flat list of 7-slab k-DOPs (Kay & Kajiya), one per Morton cluster of 32 primitives",
        |p| boxed(BvList::<_, Kdop7>::build(p, BvListParams::default())),
    )
    .bench_up_to(BVLIST_BENCH_MAX),
    generic!(
        "bvlist-box-2level",
        "boxes of 32 primitives grouped under boxes of 32 boxes (volumes of volumes)",
        |p| boxed(BvList::<_, Aabb>::build(p, bvlist_two_level())),
    ),
    generic!(
        "kd",
        "rt kd-tree, SAH over all clipped-box planes in O(N log N) (Wald & Havran 2006), iterative traversal",
        |p| boxed(KdTree::build(p, KdParams::sah())),
    )
    // Packets test a leaf's triangles one block of lanes per triangle: they run faster on
    // the smaller leaves of Wald & Havran's constants (see `KdParams::wald_havran`); single
    // rays (and incoherent groups) keep the `kd` tree.
    .with_packets(|p| packets_of(kd_packets(p).map(|(packets, singles)| WithSingleRays { packets, singles }))),
    generic!(
        "kd-mlrta",
        "the SAH kd-tree's packets by multi-level ray tracing (Reshetov et al. 2005): each beam starts at its entry point; single rays are kd's",
        |p| boxed(KdTree::build(p, KdParams::sah())),
    )
    .with_packets(|p| {
        packets_of(kd_packets(p).map(|(packets, singles)| WithSingleRays {
            packets: MlrtaKdTree::new(packets),
            singles,
        }))
    })
    .packet_only("kd"),
    generic!(
        "kd-recursive",
        "the same SAH kd-tree, traversed by the classic recursive front-to-back descent",
        |p| {
            boxed(KdTree::build(
                p,
                KdParams::sah().with_traversal(KdTraversal::Recursive),
            ))
        },
    ),
    generic!(
        "kd-midpoint",
        "rt kd-tree, naive: largest extent split at its middle, leaves of up to 8",
        |p| boxed(KdTree::build(p, KdParams::midpoint())),
    ),
    generic!(
        "kd-centroid",
        "rt kd-tree, naive: largest extent split at the centre of gravity, leaves of up to 8",
        |p| boxed(KdTree::build(p, KdParams::centroid())),
    ),
    generic!(
        "bsp",
        "rt BSP tree, planes of any orientation: 16 of the node's triangle planes and 3 axis-aligned, SAH on cell boxes",
        |p| boxed(BspTree::build(p, BspParams::standard())),
    ),
    generic!(
        "bsp-auto",
        "rt BSP tree by autopartition: only the triangles' own planes (16 tried per node)",
        |p| boxed(BspTree::build(p, BspParams::autopartition())),
    ),
    generic!(
        "grid",
        "rt uniform grid, 1 cell per 2 primitives, exact triangle/cell overlap, 3D-DDA (Amanatides & Woo) crossing empty cubes in one step",
        |p| boxed(Grid::build(p, GridParams::uniform())),
    ),
    generic!(
        "grid-mailbox",
        "the same uniform grid, each ray skipping primitives it already tested (mailboxes)",
        |p| boxed(Grid::build(p, GridParams::uniform().with_mailbox(true))),
    ),
    generic!(
        "grid-dda",
        "the same uniform grid walked cell by cell (the classic 3D-DDA, no empty-space skipping)",
        |p| boxed(Grid::build(p, GridParams::uniform().with_skip_empty(false))),
    ),
    generic!(
        "grid2",
        "rt two-level grid (Kalojanov et al. 2011): 1 top cell per 100 primitives, each cell's content refined at 1 cell per 2 primitives",
        |p| boxed(Grid::build(p, GridParams::two_level())),
    ),
    generic!(
        "grid-adaptive",
        "rt adaptive grid (Jevans & Wyvill): 1 cell per 8 primitives, cells of more than 24 refined the same way over their content, up to 4 levels",
        |p| boxed(Grid::build(p, GridParams::adaptive())),
    ),
    generic!(
        "octree",
        "rt octree, split at the centre above 24 primitives (depth <= 16), parametric walk (Revelles et al. 2000)",
        |p| boxed(Octree::build(p, OctreeParams::standard())),
    ),
    generic!(
        "octree-mailbox",
        "the same octree with per-ray mailboxes (a primitive in several leaves tested once)",
        |p| boxed(Octree::build(p, OctreeParams::standard().with_mailbox(true))),
    ),
    generic!(
        "octree-recursive",
        "the same octree, walked by the classic recursive nearest-first descent",
        |p| {
            boxed(Octree::build(
                p,
                OctreeParams::standard().with_traversal(OctreeTraversal::Recursive),
            ))
        },
    ),
    AccelEntry {
        name: "obvhs",
        about: "obvhs 0.4 Bvh2, very_slow_build preset (PLOC + reinsertion + presplits), rt's watertight kernel in its leaves: the correctness reference",
        build: |p| boxed(ObvhsBvh2::build(p)),
        build_shapes: None,
        tolerance: OBVHS_TOLERANCE,
        external: true,
        bench_max_prims: usize::MAX,
        conformance: true,
        packets: None,
        packet_only: None,
        kernel: TriangleKernel::Watertight,
    },
    AccelEntry {
        name: "obvhs-cwbvh",
        about: "obvhs 0.4 CwBvh (8-wide compressed), very_slow_build preset, its own Moeller-Trumbore triangle test: the speed peer as its users run it; drops hits below t = 1e-4",
        build: |p| boxed(ObvhsCwBvh::build(p)),
        build_shapes: None,
        tolerance: MOLLER_TOLERANCE,
        external: true,
        bench_max_prims: usize::MAX,
        // Not watertight: a ray through a shared edge or vertex may miss both triangles.
        conformance: false,
        packets: None,
        packet_only: None,
        kernel: TriangleKernel::Watertight,
    },
    AccelEntry {
        name: "obvhs-cwbvh-rt-kernel",
        about: "the same obvhs CwBvh with rt's watertight kernel in its leaves (for verify); drops hits below t = 1e-4",
        build: |p| boxed(ObvhsCwBvhRtKernel::build(p)),
        build_shapes: None,
        tolerance: Tolerance {
            near_t: CWBVH_NEAR_T,
            ..OBVHS_TOLERANCE
        },
        external: true,
        bench_max_prims: usize::MAX,
        conformance: true,
        packets: None,
        packet_only: None,
        kernel: TriangleKernel::Watertight,
    },
];

/// The entry with this name.
pub fn find(name: &str) -> Option<&'static AccelEntry> {
    REGISTRY.iter().find(|e| e.name == name)
}

/// Entries by a comma-separated list of names (all when `None`); unknown names are an error
/// that lists the known ones.
pub fn select(names: Option<&str>) -> Result<Vec<&'static AccelEntry>, String> {
    match names {
        None => Ok(REGISTRY.iter().collect()),
        Some(list) => list
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|n| find(n).ok_or_else(|| unknown(n)))
            .collect(),
    }
}

/// The error message for an unknown structure name.
pub fn unknown(name: &str) -> String {
    let names: Vec<_> = REGISTRY.iter().map(|e| e.name).collect();
    format!("unknown accel '{name}'; known: {}", names.join(", "))
}

/// The registry as a Markdown table, one row per structure (`cargo xtask accels --markdown`):
/// the README's list of structures is this output, checked by a test so it cannot drift.
pub fn markdown_table() -> String {
    let mut out =
        String::from("| name | packets | spheres, cones | what it is |\n|---|---|---|---|\n");
    for e in REGISTRY {
        let yes = |b: bool| if b { "yes" } else { "" };
        out.push_str(&format!(
            "| `{}` | {} | {} | {} |\n",
            e.name,
            yes(e.packets.is_some()),
            yes(e.build_shapes.is_some()),
            e.about.replace('|', "\\|")
        ));
    }
    out
}
