//! Empty-space skipping: per cell, its chessboard distance to the nearest occupied cell of its
//! level (the "proximity clouds" of Cohen & Sheffer 1994). A cell at distance `d >= 2` sits
//! in the middle of a cube of `2d - 1` cells a side that are all empty, so the walk leaves
//! the whole cube in one step instead of crossing its cells one by one.
//!
//! ```text
//! Grid.skip    per level, one byte per cell at the cell's place in `Grid.offsets`
//!              (`first + c`; the level's extra offset entry holds 0):
//!              0 = the cell holds primitives or a sub-grid; d = the nearest such cell is
//!              d cells away along some axis and no closer along every axis (capped at 255)
//! ```

/// The largest distance stored.
pub const MAX_SKIP: u8 = u8::MAX;

/// The chessboard distance from every cell of a `res` grid (cells numbered `x + rx (y + ry
/// z)`) to the nearest occupied one, capped at [`MAX_SKIP`]: 0 for occupied cells,
/// [`MAX_SKIP`] everywhere when none is.
///
/// Two raster passes with the 26 neighbours at distance 1 (Rosenfeld & Pfaltz's sequential
/// transform, exact for the chessboard metric): forward, each cell takes one more than the
/// least of its 13 neighbours already visited; backward, the same with the other 13.
pub fn chessboard_distances(res: [u32; 3], occupied: impl Fn(usize) -> bool) -> Vec<u8> {
    let [rx, ry, rz] = res.map(|r| r as i64);
    let cells = (rx * ry * rz) as usize;
    let mut d: Vec<u8> = (0..cells)
        .map(|c| if occupied(c) { 0 } else { MAX_SKIP })
        .collect();
    let at = |x: i64, y: i64, z: i64| (x + rx * (y + ry * z)) as usize;
    // The 13 neighbours that come before a cell in raster order (the other 13 are their
    // mirror images).
    let before: Vec<(i64, i64, i64)> = (-1..=1)
        .flat_map(|dz| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dx| (dx, dy, dz))))
        .filter(|&(dx, dy, dz)| (dz, dy, dx) < (0, 0, 0))
        .collect();
    debug_assert_eq!(before.len(), 13);
    let pass = |sign: i64, d: &mut Vec<u8>| {
        let order = |n: i64, i: i64| if sign > 0 { i } else { n - 1 - i };
        for iz in 0..rz {
            let z = order(rz, iz);
            for iy in 0..ry {
                let y = order(ry, iy);
                for ix in 0..rx {
                    let x = order(rx, ix);
                    let here = at(x, y, z);
                    if d[here] == 0 {
                        continue;
                    }
                    let mut best = d[here];
                    for &(dx, dy, dz) in &before {
                        let (nx, ny, nz) = (x + sign * dx, y + sign * dy, z + sign * dz);
                        if (0..rx).contains(&nx) && (0..ry).contains(&ny) && (0..rz).contains(&nz) {
                            best = best.min(d[at(nx, ny, nz)].saturating_add(1));
                        }
                    }
                    d[here] = best;
                }
            }
        }
    };
    pass(1, &mut d);
    pass(-1, &mut d);
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The transform against the definition, on random occupancies of odd shapes.
    #[test]
    fn distances_are_the_chessboard_distances() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (res, fill) in [
            ([7, 5, 3], 40),
            ([1, 1, 1], 2),
            ([9, 1, 6], 25),
            ([12, 10, 8], 200),
            ([20, 3, 17], 1000),
            ([5, 5, 5], 0),
        ] {
            let cells = (res[0] * res[1] * res[2]) as usize;
            let occupied: Vec<bool> = (0..cells).map(|_| fill > 0 && next() % fill == 0).collect();
            let d = chessboard_distances(res, |c| occupied[c]);
            let coords = |c: usize| {
                let (rx, ry) = (res[0] as usize, res[1] as usize);
                [c % rx, (c / rx) % ry, c / (rx * ry)].map(|v| v as i64)
            };
            for (c, &got) in d.iter().enumerate() {
                let p = coords(c);
                let expected = (0..cells)
                    .filter(|&q| occupied[q])
                    .map(|q| {
                        let o = coords(q);
                        (0..3).map(|a| (p[a] - o[a]).abs()).max().unwrap_or(0)
                    })
                    .min()
                    .map_or(MAX_SKIP, |m| m.min(MAX_SKIP as i64) as u8);
                assert_eq!(got, expected, "res {res:?}, cell {p:?}");
            }
        }
    }

    #[test]
    fn distances_saturate() {
        // A long row with one occupied end: distances count up to the cap and stay there.
        let d = chessboard_distances([400, 1, 1], |c| c == 0);
        assert_eq!(d[0], 0);
        assert_eq!(d[254], 254);
        assert_eq!(d[255], MAX_SKIP);
        assert_eq!(d[399], MAX_SKIP);
    }
}
