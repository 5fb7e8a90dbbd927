//! The capsule's ghost sites (`membrane.ghosts`; README: deviations from SPEC, "The capsule's missing
//! lattice sites as ghosts"), built once from the generated configuration for both back-ends.
//!
//! Beneath a single layer of capsule particles the blood sees half a kernel of tissue and of blood:
//! the organ's surface truncates the tissue's and the blood's lattices, so its nˢ (SPEC D-8) and its ρ
//! (2.46) fall short of the generated fractions at faces, edges and corners, and the pressure (2.53)
//! pushes it outward. Every lattice site of either phase that is missing within the kernel's radius R of
//! the body (R_× for the tissue, R_l for the blood) becomes a ghost site: owned by its nearest capsule
//! particle o as a reference offset d = X_site − X_o, placed at x_o + F_o d whenever the grids are built
//! (the site moves with the capsule's deformation), and counted by blood beneath the owner's intact
//! capsule — a tissue ghost in nˢ, a blood ghost in ρ and as a boundary particle of the pressure force
//! (SPEC §4.1, with the wall pressure of Adami, Hu & Adams 2012: the Shepard mean of the blood that sees
//! it). Liquid ghosts inside a wall or a plate are dropped: the wall continues the liquid there already.
//!
//! The per-step passes are `sim::cpu::ghosts` and `shaders/ghosts.wgsl`.

use crate::scenario::SolidFlags;
use crate::sim::cpu::forces::ObjectGeom;
use crate::sim::params::Params;
use glam::Vec3;
use std::collections::{HashMap, HashSet};

/// The ghost sites, sorted by owner.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Ghosts {
    /// The owning capsule particle (a membrane parent on the tissue's lattice).
    pub owner: Vec<u32>,
    /// The site's offset from its owner in the generated configuration.
    pub d: Vec<Vec3>,
    /// A tissue site's mass (the tissue's lattice mass), else 0.
    pub m_s: Vec<f32>,
    /// A blood site's mass (the blood's lattice mass), else 0.
    pub m_l: Vec<f32>,
    /// Ghosts of solid particle j: `start[j] .. start[j + 1]` (length = solid count + 1).
    pub start: Vec<u32>,
}

/// Lattice coordinates of `x` on the lattice through `origin` of spacing `dx`, if it lies on a site.
fn site(x: Vec3, origin: Vec3, dx: f32) -> Option<[i32; 3]> {
    let q = (x - origin) / dx;
    let r = q.round();
    ((q - r).abs().max_element() < 1e-2).then_some([r.x as i32, r.y as i32, r.z as i32])
}

/// The sites within `radius` of some site of `sites` (a sphere of lattice offsets around each) that are
/// not themselves in `sites`, in ascending order.
fn missing_sites(sites: &HashSet<[i32; 3]>, dx: f32, radius: f32) -> Vec<[i32; 3]> {
    let n = (radius / dx).ceil() as i32;
    let mut offsets = Vec::new();
    for a in -n..=n {
        for b in -n..=n {
            for c in -n..=n {
                if (((a * a + b * b + c * c) as f32).sqrt() * dx) < radius {
                    offsets.push([a, b, c]);
                }
            }
        }
    }
    let mut missing = HashSet::new();
    for k in sites {
        for o in &offsets {
            let q = [k[0] + o[0], k[1] + o[1], k[2] + o[2]];
            if !sites.contains(&q) {
                missing.insert(q);
            }
        }
    }
    let mut missing: Vec<[i32; 3]> = missing.into_iter().collect();
    missing.sort_unstable();
    missing
}

impl Ghosts {
    /// No ghosts.
    pub fn none(solid_count: usize) -> Ghosts {
        Ghosts { start: vec![0; solid_count + 1], ..Default::default() }
    }

    pub fn len(&self) -> usize {
        self.owner.len()
    }

    pub fn is_empty(&self) -> bool {
        self.owner.is_empty()
    }

    /// The ghost sites of the generated configuration: solid positions `x_ref` with `flags` and outward
    /// normals `normal0` (membrane parents lie on the tissue's lattice, their children off it), masses
    /// `m_s`; the generated liquid `x_l` with masses `m_l`; the objects' shapes `geoms` at t = 0. Empty
    /// unless `membrane.ghosts` (3-D only).
    pub fn build(
        p: &Params,
        x_ref: &[Vec3],
        flags: &[u32],
        normal0: &[Vec3],
        m_s: &[f32],
        x_l: &[Vec3],
        m_l: &[f32],
        geoms: &[ObjectGeom],
    ) -> Ghosts {
        let ns = x_ref.len();
        let (dxs, dxl) = (p.capsule_dx_solid, p.capsule_dx_liquid);
        let tissue = (0..ns).find(|&i| flags[i] & (SolidFlags::MEMBRANE | SolidFlags::KINEMATIC) == 0);
        let (Some(first), true) = (tissue, p.capsule_ghosts && p.dim.n() == 3 && dxs > 0.0 && dxl > 0.0) else {
            return Ghosts::none(ns);
        };
        // the tissue's lattice: every solid particle on it (the capsule's parents included, its children
        // and any off-lattice particle not), by site
        let os = x_ref[first];
        let solid_site: HashMap<[i32; 3], usize> =
            (0..ns).filter_map(|i| site(x_ref[i], os, dxs).map(|k| (k, i))).collect();
        let m_site = m_s[first];
        let search = (p.k_cross.r.max(p.k_liquid.r) / dxs).ceil() as i32 + 1;
        // the nearest tissue site to q (ties: the lowest index), if it is a capsule parent and q lies
        // beyond its plane
        let owner_of = |q: Vec3| -> Option<usize> {
            let c = ((q - os) / dxs).round();
            let c = [c.x as i32, c.y as i32, c.z as i32];
            let mut best = (f32::INFINITY, usize::MAX);
            for a in -search..=search {
                for b in -search..=search {
                    for e in -search..=search {
                        if let Some(&i) = solid_site.get(&[c[0] + a, c[1] + b, c[2] + e]) {
                            let d2 = (x_ref[i] - q).length_squared();
                            if d2 < best.0 || (d2 == best.0 && i < best.1) {
                                best = (d2, i);
                            }
                        }
                    }
                }
            }
            let o = best.1;
            (o != usize::MAX && flags[o] & SolidFlags::MEMBRANE != 0 && (q - x_ref[o]).dot(normal0[o]) > 0.0)
                .then_some(o)
        };
        let mut list: Vec<(u32, Vec3, f32, f32)> = Vec::new();
        let tissue_sites: HashSet<[i32; 3]> = solid_site.keys().copied().collect();
        for q in missing_sites(&tissue_sites, dxs, p.k_cross.r) {
            let x = os + Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) * dxs;
            if let Some(o) = owner_of(x) {
                list.push((o as u32, x - x_ref[o], m_site, 0.0));
            }
        }
        if let Some(&ol) = x_l.first() {
            let blood_sites: HashSet<[i32; 3]> = x_l.iter().filter_map(|&x| site(x, ol, dxl)).collect();
            for q in missing_sites(&blood_sites, dxl, p.k_liquid.r) {
                let x = ol + Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32) * dxl;
                // a wall or a plate continues the liquid there already (§4.1)
                if geoms.iter().any(|g| g.kind < 2 && crate::sim::cpu::emit::in_region(g, x, true)) {
                    continue;
                }
                if let Some(o) = owner_of(x) {
                    list.push((o as u32, x - x_ref[o], 0.0, m_l[0]));
                }
            }
        }
        list.sort_by_key(|e| e.0);
        let mut g = Ghosts::none(ns);
        for &(o, d, ms, ml) in &list {
            g.owner.push(o);
            g.d.push(d);
            g.m_s.push(ms);
            g.m_l.push(ml);
            g.start[o as usize + 1] += 1;
        }
        for j in 0..ns {
            g.start[j + 1] += g.start[j];
        }
        g
    }
}
