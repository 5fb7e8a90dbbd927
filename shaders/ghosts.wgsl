// ghosts.wgsl — the capsule's ghost sites per step (sim::ghosts builds them); twin: src/sim/cpu/ghosts.rs.
//
// * ghost_place (with every grid build, before the ghosts' own): x_g = x_o + F_o d, the offset F_o d,
//   the owner's capsule normal n̂_o (capsule_normal) and whether the owner still seals (capsule_seals;
//   with the seal off, always). The ghost grid then bins ghost_pos like the three particle sets.
// * ghost_pressure (after density_liquid): a blood ghost's wall pressure and density, the Shepard means
//   Σ p_j W / Σ W, Σ ρ_j W / Σ W over the liquid that counts it (ghost_side_counts; Adami, Hu & Adams 2012
//   without their body-force term; p clamped at 0), and the reaction of its boundary force (§4.1) on that
//   liquid, −Σ m_j a_j with the ambient pressure taken off both sides, which its owner gathers in
//   forces_solid.
#import common

@compute @workgroup_size(64)
fn ghost_place(@builtin(global_invocation_id) gid: vec3<u32>) {
    let g = gid.x;
    if (g >= params.capsule_ghosts) {
        return;
    }
    let r0 = ghost_ref[2u * g];
    let r1 = ghost_ref[2u * g + 1u];
    let o = bitcast<u32>(r0.w);
    let f = m3_load(solid_f[o]);
    let fd = m3_mul_v(f, r0.xyz);
    let n = capsule_normal(solid_f[o], solid_normal0[o].xyz);
    let seals = params.capsule_seal <= 0.0 || capsule_seals(o);
    ghost_pos[g] = vec4<f32>(solid_pos[o].xyz + fd, select(0.0, 1.0, seals));
    ghost_frame[2u * g] = vec4<f32>(fd, r1.y);
    ghost_frame[2u * g + 1u] = vec4<f32>(n, r1.x);
}

@compute @workgroup_size(64)
fn ghost_pressure(@builtin(global_invocation_id) gid: vec3<u32>) {
    let g = gid.x;
    if (g >= params.capsule_ghosts) {
        return;
    }
    let m_g = ghost_frame[2u * g].w;
    if (m_g <= 0.0) {
        ghost_state[2u * g] = vec4<f32>(0.0);
        ghost_state[2u * g + 1u] = vec4<f32>(0.0);
        return;
    }
    let kl = params.k_liquid;
    let r2l = kl.r * kl.r;
    let xg = ghost_pos[g].xyz;
    let cg = cell_coords(xg);
    let kb = nbr_begin();
    let ke = nbr_end();
    let kstep = nbr_step(cg);
    let side = ghost_side(g);
    var sw = 0.0;
    var sp = 0.0;
    var sr = 0.0;
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(cg, k);
        if (c.x < 0) { continue; }
        let q_end = liquid_cell_start[c.y + 1];
        for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
            let e = liquid_candidate(q);
            let xgj = min_image_wrapped(xg - e.pos_m.xyz);
            let r2 = dot3(xgj, xgj);
            if (r2 < r2l && ghost_side_counts(side, -xgj)) {
                let w = w_poly6(kl, sqrt(r2));
                let dj = liquid_dens[e.j];
                sw += w;
                sp += dj.w * w;
                sr += dj.x * w;
            }
        }
    }
    if (sw <= 0.0) {
        ghost_state[2u * g] = vec4<f32>(0.0);
        ghost_state[2u * g + 1u] = vec4<f32>(0.0);
        return;
    }
    let p_g = max(sp / sw, 0.0);
    let rho_g = sr / sw;
    let v_o = solid_vel[bitcast<u32>(ghost_ref[2u * g].w)].xyz;
    var reaction = vec3<f32>(0.0);
    for (var k = kb; k < ke; k += kstep) {
        let c = nbr_span(cg, k);
        if (c.x < 0) { continue; }
        let q_end = liquid_cell_start[c.y + 1];
        for (var q = liquid_cell_start[c.x]; q < q_end; q++) {
            let e = liquid_candidate(q);
            let xgj = min_image_wrapped(xg - e.pos_m.xyz);
            let r2 = dot3(xgj, xgj);
            if (r2 < r2l && ghost_side_counts(side, -xgj)) {
                let j = e.j;
                let dj = liquid_dens[j];
                let a = ghost_on_liquid(dj.x, dj.w, dj.y, liquid_vel[j].xyz, m_g, v_o, -xgj, sqrt(r2), p_g, rho_g,
                                        params.ambient_pressure);
                reaction -= a * liquid_candidate_mass(e);
            }
        }
    }
    ghost_state[2u * g] = vec4<f32>(p_g, rho_g, 0.0, 0.0);
    ghost_state[2u * g + 1u] = vec4<f32>(reaction, 0.0);
}
