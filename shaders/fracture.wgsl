// fracture.wgsl — irreversible fracture of the connectivity table (thesis §3.1.4, Algorithm 2;
// SPEC §4.6); twin: src/sim/cpu/fracture.rs. After each corrector every particle drops the bonds
// stretched beyond their breaking length — 2h_s (the thesis criterion), or max(2h_s, λ_c r₀) with a
// critical stretch λ_c (`solid.critical_stretch`) — keeping the order of the rest (and of their limits). Each particle tests its own list with the same
// rule, so removal is symmetric and needs no atomics (the broken-end counter is an integer atomic).
// The table itself is built once on the host by the CPU twin `fracture_build_bonds`.
#import common

@compute @workgroup_size(64)
fn fracture_apply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let cap = params.counts.w;
    let xi = solid_pos[i].xyz;
    let n = bond_count[i];
    var keep = 0u;
    for (var k = 0u; k < n; k++) {
        let j = bond_table[i * cap + k];
        let limit2 = bond_limit[i * cap + k];
        let d = min_image(xi - solid_pos[j].xyz);
        if (dot3(d, d) <= limit2) {
            bond_table[i * cap + keep] = j;
            bond_limit[i * cap + keep] = limit2;
            keep += 1u;
        }
    }
    for (var k = keep; k < n; k++) {
        bond_table[i * cap + k] = 0xffffffffu;
        bond_limit[i * cap + k] = 0.0;
    }
    bond_count[i] = keep;
    if (n > keep) {
        atomicAdd(&step.broken_ends, n - keep);
    }
}
