//! `stats()` and `validate()`: what the grid reports about itself, and its invariants.

use crate::level::NO_CHILD;
use crate::{Grid, skip};
use rt_geom::{AccelStats, Primitive};

impl<P: Primitive> Grid<P> {
    /// Nodes are cells (of every level), leaves the non-empty cells without a sub-grid, depth
    /// the number of levels below the root.
    pub(crate) fn compute_stats(&self) -> AccelStats {
        let mut s = AccelStats {
            primitives: self.prims.len(),
            references: self.refs.len(),
            bytes: std::mem::size_of_val(self.levels.as_slice())
                + std::mem::size_of_val(self.offsets.as_slice())
                + std::mem::size_of_val(self.children.as_slice())
                + std::mem::size_of_val(self.refs.as_slice())
                + std::mem::size_of_val(self.skip.as_slice())
                + std::mem::size_of_val(self.planes.as_slice())
                + std::mem::size_of_val(self.prims.as_slice())
                + self.listed.bytes(),
            ..AccelStats::default()
        };
        if self.levels.is_empty() {
            return s;
        }
        self.walk_levels(0, 0, &mut |l, depth| {
            let lv = &self.levels[l];
            s.max_depth = s.max_depth.max(depth);
            s.nodes += lv.cell_count();
            s.leaves += (0..lv.cell_count())
                .filter(|&c| !self.cell_refs(lv, c).is_empty())
                .count();
        });
        s
    }

    /// Offsets ascending and in range; sub-grids cover exactly their cell; every reference
    /// in range and overlapping its cell; every primitive referenced.
    pub(crate) fn check(&self) -> Result<(), String> {
        if self.levels.is_empty() {
            return if self.prims.is_empty() {
                Ok(())
            } else {
                Err("no levels for a non-empty scene".into())
            };
        }
        if self.skip.len() != self.offsets.len() {
            return Err("the skip distances do not follow the offsets".into());
        }
        if self.offsets.windows(2).any(|w| w[0] > w[1])
            || self
                .offsets
                .last()
                .is_some_and(|&e| e as usize != self.refs.len())
        {
            return Err("cell offsets are not ascending up to the reference count".into());
        }
        let mut seen = vec![false; self.prims.len()];
        let mut err = None;
        let mut levels_seen = 0;
        self.walk_levels(0, 0, &mut |l, _| {
            levels_seen += 1;
            let lv = &self.levels[l];
            if lv.first as usize + lv.cell_count() >= self.offsets.len() {
                err.get_or_insert(format!("level {l} has cells past the offsets"));
                return;
            }
            // The plane table holds the level's planes.
            let table = |a: usize| {
                let first = lv.plane_first[a] as usize;
                self.planes.get(first..first + lv.res[a] as usize + 1)
            };
            if (0..3).any(|a| {
                table(a).is_none_or(|t| (0..=lv.res[a]).any(|i| t[i as usize] != lv.plane(a, i)))
            }) {
                err.get_or_insert(format!("level {l}: the plane table is not the level's"));
                return;
            }
            // The skip distances are the level's own: a larger one would jump over content.
            let child_of = |c: usize| {
                (lv.first_child != NO_CHILD)
                    .then(|| self.children[lv.first_child as usize + c])
                    .filter(|&child| child != NO_CHILD)
            };
            let occupied = |c: usize| self.cell_list(lv, c).1 > 0 || child_of(c).is_some();
            let first = lv.first as usize;
            if skip::chessboard_distances(lv.res, occupied)[..]
                != self.skip[first..first + lv.cell_count()]
            {
                err.get_or_insert(format!("level {l}: skip distances are not the level's"));
            }
            for c in 0..lv.cell_count() {
                let cell = lv.widened(&lv.cell_box(lv.coords(c)));
                if lv.first_child != NO_CHILD {
                    let child = self.children[lv.first_child as usize + c];
                    if child != NO_CHILD && !cell.contains(&self.levels[child as usize].bounds) {
                        err.get_or_insert(format!("sub-grid {child} pokes out of its cell"));
                    }
                }
                let list = self.cell_list(lv, c);
                if let Err(e) = self.listed.check_list(&self.prims, &self.refs, list) {
                    err.get_or_insert(format!("level {l}, cell {c}: {e}"));
                }
                for &p in self.cell_refs(lv, c) {
                    match self.prims.get(p as usize) {
                        None => {
                            err.get_or_insert(format!("reference {p} out of range"));
                        }
                        Some(prim) if !rt_geom::touches_cell(prim, &self.frame.to_world(&cell)) => {
                            err.get_or_insert(format!("primitive {p} listed in a cell it misses"));
                        }
                        Some(_) => seen[p as usize] = true,
                    }
                }
            }
        });
        if levels_seen != self.levels.len() {
            return Err(format!(
                "{} levels, {levels_seen} reachable from the root",
                self.levels.len()
            ));
        }
        if let Some(e) = err {
            return Err(e);
        }
        match seen.iter().position(|s| !s) {
            Some(p) => Err(format!("primitive {p} is in no cell")),
            None => Ok(()),
        }
    }
}
