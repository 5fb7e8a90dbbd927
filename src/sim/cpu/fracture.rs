//! Connectivity table and irreversible fracture (thesis §3.1.4, Algorithm 2; SPEC §4.6) — twin of
//! `shaders/fracture.wgsl`. Bonds are built once from a radius search; after each corrector every
//! particle drops the bonds whose separation exceeds the searching radius 2h_s. Each particle tests its
//! own list with the same rule, so removal is symmetric and needs no atomics; order is preserved.
//! A scalpel with `blade_cut` (SPEC §4.6, D-25) also cuts every bond whose segment crosses its blade.

use super::SolidSet;
use super::forces::ObjectGeom;
use super::grid::{CellList, Neighbours, min_image};
use crate::scenario::{BoundaryObject, Region, ToolKind};
use crate::sim::params::Params;
use glam::Vec3;
use rayon::prelude::*;

/// The axis across which a `blade_cut` scalpel cuts: its box's thinnest axis among the first `dims`
/// (the blade is the box's mid-plane rectangle across it); `None` for every other object.
pub fn blade_axis(o: &BoundaryObject, dims: usize) -> Option<usize> {
    let tool = o.tool.as_ref()?;
    if !(tool.blade_cut && tool.kind == ToolKind::Scalpel) {
        return None;
    }
    let Region::Box { min, max } = o.shape else { return None };
    (0..dims).min_by(|&a, &b| (max[a] - min[a]).total_cmp(&(max[b] - min[b])))
}

/// A blade at its current pose: the plane x[axis] = (a + b)[axis]/2, bounded by [a, b] grown by
/// `reach` on the other axes.
///
/// The reach is the support radius R_s of the blade's virtual particles: the tissue feels the blade
/// (and is pushed by it) that far out, so a blade cutting only within its own box would push a
/// hanging organ ahead of its edge instead of entering it (measured on a 2-D slab 6 × 1 cm, Δx = 2 mm,
/// clamped at one end, blade at 0.5 m/s: it bent 2 cm down and stayed whole). The cut front therefore
/// runs one support radius ahead of the edge.
#[derive(Clone, Copy, Debug)]
pub struct Blade {
    pub axis: usize,
    pub a: Vec3,
    pub b: Vec3,
    pub reach: f32,
}

/// The blades of the `blade_cut` scalpels among `objects` at the poses `geoms`.
pub fn blades(p: &Params, objects: &[BoundaryObject], geoms: &[ObjectGeom]) -> Vec<Blade> {
    objects
        .iter()
        .zip(geoms)
        .filter_map(|(o, g)| blade_axis(o, p.dim.n()).map(|axis| Blade { axis, a: g.a, b: g.b, reach: p.k_solid.r }))
        .collect()
}

/// Is bond (i, j) cut by the blade? Tested from the lower index's end (`i_first` = i < j), so that i
/// and j, each testing its own list, take the same decision bit for bit.
#[inline]
pub fn bond_cut(bl: &Blade, xi: Vec3, xj: Vec3, i_first: bool, period: Vec3, dims: usize) -> bool {
    let (p, q) = if i_first { (xi, xj) } else { (xj, xi) };
    blade_crosses(bl, p, min_image(q - p, period), dims)
}

/// Does the segment x_i → x_i + d cross the blade? (Strictly opposite sides of its plane, and the
/// crossing point inside the rectangle.) Same f32 operations as `blade_crosses` in fracture.wgsl.
#[inline]
pub fn blade_crosses(bl: &Blade, xi: Vec3, d: Vec3, dims: usize) -> bool {
    let ax = bl.axis;
    let mid = 0.5 * (bl.a[ax] + bl.b[ax]);
    let di = xi[ax] - mid;
    let dj = (xi[ax] + d[ax]) - mid;
    if di * dj >= 0.0 {
        return false;
    }
    let t = di / (di - dj);
    (0..dims).filter(|&k| k != ax).all(|k| {
        let c = xi[k] + d[k] * t;
        c >= bl.a[k] - bl.reach && c <= bl.b[k] + bl.reach
    })
}

/// Builds C(i) = { j ≠ i : |x_j − x_i| < 2h_s } in ascending j, sized to the largest neighbourhood.
pub fn fracture_build_bonds(p: &Params, s: &mut SolidSet, list: &CellList) {
    let n = s.x.len();
    let radius = 2.0 * p.k_solid.h;
    let nb = Neighbours { grid: &p.grid, list, period: p.periodic_len(), three_d: p.dim.n() == 3 };
    let mut lists: Vec<Vec<u32>> = Vec::with_capacity(n);
    for i in 0..n {
        let mut l = Vec::new();
        nb.for_each(s.x[i], radius, |j, _, _| {
            if j != i {
                l.push(j as u32);
            }
        });
        l.sort_unstable();
        lists.push(l);
    }
    let cap = lists.iter().map(|l| l.len()).max().unwrap_or(0).max(1);
    s.bond_capacity = cap;
    s.bonds = vec![u32::MAX; n * cap];
    s.bond_limit = vec![0.0; n * cap];
    s.bond_count = vec![0; n];
    let radius2 = radius * radius;
    let period = p.periodic_len();
    for (i, l) in lists.iter().enumerate() {
        s.bonds[i * cap..i * cap + l.len()].copy_from_slice(l);
        s.bond_count[i] = l.len() as u32;
        for (k, &j) in l.iter().enumerate() {
            // Thesis criterion: r > 2h_s breaks. A bond born near 2h_s would break at a few per cent
            // strain (a lattice artefact); a critical stretch λ_c lets it reach λ_c r₀ first.
            s.bond_limit[i * cap + k] = match p.critical_stretch {
                Some(lc) => {
                    let r0 = min_image(s.x[i] - s.x[j as usize], period).length() * lc;
                    radius2.max(r0 * r0)
                }
                None => radius2,
            };
        }
    }
    s.bond_count0 = s.bond_count.clone();
}

/// Drops bonds stretched beyond their breaking length (`bond_limit`) or crossing a blade; returns how
/// many bonds (pairs) broke this step.
pub fn fracture_apply(p: &Params, s: &mut SolidSet, blades: &[Blade]) -> u64 {
    let dims = p.dim.n();
    let period = p.periodic_len();
    let cap = s.bond_capacity;
    if cap == 0 {
        return 0;
    }
    let x = &s.x;
    // each particle rewrites only its own row of the table: rows in parallel, as the GPU's threads
    let removed_ends: u64 = s
        .bonds
        .par_chunks_mut(cap)
        .zip(s.bond_limit.par_chunks_mut(cap))
        .zip(s.bond_count.par_iter_mut())
        .enumerate()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|(i, ((bonds, limits), count))| {
            let n = *count as usize;
            let mut keep = 0usize;
            for k in 0..n {
                let j = bonds[k] as usize;
                let limit2 = limits[k];
                if min_image(x[i] - x[j], period).length_squared() <= limit2
                    && !blades.iter().any(|bl| bond_cut(bl, x[i], x[j], i < j, period, dims))
                {
                    bonds[keep] = j as u32;
                    limits[keep] = limit2;
                    keep += 1;
                }
            }
            bonds[keep..n].fill(u32::MAX);
            limits[keep..n].fill(0.0);
            *count = keep as u32;
            (n - keep) as u64
        })
        .sum();
    removed_ends / 2
}
