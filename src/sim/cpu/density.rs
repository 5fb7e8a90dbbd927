//! Densities, volume fractions and penalty pressures — twin of `shaders/density.wgsl`.
//!
//! * `density_liquid`: ρˡ by summation over L ∪ B_l (2.46), nˡ = ρ/ρ₀ˡ, nˢ by summation of the solid
//!   (SPEC D-8) and of the solid-equivalent mass of walls that stand in the tissue's place (a needle's
//!   walls in its cavity: §4.1's continuation of the phase), pˡ = k_sat(nˢ + nˡ − 1 + C₁nˢnˡ) (2.53)/(3.5, D-9), clamped at 0 unless
//!   `liquid_tension` (the liquid sustains no tension; README: deviations from SPEC) and nˢ is below
//!   `liquid_tension_below_ns` or the particle lies in a `liquid_tension_in` region; plus the ambient
//!   pressure p_a (`numerics.ambient_pressure`) before the clamp; in an outlet's buffer the outlet's
//!   prescribed p_a + gauge and the density of pure liquid at it instead.
//! * `density_solid`: nˢ = ρ/ρ₀ˢ, nˡ by summation of the liquid and the walls' liquid-equivalent mass
//!   m_b^l (D-8 with §4.1's boundary as a continuation of the liquid, as in (2.46); README: deviations
//!   from SPEC; membrane override 1 − nˢ_sat, §3.1.3),
//!   pˢ = k_s(nˢ − nˢ_sat) + k_sat(nˢ + nˡ − 1) (2.52); without `sum_liquid` (`density_solid_kept`,
//!   evaluation 0) nˡ is the one of the previous step's evaluation 1, on the same positions, and the
//!   pass walks nothing. The solid's continuity dρˢ/dt (2.47) over current solid neighbours and B_s is
//!   summed by `forces::forces_solid` in its walks over the same pairs (a separate walk cost both
//!   back-ends ≈ 10 % of a step).

use super::forces::{capsule_inner, capsule_normal};
use super::{BoundarySet, LiquidSet, Nbrs, SolidSet};
use crate::scenario::SolidFlags;
use crate::sim::params::{OutletRegion, Params};
use rayon::prelude::*;

/// What `density_liquid` gives every liquid particle.
#[derive(Clone, Debug, Default)]
pub struct LiquidDensities {
    pub rho: Vec<f32>,
    pub n_s: Vec<f32>,
    pub p: Vec<f32>,
    /// Whether it counts a blood ghost of the capsule (`sim::ghosts`): then the capsule's particles are
    /// no wall for it (the ghosts stand for the blood beyond).
    pub sees_ghost: Vec<bool>,
}

/// Returns ρ, nˢ and p for every liquid particle, and whether it sees a blood ghost; `outlets` are the
/// pressure outlets in effect.
pub fn density_liquid(
    p: &Params,
    outlets: &[OutletRegion],
    l: &LiquidSet,
    s: &SolidSet,
    b: &BoundarySet,
    nb: &Nbrs,
) -> LiquidDensities {
    let kl = &p.k_liquid;
    let kx = &p.k_cross;
    let out: Vec<(f32, f32, f32, bool)> = (0..l.x.len())
        .into_par_iter()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|i| {
            let xi = l.x[i];
            let mut rho = 0.0f32;
            nb.liquid.for_each(xi, kl.r, |j, _, r| rho += l.m[j] * kl.w_poly6(r));
            // the walls continue the liquid in ρ (2.46) within R_l and, where they stand in the tissue's
            // place, the solid in nˢ within R_× (§4.1; README: deviations from SPEC)
            let mut sum_bs = 0.0f32;
            nb.boundary.for_each(xi, kl.r.max(kx.r), |j, _, r| {
                if r < kl.r {
                    rho += b.m_l[j] * kl.w_poly6(r);
                }
                if r < kx.r {
                    sum_bs += b.m_sn[j] * kx.w_poly6(r);
                }
            });
            // the capsule's ghost sites (`sim::ghosts`): tissue sites in nˢ within R_×, blood sites in ρ
            // within R_l
            let mut sum_s = 0.0f32;
            let mut sees = false;
            if let Some(gn) = &nb.ghosts {
                gn.for_each(xi, kx.r.max(kl.r), |g, _, r| {
                    if r < kl.r && gn.gh.m_l[g] > 0.0 {
                        sees = true;
                        rho += gn.gh.m_l[g] * kl.w_poly6(r);
                    }
                    if r < kx.r {
                        sum_s += gn.gh.m_s[g] * kx.w_poly6(r);
                    }
                });
            }
            // One pass over the solid (R_× ≥ R_l): membrane particles as liquid boundary, and nˢ.
            nb.solid.for_each(xi, kx.r, |j, xij, r| {
                if s.flags[j] & SolidFlags::MEMBRANE != 0 {
                    let n = capsule_normal(s.def_grad[j], s.normal0[j]);
                    // a boundary particle (2.46) unless the ghosts continue the liquid here (`capsule_inner`)
                    if !capsule_inner(p, n, xij) && r < kl.r && !sees {
                        rho += s.m_bl[j] * kl.w_poly6(r);
                    }
                }
                sum_s += s.m[j] * kx.w_poly6(r);
            });
            let n_s = (sum_s + sum_bs) / p.rho0_s;
            let n_l = rho / p.rho0_l;
            let raw = p.ambient_pressure + p.k_l * (n_s + n_l - 1.0 + p.c1 * n_s * n_l);
            // p_a + (2.53) clamped at 0 unless the liquid may take tension here (`liquid_tension_below_ns`,
            // `liquid_tension_in`); an outlet's buffer carries its prescribed pressure and density
            match OutletRegion::find(outlets, xi) {
                Some(o) => (o.density, n_s, o.pressure, sees),
                None if p.liquid_may_pull(xi, n_s) => (rho, n_s, raw, sees),
                None => (rho, n_s, raw.max(0.0), sees),
            }
        })
        .collect();
    let mut d = LiquidDensities {
        rho: Vec::with_capacity(out.len()),
        n_s: Vec::with_capacity(out.len()),
        p: Vec::with_capacity(out.len()),
        sees_ghost: Vec::with_capacity(out.len()),
    };
    for (a, b, c, e) in out {
        d.rho.push(a);
        d.n_s.push(b);
        d.p.push(c);
        d.sees_ghost.push(e);
    }
    d
}

/// Returns (nˡ, nˢ, p) for every solid particle; nˡ summed over the liquid and the walls (`density_solid`)
/// or, without `sum_liquid`, the one `s` holds (`density_solid_kept`: evaluation 0 of a step keeps the nˡ
/// of the previous step's evaluation 1, taken on the same positions). The continuity dρ/dt (2.47) is
/// summed in `forces::forces_solid`'s walks over the same neighbours.
pub fn density_solid(
    p: &Params,
    s: &SolidSet,
    l: &LiquidSet,
    b: &BoundarySet,
    nb: &Nbrs,
    sum_liquid: bool,
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let kx = &p.k_cross;
    let n_l_membrane = 1.0 - p.n_sat;
    let out: Vec<(f32, f32, f32)> = (0..s.x.len())
        .into_par_iter()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|i| {
            let xi = s.x[i];
            let n_l = if s.flags[i] & SolidFlags::MEMBRANE != 0 {
                n_l_membrane
            } else if !sum_liquid {
                s.n_l[i]
            } else {
                // the walls' liquid-equivalent mass m_b^l within R_×: a wall continues the liquid in the
                // solid's fraction as it does in the liquid's ρ (2.46)
                let mut sum_b = 0.0f32;
                nb.boundary.for_each(xi, kx.r, |j, _, r| sum_b += b.m_l[j] * kx.w_poly6(r));
                let mut sum = 0.0f32;
                nb.liquid.for_each(xi, kx.r, |j, _, r| sum += l.m[j] * kx.w_poly6(r));
                (sum + sum_b) / p.rho0_l
            };
            let n_s = s.rho[i] / p.rho0_s;
            let pr = p.k_s * (n_s - p.n_sat) + p.k_sat * (n_s + n_l - 1.0);
            (n_l, n_s, pr)
        })
        .collect();
    let mut a = Vec::with_capacity(out.len());
    let mut bb = Vec::with_capacity(out.len());
    let mut c = Vec::with_capacity(out.len());
    for (x, y, z) in out {
        a.push(x);
        bb.push(y);
        c.push(z);
    }
    (a, bb, c)
}
