//! Saved grids over triangles: a built [`Grid`] (uniform, two-level or adaptive) as bytes and
//! back. A plain little-endian layout, versioned:
//!
//! ```text
//! magic      8 bytes  "rt-grid\n"
//! version    u32      1
//! params     the build parameters (GridParams), field by field; fields the kind does not
//!            use are zero
//! primitives u64 count, u64 hash: 64-bit FNV-1a over 32-bit words of every triangle vertex's
//!            coordinates
//! levels     u64 count, each: bounds (6 f32), resolution (3 u32), first cell's offset u32,
//!            first child entry u32 (u32::MAX: no sub-grids)
//! offsets    u64 count, u32 each (per level, its cells' starts and one closing entry)
//! children   u64 count, u32 each (per level with sub-grids, one entry per cell)
//! refs       u64 count, u32 each
//! ```
//!
//! The triangles are not stored: `from_bytes` takes them again and checks them against the
//! hash; the frame, the cell sizes, the plane tables and the skip distances follow from them
//! and the levels, as the build derives them. Loading checks every length against the bytes
//! left; the layout before anything is indexed by it (the levels in the order the build
//! writes them, each reached once, no deeper than the kind allows, each level's cells and
//! sub-grid entries where that order puts them, every cell's references ascending and in
//! range, refined cells holding none, the root spanning the triangles' box); the grid's own
//! [`Accel::validate`]; and that every triangle is listed wherever the build would list it
//! (its cells at every level redone, widened and clipped as the build does) and every
//! sub-grid spans what the build would make it span. A truncated, corrupted or foreign file
//! is a [`LoadError`], never a panic or a wrong answer.
//!
//! ```
//! use rt_accel_grid::{Grid, GridParams};
//! use rt_geom::{Accel, Ray, Triangle, Vec3};
//!
//! let tris = [Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
//! let grid = Grid::build(&tris, GridParams::two_level()).unwrap();
//! let bytes = grid.to_bytes();
//! let loaded = Grid::from_bytes(&bytes, &tris).unwrap();
//! let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z);
//! assert_eq!(loaded.intersect(&ray), grid.intersect(&ray));
//! assert!(Grid::from_bytes(&bytes[..bytes.len() - 1], &tris).is_err());
//! ```

use crate::build::{add_tables, cells_of, sub_grid_box};
use crate::level::{MAX_RES, NO_CHILD};
use crate::{Grid, GridKind, GridParams, Level};
use rt_geom::saved::{LoadError, Reader, Writer, triangle_hash};
use rt_geom::{Aabb, Accel, Frame, LeafPrims, Triangle, Vec3, check_primitives};

const MAGIC: &[u8; 8] = b"rt-grid\n";
const VERSION: u32 = 1;

impl Grid<Triangle> {
    /// The grid as bytes (the format is in the [module](self) documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Writer::default();
        out.header(MAGIC, VERSION);
        write_params(&mut out, &self.params);
        out.primitives((self.prims.len(), triangle_hash(&self.prims)));
        out.u64(self.levels.len() as u64);
        for lv in &self.levels {
            for v in lv
                .bounds
                .min
                .to_array()
                .into_iter()
                .chain(lv.bounds.max.to_array())
            {
                out.f32(v);
            }
            lv.res.iter().for_each(|&r| out.u32(r));
            out.u32(lv.first);
            out.u32(lv.first_child);
        }
        for array in [&self.offsets, &self.children, &self.refs] {
            out.u64(array.len() as u64);
            array.iter().for_each(|&v| out.u32(v));
        }
        out.0
    }

    /// The grid [`Self::to_bytes`] wrote, over the same `tris`: the same answers, bit for
    /// bit. Any other bytes or triangles give a [`LoadError`].
    pub fn from_bytes(bytes: &[u8], tris: &[Triangle]) -> Result<Self, LoadError> {
        let mut r = Reader(bytes);
        r.header(MAGIC, VERSION)?;
        let params = read_params(&mut r)?;
        r.primitives((tris.len(), triangle_hash(tris)))?;
        let count = r.count(44)?;
        let mut levels = Vec::with_capacity(count);
        for _ in 0..count {
            let mut v = [0f32; 6];
            for x in &mut v {
                *x = r.f32()?;
            }
            let bounds = Aabb::new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
            let res = [r.u32()?, r.u32()?, r.u32()?];
            levels.push((bounds, res, r.u32()?, r.u32()?));
        }
        let mut arrays = [Vec::new(), Vec::new(), Vec::new()];
        for array in &mut arrays {
            let count = r.count(4)?;
            *array = (0..count).map(|_| r.u32()).collect::<Result<_, _>>()?;
        }
        if !r.0.is_empty() {
            return Err(LoadError::TrailingBytes);
        }
        let [offsets, children, refs] = arrays;
        let corrupt = |e: String| LoadError::Corrupt(e);
        // Triangles no build takes cannot have been saved.
        check_primitives(tris, u32::MAX as usize - 1).map_err(|e| corrupt(e.to_string()))?;
        let world = Aabb::around(tris);
        let frame = Frame::of(&world);
        let levels = check_layout(&levels, &offsets, &children, &refs, tris.len(), &params)
            .map_err(corrupt)?;
        if levels.first().map(|lv| lv.bounds) != (!tris.is_empty()).then(|| frame.to_local(&world))
        {
            return Err(corrupt("the root grid does not span the triangles".into()));
        }
        let grid = Self::assemble(tris, levels, offsets, children, refs, params, frame);
        grid.validate().map_err(corrupt)?;
        grid.check_coverage().map_err(corrupt)?;
        Ok(grid)
    }

    /// The grid over `tris` with these levels and arrays (checked by [`check_layout`]): the
    /// plane tables, skip distances and the cells' triangles laid out as the build does.
    fn assemble(
        tris: &[Triangle],
        mut levels: Vec<Level>,
        offsets: Vec<u32>,
        children: Vec<u32>,
        refs: Vec<u32>,
        params: GridParams,
        frame: Frame,
    ) -> Self {
        let (mut planes, mut skip) = (Vec::new(), Vec::new());
        for lv in &mut levels {
            let first = lv.first as usize;
            let child = |c: usize| {
                lv.first_child != NO_CHILD && children[lv.first_child as usize + c] != NO_CHILD
            };
            let occupied = |c: usize| offsets[first + c] < offsets[first + c + 1] || child(c);
            let mut level = lv.clone();
            add_tables(&mut level, occupied, &mut planes, &mut skip);
            *lv = level;
        }
        let lists = levels.iter().flat_map(|lv| {
            let cells = &offsets[lv.first as usize..=lv.first as usize + lv.cell_count()];
            cells.windows(2).map(|w| (w[0], w[1] - w[0]))
        });
        Self {
            listed: LeafPrims::new(tris, &refs, lists),
            levels,
            offsets: offsets.into(),
            children: children.into(),
            refs: refs.into(),
            skip: skip.into(),
            planes: planes.into(),
            prims: tris.to_vec(),
            params,
            frame,
            isa: rt_geom::Isa::selected(),
        }
    }

    /// Every triangle is listed wherever the build would list it: at each level, in the
    /// cells `build::cells_of` gives it (the build's own rule), and in a refined cell's
    /// sub-grid instead, by the same rule; and every sub-grid spans the box the build would
    /// give it (`build::sub_grid_box` of its triangles' parts in its cell).
    fn check_coverage(&self) -> Result<(), String> {
        use rayon::prelude::*;
        if self.levels.is_empty() {
            return Ok(());
        }
        let empty = || (vec![Aabb::EMPTY; self.levels.len()], None::<u32>);
        let (content, uncovered) = (0..self.prims.len() as u32)
            .into_par_iter()
            .fold(empty, |(mut content, bad), id| {
                let listed = bad.is_some() || self.listed_as_built(id, 0, &mut content);
                (content, if listed { bad } else { Some(id) })
            })
            .reduce(empty, |(a, x), (b, y)| {
                let joined = a.iter().zip(&b).map(|(p, q)| p.union(*q)).collect();
                let first = match (x, y) {
                    (Some(x), Some(y)) => Some(x.min(y)),
                    (x, y) => x.or(y),
                };
                (joined, first)
            });
        if let Some(id) = uncovered {
            return Err(format!(
                "triangle {id} is not listed in every cell it crosses"
            ));
        }
        for (l, lv) in self.levels.iter().enumerate() {
            if lv.first_child == NO_CHILD {
                continue;
            }
            for c in 0..lv.cell_count() {
                let k = self.children[lv.first_child as usize + c];
                if k == NO_CHILD {
                    continue;
                }
                let cell = lv.widened(&lv.cell_box(lv.coords(c)));
                if self.levels[k as usize].bounds != sub_grid_box(content[k as usize], &cell) {
                    return Err(format!(
                        "level {l}, cell {c}: the sub-grid does not span its cell's content"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Whether triangle `id` is listed in every cell of level `l` (or of its sub-grids) the
    /// build would list it in; the union of its parts in each refined cell is added to that
    /// sub-grid's entry of `content`.
    fn listed_as_built(&self, id: u32, l: usize, content: &mut [Aabb]) -> bool {
        let (lv, t) = (&self.levels[l], &self.prims[id as usize]);
        let mut cells = Vec::new();
        cells_of(t, lv, &self.frame, &mut cells);
        cells.into_iter().all(|c| {
            let c = c as usize;
            let child = match lv.first_child {
                NO_CHILD => NO_CHILD,
                first => self.children[first as usize + c],
            };
            if child == NO_CHILD {
                return self.cell_refs(lv, c).binary_search(&id).is_ok();
            }
            let cell = lv.widened(&lv.cell_box(lv.coords(c)));
            let k = child as usize;
            content[k] = content[k].union(self.frame.clipped_bounds(t, &cell));
            self.listed_as_built(id, k, content)
        })
    }
}

/// The levels as the build lays them out, before anything is indexed by them: in the order
/// the build writes them (depth first, sub-grids in cell order), each reached once and no
/// deeper than the kind allows; each level's box finite, its resolution within bounds (one
/// cell across a flat axis) and its cells no more than `max_cells`; its offsets and sub-grid
/// entries where that order puts them; offsets ascending from 0 to the reference count;
/// every cell's references ascending (as the build's counting sort leaves them) and in
/// range; refined cells holding none.
fn check_layout(
    saved: &[(Aabb, [u32; 3], u32, u32)],
    offsets: &[u32],
    children: &[u32],
    refs: &[u32],
    prims: usize,
    params: &GridParams,
) -> Result<Vec<Level>, String> {
    if saved.is_empty() {
        return match (prims, offsets.len(), children.len(), refs.len()) {
            (0, 0, 0, 0) => Ok(Vec::new()),
            _ => Err("no levels over triangles".into()),
        };
    }
    let max_depth = match params.kind {
        GridKind::Uniform => 1,
        GridKind::TwoLevel { .. } => 2,
        GridKind::Adaptive { max_levels, .. } => max_levels as usize,
    };
    let mut levels = Vec::with_capacity(saved.len());
    let (mut next_offset, mut next_child) = (0usize, 0usize);
    for (l, &(bounds, res, first, first_child)) in saved.iter().enumerate() {
        if !bounds.is_finite() || bounds.is_empty() {
            return Err(format!("level {l} has no box"));
        }
        let e = bounds.extent();
        if (0..3).any(|a| !(1..=MAX_RES).contains(&res[a]) || (e[a] == 0.0 && res[a] != 1)) {
            return Err(format!("level {l} has resolution {res:?}"));
        }
        let cells = res.iter().map(|&r| r as u64).product::<u64>();
        if cells > params.max_cells as u64 || cells as usize + 1 > offsets.len() {
            return Err(format!("level {l} has {cells} cells"));
        }
        let cells = cells as usize;
        if first as usize != next_offset {
            return Err(format!(
                "level {l}'s cells are not where the build puts them"
            ));
        }
        next_offset += cells + 1;
        if first_child != NO_CHILD {
            if first_child as usize != next_child {
                return Err(format!(
                    "level {l}'s sub-grids are not where the build puts them"
                ));
            }
            next_child += cells;
        }
        let mut level = Level::tiling(bounds, res);
        level.first = first;
        level.first_child = first_child;
        levels.push(level);
    }
    if next_offset != offsets.len() || next_child != children.len() {
        return Err("the offsets or sub-grid entries are not the levels'".into());
    }
    if offsets.first() != Some(&0)
        || offsets.windows(2).any(|w| w[0] > w[1])
        || offsets.last().map(|&e| e as usize) != Some(refs.len())
    {
        return Err("cell offsets are not ascending from 0 up to the reference count".into());
    }
    if let Some(&p) = refs.iter().find(|&&p| p as usize >= prims) {
        return Err(format!("reference {p} out of range"));
    }
    // Depth first from the root, sub-grids in cell order: the build's order.
    let mut order = Vec::with_capacity(levels.len());
    let mut stack = vec![(0u32, 1usize)];
    while let Some((l, depth)) = stack.pop() {
        if order.len() == levels.len() || l as usize != order.len() {
            return Err(format!("level {l} is not where the build puts it"));
        }
        if depth > max_depth {
            return Err(format!("level {l} lies deeper than the kind allows"));
        }
        order.push(l);
        let lv = &levels[l as usize];
        for c in 0..lv.cell_count() {
            let (s, e) = (
                offsets[lv.first as usize + c],
                offsets[lv.first as usize + c + 1],
            );
            let cell_refs = &refs[s as usize..e as usize];
            if cell_refs.windows(2).any(|w| w[0] >= w[1]) {
                return Err(format!("level {l}, cell {c}: references out of order"));
            }
            let child = match lv.first_child {
                NO_CHILD => NO_CHILD,
                first => children[first as usize + c],
            };
            if child != NO_CHILD && (child as usize >= levels.len() || !cell_refs.is_empty()) {
                return Err(format!(
                    "level {l}, cell {c}: a sub-grid out of range or with references"
                ));
            }
        }
        if lv.first_child != NO_CHILD {
            let first = lv.first_child as usize;
            let subs = children[first..first + lv.cell_count()].iter();
            let subs: Vec<u32> = subs.copied().filter(|&k| k != NO_CHILD).collect();
            if subs.is_empty() {
                return Err(format!("level {l} has sub-grid entries but no sub-grid"));
            }
            stack.extend(subs.into_iter().rev().map(|k| (k, depth + 1)));
        }
    }
    if order.len() != levels.len() {
        return Err(format!(
            "{} levels, {} reachable",
            levels.len(),
            order.len()
        ));
    }
    Ok(levels)
}

fn write_params(out: &mut Writer, p: &GridParams) {
    let (kind, a, b) = match p.kind {
        GridKind::Uniform => (0, 0, 0),
        GridKind::TwoLevel { top_density } => (1, top_density.to_bits(), 0),
        GridKind::Adaptive {
            max_cell_prims,
            max_levels,
        } => (2, max_cell_prims, max_levels),
    };
    out.u8(kind);
    out.u32(a);
    out.u32(b);
    out.f32(p.density);
    out.u32(p.max_cells);
    out.f32(p.max_refs_per_prim);
    out.u8(p.mailbox as u8);
    out.u8(p.skip_empty as u8);
}

fn read_params(r: &mut Reader) -> Result<GridParams, LoadError> {
    let corrupt = |what: &str| LoadError::Corrupt(format!("unknown {what}"));
    let kind = match (r.u8()?, r.u32()?, r.u32()?) {
        (0, 0, 0) => GridKind::Uniform,
        (1, t, 0) => GridKind::TwoLevel {
            top_density: f32::from_bits(t),
        },
        (2, max_cell_prims, max_levels) => GridKind::Adaptive {
            max_cell_prims,
            max_levels,
        },
        _ => return Err(corrupt("grid kind")),
    };
    let (density, max_cells, max_refs_per_prim) = (r.f32()?, r.u32()?, r.f32()?);
    let flag = |r: &mut Reader, what| match r.u8()? {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(corrupt(what)),
    };
    let mailbox = flag(r, "mailbox flag")?;
    let skip_empty = flag(r, "skip flag")?;
    let params = GridParams {
        kind,
        density,
        max_cells,
        max_refs_per_prim,
        mailbox,
        skip_empty,
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

    fn kinds() -> [GridParams; 4] {
        [
            GridParams::uniform(),
            GridParams::two_level().with_mailbox(true),
            GridParams::adaptive(),
            GridParams {
                kind: GridKind::Adaptive {
                    max_cell_prims: 1,
                    max_levels: 8,
                },
                ..GridParams::adaptive().with_skip_empty(false)
            },
        ]
    }

    /// Every conformance scene (slivers, shared edges and vertices, axis-aligned and
    /// coplanar sets, far coordinates) loads back as built under every kind: the checks
    /// refuse no grid the build makes.
    #[test]
    fn every_conformance_scene_loads_back() {
        for params in kinds() {
            let build = |t: &[Triangle]| Grid::build(t, params).unwrap();
            rt_testkit::assert_conformance_scenes_load(build, Grid::to_bytes, Grid::from_bytes);
        }
    }

    /// Every kind round-trips: the same answers bit for bit, the same bytes again; empty
    /// and one-triangle scenes too.
    #[test]
    fn every_kind_round_trips_bit_for_bit() {
        let tris = scenes::random_soup(700, 3);
        for params in kinds() {
            for tris in [&tris[..], &tris[..1], &[]] {
                let grid = Grid::build(tris, params).unwrap();
                let load = |b: &[u8]| Grid::from_bytes(b, tris);
                rt_testkit::assert_round_trip(&grid, Grid::to_bytes, load, &rays(2000));
            }
        }
    }

    /// Damaged bytes are refused, never loaded wrong: every prefix, every byte changed (every
    /// eighth unless the long tests run), other triangles, a triangle dropped from a cell
    /// (found by the coverage check alone) and a sub-grid shrunk inside its cell.
    #[test]
    fn damage_is_refused() {
        let tris = scenes::random_soup(120, 5);
        let brute = rt_geom::BruteForce::build(&tris).unwrap();
        let load = |b: &[u8]| Grid::from_bytes(b, &tris);
        for params in [GridParams::uniform(), GridParams::two_level()] {
            let grid = Grid::build(&tris, params).unwrap();
            let bytes = grid.to_bytes();
            rt_testkit::assert_damage_refused(&bytes, load, &brute, &rays(300));
            assert_eq!(
                Grid::from_bytes(&bytes, &tris[1..]).err(),
                Some(LoadError::OtherPrimitives)
            );
            // A cell loses a triangle that other cells list too (so that every triangle is
            // still listed somewhere): found by the coverage check alone.
            let listed = |p: u32| grid.refs.iter().filter(|&&q| q == p).count();
            let at = (0..grid.refs.len())
                .find(|&i| listed(grid.refs[i]) > 1)
                .unwrap();
            let mut dropped = grid.clone();
            let mut refs = dropped.refs.to_vec();
            refs.remove(at);
            dropped.refs = refs.into();
            for o in dropped.offsets.iter_mut() {
                *o -= (*o as usize > at) as u32;
            }
            let err = Grid::from_bytes(&dropped.to_bytes(), &tris).unwrap_err();
            assert!(
                err.to_string().contains("not listed in every cell"),
                "{err}"
            );
        }
        let grid = Grid::build(&tris, GridParams::two_level()).unwrap();
        let sub = (1..grid.levels.len())
            .find(|&l| grid.levels[l].bounds.extent().min_element() > 0.0)
            .unwrap();
        let mut shrunk = grid.clone();
        let b = &mut shrunk.levels[sub].bounds;
        b.max -= b.extent() * 0.25;
        let err = Grid::from_bytes(&shrunk.to_bytes(), &tris).unwrap_err();
        assert!(matches!(err, LoadError::Corrupt(_)), "{err}");
    }
}
