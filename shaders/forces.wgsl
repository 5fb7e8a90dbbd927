// forces.wgsl — accelerations of liquid and solid particles and XSPH velocities; twin:
// src/sim/cpu/forces.rs (SPEC §3.6–3.13).
//
// Liquid (2.50): −κ_S nˡ∇p with the spiky kernel (D-15, D-16), mirrored boundary pressure with the
// hydrostatic wall extrapolation (§4.1, D-23), viscosity κ_V(η/ρ_i)Σ(m_j/ρ_j)(v_j − v_i)∇²W_V (D-7, D-17)
// with the no-slip ghost factor, pairwise friction (2.17, D-18), g, and when enabled the surface tension
// (3.3) and the liquid–void attraction (3.4) (§3.12).
// Solid (2.48): deviatoric stress over bonds, −nˢ∇p, artificial stress (2.59)–(2.60), artificial
// viscosity (2.54)–(2.58), boundary contact, friction and attraction reactions, membrane reactions
// gathered from the liquid (§4.1: a gather, no atomics), g; and the solid's continuity dρ/dt (2.47) into
// solid_drho over the pairs of the pressure term and the walls' contact. XSPH (2.69) for both, in evaluation 0's
// force passes (forces_liquid_xsph, forces_solid_xsph): the sum walks the neighbours the forces walk.
#import common

// Monaghan's Π_ij (2.54)–(2.58); zero for separating pairs.
fn artificial_viscosity(vij: vec3<f32>, xij: vec3<f32>, r: f32, h: f32, c: f32, rho_bar: f32) -> f32 {
    let vx = dot3(vij, xij);
    // branch-free (once per pair; see the kernels in common.wgsl): the same value where vx < 0
    let mu = h * vx / (r * r + params.av_gamma * h * h);
    return select((-params.av_alpha * c * mu + params.av_beta * mu * mu) / rho_bar, 0.0, vx >= 0.0);
}

// K_ij = K̄ max(0, 1 − ½(nˢ_i + nˢ_j)) (D-18).
fn friction_coefficient(ns_i: f32, ns_j: f32) -> f32 {
    return params.kbar * max(1.0 - 0.5 * (ns_i + ns_j), 0.0);
}

// Outward unit normal of object o's surface nearest to x (forces.rs `surface_normal`): a box's from
// its closest point or, inside it, its nearest face (`nearest_face`, common.wgsl); a sphere's radial
// direction. Zero where the CPU twin has none.
fn surface_normal(o: ObjectGpu, x: vec3<f32>, dims: i32) -> vec3<f32> {
    let ga = o.geom_a.xyz;
    if (o.kind == 0u) {
        let d = x - min(max(x, ga), o.geom_b.xyz);
        let len = len3(d);
        if (len > 1e-30) {
            return d / len;
        }
        let face = nearest_face(o, x, dims);
        var n = vec3<f32>(0.0);
        n[face.axis] = face.side;
        return n;
    }
    if (o.kind == 1u) {
        let d = x - ga;
        let len = len3(d);
        if (len > 1e-30) {
            return d / len;
        }
    }
    return vec3<f32>(0.0);
}

// No-slip factor 1 + β of the viscous wall term (forces.rs `no_slip_factor`, SPEC §4.1).
fn no_slip_factor(obj: u32, xi: vec3<f32>, xb: vec3<f32>) -> f32 {
    let o = objects[obj];
    let ga = o.geom_a.xyz;
    var closest: vec3<f32>;
    if (o.kind == 0u) {
        closest = min(max(xi, ga), o.geom_b.xyz);
    } else if (o.kind == 1u) {
        let d = xi - ga;
        let len = len3(d);
        if (len <= 1e-30) {
            return 1.0 + NO_SLIP_BETA_MAX;
        }
        closest = ga + d * (o.geom_b.x / len);
    } else {
        return 1.0;
    }
    let off = xi - closest;
    let di = len3(off);
    if ((o.kind == 1u && len3(xi - ga) <= o.geom_b.x) || di <= 1e-30) {
        return 1.0 + NO_SLIP_BETA_MAX;
    }
    let n = off / di;
    let db = max(dot3(closest - xb, n), 0.0);
    return 1.0 + min(db / di, NO_SLIP_BETA_MAX);
}

// One solid particle's wall contacts for Coulomb friction (forces.rs `WallContact`): the load
// L = Σμa_p of the pairs' contact-pressure accelerations, Σμ|a_p| and Σμ|a_p|v_b (README: deviations
// from SPEC).
struct WallContact {
    load: vec3<f32>,
    weight: f32,
    vel: vec3<f32>,
}

fn wall_contact_add(c: ptr<function, WallContact>, mu: f32, a_p: vec3<f32>, pushes: bool, vb: vec3<f32>) {
    if (pushes) {
        let w = mu * len3(a_p);
        (*c).load += a_p * mu;
        (*c).weight += w;
        (*c).vel += vb * w;
    }
}

// −v̂_t min(|L|, |v_t|/Δt_up): kinetic Coulomb friction, or the stick regime below one step's sliding.
fn wall_contact_friction(c: WallContact, vi: vec3<f32>) -> vec3<f32> {
    let bound = len3(c.load);
    if (c.weight <= 0.0 || bound <= 0.0) {
        return vec3<f32>(0.0);
    }
    let n = c.load / bound;
    let vrel = vi - c.vel / c.weight;
    let vt = vrel - n * dot3(vrel, n);
    let speed = len3(vt);
    if (speed <= 0.0) {
        return vec3<f32>(0.0);
    }
    return vt * -min(bound / speed, 1.0 / params.dt_upper);
}

// Pair factor of the liquid–void attraction (3.4) (forces.rs `wicking_pair`, SPEC §3.12, D-22).
fn wicking_pair(h_x: f32, ns_j: f32, nl_j: f32, r: f32) -> f32 {
    let w = max(1.0 - ns_j - nl_j, 0.0);
    if (r <= 0.0 || r >= 2.0 * h_x) {
        return 0.0;
    }
    return w * (params.wicking / (h_x * h_x)) * cos(PI * r / (4.0 * h_x));
}

// Monaghan's artificial pressure of a liquid pair under tension (forces.rs `liquid_artificial_pressure`):
// (R_i + R_j) f^n with R = ε max(0, −p/ρ²), f = W_C(r; h_l)/W_C(Δx_l; h_l); pi, pj are p/ρ².
fn liquid_artificial_pressure(kl: KernelConsts, pi: f32, pj: f32, r: f32) -> f32 {
    let big_r = params.ap_eps * (max(-pi, 0.0) + max(-pj, 0.0));
    if (big_r <= 0.0) {
        return 0.0;
    }
    return big_r * powi(w_cubic(kl, r) / params.wc_dx_l, params.ap_exp);
}

// Pair force [N] of the surface tension (3.3) (forces.rs `cohesion_pair`).
fn cohesion_pair(s: f32, radius: f32, r: f32) -> f32 {
    if (r <= 0.0 || r >= radius) {
        return 0.0;
    }
    return s * cos(PI * r / (2.0 * radius));
}

// Acceleration of solid particle i from the hourglass control of bond (i, j) (forces.rs
// `hourglass_pair`): −c G (m_j/ρ_ref) W_C(|X|)/(|X|² ρ_ref) δ x̂ with δ = (½(F̃_i + F̃_j)X − x)·x̂,
// x = x_j − x_i = −xij now, X = X_j − X_i in the generated configuration. `stiffness` scales G for the
// bond: hourglass_stiffness of its two ends (a capsule bond is held as its stress holds it).
fn hourglass_pair(fit_i: mat3x3<f32>, fit_j: mat3x3<f32>, x_ref_ij: vec3<f32>, xij: vec3<f32>, m_j: f32,
                  stiffness: f32) -> vec3<f32> {
    let big = min_image(x_ref_ij);
    let now = -xij;
    let r = len3(now);
    let l0 = len3(big);
    if (r <= 0.0 || l0 <= 0.0) {
        return vec3<f32>(0.0);
    }
    let u = now / r;
    let delta = dot3(m3_mul_v(m3_add(fit_i, fit_j), big) * 0.5 - now, u);
    let g_mod = 2.0 * (params.c10 + params.c01) * stiffness;
    let k = params.hourglass * g_mod * (m_j / params.rho_ref_s) * w_cubic(params.k_solid, l0) / (l0 * l0 * params.rho_ref_s);
    return u * -(k * delta);
}

// The factor on G of the hourglass control for bond (i, j) (forces.rs `hourglass_stiffness`): the mean of
// the two ends' C10, C01 factors (common.wgsl stiffness_factor).
fn hourglass_stiffness(flags_i: u32, flags_j: u32) -> f32 {
    return 0.5 * (stiffness_factor(flags_i) + stiffness_factor(flags_j));
}

// Velocity of liquid particle i in the buffer of the outlet of unit normal n and density rho_o
// (forces.rs `outlet_velocity`): n times the normal part of the Shepard mean Σ (ρ_j/ρ_o) v_j W6 / Σ W6
// over the open liquid within R_l (the mass flux in front carried off at the buffer's density), or, with
// none near, the mean velocity of all the other liquid within R_l, or v_i.
fn outlet_velocity(i: u32, xi: vec3<f32>, vi: vec3<f32>, n: vec3<f32>, rho_o: f32) -> vec3<f32> {
    let kl = params.k_liquid;
    let ci = cell_coords(xi);
    let kb = nbr_begin();
    let ke = nbr_end();
    let kstep = nbr_step(ci);
    let r2l = kl.r * kl.r;
    var sum_w = 0.0;
    var sum_v = vec3<f32>(0.0);
    var all_w = 0.0;
    var all_v = vec3<f32>(0.0);
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = liquid_cell_start[c.y + 1];
        for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
            let e = liquid_candidate(q);
            let j = e.j;
            let xij = min_image_wrapped(xi - e.pos_m.xyz);
            let r2 = dot3(xij, xij);
            if (r2 < r2l && j != i) {
                let w = w_poly6(kl, sqrt(r2));
                let vj = liquid_vel[j].xyz;
                all_w += w;
                all_v += vj * w;
                if (outlet_find(e.pos_m.xyz) < 0) {
                    // continuity across the buffer's face, ρ_j v_j / ρ_o (forces.rs outlet_velocity)
                    sum_w += w;
                    sum_v += vj * (w * liquid_dens[j].x / rho_o);
                }
            }
        }
    }
    var v = vi;
    if (sum_w > 0.0) {
        v = sum_v / sum_w;
    } else if (all_w > 0.0) {
        v = all_v / all_w;
    }
    return n * dot3(v, n);
}

fn liquid_gravity() -> vec3<f32> {
    return select(vec3<f32>(0.0), params.gravity.xyz, params.gravity.w != 0.0);
}

// Evaluation 1's liquid forces; evaluation 0's come with the XSPH velocities (forces_liquid_xsph).
@compute @workgroup_size(64)
fn forces_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    liquid_forces(gid, false);
}

// The liquid forces and, in the same walk over the liquid, XSPH (2.69): ṽ_i = v_i + ε̃ Σ (m_j/ρ̄_ij)(v_j −
// v_i)W6 (forces.rs `forces_liquid` with `xsph`).
@compute @workgroup_size(64)
fn forces_liquid_xsph(@builtin(global_invocation_id) gid: vec3<u32>) {
    liquid_forces(gid, true);
}

// Accelerations of liquid particle gid (cell-ordered dispatch), and with `xsph` its XSPH velocity (a
// constant at each call: the driver compiles two specialised passes).
fn liquid_forces(gid: vec3<u32>, xsph: bool) {
    if (gid.x >= params.counts.x) {
        return;
    }
    let i = liquid_dispatched(gid.x); // cell-ordered dispatch (common.wgsl)
    let kl = params.k_liquid;
    let kx = params.k_cross;
    let g = liquid_gravity();
    let xi = liquid_pos[i].xyz;
    let vi = liquid_vel[i].xyz;
    let di = liquid_dens[i];
    let rho = di.x;
    let n_l = di.y;
    let n_s = di.z;
    let pr = di.w;
    let outlet = outlet_find(xi);
    if (outlet >= 0) {
        // an outlet's buffer feels no force; evaluation 0 gives it the velocity of the liquid around it as
        // its ṽ (integrate_predict_liquid makes it its v)
        liquid_acc[i] = vec4<f32>(0.0);
        if (xsph) {
            liquid_vel_adv[i] = vec4<f32>(outlet_velocity(i, xi, vi, params.outlet[3 * outlet + 2].xyz, params.outlet[3 * outlet].w), 0.0);
        }
        return;
    }
    let pi = pr / (rho * rho);
    let m_i = liquid_pos[i].w;
    let inv_m = 1.0 / m_i;
    let ci = cell_coords(xi);
    let kb = nbr_begin();
    let ke = nbr_end();
    let kstep = nbr_step(ci);
    let r2l = kl.r * kl.r;
    var a = vec3<f32>(0.0);
    var d_xsph = vec3<f32>(0.0);
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = liquid_cell_start[c.y + 1];
        for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
            let e = liquid_candidate(q);
            let j = e.j;
            let xij = min_image_wrapped(xi - e.pos_m.xyz);
            let r2 = dot3(xij, xij);
            if (r2 < r2l && j != i) {
                let r = sqrt(r2);
                let mj = liquid_candidate_mass(e);
                let dj = liquid_dens[j];
                let vj = liquid_vel[j].xyz;
                let grad = xij * grad_spiky_factor(kl, r);
                let pj = dj.w / (dj.x * dj.x);
                var p_pair = pi + pj;
                if (params.ap_eps > 0.0) {
                    p_pair += liquid_artificial_pressure(kl, pi, pj, r);
                }
                // −n∇p with the pair's mean fraction: an antisymmetric pair force, so the phase's pressure
                // forces sum to zero (D-16 with n_i alone propels a body with an asymmetric surface)
                a += grad * (-0.5 * (n_l + dj.y) * mj * p_pair * params.kappa_s);
                a += (vj - vi) * (params.kappa_v * params.eta / rho * (mj / dj.x) * lap_viscosity(kl, r));
                if (params.cohesion_ll > 0.0 && r > 0.0) {
                    // surface tension (3.3): pair force toward j
                    a -= xij * (cohesion_pair(params.cohesion_ll, kl.r, r) * inv_m / r);
                }
                if (params.switches.y != 0u) {
                    let pij = artificial_viscosity(vi - vj, xij, r, kl.h, params.c_l, 0.5 * (rho + dj.x));
                    a -= grad * (mj * pij);
                }
                if (xsph && params.xsph_l != 0.0) {
                    d_xsph += (vj - vi) * (mj / (0.5 * (rho + dj.x)) * w_poly6(kl, r));
                }
            }
        }
    }
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = boundary_cell_start[c.y + 1];
        for (var q = boundary_cell_start[c.x]; q < q_end; q++) {
            let e = boundary_order[q];
            let j = e.id;
            let xij = min_image_wrapped(xi - e.pos);
            let r2 = dot3(xij, xij);
            if (r2 < r2l) {
                let obj = boundary_object(j);
                let slip = no_slip_factor(obj, xi, e.pos);
                let o = objects[obj];
                let r = sqrt(r2);
                a += liquid_from_boundary(rho, pr, n_l, vi, boundary_pos[j].w, boundary_vel[j].xyz, xij, r, o.density, o.pressure, slip, g, 0.0);
                if (params.cohesion_lb > 0.0 && r > 0.0) {
                    // adhesion (3.3) to walls and plates
                    a -= xij * (cohesion_pair(params.cohesion_lb, kl.r, r) * inv_m / r);
                }
            }
        }
    }
    // the capsule's blood ghosts as boundary particles with their wall pressure (ghosts.wgsl)
    if (params.capsule_ghosts != 0u) {
        let r2g = kl.r * kl.r;
        for (var k = kb; k < ke; k += kstep) {
            let c = nbr_span(ci, k);
            if (c.x < 0) { continue; }
            let q_end = ghost_cell_start[c.y + 1];
            for (var q = ghost_cell_start[c.x]; q < q_end; q++) {
                let e = ghost_order[q];
                let xig = min_image_wrapped(xi - e.pos);
                let r2 = dot3(xig, xig);
                if (r2 < r2g) {
                    let side = ghost_side(e.id);
                    let m_g = side.frame0.w;
                    if (ghost_side_counts(side, xig) && m_g > 0.0) {
                        let st = ghost_state[2u * e.id];
                        if (st.y > 0.0) {
                            let v_o = solid_vel[bitcast<u32>(ghost_ref[2u * e.id].w)].xyz;
                            a += ghost_on_liquid(rho, pr, n_l, vi, m_g, v_o, xig, sqrt(r2), st.x, st.y, 0.0);
                        }
                    }
                }
            }
        }
    }
    let sees_ghost = liquid_sees[i] != 0u;
    // One pass over the solid (R_× ≥ R_l): membrane particles as boundary, and friction (2.17).
    let r2x = kx.r * kx.r;
    var f = vec3<f32>(0.0);
    // the capsule's seal (forces.rs capsule_seal_pair): Σw and Σ terms over the intact capsule in reach
    var seal_w = 0.0;
    var seal_sum = vec3<f32>(0.0);
    var seal_back = vec3<f32>(0.0);
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = solid_cell_start[c.y + 1];
        for (var q = solid_cell_start[c.x]; q < q_end; q++) {
            let e = solid_order[q];
            let j = e.id;
            let xij = min_image_wrapped(xi - e.pos);
            let r2 = dot3(xij, xij);
            if (r2 < r2x) {
                let r = sqrt(r2);
                let vj = solid_vel[j];
                if (r < kl.r && (solid_flags[j] & SOLID_MEMBRANE) != 0u) {
                    let n = capsule_normal(solid_f[j], solid_normal0[j].xyz);
                    if (params.capsule_seal > 0.0 && capsule_seals(j)) {
                        let sp = capsule_seal_pair(n, xij, r, vi - vj.xyz);
                        seal_w += sp.w;
                        seal_sum += sp.stop * capsule_seal_share(m_i, solid_pos[j].w);
                        seal_back += sp.back;
                    }
                    // beneath the capsule its ghosts are the wall (forces.rs capsule_inner)
                    if (!capsule_inner(n, xij) && !sees_ghost) {
                        a += liquid_from_boundary(rho, pr, n_l, vi, vj.w, vj.xyz, xij, r, -1.0, 0.0, 1.0, g, 0.0);
                    }
                }
                let dj = solid_dens[j];
                if (params.kbar > 0.0) {
                    let kf = friction_coefficient(n_s, dj.z);
                    f += (vi - vj.xyz) * (solid_pos[j].w / dj.x * kf * w_poly6(kx, r));
                }
                if (params.wicking > 0.0 && r > 0.0) {
                    // liquid–void attraction (3.4) toward unsaturated solid, per unit volume ÷ ρ_i
                    a -= xij * (wicking_pair(kx.h, dj.z, dj.y, r) / (rho * r));
                }
            }
        }
    }
    if (params.kbar > 0.0) {
        a -= f / rho;
    }
    // the seal's 1/(Σw Δt_max) stays in .w for the membrane's reaction (forces_solid)
    var scale = 0.0;
    if (seal_w > 0.0) {
        scale = 1.0 / (seal_w * (CAPSULE_SEAL_STOP_STEPS * params.dt_upper));
    }
    a -= seal_sum * scale;
    liquid_acc[i] = vec4<f32>(a + g, scale);
    if (xsph) {
        let eps = params.xsph_l;
        // and the seal's walk back to the capsule's plane, in ṽ alone, where the mirror pressure does not
        // hold the blood (capsule_seal_walks)
        var back = vec3<f32>(0.0);
        if (seal_w > 0.0 && capsule_seal_walks(pr)) {
            back = seal_back / seal_w;
        }
        liquid_vel_adv[i] = vec4<f32>(select(vi + d_xsph * eps, vi, eps == 0.0) + back, 0.0);
    }
}

// Evaluation 1's solid forces; evaluation 0's come with the XSPH velocities (forces_solid_xsph).
@compute @workgroup_size(64)
fn forces_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    solid_forces(gid, false);
}

// The solid forces and, in the same walk over the solid, XSPH (2.69) with poly6 of R_s; kinematic
// particles keep v (forces.rs `forces_solid` with `xsph`).
@compute @workgroup_size(64)
fn forces_solid_xsph(@builtin(global_invocation_id) gid: vec3<u32>) {
    solid_forces(gid, true);
}

// Accelerations of solid particle gid (cell-ordered dispatch), and with `xsph` its XSPH velocity.
fn solid_forces(gid: vec3<u32>, xsph: bool) {
    if (gid.x >= params.counts.y) {
        return;
    }
    let i = solid_order[gid.x].id; // cell-ordered dispatch (common.wgsl)
    if ((solid_flags[i] & SOLID_KINEMATIC) != 0u) {
        solid_acc[i] = vec4<f32>(0.0);
        solid_drho[i].x = 0.0;
        if (xsph) {
            solid_vel_adv[i] = vec4<f32>(solid_vel[i].xyz, 0.0);
        }
        return;
    }
    let ks = params.k_solid;
    let kl = params.k_liquid;
    let kx = params.k_cross;
    let support = 2.0 * ks.h;
    let r2s = support * support;
    let cap = params.counts.w;
    let g_l = liquid_gravity();
    let pi4 = solid_pos[i];
    let xi = pi4.xyz;
    let vi4 = solid_vel[i];
    let vi = vi4.xyz;
    let di = solid_dens[i];
    let rho = di.x;
    let pr = di.w;
    let n_s = di.z;
    let inv2 = 1.0 / (rho * rho);
    let tau_i = m3_scale(stress_tau_of(i), inv2);
    let art_i = stress_art_of(i);
    var a = vec3<f32>(0.0);
    // deviatoric stress over intact bonds (2.48), (2.43)
    let nb = bond_count[i];
    for (var b = 0u; b < nb; b++) {
        let j = bond_table[i * cap + b];
        let pj4 = solid_pos[j];
        let xij = min_image(xi - pj4.xyz);
        let grad = xij * grad_cubic_factor(ks, len3(xij));
        let rj = solid_dens[j].x;
        let tj = m3_div(stress_tau_of(j), rj * rj);
        a += m3_mul_v(m3_add(tau_i, tj), grad) * pj4.w;
    }
    // the hourglass control over the same bonds, in its own loop so that the stress loop carries no
    // extra state when the control is off
    if (params.hourglass > 0.0) {
        let fit_i = m3_load(solid_affine[i]);
        let x0i = solid_pos_ref[i].xyz;
        let flags_i = solid_flags[i];
        for (var b = 0u; b < nb; b++) {
            let j = bond_table[i * cap + b];
            let pj4 = solid_pos[j];
            let xij = min_image(xi - pj4.xyz);
            let stiff = hourglass_stiffness(flags_i, solid_flags[j]);
            a += hourglass_pair(fit_i, m3_load(solid_affine[j]), solid_pos_ref[j].xyz - x0i, xij, pj4.w, stiff);
        }
    }
    // isotropic pressure, artificial stress and artificial viscosity over current neighbours
    let pi = pr * inv2;
    let ci = cell_coords(xi);
    let kb = nbr_begin();
    let ke = nbr_end();
    let kstep = nbr_step(ci);
    var d_xsph = vec3<f32>(0.0);
    // and the continuity dρ/dt (2.47) over the same pairs
    var drho = 0.0;
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = solid_cell_start[c.y + 1];
        for (var q = solid_cell_start[c.x]; q < q_end; q++) {
            let e = solid_order[q];
            let j = e.id;
            let xij = min_image_wrapped(xi - e.pos);
            let r2 = dot3(xij, xij);
            if (r2 < r2s && j != i) {
                let r = sqrt(r2);
                let dj = solid_dens[j];
                let vj = solid_vel[j].xyz;
                let mj = solid_pos[j].w;
                let grad = xij * grad_cubic_factor(ks, r);
                drho += mj * dot3(vi - vj, grad);
                let pj = dj.w / (dj.x * dj.x);
                // −n∇p with the pair's mean fraction (antisymmetric: see forces_liquid)
                var acc = grad * (-0.5 * (n_s + dj.z) * (pi + pj));
                if (params.as_eps > 0.0) {
                    let f = w_cubic(ks, r) / params.wc_dx;
                    acc += m3_mul_v(m3_add(art_i, stress_art_of(j)), grad) * powi(f, params.as_exp);
                }
                let pij = artificial_viscosity(vi - vj, xij, r, ks.h, params.c_s, 0.5 * (rho + dj.x));
                acc -= grad * pij;
                a += acc * mj;
                if (xsph && params.xsph_s != 0.0) {
                    d_xsph += (vj - vi) * (mj / (0.5 * (rho + dj.x)) * w_poly6(ks, r));
                }
            }
        }
    }
    // boundary contact (mirror pressure, SPEC §4.1) and artificial viscosity against walls; an object
    // with Coulomb contact damps only the normal relative velocity and adds Coulomb friction (README:
    // deviations from SPEC)
    var contact = WallContact(vec3<f32>(0.0), 0.0, vec3<f32>(0.0));
    let dims = select(2, 3, params.switches.x != 0u);
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = boundary_cell_start[c.y + 1];
        for (var q = boundary_cell_start[c.x]; q < q_end; q++) {
            let e = boundary_order[q];
            let j = e.id;
            let xib = min_image_wrapped(xi - e.pos);
            let r2 = dot3(xib, xib);
            if (r2 < r2s) {
                let r = sqrt(r2);
                let grad = xib * grad_cubic_factor(ks, r);
                let vb = boundary_vel[j];
                // B_s in the continuity (2.47), with its solid-equivalent mass
                if (r < support) {
                    drho += vb.w * dot3(vi - vb.xyz, grad);
                }
                let o = objects[boundary_object(j)];
                var bracket: f32;
                if (o.density < 0.0) {
                    bracket = 2.0 * max(pr, 0.0) * inv2;
                } else {
                    bracket = pi + o.pressure / (o.density * o.density);
                }
                var vib = vi - vb.xyz;
                if (o.friction >= 0.0) {
                    let n = surface_normal(o, xi, dims);
                    if (dot3(n, n) > 0.0) {
                        vib = n * dot3(n, vib);
                    }
                }
                let pib = artificial_viscosity(vib, xib, r, ks.h, params.c_s, rho);
                a += grad * (vb.w * (-n_s * bracket - pib));
                if (o.friction > 0.0) {
                    // the pressure part alone; grad ∥ −x_ib, so it pushes i off the wall when nˢ·bracket > 0
                    wall_contact_add(&contact, o.friction, grad * (vb.w * (-n_s * bracket)), n_s * bracket > 0.0, vb.xyz);
                }
            }
        }
    }
    a += wall_contact_friction(contact, vi);
    // friction reaction (2.17, D-18) and reaction of the liquid–void attraction (3.4) — −(m_j/ρ_j) × the
    // pair term on liquid j (§3.12) — and on a membrane particle the reaction of the liquid–membrane
    // boundary forces (§4.1, within R_l), in one walk over the liquid within R_× ≥ R_l (each sum takes its
    // terms in the order separate walks would)
    let pair_terms = params.kbar > 0.0 || params.wicking > 0.0;
    let membrane = (solid_flags[i] & SOLID_MEMBRANE) != 0u;
    var normal_i = vec3<f32>(0.0);
    if (membrane) {
        normal_i = capsule_normal(solid_f[i], solid_normal0[i].xyz);
    }
    let seals = membrane && params.capsule_seal > 0.0 && capsule_seals(i);
    if (pair_terms || membrane) {
        let r2x = kx.r * kx.r;
        let r2l = kl.r * kl.r;
        var f = vec3<f32>(0.0);
        var fw = vec3<f32>(0.0);
        var fm = vec3<f32>(0.0);
        for (var k = kb; k < ke; k += kstep) {
            let c = nbr_span(ci, k);
            if (c.x < 0) { continue; }
            let q_end = liquid_cell_start[c.y + 1];
            for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
                let e = liquid_candidate(q);
                let j = e.j;
                let xij = min_image_wrapped(xi - e.pos_m.xyz);
                let r2 = dot3(xij, xij);
                if (r2 < r2x) {
                    let dj = liquid_dens[j];
                    let mj = liquid_candidate_mass(e);
                    let r = sqrt(r2);
                    if (params.kbar > 0.0) {
                        let kf = friction_coefficient(n_s, dj.z);
                        f += (vi - liquid_vel[j].xyz) * (mj / dj.x * kf * w_poly6(kx, r));
                    }
                    if (params.wicking > 0.0 && r > 0.0) {
                        fw -= xij * (mj / dj.x * wicking_pair(kx.h, n_s, di.y, r) / r);
                    }
                    if (membrane && r2 < r2l) {
                        let vj = liquid_vel[j].xyz;
                        // on liquid j beneath the capsule its ghosts' reaction acts instead (ghosts.wgsl)
                        if (!capsule_inner(normal_i, -xij) && liquid_sees[j] == 0u) {
                            let on_j = liquid_from_boundary(dj.x, dj.w, dj.y, vj, vi4.w, vi, -xij, r, -1.0, 0.0, 1.0, g_l,
                                                        params.ambient_pressure);
                            fm -= on_j * mj;
                        }
                        let seal_scale = liquid_acc[j].w;
                        if (seals && seal_scale > 0.0) {
                            // the reaction of the capsule's seal on liquid j (forces.rs capsule_seal_pair)
                            let sp = capsule_seal_pair(normal_i, -xij, r, vj - vi);
                            fm += sp.stop * (mj * seal_scale * capsule_seal_share(mj, pi4.w));
                        }
                    }
                }
            }
        }
        if (pair_terms) {
            a -= f / rho;
            a += fw / pi4.w;
        }
        if (membrane) {
            // the reaction of its ghosts' boundary forces on the liquid (ghosts.wgsl ghost_pressure)
            if (params.capsule_ghosts != 0u) {
                let k_end = ghost_start[i + 1u];
                for (var k = ghost_start[i]; k < k_end; k++) {
                    fm += ghost_state[2u * k + 1u].xyz;
                }
            }
            a += fm / pi4.w;
        }
    }
    // ligament spring and dashpot to the anchor X (Scenario::ligaments): −ω²(x − X) − 2ζω v
    if ((solid_flags[i] & SOLID_TETHERED) != 0u) {
        let d = min_image(xi - solid_pos_ref[i].xyz);
        a -= d * params.tether_omega2 + vi * params.tether_damping;
    }
    solid_acc[i] = vec4<f32>(a + params.gravity.xyz, 0.0);
    solid_drho[i].x = drho;
    if (xsph) {
        let eps = params.xsph_s;
        solid_vel_adv[i] = vec4<f32>(select(vi + d_xsph * eps, vi, eps == 0.0), 0.0);
    }
}
