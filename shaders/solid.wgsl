// solid.wgsl — solid kinematics and stress; twin: src/sim/cpu/solid.rs.
//
// * solid_stress: Mooney–Rivlin deviatoric Cauchy stress τ (2.12)/(2.15) with the isochoric B̄
//   (SPEC §3.5, D-13), σ = τ − nˢpˢI, and Monaghan's artificial stress R (2.59), D-21, from a fixed
//   number of cyclic Jacobi sweeps (SPEC §3.8), operation for operation as the CPU.
// * solid_def_grad: ∇u over the bond table (2.43) at xⁿ and F^{n+1} = (I + ∇u)Fⁿ (2.41)–(2.42), D-11.
// * solid_fit: the best affine fit F̃ of each particle's intact bonds, for the hourglass control
//   (numerics.hourglass; README: deviations from SPEC).
#import common

fn mooney_rivlin_tau(f: mat3x3<f32>, c10: f32, c01: f32) -> mat3x3<f32> {
    let j = m3_det(f);
    let b = m3_mul(f, m3_transpose(f));
    let bb = m3_scale(b, pow(j, -2.0 / 3.0));
    let bb2 = m3_mul(bb, bb);
    let i1 = bb[0].x + bb[1].y + bb[2].z;
    let tr_b2 = bb2[0].x + bb2[1].y + bb2[2].z;
    let i2 = 0.5 * (i1 * i1 - tr_b2);
    let dev = m3_sub(m3_scale(bb, 2.0 / j * (c10 + c01 * i1)), m3_scale(bb2, 2.0 / j * c01));
    let iso = 2.0 / (3.0 * j) * (c10 * i1 + 2.0 * c01 * i2);
    return m3_sub(dev, m3_scale(m3_identity(), iso));
}

struct Eigen {
    lam: vec3<f32>,
    q: mat3x3<f32>,
}

// Cyclic Jacobi (JACOBI_SWEEPS sweeps over (0,1), (0,2), (1,2)); a[col][row].
fn sym_eigen(m: mat3x3<f32>) -> Eigen {
    var a: array<array<f32, 3>, 3>;
    var v: array<array<f32, 3>, 3>;
    for (var c = 0; c < 3; c++) {
        for (var r = 0; r < 3; r++) {
            a[c][r] = m[c][r];
            v[c][r] = select(0.0, 1.0, c == r);
        }
    }
    for (var sweep = 0u; sweep < JACOBI_SWEEPS; sweep++) {
        for (var pair = 0; pair < 3; pair++) {
            let p = select(select(1, 0, pair < 2), 0, pair == 0);
            let q = select(2, 1, pair == 0);
            let apq = a[q][p];
            if (abs(apq) <= 1e-30) {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
            let t = signum(theta) / (abs(theta) + sqrt(theta * theta + 1.0));
            let c = 1.0 / sqrt(t * t + 1.0);
            let s = t * c;
            let r = 3 - p - q;
            let arp = a[p][r];
            let arq = a[q][r];
            a[p][p] -= t * apq;
            a[q][q] += t * apq;
            a[q][p] = 0.0;
            a[p][q] = 0.0;
            let nrp = c * arp - s * arq;
            let nrq = s * arp + c * arq;
            a[p][r] = nrp;
            a[r][p] = nrp;
            a[q][r] = nrq;
            a[r][q] = nrq;
            for (var row = 0; row < 3; row++) {
                let vp = v[p][row];
                let vq = v[q][row];
                v[p][row] = c * vp - s * vq;
                v[q][row] = s * vp + c * vq;
            }
        }
    }
    return Eigen(
        vec3<f32>(a[0][0], a[1][1], a[2][2]),
        m3(vec3<f32>(v[0][0], v[0][1], v[0][2]), vec3<f32>(v[1][0], v[1][1], v[1][2]), vec3<f32>(v[2][0], v[2][1], v[2][2])),
    );
}

// R of (2.59): −εσ'_a/ρ² on positive principal stresses, rotated back (D-21).
fn artificial_stress(sigma: mat3x3<f32>, rho: f32, eps: f32) -> mat3x3<f32> {
    var r = m3_scale(m3_identity(), 0.0);
    if (eps == 0.0) {
        return r;
    }
    let e = sym_eigen(sigma);
    for (var a = 0; a < 3; a++) {
        let s = e.lam[a];
        if (s > 0.0) {
            let ra = -eps * s / (rho * rho);
            let qa = e.q[a];
            r = m3_add(r, m3_scale(m3(qa * qa.x, qa * qa.y, qa * qa.z), ra));
        }
    }
    return r;
}

@compute @workgroup_size(64)
fn solid_stress(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    // a membrane (capsule) particle's C10, C01 are the tissue's times membrane_stiffness
    let k = stiffness_factor(solid_flags[i]);
    let t = mooney_rivlin_tau(m3_load(solid_f[i]), params.c10 * k, params.c01 * k);
    let d = solid_dens[i];
    let sigma = m3_sub(t, m3_scale(m3_identity(), d.z * d.w));
    let art = artificial_stress(sigma, d.x, params.as_eps);
    solid_tau_art[i] = stress_pack(t, art);
}

@compute @workgroup_size(64)
fn solid_def_grad(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y) {
        return;
    }
    let k = params.k_solid;
    let cap = params.counts.w;
    let xi = solid_pos[i].xyz;
    let dxi = solid_disp[i].xyz;
    var grad_u = m3_scale(m3_identity(), 0.0);
    let n = bond_count[i];
    for (var b = 0u; b < n; b++) {
        let j = bond_table[i * cap + b];
        let pj = solid_pos[j];
        let xij = min_image(xi - pj.xyz);
        let g = grad_cubic_factor(k, len3(xij));
        grad_u = m3_add(grad_u, m3_scale(outer3(solid_disp[j].xyz - dxi, xij * g), pj.w / solid_dens[j].x));
    }
    let f = m3_mul(m3_add(m3_identity(), grad_u), m3_load(solid_f[i]));
    solid_f[i] = m3_store(f);
}

struct InverseDet {
    inv: mat3x3<f32>,
    det: f32,
}

// M⁻¹ by cofactors, (c₁ × c₂, c₂ × c₀, c₀ × c₁)ᵀ / det, and det M (solid.rs `inverse_and_det`).
fn m3_inverse(m: mat3x3<f32>) -> InverseDet {
    let t0 = cross3(m[1], m[2]);
    let t1 = cross3(m[2], m[0]);
    let t2 = cross3(m[0], m[1]);
    let det = dot3(m[2], t2);
    let inv = 1.0 / det;
    return InverseDet(m3_transpose(m3(t0 * inv, t1 * inv, t2 * inv)), det);
}

// F̃_i = [Σ w x_ij ⊗ X_ij][Σ w X_ij ⊗ X_ij]⁻¹ over the intact bonds, x_ij = x_j − x_i now, X_ij in the
// generated configuration, w = W_C(|X_ij|); plane strain in 2-D (F̃_zz = 1); F̃ := F where the bonds do
// not span the space (solid.rs `solid_fit`).
@compute @workgroup_size(64)
fn solid_fit(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.counts.y || params.hourglass <= 0.0) {
        return;
    }
    let k = params.k_solid;
    let cap = params.counts.w;
    let xi = solid_pos[i].xyz;
    let x0i = solid_pos_ref[i].xyz;
    var a = m3_scale(m3_identity(), 0.0);
    var b = m3_scale(m3_identity(), 0.0);
    let n = bond_count[i];
    for (var q = 0u; q < n; q++) {
        let j = bond_table[i * cap + q];
        let big = min_image(solid_pos_ref[j].xyz - x0i);
        let now = min_image(solid_pos[j].xyz - xi);
        let w = w_cubic(k, len3(big));
        a = m3_add(a, m3_scale(outer3(now, big), w));
        b = m3_add(b, m3_scale(outer3(big, big), w));
    }
    var tr = b[0].x + b[1].y + b[2].z;
    var d = 3;
    if (params.switches.x == 0u) {
        a[2].z = 1.0;
        b[2].z = 1.0;
        tr = b[0].x + b[1].y;
        d = 2;
    }
    let id = m3_inverse(b);
    let scale = powi(tr / f32(d), d);
    if (tr > 0.0 && id.det > 1e-6 * scale) {
        solid_affine[i] = m3_store(m3_mul(a, id.inv));
    } else {
        solid_affine[i] = solid_f[i];
    }
}
