// integrate.wgsl — predictor–corrector leapfrog (2.64)–(2.68) with XSPH advection (2.69); twin:
// src/sim/cpu/integrate.rs (SPEC §5.1). Δt is read from the GPU-resident `step.dt` (dt.wgsl).
// Also: integrate_boundary (placing the virtual boundary particles, the twin of
// CpuSolver::move_boundaries) and integrate_check_* (the divergence check of CpuSolver).
#import common

// Rust f32::rem_euclid (WGSL % on floats is x − y·trunc(x/y); exact for |x| < 2|y|, our case).
fn rem_euclid(x: f32, m: f32) -> f32 {
    let r = x % m;
    if (r < 0.0) {
        return r + abs(m);
    }
    return r;
}

fn wrap_periodic(x_in: vec3<f32>) -> vec3<f32> {
    var x = x_in;
    for (var a = 0; a < 3; a++) {
        if (params.period[a] > 0.0) {
            let lo = params.domain_min[a];
            let len = params.domain_max[a] - lo;
            x[a] = lo + rem_euclid(x[a] - lo, len);
        }
    }
    return x;
}

// a⁰ ← a, v^p = vⁿ + Δt a⁰ (2.64); inside an inlet's buffer: a⁰ = 0, v = u (emit.wgsl); inside an outlet's
// buffer: a⁰ = 0, v = ṽ (its Shepard velocity, forces.wgsl outlet_velocity).
@compute @workgroup_size(64)
fn integrate_predict_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let dt = step.dt;
    let u = inlet_velocity(liquid_pos[i].xyz);
    if (u.w != 0.0) {
        liquid_acc0[i] = vec4<f32>(0.0);
        liquid_vel[i] = vec4<f32>(u.xyz, 0.0);
        return;
    }
    if (outlet_find(liquid_pos[i].xyz) >= 0) {
        // an outlet's buffer: the Shepard velocity forces_liquid_xsph left in ṽ, unaccelerated
        liquid_acc0[i] = vec4<f32>(0.0);
        liquid_vel[i] = vec4<f32>(liquid_vel_adv[i].xyz, 0.0);
        return;
    }
    let a = liquid_acc[i];
    liquid_acc0[i] = a;
    liquid_vel[i] = vec4<f32>(liquid_vel[i].xyz + a.xyz * dt, 0.0);
}

// a⁰ ← a, D⁰ ← D, Δx = Δt ṽ + ½Δt² a⁰ (D-11), v^p = vⁿ + Δt a⁰; kinematic particles stay at rest.
@compute @workgroup_size(64)
fn integrate_predict_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let dt = step.dt;
    let half_dt2 = 0.5 * dt * dt;
    let a0 = solid_acc[i];
    solid_acc0[i] = a0;
    let d = solid_drho[i];
    solid_drho[i] = vec2<f32>(d.x, d.x);
    let v4 = solid_vel[i];
    if ((solid_flags[i] & SOLID_KINEMATIC) != 0u) {
        solid_disp[i] = vec4<f32>(0.0);
        solid_vel[i] = vec4<f32>(0.0, 0.0, 0.0, v4.w);
    } else {
        solid_disp[i] = vec4<f32>(solid_vel_adv[i].xyz * dt + a0.xyz * half_dt2, 0.0);
        solid_vel[i] = vec4<f32>(v4.xyz + a0.xyz * dt, v4.w);
    }
}

// Contact with a moulded bed's surface (twin: sim::bed::bed_contact, same f32 operations): when x lies
// in one of the bed's lattice columns, below its top and above the bed's lower face, the nearest way
// out — up onto the column's top, or sideways through a face whose neighbour column is empty or lower
// than x. `off` is the bed's header in bed_table. Returns the new position, the outward normal and
// whether x was inside.
const BED_HEADER: u32 = 11u;
const BED_EMPTY: f32 = -3.0e38;

struct BedHit {
    x: vec3<f32>,
    n: vec3<f32>,
    hit: bool,
}

fn bed_top(off: u32, na: i32, nb: i32, a: i32, b: i32) -> f32 {
    if (a < 0 || b < 0 || a >= na || b >= nb) {
        return BED_EMPTY;
    }
    return bed_table[off + BED_HEADER + u32(b * na + a)];
}

fn bed_contact(off: u32, x: vec3<f32>, three_d: bool) -> BedHit {
    var r = BedHit(x, vec3<f32>(0.0), false);
    let sp = bed_table[off];
    let inv_sp = bed_table[off + 1u];
    let lo_a = bed_table[off + 2u];
    let lo_b = bed_table[off + 3u];
    let bottom = bed_table[off + 4u];
    let up = bitcast<u32>(bed_table[off + 5u]);
    let la = bitcast<u32>(bed_table[off + 6u]);
    let lb = bitcast<u32>(bed_table[off + 7u]);
    let sgn = bed_table[off + 8u];
    let na = i32(bitcast<u32>(bed_table[off + 9u]));
    let nb = i32(bitcast<u32>(bed_table[off + 10u]));
    let fa = floor((x[la] - lo_a) * inv_sp);
    var fb = 0.0;
    if (three_d) {
        fb = floor((x[lb] - lo_b) * inv_sp);
    }
    if (!(fa >= 0.0 && fb >= 0.0 && fa < f32(na) && fb < f32(nb))) {
        return r;
    }
    let ka = i32(fa);
    let kb = i32(fb);
    let h = sgn * x[up];
    let top = bed_top(off, na, nb, ka, kb);
    if (!(h > bottom && h < top)) {
        return r;
    }
    var best = top - h;
    var axis = up;
    var to = sgn * top;
    var side = sgn;
    // sideways along la, then lb (3-D): the low face, then the high one, each only when the neighbour
    // column beyond it does not cover h
    for (var lat = 0u; lat < 2u; lat++) {
        if (lat == 1u && !three_d) {
            break;
        }
        var a = la;
        var k = ka;
        var lo = lo_a;
        var lower = bed_top(off, na, nb, ka - 1, kb);
        var higher = bed_top(off, na, nb, ka + 1, kb);
        if (lat == 1u) {
            a = lb;
            k = kb;
            lo = lo_b;
            lower = bed_top(off, na, nb, ka, kb - 1);
            higher = bed_top(off, na, nb, ka, kb + 1);
        }
        let e0 = lo + f32(k) * sp;
        let e1 = lo + f32(k + 1) * sp;
        if (x[a] - e0 < best && lower <= h) {
            best = x[a] - e0;
            axis = a;
            to = e0;
            side = -1.0;
        }
        if (e1 - x[a] < best && higher <= h) {
            best = e1 - x[a];
            axis = a;
            to = e1;
            side = 1.0;
        }
    }
    r.x[axis] = to;
    r.n[axis] = side;
    r.hit = true;
    return r;
}

// Contact with the rigid boundary objects at tⁿ⁺¹ (twin: cpu::integrate::object_contact): a particle
// inside an object's shape goes back onto the boxes' surface (box_exit) or the sphere, and the inward part of
// its velocity relative to the object is removed; a moulded bed (kind 2 with a heightfield) uses
// bed_contact. Returns the new position (xyz) and velocity.
struct Contact {
    x: vec3<f32>,
    v: vec3<f32>,
}

fn object_contact(x_in: vec3<f32>, v_in: vec3<f32>) -> Contact {
    var x = x_in;
    var v = v_in;
    var dims = 2;
    if (params.switches.x != 0u) {
        dims = 3;
    }
    let n_obj = params.switches.w;
    for (var k = 0u; k < n_obj; k++) {
        let o = objects[k];
        var n = vec3<f32>(0.0);
        var inside = false;
        if (o.kind == 0u) {
            inside = true;
            for (var a = 0; a < dims; a++) {
                if (!(x[a] > o.geom_a[a] && x[a] < o.geom_b[a])) {
                    inside = false;
                }
            }
            if (inside) {
                let e = box_exit(k, x, dims);
                x = e.y;
                // the inward part along each face's normal (one, or two or three at a corner of boxes)
                for (var a = 0; a < 3; a++) {
                    let vn = (v[a] - o.vel[a]) * e.n[a];
                    if (vn < 0.0) {
                        v[a] = v[a] - e.n[a] * vn;
                    }
                }
                continue;
            }
        } else if (o.kind == 1u) {
            let d = x - o.geom_a.xyz;
            let len = length(d);
            if (len < o.geom_b.x) {
                inside = true;
                if (len > 0.0) {
                    n = d / len;
                } else if (dims == 3) {
                    n = vec3<f32>(0.0, 0.0, 1.0);
                } else {
                    n = vec3<f32>(0.0, 1.0, 0.0);
                }
                x = o.geom_a.xyz + n * o.geom_b.x;
            }
        } else if (o.bed != 0u) {
            let b = bed_contact(o.bed - 1u, x, dims == 3);
            if (b.hit) {
                inside = true;
                x = b.x;
                n = b.n;
            }
        }
        if (inside) {
            let vn = dot(v - o.vel.xyz, n);
            if (vn < 0.0) {
                v = v - n * vn;
            }
        }
    }
    return Contact(x, v);
}

// xⁿ⁺¹ = xⁿ + Δt ṽⁿ + ½Δt² a⁰ (2.65), then object_contact (not for inlet buffers).
@compute @workgroup_size(64)
fn integrate_advance_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let dt = step.dt;
    let half_dt2 = 0.5 * dt * dt;
    let p = liquid_pos[i];
    let u = inlet_velocity(p.xyz);
    var adv = liquid_vel_adv[i].xyz;
    if (u.w != 0.0) {
        adv = u.xyz;
    }
    let x = wrap_periodic(p.xyz + adv * dt + liquid_acc0[i].xyz * half_dt2);
    if (u.w != 0.0) {
        liquid_pos[i] = vec4<f32>(x, p.w);
        return;
    }
    let v4 = liquid_vel[i];
    let c = object_contact(x, v4.xyz);
    liquid_pos[i] = vec4<f32>(c.x, p.w);
    liquid_vel[i] = vec4<f32>(c.v, v4.w);
}

// xⁿ⁺¹ = xⁿ + Δx, ρ^p = ρⁿ + Δt D⁰ (2.66), then object_contact (not for kinematic particles).
@compute @workgroup_size(64)
fn integrate_advance_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let dt = step.dt;
    let p = solid_pos[i];
    let x = wrap_periodic(p.xyz + solid_disp[i].xyz);
    if ((solid_flags[i] & SOLID_KINEMATIC) == 0u) {
        let v4 = solid_vel[i];
        let c = object_contact(x, v4.xyz);
        solid_pos[i] = vec4<f32>(c.x, p.w);
        solid_vel[i] = vec4<f32>(c.v, v4.w);
        solid_dens[i].x = solid_dens[i].x + dt * solid_drho[i].y;
    } else {
        solid_pos[i] = vec4<f32>(x, p.w);
    }
}

// Virtual boundary particles at the objects' current pose: x = x⁰ + d(t), v = v(t) (SPEC §4.1).
@compute @workgroup_size(64)
fn integrate_boundary(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.z) {
        return;
    }
    let p0 = boundary_pos0[i];
    let o = objects[boundary_object(i)];
    boundary_pos[i] = vec4<f32>(p0.xyz + o.disp.xyz, boundary_pos[i].w);
    boundary_vel[i] = vec4<f32>(o.vel.xyz, boundary_vel[i].w);
}

// vⁿ⁺¹ = v^p + ½Δt(a¹ − a⁰) (2.67), then relaxation damping (SPEC §7.5).
@compute @workgroup_size(64)
fn integrate_correct_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let dt = step.dt;
    let u = inlet_velocity(liquid_pos[i].xyz);
    if (u.w != 0.0) {
        liquid_vel[i] = vec4<f32>(u.xyz, 0.0);
        return;
    }
    let damp = max(1.0 - params.damping * dt, 0.0);
    let v = liquid_vel[i].xyz;
    liquid_vel[i] = vec4<f32>((v + (liquid_acc[i].xyz - liquid_acc0[i].xyz) * (0.5 * dt)) * damp, 0.0);
}

// vⁿ⁺¹ (2.67) and ρⁿ⁺¹ = ρ^p + ½Δt(D¹ − D⁰) (2.68).
@compute @workgroup_size(64)
fn integrate_correct_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    if ((solid_flags[i] & SOLID_KINEMATIC) != 0u) {
        return;
    }
    let dt = step.dt;
    let damp = max(1.0 - params.damping * dt, 0.0);
    let v4 = solid_vel[i];
    solid_vel[i] = vec4<f32>((v4.xyz + (solid_acc[i].xyz - solid_acc0[i].xyz) * (0.5 * dt)) * damp, v4.w);
    let d = solid_drho[i];
    solid_dens[i].x = solid_dens[i].x + 0.5 * dt * (d.x - d.y);
}

// Divergence check (CpuSolver::check_divergence): non-finite x, v, ρ or |v| > max_speed.
@compute @workgroup_size(64)
fn integrate_check_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let x = liquid_pos[i].xyz;
    let v = liquid_vel[i].xyz;
    let vmax2 = params.max_speed * params.max_speed;
    if (!(is_finite3(x) && is_finite3(v)) || dot3(v, v) > vmax2 || !is_finite_f32(liquid_dens[i].x)) {
        atomicOr(&step.status, STATUS_NONFINITE_LIQUID);
        // the id, not the index: the liquid is renumbered by cell every step (grid_reorder)
        atomicMin(&step.bad_liquid, liquid_id[i]);
    }
}

@compute @workgroup_size(64)
fn integrate_check_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let x = solid_pos[i].xyz;
    let v = solid_vel[i].xyz;
    let vmax2 = params.max_speed * params.max_speed;
    if (!(is_finite3(x) && is_finite3(v)) || dot3(v, v) > vmax2 || !is_finite_f32(solid_dens[i].x)) {
        atomicOr(&step.status, STATUS_NONFINITE_SOLID);
        atomicMin(&step.bad_solid, i);
    }
}
