//! Predictor–corrector leapfrog (2.64)–(2.68) with XSPH advection (2.69) — twin of
//! `shaders/integrate.wgsl`. Positions are advanced once per step by Δt ṽⁿ + ½Δt²a⁰ and not corrected;
//! velocities and solid densities are predicted and corrected (SPEC §5.1). Kinematic solid particles
//! keep their prescribed (here: fixed) state.

use super::CpuState;
use crate::scenario::SolidFlags;
use crate::sim::params::Params;
use glam::Vec3;
use rayon::prelude::*;

/// integrate_predict: a⁰ ← a, D⁰ ← D, solid increments Δx = Δt ṽ + ½Δt²a⁰, v^p = vⁿ + Δt a⁰ (2.64).
/// Positions and solid densities are advanced by `integrate_advance`, after the F update has read xⁿ, ρⁿ.
/// Liquid inside an inlet's buffer (`emit::inlet_velocity`) moves with the buffer, unaccelerated.
pub fn integrate_predict(p: &Params, st: &mut CpuState, dt: f32, _t_next: f64) {
    let half_dt2 = 0.5 * dt * dt;
    let three_d = p.dim.n() == 3;
    let l = &mut st.liquid;
    let emit = &st.emit;
    let x = &l.x;
    l.a0.par_iter_mut().zip(l.a.par_iter()).zip(l.v.par_iter_mut()).enumerate().for_each(|(i, ((a0, a), v))| {
        match super::emit::inlet_velocity(emit, x[i], three_d) {
            Some(u) => {
                *a0 = Vec3::ZERO;
                *v = u;
            }
            None => {
                *a0 = *a;
                *v += *a0 * dt;
            }
        }
    });
    let s = &mut st.solid;
    s.a0.clone_from(&s.a);
    s.drho0.clone_from(&s.drho);
    let flags = &s.flags;
    s.dx.par_iter_mut().zip(s.v.par_iter_mut()).enumerate().for_each(|(i, (dx, v))| {
        if flags[i] & SolidFlags::KINEMATIC != 0 {
            *dx = Vec3::ZERO;
            *v = Vec3::ZERO;
        } else {
            *dx = s.vx[i] * dt + s.a0[i] * half_dt2;
            *v += s.a0[i] * dt;
        }
    });
}

/// Wraps a position into the domain on periodic axes (SPEC §4.3).
#[inline]
pub fn wrap_periodic(p: &Params, mut x: Vec3) -> Vec3 {
    for a in 0..3 {
        if p.periodic[a] {
            let lo = p.domain_min[a];
            let len = p.domain_max[a] - lo;
            x[a] = lo + (x[a] - lo).rem_euclid(len);
        }
    }
    x
}

/// integrate_advance: xⁿ⁺¹ = xⁿ + Δt ṽⁿ + ½Δt²a⁰ (2.65), ρ^p = ρⁿ + Δt D⁰ (2.66).
pub fn integrate_advance(p: &Params, st: &mut CpuState, dt: f32) {
    let half_dt2 = 0.5 * dt * dt;
    let three_d = p.dim.n() == 3;
    let l = &mut st.liquid;
    let (vx, a0, emit) = (&l.vx, &l.a0, &st.emit);
    l.x.par_iter_mut().enumerate().for_each(|(i, x)| {
        let adv = super::emit::inlet_velocity(emit, *x, three_d).unwrap_or(vx[i]);
        *x = wrap_periodic(p, *x + adv * dt + a0[i] * half_dt2)
    });
    let s = &mut st.solid;
    let (dx, drho0) = (&s.dx, &s.drho0);
    s.x.par_iter_mut().enumerate().for_each(|(i, x)| *x = wrap_periodic(p, *x + dx[i]));
    let flags = &s.flags;
    s.rho.par_iter_mut().enumerate().for_each(|(i, r)| {
        if flags[i] & SolidFlags::KINEMATIC == 0 {
            *r += dt * drho0[i];
        }
    });
}

/// integrate_correct: vⁿ⁺¹ = v^p + ½Δt(a¹ − a⁰) (2.67), ρⁿ⁺¹ = ρ^p + ½Δt(D¹ − D⁰) (2.68), then the
/// relaxation damping v ← v(1 − ζΔt) when active (SPEC §7.5).
pub fn integrate_correct(p: &Params, st: &mut CpuState, dt: f32) {
    let damp = (1.0 - st.damping * dt).max(0.0);
    let three_d = p.dim.n() == 3;
    let l = &mut st.liquid;
    let (a, a0, x, emit) = (&l.a, &l.a0, &l.x, &st.emit);
    l.v.par_iter_mut().enumerate().for_each(|(i, v)| {
        *v = match super::emit::inlet_velocity(emit, x[i], three_d) {
            Some(u) => u,
            None => (*v + (a[i] - a0[i]) * (0.5 * dt)) * damp,
        }
    });
    let s = &mut st.solid;
    let (a, a0, d, d0, flags) = (&s.a, &s.a0, &s.drho, &s.drho0, &s.flags);
    s.v.par_iter_mut().zip(s.rho.par_iter_mut()).enumerate().for_each(|(i, (v, r))| {
        if flags[i] & SolidFlags::KINEMATIC == 0 {
            *v = (*v + (a[i] - a0[i]) * (0.5 * dt)) * damp;
            *r += 0.5 * dt * (d[i] - d0[i]);
        }
    });
}
