//! Analytic reference solutions of the validation cases (SPEC.md §7), in f64.

use std::f64::consts::PI;

/// Dimensionless start-up Poiseuille velocity v*(y*, t*) of (4.1), SPEC §7.1 (H = half-width):
/// v* = 1.5(1 − y*²) − Σ_k 48/N_k³ sin(N_k(1 + y*)/2) exp(−N_k² t*/4), N_k = (2k + 1)π.
pub fn poiseuille_startup(y_star: f64, t_star: f64) -> f64 {
    let mut v = 1.5 * (1.0 - y_star * y_star);
    for k in 0..400 {
        let nk = (2 * k + 1) as f64 * PI;
        let e = (-nk * nk * t_star / 4.0).exp();
        if e < 1e-18 && k > 10 {
            break;
        }
        v -= 48.0 / (nk * nk * nk) * (nk * (1.0 + y_star) / 2.0).sin() * e;
    }
    v
}

/// Steady Brinkman velocity (SPEC §7.3): u = (nˡρ₀f/K)[1 − cosh(λy)/cosh(λH)], λ = sqrt(K/η),
/// K = (1 − nˢ)K̄.
pub fn brinkman_steady(y: f64, half_width: f64, n_l: f64, rho0: f64, f: f64, k: f64, eta: f64) -> f64 {
    if k <= 0.0 {
        // Frictionless limit: plane Poiseuille with the body force nˡρ₀f.
        return n_l * rho0 * f / (2.0 * eta) * (half_width * half_width - y * y);
    }
    let lam = (k / eta).sqrt();
    n_l * rho0 * f / k * (1.0 - (lam * y).cosh() / (lam * half_width).cosh())
}

/// First-mode angular frequency of a clamped–free Euler–Bernoulli beam, ω₁ = (βL)²√(EI/μ)/L²
/// with (βL)² = 3.516 (SPEC §7.2). `mu` is mass per unit length [kg/m].
pub fn cantilever_omega1(e: f64, i: f64, mu: f64, length: f64) -> f64 {
    let bl: f64 = 1.875_104_1;
    bl * bl * (e * i / mu).sqrt() / (length * length)
}

/// Young's modulus and Poisson ratio from bulk modulus K and shear modulus G.
pub fn young_poisson(k: f64, g: f64) -> (f64, f64) {
    (9.0 * k * g / (3.0 * k + g), (3.0 * k - 2.0 * g) / (2.0 * (3.0 * k + g)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Check values of SPEC §7.1 at the centre.
    #[test]
    fn poiseuille_series_check_values() {
        for (t, v) in [
            (0.05, 0.14993),
            (0.1, 0.29662),
            (0.2, 0.55558),
            (0.5, 1.04918),
            (1.0, 1.36872),
            (2.0, 1.48887),
            (3.0, 1.49906),
        ] {
            let got = poiseuille_startup(0.0, t);
            assert!((got - v).abs() < 2e-5, "t* = {t}: {got} vs {v}");
        }
        assert!(poiseuille_startup(1.0, 0.5).abs() < 1e-12);
    }

    /// SPEC §7.3 values: u_Br/V_B at y* = 0, 0.5, 0.9 with (λH)² = 2.
    #[test]
    fn brinkman_reference_values() {
        let (h, eta, rho, f, n_l) = (0.01, 0.35, 1000.0, 1.0, 0.5);
        let kbar = 4.0 * eta / (h * h);
        let k = 0.5 * kbar;
        let vb = n_l * rho * f * h * h / (3.0 * eta);
        for (ys, r) in [(0.0, 0.81135), (0.5, 0.63190), (0.9, 0.17406)] {
            let u = brinkman_steady(ys * h, h, n_l, rho, f, k, eta) / vb;
            assert!((u - r).abs() < 1e-4, "y* = {ys}: {u} vs {r}");
        }
        assert!((brinkman_steady(0.0, h, n_l, rho, f, k, eta) - 0.03864).abs() < 1e-5);
    }

    /// SPEC §7.2 derived numbers: ω₁ = 3.1373 rad/s for the thesis beam.
    #[test]
    fn cantilever_reference_frequency() {
        let g = 2.0 * (250_000.0 + 9167.5);
        let (e, _nu) = young_poisson(900_000.0, g);
        let a: f64 = 0.025;
        let w = cantilever_omega1(e, a.powi(4) / 12.0, 0.4267 / 0.5, 0.5);
        assert!((w - 3.1373).abs() < 2e-3, "{w}");
    }
}
