//! Time-step restriction (2.70) plus the explicit-friction bound and Δt_max (SPEC §5.3, D-27) — twin of
//! `shaders/dt.wgsl`. Minimum and maximum are exact in any order, so the parallel reduction is
//! deterministic.

use super::{LiquidSet, SolidSet};
use crate::scenario::SolidFlags;
use crate::sim::DtLimit;
use crate::sim::params::Params;
use rayon::prelude::*;

/// Returns Δt and the criterion that limited it.
pub fn dt_reduce(p: &Params, l: &LiquidSet, s: &SolidSet) -> (f32, DtLimit) {
    let a_max_l = l.a.par_iter().map(|a| a.length()).reduce(|| 0.0, f32::max);
    let a_max_s =
        s.a.par_iter()
            .zip(s.flags.par_iter())
            .map(|(a, f)| if f & SolidFlags::KINEMATIC != 0 { 0.0 } else { a.length() })
            .reduce(|| 0.0, f32::max);
    let a_max = a_max_l.max(a_max_s);
    let h = p.h_min();
    let mut best = (p.dt_max, DtLimit::Max);
    let mut consider = |dt: f32, why: DtLimit| {
        if dt < best.0 {
            best = (dt, why);
        }
    };
    if p.has_liquid && p.eta > 0.0 {
        let rho_min = l.rho.par_iter().copied().reduce(|| f32::INFINITY, f32::min);
        consider(p.cfl_viscous * rho_min * p.k_liquid.h * p.k_liquid.h / p.eta, DtLimit::Viscous);
    }
    let c = p.c_max();
    if c > 0.0 {
        consider(p.cfl_sound * h / (3.0 * c), DtLimit::Sound);
    }
    if a_max > 0.0 {
        consider(p.cfl_force * (h / (3.0 * a_max)).sqrt(), DtLimit::Force);
    }
    if p.kbar > 0.0 && p.has_liquid && p.has_solid {
        let fl = l
            .n_s
            .par_iter()
            .zip(l.rho.par_iter())
            .map(|(&ns, &r)| if ns > 1e-6 { p.kbar * (1.0 - ns).max(0.0) * (1.0 / r + 1.0 / p.rho_ref_s) } else { 0.0 })
            .reduce(|| 0.0, f32::max);
        // Kinematic solid particles integrate nothing: only dynamic ones bound the friction step.
        let fs = s
            .n_l
            .par_iter()
            .zip(s.n_s.par_iter().zip(s.rho.par_iter().zip(s.flags.par_iter())))
            .map(|(&nl, (&ns, (&r, &f)))| {
                if nl > 1e-6 && f & SolidFlags::KINEMATIC == 0 {
                    p.kbar * (1.0 - ns).max(0.0) * (1.0 / r + 1.0 / p.rho_ref_l)
                } else {
                    0.0
                }
            })
            .reduce(|| 0.0, f32::max);
        let f = fl.max(fs);
        if f > 0.0 {
            consider(p.cfl_friction / f, DtLimit::Friction);
        }
    }
    let dt = best.0 * p.cfl_factor;
    match p.fixed_dt {
        Some(fixed) => (fixed, DtLimit::Fixed),
        None => (dt, best.1),
    }
}
