//! Solid kinematics and stress — twin of `shaders/solid.wgsl`.
//!
//! * `solid_def_grad`: displacement gradient over the bond table (2.43) and the updated-Lagrangian
//!   deformation gradient F^{n+1} = (I + ∇u)Fⁿ (2.41)–(2.42), SPEC §3.5 / D-11.
//! * `solid_stress`: Mooney–Rivlin deviatoric Cauchy stress τ (2.12)/(2.15) with the isochoric B̄
//!   (SPEC D-13), full stress σ = τ − nˢpˢI, and Monaghan's artificial stress R (2.59), D-21, from a
//!   fixed number of cyclic Jacobi sweeps (identical on both back-ends).
//! * `solid_fit`: the best affine fit F̃ of each particle's intact bonds, for the hourglass control
//!   (`numerics.hourglass`; README: deviations from SPEC).

use super::SolidSet;
use crate::sim::params::Params;
use glam::{Mat3, Vec3};
use rayon::prelude::*;

/// Number of cyclic Jacobi sweeps of the 3×3 symmetric eigen-decomposition (SPEC §3.8).
pub const JACOBI_SWEEPS: usize = 6;

/// Mooney–Rivlin deviatoric Cauchy stress (SPEC §3.5):
/// τ = (2/J)[(C10 + C01 Ī₁)B̄ − C01 B̄²] − (2/(3J))(C10 Ī₁ + 2C01 Ī₂) I, B̄ = J^(−2/3) F Fᵀ.
pub fn mooney_rivlin_tau(f: Mat3, c10: f32, c01: f32) -> Mat3 {
    let j = f.determinant();
    let b = f * f.transpose();
    let bb = b * j.powf(-2.0 / 3.0);
    let bb2 = bb * bb;
    let i1 = bb.x_axis.x + bb.y_axis.y + bb.z_axis.z;
    let tr_b2 = bb2.x_axis.x + bb2.y_axis.y + bb2.z_axis.z;
    let i2 = 0.5 * (i1 * i1 - tr_b2);
    let dev = bb * (2.0 / j * (c10 + c01 * i1)) - bb2 * (2.0 / j * c01);
    let iso = 2.0 / (3.0 * j) * (c10 * i1 + 2.0 * c01 * i2);
    dev - Mat3::IDENTITY * iso
}

/// Eigen-decomposition of a symmetric 3×3 matrix by `JACOBI_SWEEPS` cyclic Jacobi sweeps.
/// Returns the eigenvalues and the matrix whose columns are the eigenvectors.
pub fn sym_eigen(m: Mat3) -> (Vec3, Mat3) {
    let mut a = m.to_cols_array_2d(); // a[col][row]; symmetric, so a[p][q] = A_pq
    let mut v = [[1.0f32, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]; // v[col][row]
    for _ in 0..JACOBI_SWEEPS {
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            let apq = a[q][p];
            if apq.abs() <= 1e-30 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
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
            for row in 0..3 {
                let vp = v[p][row];
                let vq = v[q][row];
                v[p][row] = c * vp - s * vq;
                v[q][row] = s * vp + c * vq;
            }
        }
    }
    (Vec3::new(a[0][0], a[1][1], a[2][2]), Mat3::from_cols(Vec3::from(v[0]), Vec3::from(v[1]), Vec3::from(v[2])))
}

/// Artificial stress R_i of (2.59) from the full stress σ (tension positive): R'_a = −εσ'_a/ρ² on the
/// positive principal stresses, rotated back (SPEC D-21).
pub fn artificial_stress(sigma: Mat3, rho: f32, eps: f32) -> Mat3 {
    if eps == 0.0 {
        return Mat3::ZERO;
    }
    let (lam, q) = sym_eigen(sigma);
    let mut r = Mat3::ZERO;
    for a in 0..3 {
        let s = lam[a];
        if s > 0.0 {
            let ra = -eps * s / (rho * rho);
            let qa = q.col(a);
            r += Mat3::from_cols(qa * qa.x, qa * qa.y, qa * qa.z) * ra;
        }
    }
    r
}

/// Outer product u ⊗ w (M_ab = u_a w_b).
#[inline]
pub fn outer(u: Vec3, w: Vec3) -> Mat3 {
    Mat3::from_cols(u * w.x, u * w.y, u * w.z)
}

/// M⁻¹ by cofactors, (c₁ × c₂, c₂ × c₀, c₀ × c₁)ᵀ / det (solid.wgsl `m3_inverse`, operation for
/// operation), and det M.
pub fn inverse_and_det(m: Mat3) -> (Mat3, f32) {
    let (c0, c1, c2) = (m.x_axis, m.y_axis, m.z_axis);
    let t0 = c1.cross(c2);
    let t1 = c2.cross(c0);
    let t2 = c0.cross(c1);
    let det = c2.dot(t2);
    let inv = 1.0 / det;
    (Mat3::from_cols(t0 * inv, t1 * inv, t2 * inv).transpose(), det)
}

/// solid_fit: F̃_i = [Σ_j w_ij x_ij ⊗ X_ij][Σ_j w_ij X_ij ⊗ X_ij]⁻¹ over the intact bonds of i, with
/// x_ij = x_j − x_i now, X_ij the same bond in the generated configuration (`x_ref`) and w_ij = W_C(|X_ij|):
/// the affine map that best explains the bonds (least squares). Unlike the SPH gradient (2.43) it
/// reproduces an affine deformation exactly at a surface or beside a crack, so that F̃X_ij − x_ij is
/// the non-affine (zero-energy, "hourglass") part of the motion alone. 2-D: plane strain, F̃_zz = 1.
/// Where the bonds do not span the space (det B ≤ 10⁻⁶ (tr B/d)^d, e.g. a fragment of two particles)
/// F̃ := F, the particle's deformation gradient.
pub fn solid_fit(p: &Params, s: &SolidSet) -> Vec<Mat3> {
    let k = &p.k_solid;
    let period = p.periodic_len();
    let cap = s.bond_capacity;
    let three_d = p.dim.n() == 3;
    (0..s.x.len())
        .into_par_iter()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|i| {
            let mut a = Mat3::ZERO;
            let mut b = Mat3::ZERO;
            for &j in &s.bonds[i * cap..i * cap + s.bond_count[i] as usize] {
                let j = j as usize;
                let big = super::grid::min_image(s.x_ref[j] - s.x_ref[i], period);
                let now = super::grid::min_image(s.x[j] - s.x[i], period);
                let w = k.w_cubic(big.length());
                a += outer(now, big) * w;
                b += outer(big, big) * w;
            }
            let (tr, d) = if three_d {
                (b.x_axis.x + b.y_axis.y + b.z_axis.z, 3)
            } else {
                a.z_axis.z = 1.0;
                b.z_axis.z = 1.0;
                (b.x_axis.x + b.y_axis.y, 2)
            };
            let (inv, det) = inverse_and_det(b);
            let scale = (tr / d as f32).powi(d);
            if tr > 0.0 && det > 1e-6 * scale { a * inv } else { s.def_grad[i] }
        })
        .collect()
}

/// solid_stress: τ, then σ = τ − nˢpˢI and R for every solid particle; a membrane (capsule) particle's
/// C10, C01 are the tissue's times `membrane_stiffness`.
pub fn solid_stress(p: &Params, s: &mut SolidSet) {
    let (c10, c01, eps) = (p.c10, p.c01, p.as_eps);
    s.tau.par_iter_mut().zip(s.art.par_iter_mut()).enumerate().for_each(|(i, (tau, art))| {
        let k = p.stiffness_factor(s.flags[i]);
        let t = mooney_rivlin_tau(s.def_grad[i], c10 * k, c01 * k);
        *tau = t;
        let sigma = t - Mat3::IDENTITY * (s.n_s[i] * s.p[i]);
        *art = artificial_stress(sigma, s.rho[i], eps);
    });
}

/// solid_def_grad: ∇u_i = Σ_{j∈C(i)} (m_j/ρ_j)(Δx_j − Δx_i) ⊗ ∇W_C(x_i − x_j) at xⁿ, F ← (I + ∇u)F.
pub fn solid_def_grad(p: &Params, s: &mut SolidSet) {
    let k = &p.k_solid;
    let period = p.periodic_len();
    let cap = s.bond_capacity;
    let (x, dx, m, rho, bonds, count) = (&s.x, &s.dx, &s.m, &s.rho, &s.bonds, &s.bond_count);
    s.def_grad.par_iter_mut().enumerate().for_each(|(i, f)| {
        let mut grad_u = Mat3::ZERO;
        let n = count[i] as usize;
        for &j in &bonds[i * cap..i * cap + n] {
            let j = j as usize;
            let xij = super::grid::min_image(x[i] - x[j], period);
            let g = k.grad_cubic_factor(xij.length());
            grad_u += outer(dx[j] - dx[i], xij * g) * (m[j] / rho[j]);
        }
        *f = (Mat3::IDENTITY + grad_u) * *f;
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 33) as f64 / (1u64 << 31) as f64) as f32
    }

    /// ψ_iso = C10(Ī₁ − 3) + C01(Ī₂ − 3), in f64 for finite differences.
    fn psi(f: [[f64; 3]; 3], c10: f64, c01: f64) -> f64 {
        let det = f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1]) - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
            + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]);
        let mut b = [[0.0; 3]; 3];
        for a in 0..3 {
            for c in 0..3 {
                b[a][c] = (0..3).map(|k| f[a][k] * f[c][k]).sum::<f64>() * det.powf(-2.0 / 3.0);
            }
        }
        let i1 = b[0][0] + b[1][1] + b[2][2];
        let tr_b2: f64 = (0..3).flat_map(|a| (0..3).map(move |c| (a, c))).map(|(a, c)| b[a][c] * b[c][a]).sum();
        c10 * (i1 - 3.0) + c01 * (0.5 * (i1 * i1 - tr_b2) - 3.0)
    }

    /// SPEC §3.15 (4): τ = (1/J)(∂ψ/∂F)Fᵀ by central differences; tr τ = 0; small strain τ = 2G dev ε.
    #[test]
    fn mooney_rivlin_matches_energy_derivative() {
        let (c10, c01) = (250_000.0f64, 9167.5f64);
        let mut seed = 7u64;
        for _ in 0..20 {
            let mut f = [[0.0f64; 3]; 3];
            for (a, row) in f.iter_mut().enumerate() {
                for (c, x) in row.iter_mut().enumerate() {
                    *x = if a == c { 1.0 } else { 0.0 } + 0.3 * (lcg(&mut seed) as f64 - 0.5);
                }
            }
            let fm = Mat3::from_cols_array_2d(&[
                [f[0][0] as f32, f[1][0] as f32, f[2][0] as f32],
                [f[0][1] as f32, f[1][1] as f32, f[2][1] as f32],
                [f[0][2] as f32, f[1][2] as f32, f[2][2] as f32],
            ]);
            let j = fm.determinant() as f64;
            assert!(j > 0.0);
            let tau = mooney_rivlin_tau(fm, c10 as f32, c01 as f32);
            // P = ∂ψ/∂F by central differences, then τ = P Fᵀ / J.
            let hstep = 1e-6;
            let mut p = [[0.0f64; 3]; 3];
            for a in 0..3 {
                for c in 0..3 {
                    let mut fp = f;
                    let mut fmn = f;
                    fp[a][c] += hstep;
                    fmn[a][c] -= hstep;
                    p[a][c] = (psi(fp, c10, c01) - psi(fmn, c10, c01)) / (2.0 * hstep);
                }
            }
            let scale = c10 + c01;
            for a in 0..3 {
                for c in 0..3 {
                    let expect: f64 = (0..3).map(|k| p[a][k] * f[c][k]).sum::<f64>() / j;
                    let got = tau.col(c)[a] as f64;
                    assert!((got - expect).abs() <= 2e-4 * scale, "τ[{a}][{c}] {got} vs {expect}");
                }
            }
            let tr = tau.x_axis.x + tau.y_axis.y + tau.z_axis.z;
            assert!(tr.abs() <= 1e-5 * scale as f32, "trace {tr}");
        }
        // Small strain: τ ≈ 2G dev(ε), G = 2(C10 + C01).
        let e = Mat3::from_cols(
            Vec3::new(1e-4, 0.3e-4, 0.0),
            Vec3::new(0.3e-4, -0.5e-4, 0.2e-4),
            Vec3::new(0.0, 0.2e-4, 0.2e-4),
        );
        let tau = mooney_rivlin_tau(Mat3::IDENTITY + e, c10 as f32, c01 as f32);
        let g = 2.0 * (c10 + c01) as f32;
        let tr = (e.x_axis.x + e.y_axis.y + e.z_axis.z) / 3.0;
        let dev = e - Mat3::IDENTITY * tr;
        for c in 0..3 {
            for a in 0..3 {
                let expect = 2.0 * g * dev.col(c)[a];
                assert!((tau.col(c)[a] - expect).abs() <= 1e-3 * 2.0 * g * 1e-4 + 2e-3 * expect.abs(), "{a}{c}");
            }
        }
    }

    /// τ (2.12) and R (2.59) come out symmetric bit for bit (B = FFᵀ, B̄², and Σ ra qa ⊗ qa form each
    /// pair (r, c), (c, r) from the same products in the same order), so the GPU's `StressGpu`, which
    /// keeps their upper triangles, holds exactly what the CPU twin uses; and the packing round-trips.
    #[test]
    fn stress_and_artificial_stress_are_exactly_symmetric() {
        use crate::sim::gpu::gpu_types::StressGpu;
        let mut seed = 11u64;
        for _ in 0..200 {
            let f = Mat3::from_cols_array(&std::array::from_fn(|k| {
                (if k % 4 == 0 { 1.0 } else { 0.0 }) + 0.4 * (lcg(&mut seed) - 0.5)
            }));
            let tau = mooney_rivlin_tau(f, 250_000.0, 9167.5);
            let sigma = tau - Mat3::IDENTITY * (3.0e4 * (lcg(&mut seed) - 0.5));
            let art = artificial_stress(sigma, 1000.0, 0.3);
            for m in [tau, art] {
                assert_eq!(m, m.transpose(), "{m:?}");
            }
            let packed = StressGpu::pack(tau, art);
            assert_eq!((packed.tau(), packed.art()), (tau, art));
        }
    }

    #[test]
    fn jacobi_diagonalises() {
        let mut seed = 3u64;
        for _ in 0..50 {
            let mut a = Mat3::ZERO;
            for r in 0..3 {
                for c in r..3 {
                    let v = 2.0 * lcg(&mut seed) - 1.0;
                    a.col_mut(c)[r] = v;
                    a.col_mut(r)[c] = v;
                }
            }
            let (lam, q) = sym_eigen(a);
            let recon = q * Mat3::from_diagonal(lam) * q.transpose();
            for c in 0..3 {
                assert!((recon.col(c) - a.col(c)).length() < 1e-5, "{a} vs {recon}");
            }
        }
    }
}
