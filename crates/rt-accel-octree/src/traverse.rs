//! Both walks. Each octant's box is the same `octant()` of its parent that the build used,
//! and both skip an octant whose content box (the node's min/max information, see
//! [`crate::node`]) the ray does not enter, or enters beyond the closest hit.
//!
//! - `recursive`: the seeds' walk. At an inner node, every non-empty octant whose content box
//!   the ray enters (the padded box test) is collected with its entry distance, the list is
//!   sorted, and the octants are visited nearest first; octants entered beyond the closest
//!   hit are skipped.
//! - `parametric` (Revelles, Ureña & Lastra 2000): per axis, the distances to the node's near
//!   and far planes and to its centre plane, in the mirrored frame where every direction is
//!   positive (octant numbers XOR-ed with the direction mask give the real ones). Each
//!   octant's interval follows from these nine parameters, not from a box test: along an
//!   axis it is `[near, mid]` or `[mid, far]`. Revelles' walk steps from the first octant
//!   (from the entry plane) to the next (across the smallest exit) with data-dependent
//!   branches; here the eight intervals are evaluated at once in SIMD lanes and the
//!   octants whose interval is non-empty are the ones the sequence visits, ordered as the
//!   sequence orders them (each step crosses one more centre plane). The distances are
//!   computed afresh at each node from the cell's coordinates (not averaged from the
//!   parent's, so they are exactly the build's planes), NaN (a ray lying in a plane) counts
//!   as "inside the slab", and each interval is padded like the box test. No sorting, and
//!   the walk is iterative with an explicit stack.
//!
//! Both walks keep a per-ray mailbox of the last 8 primitives tested: a primitive listed in
//! several leaves along the ray is tested once.

use crate::MAX_DEPTH;
use crate::Octree;
use crate::node::{OctNode, octant};
use rt_geom::aabb::PAD;
use rt_geom::{Aabb, Hit, Mailbox, Primitive, Ray, test_primitives};
use wide::{CmpGe, CmpLe, CmpNe, f32x8};

struct Walk<'a, P> {
    tree: &'a Octree<P>,
    origin: [f32; 3],
    inv: [f32; 3],
    /// Bit `a` set: the ray runs towards -a (octant bits mirrored).
    mirror: usize,
    /// Per axis, the lanes (mirrored octants) in the upper half along it.
    upper_half: [f32x8; 3],
    ray: Ray,
    best: Option<Hit>,
    /// Primitives listed in several leaves are tested once per ray.
    mailbox: Mailbox<8>,
}

impl<P: Primitive> Walk<'_, P> {
    /// Tests leaf `i`; true when `ANY_HIT` and something was hit.
    fn leaf<const ANY_HIT: bool>(&mut self, i: usize) -> bool {
        let tree = self.tree;
        let ids = &tree.indices[tree.nodes[i].prims()];
        let mailbox = &mut self.mailbox;
        test_primitives::<P, ANY_HIT>(&tree.prims, ids, &mut self.ray, &mut self.best, |p| {
            mailbox.seen(p)
        })
    }

    /// True when a pending part of the ray entered at `t` cannot hold a closer hit.
    #[inline]
    fn beyond(&self, t: f32) -> bool {
        // `test_primitives` lowers `ray.tmax` to every hit it keeps.
        t > self.ray.tmax
    }

    fn recursive<const ANY_HIT: bool>(&mut self, i: usize, bounds: &Aabb) -> bool {
        let node = self.tree.nodes[i];
        if node.is_leaf() {
            return self.leaf::<ANY_HIT>(i);
        }
        let mut entered: [(f32, usize, Aabb); 8] = [(0.0, 0, Aabb::EMPTY); 8];
        let mut count = 0;
        for o in 0..8 {
            if let Some(child) = node.child(o) {
                let b = octant(bounds, o);
                let content = self.tree.nodes[child].content_box(&b);
                if let Some((t0, _)) = content.clip_ray(&self.ray) {
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

    /// `(near, mid, far)` distances to the planes of the box `lo..hi` along each axis, in the
    /// mirrored frame. The centre is computed as [`Aabb::center`] does, so the planes are
    /// exactly those of the build's [`octant`] boxes.
    #[inline(always)]
    fn planes(&self, cell: &Aabb) -> [[f32; 3]; 3] {
        let (lo, hi) = (&cell.min, &cell.max);
        std::array::from_fn(|a| {
            let (near, far) = if self.mirror >> a & 1 == 1 {
                (hi[a], lo[a])
            } else {
                (lo[a], hi[a])
            };
            let c = (lo[a] + hi[a]) * 0.5;
            let t = |x: f32| (x - self.origin[a]) * self.inv[a];
            // NaN: the ray lies in that plane; for the slab it is inside, and it never
            // crosses the centre plane.
            let (near, mid, far) = (t(near), t(c), t(far));
            [
                if near.is_nan() {
                    f32::NEG_INFINITY
                } else {
                    near
                },
                if mid.is_nan() { f32::INFINITY } else { mid },
                if far.is_nan() { f32::INFINITY } else { far },
            ]
        })
    }

    /// The parametric walk, iterative: at an inner node the octants the ray enters are found
    /// at once ([`Walk::entered_octants`]) and pushed far to near; the nearest comes up
    /// next. A cell entered beyond the closest hit is dropped when it comes up. Each inner
    /// node adds at most seven cells to the stack beyond the one walked next, so
    /// `7 * depth + 1` entries suffice for a tree of that depth ([`stack_size`]); the stack
    /// is the thread's own, reused from ray to ray.
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
        stack[0] = Pending {
            cell: tree.bounds,
            node: 0,
            t_enter: f32::NEG_INFINITY,
        };
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let cur = stack[top];
            if self.beyond(cur.t_enter) {
                continue;
            }
            let node = tree.nodes[cur.node as usize];
            if node.is_leaf() {
                if self.leaf::<ANY_HIT>(cur.node as usize) {
                    return true;
                }
                continue;
            }
            let (entered, t0) = self.entered_octants(&node, &cur.cell);
            // Far to near: the sequence order reversed, one step per octant entered.
            let mut pending = in_sequence_order(entered);
            while pending != 0 {
                let k = 7 - pending.leading_zeros() as usize;
                pending &= !(1 << k);
                let j = SEQUENCE_ORDER[k];
                let real = j as usize ^ self.mirror;
                let Some(child) = node.child(real) else {
                    continue;
                };
                // Entered only if the ray meets what the octant holds.
                let b = octant(&cur.cell, real);
                let content = tree.nodes[child].content_box(&b);
                if let Some((t_content, _)) = content.clip_ray(&self.ray) {
                    stack[top] = Pending {
                        cell: b,
                        node: child as u32,
                        t_enter: t0[j as usize].max(t_content),
                    };
                    top += 1;
                }
            }
        }
        false
    }

    /// Revelles et al.'s octant intervals, for the eight octants of an inner node at once
    /// (one 8-lane pass; lane `j` is octant `j` of the mirrored frame): along axis `a` the
    /// octant spans `[near, mid]`, or `[mid, far]` when bit `a` of `j` is set; its interval
    /// is the largest lower end to the smallest upper end, padded like the box test. Returns
    /// the mirrored octants whose padded interval is non-empty and meets
    /// `[tmin, tmax]` (bit `j`), with their padded entry distances.
    ///
    /// These are the octants of Revelles' sequence (first octant from the entry plane, the
    /// next across the plane of the smallest exit), found without its data-dependent steps;
    /// along the sequence each octant sets one more bit of `j` than the last, which is why
    /// [`SEQUENCE_ORDER`] (by the number of bits set) visits them nearest first.
    #[inline(always)]
    fn entered_octants(&self, node: &OctNode, cell: &Aabb) -> (u8, [f32; 8]) {
        let p = self.planes(cell);
        let lane = |a: usize, upper: bool| {
            let (below, above) = if upper {
                (p[a][1], p[a][2])
            } else {
                (p[a][0], p[a][1])
            };
            self.upper_half[a].blend(f32x8::splat(above), f32x8::splat(below))
        };
        let t0 = lane(0, false).max(lane(1, false)).max(lane(2, false));
        let t1 = lane(0, true).min(lane(1, true)).min(lane(2, true));
        let pad = f32x8::splat(PAD);
        let t0 = t0 - t0.abs() * pad;
        let t1 = t1 + t1.abs() * pad;
        let ok = t0.cmp_le(t1)
            & t1.cmp_ge(f32x8::splat(self.ray.tmin))
            & t0.cmp_le(f32x8::splat(self.ray.tmax));
        let entered = ok.move_mask() as u8 & mirror_mask(node.mask(), self.mirror);
        (entered, t0.to_array())
    }
}

/// Mirrored octants in the order Revelles' sequence meets them: by the number of centre
/// planes crossed.
const SEQUENCE_ORDER: [u8; 8] = [0, 1, 2, 4, 3, 5, 6, 7];

/// Bit `k` of the result is bit `SEQUENCE_ORDER[k]` of `mask` (octants 3 and 4 trade places).
#[inline(always)]
fn in_sequence_order(mask: u8) -> u8 {
    mask & 0b1110_0111 | (mask & 0b1000) << 1 | (mask & 0b1_0000) >> 1
}

/// `mask` (bit `i`: real octant `i`) renumbered to mirrored octants `i ^ mirror`.
#[inline(always)]
fn mirror_mask(mut mask: u8, mirror: usize) -> u8 {
    if mirror & 1 != 0 {
        mask = (mask & 0x55) << 1 | (mask & 0xaa) >> 1;
    }
    if mirror & 2 != 0 {
        mask = (mask & 0x33) << 2 | (mask & 0xcc) >> 2;
    }
    if mirror & 4 != 0 {
        mask = mask.rotate_left(4);
    }
    mask
}

/// Lane `j` of axis `a` is non-zero when bit `a` of `j` is set.
const UPPER_HALF: [[f32; 8]; 3] = [
    [0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0],
    [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0],
    [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
];

/// A cell waiting on the parametric walk's stack.
#[derive(Clone, Copy)]
struct Pending {
    cell: Aabb,
    node: u32,
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
        node: 0,
        t_enter: 0.0,
    };
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
    pub(crate) fn traverse<const ANY_HIT: bool>(&self, ray: &Ray) -> Option<Hit> {
        if self.nodes.is_empty() || !ray.is_valid() {
            return None;
        }
        self.bounds.clip_ray(ray)?;
        let dir = ray.dir();
        let mut walk = Walk {
            tree: self,
            origin: ray.origin().to_array(),
            inv: ray.inv_dir().to_array(),
            mirror: (0..3).fold(0, |m, a| m | ((dir[a].is_sign_negative() as usize) << a)),
            upper_half: UPPER_HALF.map(f32x8::from).map(|l| l.cmp_ne(f32x8::ZERO)),
            ray: *ray,
            best: None,
            mailbox: Mailbox::default(),
        };
        match self.params.traversal {
            crate::OctreeTraversal::Recursive => walk.recursive::<ANY_HIT>(0, &self.bounds),
            crate::OctreeTraversal::Parametric => walk.parametric::<ANY_HIT>(),
        };
        walk.best
    }
}
