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

/// A blade at its current pose: the plane x\[axis\] = (a + b)\[axis\]/2, bounded by [a, b] grown by
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

/// Can a bond of particle x_i no longer than `bond_reach` (`Params::bond_reach`) cross the blade? Such a
/// bond has its ends on either side of the blade's plane, and its crossing point lies in the grown
/// rectangle within `bond_reach` of x_i; the test is conservative (a margin of 10⁻³ of the reach, far
/// above f32 rounding), so skipping the bonds of a particle it rejects changes no result — it spares
/// the per-bond test to the particles far from every blade, most of an organ. `bond_reach` = 0 (a
/// periodic domain): always true.
#[inline]
pub fn blade_near(bl: &Blade, xi: Vec3, bond_reach: f32, dims: usize) -> bool {
    if bond_reach <= 0.0 {
        return true;
    }
    let r = bond_reach * 1.001;
    let ax = bl.axis;
    let mid = 0.5 * (bl.a[ax] + bl.b[ax]);
    (xi[ax] - mid).abs() <= r
        && (0..dims).filter(|&k| k != ax).all(|k| xi[k] >= bl.a[k] - bl.reach - r && xi[k] <= bl.b[k] + bl.reach + r)
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
    let reach = p.bond_reach();
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
            let near = blades.iter().any(|bl| blade_near(bl, x[i], reach, dims));
            for k in 0..n {
                let j = bonds[k] as usize;
                let limit2 = limits[k];
                if min_image(x[i] - x[j], period).length_squared() <= limit2
                    && !(near && blades.iter().any(|bl| bond_cut(bl, x[i], x[j], i < j, period, dims)))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// `blade_near` never rejects a particle with a bond that `bond_cut` cuts: 200 000 random bonds up
    /// to the reach, half of them around the blade's edges, tested from both ends; and it does reject
    /// most particles of a box fifteen reaches wide (else it would spare nothing).
    #[test]
    fn blade_near_keeps_every_bond_the_blade_cuts() {
        let reach = 0.013f32 * 1.3;
        let bl = Blade { axis: 0, a: Vec3::new(0.01, -0.04, -0.03), b: Vec3::new(0.014, 0.05, 0.02), reach: 0.013 };
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut cut, mut near, mut total) = (0, 0, 0);
        for k in 0..200_000 {
            // every other particle within a few reaches of the blade's edges, the rest anywhere in the box
            let scale = if k % 2 == 0 { Vec3::new(0.06, 0.14, 0.1) } else { Vec3::splat(0.26) };
            let xi = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * scale;
            let dir = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize_or_zero();
            let xj = xi + dir * reach * rnd();
            if k % 2 == 1 {
                total += 1;
                if blade_near(&bl, xi, reach, 3) {
                    near += 1;
                }
            }
            for i_first in [true, false] {
                if bond_cut(&bl, xi, xj, i_first, Vec3::ZERO, 3) {
                    cut += 1;
                    assert!(blade_near(&bl, xi, reach, 3), "cut bond {xi:?}–{xj:?} rejected from x_i");
                    assert!(blade_near(&bl, xj, reach, 3), "cut bond {xi:?}–{xj:?} rejected from x_j");
                }
            }
        }
        eprintln!("{cut} cuts; {near} of {total} particles near the blade");
        assert!(cut > 1000, "the test must cut bonds ({cut})");
        assert!(near < total / 5, "the filter must reject most of the box ({near} of {total})");
        assert!(blade_near(&bl, Vec3::new(0.5, 0.5, 0.5), 0.0, 3), "no reach (periodic): never rejects");
    }
}
