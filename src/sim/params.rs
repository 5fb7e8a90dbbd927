//! Derived, backend-independent step parameters: kernels per neighbour relation, stiffnesses, signal
//! speeds (SPEC D-27), κ_V (D-7), grid geometry. Built once from a validated scenario; both back-ends
//! read the same numbers (the GPU copies them into its `StepUniforms` block).

use super::kernels::{Dim, Kernel, viscous_normalisation};
use crate::scenario::{GeneratedParticles, Scenario};
use glam::Vec3;

/// Step parameters in f32, as both back-ends use them.
#[derive(Clone, Debug)]
pub struct Params {
    pub dim: Dim,
    /// Liquid–liquid and liquid–boundary kernels (R_l = 2h_l).
    pub k_liquid: Kernel,
    /// Solid–solid and solid–boundary kernels (cubic spline with h_s).
    pub k_solid: Kernel,
    /// Cross-phase kernel, R_× = max(R_s, R_l) (SPEC §2.1, D-3).
    pub k_cross: Kernel,
    pub dx_solid: f32,
    /// Liquid lattice spacing Δx_l \[m\] (emitter slots, 0 without liquid).
    pub dx_liquid: f32,
    /// W_C(Δx_s; h_s), denominator of f_ij (2.60).
    pub wc_dx: f32,
    pub rho0_l: f32,
    pub rho0_s: f32,
    pub eta: f32,
    /// Liquid penalty stiffness of (2.53) \[Pa\].
    pub k_l: f32,
    pub c1: f32,
    /// Liquid–void attraction γ [N/m] of (3.4) (0: off).
    pub wicking: f32,
    /// Pairwise surface-tension strengths \[N\] of (3.3): liquid–liquid s_ll and liquid–boundary s_lb.
    pub cohesion_ll: f32,
    pub cohesion_lb: f32,
    /// Where the liquid pressure may go negative: nˢ below this (`numerics.liquid_tension` and
    /// `liquid_tension_below_ns`; +∞ for everywhere, 0 without `liquid_tension` or with only a
    /// region, so that `n_s < liquid_tension_below_ns` or `x` in a `liquid_tension_in` region is the
    /// whole rule: [`Params::liquid_may_pull`]).
    pub liquid_tension_below_ns: f32,
    /// Where else the liquid pressure may go negative, whatever nˢ (`numerics.liquid_tension_in`, in
    /// simulation coordinates; empty without `liquid_tension`).
    pub liquid_tension_in: Vec<TensionRegion>,
    /// Ambient pressure p_a \[Pa\] added to the liquid's (2.53) (`numerics.ambient_pressure`; 0: none).
    pub ambient_pressure: f32,
    /// Pressure outlets (`outlets`) in simulation coordinates, pressures absolute (p_a + gauge).
    pub outlets: Vec<OutletRegion>,
    /// Hourglass-control coefficient c of `numerics.hourglass` (0: off).
    pub hourglass: f32,
    /// `numerics.reorder_liquid`: renumber the liquid by cell at every grid build (`grid_reorder`);
    /// fixed for a solver's life (the GPU compiles its liquid walks for it, `LIQUID_IN_CELL_ORDER`).
    pub reorder_liquid: bool,
    /// Ligament springs of the tethered solid particles: ω² [1/s²] and 2ζω [1/s] (`ligaments`; 0: none).
    pub tether_omega2: f32,
    pub tether_damping: f32,
    /// Membrane (capsule) particles' C10, C01 over the tissue's (`membrane.stiffness`; 1: none).
    pub membrane_stiffness: f32,
    /// The lattice spacings Δx_l and Δx_s that the capsule's ghost sites and seal are measured in
    /// (`sim::ghosts`, `forces::capsule_seal_pair`).
    pub capsule_dx_liquid: f32,
    pub capsule_dx_solid: f32,
    /// The capsule's seal (`membrane.seal`, `forces::capsule_seal`): 1 on, 0 off.
    pub capsule_seal: f32,
    /// The capsule's ghost sites stand for the blood's and the tissue's missing lattice sites beneath it
    /// (`membrane.ghosts`, `sim::ghosts`); off, the blood sees the capsule as SPEC §4.1's single layer of
    /// boundary particles (the thesis's capsule).
    pub capsule_ghosts: bool,
    pub k_s: f32,
    pub k_sat: f32,
    pub n_sat: f32,
    pub c10: f32,
    pub c01: f32,
    /// K̄ [Pa·s/m²].
    pub kbar: f32,
    /// Signal speeds [m/s].
    pub c_l: f32,
    pub c_s: f32,
    pub av_alpha: f32,
    pub av_beta: f32,
    pub av_gamma: f32,
    pub av_liquid: bool,
    pub as_eps: f32,
    pub as_exp: i32,
    /// Liquid artificial pressure ε (0: off) and exponent n (`numerics.liquid_artificial_pressure`).
    pub ap_eps: f32,
    pub ap_exp: i32,
    /// W_C(Δx_l; h_l), denominator of the liquid's f_ij.
    pub wc_dx_l: f32,
    pub xsph_s: f32,
    pub xsph_l: f32,
    pub kappa_v: f32,
    /// Pressure-gradient normalisation κ_S of the liquid (1 when disabled).
    pub kappa_s: f32,
    pub gravity: Vec3,
    /// Reference apparent densities n₀ρ₀ of each phase (friction time-step bound).
    pub rho_ref_l: f32,
    pub rho_ref_s: f32,
    pub cfl_factor: f32,
    pub cfl_viscous: f32,
    pub cfl_sound: f32,
    pub cfl_force: f32,
    pub cfl_friction: f32,
    pub dt_min: f32,
    pub dt_max: f32,
    pub fixed_dt: Option<f32>,
    pub max_speed: f32,
    /// Simulation coordinates are relative to this point (SPEC §5.4: f32 positions near 0).
    pub origin: [f64; 3],
    /// Domain in simulation coordinates.
    pub domain_min: Vec3,
    pub domain_max: Vec3,
    pub periodic: [bool; 3],
    pub grid: GridDims,
    pub has_liquid: bool,
    pub has_solid: bool,
    /// Some solid particle is not kinematic.
    pub solid_dynamic: bool,
    /// Critical stretch λ_c of fracture (None: break beyond 2h_s, the thesis criterion).
    pub critical_stretch: Option<f32>,
}

/// A region of `numerics.liquid_tension_in` in simulation coordinates: there the liquid pressure (2.53)
/// may go negative whatever the solid fraction (the bore of a syringe's needle, whose blood sees the
/// tissue around the tip). One rule for `density_liquid` and density.wgsl (`SimParams::tension`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TensionRegion {
    Box { min: Vec3, max: Vec3 },
    Sphere { centre: Vec3, radius: f32 },
}

impl TensionRegion {
    /// Whether `x` lies in the region (boundaries included), with the arithmetic of density.wgsl.
    pub fn contains(&self, x: Vec3) -> bool {
        match *self {
            TensionRegion::Box { min, max } => {
                x.x >= min.x && x.y >= min.y && x.z >= min.z && x.x <= max.x && x.y <= max.y && x.z <= max.z
            }
            TensionRegion::Sphere { centre, radius } => {
                let d = x - centre;
                d.x * d.x + d.y * d.y + d.z * d.z <= radius * radius
            }
        }
    }
}

/// A pressure outlet's buffer (scenario `outlets`) in simulation coordinates: a box (boundaries
/// included, the arithmetic of `outlet_at` in common.wgsl), the absolute pressure p_a + gauge its
/// liquid carries, the density ρ₀ˡ(1 + gauge/k) of pure liquid at that pressure by (2.53), which
/// its liquid shows in the pair terms of its neighbours, and the unit normal along which it moves.
/// Twin of `SimParams::outlet`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutletRegion {
    pub min: Vec3,
    pub max: Vec3,
    pub pressure: f32,
    pub density: f32,
    pub normal: Vec3,
}

impl OutletRegion {
    /// The first outlet of `outlets` whose buffer holds `x`.
    #[inline]
    pub fn find(outlets: &[OutletRegion], x: Vec3) -> Option<&OutletRegion> {
        outlets.iter().find(|o| o.contains(x))
    }

    #[inline]
    pub fn contains(&self, x: Vec3) -> bool {
        let (a, b) = (self.min, self.max);
        x.x >= a.x && x.y >= a.y && x.z >= a.z && x.x <= b.x && x.y <= b.y && x.z <= b.z
    }
}

/// Uniform background grid (cells of edge ≥ the largest search radius).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridDims {
    pub n: [u32; 3],
    pub cell: [f32; 3],
    pub min: Vec3,
}

impl GridDims {
    pub fn cell_count(&self) -> usize {
        self.n.iter().map(|&x| x as usize).product()
    }
}

impl Params {
    pub fn new(s: &Scenario, g: &GeneratedParticles) -> Params {
        let dim = s.dim();
        let n = &s.numerics;
        let has_liquid = !g.liquid.pos.is_empty() || !g.emitters.is_empty();
        let has_solid = !g.solid.pos.is_empty();
        // A skeleton held entirely still (Brinkman) moves nothing: its wave speed sets no time step.
        let solid_dynamic = g.solid_flags.iter().any(|f| f & crate::scenario::SolidFlags::KINEMATIC == 0);
        // Absent phases still get harmless, finite kernels so that uniform blocks stay valid.
        let h_l = if g.h_liquid > 0.0 { g.h_liquid } else { g.h_solid };
        let h_s = if g.h_solid > 0.0 { g.h_solid } else { g.h_liquid };
        let h_x = h_l.max(h_s);
        let (rho0_l, eta, k_l, c1) = match &s.liquid {
            Some(l) => (
                l.density,
                l.viscosity,
                l.stiffness.unwrap_or_else(|| l.density * l.sound_speed.unwrap_or(0.0).powi(2)),
                l.c1_from_equilibrium.map(|e| e.c1()).unwrap_or(l.c1),
            ),
            None => (1000.0, 0.0, 0.0, 0.0),
        };
        let (wicking, cohesion_ll, cohesion_lb) = match &s.liquid {
            Some(l) => {
                let c = l.cohesion.unwrap_or(crate::scenario::Cohesion { liquid: 0.0, boundary: 0.0 });
                (l.wicking, c.liquid, c.boundary)
            }
            None => (0.0, 0.0, 0.0),
        };
        let (rho0_s, c10, c01, k_s, k_sat, n_sat, kbar) = match &s.solid {
            Some(m) => (m.density, m.c10, m.c01, m.k_s, m.k_sat, m.n_sat, m.friction),
            None => (1000.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0),
        };
        let c_l = n.sound_speed_liquid.unwrap_or((k_l / rho0_l).sqrt());
        // the stiffest solid particles set the derived sound speed: the capsule's when it is stiffer
        let capsule = s.membrane.as_ref().map_or(1.0, |m| m.stiffness.max(1.0));
        let g_mod = 2.0 * (c10 + c01) * capsule;
        let n0s = if g.fraction_solid > 0.0 { g.fraction_solid } else { 1.0 };
        let c_s = n.sound_speed_solid.unwrap_or(((k_s + k_sat) / rho0_s + 4.0 / 3.0 * g_mod / (n0s * rho0_s)).sqrt());
        let c_max = if has_liquid { c_l } else { 0.0 }.max(if solid_dynamic { c_s } else { 0.0 });
        let max_boundary_speed = s
            .boundaries
            .iter()
            .map(|b| match &b.motion {
                crate::scenario::Motion::Static => 0.0,
                crate::scenario::Motion::Translate { velocity, .. } => norm(*velocity),
                crate::scenario::Motion::Oscillate { amplitude, frequency, .. } => {
                    norm(*amplitude) * 2.0 * std::f64::consts::PI * frequency
                }
            })
            .fold(0.0, f64::max);
        let max_speed = n.max_speed.unwrap_or(20.0 * c_max.max(max_boundary_speed).max(1e-6));
        let kappa_v = if n.viscous_laplacian_normalisation && has_liquid {
            viscous_normalisation(g.dx_liquid, 2.0 * h_l, dim)
        } else {
            1.0
        };
        let kappa_s = if n.pressure_gradient_normalisation && has_liquid {
            super::kernels::pressure_gradient_normalisation(g.dx_liquid, 2.0 * h_l, dim)
        } else {
            1.0
        };
        let d = s.dimensions as usize;
        let mut origin = [0.0; 3];
        for a in 0..d {
            origin[a] = 0.5 * (s.domain.min[a] + s.domain.max[a]);
        }
        let to_sim =
            |p: [f64; 3]| Vec3::new((p[0] - origin[0]) as f32, (p[1] - origin[1]) as f32, (p[2] - origin[2]) as f32);
        let mut domain_min = to_sim(s.domain.min);
        let mut domain_max = to_sim(s.domain.max);
        if d == 2 {
            domain_min.z = 0.0;
            domain_max.z = 0.0;
        }
        let r_x = 2.0 * h_x as f32;
        // cells of at least R_× / GRID_REACH: the neighbour block (± GRID_REACH cells) covers R_×
        let cell_min = r_x / super::cpu::grid::GRID_REACH as f32;
        let mut gn = [1u32; 3];
        let mut cell = [cell_min; 3];
        for a in 0..d {
            let ext = domain_max[a] - domain_min[a];
            let cells = (ext / cell_min).floor().max(1.0);
            gn[a] = cells as u32;
            cell[a] = ext / cells;
        }
        let k_solid = Kernel::new(h_s as f32, dim);
        let (tether_omega, tether_zeta_2omega) = match &s.ligaments {
            Some(l) => {
                let w = 2.0 * std::f64::consts::PI * l.frequency;
                (w, 2.0 * l.damping_ratio * w)
            }
            None => (0.0, 0.0),
        };
        Params {
            dim,
            k_liquid: Kernel::new(h_l as f32, dim),
            k_solid,
            k_cross: Kernel::new(h_x as f32, dim),
            dx_solid: g.dx_solid as f32,
            dx_liquid: g.dx_liquid as f32,
            wc_dx: if g.dx_solid > 0.0 { k_solid.w_cubic(g.dx_solid as f32) } else { 1.0 },
            rho0_l: rho0_l as f32,
            rho0_s: rho0_s as f32,
            eta: eta as f32,
            k_l: k_l as f32,
            c1: c1 as f32,
            wicking: wicking as f32,
            cohesion_ll: cohesion_ll as f32,
            cohesion_lb: cohesion_lb as f32,
            // with regions but no limit, the regions alone; with neither, everywhere
            liquid_tension_below_ns: match (n.liquid_tension, n.liquid_tension_below_ns) {
                (false, _) => 0.0,
                (true, Some(v)) => v as f32,
                (true, None) if !n.liquid_tension_in.is_empty() => 0.0,
                (true, None) => f32::INFINITY,
            },
            liquid_tension_in: if n.liquid_tension {
                n.liquid_tension_in
                    .iter()
                    .map(|r| match r {
                        crate::scenario::Region::Box { min, max } => {
                            let (mut a, mut b) = (to_sim(*min), to_sim(*max));
                            if d == 2 {
                                (a.z, b.z) = (f32::NEG_INFINITY, f32::INFINITY);
                            }
                            TensionRegion::Box { min: a, max: b }
                        }
                        crate::scenario::Region::Sphere { centre, radius } => {
                            let mut c = to_sim(*centre);
                            if d == 2 {
                                c.z = 0.0;
                            }
                            TensionRegion::Sphere { centre: c, radius: *radius as f32 }
                        }
                    })
                    .collect()
            } else {
                Vec::new()
            },
            ambient_pressure: n.ambient_pressure.unwrap_or(0.0) as f32,
            outlets: s
                .outlets
                .iter()
                .filter_map(|o| match o.region {
                    // validation admits boxes only
                    crate::scenario::Region::Box { min, max } => {
                        let (mut a, mut b) = (to_sim(min), to_sim(max));
                        if d == 2 {
                            (a.z, b.z) = (f32::NEG_INFINITY, f32::INFINITY);
                        }
                        Some(OutletRegion {
                            min: a,
                            max: b,
                            pressure: (n.ambient_pressure.unwrap_or(0.0) + o.pressure) as f32,
                            // validation keeps the suction below k/2
                            density: if k_l > 0.0 { (rho0_l * (1.0 + o.pressure / k_l)) as f32 } else { rho0_l as f32 },
                            normal: {
                                let mut v = Vec3::new(o.normal[0] as f32, o.normal[1] as f32, o.normal[2] as f32);
                                if d == 2 {
                                    v.z = 0.0;
                                }
                                v.normalize_or_zero()
                            },
                        })
                    }
                    crate::scenario::Region::Sphere { .. } => None,
                })
                .collect(),
            hourglass: n.hourglass.unwrap_or(0.0) as f32,
            reorder_liquid: n.reorder_liquid,
            tether_omega2: tether_omega.powi(2) as f32,
            tether_damping: tether_zeta_2omega as f32,
            membrane_stiffness: capsule as f32,
            capsule_dx_liquid: g.dx_liquid as f32,
            capsule_dx_solid: g.dx_solid as f32,
            capsule_ghosts: matches!(&s.membrane, Some(m) if m.ghosts && g.dx_liquid > 0.0 && g.dx_solid > 0.0),
            capsule_seal: match &s.membrane {
                Some(m) if m.seal && g.dx_liquid > 0.0 && g.dx_solid > 0.0 => 1.0,
                _ => 0.0,
            },
            k_s: k_s as f32,
            k_sat: k_sat as f32,
            n_sat: n_sat as f32,
            c10: c10 as f32,
            c01: c01 as f32,
            kbar: kbar as f32,
            c_l: c_l as f32,
            c_s: c_s as f32,
            av_alpha: n.artificial_viscosity.alpha as f32,
            av_beta: n.artificial_viscosity.beta as f32,
            av_gamma: n.artificial_viscosity.gamma as f32,
            av_liquid: n.artificial_viscosity.liquid,
            as_eps: n.artificial_stress.epsilon as f32,
            as_exp: n.artificial_stress.exponent as i32,
            ap_eps: match &n.liquid_artificial_pressure {
                Some(a) if n.liquid_tension && g.dx_liquid > 0.0 => a.epsilon as f32,
                _ => 0.0,
            },
            ap_exp: n.liquid_artificial_pressure.as_ref().map_or(4, |a| a.exponent as i32),
            wc_dx_l: if g.dx_liquid > 0.0 { Kernel::new(h_l as f32, dim).w_cubic(g.dx_liquid as f32) } else { 1.0 },
            xsph_s: n.xsph.solid as f32,
            xsph_l: n.xsph.liquid as f32,
            kappa_v: kappa_v as f32,
            kappa_s: kappa_s as f32,
            gravity: Vec3::new(
                s.gravity[0] as f32,
                s.gravity[1] as f32,
                if d == 3 { s.gravity[2] as f32 } else { 0.0 },
            ),
            rho_ref_l: (g.fraction_liquid.max(1e-3) * rho0_l) as f32,
            rho_ref_s: (g.fraction_solid.max(1e-3) * rho0_s) as f32,
            cfl_factor: n.cfl.factor as f32,
            cfl_viscous: n.cfl.viscous as f32,
            cfl_sound: n.cfl.sound as f32,
            cfl_force: n.cfl.force as f32,
            cfl_friction: n.cfl.friction as f32,
            dt_min: n.dt_min as f32,
            dt_max: n.dt_max as f32,
            fixed_dt: n.fixed_dt.map(|x| x as f32),
            max_speed: max_speed as f32,
            origin,
            domain_min,
            domain_max,
            periodic: s.domain.periodic,
            grid: GridDims { n: gn, cell, min: domain_min },
            has_liquid,
            has_solid,
            solid_dynamic,
            critical_stretch: s.solid.as_ref().and_then(|m| m.critical_stretch).map(|x| x as f32),
        }
    }

    /// Whether the liquid pressure (2.53) may go negative for a liquid particle at `x` that sees the
    /// solid fraction `n_s` (`density_liquid` and its WGSL twin `liquid_may_pull`).
    pub fn liquid_may_pull(&self, x: Vec3, n_s: f32) -> bool {
        n_s < self.liquid_tension_below_ns || self.liquid_tension_in.iter().any(|r| r.contains(x))
    }

    /// The pressure outlets in effect: none while the suction is held (`Command::SetSuction(false)`,
    /// `relaxation.hold_suction`), when their buffers' liquid is liquid like any other.
    pub fn outlets_in_effect(&self, suction_held: bool) -> &[OutletRegion] {
        if suction_held { &[] } else { &self.outlets }
    }

    /// Converts absolute scenario coordinates to simulation coordinates.
    pub fn to_sim(&self, p: [f64; 3]) -> Vec3 {
        let z = if self.dim == Dim::Two { 0.0 } else { (p[2] - self.origin[2]) as f32 };
        Vec3::new((p[0] - self.origin[0]) as f32, (p[1] - self.origin[1]) as f32, z)
    }

    /// Converts simulation coordinates back to absolute scenario coordinates.
    pub fn to_world(&self, p: Vec3) -> [f64; 3] {
        [p.x as f64 + self.origin[0], p.y as f64 + self.origin[1], p.z as f64 + self.origin[2]]
    }

    /// Factor on C10, C01 of a solid particle with these `SolidFlags`: `membrane_stiffness` for the
    /// capsule, 1 for the tissue (`solid_stress` and its WGSL twin).
    pub fn stiffness_factor(&self, flags: u32) -> f32 {
        if flags & crate::scenario::SolidFlags::MEMBRANE != 0 { self.membrane_stiffness } else { 1.0 }
    }

    /// Upper bound of every Δt the step can take (fixed, or the sound and Δt_max bounds of (2.70) ×
    /// the CFL factor): the relaxation time of the stick regime of wall friction, so that friction never
    /// reverses a sliding velocity within one step (`cpu::forces::wall_friction`).
    pub fn dt_upper(&self) -> f32 {
        if let Some(fixed) = self.fixed_dt {
            return fixed;
        }
        let c = self.c_max();
        let mut dt = self.dt_max;
        if c > 0.0 {
            dt = dt.min(self.cfl_sound * self.h_min() / (3.0 * c));
        }
        dt * self.cfl_factor
    }

    /// Largest signal speed of the phases present.
    pub fn c_max(&self) -> f32 {
        let cl = if self.has_liquid { self.c_l } else { 0.0 };
        let cs = if self.solid_dynamic { self.c_s } else { 0.0 };
        cl.max(cs)
    }

    /// Smallest smoothing length of the phases present (h of (2.70)).
    pub fn h_min(&self) -> f32 {
        match (self.has_liquid, self.solid_dynamic) {
            (true, true) => self.k_liquid.h.min(self.k_solid.h),
            (true, false) => self.k_liquid.h,
            _ => self.k_solid.h,
        }
    }

    /// The longest an intact bond can be: its breaking length, 2h_s or λ_c r₀ with r₀ < 2h_s at the
    /// table's build (`fracture_build_bonds`); 0 (no pruning) on a periodic domain, where a bond's
    /// length is a minimum image. The blade test of fracture skips particles farther than this from
    /// every blade (`fracture::blade_near`).
    pub fn bond_reach(&self) -> f32 {
        if self.periodic.iter().any(|&p| p) {
            return 0.0;
        }
        self.k_solid.r * self.critical_stretch.unwrap_or(1.0).max(1.0)
    }

    /// Periodic lengths per axis (0 where not periodic).
    pub fn periodic_len(&self) -> Vec3 {
        let e = self.domain_max - self.domain_min;
        Vec3::new(
            if self.periodic[0] { e.x } else { 0.0 },
            if self.periodic[1] { e.y } else { 0.0 },
            if self.periodic[2] { e.z } else { 0.0 },
        )
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}
