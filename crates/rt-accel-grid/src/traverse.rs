//! The 3D-DDA of Amanatides & Woo (1987), level by level: from the cell the ray enters,
//! step to the neighbour across whichever cell wall the ray leaves through first. A refined
//! cell hands the ray's interval in it, clipped to the sub-grid's box (the cell's content), to
//! its sub-grid.
//!
//! Exactness with brute force rests on these rules:
//! - the cell walls are the level's planes ([`Level::plane`]) and each exit distance is
//!   computed afresh from them (no accumulated `t += delta`), once per wall: after a step
//!   only the axis stepped along gets a new one (Amanatides & Woo's `tMax` array);
//! - the entry cell is found from the entry point and, if that point lies within rounding of
//!   the wall behind it, the walk starts one cell earlier (an extra cell costs a few tests; a
//!   cell skipped would lose hits);
//! - a hit ends the walk only once it lies before the current cell's exit, padded like the box
//!   test: a hit near a wall waits until the cells beyond the wall have been tested too;
//! - the walk ends when the next wall lies beyond the (padded) end of the interval, not at the
//!   grid's outer walls, so a ray grazing the grid's box still visits every cell it touches;
//! - an empty cell whose [`crate::skip`] distance is `d >= 2` lies in a cube of empty cells
//!   `d - 1` deep on every side: the walk leaves the cube in one step, through the first of
//!   its walls ahead (computed from the level's planes, as every wall), into the cell beyond;
//!   along the other axes the cell is found from the point as on entering a level (one cell
//!   early within rounding of a wall) and kept inside the cube, which the ray has not left
//!   there. The cells it skips hold nothing, so the walk tests what it tested before.
//!
//! With `mailbox`, each ray remembers the last primitives it tested and skips them in later
//! cells (Amanatides & Woo's mailboxes, kept per ray so that threads share nothing).

use crate::Grid;
use crate::level::{Level, NO_CHILD};
use rt_geom::aabb::{pad_down, pad_up};
use rt_geom::{Hit, Keep, Mailbox, Primitive, Ray};

/// Empty cells at this skip distance or more are left a whole empty cube at a time (cubes of
/// 3x3x3 cells and up); starting at larger cubes skips less for the same bookkeeping.
const JUMP_MIN: u8 = 2;

/// Mailbox slots per ray.
const MAILBOX: usize = 8;

struct Walk<'a, P, K> {
    grid: &'a Grid<P>,
    origin: [f32; 3],
    dir: [f32; 3],
    inv: [f32; 3],
    ray: Ray,
    best: K,
    mailbox: Mailbox<MAILBOX>,
}

impl<P: Primitive, K: Keep> Walk<'_, P, K> {
    /// Tests the primitives at places `s..e` of `refs` (a cell); true when `ANY_HIT` and
    /// something was hit.
    #[inline(always)]
    fn test<const ANY_HIT: bool, const MAILBOXES: bool>(&mut self, (s, e): (usize, usize)) -> bool {
        let mailbox = &mut self.mailbox;
        let grid = self.grid;
        let (ray, best) = (&mut self.ray, &mut self.best);
        grid.listed
            .test_on::<ANY_HIT, K>(grid.isa, (s, e - s), &grid.refs, ray, best, |p| {
                MAILBOXES && mailbox.seen(p)
            })
    }

    /// Plane `i` (`0..=res`) of level `lv` along axis `a`: [`Level::plane`] read from the
    /// grid's table.
    #[inline(always)]
    fn plane(&self, lv: &Level, a: usize, i: u32) -> f32 {
        self.grid.planes[lv.plane_first[a] as usize + i as usize]
    }

    /// The distance at which the ray crosses the wall ahead of cell `i` along axis `a`,
    /// computed from the level's plane (never accumulated); +inf when that wall is the
    /// level's own box. Walls of the level's box are not walls to step across: the interval
    /// [t0, t1] (padded) already ends there, and a ray that grazes the box (or a flat level)
    /// may still cross inner walls along the other axes before t1.
    #[inline(always)]
    fn next_wall(&self, lv: &Level, a: usize, i: u32) -> f32 {
        let wall = if self.dir[a] > 0.0 && i + 1 < lv.res[a] {
            self.plane(lv, a, i + 1)
        } else if self.dir[a] < 0.0 && i > 0 {
            self.plane(lv, a, i)
        } else {
            return f32::INFINITY;
        };
        // NaN (a wall through the origin, infinite 1/dir) counts as leaving at once.
        ((wall - self.origin[a]) * self.inv[a]).max(f32::NEG_INFINITY)
    }

    /// The cell along axis `a` of level `lv` that holds the ray at `t`: the one the point
    /// lies in, or the one before it when the point lies within rounding of the wall behind
    /// (an extra cell costs a few tests; a cell skipped would lose hits).
    #[inline(always)]
    fn cell_at(&self, lv: &Level, a: usize, t: f32) -> u32 {
        let x = self.origin[a] + t * self.dir[a];
        let i = lv.index_by(a, x, |i| self.plane(lv, a, i));
        let tol = 1e-6 * (self.origin[a].abs() + (t * self.dir[a]).abs());
        if self.dir[a] > 0.0 && i > 0 && x - self.plane(lv, a, i) <= tol {
            i - 1
        } else if self.dir[a] < 0.0 && i + 1 < lv.res[a] && self.plane(lv, a, i + 1) - x <= tol {
            i + 1
        } else {
            i
        }
    }

    /// From cell `idx`, whose cells within `empty_around - 1` along every axis are all empty
    /// (its [`crate::skip`] distance), leaves that cube in one step: `idx` becomes the cell
    /// beyond the wall the ray leaves it by, `next` that cell's walls ahead. Returns the
    /// distance where the ray enters it (padded down, as every step), or `None` when the walk
    /// ends in the cube: the closest hit so far lies before its exit, or the ray's interval
    /// (or the level) ends inside it.
    #[inline(never)]
    fn leave_empty_cube(
        &self,
        lv: &Level,
        idx: &mut [u32; 3],
        next: &mut [f32; 3],
        empty_around: u8,
        t1: f32,
    ) -> Option<f32> {
        let r = empty_around as u32 - 1;
        // The cube's last cell ahead along each axis.
        let far: [u32; 3] = std::array::from_fn(|a| {
            if self.dir[a] > 0.0 {
                (idx[a] + r).min(lv.res[a] - 1)
            } else if self.dir[a] < 0.0 {
                idx[a].saturating_sub(r)
            } else {
                idx[a]
            }
        });
        let walls: [f32; 3] = std::array::from_fn(|a| self.next_wall(lv, a, far[a]));
        let (exit, axis) = first_wall(&walls);
        if self.best.best().is_some_and(|h| h.t < pad_down(exit)) || axis == 3 || exit > t1 {
            return None;
        }
        // Along the other axes the ray is still inside the cube there: the cell that holds
        // it (found as on entering a level), kept within the cube.
        for a in 0..3 {
            idx[a] = if a == axis {
                if self.dir[a] > 0.0 {
                    far[a] + 1
                } else {
                    far[a] - 1
                }
            } else if self.dir[a] == 0.0 {
                idx[a]
            } else {
                let (lo, hi) = (idx[a].min(far[a]), idx[a].max(far[a]));
                self.cell_at(lv, a, exit).clamp(lo, hi)
            };
            next[a] = self.next_wall(lv, a, idx[a]);
        }
        Some(pad_down(exit))
    }

    /// Walks level `l` over `[t0, t1]`; true when `ANY_HIT` found a hit.
    fn level<const ANY_HIT: bool, const MAILBOXES: bool>(
        &mut self,
        l: usize,
        t0: f32,
        t1: f32,
    ) -> bool {
        let grid = self.grid;
        let lv = &grid.levels[l];
        let mut idx: [u32; 3] = std::array::from_fn(|a| self.cell_at(lv, a, t0));
        // Per axis, the distance at which the ray leaves through the next wall ahead (+inf
        // when there is none); only the axis just stepped along is computed again.
        let mut next: [f32; 3] = std::array::from_fn(|a| self.next_wall(lv, a, idx[a]));
        let mut entry = t0;
        loop {
            rt_geom::counters::nodes(1);
            let (exit, axis) = first_wall(&next);
            let c = lv.linear(idx);
            let child = if lv.first_child == NO_CHILD {
                NO_CHILD
            } else {
                grid.children[lv.first_child as usize + c]
            };
            if child != NO_CHILD {
                // The sub-grid spans the cell's content: the part of the ray in the cell,
                // clipped to that box (padded, as every box test), or nothing.
                let inside = (entry.max(t0), pad_up(exit).min(t1));
                let sub = child as usize;
                let content = &grid.levels[sub].bounds;
                if let Some((s0, s1)) = content.clip_interval(&self.origin, &self.inv, inside) {
                    if self.level::<ANY_HIT, MAILBOXES>(sub, s0, s1) {
                        return true;
                    }
                }
            } else {
                let first = lv.first as usize + c;
                let (s, e) = (
                    grid.offsets[first] as usize,
                    grid.offsets[first + 1] as usize,
                );
                if s < e {
                    if self.test::<ANY_HIT, MAILBOXES>((s, e)) {
                        return true;
                    }
                } else if grid.params.skip_empty && grid.skip[first] >= JUMP_MIN {
                    // Empty, and so is every cell around it up to `skip - 1` cells away.
                    match self.leave_empty_cube(lv, &mut idx, &mut next, grid.skip[first], t1) {
                        Some(t) => {
                            entry = t;
                            continue;
                        }
                        None => return false,
                    }
                }
            }
            if let Some(h) = self.best.best() {
                if h.t < pad_down(exit) {
                    return false;
                }
            }
            if axis == 3 || exit > t1 {
                return false;
            }
            if self.dir[axis] > 0.0 {
                idx[axis] += 1;
            } else {
                idx[axis] -= 1;
            }
            next[axis] = self.next_wall(lv, axis, idx[axis]);
            entry = pad_down(exit);
        }
    }
}

/// The wall the ray leaves through first, of the three ahead, and its axis (the first of
/// equal distances); axis 3 when there is none.
#[inline(always)]
fn first_wall(walls: &[f32; 3]) -> (f32, usize) {
    let mut exit = f32::INFINITY;
    let mut axis = 3;
    for (a, &t) in walls.iter().enumerate() {
        if t < exit {
            exit = t;
            axis = a;
        }
    }
    (exit, axis)
}

impl<P: Primitive> Grid<P> {
    pub(crate) fn traverse<const ANY_HIT: bool, K: Keep>(
        &self,
        ray: &Ray,
        best: impl FnOnce() -> K,
    ) -> Option<Hit> {
        if self.levels.is_empty() || !ray.is_valid() {
            return None;
        }
        let inv = ray.inv_dir().to_array();
        // The walk computes in the grid's frame: the ray's origin relative to it.
        let origin = self.frame.local_point(ray.origin());
        let (t0, t1) = self.levels[0]
            .bounds
            .clip_interval(&origin, &inv, (ray.tmin, ray.tmax))?;
        let mut walk = Walk {
            grid: self,
            origin,
            dir: ray.dir().to_array(),
            inv,
            ray: *ray,
            best: best(),
            mailbox: Mailbox::default(),
        };
        if self.params.mailbox {
            walk.level::<ANY_HIT, true>(0, t0, t1);
        } else {
            walk.level::<ANY_HIT, false>(0, t0, t1);
        }
        walk.best.best()
    }
}
