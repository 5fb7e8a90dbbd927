// density.wgsl — densities, volume fractions and penalty pressures; twin: src/sim/cpu/density.rs.
//
// * density_liquid: ρˡ by summation over L ∪ B_l (2.46) (membrane particles count as boundary),
//   nˡ = ρ/ρ₀ˡ, nˢ by summation of the solid (SPEC D-8), pˡ = k(nˢ + nˡ − 1 + C₁nˢnˡ) (2.53)/(3.5, D-9),
//   clamped at 0 unless liquid_tension and nˢ below its limit or the particle in its region; plus the
//   ambient pressure p_a before the clamp; in an outlet's buffer the outlet's p_a + gauge and the
//   density of pure liquid at it instead.
// * density_solid: nˢ = ρ/ρ₀ˢ, nˡ by summation of the liquid and the walls' liquid-equivalent mass (D-8
//   with §4.1's boundary as a continuation of the liquid, as in 2.46; membrane override 1 − nˢ_sat,
//   §3.1.3), pˢ = k_s(nˢ − nˢ_sat) + k_sat(nˢ + nˡ − 1) (2.52); density_solid_kept, evaluation 0's, keeps
//   the nˡ of the previous step's evaluation 1 (same positions) and walks nothing. The continuity
//   dρˢ/dt (2.47) is summed in forces.wgsl's walks over the same solid and wall neighbours.
// Neighbour sums run in the canonical order of grid.wgsl, as on the CPU.
#import common

// Params::liquid_may_pull: the liquid pressure may go negative below the solid fraction limit
// (switches.z: bits of Params::liquid_tension_below_ns) or in a region of Params::liquid_tension_in
// (TensionRegion::contains, same comparisons and arithmetic).
fn liquid_may_pull(x: vec3<f32>, n_s: f32) -> bool {
    if (n_s < bitcast<f32>(params.switches.z)) {
        return true;
    }
    for (var k = 0u; k < 4u; k++) {
        let a = params.tension[2u * k];
        let b = params.tension[2u * k + 1u];
        if (a.w == 1.0) {
            if (x.x >= a.x && x.y >= a.y && x.z >= a.z && x.x <= b.x && x.y <= b.y && x.z <= b.z) {
                return true;
            }
        } else if (a.w == 2.0) {
            let d = x - a.xyz;
            if (d.x * d.x + d.y * d.y + d.z * d.z <= b.w) {
                return true;
            }
        }
    }
    return false;
}

@compute @workgroup_size(64)
fn density_liquid(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.counts.x) {
        return;
    }
    let i = liquid_dispatched(gid.x); // cell-ordered dispatch (common.wgsl)
    let kl = params.k_liquid;
    let kx = params.k_cross;
    let xi = liquid_pos[i].xyz;
    let ci = cell_coords(xi);
    let kb = nbr_begin();
    let ke = nbr_end();
    let kstep = nbr_step(ci);
    let r2l = kl.r * kl.r;
    let r2x = kx.r * kx.r;
    var rho = 0.0;
    // liquid (2.46)
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = liquid_cell_start[c.y + 1];
        for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
            let e = liquid_candidate(q);
            let xij = min_image_wrapped(xi - e.pos_m.xyz);
            let r2 = dot3(xij, xij);
            if (r2 < r2l) {
                rho += liquid_candidate_mass(e) * w_poly6(kl, sqrt(r2));
            }
        }
    }
    // wall particles: the liquid-equivalent mass in ρ (2.46) within R_l and, where a wall stands in the
    // tissue's place, its solid-equivalent mass in nˢ within R_× (§4.1)
    var sum_bs = 0.0;
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(ci, k);
        if (c.x < 0) { continue; }
        let q_end = boundary_cell_start[c.y + 1];
        for (var q = boundary_cell_start[c.x]; q < q_end; q++) {
            let e = boundary_order[q];
            let j = e.id;
            let xij = min_image_wrapped(xi - e.pos);
            let r2 = dot3(xij, xij);
            if (r2 < r2x) {
                let r = sqrt(r2);
                if (r < kl.r) {
                    rho += boundary_pos[j].w * w_poly6(kl, r);
                }
                if ((bitcast<u32>(boundary_pos0[j].w) & BOUNDARY_IN_TISSUE) != 0u) {
                    sum_bs += boundary_vel[j].w * w_poly6(kx, r);
                }
            }
        }
    }
    // the capsule's ghost sites (ghosts.wgsl): tissue sites in nˢ within R_×, blood sites in ρ within R_l
    var sum_s = 0.0;
    var sees = false;
    if (params.capsule_ghosts != 0u) {
        let r2g = max(r2x, r2l);
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
                    if (ghost_side_counts(side, xig)) {
                        let r = sqrt(r2);
                        let m_l = side.frame0.w;
                        if (r < kl.r && m_l > 0.0) {
                            sees = true;
                            rho += m_l * w_poly6(kl, r);
                        }
                        if (r < kx.r) {
                            sum_s += side.frame1.w * w_poly6(kx, r);
                        }
                    }
                }
            }
        }
    }
    liquid_sees[i] = select(0u, 1u, sees);
    // One pass over the solid (R_× ≥ R_l): membrane particles as liquid boundary, and nˢ (D-8).
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
                if ((solid_flags[j] & SOLID_MEMBRANE) != 0u) {
                    let n = capsule_normal(solid_f[j], solid_normal0[j].xyz);
                    // a boundary particle (2.46) unless the ghosts continue the liquid here (forces.rs capsule_inner)
                    if (!capsule_inner(n, xij) && r < kl.r && !sees) {
                        rho += solid_vel[j].w * w_poly6(kl, r);
                    }
                }
                sum_s += solid_pos[j].w * w_poly6(kx, r);
            }
        }
    }
    let n_s = (sum_s + sum_bs) / params.rho0_s;
    let n_l = rho / params.rho0_l;
    let raw = params.ambient_pressure + params.k_l * (n_s + n_l - 1.0 + params.c1 * n_s * n_l);
    // p_a + (2.53) clamped at 0 unless the liquid may take tension here; an outlet's buffer carries its
    // prescribed pressure and density
    var pr = raw;
    var rho_i = rho;
    var n_l_i = n_l;
    let outlet = outlet_find(xi);
    if (outlet >= 0) {
        rho_i = params.outlet[3 * outlet].w;
        n_l_i = rho_i / params.rho0_l;
        pr = params.outlet[3 * outlet + 1].w;
    } else if (!liquid_may_pull(xi, n_s)) {
        pr = max(raw, 0.0);
    }
    // CPU: n_l = rho / rho0_l computed again from the stored ρ (same operation).
    liquid_dens[i] = vec4<f32>(rho_i, n_l_i, n_s, pr);
}

// The solid's continuity, fractions and pressure, nˡ summed over the liquid.
@compute @workgroup_size(64)
fn density_solid(@builtin(global_invocation_id) gid: vec3<u32>) {
    solid_density(gid, true);
}

// The same with the nˡ of the previous step's evaluation 1 (solid_dens.y): evaluation 0 of a step, on
// the positions evaluation 1 saw (the corrector moves nothing), so the sum would repeat it bit for bit.
@compute @workgroup_size(64)
fn density_solid_kept(@builtin(global_invocation_id) gid: vec3<u32>) {
    solid_density(gid, false);
}

fn solid_density(gid: vec3<u32>, sum_liquid: bool) {
    if (gid.x >= params.counts.y) {
        return;
    }
    let i = solid_order[gid.x].id; // cell-ordered dispatch (common.wgsl)
    let kx = params.k_cross;
    let r2x = kx.r * kx.r;
    var n_l = 1.0 - params.n_sat;
    if ((solid_flags[i] & SOLID_MEMBRANE) == 0u && !sum_liquid) {
        n_l = solid_dens[i].y;
    } else if ((solid_flags[i] & SOLID_MEMBRANE) == 0u) {
        let xi = solid_pos[i].xyz;
        let ci = cell_coords(xi);
        let kb = nbr_begin();
        let ke = nbr_end();
        let kstep = nbr_step(ci);
        // the walls' liquid-equivalent mass m_b^l within R_×: a wall continues the liquid in the solid's
        // fraction as it does in the liquid's ρ (2.46)
        var sum_b = 0.0;
        for (var k = kb; k < ke; k += kstep) {
            let c = nbr_span(ci, k);
            if (c.x < 0) { continue; }
            let q_end = boundary_cell_start[c.y + 1];
            for (var q = boundary_cell_start[c.x]; q < q_end; q++) {
                let e = boundary_order[q];
                let xij = min_image_wrapped(xi - e.pos);
                let r2 = dot3(xij, xij);
                if (r2 < r2x) {
                    sum_b += boundary_pos[e.id].w * w_poly6(kx, sqrt(r2));
                }
            }
        }
        var sum = 0.0;
        for (var k = kb; k < ke; k += kstep) {
            let c = nbr_span(ci, k);
            if (c.x < 0) { continue; }
            let q_end = liquid_cell_start[c.y + 1];
            for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
                let e = liquid_candidate(q);
                let xij = min_image_wrapped(xi - e.pos_m.xyz);
                let r2 = dot3(xij, xij);
                if (r2 < r2x) {
                    sum += liquid_candidate_mass(e) * w_poly6(kx, sqrt(r2));
                }
            }
        }
        n_l = (sum + sum_b) / params.rho0_l;
    }
    let rho = solid_dens[i].x;
    let n_s = rho / params.rho0_s;
    let pr = params.k_s * (n_s - params.n_sat) + params.k_sat * (n_s + n_l - 1.0);
    solid_dens[i] = vec4<f32>(rho, n_l, n_s, pr);
}
