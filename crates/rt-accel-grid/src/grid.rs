//! [`Grid`]: the uniform, two-level or adaptive grid over any primitive, its build entry points and queries.

use crate::level::NO_CHILD;
use crate::{GridParams, Level, build};
use rt_geom::pages::Pages;
use rt_geom::{
    Aabb, Accel, BuildError, FilteredAccel, Frame, Isa, LeafPrims, Primitive, check_primitives,
};

/// A grid over primitives `P`: uniform, two-level or adaptive (see [`GridKind`](crate::GridKind)).
#[derive(Clone, Debug)]
pub struct Grid<P> {
    pub(crate) levels: Vec<Level>,
    pub(crate) offsets: Pages<u32>,
    pub(crate) children: Pages<u32>,
    pub(crate) refs: Pages<u32>,
    /// Per cell, its distance to the nearest occupied cell of its level ([`skip`](crate::skip)).
    pub(crate) skip: Pages<u8>,
    /// Every level's cell planes ([`level`]).
    pub(crate) planes: Pages<f32>,
    pub(crate) prims: Vec<P>,
    /// The primitives of every cell, in `refs` order, laid out for the cell test.
    pub(crate) listed: LeafPrims<P>,
    pub(crate) params: GridParams,
    /// The frame the levels' boxes and planes are in (the world's, for scenes about the
    /// origin).
    pub(crate) frame: Frame,
    /// The instruction set its leaf tests run compiled for (one dispatch per leaf: the walk
    /// itself recurses, so it stays at the baseline).
    pub(crate) isa: Isa,
}

impl<P: Primitive> Grid<P> {
    /// Builds over `prims` (copied). Empty input gives an empty grid.
    pub fn build(prims: &[P], params: GridParams) -> Result<Self, BuildError> {
        params.validate()?;
        check_primitives(prims, u32::MAX as usize - 1)?;
        let mut flat = build::Flat::default();
        let bounds = Aabb::around(prims);
        let frame = Frame::of(&bounds);
        if !prims.is_empty() {
            let ids: Vec<u32> = (0..prims.len() as u32).collect();
            let ctx = build::Ctx {
                prims,
                params: &params,
                frame,
            };
            let budget = (params.max_refs_per_prim as f64 * prims.len() as f64) as u64;
            let root = build::build_level(
                &ctx,
                &ids,
                frame.to_local(&bounds),
                0,
                budget.max(prims.len() as u64),
            );
            build::flatten(&root, &mut flat);
        }
        // Every cell's range of `refs`, level by level.
        let lists = flat.levels.iter().flat_map(|lv| {
            let cells = &flat.offsets[lv.first as usize..=lv.first as usize + lv.cell_count()];
            cells.windows(2).map(|w| (w[0], w[1] - w[0]))
        });
        let listed = LeafPrims::new(prims, &flat.refs, lists);
        Ok(Self {
            listed,
            levels: flat.levels,
            offsets: Pages::from(flat.offsets),
            children: Pages::from(flat.children),
            refs: Pages::from(flat.refs),
            skip: Pages::from(flat.skip),
            planes: Pages::from(flat.planes),
            prims: prims.to_vec(),
            params,
            frame,
            isa: Isa::selected(),
        })
    }

    /// The same grid, its leaf tests run compiled for `isa` (or, where this CPU lacks it,
    /// for the best level it has): for tests and measurements of each level.
    pub fn with_isa(mut self, isa: Isa) -> Self {
        self.isa = isa.or_best();
        self
    }

    /// The frame the levels' boxes and planes are in: world coordinates minus its anchor
    /// (the world's own for scenes about the origin).
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The levels; level 0 is the root grid (layout in [`level`](crate::level)), their boxes
    /// and planes in [`Self::frame`].
    pub fn levels(&self) -> &[Level] {
        &self.levels
    }

    /// Per cell of all levels, the start of its references in [`Self::refs`] (one more entry per level closes the last cell).
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }

    /// Primitive indices, cell by cell.
    pub fn refs(&self) -> &[u32] {
        &self.refs
    }

    /// Per cell, at its place in [`Self::offsets`], the distance to the nearest occupied cell
    /// of its level ([`skip`](crate::skip)).
    pub fn skip(&self) -> &[u8] {
        &self.skip
    }

    /// The parameters the grid was built with.
    pub fn params(&self) -> &GridParams {
        &self.params
    }

    /// Calls `f(level, depth)` for every level below `l`, parents first.
    pub(crate) fn walk_levels(&self, l: usize, depth: usize, f: &mut impl FnMut(usize, usize)) {
        f(l, depth);
        let lv = &self.levels[l];
        if lv.first_child == NO_CHILD {
            return;
        }
        for c in 0..lv.cell_count() {
            let child = self.children[lv.first_child as usize + c];
            if child != NO_CHILD && (child as usize) < self.levels.len() && child as usize > l {
                self.walk_levels(child as usize, depth + 1, f);
            }
        }
    }

    /// Cell `c` of level `lv` as `(first, count)` places of `refs`.
    pub(crate) fn cell_list(&self, lv: &Level, c: usize) -> (u32, u32) {
        let first = lv.first as usize + c;
        let (s, e) = (self.offsets[first], self.offsets[first + 1]);
        (s, e - s)
    }

    pub(crate) fn cell_refs(&self, lv: &Level, c: usize) -> &[u32] {
        let (s, n) = self.cell_list(lv, c);
        &self.refs[s as usize..(s + n) as usize]
    }
}

impl<P: Primitive> FilteredAccel for Grid<P> {
    rt_geom::filtered_from_walk!();
}

impl<P: Primitive> Accel for Grid<P> {
    rt_geom::queries_from_walk!(stats: compute_stats, validate: check);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridKind;

    rt_testkit::conformance_per_params!(Grid::build {
        uniform: GridParams::uniform(),
        uniform_mailbox: GridParams::uniform().with_mailbox(true),
        uniform_dda: GridParams::uniform().with_skip_empty(false),
        uniform_coarse: GridParams {
            density: 0.05,
            ..GridParams::uniform()
        },
        uniform_fine: GridParams {
            density: 16.0,
            ..GridParams::uniform()
        },
        two_level: GridParams::two_level(),
        two_level_mailbox: GridParams::two_level().with_mailbox(true),
        adaptive: GridParams::adaptive(),
        adaptive_deep: GridParams {
            kind: GridKind::Adaptive {
                max_cell_prims: 1,
                max_levels: 8
            },
            ..GridParams::adaptive()
        },
    });

    /// Each instruction set's leaf tests answer as brute force (a level this CPU lacks runs
    /// its best one), with and without mailboxes.
    macro_rules! per_isa {
        ($($name:ident: $isa:expr;)*) => {$(
            mod $name {
                use super::*;
                rt_testkit::conformance_tests!(
                    triangles: |p: &[rt_geom::Triangle]| Grid::build(p, GridParams::two_level()).map(|g| g.with_isa($isa)),
                );
                mod mailbox {
                    use super::*;
                    rt_testkit::conformance_tests!(
                        triangles: |p: &[rt_geom::Triangle]| Grid::build(p, GridParams::adaptive().with_mailbox(true)).map(|g| g.with_isa($isa)),
                    );
                }
            }
        )*};
    }
    per_isa! {
        isa_baseline: Isa::Baseline;
        isa_avx2: Isa::Avx2;
    }
}

#[cfg(test)]
mod content_tests {
    use super::*;
    use rt_geom::Vec3;

    /// A sub-grid spans its cell's content: a small dense sphere floating between two far
    /// walls gets a sub-grid of its own size, not the size of the huge top cell around it,
    /// and still answers exactly.
    #[test]
    fn sub_grids_span_their_cells_content() {
        let mut tris =
            rt_testkit::scenes::tessellated_sphere(4000, Vec3::new(0.0, 0.02, 0.0), 0.01);
        for x in [-500.0, 500.0] {
            let p = |y: f32, z: f32| Vec3::new(x, y, z);
            tris.push(rt_geom::Triangle::new(
                p(-500.0, -500.0),
                p(500.0, -500.0),
                p(0.0, 500.0),
            ));
        }
        for params in [GridParams::two_level(), GridParams::adaptive()] {
            let grid = Grid::build(&tris, params).unwrap();
            grid.validate().unwrap();
            let top = &grid.levels()[0];
            let cell_area = top.cell_box([0, 0, 0]).half_area();
            let smallest = grid.levels()[1..]
                .iter()
                .map(|lv| lv.bounds.half_area())
                .fold(f32::INFINITY, f32::min);
            assert!(
                smallest < 1e-4 * cell_area,
                "{params:?}: smallest sub-grid {smallest}, top cell {cell_area}"
            );
            let brute = rt_geom::BruteForce::build(&tris).unwrap();
            let eye = Vec3::new(3.0, 2.0, -5.0);
            for k in 0..400 {
                let (u, v) = ((k % 20) as f32 / 19.0 - 0.5, (k / 20) as f32 / 19.0 - 0.5);
                let target = Vec3::new(0.03 * u, 0.02 + 0.03 * v, 0.0);
                let ray = rt_geom::Ray::new(eye, target - eye);
                assert_eq!(
                    grid.intersect(&ray),
                    brute.intersect(&ray),
                    "{params:?} ray {k}"
                );
            }
        }
    }
}

#[cfg(test)]
mod skip_tests {
    use super::*;
    use crate::GridKind;
    use rt_geom::{Triangle, Vec3};
    use rt_testkit::Scene;
    use rt_testkit::scenes::tessellated_sphere;

    /// Small clusters far apart, a long sliver across the empty space between them, and a
    /// flat triangle on a cell plane: most cells are empty, many far from any occupied one,
    /// so walks leave whole empty cubes in one step (jumps that end on cell walls, in the
    /// middle of cubes, at the grid's edge) and must still answer as brute force does.
    #[test]
    fn empty_cubes_are_crossed_exactly() {
        let mut tris = Vec::new();
        for (k, c) in [
            Vec3::new(-0.9, -0.9, -0.9),
            Vec3::new(0.9, 0.85, -0.9),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(-0.8, 0.9, 0.7),
            Vec3::new(0.7, -0.6, 0.9),
        ]
        .into_iter()
        .enumerate()
        {
            tris.extend(tessellated_sphere(200 + 100 * k, c, 0.03));
        }
        tris.push(Triangle::new(
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -0.999),
        ));
        tris.push(Triangle::new(
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, -0.5, 0.0),
            Vec3::new(0.6, -1.0, 0.0),
        ));
        let scene = Scene::new("sparse_clusters", tris);
        // (parameters, the least skip distance some cell must reach: fine grids have large
        // empty cubes; the presets' coarse levels over 1.5k triangles have small ones).
        for (params, reach) in [
            (
                GridParams {
                    density: 8.0,
                    ..GridParams::uniform()
                },
                8,
            ),
            (GridParams::uniform(), 3),
            (GridParams::two_level(), 2),
            (
                GridParams {
                    kind: GridKind::TwoLevel { top_density: 1.0 },
                    ..GridParams::two_level()
                },
                4,
            ),
            (GridParams::adaptive(), 2),
        ] {
            let grid = Grid::build(&scene.prims, params).unwrap();
            let farthest = grid.skip().iter().copied().max().unwrap_or(0);
            assert!(
                farthest >= reach,
                "{params:?}: empty cubes of radius {farthest} at most"
            );
            rt_testkit::conformance::assert_conforms(&scene, |p| Grid::build(p, params));
        }
    }

    /// The skip distances and the plane table are part of what `validate` checks: a skip
    /// distance larger than the level's (a jump over content), or a plane moved, is caught.
    #[test]
    fn validate_catches_a_wrong_skip_distance() {
        let tris = tessellated_sphere(500, Vec3::ZERO, 1.0);
        let mut grid = Grid::build(&tris, GridParams::uniform()).unwrap();
        grid.validate().unwrap();
        let c = grid
            .skip
            .iter()
            .position(|&d| d == 1)
            .expect("an empty cell by the sphere");
        grid.skip[c] = 3;
        assert!(grid.validate().unwrap_err().contains("skip"));
        // So is the plane table the walk reads.
        let mut grid = Grid::build(&tris, GridParams::two_level()).unwrap();
        grid.validate().unwrap();
        let last = grid.planes.len() - 1;
        grid.planes[last] += 1e-3;
        assert!(grid.validate().unwrap_err().contains("plane table"));
    }
}
