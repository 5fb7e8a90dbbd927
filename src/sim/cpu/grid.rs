//! Uniform-grid neighbour search (thesis §2.2.5, §2.2.9) — twin of `shaders/grid.wgsl`.
//!
//! Each particle set (liquid, solid, boundary) is binned into the same grid by a counting sort:
//! cell index → count → exclusive prefix sum → scatter. The scatter visits particles in ascending
//! index, so inside a cell particles stay in ascending order: neighbour sums always run over the
//! (2·[`GRID_REACH`] + 1)³ cells (125; 25 in 2-D) in a fixed offset order, then ascending index — the
//! canonical order both back-ends follow, which makes runs bit-reproducible.
//!
//! A cell is half the largest search radius (`GRID_REACH` = 2 cells per radius): the 5³ block of cells
//! around a particle holds 15.6 R³ of candidates against 27 R³ for radius-sized cells, 1.7 times fewer
//! distance tests for the same neighbours, and the GPU walks each row of five consecutive cells as one
//! range of the cell list.

use crate::sim::params::GridDims;
use glam::Vec3;

/// Cells per search radius along each axis: the neighbour block is the cells within ±`GRID_REACH` of a
/// particle's cell (`GRID_REACH` in `shaders/common.wgsl`).
pub const GRID_REACH: i32 = 2;

/// Cell-sorted view of one particle set.
#[derive(Clone, Debug, Default)]
pub struct CellList {
    /// Particle indices sorted by cell, ascending index inside a cell.
    pub order: Vec<u32>,
    /// The particles' positions at the build, in `order`'s order (`CellEntry.pos` of common.wgsl): the
    /// distance tests of a neighbour walk read consecutive memory instead of gathering by index.
    pub pos: Vec<Vec3>,
    /// `cell_start[c]..cell_start[c + 1]` is the range of `order` in cell c.
    pub cell_start: Vec<u32>,
    /// Particles found outside the domain (clamped into the border cells).
    pub outside: u32,
}

/// Integer cell coordinates of a position (clamped into the grid); the bool says whether it was inside.
#[inline]
pub fn grid_cell_coords(g: &GridDims, x: Vec3) -> ([i32; 3], bool) {
    let mut c = [0i32; 3];
    let mut inside = true;
    for a in 0..3 {
        let f = ((x[a] - g.min[a]) / g.cell[a]).floor();
        let n = g.n[a] as i32;
        let k = if f.is_finite() { f as i32 } else { 0 };
        if k < 0 || k >= n {
            inside = false;
        }
        c[a] = k.clamp(0, n - 1);
    }
    (c, inside)
}

#[inline]
pub fn grid_cell_index(g: &GridDims, c: [i32; 3]) -> usize {
    (c[0] as usize) + g.n[0] as usize * ((c[1] as usize) + g.n[1] as usize * c[2] as usize)
}

/// grid_count · grid_scan_* · grid_scatter: builds the cell list of one set.
pub fn grid_build(g: &GridDims, pos: &[Vec3], out: &mut CellList) {
    let cells = g.cell_count();
    out.cell_start.clear();
    out.cell_start.resize(cells + 1, 0);
    out.outside = 0;
    let mut cell_of = Vec::with_capacity(pos.len());
    for x in pos {
        let (c, inside) = grid_cell_coords(g, *x);
        if !inside {
            out.outside += 1;
        }
        let ci = grid_cell_index(g, c);
        cell_of.push(ci as u32);
        out.cell_start[ci + 1] += 1;
    }
    for c in 0..cells {
        out.cell_start[c + 1] += out.cell_start[c];
    }
    let mut cursor: Vec<u32> = out.cell_start[..cells].to_vec();
    out.order.clear();
    out.order.resize(pos.len(), 0);
    out.pos.clear();
    out.pos.resize(pos.len(), Vec3::ZERO);
    for (i, &c) in cell_of.iter().enumerate() {
        let slot = &mut cursor[c as usize];
        out.order[*slot as usize] = i as u32;
        out.pos[*slot as usize] = pos[i];
        *slot += 1;
    }
}

/// grid_reorder_gather · grid_reorder_apply: renumbers the liquid into the cell order of its fresh
/// list `list` (issue 4: particle arrays reordered by cell), so that a neighbour walk gathers the
/// velocities and densities of one cell's particles from nearby memory however far the blood has
/// flowed and mixed; the list then points at the new places (`order` = 0, 1, 2, …; its cells and
/// positions are unchanged). Every array moves (the GPU moves only those live across the grid build —
/// x and m, v, a⁰, id —: the others are rewritten by evaluation 1 before they are read).
pub fn grid_reorder(l: &mut crate::sim::cpu::LiquidSet, list: &mut CellList) {
    let order = &list.order;
    if order.len() != l.x.len() || order.iter().enumerate().all(|(k, &i)| k == i as usize) {
        return;
    }
    l.gather(order);
    for (k, o) in list.order.iter_mut().enumerate() {
        *o = k as u32;
    }
}

/// Neighbour query over one cell-sorted set, at the positions the set had when its list was built (the
/// solver rebuilds the lists whenever positions change, as the GPU twin does).
pub struct Neighbours<'a> {
    pub grid: &'a GridDims,
    pub list: &'a CellList,
    /// Periodic length per axis, 0 where not periodic.
    pub period: Vec3,
    pub three_d: bool,
}

/// Minimum-image difference x_i − x_j on periodic axes (SPEC §4.3).
#[inline]
pub fn min_image(mut d: Vec3, period: Vec3) -> Vec3 {
    for a in 0..3 {
        let l = period[a];
        if l > 0.0 {
            d[a] -= l * (d[a] / l).round();
        }
    }
    d
}

/// [`min_image`] without its division, for a neighbour walk: positions are wrapped into the domain
/// (`integrate::wrap_periodic`), so |d| < l and one add or subtract of l is the minimum image. The two
/// agree bit for bit except where d/l rounds onto ±½ — a pair half a period apart, beyond every search
/// radius, which the walk's distance test drops either way. (The periodic 2-D validation channels ran
/// the division for every candidate.)
#[inline]
fn min_image_wrapped(mut d: Vec3, period: Vec3, half: Vec3) -> Vec3 {
    for a in 0..3 {
        let l = period[a];
        if l > 0.0 {
            if d[a] > half[a] {
                d[a] -= l;
            } else if d[a] < -half[a] {
                d[a] += l;
            }
        }
    }
    d
}

impl Neighbours<'_> {
    /// Calls `f(j, x_ij, r_ij)` for every particle j of the set with r_ij < radius, in canonical order.
    /// A row of the neighbour block (dx = −GRID_REACH … GRID_REACH at one dy, dz) is one range of the
    /// cell list unless a periodic x wraps (then cell by cell) — the walk of `nbr_span` in common.wgsl.
    #[inline]
    pub fn for_each(&self, xi: Vec3, radius: f32, mut f: impl FnMut(usize, Vec3, f32)) {
        let g = self.grid;
        let (c, _) = grid_cell_coords(g, xi);
        let zr = if self.three_d { -GRID_REACH..=GRID_REACH } else { 0..=0 };
        let r2max = radius * radius;
        let nx = g.n[0] as i32;
        let wraps = self.period[0] > 0.0 && (c[0] < GRID_REACH || c[0] >= nx - GRID_REACH);
        let periodic = self.period != Vec3::ZERO;
        let half = 0.5 * self.period;
        let mut visit = |first: usize, last: usize| {
            let (s, e) = (self.list.cell_start[first] as usize, self.list.cell_start[last + 1] as usize);
            for (&j, &xj) in self.list.order[s..e].iter().zip(&self.list.pos[s..e]) {
                let d = xi - xj;
                let xij = if periodic { min_image_wrapped(d, self.period, half) } else { d };
                let r2 = xij.length_squared();
                if r2 < r2max {
                    f(j as usize, xij, r2.sqrt());
                }
            }
        };
        for dz in zr {
            for dy in -GRID_REACH..=GRID_REACH {
                // y and z of the row (wrapped on periodic axes), or skip it
                let mut yz = [c[1] + dy, c[2] + dz];
                let mut skip = false;
                for (a, v) in yz.iter_mut().enumerate() {
                    let n = g.n[a + 1] as i32;
                    if *v < 0 || *v >= n {
                        if self.period[a + 1] > 0.0 {
                            *v = v.rem_euclid(n);
                        } else {
                            skip = true;
                        }
                    }
                }
                if skip {
                    continue;
                }
                if wraps {
                    for dx in -GRID_REACH..=GRID_REACH {
                        let ci = grid_cell_index(g, [(c[0] + dx).rem_euclid(nx), yz[0], yz[1]]);
                        visit(ci, ci);
                    }
                } else {
                    let lo = grid_cell_index(g, [(c[0] - GRID_REACH).max(0), yz[0], yz[1]]);
                    let hi = grid_cell_index(g, [(c[0] + GRID_REACH).min(nx - 1), yz[0], yz[1]]);
                    visit(lo, hi);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic scatter of `n` points in [0, ext) (a 64-bit LCG; no test-only dependency).
    fn points(n: usize, ext: Vec3, three_d: bool, seed: u64) -> Vec<Vec3> {
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n).map(|_| Vec3::new(next() * ext.x, next() * ext.y, if three_d { next() * ext.z } else { 0.0 })).collect()
    }

    /// The row walk finds exactly the particles a brute-force search finds (minimum image on periodic
    /// axes), each once, for cells of R/2 — interior, clipped borders and wrapped periodic rows, 2-D and
    /// 3-D, with particles on the cell faces and pairs outside the domain (clamped into a border cell).
    #[test]
    fn row_walk_finds_the_brute_force_neighbours() {
        for (three_d, periodic) in
            [(true, [false; 3]), (true, [true, false, true]), (false, [true, false, false]), (false, [false; 3])]
        {
            let ext = Vec3::new(0.06, 0.05, if three_d { 0.04 } else { 0.0 });
            let radius = 0.01f32;
            let cell_min = radius / GRID_REACH as f32;
            let mut n = [1u32; 3];
            let mut cell = [cell_min; 3];
            for a in 0..if three_d { 3 } else { 2 } {
                n[a] = (ext[a] / cell_min).floor().max(1.0) as u32;
                cell[a] = ext[a] / n[a] as f32;
            }
            let g = GridDims { n, cell, min: Vec3::ZERO };
            let period = Vec3::from_array(std::array::from_fn(|a| if periodic[a] { ext[a] } else { 0.0 }));
            let mut pos = points(600, ext, three_d, 7);
            // a lattice on the cell faces
            for k in 0..if three_d { 4 } else { 1 } {
                for j in 0..5 {
                    for i in 0..6 {
                        pos.push(Vec3::new(i as f32 * cell[0], j as f32 * cell[1], k as f32 * cell[2]) * 2.0);
                    }
                }
            }
            // outside the domain (binned into border cells): a pair below the non-periodic y, a pair beyond
            // each end of x where x is not periodic, a pair above z
            let z = if three_d { 0.02 } else { 0.0 };
            pos.extend([Vec3::new(0.02, -0.004, z), Vec3::new(0.021, -0.009, z)]);
            if !periodic[0] {
                pos.extend([Vec3::new(-0.012, 0.01, z), Vec3::new(-0.018, 0.012, z)]);
                pos.extend([Vec3::new(0.075, 0.03, z), Vec3::new(0.07, 0.033, z)]);
            }
            if three_d && !periodic[2] {
                pos.extend([Vec3::new(0.03, 0.02, 0.052), Vec3::new(0.031, 0.022, 0.058)]);
            }
            let mut list = CellList::default();
            grid_build(&g, &pos, &mut list);
            let nb = Neighbours { grid: &g, list: &list, period, three_d };
            for (i, &xi) in pos.iter().enumerate() {
                let mut found = Vec::new();
                nb.for_each(xi, radius, |j, xij, _| {
                    assert_eq!(xij, min_image(xi - pos[j], period), "x_ij of {i}–{j}");
                    found.push(j);
                });
                let mut want: Vec<usize> = (0..pos.len())
                    .filter(|&j| min_image(xi - pos[j], period).length_squared() < radius * radius)
                    .collect();
                found.sort_unstable();
                want.sort_unstable();
                assert_eq!(found, want, "particle {i} at {xi:?} (3-D {three_d}, periodic {periodic:?})");
            }
        }
    }
}
