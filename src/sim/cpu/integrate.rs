//! Predictor–corrector leapfrog (2.64)–(2.68) with XSPH advection (2.69) — twin of
//! `shaders/integrate.wgsl`. Positions are advanced once per step by Δt ṽⁿ + ½Δt²a⁰ and not corrected;
//! velocities and solid densities are predicted and corrected (SPEC §5.1). Kinematic solid particles
//! keep their prescribed (here: fixed) state.

use super::CpuState;
use super::forces::{ObjectGeom, box_exit};
use crate::scenario::SolidFlags;
use crate::sim::bed::{self, BedTable};
use crate::sim::params::{OutletRegion, Params};
use glam::Vec3;
use rayon::prelude::*;

/// integrate_predict: a⁰ ← a, D⁰ ← D, solid increments Δx = Δt ṽ + ½Δt²a⁰, v^p = vⁿ + Δt a⁰ (2.64).
/// Positions and solid densities are advanced by `integrate_advance`, after the F update has read xⁿ, ρⁿ.
/// Liquid inside an inlet's buffer (`emit::inlet_velocity`) moves with the buffer, unaccelerated;
/// liquid inside an outlet's buffer takes the Shepard velocity that evaluation 0 left in ṽ
/// (`forces::forces_liquid`), unaccelerated.
pub fn integrate_predict(p: &Params, st: &mut CpuState, dt: f32, _t_next: f64) {
    let half_dt2 = 0.5 * dt * dt;
    let three_d = p.dim.n() == 3;
    let outlets = p.outlets_in_effect(st.suction_held);
    let l = &mut st.liquid;
    let emit = &st.emit;
    let (x, vx) = (&l.x, &l.vx);
    l.a0.par_iter_mut().zip(l.a.par_iter()).zip(l.v.par_iter_mut()).enumerate().for_each(|(i, ((a0, a), v))| {
        match super::emit::inlet_velocity(emit, x[i], three_d) {
            Some(u) => {
                *a0 = Vec3::ZERO;
                *v = u;
            }
            None if OutletRegion::find(outlets, x[i]).is_some() => {
                *a0 = Vec3::ZERO;
                *v = vx[i];
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

/// Contact with the rigid boundary objects (SPEC §4.1 "impenetrable objects", §7.5 penetration
/// invariant; README: deviations): a material particle found inside an object's shape at tⁿ⁺¹ is put
/// back on the nearest point of the boxes' surface ([`box_exit`]: the nearest face, unless another box
/// covers it there) or on the sphere, and the part of its velocity relative to the object
/// that points into the object is removed (inelastic normal contact; the tangential part is left to
/// the no-slip viscous term). The virtual particles alone cannot guarantee this: blood that has left
/// the tissue is pressureless until it is compressed to nˡ = 1 (2.53 clamped at 0), so it falls
/// through a plate's particle layers. A bed moulded to the tissue (kind 2, no shape) has the surface of
/// its lattice columns instead (`bed::bed_contact`, from `beds`); other objects of kind 2 are skipped. Twin of
/// `object_contact` in `shaders/integrate.wgsl`, in the same f32 operations.
#[inline]
pub fn object_contact(geoms: &[ObjectGeom], vel: &[Vec3], beds: &BedTable, three_d: bool, x: &mut Vec3, v: &mut Vec3) {
    let dims = if three_d { 3 } else { 2 };
    for (k, (g, vo)) in geoms.iter().zip(vel).enumerate() {
        let mut n = Vec3::ZERO;
        let mut inside = false;
        if g.kind == 0 {
            inside = (0..dims).all(|a| x[a] > g.a[a] && x[a] < g.b[a]);
            if inside {
                (*x, n) = box_exit(geoms, k, *x, dims);
                // the inward part along each face's normal (one, or two or three at a corner of boxes)
                for a in 0..3 {
                    let vn = (v[a] - vo[a]) * n[a];
                    if vn < 0.0 {
                        v[a] -= n[a] * vn;
                    }
                }
                continue;
            }
        } else if g.kind == 1 {
            let d = *x - g.a;
            let len = d.length();
            if len < g.b.x {
                inside = true;
                n = if len > 0.0 {
                    d / len
                } else if three_d {
                    Vec3::Z
                } else {
                    Vec3::Y
                };
                *x = g.a + n * g.b.x;
            }
        } else if let Some(&off) = beds.offsets.get(k).filter(|o| **o > 0)
            && let Some((y, normal)) = bed::bed_contact(&beds.data, off as usize - 1, *x, three_d)
        {
            inside = true;
            (*x, n) = (y, normal);
        }
        if inside {
            let vn = (*v - *vo).dot(n);
            if vn < 0.0 {
                *v -= n * vn;
            }
        }
    }
}

/// integrate_advance: xⁿ⁺¹ = xⁿ + Δt ṽⁿ + ½Δt²a⁰ (2.65), ρ^p = ρⁿ + Δt D⁰ (2.66), then
/// [`object_contact`] against the objects at tⁿ⁺¹ (`geoms`, `vel`) for every particle that is not
/// kinematic (inlet buffers, clamps).
pub fn integrate_advance(p: &Params, st: &mut CpuState, dt: f32, geoms: &[ObjectGeom], vel: &[Vec3], beds: &BedTable) {
    let half_dt2 = 0.5 * dt * dt;
    let three_d = p.dim.n() == 3;
    let l = &mut st.liquid;
    let (vx, a0, emit) = (&l.vx, &l.a0, &st.emit);
    l.x.par_iter_mut().zip(l.v.par_iter_mut()).enumerate().for_each(|(i, (x, v))| {
        let inlet = super::emit::inlet_velocity(emit, *x, three_d);
        let adv = inlet.unwrap_or(vx[i]);
        *x = wrap_periodic(p, *x + adv * dt + a0[i] * half_dt2);
        if inlet.is_none() {
            object_contact(geoms, vel, beds, three_d, x, v);
        }
    });
    let s = &mut st.solid;
    let (dx, drho0, flags) = (&s.dx, &s.drho0, &s.flags);
    s.x.par_iter_mut().zip(s.v.par_iter_mut()).enumerate().for_each(|(i, (x, v))| {
        *x = wrap_periodic(p, *x + dx[i]);
        if flags[i] & SolidFlags::KINEMATIC == 0 {
            object_contact(geoms, vel, beds, three_d, x, v);
        }
    });
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A particle inside a box goes to the nearest face and keeps only outward/tangential relative
    /// velocity; inside a moving sphere it goes radially onto the surface; outside nothing changes.
    #[test]
    fn object_contact_projects_onto_the_surface() {
        let boxed = ObjectGeom { kind: 0, a: Vec3::new(-1.0, -1.0, -1.0), b: Vec3::new(1.0, 1.0, 0.0) };
        let (mut x, mut v) = (Vec3::new(0.5, 0.0, -0.1), Vec3::new(0.3, 0.2, -2.0));
        object_contact(&[boxed], &[Vec3::ZERO], &BedTable::default(), true, &mut x, &mut v);
        assert_eq!(x, Vec3::new(0.5, 0.0, 0.0));
        assert_eq!(v, Vec3::new(0.3, 0.2, 0.0));
        // leaving already: the velocity is kept
        let (mut x, mut v) = (Vec3::new(0.0, 0.95, -0.5), Vec3::new(0.0, 1.0, 0.0));
        object_contact(&[boxed], &[Vec3::ZERO], &BedTable::default(), true, &mut x, &mut v);
        assert_eq!((x, v), (Vec3::new(0.0, 1.0, -0.5), Vec3::new(0.0, 1.0, 0.0)));
        // a sphere moving at +x pushes the particle along with it
        let ball = ObjectGeom { kind: 1, a: Vec3::ZERO, b: Vec3::new(2.0, 0.0, 0.0) };
        let (mut x, mut v) = (Vec3::new(1.0, 0.0, 0.0), Vec3::ZERO);
        object_contact(&[ball], &[Vec3::new(5.0, 0.0, 0.0)], &BedTable::default(), true, &mut x, &mut v);
        assert_eq!((x, v), (Vec3::new(2.0, 0.0, 0.0), Vec3::new(5.0, 0.0, 0.0)));
        let (mut x, mut v) = (Vec3::new(3.0, 0.0, 0.0), Vec3::new(-1.0, 0.0, 0.0));
        object_contact(&[ball], &[Vec3::ZERO], &BedTable::default(), true, &mut x, &mut v);
        assert_eq!((x, v), (Vec3::new(3.0, 0.0, 0.0), Vec3::new(-1.0, 0.0, 0.0)));
    }

    /// A vessel of boxes: a floor and two side walls standing on it, meeting at a corner (the walls of
    /// `syringe.ron`'s barrel, of `docs/sealed_column.ron`). A particle that entered a wall just above
    /// the floor goes back to the wall's inner face, not onto the plane the wall shares with the floor
    /// (its nearest face), along which it would slide out; one that entered the corner goes to the
    /// corner, not out through the wall's outer face; inward velocity is removed along both normals.
    /// Where no other box covers the nearest face, that face it is, as with one box.
    #[test]
    fn object_contact_keeps_particles_inside_a_vessel_of_boxes() {
        let floor = ObjectGeom { kind: 0, a: Vec3::new(-3.0, -3.0, -1.0), b: Vec3::new(3.0, 3.0, 0.0) };
        let wall_x = ObjectGeom { kind: 0, a: Vec3::new(1.0, -3.0, 0.0), b: Vec3::new(3.0, 3.0, 5.0) };
        let wall_y = ObjectGeom { kind: 0, a: Vec3::new(-1.0, 1.0, 0.0), b: Vec3::new(1.0, 3.0, 5.0) };
        let geoms = [floor, wall_x, wall_y];
        let vel = [Vec3::ZERO; 3];
        let beds = BedTable::default();
        let contact = |x: Vec3, v: Vec3| {
            let (mut x, mut v) = (x, v);
            object_contact(&geoms, &vel, &beds, true, &mut x, &mut v);
            (x, v)
        };
        // the wall's foot: the seam z = 0 is nearer (0.1) than the inner face x = 1 (0.3)
        let (x, v) = contact(Vec3::new(1.3, 0.0, 0.1), Vec3::new(0.5, 0.2, -0.2));
        assert_eq!(x, Vec3::new(1.0, 0.0, 0.1));
        assert_eq!(v, Vec3::new(0.0, 0.2, -0.2));
        // the corner of the two walls, entered diagonally: to the corner, both inward parts removed
        let (x, v) = contact(Vec3::new(1.1, 1.2, 2.0), Vec3::new(0.5, 0.5, 0.1));
        assert_eq!(x, Vec3::new(1.0, 1.0, 2.0));
        assert_eq!(v, Vec3::new(0.0, 0.0, 0.1));
        // higher up a wall, and into the floor away from the walls: the nearest face, as with one box
        let (x, _) = contact(Vec3::new(1.2, -2.0, 3.0), Vec3::ZERO);
        assert_eq!(x, Vec3::new(1.0, -2.0, 3.0));
        let (x, _) = contact(Vec3::new(0.0, -1.0, -0.2), Vec3::ZERO);
        assert_eq!(x, Vec3::new(0.0, -1.0, 0.0));
        // nothing moves a particle resting on the floor or against a wall
        for p in [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 2.0), Vec3::new(1.0, 1.0, 0.0)] {
            assert_eq!(contact(p, Vec3::new(0.1, 0.1, -0.1)), (p, Vec3::new(0.1, 0.1, -0.1)));
        }
    }
}
