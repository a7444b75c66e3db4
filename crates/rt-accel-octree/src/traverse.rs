//! Both walks. Each octant's box is the same `octant()` of its parent that the build used,
//! and both skip an octant whose content box (the min/max information its parent stores,
//! see [`crate::node`]) the ray does not enter, or enters beyond the closest hit.
//!
//! - `recursive`: the classic walk. At an inner node, every non-empty octant whose content box
//!   the ray enters (the padded box test, one octant at a time) is collected with its entry
//!   distance, the list is sorted, and the octants are visited nearest first; octants
//!   entered beyond the closest hit are skipped.
//! - `parametric` (Revelles, Ureña & Lastra 2000): per axis, the distances to the node's two
//!   planes and to its centre plane; along an axis an octant's interval is `[t(lo), t(mid)]`
//!   or `[t(mid), t(hi)]` (swapped for a negative direction), so the eight octant intervals
//!   follow from per-axis parameters, not from eight box tests. Revelles' walk steps from
//!   the first octant (from the entry plane) to the next (across the smallest exit) with
//!   data-dependent branches; here the eight intervals are evaluated at once in SIMD lanes
//!   and the octants left are the ones the sequence visits, taken in the order the sequence
//!   takes them: in the mirrored frame where every direction is positive (octant numbers
//!   XOR-ed with the direction's sign mask), each step crosses one more centre plane, so
//!   the sequence orders octants by the number of bits set. The planes are those of the
//!   octants' content boxes (read from the parent's one cache line): a content box lies
//!   inside its octant (up to 1/254 of the side), so it narrows Revelles' interval to its
//!   own, and an octant holding its whole cell has Revelles' planes exactly (code 0 is the
//!   low plane, 254 the high one, see [`crate::node`]); computing the octant's slab too
//!   would narrow nothing further. The parameters are computed afresh at each node from the cell's coordinates
//!   (not averaged from the parent's, so they are exactly the build's planes); NaN (a ray
//!   lying in a plane) leaves an interval unchanged, as in the box test, and each interval
//!   is padded like the box test. No sorting: one octant entered is walked next with no
//!   stack traffic, several are pushed far to near.
//!
//! With [`OctreeParams::mailbox`](crate::OctreeParams::mailbox), both walks keep a per-ray
//! mailbox of the last 8 primitives tested, so that a primitive listed in several leaves
//! along the ray is tested once; without, a repeat is tested again (same answer).

use crate::MAX_DEPTH;
use crate::Octree;
use crate::node::{ChildRef, OctNode, content_box, content_step, octant, octant_at};
use rt_geom::aabb::{PAD, SlabRay};
use rt_geom::{Aabb, Hit, Keep, Mailbox, Primitive, Ray, Vec3};
use wide::{CmpGt, CmpLe, CmpLt, CmpNe, f32x8, i32x8, u8x16, u16x8};

struct Walk<'a, P, K> {
    tree: &'a Octree<P>,
    origin: [f32; 3],
    /// Per axis, the reciprocal direction for planes met as a cell's lower and upper plane,
    /// with the box test's padding folded in ([`SlabRay`]: the near one scaled by `1 - PAD`,
    /// the far one by `1 + PAD`; both plain when `pad_after`).
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    /// The intervals are padded after the planes (rays with `tmin < 0`, see [`SlabRay`]).
    pad_after: bool,
    /// Per axis: the ray runs towards -a.
    neg: [bool; 3],
    /// Bit `k`: the `k`-th octant of Revelles' sequence (see [`SEQUENCE_MASKS`]), by the
    /// mask of real octants; the ray's row of the table.
    sequence: &'static [u8; 256],
    /// The real octant of step `k` of the sequence: `SEQUENCE_ORDER[k] ^ mirror`, where bit
    /// `a` of `mirror` is set when the ray runs towards -a (octant bits mirrored).
    octant_at_step: [u8; 8],
    /// Per axis, the lanes (octants) in the upper half along it.
    upper_half: [f32x8; 3],
    /// The ray's reciprocal direction (the recursive walk's box tests).
    inv: [f32; 3],
    ray: Ray,
    best: K,
    /// With `params.mailbox`: primitives listed in several leaves are tested once per ray.
    mailbox: Mailbox<8>,
}

impl<P: Primitive, K: Keep> Walk<'_, P, K> {
    /// Tests leaf `i`; true when `ANY_HIT` and something was hit.
    #[inline(always)]
    fn leaf<const ANY_HIT: bool>(&mut self, i: usize) -> bool {
        let tree = self.tree;
        let leaf = tree.leaves[i];
        let places = (leaf.first as usize, leaf.count as usize);
        let (ray, best) = (&mut self.ray, &mut self.best);
        // Two instances: without mailboxes, no per-primitive question at all.
        if tree.params.mailbox {
            let mailbox = &mut self.mailbox;
            let seen = |p| mailbox.seen(p);
            tree.leaf_prims
                .test_on::<ANY_HIT, K>(tree.isa, places, &tree.indices, ray, best, seen)
        } else {
            let isa = tree.isa;
            tree.leaf_prims
                .test_on::<ANY_HIT, K>(isa, places, &tree.indices, ray, best, |_| false)
        }
    }

    /// True when a pending part of the ray entered at `t` cannot hold a closer hit.
    #[inline]
    fn beyond(&self, t: f32) -> bool {
        // The leaf test lowers `ray.tmax` to every hit it keeps.
        t > self.ray.tmax
    }

    fn recursive<const ANY_HIT: bool>(&mut self, r: ChildRef, cell: &Aabb) -> bool {
        rt_geom::counters::nodes(1);
        if r.is_leaf() {
            return self.leaf::<ANY_HIT>(r.index());
        }
        let node = &self.tree.nodes[r.index()];
        let mut entered: [(f32, ChildRef, Aabb); 8] = [(0.0, r, Aabb::EMPTY); 8];
        let mut count = 0;
        let step = content_step(cell);
        for o in 0..8 {
            if let Some(child) = node.child(o) {
                let b = octant(cell, o);
                let content = content_box(&b, step, &node.content(o));
                let interval = (self.ray.tmin, self.ray.tmax);
                if let Some((t0, _)) = content.clip_interval(&self.origin, &self.inv, interval) {
                    entered[count] = (t0, child, b);
                    count += 1;
                }
            }
        }
        let entered = &mut entered[..count];
        entered.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for &(t0, child, b) in entered.iter() {
            if self.beyond(t0) {
                break;
            }
            if self.recursive::<ANY_HIT>(child, &b) {
                return true;
            }
        }
        false
    }

    /// The parametric walk, iterative: at an inner node the octants the ray enters are found
    /// at once ([`Walk::entered_octants`]); the nearest is walked next and the others are
    /// pushed far to near. A cell entered beyond the closest hit is dropped when it comes
    /// up. Each inner node adds at most seven cells to the stack, so `7 * depth + 1` entries
    /// suffice for a tree of that depth ([`stack_size`]); the stack is the thread's own,
    /// reused from ray to ray.
    fn parametric<const ANY_HIT: bool>(&mut self) -> bool {
        STACK.with(|stack| {
            let mut stack = stack.borrow_mut();
            let need = stack_size(self.tree.params.max_depth);
            if stack.len() < need {
                stack.resize(need, Pending::ZERO);
            }
            self.parametric_on::<ANY_HIT>(&mut stack)
        })
    }

    /// [`Walk::parametric`] on a stack of at least [`stack_size`] entries.
    fn parametric_on<const ANY_HIT: bool>(&mut self, stack: &mut [Pending]) -> bool {
        let tree = self.tree;
        let mut cur = Pending {
            cell: tree.bounds,
            node: tree.root,
            t_enter: f32::NEG_INFINITY,
        };
        let mut top = 0;
        loop {
            rt_geom::counters::nodes(1);
            if cur.node.is_leaf() {
                if self.leaf::<ANY_HIT>(cur.node.index()) {
                    return true;
                }
            } else {
                let node = &tree.nodes[cur.node.index()];
                // As `Aabb::center` computes it: exactly the build's planes.
                let mid = cur.cell.center();
                let (entered, t0) = self.entered_octants(node, &cur.cell, mid);
                let entered = entered & node.mask();
                if entered != 0 {
                    // Bit k: the k-th octant of the sequence (mirrored numbering).
                    let mut pending = self.sequence[entered as usize];
                    let nearest = pending.trailing_zeros() as usize;
                    pending &= pending - 1;
                    while pending != 0 {
                        let k = 7 - pending.leading_zeros() as usize;
                        pending &= !(1 << k);
                        let i = self.octant_at_step[k] as usize;
                        stack[top] = Pending::octant(node, &cur.cell, mid, i, t0[i]);
                        top += 1;
                    }
                    let i = self.octant_at_step[nearest] as usize;
                    cur = Pending::octant(node, &cur.cell, mid, i, t0[i]);
                    continue;
                }
            }
            loop {
                if top == 0 {
                    return false;
                }
                top -= 1;
                cur = stack[top];
                if !self.beyond(cur.t_enter) {
                    break;
                }
            }
        }
    }

    /// Revelles et al.'s octant intervals, for the eight octants of an inner node at once
    /// (lane `i`: octant `i`), each from the planes of the octant's content box, intersected
    /// with `[tmin, tmax]` and padded like the box test. Returns the mask of the octants the
    /// ray enters (bit `i`: octant `i`) and the padded entry distance per octant (meaningful
    /// for those).
    #[inline(always)]
    fn entered_octants(&self, node: &OctNode, cell: &Aabb, mid: Vec3) -> (u8, [f32; 8]) {
        let mut t = (f32x8::splat(self.ray.tmin), f32x8::splat(self.ray.tmax));
        // One quantization step for the eight octants: the build's own formula.
        let step = content_step(cell);
        let planes = |a: usize| (cell.min[a], mid[a], step[a]);
        self.narrow_along(0, node, planes(0), &mut t);
        self.narrow_along(1, node, planes(1), &mut t);
        self.narrow_along(2, node, planes(2), &mut t);
        let (t0, t1) = t;
        if !self.pad_after {
            // Padded by the reciprocals, and never below `tmin` (the intervals start there).
            return (t0.cmp_le(t1).move_mask() as u8, t0.to_array());
        }
        let pad = f32x8::splat(PAD);
        let (t0, t1) = (t0 - t0.abs() * pad, t1 + t1.abs() * pad);
        let entry = t0
            .cmp_gt(f32x8::splat(self.ray.tmin))
            .blend(t0, f32x8::splat(self.ray.tmin));
        (t0.cmp_le(t1).move_mask() as u8, entry.to_array())
    }

    /// Narrows the eight intervals `t` to the slabs of the octants' content boxes along axis
    /// `a`. A content box lies inside its octant (code 255 reaches 1/254 of the side beyond
    /// it, see [`crate::node`]), so the octant's own slab would narrow nothing more and is not
    /// computed. `(lo, mid, step)`: the cell's low plane and centre along `a`, and the
    /// octants' quantization step ([`content_step`]). NaN (origin in a plane, zero direction)
    /// leaves an interval unchanged, as in the box test.
    #[inline(always)]
    fn narrow_along(
        &self,
        a: usize,
        node: &OctNode,
        (lo, mid, step): (f32, f32, f32),
        t: &mut (f32x8, f32x8),
    ) {
        let o = f32x8::splat(self.origin[a]);
        let (inv_lo, inv_hi) = (f32x8::splat(self.inv_lo[a]), f32x8::splat(self.inv_hi[a]));
        // Per lane, the octant is the lower or the upper half along `a`; content codes count
        // steps of 1/254 of its side from its low corner (`node::content_box`).
        let upper = self.upper_half[a];
        let half = |below: f32, above: f32| upper.blend(f32x8::splat(above), f32x8::splat(below));
        let base = half(lo, mid);
        let step = f32x8::splat(step);
        // Distances to the planes met as the box's lower and upper plane.
        let box_a = (base + codes_to_f32(&node.lo[a]) * step - o) * inv_lo;
        let box_b = (base + codes_to_f32(&node.hi[a]) * step - o) * inv_hi;
        let (near, far) = if self.neg[a] {
            (box_b, box_a)
        } else {
            (box_a, box_b)
        };
        t.0 = near.cmp_gt(t.0).blend(near, t.0);
        t.1 = far.cmp_lt(t.1).blend(far, t.1);
    }
}

/// Eight content codes as numbers (zero-extended through 16 and 32 bits: `vpmovzx`
/// instructions where the CPU has them).
#[inline(always)]
fn codes_to_f32(q: &[u8; 8]) -> f32x8 {
    let mut bytes = [0u8; 16];
    bytes[..8].copy_from_slice(q);
    let words = u16x8::from_u8x16_low(u8x16::from(bytes));
    f32x8::from_i32x8(i32x8::from_u16x8(words))
}

/// Mirrored octants in the order Revelles' sequence meets them: by the number of centre
/// planes crossed.
const SEQUENCE_ORDER: [u8; 8] = [0, 1, 2, 4, 3, 5, 6, 7];

/// `SEQUENCE_MASKS[mirror][mask]`: bit `k` set when the `k`-th octant of the sequence,
/// real octant `SEQUENCE_ORDER[k] ^ mirror`, is in `mask` (bit `i`: real octant `i`).
static SEQUENCE_MASKS: [[u8; 256]; 8] = {
    let mut t = [[0u8; 256]; 8];
    let mut mirror = 0;
    while mirror < 8 {
        let mut mask = 0;
        while mask < 256 {
            let mut k = 0;
            while k < 8 {
                let real = SEQUENCE_ORDER[k] as usize ^ mirror;
                t[mirror][mask] |= ((mask >> real & 1) as u8) << k;
                k += 1;
            }
            mask += 1;
        }
        mirror += 1;
    }
    t
};

/// Lane `i` of axis `a` is non-zero when bit `a` of `i` is set.
const UPPER_HALF: [[f32; 8]; 3] = [
    [0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0],
    [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0],
    [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
];

/// A cell waiting on the parametric walk's stack.
#[derive(Clone, Copy)]
struct Pending {
    /// The node's cell (unused for leaves).
    cell: Aabb,
    node: ChildRef,
    /// Padded entry distance of the cell (`-inf` for the root).
    t_enter: f32,
}

impl Pending {
    /// All zeros (the stack is cleared with one `memset`).
    const ZERO: Self = Self {
        cell: Aabb {
            min: rt_geom::Vec3::ZERO,
            max: rt_geom::Vec3::ZERO,
        },
        node: ChildRef(0),
        t_enter: 0.0,
    };

    /// Octant `i` (non-empty) of `node`, whose cell is `cell` with centre `mid`, entered at
    /// `t_enter`.
    #[inline(always)]
    fn octant(node: &OctNode, cell: &Aabb, mid: Vec3, i: usize, t_enter: f32) -> Self {
        let child = node.child(i).unwrap_or(ChildRef::leaf(0));
        debug_assert!(node.mask() >> i & 1 == 1);
        Self {
            cell: octant_at(cell, mid, i),
            node: child,
            t_enter,
        }
    }
}

/// Stack entries the parametric walk needs in a tree of depth at most `depth`: seven per
/// level and the root.
fn stack_size(depth: u32) -> usize {
    7 * depth.min(MAX_DEPTH) as usize + 1
}

thread_local! {
    /// Walk stacks are reused per thread: no allocation and no clearing per ray.
    static STACK: std::cell::RefCell<Vec<Pending>> = const { std::cell::RefCell::new(Vec::new()) };
}

impl<P: Primitive> Octree<P> {
    pub(crate) fn traverse<const ANY_HIT: bool, K: Keep>(
        &self,
        ray: &Ray,
        best: impl FnOnce() -> K,
    ) -> Option<Hit> {
        if self.leaves.is_empty() || !ray.is_valid() {
            return None;
        }
        // No clip to the root cell first: the root's octant test culls the same rays.
        let inv = ray.inv_dir().to_array();
        let slab = SlabRay::with_inv_dir(ray, inv);
        let neg = slab.neg;
        let mirror = (0..3).fold(0, |m, a| m | ((neg[a] as usize) << a));
        let (inv_lo, inv_hi) = slab.plane_reciprocals();
        let mut walk = Walk {
            tree: self,
            // The walk computes in the tree's frame: the ray's origin relative to it.
            origin: self.frame.local_point(ray.origin()),
            inv_lo,
            inv_hi,
            pad_after: slab.pad_after,
            neg,
            sequence: &SEQUENCE_MASKS[mirror],
            octant_at_step: SEQUENCE_ORDER.map(|j| j ^ mirror as u8),
            upper_half: UPPER_HALF.map(f32x8::from).map(|l| l.cmp_ne(f32x8::ZERO)),
            inv,
            ray: *ray,
            best: best(),
            mailbox: Mailbox::default(),
        };
        match self.params.traversal {
            crate::OctreeTraversal::Recursive => walk.recursive::<ANY_HIT>(self.root, &self.bounds),
            crate::OctreeTraversal::Parametric => walk.parametric::<ANY_HIT>(),
        };
        walk.best.best()
    }
}
