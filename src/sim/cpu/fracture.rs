//! Connectivity table and irreversible fracture (thesis §3.1.4, Algorithm 2; SPEC §4.6) — twin of
//! `shaders/fracture.wgsl`. Bonds are built once from a radius search; after each corrector every
//! particle drops the bonds whose separation exceeds the searching radius 2h_s. Each particle tests its
//! own list with the same rule, so removal is symmetric and needs no atomics; order is preserved.

use super::SolidSet;
use super::grid::{CellList, Neighbours, min_image};
use crate::sim::params::Params;

/// Builds C(i) = { j ≠ i : |x_j − x_i| < 2h_s } in ascending j, sized to the largest neighbourhood.
pub fn fracture_build_bonds(p: &Params, s: &mut SolidSet, list: &CellList) {
    let n = s.x.len();
    let radius = 2.0 * p.k_solid.h;
    let nb = Neighbours { grid: &p.grid, list, pos: &s.x, period: p.periodic_len(), three_d: p.dim.n() == 3 };
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

/// Drops bonds stretched beyond their breaking length (`bond_limit`); returns how many bonds (pairs) broke this step.
pub fn fracture_apply(p: &Params, s: &mut SolidSet) -> u64 {
    let period = p.periodic_len();
    let cap = s.bond_capacity;
    let mut removed_ends = 0u64;
    for i in 0..s.x.len() {
        let n = s.bond_count[i] as usize;
        let mut keep = 0usize;
        for k in 0..n {
            let j = s.bonds[i * cap + k] as usize;
            let limit2 = s.bond_limit[i * cap + k];
            if min_image(s.x[i] - s.x[j], period).length_squared() <= limit2 {
                s.bonds[i * cap + keep] = j as u32;
                s.bond_limit[i * cap + keep] = limit2;
                keep += 1;
            } else {
                removed_ends += 1;
            }
        }
        for k in keep..n {
            s.bonds[i * cap + k] = u32::MAX;
            s.bond_limit[i * cap + k] = 0.0;
        }
        s.bond_count[i] = keep as u32;
    }
    removed_ends / 2
}
