//! Saved kd-trees over triangles: a built [`KdTree`] as bytes and back, so that a renderer
//! runs the SAH build once. A plain little-endian layout, versioned:
//!
//! ```text
//! magic      8 bytes  "rt-kd\r\n\0"
//! version    u32      1
//! params     the build parameters (KdParams), field by field; a depth cap of `None` is a
//!            zero flag and a zero value
//! primitives u64 count, u64 hash: 64-bit FNV-1a over 32-bit words of every triangle vertex's
//!            coordinates
//! nodes      u64 count, each node's two words (data, meta; see `node`)
//! indices    u64 count, u32 each
//! ```
//!
//! The triangles are not stored: `from_bytes` takes them again and checks them against the
//! hash; the bounds and the frame the planes are in follow from them and the parameters, as
//! the build derives them. Loading checks every length against the bytes left; the topology
//! before anything is indexed by it (each node reached once, depth-first, children forward,
//! depth at most [`crate::MAX_DEPTH`], each plane inside its cell, each leaf's primitives in
//! range); the tree's own [`Accel::validate`]; and that every triangle is covered by the
//! cells of the leaves that list it (its polygon cut down the tree in `f64`: a part of it
//! thicker than `1e-9` of its size in a leaf that does not list it is refused). A truncated,
//! corrupted or foreign file is a [`LoadError`], never a panic or a wrong answer.
//!
//! ```
//! use rt_accel_kd::{KdParams, KdTree};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let kd = KdTree::build(&tris, KdParams::sah()).unwrap();
//! let bytes = kd.to_bytes();
//! let loaded = KdTree::from_bytes(&bytes, &tris).unwrap();
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! assert_eq!(loaded.intersect(&ray), kd.intersect(&ray));
//! assert!(KdTree::from_bytes(&bytes[..bytes.len() - 1], &tris).is_err());
//! ```

use crate::build::child_bounds;
use crate::{KdBuilder, KdNode, KdParams, KdTraversal, KdTree, MAX_DEPTH};
use rt_geom::saved::{LoadError, Reader, Writer, polygon, split_polygon, thick, triangle_hash};
use rt_geom::{Aabb, Accel, DVec3, Triangle, check_primitives};

const MAGIC: &[u8; 8] = b"rt-kd\r\n\0";
const VERSION: u32 = 1;

impl KdTree<Triangle> {
    /// The tree as bytes (the format is in the [module](self) documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Writer::default();
        out.header(MAGIC, VERSION);
        write_params(&mut out, &self.params);
        out.primitives((self.prims.len(), triangle_hash(&self.prims)));
        out.u64(self.nodes.len() as u64);
        for n in &self.nodes {
            let (data, meta) = n.words();
            out.u32(data);
            out.u32(meta);
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
        let corrupt = |e: String| LoadError::Corrupt(e);
        let count = r.count(8)?;
        let mut nodes = Vec::with_capacity(count);
        for _ in 0..count {
            nodes.push(KdNode::from_words(r.u32()?, r.u32()?));
        }
        let count = r.count(4)?;
        let indices = (0..count).map(|_| r.u32()).collect::<Result<Vec<_>, _>>()?;
        if !r.0.is_empty() {
            return Err(LoadError::TrailingBytes);
        }
        // Triangles no build takes cannot have been saved.
        check_primitives(tris, crate::build::MAX_LOCAL).map_err(|e| corrupt(e.to_string()))?;
        let frame = Self::frame_for(tris, &params);
        let root = frame.to_local(&Aabb::around(tris));
        check_topology(&nodes, &indices, tris.len(), root).map_err(corrupt)?;
        let tree = Self::assemble(tris, nodes, indices, frame, params);
        tree.validate().map_err(corrupt)?;
        tree.check_coverage().map_err(corrupt)?;
        Ok(tree)
    }

    /// Every triangle that can be hit is listed by each leaf whose cell holds a part of it
    /// thicker than `1e-9` of its size (a triangle lying in a split plane: by the leaves of
    /// one side or the other), so that the walk meets it in every cell it crosses.
    fn check_coverage(&self) -> Result<(), String> {
        use rayon::prelude::*;
        if self.nodes.is_empty() {
            return Ok(());
        }
        let anchor = self.frame.anchor.as_dvec3();
        let uncovered = (0..self.prims.len()).into_par_iter().find_first(|&i| {
            let t = &self.prims[i];
            if t.is_degenerate() {
                return false;
            }
            let (tri, size) = polygon(t);
            let local: Vec<DVec3> = tri.into_iter().map(|p| p - anchor).collect();
            thick(&local, size) && !self.covers(0, local, i as u32, size)
        });
        match uncovered {
            Some(id) => Err(format!(
                "triangle {id} is not listed in every cell it crosses"
            )),
            None => Ok(()),
        }
    }

    /// Whether polygon `p` (a part of triangle `id`, in the frame, thicker than a sliver) is
    /// covered below node `i`. A part wholly on one side of a plane goes down as it is; only
    /// one that straddles a plane is cut, and its slivers are dropped.
    fn covers(&self, mut i: usize, p: Vec<DVec3>, id: u32, size: f64) -> bool {
        loop {
            let n = &self.nodes[i];
            if n.is_leaf() {
                return n.leaf_prims(&self.indices).contains(&id);
            }
            let (axis, pos) = (n.axis(), n.split() as f64);
            let (lo, hi) = p
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                    (lo.min(q[axis]), hi.max(q[axis]))
                });
            if hi < pos {
                i += 1;
            } else if lo > pos {
                i = n.above();
            } else if lo == pos && hi == pos {
                // In the plane: the build puts it on one side.
                return self.covers(i + 1, p.clone(), id, size)
                    || self.covers(n.above(), p, id, size);
            } else {
                let (below, above) = split_polygon(&p, axis, pos, true);
                let covered = |node, part: Vec<DVec3>| {
                    !thick(&part, size) || self.covers(node, part, id, size)
                };
                return covered(i + 1, below) && covered(n.above(), above);
            }
        }
    }
}

/// The tree's shape, before anything is indexed by it: from node 0 depth-first, each node
/// reached once and every node reached, the child below an inner node next to it and the one
/// above further on, depth at most [`MAX_DEPTH`], each plane finite and inside its cell, each
/// leaf's range inside `indices`, and every primitive named (by a leaf or by `indices`) in
/// range.
fn check_topology(
    nodes: &[KdNode],
    indices: &[u32],
    prims: usize,
    root: Aabb,
) -> Result<(), String> {
    if nodes.is_empty() {
        return match (prims, indices.len()) {
            (0, 0) => Ok(()),
            _ => Err("no nodes over primitives".into()),
        };
    }
    // Every entry is laid out for the leaf test, listed by a leaf or not.
    if let Some(&p) = indices.iter().find(|&&p| p as usize >= prims) {
        return Err(format!("the index array holds primitive {p}, out of range"));
    }
    let mut reached = vec![false; nodes.len()];
    let mut stack = vec![(0usize, root, 0u32)];
    while let Some((i, cell, depth)) = stack.pop() {
        if std::mem::replace(&mut reached[i], true) {
            return Err(format!("node {i} is reached twice"));
        }
        if depth > MAX_DEPTH {
            return Err(format!("node {i} lies deeper than {MAX_DEPTH}"));
        }
        let n = &nodes[i];
        if n.is_leaf() {
            let listed = match n.count() {
                0 | 1 => true,
                c => (n.data() as usize)
                    .checked_add(c)
                    .is_some_and(|end| end <= indices.len()),
            };
            if !listed {
                return Err(format!("leaf {i} lists entries past the index array"));
            }
            if let Some(&p) = n.leaf_prims(indices).iter().find(|&&p| p as usize >= prims) {
                return Err(format!("leaf {i} holds primitive {p}, out of range"));
            }
            continue;
        }
        let (axis, split, above) = (n.axis(), n.split(), n.above());
        if !(above > i + 1 && above < nodes.len()) {
            return Err(format!("node {i} has children {} and {above}", i + 1));
        }
        if !(split >= cell.min[axis] && split <= cell.max[axis]) {
            return Err(format!("node {i} splits at {split}, outside its cell"));
        }
        let (below_cell, above_cell) = child_bounds(&cell, axis, split);
        stack.push((above, above_cell, depth + 1));
        stack.push((i + 1, below_cell, depth + 1));
    }
    match reached.iter().position(|r| !r) {
        Some(i) => Err(format!("node {i} is not in the tree")),
        None => Ok(()),
    }
}

fn write_params(out: &mut Writer, p: &KdParams) {
    out.u8(match p.builder {
        KdBuilder::Sah => 0,
        KdBuilder::Midpoint => 1,
        KdBuilder::Centroid => 2,
    });
    out.f32(p.traversal_cost);
    out.f32(p.intersection_cost);
    out.f32(p.empty_bonus);
    out.u8(p.max_depth.is_some() as u8);
    out.u32(p.max_depth.unwrap_or(0));
    out.u32(p.max_leaf_size);
    out.f32(p.reference_budget);
    out.u64(p.parallel_threshold as u64);
    out.u8(match p.traversal {
        KdTraversal::Iterative => 0,
        KdTraversal::Recursive => 1,
    });
}

fn read_params(r: &mut Reader) -> Result<KdParams, LoadError> {
    let corrupt = |what: &str| LoadError::Corrupt(format!("unknown {what}"));
    let builder = match r.u8()? {
        0 => KdBuilder::Sah,
        1 => KdBuilder::Midpoint,
        2 => KdBuilder::Centroid,
        _ => return Err(corrupt("builder")),
    };
    let (traversal_cost, intersection_cost, empty_bonus) = (r.f32()?, r.f32()?, r.f32()?);
    let max_depth = match (r.u8()?, r.u32()?) {
        (0, 0) => None,
        (1, d) => Some(d),
        _ => return Err(corrupt("depth cap")),
    };
    let max_leaf_size = r.u32()?;
    let reference_budget = r.f32()?;
    let parallel_threshold = usize::try_from(r.u64()?).map_err(|_| corrupt("threshold"))?;
    let traversal = match r.u8()? {
        0 => KdTraversal::Iterative,
        1 => KdTraversal::Recursive,
        _ => return Err(corrupt("traversal")),
    };
    let params = KdParams {
        builder,
        traversal_cost,
        intersection_cost,
        empty_bonus,
        max_depth,
        max_leaf_size,
        reference_budget,
        parallel_threshold,
        traversal,
    };
    params
        .validate()
        .map_err(|e| LoadError::Corrupt(format!("parameters: {e}")))?;
    Ok(params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Vec3;
    use rt_testkit::scenes;

    use rt_testkit::rays::rays_through_unit_cube as rays;

    /// Every builder round-trips: the same answers bit for bit, the same bytes again.
    #[test]
    fn every_builder_round_trips_bit_for_bit() {
        let mut tris = scenes::random_soup(700, 3);
        // Triangles lying in planes the SAH splits at.
        tris.extend(scenes::triangle_scene("coplanar").prims);
        for params in [KdParams::sah(), KdParams::midpoint(), KdParams::centroid()] {
            for tris in [&tris[..], &tris[..1], &[]] {
                let kd = KdTree::build(tris, params).unwrap();
                let load = |b: &[u8]| KdTree::from_bytes(b, tris);
                rt_testkit::assert_round_trip(&kd, KdTree::to_bytes, load, &rays(2000));
            }
        }
    }

    /// Every conformance scene (slivers, shared edges and vertices, axis-aligned and
    /// coplanar sets, far coordinates) loads back as built under every builder: the checks
    /// refuse no tree the build makes.
    #[test]
    fn every_conformance_scene_loads_back() {
        for params in [KdParams::sah(), KdParams::midpoint(), KdParams::centroid()] {
            let build = |t: &[Triangle]| KdTree::build(t, params).unwrap();
            rt_testkit::assert_conformance_scenes_load(build, KdTree::to_bytes, KdTree::from_bytes);
        }
    }

    /// The loader fuzzer's finding (`fuzz/regressions/load_bvh`): an index entry no leaf lists,
    /// out of range, panicked laying out the leaves; it is refused for what it is.
    #[test]
    fn fuzz_findings_are_refused_for_their_fault() {
        let tris = scenes::tessellated_sphere(40, Vec3::ZERO, 1.0);
        let bytes = rt_testkit::fuzz_regression("load_bvh", "kd-unlisted-index-out-of-range");
        match KdTree::from_bytes(&bytes, &tris) {
            Err(LoadError::Corrupt(why)) => assert!(why.contains("index array"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    /// Damaged bytes are refused, never loaded wrong: every prefix, every byte changed (every
    /// eighth unless the long tests run), and a triangle dropped from a leaf (found by the
    /// coverage check alone).
    #[test]
    fn damage_is_refused() {
        let tris = scenes::random_soup(120, 5);
        let kd = KdTree::build(&tris, KdParams::sah()).unwrap();
        let bytes = kd.to_bytes();
        let brute = rt_geom::BruteForce::build(&tris).unwrap();
        let load = |b: &[u8]| KdTree::from_bytes(b, &tris);
        rt_testkit::assert_damage_refused(&bytes, load, &brute, &rays(300));
        assert_eq!(
            KdTree::from_bytes(&bytes, &tris[1..]).err(),
            Some(LoadError::OtherPrimitives)
        );
        // A leaf of several primitives loses one that other leaves list too (so that every
        // primitive is still listed somewhere): it now lists its neighbour twice.
        let listed = |p: u32| kd.indices.iter().filter(|&&q| q == p).count();
        let first = kd
            .nodes
            .iter()
            .filter_map(KdNode::list)
            .map(|(first, _)| first as usize)
            .find(|&f| listed(kd.indices[f]) > 1)
            .unwrap();
        let mut indices = kd.indices.to_vec();
        indices[first] = indices[first + 1];
        let dropped = KdTree::assemble(&tris, kd.nodes.to_vec(), indices, kd.frame, kd.params);
        let err = KdTree::from_bytes(&dropped.to_bytes(), &tris).unwrap_err();
        assert!(
            err.to_string().contains("not listed in every cell"),
            "{err}"
        );
    }
}
