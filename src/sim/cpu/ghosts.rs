//! The capsule's ghost sites per step (`sim::ghosts` builds them) — twin of `shaders/ghosts.wgsl`.
//!
//! * `ghost_place` (with every grid build): x_g = x_o + F_o d, the owner's capsule normal n̂_o
//!   (`capsule_normal`), the offset F_o d, and whether the owner still seals (`capsule_seals`; with the
//!   seal off, always). The ghosts are binned on these positions like the three particle sets.
//! * [`GhostNbrs::for_each`]: the ghosts a liquid particle at x_i counts — its owner seals, and x_i lies
//!   beneath the organ's surface s = Δx_s/2 beyond the owner by the capsule's normal or along the
//!   ghost's own offset, (x_i − x_o)·n̂_o ≤ s ∨ (x_i − x_o)·F_o d ≤ s|F_o d| (near an edge the
//!   detection's normal is tilted and fails the first for the edge's blood; the blood lattice's misfit
//!   to the tissue's fails the second at faces). `density_liquid` adds tissue ghosts to nˢ (D-8) and
//!   blood ghosts to ρ (2.46).
//! * `ghost_pressure` (after `density_liquid`): each blood ghost's wall pressure and density, the
//!   Shepard means Σ p_j W / Σ W, Σ ρ_j W / Σ W over the liquid that counts it (Adami, Hu & Adams 2012,
//!   without their body-force term; p clamped at 0), and the reaction of its boundary force (§4.1) on
//!   that liquid, which its owner gathers in `forces_solid`.

use super::forces::{capsule_normal, capsule_seal_offset, capsule_seals, liquid_from_boundary};
use super::grid::Neighbours;
use super::{LiquidSet, ObjectContact, SolidSet};
use crate::sim::ghosts::Ghosts;
use crate::sim::params::Params;
use glam::Vec3;
use rayon::prelude::*;

/// The ghosts where the last grid build placed them (`ghost_place`).
#[derive(Clone, Debug, Default)]
pub struct Placed {
    pub x: Vec<Vec3>,
    /// F_o d: the ghost's offset from its owner now.
    pub fd: Vec<Vec3>,
    /// The owner's outward capsule normal now (zero where F is degenerate).
    pub n: Vec<Vec3>,
    /// Whether the owner still seals.
    pub seals: Vec<bool>,
}

/// Places every ghost at x_o + F_o d (twin: `ghost_place` in ghosts.wgsl).
pub fn ghost_place(p: &Params, gh: &Ghosts, s: &SolidSet) -> Placed {
    let n = gh.len();
    let mut out = Placed {
        x: Vec::with_capacity(n),
        fd: Vec::with_capacity(n),
        n: Vec::with_capacity(n),
        seals: Vec::with_capacity(n),
    };
    for g in 0..n {
        let o = gh.owner[g] as usize;
        let fd = s.def_grad[o] * gh.d[g];
        out.x.push(s.x[o] + fd);
        out.fd.push(fd);
        out.n.push(capsule_normal(s.def_grad[o], s.normal0[o]));
        out.seals.push(p.capsule_seal <= 0.0 || capsule_seals(s.bond_count[o], s.bond_count0[o]));
    }
    out
}

/// Each blood ghost's wall pressure and density and the reaction of its boundary force (`ghost_pressure`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GhostState {
    pub p: f32,
    pub rho: f32,
    /// Σ of −m_i a_i over the liquid it acts on \[N\] (the ambient pressure taken off both sides).
    pub reaction: Vec3,
}

/// The ghosts as a neighbour set.
pub struct GhostNbrs<'a> {
    pub p: &'a Params,
    pub nbrs: Neighbours<'a>,
    pub gh: &'a Ghosts,
    pub placed: &'a Placed,
    /// `ghost_pressure`'s result (empty before it ran).
    pub state: &'a [GhostState],
}

/// Whether liquid at x_i − x_g = `xig` counts ghost g (its owner sealing): x_i beneath the organ's
/// surface at the owner — by the owner's normal or along the ghost's offset — which lies `surface`
/// beyond the owner's particle (`forces::capsule_seal_offset`: Δx_s/2, where the seal holds the blood).
/// Blood in the half spacing between the capsule's particles and the surface still counts the ghosts
/// beyond; counted only beneath the particles' plane, it lost every ghost at once as it crossed the
/// plane (nˢ, ρ and its pressure dropped, the capsule particle became its wall) and jolted the capsule.
/// Twin of `ghost_side_counts` in common.wgsl.
#[inline]
pub fn ghost_counts(pl: &Placed, g: usize, xig: Vec3, surface: f32) -> bool {
    if !pl.seals[g] {
        return false;
    }
    let (xio, fd) = (xig + pl.fd[g], pl.fd[g]);
    (pl.n[g] != Vec3::ZERO && xio.dot(pl.n[g]) <= surface) || xio.dot(fd) <= surface * fd.length()
}

impl GhostNbrs<'_> {
    /// Calls f(g, x_i − x_g, r) for every ghost within `radius` of x_i that liquid there counts.
    #[inline]
    pub fn for_each(&self, xi: Vec3, radius: f32, mut f: impl FnMut(usize, Vec3, f32)) {
        let surface = capsule_seal_offset(self.p);
        self.nbrs.for_each(xi, radius, |g, xig, r| {
            if ghost_counts(self.placed, g, xig, surface) {
                f(g, xig, r)
            }
        });
    }
}

/// Acceleration of liquid i (ρ, p, nˡ, v) from blood ghost g of mass m_g at x_i − x_g = `xig`, r, whose
/// owner moves at `v_o`: the boundary force of §4.1 with the ghost's wall pressure and density (SPEC's
/// bracket p_i/ρ_i² + p_g/ρ_g²) and the no-slip viscous term; `outside` is taken off both pressures
/// (0 on the liquid; the ambient p_a for the reaction on the owner, as for the capsule's particles).
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn ghost_on_liquid(
    p: &Params,
    rho: f32,
    pr: f32,
    n_l: f32,
    vi: Vec3,
    m_g: f32,
    v_o: Vec3,
    xig: Vec3,
    r: f32,
    st: &GhostState,
    outside: f32,
) -> Vec3 {
    let mode = ObjectContact { density: st.rho, pressure: st.p - outside, friction: -1.0 };
    liquid_from_boundary(p, rho, pr - outside, n_l, vi, m_g, v_o, xig, r, mode, 1.0, Vec3::ZERO, 0.0)
}

/// Every ghost's wall pressure, density and reaction (tissue ghosts and ghosts no liquid counts: zero).
pub fn ghost_pressure(
    p: &Params,
    gh: &Ghosts,
    pl: &Placed,
    l: &LiquidSet,
    s: &SolidSet,
    liquid: &Neighbours,
) -> Vec<GhostState> {
    let kl = &p.k_liquid;
    (0..gh.len())
        .into_par_iter()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|g| {
            let m_g = gh.m_l[g];
            if m_g <= 0.0 {
                return GhostState::default();
            }
            let xg = pl.x[g];
            let surface = capsule_seal_offset(p);
            let (mut sw, mut sp, mut sr) = (0.0f32, 0.0f32, 0.0f32);
            liquid.for_each(xg, kl.r, |j, xgj, r| {
                if ghost_counts(pl, g, -xgj, surface) {
                    let w = kl.w_poly6(r);
                    sw += w;
                    sp += l.p[j] * w;
                    sr += l.rho[j] * w;
                }
            });
            if sw <= 0.0 {
                return GhostState::default();
            }
            let mut st = GhostState { p: (sp / sw).max(0.0), rho: sr / sw, reaction: Vec3::ZERO };
            let v_o = s.v[gh.owner[g] as usize];
            let mut reaction = Vec3::ZERO;
            liquid.for_each(xg, kl.r, |j, xgj, r| {
                if ghost_counts(pl, g, -xgj, surface) {
                    let a = ghost_on_liquid(
                        p,
                        l.rho[j],
                        l.p[j],
                        l.n_l[j],
                        l.v[j],
                        m_g,
                        v_o,
                        -xgj,
                        r,
                        &st,
                        p.ambient_pressure,
                    );
                    reaction -= a * l.m[j];
                }
            });
            st.reaction = reaction;
            st
        })
        .collect()
}
