// fracture.wgsl — irreversible fracture of the connectivity table (thesis §3.1.4, Algorithm 2;
// SPEC §4.6); twin: src/sim/cpu/fracture.rs. After each corrector every particle drops the bonds
// stretched beyond their breaking length — 2h_s (the thesis criterion), or max(2h_s, λ_c r₀) with a
// critical stretch λ_c (`solid.critical_stretch`) — keeping the order of the rest (and of their limits). Each particle tests its own list with the same
// rule, so removal is symmetric and needs no atomics (the broken-end counter is an integer atomic).
// The table itself is built once on the host by the CPU twin `fracture_build_bonds`. A scalpel with
// `blade_cut` (SPEC §4.6, D-25; ObjectGpu.blade > 0) also cuts every bond whose segment crosses its
// blade: the mid-plane rectangle of its box across the cut axis, at the pose of tⁿ⁺¹.
#import common

// Twin of cpu::fracture::blade_crosses: does the segment xi → xi + d cross object o's blade (its
// mid-plane rectangle grown by the support radius R_s in the plane — the reach of its particles)?
fn blade_crosses(o: ObjectGpu, xi: vec3<f32>, d: vec3<f32>) -> bool {
    let ax = i32(o.blade) - 1;
    let mid = 0.5 * (o.geom_a[ax] + o.geom_b[ax]);
    let di = xi[ax] - mid;
    let dj = (xi[ax] + d[ax]) - mid;
    if (di * dj >= 0.0) {
        return false;
    }
    let t = di / (di - dj);
    var dims = 2;
    if (params.switches.x != 0u) {
        dims = 3;
    }
    for (var k = 0; k < dims; k++) {
        if (k != ax) {
            let c = xi[k] + d[k] * t;
            if (!(c >= o.geom_a[k] - params.k_solid.r && c <= o.geom_b[k] + params.k_solid.r)) {
                return false;
            }
        }
    }
    return true;
}

// Twin of cpu::fracture::bond_cut: tested from the lower index's end so that i and j agree bit for bit.
fn bond_cut(i: u32, j: u32, xi: vec3<f32>, xj: vec3<f32>) -> bool {
    var p = xi;
    var q = xj;
    if (j < i) {
        p = xj;
        q = xi;
    }
    let d = min_image(q - p);
    for (var k = 0u; k < params.switches.w; k++) {
        if (objects[k].blade != 0u && blade_crosses(objects[k], p, d)) {
            return true;
        }
    }
    return false;
}

// Twin of cpu::fracture::blade_near: can a bond of x_i no longer than params.bond_reach cross object
// o's blade? (Conservative by a margin of 10⁻³ of the reach; bond_reach = 0: always.)
fn blade_near(o: ObjectGpu, xi: vec3<f32>) -> bool {
    if (params.bond_reach <= 0.0) {
        return true;
    }
    let r = params.bond_reach * 1.001;
    let ax = i32(o.blade) - 1;
    let mid = 0.5 * (o.geom_a[ax] + o.geom_b[ax]);
    if (!(abs(xi[ax] - mid) <= r)) {
        return false;
    }
    var dims = 2;
    if (params.switches.x != 0u) {
        dims = 3;
    }
    for (var k = 0; k < dims; k++) {
        if (k != ax) {
            if (!(xi[k] >= o.geom_a[k] - params.k_solid.r - r && xi[k] <= o.geom_b[k] + params.k_solid.r + r)) {
                return false;
            }
        }
    }
    return true;
}

// Whether some cutting blade can reach a bond of x_i (the CPU's `near`): most scenes have no blade and
// most of an organ lies far from it, and then no bond of i needs bond_cut's test against every object.
fn blade_within_reach(xi: vec3<f32>) -> bool {
    for (var k = 0u; k < params.switches.w; k++) {
        if (objects[k].blade != 0u && blade_near(objects[k], xi)) {
            return true;
        }
    }
    return false;
}

@compute @workgroup_size(64)
fn fracture_apply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let cap = params.counts.w;
    let xi = solid_pos[i].xyz;
    let n = bond_count[i];
    let blades = blade_within_reach(xi);
    var keep = 0u;
    for (var k = 0u; k < n; k++) {
        let j = bond_table[i * cap + k];
        let limit2 = bond_limit[i * cap + k];
        let xj = solid_pos[j].xyz;
        let d = min_image(xi - xj);
        if (dot3(d, d) <= limit2 && !(blades && bond_cut(i, j, xi, xj))) {
            // compact only behind a broken bond: an intact table is not rewritten every step
            if (keep != k) {
                bond_table[i * cap + keep] = j;
                bond_limit[i * cap + keep] = limit2;
            }
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
