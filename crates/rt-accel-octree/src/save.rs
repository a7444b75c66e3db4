//! Saved octrees over triangles: a built [`Octree`] as bytes and back, so that a renderer
//! runs the build once. A plain little-endian layout, versioned:
//!
//! ```text
//! magic      8 bytes  "rt-oct\r\n"
//! version    u32      1
//! params     the build parameters (OctreeParams), field by field
//! primitives u64 count, u64 hash: 64-bit FNV-1a over 32-bit words of every triangle vertex's
//!            coordinates
//! root       u32      the root reference (ChildRef)
//! nodes      u64 count, each: inner_base u32, leaf_base u32, mask u8, leaf_mask u8,
//!            lo 24 bytes, hi 24 bytes (the quantized content boxes, by axis and octant)
//! leaves     u64 count, each: first u32, count u32
//! indices    u64 count, u32 each
//! ```
//!
//! The triangles are not stored: `from_bytes` takes them again and checks them against the
//! hash; the root cube and the frame the cells are in follow from them, as the build derives
//! them. Loading checks every length against the bytes left; the topology before anything is
//! indexed by it (each node and leaf reached once from the root, depth at most the
//! parameters' `max_depth`, each leaf's primitives in range); the tree's own
//! [`Accel::validate`] (each listed triangle in its leaf's cell and content box); and that
//! every triangle is listed wherever the build would list it (its distribution down the tree
//! redone, clipped as the build clips: rounding that a coverage test of the cells would judge
//! otherwise cannot let a file through that the walk would answer wrong). A truncated,
//! corrupted or foreign file is a [`LoadError`], never a panic or a wrong answer.
//!
//! ```
//! use rt_accel_octree::{Octree, OctreeParams};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let tree = Octree::build(&tris, OctreeParams::standard()).unwrap();
//! let bytes = tree.to_bytes();
//! let loaded = Octree::from_bytes(&bytes, &tris).unwrap();
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! assert_eq!(loaded.intersect(&ray), tree.intersect(&ray));
//! assert!(Octree::from_bytes(&bytes[..bytes.len() - 1], &tris).is_err());
//! ```

use crate::node::{MAX_NODES, octant};
use crate::{ChildRef, OctLeaf, OctNode, Octree, OctreeParams, OctreeTraversal, build};
use rt_geom::saved::{LoadError, Reader, Writer, triangle_hash};
use rt_geom::{Accel, LeafPrims, Triangle, check_primitives};

const MAGIC: &[u8; 8] = b"rt-oct\r\n";
const VERSION: u32 = 1;

impl Octree<Triangle> {
    /// The tree as bytes (the format is in the [module](self) documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Writer::default();
        out.header(MAGIC, VERSION);
        write_params(&mut out, &self.params);
        out.primitives((self.prims.len(), triangle_hash(&self.prims)));
        out.u32(self.root.0);
        out.u64(self.nodes.len() as u64);
        for n in &self.nodes {
            out.u32(n.inner_base() as u32);
            out.u32(n.leaf_base() as u32);
            out.u8(n.mask());
            out.u8(n.leaf_mask());
            out.0.extend(n.lo.iter().flatten());
            out.0.extend(n.hi.iter().flatten());
        }
        out.u64(self.leaves.len() as u64);
        for l in &self.leaves {
            out.u32(l.first);
            out.u32(l.count);
        }
        out.u64(self.indices.len() as u64);
        for &i in &self.indices {
            out.u32(i);
        }
        out.0
    }

    /// The tree [`Self::to_bytes`] wrote, over the same `tris`: the same answers, bit for
    /// bit. Any other bytes or triangles give a [`LoadError`].
    pub fn from_bytes(bytes: &[u8], tris: &[Triangle]) -> Result<Self, LoadError> {
        let mut r = Reader(bytes);
        r.header(MAGIC, VERSION)?;
        let params = read_params(&mut r)?;
        r.primitives((tris.len(), triangle_hash(tris)))?;
        let root = ChildRef(r.u32()?);
        let count = r.count(58)?;
        let mut nodes = Vec::with_capacity(count);
        let codes = |r: &mut Reader| -> Result<[[u8; 8]; 3], LoadError> {
            Ok([r.take::<8>()?, r.take::<8>()?, r.take::<8>()?])
        };
        for _ in 0..count {
            let bases = (r.u32()?, r.u32()?);
            let masks = (r.u8()?, r.u8()?);
            nodes.push(OctNode::from_parts(
                bases,
                masks,
                codes(&mut r)?,
                codes(&mut r)?,
            ));
        }
        let count = r.count(8)?;
        let mut leaves = Vec::with_capacity(count);
        for _ in 0..count {
            leaves.push(OctLeaf {
                first: r.u32()?,
                count: r.u32()?,
            });
        }
        let count = r.count(4)?;
        let indices = (0..count).map(|_| r.u32()).collect::<Result<Vec<_>, _>>()?;
        if !r.0.is_empty() {
            return Err(LoadError::TrailingBytes);
        }
        let corrupt = |e: String| LoadError::Corrupt(e);
        // Triangles no build takes cannot have been saved.
        check_primitives(tris, MAX_NODES - 1).map_err(|e| corrupt(e.to_string()))?;
        check_topology(root, &nodes, &leaves, &indices, tris.len(), &params).map_err(corrupt)?;
        let (frame, bounds) = Self::root_cube(tris);
        let lists = leaves.iter().map(|l| (l.first, l.count));
        let tree = Self {
            leaf_prims: LeafPrims::new(tris, &indices, lists),
            nodes: nodes.into(),
            leaves: leaves.into(),
            indices: indices.into(),
            root,
            prims: tris.to_vec(),
            bounds,
            params,
            frame,
            isa: rt_geom::Isa::selected(),
        };
        tree.validate().map_err(corrupt)?;
        tree.check_coverage().map_err(corrupt)?;
        Ok(tree)
    }

    /// Every triangle is listed wherever the build would list it: from the root down, the
    /// octants the build's own distribution sends it to (`build::distribute`, clipped as
    /// the build clips) are stored, and the leaves among them list it; so the walk meets it
    /// in every cell the build's walk would.
    fn check_coverage(&self) -> Result<(), String> {
        use rayon::prelude::*;
        if self.leaves.is_empty() {
            return Ok(());
        }
        let ctx = build::Ctx {
            prims: &self.prims,
            params: &self.params,
            frame: self.frame,
        };
        let uncovered = (0..self.prims.len() as u32)
            .into_par_iter()
            .find_first(|&id| !self.listed_as_built(&ctx, id));
        match uncovered {
            Some(id) => Err(format!(
                "triangle {id} is not listed in every cell it crosses"
            )),
            None => Ok(()),
        }
    }

    /// Whether triangle `id` is listed by every leaf the build would list it in (see
    /// [`Self::check_coverage`]).
    fn listed_as_built(&self, ctx: &build::Ctx<Triangle>, id: u32) -> bool {
        let mut stack = vec![(self.root, self.bounds)];
        while let Some((r, cell)) = stack.pop() {
            if r.is_leaf() {
                if !self.indices[self.leaves[r.index()].prims()].contains(&id) {
                    return false;
                }
                continue;
            }
            let n = &self.nodes[r.index()];
            let sent = build::distribute(ctx, &[id], &cell);
            for (o, ids) in sent.iter().enumerate() {
                if ids.is_empty() {
                    continue;
                }
                match n.child(o) {
                    Some(c) => stack.push((c, octant(&cell, o))),
                    None => return false,
                }
            }
        }
        true
    }
}

/// The tree's shape, before anything is indexed by it: from the root, each inner node and
/// leaf reached once and every one reached, depth at most `params.max_depth`, each leaf's
/// range inside `indices`, and every primitive in `indices` in range.
fn check_topology(
    root: ChildRef,
    nodes: &[OctNode],
    leaves: &[OctLeaf],
    indices: &[u32],
    prims: usize,
    params: &OctreeParams,
) -> Result<(), String> {
    if let Some(&p) = indices.iter().find(|&&p| p as usize >= prims) {
        return Err(format!("the index array holds primitive {p}, out of range"));
    }
    if leaves.is_empty() {
        return match (prims, nodes.len(), root) {
            (0, 0, ChildRef(0)) => Ok(()),
            _ => Err("no leaves over primitives".into()),
        };
    }
    let (mut inner_seen, mut leaf_seen) = (vec![false; nodes.len()], vec![false; leaves.len()]);
    let mut stack = vec![(root, 0u32)];
    while let Some((r, depth)) = stack.pop() {
        if depth > params.max_depth {
            return Err(format!("{r:?} lies deeper than {}", params.max_depth));
        }
        let i = r.index();
        let seen = if r.is_leaf() {
            leaf_seen.get_mut(i)
        } else {
            inner_seen.get_mut(i)
        };
        match seen {
            None => return Err(format!("{r:?} is out of range")),
            Some(s) if *s => return Err(format!("{r:?} is reached twice")),
            Some(s) => *s = true,
        }
        if r.is_leaf() {
            let l = &leaves[i];
            if (l.first as usize).saturating_add(l.count as usize) > indices.len() {
                return Err(format!("leaf {i} lists entries past the index array"));
            }
            continue;
        }
        let n = &nodes[i];
        if n.mask() == 0 || n.leaf_mask() & !n.mask() != 0 {
            return Err(format!(
                "inner node {i} has no octants, or leaves it does not hold"
            ));
        }
        // Before the children are named (their indices are sums with the bases).
        let inner = (n.mask() & !n.leaf_mask()).count_ones() as usize;
        let leaf_children = n.leaf_mask().count_ones() as usize;
        if n.inner_base() + inner > nodes.len() || n.leaf_base() + leaf_children > leaves.len() {
            return Err(format!("inner node {i} has children out of range"));
        }
        stack.extend((0..8).filter_map(|o| n.child(o)).map(|c| (c, depth + 1)));
    }
    if let Some(i) = inner_seen.iter().position(|s| !s) {
        return Err(format!("inner node {i} is not in the tree"));
    }
    if let Some(i) = leaf_seen.iter().position(|s| !s) {
        return Err(format!("leaf {i} is not in the tree"));
    }
    Ok(())
}

fn write_params(out: &mut Writer, p: &OctreeParams) {
    out.u32(p.max_prims);
    out.u32(p.max_depth);
    out.f32(p.reference_budget);
    out.u64(p.parallel_threshold as u64);
    out.u8(match p.traversal {
        OctreeTraversal::Recursive => 0,
        OctreeTraversal::Parametric => 1,
    });
    out.u8(p.mailbox as u8);
}

fn read_params(r: &mut Reader) -> Result<OctreeParams, LoadError> {
    let corrupt = |what: &str| LoadError::Corrupt(format!("unknown {what}"));
    let (max_prims, max_depth, reference_budget) = (r.u32()?, r.u32()?, r.f32()?);
    let parallel_threshold = usize::try_from(r.u64()?).map_err(|_| corrupt("threshold"))?;
    let traversal = match r.u8()? {
        0 => OctreeTraversal::Recursive,
        1 => OctreeTraversal::Parametric,
        _ => return Err(corrupt("traversal")),
    };
    let mailbox = match r.u8()? {
        0 => false,
        1 => true,
        _ => return Err(corrupt("mailbox flag")),
    };
    let params = OctreeParams {
        max_prims,
        max_depth,
        reference_budget,
        parallel_threshold,
        traversal,
        mailbox,
    };
    params
        .validate()
        .map_err(|e| LoadError::Corrupt(format!("parameters: {e}")))?;
    Ok(params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_testkit::rays::rays_through_unit_cube as rays;
    use rt_testkit::scenes;

    /// Every conformance scene (slivers, shared edges and vertices, axis-aligned and
    /// coplanar sets, far coordinates) loads back as built: the coverage check refuses no tree
    /// the build makes.
    #[test]
    fn every_conformance_scene_loads_back() {
        let s = OctreeParams::standard();
        for params in [s, OctreeParams { max_prims: 1, ..s }] {
            let build = |t: &[Triangle]| Octree::build(t, params).unwrap();
            rt_testkit::assert_conformance_scenes_load(build, Octree::to_bytes, Octree::from_bytes);
        }
    }

    /// Every walk and leaf size round-trips: the same answers bit for bit, the same bytes
    /// again; empty and one-triangle scenes too.
    #[test]
    fn every_variant_round_trips_bit_for_bit() {
        let mut tris = scenes::random_soup(700, 3);
        // Triangles lying in the planes the octants are cut at.
        tris.extend(scenes::triangle_scene("coplanar").prims);
        let s = OctreeParams::standard();
        for params in [
            s,
            s.with_traversal(OctreeTraversal::Recursive)
                .with_mailbox(true),
            OctreeParams {
                max_prims: 1,
                max_depth: 10,
                ..s
            },
        ] {
            for tris in [&tris[..], &tris[..1], &[]] {
                let tree = Octree::build(tris, params).unwrap();
                let load = |b: &[u8]| Octree::from_bytes(b, tris);
                rt_testkit::assert_round_trip(&tree, Octree::to_bytes, load, &rays(2000));
            }
        }
    }

    /// Damaged bytes are refused, never loaded wrong: every prefix, every byte changed (every
    /// eighth unless the long tests run), other triangles, and a triangle dropped from a leaf
    /// (found by the coverage check alone).
    #[test]
    fn damage_is_refused() {
        let tris = scenes::random_soup(120, 5);
        let tree = Octree::build(&tris, OctreeParams::standard()).unwrap();
        let bytes = tree.to_bytes();
        let brute = rt_geom::BruteForce::build(&tris).unwrap();
        let load = |b: &[u8]| Octree::from_bytes(b, &tris);
        rt_testkit::assert_damage_refused(&bytes, load, &brute, &rays(300));
        assert_eq!(
            Octree::from_bytes(&bytes, &tris[1..]).err(),
            Some(LoadError::OtherPrimitives)
        );
        // A leaf loses a triangle that other leaves list too (so that every triangle is
        // still listed somewhere): it now lists its neighbour twice.
        let listed = |p: u32| tree.indices.iter().filter(|&&q| q == p).count();
        let leaf = tree
            .leaves
            .iter()
            .find(|l| l.count > 1 && listed(tree.indices[l.first as usize]) > 1)
            .unwrap();
        let mut dropped = tree.clone();
        let first = leaf.first as usize;
        dropped.indices[first] = dropped.indices[first + 1];
        let err = Octree::from_bytes(&dropped.to_bytes(), &tris).unwrap_err();
        assert!(
            err.to_string().contains("not listed in every cell"),
            "{err}"
        );
    }

    /// The loader fuzzer's finding (`fuzz/regressions/load_bvh`): an inner node whose first
    /// leaf lies near the top of the index range overflowed naming its children; it is
    /// refused for what it is.
    #[test]
    fn fuzz_findings_are_refused_for_their_fault() {
        let tris = scenes::tessellated_sphere(40, rt_geom::Vec3::ZERO, 1.0);
        let bytes = rt_testkit::fuzz_regression("load_bvh", "octree-child-base-overflow");
        match Octree::from_bytes(&bytes, &tris) {
            Err(LoadError::Corrupt(why)) => assert!(why.contains("out of range"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    /// A node reached twice (two parents sharing their children) is refused before the
    /// checks that walk the tree, which would otherwise visit it once per path.
    #[test]
    fn shared_children_are_refused() {
        let tris = scenes::random_soup(400, 9);
        let tree = Octree::build(&tris, OctreeParams::standard()).unwrap();
        let inner: Vec<usize> = (0..tree.nodes.len())
            .filter(|&i| tree.nodes[i].mask() & !tree.nodes[i].leaf_mask() != 0)
            .collect();
        assert!(
            inner.len() >= 2,
            "the scene must have two inner nodes with inner children"
        );
        let mut shared = tree.clone();
        let (a, b) = (inner[0], inner[1]);
        shared.nodes[b] = shared.nodes[a];
        match Octree::from_bytes(&shared.to_bytes(), &tris) {
            Err(LoadError::Corrupt(why)) => {
                assert!(
                    why.contains("reached twice") || why.contains("not in the tree"),
                    "{why}"
                )
            }
            other => panic!("{other:?}"),
        }
    }
}
