//! Wetting measurements of the surface-tension cases (SPEC §3.12, §7.12): the contact angle of a drop
//! resting on a plate (thesis Fig. 3.13, eq. 3.3) and the stain of a drop wicked into a fabric sheet
//! (thesis §4.3, eqs. 3.4–3.5). Pure functions of particle positions and fractions, so the tests, the
//! `perfuse validate` wicking case and any post-processing measure the same way.

use glam::Vec3;

/// A drop resting on a plate, measured as the circular (2-D) or spherical (3-D) cap that has the drop's
/// volume.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ContactAngle {
    /// Contact angle θ \[degrees\] inside the liquid, of the cap with the drop's volume and height.
    pub degrees: f64,
    /// θ of the cap with the drop's volume over its contact layer (noisier on small drops: the contact
    /// layer gains or loses a particle at a time).
    pub degrees_from_base: f64,
    /// Height H of the drop's top above the plate surface \[m\] (top particle + Δx/2).
    pub height: f64,
    /// Half-width (2-D) or radius (3-D) a of the contact layer \[m\].
    pub base_half_width: f64,
    /// Particles in the contact layer (within Δx/2 of the lowest one).
    pub contact_particles: usize,
}

/// Measures the contact angle of a drop of `volume` (m² in 2-D, m³ in 3-D) whose particles `liquid` rest
/// on a plate whose top surface is at height `plate_top` along the plate's normal axis `up` (0 x, 1 y,
/// 2 z; `droplet_plate.ron` and the 2-D tests use y), lattice spacing `dx`.
///
/// θ is the angle of the cap that holds the drop's volume at the drop's height H (top particle + Δx/2):
/// with R = H/(1 − cos θ), A = R²(θ − sin θ cos θ) in 2-D and V = πH²(3R − H)/3 in 3-D, both decreasing
/// in θ, solved by bisection. A global measure: on drops a few tens of particles across the free surface
/// and the contact line are ragged at the particle scale, which defeats local slope or circle fits.
/// The same cap over the contact layer's width is reported as `degrees_from_base`. None without liquid
/// or with a non-positive volume.
pub fn contact_angle(
    liquid: &[Vec3],
    volume: f64,
    plate_top: f64,
    dx: f64,
    dim: usize,
    up: usize,
) -> Option<ContactAngle> {
    let heights: Vec<f64> = liquid.iter().map(|p| p[up.min(2)] as f64 - plate_top).collect();
    let lowest = heights.iter().copied().fold(f64::INFINITY, f64::min);
    let top = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !lowest.is_finite() || volume.is_nan() || volume <= 0.0 {
        return None;
    }
    let h = top + 0.5 * dx;
    let n = heights.iter().filter(|&&z| z < lowest + 0.5 * dx).count();
    let a = if dim == 2 { 0.5 * n as f64 * dx } else { dx * (n as f64 / std::f64::consts::PI).sqrt() };
    let pi = std::f64::consts::PI;
    // Volume of the cap of angle t on base half-width a (increasing in t) ...
    let on_base = |t: f64| {
        let (s, c) = t.sin_cos();
        if dim == 2 {
            a * a * (t - s * c) / (s * s)
        } else {
            pi * a.powi(3) * (2.0 - 3.0 * c + c.powi(3)) / (3.0 * s.powi(3))
        }
    };
    // ... and of the cap of angle t and height h (decreasing in t).
    let of_height = |t: f64| {
        let r = h / (1.0 - t.cos());
        if dim == 2 { r * r * (t - t.sin() * t.cos()) } else { pi * h * h * (3.0 * r - h) / 3.0 }
    };
    let solve = |f: &dyn Fn(f64) -> f64, increasing: bool| {
        let (mut lo, mut hi) = (1e-3f64, pi - 1e-3);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if (f(mid) < volume) == increasing {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (0.5 * (lo + hi)).to_degrees()
    };
    Some(ContactAngle {
        degrees: solve(&of_height, false),
        degrees_from_base: solve(&on_base, true),
        height: h,
        base_half_width: a,
        contact_particles: n,
    })
}

/// Sheet thickness t_eff = 1/∫W6 across the sheet that a kernel of support R sees (SPEC §7.12):
/// (256/315)R in 3-D; 35πR/128 in 2-D (the row's line density).
pub fn sheet_effective_thickness(radius: f64, dim: usize) -> f64 {
    if dim == 2 { 35.0 * std::f64::consts::PI * radius / 128.0 } else { 256.0 * radius / 315.0 }
}

/// The stain a drop leaves in a fabric sheet (SPEC §7.12 "Measured").
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Stain {
    /// Wetted area A = Δx_s^(d−1) × #{sheet particles with nˡ ≥ ¼ nˡ_eq} [m² in 3-D, m in 2-D].
    pub area: f64,
    /// Wetted sheet particles.
    pub wetted: usize,
    /// Horizontal centroid of the wetted particles (x, y; simulation coordinates) \[m\].
    pub centroid: [f64; 2],
}

/// Measures the stain on the sheet particles `sheet` (positions and nˡ by summation at them).
pub fn stain(pos: &[Vec3], n_l: &[f32], n_eq: f64, dx_s: f64, dim: usize) -> Stain {
    let mut wetted = 0usize;
    let mut c = [0.0f64; 2];
    for (p, &nl) in pos.iter().zip(n_l) {
        if nl as f64 >= 0.25 * n_eq {
            wetted += 1;
            c[0] += p.x as f64;
            c[1] += p.y as f64;
        }
    }
    if wetted > 0 {
        c[0] /= wetted as f64;
        c[1] /= wetted as f64;
    }
    Stain { area: dx_s.powi(dim as i32 - 1) * wetted as f64, wetted, centroid: c }
}

/// The stain expected at equilibrium, A_ref = V_d/(nˡ_eq t_eff) (SPEC §7.12), for a liquid volume V_d
/// (m³ in 3-D, m² in 2-D) and cross-phase support R_×.
pub fn reference_stain_area(volume: f64, n_eq: f64, r_x: f64, dim: usize) -> f64 {
    volume / (n_eq * sheet_effective_thickness(r_x, dim))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Particles on a lattice filling a circular cap of known angle give that angle back, within the
    /// lattice's resolution: the top particle locates H to ±Δx/2 (±7 % on the 7-row 60° cap: 6°).
    #[test]
    fn contact_angle_of_lattice_caps() {
        let dx = 1e-4;
        for (dim, theta_deg) in [(2usize, 60.0f64), (2, 90.0), (2, 120.0), (3, 70.0), (3, 110.0)] {
            let r = 1.5e-3;
            let zc = -r * theta_deg.to_radians().cos(); // centre height above the plate
            let n = (r / dx) as i64 + 2;
            let mut pts = Vec::new();
            let kz = if dim == 3 { n } else { 0 };
            for i in -n..=n {
                for j in 0..=2 * n {
                    for k in -kz..=kz {
                        let x = (i as f64 + 0.5) * dx;
                        let h = (j as f64 + 0.5) * dx;
                        let y = (k as f64 + 0.5) * dx;
                        if x * x + if dim == 3 { y * y } else { 0.0 } + (h - zc).powi(2) <= r * r {
                            pts.push(if dim == 2 {
                                Vec3::new(x as f32, h as f32, 0.0)
                            } else {
                                Vec3::new(x as f32, y as f32, h as f32)
                            });
                        }
                    }
                }
            }
            let volume = pts.len() as f64 * dx.powi(dim as i32);
            let ca = contact_angle(&pts, volume, 0.0, dx, dim, if dim == 2 { 1 } else { 2 }).expect("a cap");
            assert!(
                (ca.degrees - theta_deg).abs() < 6.0 && (ca.degrees_from_base - theta_deg).abs() < 4.0,
                "{dim}-D cap of {theta_deg}°: measured {:.1}° from the height, {:.1}° from the base",
                ca.degrees,
                ca.degrees_from_base
            );
        }
    }

    #[test]
    fn effective_thickness_is_the_inverse_kernel_integral() {
        // ∫W6 across the sheet by quadrature, both dimensions.
        let r = 1.0f64;
        let n = 2000;
        let h = 2.0 * r / n as f64;
        let w2 = |x: f64| 4.0 / (std::f64::consts::PI * r * r) * (1.0 - x * x / (r * r)).max(0.0).powi(3);
        let int2: f64 = (0..n).map(|i| w2(-r + (i as f64 + 0.5) * h) * h).sum();
        assert!((1.0 / int2 / sheet_effective_thickness(r, 2) - 1.0).abs() < 1e-4);
        let w3 = |q: f64| 315.0 / (64.0 * std::f64::consts::PI * r.powi(3)) * (1.0 - q * q / (r * r)).max(0.0).powi(3);
        let int3: f64 =
            (0..n).map(|i| (i as f64 + 0.5) * h * 0.5).map(|q| w3(q) * 2.0 * std::f64::consts::PI * q * h * 0.5).sum();
        assert!((1.0 / int3 / sheet_effective_thickness(r, 3) - 1.0).abs() < 1e-4);
    }
}
