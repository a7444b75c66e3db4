//! Building: primitives into the cells they really overlap (the box test narrowed by
//! clipping the primitive to each cell), counted and scattered into one reference array per
//! level, sub-grids for the cells the kind refines, then flattened.

use crate::level::{Level, NO_CHILD};
use crate::params::{GridKind, GridParams};
use crate::skip;
use rayon::prelude::*;
use rt_geom::{Aabb, Frame, Primitive};

/// A level before flattening.
pub(crate) struct LevelBuild {
    pub level: Level,
    /// Cell `c` holds `refs[offsets[c]..offsets[c + 1]]`.
    pub offsets: Vec<u32>,
    pub refs: Vec<u32>,
    /// Refined cells and their sub-grids (the cell's own references are then dropped).
    pub children: Vec<(u32, LevelBuild)>,
}

pub(crate) struct Ctx<'a, P> {
    pub prims: &'a [P],
    pub params: &'a GridParams,
    /// The frame the levels' boxes and planes are in: primitives are clipped to the cells'
    /// world boxes (rounded outward) and their boxes taken back to it (rounded outward).
    pub frame: Frame,
}

/// Cells per primitive at `depth` for `kind`.
fn density(params: &GridParams, depth: u32) -> f32 {
    match params.kind {
        GridKind::TwoLevel { top_density } if depth == 0 => top_density,
        _ => params.density,
    }
}

/// Whether a cell of `count` primitives at `depth` gets a sub-grid.
fn refines(params: &GridParams, depth: u32, count: usize) -> bool {
    match params.kind {
        GridKind::Uniform => false,
        GridKind::TwoLevel { .. } => depth == 0 && count > 1,
        GridKind::Adaptive {
            max_cell_prims,
            max_levels,
        } => depth + 1 < max_levels && count > max_cell_prims as usize,
    }
}

/// The cells of `level` (in `frame`) that primitive `p` overlaps, each cell widened by the
/// level's band ([`Level::widened`]), appended to `out`.
pub(crate) fn cells_of<P: Primitive>(p: &P, level: &Level, frame: &Frame, out: &mut Vec<u32>) {
    let b = frame.clipped_bounds(p, &level.widened(&level.bounds));
    if b.is_empty() {
        return;
    }
    // The cells the box reaches once widened by the band. A box starting exactly on a plane
    // touches the previous cell's face, one ending exactly on a plane the next cell's (where
    // `index_of` already puts `hi`): both cells list it, so that a ray crossing the plane at
    // that edge or vertex, whichever way its walk turns at a corner, meets it (found by
    // fuzzing: a walk stepping diagonally past a shared vertex).
    let b = level.widened(&b);
    let lo: [u32; 3] = std::array::from_fn(|a| {
        let i = level.index_of(a, b.min[a]);
        if i > 0 && b.min[a] == level.plane(a, i) {
            i - 1
        } else {
            i
        }
    });
    let hi: [u32; 3] = std::array::from_fn(|a| level.index_of(a, b.max[a]));
    // One cell: no test needed.
    let single = lo == hi;
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let idx = [x, y, z];
                let cell = level.widened(&level.cell_box(idx));
                if single || !frame.clipped_bounds(p, &cell).is_empty() {
                    out.push(level.linear(idx) as u32);
                }
            }
        }
    }
}

/// The box of what `ids` hold inside `cell` (local, widened by its level's band): their
/// parts clipped to it. A sub-grid spans this box, not the whole cell, so that a small dense
/// object in a large cell (the teapot in a stadium) gets the sub-grid's resolution for
/// itself.
fn content_box<P: Primitive>(ctx: &Ctx<P>, ids: &[u32], cell: &Aabb) -> Aabb {
    let content = ids.iter().fold(Aabb::EMPTY, |b, &id| {
        b.union(ctx.frame.clipped_bounds(&ctx.prims[id as usize], cell))
    });
    sub_grid_box(content, cell)
}

/// The box a sub-grid of `cell` spans, from the union of its primitives' clipped boxes.
pub(crate) fn sub_grid_box(content: Aabb, cell: &Aabb) -> Aabb {
    let content = content.intersection(*cell);
    if content.is_empty() { *cell } else { content }
}

/// Upper bound on the references of `ids` in `level` (their boxes' cell ranges).
fn reference_bound<P: Primitive>(ctx: &Ctx<P>, ids: &[u32], level: &Level) -> u64 {
    ids.par_iter()
        .map(|&id| {
            let b = ctx
                .frame
                .to_local(&ctx.prims[id as usize].bounds())
                .intersection(level.bounds);
            if b.is_empty() {
                return 0;
            }
            (0..3)
                .map(|a| (level.index_of(a, b.max[a]) - level.index_of(a, b.min[a]) + 1) as u64)
                .product::<u64>()
        })
        .sum()
}

/// Builds the level over `ids` inside `bounds` and, recursively, its sub-grids, holding at
/// most `budget` references in all (`budget >= ids.len()`).
///
/// The level is made coarser until its references fit the budget (large primitives in fine
/// cells); what it leaves is shared by the refined cells in proportion to their counts, on
/// top of the count each gives up (a refined cell keeps no references of its own). By
/// induction the whole grid stays within the root's budget, `max_refs_per_prim * N`.
pub(crate) fn build_level<P: Primitive>(
    ctx: &Ctx<P>,
    ids: &[u32],
    bounds: Aabb,
    depth: u32,
    budget: u64,
) -> LevelBuild {
    let n = ids.len();
    let params = ctx.params;
    let mut cells = density(params, depth) as f64 * n as f64;
    let mut level = Level::new(bounds, cells, params.max_cells);
    while level.cell_count() > 1 && reference_bound(ctx, ids, &level) > budget {
        if cells <= 1.0 {
            // Down to the coarsest shape the box allows and still too many: one cell.
            level = Level::new(bounds, 1.0, 1);
            break;
        }
        cells = cells.min(level.cell_count() as f64) * 0.5;
        level = Level::new(bounds, cells, params.max_cells);
    }
    let lists: Vec<Vec<u32>> = ids
        .par_iter()
        .with_min_len(256)
        .map(|&id| {
            let mut out = Vec::new();
            cells_of(&ctx.prims[id as usize], &level, &ctx.frame, &mut out);
            out
        })
        .collect();
    // Counting sort by cell.
    let count = level.cell_count();
    let mut offsets = vec![0u32; count + 1];
    for list in &lists {
        for &c in list {
            offsets[c as usize + 1] += 1;
        }
    }
    for c in 0..count {
        offsets[c + 1] += offsets[c];
    }
    let mut fill = offsets.clone();
    let mut refs = vec![0u32; offsets[count] as usize];
    for (list, &id) in lists.iter().zip(ids) {
        for &c in list {
            refs[fill[c as usize] as usize] = id;
            fill[c as usize] += 1;
        }
    }
    drop(lists);
    // Sub-grids; one that separates nothing (every non-empty sub-cell holds every primitive)
    // is not kept.
    let refine: Vec<u32> = (0..count as u32)
        .filter(|&c| {
            refines(
                params,
                depth,
                (offsets[c as usize + 1] - offsets[c as usize]) as usize,
            )
        })
        .collect();
    let count_of = |c: u32| (offsets[c as usize + 1] - offsets[c as usize]) as u64;
    let refined: u64 = refine.iter().map(|&c| count_of(c)).sum();
    let spare = budget.saturating_sub(refs.len() as u64);
    let children = refine
        .into_par_iter()
        .filter_map(|c| {
            let cell_ids = &refs[offsets[c as usize] as usize..offsets[c as usize + 1] as usize];
            let cell_box = level.widened(&level.cell_box(level.coords(c as usize)));
            let share = (spare as u128 * count_of(c) as u128 / refined.max(1) as u128) as u64;
            let content = content_box(ctx, cell_ids, &cell_box);
            let child = build_level(ctx, cell_ids, content, depth + 1, count_of(c) + share);
            // Kept when some non-empty sub-cell holds fewer primitives than the cell: a ray
            // through it tests fewer.
            let leanest = child
                .offsets
                .windows(2)
                .map(|w| (w[1] - w[0]) as usize)
                .filter(|&n| n > 0)
                .min()
                .unwrap_or(0);
            (leanest < cell_ids.len() || !child.children.is_empty()).then_some((c, child))
        })
        .collect();
    LevelBuild {
        level,
        offsets,
        refs,
        children,
    }
}

/// The flattened arrays of a grid (see [`crate::level`]).
#[derive(Default)]
pub(crate) struct Flat {
    pub levels: Vec<Level>,
    pub offsets: Vec<u32>,
    pub children: Vec<u32>,
    pub refs: Vec<u32>,
    /// Per cell, in step with `offsets`: its distance to the nearest occupied cell
    /// ([`crate::skip`]).
    pub skip: Vec<u8>,
    /// Every level's planes (see [`crate::level`]).
    pub planes: Vec<f32>,
}

/// Appends `b` and its sub-grids; returns the index of `b`'s level.
pub(crate) fn flatten(b: &LevelBuild, out: &mut Flat) -> u32 {
    let me = out.levels.len();
    let mut level = b.level.clone();
    level.first = out.offsets.len() as u32;
    let count = level.cell_count();
    level.first_child = if b.children.is_empty() {
        NO_CHILD
    } else {
        let first = out.children.len() as u32;
        out.children.resize(out.children.len() + count, NO_CHILD);
        first
    };
    out.levels.push(level);
    // This level's cells; refined cells keep no references of their own.
    let mut refined = b.children.iter().map(|(c, _)| *c).peekable();
    for c in 0..count {
        out.offsets.push(out.refs.len() as u32);
        if refined.peek() == Some(&(c as u32)) {
            refined.next();
            continue;
        }
        out.refs
            .extend_from_slice(&b.refs[b.offsets[c] as usize..b.offsets[c + 1] as usize]);
    }
    out.offsets.push(out.refs.len() as u32);
    // A cell is occupied when it holds references or a sub-grid.
    let mut occupied: Vec<bool> = b.offsets.windows(2).map(|w| w[0] < w[1]).collect();
    for (c, _) in &b.children {
        occupied[*c as usize] = true;
    }
    add_tables(
        &mut out.levels[me],
        |c| occupied[c],
        &mut out.planes,
        &mut out.skip,
    );
    debug_assert_eq!(out.skip.len(), out.offsets.len());
    for (c, child) in &b.children {
        let l = flatten(child, out);
        let first_child = out.levels[me].first_child;
        out.children[first_child as usize + *c as usize] = l;
    }
    me as u32
}

/// Appends `level`'s plane table to `planes` (setting its `plane_first`), and its cells' skip
/// distances, `occupied` telling which cells hold references or a sub-grid, then the entry
/// that closes the level, to `skip`: the tables the walk reads.
pub(crate) fn add_tables(
    level: &mut Level,
    occupied: impl Fn(usize) -> bool,
    planes: &mut Vec<f32>,
    skip: &mut Vec<u8>,
) {
    for a in 0..3 {
        level.plane_first[a] = planes.len() as u32;
        planes.extend((0..=level.res[a]).map(|i| level.plane(a, i)));
    }
    skip.extend(skip::chessboard_distances(level.res, occupied));
    skip.push(0);
}
