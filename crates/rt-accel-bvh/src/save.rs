//! Saved structures: a built [`TriBvh`], [`WideBvh`] or [`Bvh`] as bytes and back, so that
//! a renderer builds a scene once. A plain little-endian layout, versioned:
//!
//! ```text
//! magic      8 bytes  "rt-bvh\r\n"
//! version    u32      1
//! layout     3 x u8   leaves (0: SoA triangles, 1: any primitives, 2: binary tree over any
//!                     primitives), lanes (4 or 8; 2 for the binary tree), node kind (0: exact
//!                     boxes, 1: quantized)
//! params     the build parameters (BvhParams), field by field; fields a variant does not
//!            use are zero
//! primitives u64 count, u64 hash: 64-bit FNV-1a over 32-bit words of every triangle vertex's
//!            coordinates (WideBvh, Bvh: of every primitive's box, all they depend on)
//! tree       wide: root box (6 f32), root leaf (u8 flag, u32 first, u32 count), then nodes;
//!            binary: nodes; nodes as a u64 count and each node field by field
//! ids        u64 count, u32 each: the caller's index of each primitive in leaf order
//! ```
//!
//! The primitives are not stored: `from_bytes` takes them again and checks them against the
//! hash, so a file cannot be loaded over other geometry. Loading checks the magic, the
//! version, the layout, every length against the bytes left, the topology of every node
//! before anything is indexed by it, each leaf's contents, the structure's own
//! [`Accel::validate`], and for spatial splits that every triangle is covered by the boxes
//! of its leaves (split structures over other primitives are refused): a truncated,
//! corrupted or foreign file is a [`LoadError`], never a panic or a wrong answer.
//!
//! ```
//! use rt_accel_bvh::TriBvh8;
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let bvh = TriBvh8::build_for_tracing(&tris).unwrap();
//! let bytes = bvh.to_bytes();
//! let loaded = TriBvh8::from_bytes(&bytes, &tris).unwrap();
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! assert_eq!(loaded.intersect(&ray), bvh.intersect(&ray));
//! // Other triangles, or damaged bytes, are refused.
//! assert!(TriBvh8::from_bytes(&bytes, &[Triangle::new(Vec3::ZERO, Vec3::Y, Vec3::X)]).is_err());
//! assert!(TriBvh8::from_bytes(&bytes[..bytes.len() - 1], &tris).is_err());
//! ```

use crate::compressed::CompressedNode;
use crate::refit::in_leaf_order;
use crate::wide::{NodeLayout, WideNode, WideTree};
use crate::{Bvh, BvhBuilder, BvhNode, BvhParams, TriBvh, WideBvh, WideCollapse};
use rt_geom::saved::{Reader as In, Writer as Out, covered, triangle_hash as hash};
use rt_geom::{Aabb, Accel, Isa, Primitive, Triangle, TriangleSoa, Vec3};

pub use rt_geom::saved::LoadError;

const MAGIC: &[u8; 8] = b"rt-bvh\r\n";
const VERSION: u32 = 1;

/// A node layout's fields as bytes.
pub trait SavedNode: Sized {
    /// The node kind byte of the format.
    const KIND: u8;
    /// Bytes per node in the format.
    const SIZE: usize;
    /// Writes the node.
    #[doc(hidden)]
    fn write(&self, out: &mut Vec<u8>);
    /// Reads a node.
    #[doc(hidden)]
    fn read(bytes: &[u8; 256]) -> Self;
}

impl<const N: usize> SavedNode for WideNode<N> {
    const KIND: u8 = 0;
    const SIZE: usize = 32 * N;

    fn write(&self, out: &mut Vec<u8>) {
        let planes = self.min.iter().chain(&self.max).flatten();
        out.extend(planes.flat_map(|x| x.to_bits().to_le_bytes()));
        out.extend(
            self.child
                .iter()
                .chain(&self.count)
                .flat_map(|x| x.to_le_bytes()),
        );
    }

    fn read(b: &[u8; 256]) -> Self {
        let word =
            |i: usize| u32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]]);
        let mut n = WideNode::<N>::EMPTY;
        for a in 0..3 {
            for l in 0..N {
                n.min[a][l] = f32::from_bits(word(a * N + l));
                n.max[a][l] = f32::from_bits(word((3 + a) * N + l));
            }
        }
        for l in 0..N {
            n.child[l] = word(6 * N + l);
            n.count[l] = word(7 * N + l);
        }
        n
    }
}

impl SavedNode for CompressedNode {
    const KIND: u8 = 1;
    const SIZE: usize = 12 + 3 + 1 + 48 + 64;

    fn write(&self, out: &mut Vec<u8>) {
        out.extend(self.origin.iter().flat_map(|x| x.to_bits().to_le_bytes()));
        out.extend(self.exponent);
        out.push(self.used);
        out.extend(self.qmin.iter().chain(&self.qmax).flatten());
        out.extend(
            self.child
                .iter()
                .chain(&self.count)
                .flat_map(|x| x.to_le_bytes()),
        );
    }

    fn read(b: &[u8; 256]) -> Self {
        let word = |at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let byte8 = |at: usize| -> [u8; 8] { std::array::from_fn(|l| b[at + l]) };
        CompressedNode {
            origin: std::array::from_fn(|a| f32::from_bits(word(4 * a))),
            exponent: [b[12], b[13], b[14]],
            used: b[15],
            qmin: std::array::from_fn(|a| byte8(16 + 8 * a)),
            qmax: std::array::from_fn(|a| byte8(40 + 8 * a)),
            child: std::array::from_fn(|l| word(64 + 4 * l)),
            count: std::array::from_fn(|l| word(96 + 4 * l)),
        }
    }
}

/// With spatial splits a triangle may lie in several leaves, each holding a part of it, and
/// `validate` only asks each leaf to overlap its triangles: here every triangle that can be
/// hit is asked to be covered by the union of its leaves' boxes (`boxes[id]`, as the walk
/// sees them, intersected down the path), so that no part of it is out of every leaf the
/// walk enters.
fn check_coverage(tris: &[Triangle], boxes: &[Vec<Aabb>]) -> Result<(), String> {
    use rayon::prelude::*;
    let uncovered = (0..tris.len())
        .into_par_iter()
        .find_first(|&i| !tris[i].is_degenerate() && !covered(&tris[i], &boxes[i]));
    match uncovered {
        Some(id) => Err(format!("triangle {id} is not covered by its leaves")),
        None => Ok(()),
    }
}

fn write_params(out: &mut Out, p: &BvhParams) {
    let (builder, bins) = match p.builder {
        BvhBuilder::Midpoint => (0, 0),
        BvhBuilder::Median => (1, 0),
        BvhBuilder::BinnedSah { bins } => (2, bins),
        BvhBuilder::SweepSah => (3, 0),
    };
    out.u8(builder);
    out.u32(bins);
    out.u32(p.max_leaf_size);
    out.f32(p.traversal_cost);
    out.f32(p.intersection_cost);
    out.u64(p.parallel_threshold as u64);
    out.u8(p.spatial_alpha.is_some() as u8);
    out.f32(p.spatial_alpha.unwrap_or(0.0));
    out.f32(p.spatial_budget);
    out.u32(p.leaf_block);
    let (collapse, above) = match p.collapse {
        WideCollapse::LargestArea => (0, 0.0),
        WideCollapse::Sah => (1, 0.0),
        WideCollapse::LargestAreaThenSah { above } => (2, above),
    };
    out.u8(collapse);
    out.f32(above);
    out.f32(p.reinsertion);
}

fn read_params(r: &mut In) -> Result<BvhParams, LoadError> {
    let corrupt = |what: &str| LoadError::Corrupt(format!("unknown {what}"));
    // Fields a variant does not use are written as zeros and must read as zeros: one
    // structure, one encoding.
    let unused = |bits: u32| {
        if bits == 0 {
            Ok(())
        } else {
            Err(corrupt("non-zero unused field"))
        }
    };
    let (builder, bins) = (r.u8()?, r.u32()?);
    let builder = match builder {
        0 => BvhBuilder::Midpoint,
        1 => BvhBuilder::Median,
        2 => BvhBuilder::BinnedSah { bins },
        3 => BvhBuilder::SweepSah,
        _ => return Err(corrupt("builder")),
    };
    if builder != (BvhBuilder::BinnedSah { bins }) {
        unused(bins)?;
    }
    let max_leaf_size = r.u32()?;
    let (traversal_cost, intersection_cost) = (r.f32()?, r.f32()?);
    let parallel_threshold = usize::try_from(r.u64()?).map_err(|_| corrupt("threshold"))?;
    let (spatial, alpha) = (r.u8()?, r.f32()?);
    let spatial_alpha = match spatial {
        0 => unused(alpha.to_bits()).map(|()| None)?,
        1 => Some(alpha),
        _ => return Err(corrupt("spatial flag")),
    };
    let spatial_budget = r.f32()?;
    let leaf_block = r.u32()?;
    let (collapse, above) = (r.u8()?, r.f32()?);
    let collapse = match collapse {
        0 => unused(above.to_bits()).map(|()| WideCollapse::LargestArea)?,
        1 => unused(above.to_bits()).map(|()| WideCollapse::Sah)?,
        2 => WideCollapse::LargestAreaThenSah { above },
        _ => return Err(corrupt("collapse")),
    };
    let params = BvhParams {
        builder,
        max_leaf_size,
        traversal_cost,
        intersection_cost,
        parallel_threshold,
        spatial_alpha,
        spatial_budget,
        leaf_block,
        collapse,
        reinsertion: r.f32()?,
    };
    params
        .validate()
        .map_err(|e| LoadError::Corrupt(format!("parameters: {e}")))?;
    Ok(params)
}

/// The family byte of the format: what the leaves hold.
const TRIANGLES: u8 = 0;
const PRIMITIVES: u8 = 1;
const BINARY: u8 = 2;

/// What [`write_tree`] writes and [`read_tree`] reads: everything but the leaves' contents.
struct Saved<const N: usize, Node> {
    params: BvhParams,
    tree: WideTree<N, Node>,
    ids: Vec<u32>,
}

/// The header, the parameters, the primitives' count and `hash`, the tree and the ids.
fn write_tree<const N: usize, Node: SavedNode>(
    family: u8,
    params: &BvhParams,
    (count, hash): (usize, u64),
    tree: &WideTree<N, Node>,
    ids: &[u32],
) -> Vec<u8> {
    let mut out = Out::default();
    write_header(
        &mut out,
        (family, N as u8, Node::KIND),
        params,
        (count, hash),
    );
    let b = &tree.root_bounds;
    for x in b.min.to_array().into_iter().chain(b.max.to_array()) {
        out.f32(x);
    }
    let (flag, first, leaf) = tree.root_leaf.map_or((0, 0, 0), |(f, c)| (1, f, c));
    out.u8(flag);
    out.u32(first);
    out.u32(leaf);
    out.u64(tree.nodes.len() as u64);
    for n in &tree.nodes {
        n.write(&mut out.0);
    }
    out.u64(ids.len() as u64);
    for &id in ids {
        out.u32(id);
    }
    out.0
}

/// Checks the magic, the version and the layout `expected`, reads the parameters, and checks
/// the primitives' `count` and `hash`.
fn read_header(
    r: &mut In,
    expected: (u8, u8, u8),
    (count, hash): (usize, u64),
) -> Result<BvhParams, LoadError> {
    r.header(MAGIC, VERSION)?;
    let layout = (r.u8()?, r.u8()?, r.u8()?);
    if layout != expected {
        return Err(LoadError::Layout {
            found: layout,
            expected,
        });
    }
    let params = read_params(r)?;
    r.primitives((count, hash))?;
    Ok(params)
}

/// Writes the header: magic, version, layout, parameters, the primitives' count and hash.
fn write_header(
    out: &mut Out,
    layout: (u8, u8, u8),
    params: &BvhParams,
    (count, hash): (usize, u64),
) {
    out.header(MAGIC, VERSION);
    out.u8(layout.0);
    out.u8(layout.1);
    out.u8(layout.2);
    write_params(out, params);
    out.primitives((count, hash));
}

/// Reads what [`write_tree`] wrote for `count` primitives of hash `hash`, and checks the
/// topology (every node's lanes, reached or not; children after parents; depth bounded;
/// leaves inside the id list; ids naming primitives) before anything is indexed by it.
fn read_tree<const N: usize, Node: NodeLayout<N> + SavedNode>(
    bytes: &[u8],
    family: u8,
    (count, hash): (usize, u64),
) -> Result<Saved<N, Node>, LoadError> {
    let mut r = In(bytes);
    let params = read_header(&mut r, (family, N as u8, Node::KIND), (count, hash))?;
    let mut corners = [0.0f32; 6];
    for c in &mut corners {
        *c = r.f32()?;
    }
    let root_bounds = Aabb::new(
        Vec3::new(corners[0], corners[1], corners[2]),
        Vec3::new(corners[3], corners[4], corners[5]),
    );
    let (flag, first, leaf_count) = (r.u8()?, r.u32()?, r.u32()?);
    let root_leaf = match (flag, first, leaf_count) {
        (0, 0, 0) => None,
        (1, ..) => Some((first, leaf_count)),
        (0, ..) => {
            return Err(LoadError::Corrupt(
                "non-zero unused field (root leaf)".into(),
            ));
        }
        _ => return Err(LoadError::Corrupt("unknown root leaf flag".into())),
    };
    let nodes: Vec<Node> = (0..r.count(Node::SIZE)?)
        .map(|_| {
            let mut b = [0u8; 256];
            let (head, rest) = r.0.split_at(Node::SIZE);
            b[..Node::SIZE].copy_from_slice(head);
            r.0 = rest;
            Node::read(&b)
        })
        .collect();
    let ids: Vec<u32> = (0..r.count(4)?)
        .map(|_| r.u32())
        .collect::<Result<_, _>>()?;
    if !r.0.is_empty() {
        return Err(LoadError::TrailingBytes);
    }
    let mut tree: WideTree<N, Node> = WideTree {
        nodes: rt_geom::pages::Pages::from(nodes),
        root_bounds,
        root_leaf,
        depth: 0,
        isa: Isa::selected(),
    };
    let corrupt = |e: String| LoadError::Corrupt(e);
    let slots = ids.len() as u64;
    let in_range = |first: u32, count: u32, _: &Aabb| {
        if first as u64 + count as u64 <= slots {
            Ok(())
        } else {
            Err(format!("leaf {first}+{count} runs past the {slots} ids"))
        }
    };
    tree.depth = tree.check(in_range).map_err(corrupt)?;
    // Nodes the root does not reach are never walked, but their leaves are laid out too.
    for (i, n) in tree.nodes.iter().enumerate() {
        for lane in (0..N).filter(|&l| n.is_used(l)) {
            let (child, leaf) = (n.child(lane), n.count(lane));
            let fits = if leaf > 0 {
                child as u64 + leaf as u64 <= slots
            } else {
                (child as usize) > i && (child as usize) < tree.nodes.len()
            };
            if !fits {
                return Err(corrupt(format!("node {i} lane {lane} points out of range")));
            }
        }
    }
    if let Some(&id) = ids.iter().find(|&&i| i as usize >= count) {
        return Err(corrupt(format!("id {id} of {count} primitives")));
    }
    Ok(Saved { params, tree, ids })
}

impl<const N: usize, Node: NodeLayout<N> + SavedNode> TriBvh<N, Node> {
    /// The structure as bytes (the [format](crate::save)); the triangles are not included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let hash = hash(&self.caller_triangles());
        write_tree(
            TRIANGLES,
            &self.params,
            (self.count, hash),
            &self.tree,
            &self.ids,
        )
    }

    /// The structure [`Self::to_bytes`] saved, over the same `tris` it was built over (checked
    /// by hash), checked as the [module](crate::save) says; its queries answer bit for bit as
    /// the saved structure's did, with the same kernel ([`Self::with_kernel`]: a choice of
    /// the queries, like the instruction set, not saved; the watertight one by default).
    pub fn from_bytes(bytes: &[u8], tris: &[Triangle]) -> Result<Self, LoadError> {
        let Saved { params, tree, ids } =
            read_tree::<N, Node>(bytes, TRIANGLES, (tris.len(), hash(tris)))?;
        let corrupt = |e: String| LoadError::Corrupt(e);
        let leaf_tris = in_leaf_order(tris, &ids);
        let soa = TriangleSoa::new(&leaf_tris, tree.leaves());
        // Each leaf tests exactly the triangles its ids name (leaves laid over each other
        // would not).
        for (first, count) in tree.leaves() {
            let (first, count) = (first as usize, count as usize);
            if (0..count).any(|k| soa.get(first, count, k) != leaf_tris[first + k]) {
                return Err(corrupt(format!("leaf {first}+{count} overlaps another")));
            }
        }
        let bvh = Self::assemble(tree, soa, ids.into(), tris.len(), params);
        bvh.validate().map_err(corrupt)?;
        if params.splits_primitives() {
            let boxes = wide_leaf_boxes(&bvh.tree, &bvh.ids, tris.len()).map_err(corrupt)?;
            check_coverage(tris, &boxes).map_err(corrupt)?;
        }
        Ok(bvh)
    }
}

impl<P: Primitive, const N: usize, Node: NodeLayout<N> + SavedNode> WideBvh<P, N, Node> {
    /// The structure as bytes (the [format](crate::save)); the primitives are not included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let hash = caller_bounds_hash(&self.prims, &self.ids, self.count);
        write_tree(
            PRIMITIVES,
            &self.params,
            (self.count, hash),
            &self.tree,
            &self.ids,
        )
    }

    /// The structure [`Self::to_bytes`] saved, over primitives with the same boxes as those
    /// it was built over (checked by hash: the structure depends on nothing else), checked as
    /// the [module](crate::save) says. Spatial splits are checked for triangles only (the
    /// coverage of a split primitive by its leaves): a split structure over other primitives
    /// is refused.
    pub fn from_bytes(bytes: &[u8], prims: &[P]) -> Result<Self, LoadError> {
        let Saved { params, tree, ids } =
            read_tree::<N, Node>(bytes, PRIMITIVES, (prims.len(), bounds_hash(prims)))?;
        let corrupt = |e: String| LoadError::Corrupt(e);
        let leaf_prims = in_leaf_order(prims, &ids).into();
        let bvh = Self::assemble(tree, leaf_prims, ids.into(), prims.len(), params);
        bvh.validate().map_err(corrupt)?;
        if params.splits_primitives() {
            let boxes = wide_leaf_boxes(&bvh.tree, &bvh.ids, prims.len()).map_err(corrupt)?;
            check_coverage(&split_triangles(prims)?, &boxes).map_err(corrupt)?;
        }
        Ok(bvh)
    }
}

impl<P: Primitive> Bvh<P> {
    /// The structure as bytes (the [format](crate::save): layout family 2, two lanes, the
    /// 32-byte nodes field by field where the wide trees have theirs); the primitives are not
    /// included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let hash = caller_bounds_hash(&self.prims, &self.ids, self.count);
        let mut out = Out::default();
        write_header(&mut out, (BINARY, 2, 0), &self.params, (self.count, hash));
        out.u64(self.nodes.len() as u64);
        for n in &self.nodes {
            n.min.iter().for_each(|&x| out.f32(x));
            out.u32(n.offset);
            n.max.iter().for_each(|&x| out.f32(x));
            out.u32(n.meta);
        }
        out.u64(self.ids.len() as u64);
        self.ids.iter().for_each(|&id| out.u32(id));
        out.0
    }

    /// The structure [`Self::to_bytes`] saved, over primitives with the same boxes as those
    /// it was built over, checked as [`WideBvh::from_bytes`] checks its own.
    pub fn from_bytes(bytes: &[u8], prims: &[P]) -> Result<Self, LoadError> {
        let mut r = In(bytes);
        let params = read_header(&mut r, (BINARY, 2, 0), (prims.len(), bounds_hash(prims)))?;
        let nodes: Vec<BvhNode> = (0..r.count(32)?)
            .map(|_| read_node(&mut r))
            .collect::<Result<_, _>>()?;
        let ids: Vec<u32> = (0..r.count(4)?)
            .map(|_| r.u32())
            .collect::<Result<_, _>>()?;
        if !r.0.is_empty() {
            return Err(LoadError::TrailingBytes);
        }
        let corrupt = |e: String| LoadError::Corrupt(e);
        if let Some(&id) = ids.iter().find(|&&i| i as usize >= prims.len()) {
            return Err(corrupt(format!("id {id} of {} primitives", prims.len())));
        }
        let bvh = Bvh {
            nodes: nodes.into(),
            prims: in_leaf_order(prims, &ids).into(),
            ids: ids.into(),
            count: prims.len(),
            params,
            isa: Isa::selected(),
        };
        bvh.validate().map_err(corrupt)?;
        if params.splits_primitives() {
            check_coverage(&split_triangles(prims)?, &bvh.leaf_boxes()).map_err(corrupt)?;
        }
        Ok(bvh)
    }

    /// Per primitive, the boxes of the leaves that list it, each intersected with the boxes
    /// on its way down (what the walk tests before it reaches the leaf). The tree must have
    /// passed `validate()`.
    fn leaf_boxes(&self) -> Vec<Vec<Aabb>> {
        let mut boxes = vec![Vec::new(); self.count];
        if self.nodes.is_empty() {
            return boxes;
        }
        let mut stack = vec![(0usize, Aabb::new(Vec3::NEG_INFINITY, Vec3::INFINITY))];
        while let Some((i, above)) = stack.pop() {
            let n = &self.nodes[i];
            let b = n.bounds().intersection(above);
            if n.is_leaf() {
                let first = n.offset as usize;
                for &id in &self.ids[first..first + n.count() as usize] {
                    boxes[id as usize].push(b);
                }
            } else {
                stack.push((i + 1, b));
                stack.push((n.offset as usize, b));
            }
        }
        boxes
    }
}

/// A node of the binary layout, field by field.
fn read_node(r: &mut In) -> Result<BvhNode, LoadError> {
    Ok(BvhNode {
        min: [r.f32()?, r.f32()?, r.f32()?],
        offset: r.u32()?,
        max: [r.f32()?, r.f32()?, r.f32()?],
        meta: r.u32()?,
    })
}

/// [`bounds_hash`] of the primitives in the caller's order, from the leaf-ordered `prims`
/// and their `ids` (each once, wherever a spatial split listed it twice).
fn caller_bounds_hash<P: Primitive>(prims: &[P], ids: &[u32], count: usize) -> u64 {
    let mut caller: Vec<Option<&P>> = vec![None; count];
    for (p, &id) in prims.iter().zip(ids) {
        caller[id as usize] = Some(p);
    }
    bounds_hash(caller.into_iter().flatten())
}

/// Per primitive, the boxes of the wide tree's leaves that list it, each intersected with
/// the boxes on its way down (what the walk tests before it reaches the leaf).
fn wide_leaf_boxes<const N: usize, Node: NodeLayout<N>>(
    tree: &WideTree<N, Node>,
    ids: &[u32],
    count: usize,
) -> Result<Vec<Vec<Aabb>>, String> {
    let mut boxes = vec![Vec::new(); count];
    tree.check(|first, n, bounds| {
        for &id in &ids[first as usize..(first + n) as usize] {
            boxes[id as usize].push(*bounds);
        }
        Ok(())
    })?;
    Ok(boxes)
}

/// The primitives as triangles, whose coverage by split leaves can be checked; a split
/// structure over other primitives is refused.
fn split_triangles<P: Primitive>(prims: &[P]) -> Result<Vec<Triangle>, LoadError> {
    prims
        .iter()
        .map(|p| p.as_triangle().copied())
        .collect::<Option<_>>()
        .ok_or_else(|| {
            LoadError::Corrupt("spatial splits over primitives other than triangles".into())
        })
}

/// A hash of the primitives' boxes ([`hash`]'s words: the count, then each box's corners).
fn bounds_hash<'a, P: Primitive>(prims: impl IntoIterator<Item = &'a P>) -> u64 {
    let boxes: Vec<Triangle> = prims
        .into_iter()
        .map(|p| {
            let b = p.bounds();
            Triangle::new(b.min, b.max, Vec3::ZERO)
        })
        .collect();
    hash(&boxes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CompressedTriBvh8, TriBvh4, TriBvh8};
    use rt_geom::{BruteForce, Ray};
    use rt_testkit::scenes;

    use rt_testkit::rays::rays_through_unit_cube as rays;

    /// Answers bit for bit those of `reference` on `rays`.
    fn same_answers(a: &dyn Accel, reference: &dyn Accel, rays: &[Ray]) -> bool {
        let key = |h: Option<rt_geom::Hit>| {
            h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim))
        };
        rays.iter().all(|r| {
            key(a.intersect(r)) == key(reference.intersect(r))
                && a.occluded(r) == reference.occluded(r)
        })
    }

    fn round_trip<const N: usize, Node: NodeLayout<N> + SavedNode>(
        bvh: TriBvh<N, Node>,
        tris: &[Triangle],
    ) {
        let bytes = bvh.to_bytes();
        let loaded = TriBvh::<N, Node>::from_bytes(&bytes, tris).unwrap();
        assert!(same_answers(&loaded, &bvh, &rays(3000)));
        assert_eq!(loaded.stats(), bvh.stats());
        assert_eq!(loaded.to_bytes(), bytes);
    }

    #[test]
    fn every_layout_and_preset_round_trips_bit_for_bit() {
        let tris = scenes::random_soup(700, 3);
        round_trip(TriBvh8::build_for_tracing(&tris).unwrap(), &tris);
        // Spatial splits list a triangle in several leaves.
        round_trip(
            TriBvh8::build(&tris, BvhParams::spatial().for_soa_leaves()).unwrap(),
            &tris,
        );
        round_trip(TriBvh4::build(&tris, BvhParams::balanced()).unwrap(), &tris);
        round_trip(
            CompressedTriBvh8::build(&tris, BvhParams::balanced()).unwrap(),
            &tris,
        );
        // A single leaf, and nothing.
        round_trip(TriBvh8::build_for_tracing(&tris[..3]).unwrap(), &tris[..3]);
        round_trip(TriBvh8::build_for_tracing(&[]).unwrap(), &[]);
    }

    /// Every conformance scene (slivers, shared edges and vertices, axis-aligned and
    /// coplanar sets, far coordinates) loads back as built with spatial splits, whose
    /// coverage check is the strictest: the checks refuse no tree the build makes.
    #[test]
    fn every_conformance_scene_loads_back() {
        let spatial = BvhParams::spatial().for_soa_leaves();
        let build = |t: &[Triangle]| TriBvh8::build(t, spatial).unwrap();
        rt_testkit::assert_conformance_scenes_load(build, TriBvh8::to_bytes, TriBvh8::from_bytes);
    }

    /// Wide BVHs over any primitive: spheres, mixed shapes, every layout; spatial splits of
    /// triangles load (their coverage is checked), of other primitives are refused.
    #[test]
    fn wide_bvhs_over_any_primitive_round_trip() {
        use crate::{Bvh4, Bvh8, CompressedBvh8};
        fn again<P: Primitive, const N: usize, Node: NodeLayout<N> + SavedNode>(
            bvh: WideBvh<P, N, Node>,
            prims: &[P],
        ) -> Result<(), LoadError> {
            let bytes = bvh.to_bytes();
            let loaded = WideBvh::<P, N, Node>::from_bytes(&bytes, prims)?;
            assert!(same_answers(&loaded, &bvh, &rays(2000)));
            assert_eq!(loaded.to_bytes(), bytes);
            Ok(())
        }
        let spheres = scenes::random_spheres(300, 5);
        let shapes = scenes::mixed_shapes(300, 6);
        let tris = scenes::random_soup(300, 7);
        let balanced = BvhParams::balanced();
        again(Bvh8::build(&spheres, balanced).unwrap(), &spheres).unwrap();
        again(Bvh4::build(&shapes, balanced).unwrap(), &shapes).unwrap();
        again(CompressedBvh8::build(&shapes, balanced).unwrap(), &shapes).unwrap();
        again(Bvh8::build(&tris, BvhParams::spatial()).unwrap(), &tris).unwrap();
        let split_shapes = Bvh8::build(&shapes, BvhParams::spatial()).unwrap();
        assert!(matches!(
            again(split_shapes, &shapes),
            Err(LoadError::Corrupt(_))
        ));
        // Primitives with other boxes are refused; the triangle family is another layout.
        let bytes = Bvh8::build(&spheres, balanced).unwrap().to_bytes();
        let mut moved = spheres.clone();
        moved[3].radius *= 2.0;
        let err = Bvh8::from_bytes(&bytes, &moved).unwrap_err();
        assert_eq!(err, LoadError::OtherPrimitives);
        let tri_bytes = TriBvh8::build_for_tracing(&tris).unwrap().to_bytes();
        let err = Bvh8::from_bytes(&tri_bytes, &tris).unwrap_err();
        assert!(matches!(err, LoadError::Layout { .. }));
    }

    /// Binary BVHs over any primitive round trip; a damaged one is refused or harmless, never
    /// a panic or a hang (children pointing backwards, a split axis past z).
    #[test]
    fn binary_bvhs_round_trip_and_refuse_damage() {
        use crate::Bvh;
        let shapes = scenes::mixed_shapes(200, 8);
        let tris = scenes::random_soup(200, 9);
        for (bvh, prims) in [
            (Bvh::build(&shapes, BvhParams::balanced()).unwrap(), &shapes),
            (Bvh::build(&shapes, BvhParams::quality()).unwrap(), &shapes),
        ] {
            let bytes = bvh.to_bytes();
            let loaded = Bvh::from_bytes(&bytes, prims).unwrap();
            assert!(same_answers(&loaded, &bvh, &rays(2000)));
            assert_eq!(loaded.to_bytes(), bytes);
        }
        let split = Bvh::build(&tris, BvhParams::spatial()).unwrap();
        let loaded = Bvh::from_bytes(&split.to_bytes(), &tris).unwrap();
        assert!(same_answers(&loaded, &split, &rays(2000)));
        let brute = BruteForce::build(&shapes).unwrap();
        let bytes = Bvh::build(&shapes, BvhParams::balanced())
            .unwrap()
            .to_bytes();
        let rays = rays(200);
        // Three bits of every byte with `RT_LONG_TESTS=1`, else one of them in turn.
        let (long, bits) = (rt_testkit::long_tests(), [0, 5, 7]);
        for at in 0..bytes.len() {
            let bits = if long {
                &bits[..]
            } else {
                &bits[at % 3..][..1]
            };
            for &bit in bits {
                let mut b = bytes.clone();
                b[at] ^= 1 << bit;
                if let Ok(a) = Bvh::from_bytes(&b, &shapes) {
                    assert!(same_answers(&a, &brute, &rays), "byte {at} bit {bit}");
                }
            }
        }
    }

    /// The loader fuzzer's findings (`fuzz/regressions/load_bvh`), each refused for what it
    /// is: a second encoding of the parameters, a spatial-split triangle its leaves no longer
    /// cover (wrong answers before), a leaf in a node the root does not reach (a panic
    /// before), binary trees without nodes.
    #[test]
    fn fuzz_findings_are_refused_for_their_fault() {
        let tris = scenes::tessellated_sphere(40, Vec3::ZERO, 1.0);
        for (file, fault) in [
            ("non-canonical-params", "unused field"),
            ("wrong-answer-1", "not covered"),
            ("unreachable-node-leaf", "out of range"),
        ] {
            let bytes = rt_testkit::fuzz_regression("load_bvh", file);
            match TriBvh8::from_bytes(&bytes, &tris) {
                Err(LoadError::Corrupt(why)) => assert!(why.contains(fault), "{file}: {why}"),
                other => panic!("{file}: {other:?}"),
            }
        }
        // Binary trees without nodes for a non-empty scene: it answered nothing, and with
        // spatial-split parameters its coverage check panicked.
        for file in ["no-nodes-for-primitives", "empty-binary-split"] {
            let bytes = rt_testkit::fuzz_regression("load_bvh", file);
            match crate::Bvh::from_bytes(&bytes, &tris) {
                Err(LoadError::Corrupt(why)) => assert!(why.contains("no nodes"), "{file}: {why}"),
                other => panic!("{file}: {other:?}"),
            }
        }
    }

    #[test]
    fn foreign_bytes_other_triangles_and_other_layouts_are_refused() {
        let tris = scenes::random_soup(50, 4);
        let bytes = TriBvh8::build_for_tracing(&tris).unwrap().to_bytes();
        assert_eq!(
            TriBvh8::from_bytes(b"hello", &tris).unwrap_err(),
            LoadError::NotASavedStructure
        );
        let mut moved = tris.clone();
        moved[7].v[1].x += 1e-3;
        assert_eq!(
            TriBvh8::from_bytes(&bytes, &moved).unwrap_err(),
            LoadError::OtherPrimitives
        );
        assert_eq!(
            TriBvh8::from_bytes(&bytes, &tris[1..]).unwrap_err(),
            LoadError::OtherPrimitives
        );
        assert!(matches!(
            TriBvh4::from_bytes(&bytes, &tris),
            Err(LoadError::Layout { .. })
        ));
        assert!(matches!(
            CompressedTriBvh8::from_bytes(&bytes, &tris),
            Err(LoadError::Layout { .. })
        ));
        let mut newer = bytes.clone();
        newer[8] = 2;
        assert_eq!(
            TriBvh8::from_bytes(&newer, &tris).unwrap_err(),
            LoadError::Version { found: 2 }
        );
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(
            TriBvh8::from_bytes(&longer, &tris).unwrap_err(),
            LoadError::TrailingBytes
        );
    }

    /// Every truncation is refused; every byte changed (each bit of it, in turn) is refused
    /// or loads a structure that still answers as brute force: never a panic, never a wrong
    /// answer.
    #[test]
    fn truncated_and_corrupted_bytes_are_refused_or_harmless() {
        let tris = scenes::random_soup(40, 5);
        let brute = BruteForce::build(&tris).unwrap();
        let rays = rays(300);
        for bvh_bytes in [
            TriBvh8::build_for_tracing(&tris).unwrap().to_bytes(),
            CompressedTriBvh8::build(&tris, BvhParams::balanced())
                .unwrap()
                .to_bytes(),
        ] {
            let compressed = bvh_bytes[14] == 1;
            let load = |b: &[u8]| -> Result<Box<dyn Accel>, LoadError> {
                if compressed {
                    Ok(Box::new(CompressedTriBvh8::from_bytes(b, &tris)?))
                } else {
                    Ok(Box::new(TriBvh8::from_bytes(b, &tris)?))
                }
            };
            for len in 0..bvh_bytes.len() {
                assert!(load(&bvh_bytes[..len]).is_err(), "{len} bytes loaded");
            }
            let (mut refused, mut harmless) = (0, 0);
            for at in 0..bvh_bytes.len() {
                for bit in [0, 3, 7] {
                    let mut b = bvh_bytes.clone();
                    b[at] ^= 1 << bit;
                    match load(&b) {
                        Err(_) => refused += 1,
                        Ok(a) => {
                            assert!(
                                same_answers(a.as_ref(), &brute, &rays),
                                "byte {at} bit {bit}"
                            );
                            harmless += 1;
                        }
                    }
                }
            }
            assert!(
                refused > harmless / 4,
                "{refused} refused, {harmless} harmless"
            );
        }
    }
}
