//! SPH kernels of thesis §2.2.1 (SPEC.md §2), evaluated with the support conventions of SPEC D-1:
//! the cubic spline W_C(r; h) has support 2h, poly6 / spiky / viscosity kernels are written with
//! their support radius R = 2h.
//!
//! One set of formulas serves both back-ends: the WGSL twins live in `shaders/common.wgsl`
//! (`kernel_*` functions) and must follow these line for line.

use std::f32::consts::PI;

/// Spatial dimension, 2 or 3. Kernel normalisation constants depend on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dim {
    Two,
    Three,
}

impl Dim {
    pub fn from_u32(d: u32) -> Option<Dim> {
        match d {
            2 => Some(Dim::Two),
            3 => Some(Dim::Three),
            _ => None,
        }
    }
    pub fn n(self) -> usize {
        match self {
            Dim::Two => 2,
            Dim::Three => 3,
        }
    }
}

/// Precomputed constants of the four kernels for one (h, R = 2h) pair.
///
/// Kept as plain numbers so that the GPU uniform block (`KernelConsts` in `common.wgsl`) can carry
/// exactly the same values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    /// Smoothing length h \[m\] of the cubic spline.
    pub h: f32,
    /// Support radius R = 2h \[m\] of poly6, spiky and viscosity kernels.
    pub r: f32,
    /// Cubic spline normalisation α_C (2.30): 10/(7πh²) in 2-D, 1/(πh³) in 3-D.
    pub alpha_c: f32,
    /// Poly6 normalisation α_6 (2.35): 4/(πR²) in 2-D, 315/(64πR³) in 3-D.
    pub alpha_6: f32,
    /// Spiky normalisation α_S (2.38): 10/(πR²) in 2-D, 15/(πR³) in 3-D.
    pub alpha_s: f32,
    /// Viscosity-kernel Laplacian constant C_V (2.34, repaired by SPEC D-4): 40/(πR⁴) 2-D, 45/(πR⁵) 3-D.
    pub c_v: f32,
}

impl Kernel {
    pub fn new(h: f32, dim: Dim) -> Kernel {
        let r = 2.0 * h;
        match dim {
            Dim::Two => Kernel {
                h,
                r,
                alpha_c: 10.0 / (7.0 * PI * h * h),
                alpha_6: 4.0 / (PI * r * r),
                alpha_s: 10.0 / (PI * r * r),
                c_v: 40.0 / (PI * r.powi(4)),
            },
            Dim::Three => Kernel {
                h,
                r,
                alpha_c: 1.0 / (PI * h * h * h),
                alpha_6: 315.0 / (64.0 * PI * r * r * r),
                alpha_s: 15.0 / (PI * r * r * r),
                c_v: 45.0 / (PI * r.powi(5)),
            },
        }
    }

    /// Cubic spline W_C(r; h) (2.29).
    #[inline]
    pub fn w_cubic(&self, r: f32) -> f32 {
        let q = r / self.h;
        if q < 1.0 {
            self.alpha_c * (1.0 - 1.5 * q * q + 0.75 * q * q * q)
        } else if q < 2.0 {
            let t = 2.0 - q;
            self.alpha_c * 0.25 * t * t * t
        } else {
            0.0
        }
    }

    /// Scalar factor g of ∇W_C = g · x_ij (x_ij = x_i − x_j, r = |x_ij|) from (2.30).
    /// Writing the gradient as a multiple of x_ij avoids a division by r at r = 0.
    #[inline]
    pub fn grad_cubic_factor(&self, r: f32) -> f32 {
        let q = r / self.h;
        if r <= 0.0 || q >= 2.0 {
            return 0.0;
        }
        let dw = if q < 1.0 {
            3.0 * q - 2.25 * q * q
        } else {
            let t = 2.0 - q;
            0.75 * t * t
        };
        -(self.alpha_c / self.h) * dw / r
    }

    /// Poly6 W6(r; R) (2.35).
    #[inline]
    pub fn w_poly6(&self, r: f32) -> f32 {
        if r >= self.r {
            return 0.0;
        }
        let s = r / self.r;
        let t = 1.0 - s * s;
        self.alpha_6 * t * t * t
    }

    /// Scalar factor of ∇W_S = g · x_ij for the spiky kernel (2.39).
    #[inline]
    pub fn grad_spiky_factor(&self, r: f32) -> f32 {
        if r <= 0.0 || r >= self.r {
            return 0.0;
        }
        let t = 1.0 - r / self.r;
        -(3.0 * self.alpha_s / self.r) * t * t / r
    }

    /// Laplacian of the viscosity kernel ∇²W_V(r; R) (2.34, SPEC D-4).
    #[inline]
    pub fn lap_viscosity(&self, r: f32) -> f32 {
        if r >= self.r {
            return 0.0;
        }
        self.c_v * (1.0 - r / self.r)
    }
}

/// Visits the offsets k·Δx of an ideal lattice within radius `radius` (k ∈ ℤ^d), self included.
pub fn for_lattice_offsets(dx: f64, radius: f64, dim: Dim, mut f: impl FnMut([f64; 3])) {
    let n = (radius / dx).ceil() as i64 + 1;
    let nz = if dim == Dim::Three { n } else { 0 };
    for k in -nz..=nz {
        for j in -n..=n {
            for i in -n..=n {
                let p = [i as f64 * dx, j as f64 * dx, k as f64 * dx];
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                if r < radius {
                    f(p);
                }
            }
        }
    }
}

/// Normalisation α₆ of the poly6 kernel of support R (SPEC §2), in f64.
fn poly6_alpha(radius: f64, dim: Dim) -> f64 {
    match dim {
        Dim::Two => 4.0 / (std::f64::consts::PI * radius * radius),
        Dim::Three => 315.0 / (64.0 * std::f64::consts::PI * radius.powi(3)),
    }
}

/// S_W = Σ_k W6(|k|Δx; R) over the ideal lattice, self included (SPEC §1.2, D-2), in f64.
/// The particle mass of a phase generated on that lattice at volume fraction n₀ is n₀ρ₀/S_W.
pub fn lattice_poly6_sum(dx: f64, radius: f64, dim: Dim) -> f64 {
    let alpha = poly6_alpha(radius, dim);
    let mut s = 0.0;
    for_lattice_offsets(dx, radius, dim, |p| {
        let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        let t = 1.0 - r2 / (radius * radius);
        s += alpha * t * t * t;
    });
    s
}

/// Σ_k W6(|k|Δx; R) over a single layer of the lattice (a sheet: the plane in 3-D, the row in 2-D),
/// self included, with the d-dimensional poly6 normalisation (SPEC §7.12). The particle mass of a
/// sheet seen at volume fraction nˢ on its mid-plane is nˢρ₀/(this sum).
pub fn sheet_poly6_sum(dx: f64, radius: f64, dim: Dim) -> f64 {
    let alpha = poly6_alpha(radius, dim);
    let mut s = 0.0;
    // The in-plane lattice of the sheet is the (d − 1)-dimensional lattice: offsets with z = 0 in 3-D,
    // with y = z = 0 in 2-D.
    for_lattice_offsets(dx, radius, dim, |p| {
        if p[2] != 0.0 || (dim == Dim::Two && p[1] != 0.0) {
            return;
        }
        let r2 = p[0] * p[0] + p[1] * p[1];
        let t = 1.0 - r2 / (radius * radius);
        s += alpha * t * t * t;
    });
    s
}

/// κ_V = 2d / Σ_k V ∇²W_V(|k|Δx) on the ideal lattice (SPEC §2.5, D-7), in f64.
pub fn viscous_normalisation(dx: f64, radius: f64, dim: Dim) -> f64 {
    let c_v = match dim {
        Dim::Two => 40.0 / (std::f64::consts::PI * radius.powi(4)),
        Dim::Three => 45.0 / (std::f64::consts::PI * radius.powi(5)),
    };
    let vol = dx.powi(dim.n() as i32);
    let mut s = 0.0;
    for_lattice_offsets(dx, radius, dim, |p| {
        let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        let r = r2.sqrt();
        s += vol * r2 * c_v * (1.0 - r / radius);
    });
    // Σ V x_a² ∇²W summed over all a gives d·(one diagonal); the estimator's target is 2 per diagonal.
    2.0 * dim.n() as f64 / s
}

/// κ_S = 1 / Σ_k V (k_a)(∇W_S)_a on the ideal lattice with the mass-calibrated volume V = 1/S_W: the
/// pressure-gradient twin of κ_V (README: deviations from SPEC). 2-D: 1/0.94652, 3-D: 1/0.97124 at
/// R = 2.6Δx.
pub fn pressure_gradient_normalisation(dx: f64, radius: f64, dim: Dim) -> f64 {
    let alpha_s = match dim {
        Dim::Two => 10.0 / (std::f64::consts::PI * radius * radius),
        Dim::Three => 15.0 / (std::f64::consts::PI * radius.powi(3)),
    };
    let vol = 1.0 / lattice_poly6_sum(dx, radius, dim);
    let mut s = 0.0;
    for_lattice_offsets(dx, radius, dim, |p| {
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        if r > 0.0 {
            // (x_j − x_i)_a (∇W_S)_a with x_j − x_i = p, ∇W_S = −(3α/R)(1 − r/R)² (−p)/r.
            let t = 1.0 - r / radius;
            s += vol * p[0] * (3.0 * alpha_s / radius) * t * t * p[0] / r;
        }
    });
    1.0 / s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SPEC §2.5 lattice constants (R = 2.6Δx) to 1e-4, in f64.
    #[test]
    fn lattice_constants_match_spec() {
        let dx = 1.0;
        let r = 2.6;
        for (dim, sw, nb, kv) in [(Dim::Two, 0.99532, 20, 0.93215), (Dim::Three, 0.99334, 80, 0.93337)] {
            let s = lattice_poly6_sum(dx, r, dim);
            assert!((s - sw).abs() < 1e-4, "S_W {dim:?}: {s}");
            let mut count = 0;
            for_lattice_offsets(dx, r, dim, |_| count += 1);
            assert_eq!(count - 1, nb, "neighbour count {dim:?}");
            let k = viscous_normalisation(dx, r, dim);
            assert!((k - kv).abs() < 1e-4, "kappa_V {dim:?}: {k}");
        }
    }

    /// Σ V (x_j − x_i)_a (∇W)_a per diagonal entry for the cubic spline and the spiky kernel (SPEC §2.5).
    #[test]
    fn gradient_moments_match_spec() {
        for (dim, cubic, spiky, wc) in [(Dim::Two, 1.01054, 0.94209, 0.12210), (Dim::Three, 0.99348, 0.96478, 0.06575)]
        {
            let k = Kernel::new(1.3, dim);
            let mut mc = 0.0f64;
            let mut ms = 0.0f64;
            for_lattice_offsets(1.0, 2.6, dim, |p| {
                // x_j − x_i = p, x_ij = −p, ∇W = g·x_ij.
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() as f32;
                mc += p[0] * (k.grad_cubic_factor(r) as f64 * -p[0]);
                ms += p[0] * (k.grad_spiky_factor(r) as f64 * -p[0]);
            });
            assert!((mc - cubic).abs() < 1e-3, "cubic moment {dim:?}: {mc}");
            assert!((ms - spiky).abs() < 1e-3, "spiky moment {dim:?}: {ms}");
            assert!((k.w_cubic(1.0) as f64 - wc).abs() < 1e-4, "W_C(dx) {dim:?}");
        }
    }

    #[test]
    fn pressure_normalisation_values() {
        let k2 = pressure_gradient_normalisation(1.0, 2.6, Dim::Two);
        let k3 = pressure_gradient_normalisation(1.0, 2.6, Dim::Three);
        assert!((1.0 / k2 - 0.94209 / 0.99532).abs() < 1e-4, "{k2}");
        assert!((1.0 / k3 - 0.96478 / 0.99334).abs() < 1e-4, "{k3}");
    }

    /// Each kernel integrates to one (cubic spline, poly6, spiky) over a fine lattice.
    #[test]
    fn kernels_are_normalised() {
        for dim in [Dim::Two, Dim::Three] {
            let k = Kernel::new(1.0, dim);
            let dx = 0.05f64;
            let vol = dx.powi(dim.n() as i32);
            let (mut c, mut p6) = (0.0f64, 0.0f64);
            for_lattice_offsets(dx, 2.0, dim, |p| {
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() as f32;
                c += vol * k.w_cubic(r) as f64;
                p6 += vol * k.w_poly6(r) as f64;
            });
            assert!((c - 1.0).abs() < 2e-3, "cubic {dim:?} {c}");
            assert!((p6 - 1.0).abs() < 2e-3, "poly6 {dim:?} {p6}");
        }
    }
}
