//! Accelerations of liquid and solid particles — twin of `shaders/forces.wgsl` (SPEC §3.6–3.13).
//!
//! Liquid (2.50): −nˡ∇p with the spiky kernel (D-15, D-16), mirrored boundary pressure (§4.1, D-23),
//! viscosity κ_V(η/ρ_i)Σ(m_j/ρ_j)(v_j − v_i)∇²W_V (D-7, D-17), pairwise friction (2.17, D-18), g, and
//! when enabled the surface tension (3.3) and the liquid–void attraction (3.4) (§3.12); the capsule's
//! ghost sites and its seal (`capsule_inner`, `sim::ghosts`, `capsule_seal_pair`; README: deviations from SPEC).
//! Solid (2.48): deviatoric stress over bonds, −nˢ∇p, artificial stress (2.59)–(2.60), artificial
//! viscosity (2.54)–(2.58) over current neighbours, boundary contact, friction and attraction reactions,
//! membrane reactions gathered from the liquid (§4.1: no atomics), g; and the solid's continuity dρ/dt
//! (2.47), whose pairs are those of the pressure term and the walls' contact. XSPH (2.69) for both, in
//! evaluation 0's force passes (`xsph`): its sum walks the neighbours the forces walk.

use super::{BoundarySet, LiquidSet, Nbrs, ObjectContact, SolidSet};
use crate::scenario::SolidFlags;
use crate::sim::params::{OutletRegion, Params};
use glam::{Mat3, Vec3};
use rayon::prelude::*;

pub struct ForceCtx<'a> {
    pub p: &'a Params,
    /// Current surface geometry of each boundary object (no-slip extrapolation).
    pub geoms: &'a [ObjectGeom],
    pub gravity: Vec3,
    pub contacts: &'a [ObjectContact],
    /// During relaxation with `gravity_solid_only`, the liquid feels no gravity.
    pub gravity_liquid: bool,
    /// The pressure outlets in effect (`Params::outlets_in_effect`).
    pub outlets: &'a [OutletRegion],
    /// Per liquid particle, whether it sees a blood ghost of the capsule (`density::LiquidDensities`;
    /// empty without ghosts): then the capsule's particles are no wall for it.
    pub sees_ghost: &'a [bool],
}

impl ForceCtx<'_> {
    /// Whether liquid i sees a blood ghost (`sees_ghost`).
    #[inline]
    pub fn sees_ghost(&self, i: usize) -> bool {
        self.sees_ghost.get(i) == Some(&true)
    }
}

/// Acceleration of solid particle i from the hourglass control of bond (i, j) (`numerics.hourglass`,
/// README: deviations from SPEC): δ = (½(F̃_i + F̃_j)X_ij − x_ij)·x̂_ij, the part of the bond's stretch
/// that the affine fits F̃ (`solid::solid_fit`) of its two ends do not explain, drives the central pair
/// force −c G V_i V_j W_C(|X_ij|)/|X_ij|² δ x̂_ij (after Ganzenmüller 2015; G = 2(C10 + C01), V = m/ρ_ref,
/// x_ij = x_j − x_i now, X_ij in the generated configuration). It is antisymmetric in (i, j), so it
/// conserves momentum, and zero for any affine motion. `xij` is x_i − x_j as in the stress loop.
/// `stiffness` scales G for the bond: `hourglass_stiffness` of its two ends, so that a capsule bond
/// (`membrane.stiffness`) is held as stiffly as the capsule's stress holds it.
#[inline]
pub fn hourglass_pair(
    p: &Params,
    fit_i: Mat3,
    fit_j: Mat3,
    x_ref_ij: Vec3,
    xij: Vec3,
    m_j: f32,
    stiffness: f32,
) -> Vec3 {
    let big = super::grid::min_image(x_ref_ij, p.periodic_len());
    let now = -xij;
    let r = now.length();
    let l0 = big.length();
    if r <= 0.0 || l0 <= 0.0 {
        return Vec3::ZERO;
    }
    let u = now / r;
    let delta = ((fit_i + fit_j) * big * 0.5 - now).dot(u);
    let g_mod = 2.0 * (p.c10 + p.c01) * stiffness;
    let k = p.hourglass * g_mod * (m_j / p.rho_ref_s) * p.k_solid.w_cubic(l0) / (l0 * l0 * p.rho_ref_s);
    u * -(k * delta)
}

/// The factor on G of the hourglass control for a bond between particles with these `SolidFlags`: the
/// mean of the two ends' `Params::stiffness_factor` (symmetric, so the pair force stays antisymmetric).
#[inline]
pub fn hourglass_stiffness(p: &Params, flags_i: u32, flags_j: u32) -> f32 {
    0.5 * (p.stiffness_factor(flags_i) + p.stiffness_factor(flags_j))
}

/// Monaghan's Π_ij (2.54)–(2.58); zero for separating pairs.
#[inline]
pub fn artificial_viscosity(
    vij: Vec3,
    xij: Vec3,
    r: f32,
    h: f32,
    c: f32,
    rho_bar: f32,
    alpha: f32,
    beta: f32,
    gamma: f32,
) -> f32 {
    let vx = vij.dot(xij);
    if vx >= 0.0 {
        return 0.0;
    }
    let mu = h * vx / (r * r + gamma * h * h);
    (-alpha * c * mu + beta * mu * mu) / rho_bar
}

/// Friction coefficient K_ij = K̄ max(0, 1 − ½(nˢ_i + nˢ_j)) (D-18).
#[inline]
pub fn friction_coefficient(kbar: f32, ns_i: f32, ns_j: f32) -> f32 {
    kbar * (1.0 - 0.5 * (ns_i + ns_j)).max(0.0)
}

/// Surface of a boundary object at its current pose, in simulation coordinates (mirrored by
/// `ObjectGeom` in `shaders/common.wgsl`). `kind`: 0 box [a, b], 1 sphere (centre a, radius b.x),
/// 2 none (no extrapolation).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ObjectGeom {
    pub kind: u32,
    pub a: Vec3,
    pub b: Vec3,
}

/// Nearest face of box `g` to a point x inside it, over the first `dims` axes: (axis, side) with side
/// −1 for the low face and +1 for the high one; the first axis and the low side win ties. Twin of
/// `nearest_face` in `shaders/common.wgsl`.
pub fn nearest_face(g: &ObjectGeom, x: Vec3, dims: usize) -> (usize, f32) {
    let mut best = f32::INFINITY;
    let (mut axis, mut side) = (0, -1.0);
    for a in 0..dims {
        let (lo, hi) = (x[a] - g.a[a], g.b[a] - x[a]);
        if lo < best {
            (best, axis, side) = (lo, a, -1.0);
        }
        if hi < best {
            (best, axis, side) = (hi, a, 1.0);
        }
    }
    (axis, side)
}

/// A box (kind 0) that holds `y` on the side `n` points to: closed on the axes where n is 0, and
/// just past y where it is not (the box covers the ground a particle put on y would stand on). Twin
/// of `box_covering` in `shaders/common.wgsl`.
pub fn box_covering(geoms: &[ObjectGeom], y: Vec3, n: Vec3, dims: usize) -> Option<usize> {
    geoms.iter().position(|o| {
        o.kind == 0
            && (0..dims).all(|a| {
                if n[a] < 0.0 {
                    y[a] > o.a[a] && y[a] <= o.b[a]
                } else if n[a] > 0.0 {
                    y[a] >= o.a[a] && y[a] < o.b[a]
                } else {
                    y[a] >= o.a[a] && y[a] <= o.b[a]
                }
            })
    })
}

/// Where a point x strictly inside box `geoms[k]` is put back out (`object_contact`): the nearest
/// point on the surface of the union of the boxes among these candidates — each face of box k, and,
/// where another box covers that face at x's landing point (a vessel's side wall standing on its
/// floor), that landing point moved onto a face of the covering box on another axis, and so on once
/// more (the corner where two walls meet the floor). A candidate counts when no box covers it. Returns
/// the point and the outward normals used (±1 on one axis, or on two or three at a corner). With one
/// box, or no box at a face, this is the nearest face ([`nearest_face`], same ties); when every
/// candidate is covered, the nearest face too. The nearest face alone could be the plane a wall shares
/// with its floor: a particle that entered the wall's foot went onto that seam and slid out of the
/// vessel along it (`docs/sealed_column.ron`). Twin of `box_exit` in `shaders/common.wgsl`, in the same
/// f32 operations and order.
pub fn box_exit(geoms: &[ObjectGeom], k: usize, x: Vec3, dims: usize) -> (Vec3, Vec3) {
    let g = &geoms[k];
    let mut best = (f32::INFINITY, None);
    for a in 0..dims {
        for side in [-1.0f32, 1.0] {
            let (face, d) = if side < 0.0 { (g.a[a], x[a] - g.a[a]) } else { (g.b[a], g.b[a] - x[a]) };
            if d >= best.0 {
                continue;
            }
            let mut y = x;
            y[a] = face;
            let mut n = Vec3::ZERO;
            n[a] = side;
            match box_covering(geoms, y, n, dims) {
                None => best = (d, Some((y, n))),
                Some(j) => exit_via(geoms, j, x, y, n, dims, &mut best),
            }
        }
    }
    best.1.unwrap_or_else(|| {
        let (axis, side) = nearest_face(g, x, dims);
        let mut y = x;
        y[axis] = if side < 0.0 { g.a[axis] } else { g.b[axis] };
        let mut n = Vec3::ZERO;
        n[axis] = side;
        (y, n)
    })
}

/// [`box_exit`]'s next level: the landing point y (normals n so far) is covered by box j; moves it onto
/// each face of j on an axis not used yet, and keeps the nearest uncovered result in `best`. The search
/// ends when every axis has a normal (a corner of three boxes in 3-D).
fn exit_via(
    geoms: &[ObjectGeom],
    j: usize,
    x: Vec3,
    y: Vec3,
    n: Vec3,
    dims: usize,
    best: &mut (f32, Option<(Vec3, Vec3)>),
) {
    let c = &geoms[j];
    for b in (0..dims).filter(|&b| n[b] == 0.0) {
        for side in [-1.0f32, 1.0] {
            let mut y2 = y;
            y2[b] = if side < 0.0 { c.a[b] } else { c.b[b] };
            let mut n2 = n;
            n2[b] = side;
            let d = (y2 - x).length();
            if d >= best.0 {
                continue;
            }
            match box_covering(geoms, y2, n2, dims) {
                None => *best = (d, Some((y2, n2))),
                Some(j2) => exit_via(geoms, j2, x, y2, n2, dims, best),
            }
        }
    }
}

/// Outward unit normal of an object's surface nearest to x (twin of `surface_normal` in forces.wgsl):
/// a box's from its closest point, or, for x inside it, its nearest face ([`nearest_face`]); a
/// sphere's radial direction. None at a sphere's centre and for kind 2.
pub fn surface_normal(g: &ObjectGeom, x: Vec3, dims: usize) -> Option<Vec3> {
    match g.kind {
        0 => {
            let d = x - x.clamp(g.a, g.b);
            let len = d.length();
            if len > 1e-30 {
                return Some(d / len);
            }
            let (axis, side) = nearest_face(g, x, dims);
            let mut n = Vec3::ZERO;
            n[axis] = side;
            Some(n)
        }
        1 => {
            let d = x - g.a;
            let len = d.length();
            (len > 1e-30).then(|| d / len)
        }
        _ => None,
    }
}

/// Largest ghost-velocity extrapolation factor β (Morris, Fox & Zhu 1997).
pub const NO_SLIP_BETA_MAX: f32 = 1.5;

/// No-slip factor 1 + β for the viscous term of a liquid particle at x_i and a boundary particle at
/// x_b (SPEC §4.1, deviation noted in the README): the wall particle carries the extrapolated ghost
/// velocity v_g = v_b − β(v_i − v_b), β = min(β_max, d_b/d_i), with d_i the distance of i to the
/// object's surface and d_b the depth of b below the same tangent plane. This places the no-slip plane
/// on the object's surface instead of ~Δx inside the fluid (measured: +8.8 % steady Poiseuille velocity
/// at 40 rows with β = 0).
#[inline]
pub fn no_slip_factor(g: &ObjectGeom, xi: Vec3, xb: Vec3) -> f32 {
    let closest = match g.kind {
        0 => xi.clamp(g.a, g.b),
        1 => {
            let d = xi - g.a;
            let len = d.length();
            if len <= 1e-30 {
                return 1.0 + NO_SLIP_BETA_MAX;
            }
            g.a + d * (g.b.x / len)
        }
        _ => return 1.0,
    };
    let off = xi - closest;
    let di = off.length();
    if g.kind == 1 && (xi - g.a).length() <= g.b.x || di <= 1e-30 {
        return 1.0 + NO_SLIP_BETA_MAX;
    }
    let n = off / di;
    let db = (closest - xb).dot(n).max(0.0);
    1.0 + (db / di).min(NO_SLIP_BETA_MAX)
}

/// One solid particle's wall contacts, gathered for Coulomb friction (README: deviations from SPEC).
/// Each pair contributes its contact-pressure acceleration a_p (the mirror pressure force of SPEC §4.1,
/// pushing the particle off the wall) weighted by the object's μ. Their vector sum L = Σμa_p is the
/// friction bound |L| = μ × the net normal load along n̂ = L/|L| (pair components along the wall cancel,
/// so a flat wall's load is its normal force, not the sum of the pair magnitudes); the walls' velocity
/// is the mean v_b weighted by μ|a_p|. Twin of `wall_contact_*` in `shaders/forces.wgsl`.
#[derive(Clone, Copy, Debug, Default)]
pub struct WallContact {
    /// L = Σ μ a_p [m/s²].
    pub load: Vec3,
    /// Σ μ |a_p|.
    pub weight: f32,
    /// Σ μ |a_p| v_b.
    pub vel: Vec3,
}

impl WallContact {
    /// Adds one pair's contact-pressure acceleration a_p (zero when the pair pulls: a prescribed
    /// suction pressure carries no load).
    #[inline]
    pub fn add(&mut self, mu: f32, a_p: Vec3, pushes: bool, vb: Vec3) {
        if pushes {
            let w = mu * a_p.length();
            self.load += a_p * mu;
            self.weight += w;
            self.vel += vb * w;
        }
    }

    /// Friction acceleration of a particle moving at v_i: −v̂_t min(|L|, |v_t|/Δt_up), with v_t the
    /// velocity relative to the walls tangent to n̂. Sliding (|v_t| > |L|Δt_up) feels the kinetic
    /// Coulomb force; slower motion is removed at the rate 1/Δt_up, which with every Δt ≤ Δt_up
    /// (`Params::dt_upper`) never reverses it within a step — the stick regime.
    #[inline]
    pub fn friction(&self, vi: Vec3, dt_upper: f32) -> Vec3 {
        let bound = self.load.length();
        if self.weight <= 0.0 || bound <= 0.0 {
            return Vec3::ZERO;
        }
        let n = self.load / bound;
        let vrel = vi - self.vel / self.weight;
        let vt = vrel - n * vrel.dot(n);
        let speed = vt.length();
        if speed <= 0.0 {
            return Vec3::ZERO;
        }
        vt * -(bound / speed).min(1.0 / dt_upper)
    }
}

/// Acceleration a liquid particle (ρ, p, nˡ, v) receives from one boundary-like neighbour
/// (wall particle or membrane particle) of liquid-equivalent mass m_b (SPEC §4.1, §3.6). In mirror mode
/// the wall shows ρ_b = ρ_i and the hydrostatically extrapolated p_b = max(p_i + ρ_i g·(x_b − x_i), 0)
/// (Adami, Hu & Adams 2012; README: deviations from SPEC), so a wall carries the weight above it.
/// `outside`: the pressure on the boundary particle's far side, taken off the mirror's bracket as
/// 2·outside/ρ² — 0 for the force on the liquid, the ambient p_a for the reaction on a capsule
/// particle (`numerics.ambient_pressure`: the air outside balances p_a of the blood inside).
#[inline]
pub fn liquid_from_boundary(
    p: &Params,
    rho: f32,
    pr: f32,
    n_l: f32,
    vi: Vec3,
    m_b: f32,
    vb: Vec3,
    xib: Vec3,
    r: f32,
    mode: ObjectContact,
    no_slip: f32,
    g: Vec3,
    outside: f32,
) -> Vec3 {
    let k = &p.k_liquid;
    let grad = xib * k.grad_spiky_factor(r);
    let bracket = if mode.density < 0.0 {
        let pb = (pr + rho * g.dot(-xib)).max(0.0);
        (pr.max(0.0) + pb - 2.0 * outside) / (rho * rho)
    } else {
        pr / (rho * rho) + mode.pressure / (mode.density * mode.density)
    };
    let mut a = grad * (-n_l * m_b * bracket * p.kappa_s);
    a += (vb - vi) * (no_slip * p.kappa_v * p.eta / rho * (m_b / rho) * k.lap_viscosity(r));
    a
}

/// Outward unit normal of a membrane particle now, from its generated one n̂₀ and its deformation
/// gradient F: cof(F) n̂₀ = det F · F⁻ᵀ n̂₀ (Nanson's formula), normalised; zero where F is degenerate.
/// Twin of `capsule_normal` in common.wgsl.
#[inline]
pub fn capsule_normal(f: Mat3, n0: Vec3) -> Vec3 {
    let n = f.y_axis.cross(f.z_axis) * n0.x + f.z_axis.cross(f.x_axis) * n0.y + f.x_axis.cross(f.y_axis) * n0.z;
    let l2 = n.dot(n);
    if l2 > 1e-12 { n / l2.sqrt() } else { Vec3::ZERO }
}

/// Whether liquid i lies beneath membrane particle j's capsule, (x_j − x_i)·n̂ ≥ 0 along its outward
/// normal n̂ (`capsule_normal`), where the capsule's ghost sites (`membrane.ghosts`, `sim::ghosts`)
/// stand in for the tissue and the blood that the organ's surface truncates: for such liquid j is no
/// boundary particle (its ghosts are the wall, `ghosts::ghost_on_liquid`), and for liquid on the outer
/// side it is one unless that liquid sees a ghost (SPEC §4.1). Without ghosts every liquid particle
/// sees j as SPEC §4.1's boundary particle — the thesis's single-layer capsule, beneath which the blood
/// sees half a kernel of tissue (nˢ ≈ 0.3–0.45 where the tissue holds 0.6–0.7), so its penalty
/// pressure (2.53) stays 0 however much blood collects there and it drains through a lower face at
/// the Darcy speed (README: deviations from SPEC). Twin of `capsule_inner` in common.wgsl.
#[inline]
pub fn capsule_inner(p: &Params, n: Vec3, xij: Vec3) -> bool {
    p.capsule_ghosts && n != Vec3::ZERO && xij.dot(n) <= 0.0
}

/// Steps (of Δt_max) over which the capsule's seal walks liquid that lies beyond the capsule's plane
/// back to it ([`capsule_seal_pair`]), by its advection velocity ṽ alone. Slow enough that the blood's
/// walk does not drag the light capsule outward through the pressure it leaves behind: the 8³
/// projectile specimen relaxed with no source inside (`relax_probe … emitters=[]`) keeps its capsule
/// at up to 41.6 mm/s at 32 steps, 4.1 at 128, 2.3 at 256; the capsule case passes at all three and the
/// liver at rest moves at 1.95, 1.90 and 2.00 mm/s (README, Deviations; measured while the seal still
/// walked blood at any pressure, before [`capsule_seal_walks`]).
pub const CAPSULE_SEAL_STEPS: f32 = 128.0;

/// Steps (of Δt_max) over which the capsule's seal stops liquid moving out through the capsule: a few,
/// so that blood draining onto the capsule at ≈ 1 cm/s does not strike it in a single step (which
/// shook the default liver's capsule), and few enough that it moves microns into the band meanwhile.
pub const CAPSULE_SEAL_STOP_STEPS: f32 = 4.0;

/// Whether the seal walks liquid at pressure `pr` back to the capsule's plane ([`capsule_seal_pair`]'s
/// `back`): only where the capsule's mirror pressure does not hold it, p ≤ 0 (SPEC §4.1's bracket on the
/// liquid is 2 max(p, 0)/ρ², nothing at p = 0 — the unsaturated blood that crossed the capsule at the
/// Darcy speed). Blood under pressure is pushed back by the mirror already; walking it inward as well
/// moved it against its own pressure, a correction of where it goes that does work on the blood without
/// a force, returned as motion by the next steps: the seal's walk-back kept the relaxed projectile
/// specimen moving (8³: fastest solid 6.26 mm/s at t = 0 with every particle walked, 1.82 with p ≤ 0
/// alone; the capsule case holds its indented blood either way; README, Deviations). Twin of
/// `capsule_seal_walks` in common.wgsl.
///
/// With the capsule's ghost sites (`membrane.ghosts`) the seal's plane is the organ's surface
/// ([`capsule_seal_offset`]), and the walk acts on the rare blood that crept past it — which has lost
/// the ghosts beyond (they count only beneath the surface) and with them its pressure: the hanging cube
/// of `perfuse validate --case capsule` had 1 such particle at 10⁴ steps without the walk, none with it
/// (session 55). (The probe's walk from the particles' plane, where all the blood of that half spacing
/// was walked, threw the capsule at up to 24 mm/s.)
#[inline]
pub fn capsule_seal_walks(pr: f32) -> bool {
    pr <= 0.0
}

/// Where the seal's plane lies beyond the capsule particle along its normal: at the particle itself,
/// or with the capsule's ghost sites at the organ's surface, Δx_s/2 beyond it (the particle stands for
/// the volume Δx_s³ around it; the ghosts' blood fills the half spacing beneath the surface, which the
/// seal at the particle's plane would cut off). Twin of `capsule_seal_offset` in common.wgsl.
#[inline]
pub fn capsule_seal_offset(p: &Params) -> f32 {
    if p.capsule_ghosts { 0.5 * p.capsule_dx_solid } else { 0.0 }
}

/// Whether membrane particle j still seals: three quarters of its bonds intact (SPEC §4.6). A capsule
/// torn by a blade or a projectile stops sealing there, and blood leaves through the wound. Twin of
/// `capsule_seals` in common.wgsl.
#[inline]
pub fn capsule_seals(bond_count: u32, bond_count0: u32) -> bool {
    4 * bond_count >= 3 * bond_count0
}

/// The capsule's seal (`membrane.seal`; README: deviations from SPEC). The thesis's capsule holds its
/// blood by the mirror pressure of its particles alone (SPEC §4.1), which is max(p, 0): blood that
/// has drained to a face or an edge of the organ, unsaturated there and so at p = 0, crossed it at the
/// Darcy speed, a few particles per 10⁴ steps (`perfuse validate --case capsule`). The seal makes the
/// intact capsule impermeable to liquid moving outward through it: for liquid i within the capsule's
/// spacing Δx_s of an intact membrane particle j (`capsule_seals`) whose plane it lies in the band
/// −δ < (x_i − x_j)·n̂ < δ, δ = Δx_l/4 (the liquid rests Δx_l/2 beneath the capsule:
/// `keep_liquid_beneath_capsule`), the outward normal velocity relative to j is removed within
/// [`CAPSULE_SEAL_STOP_STEPS`] steps, an inelastic stop shared between the two ([`capsule_seal_share`]);
/// liquid beyond the plane (blood generated there, or a step's drift) that the mirror pressure does not
/// hold ([`capsule_seal_walks`]: p ≤ 0) is in addition walked back to it in [`CAPSULE_SEAL_STEPS`] steps
/// by its advection velocity ṽ (2.65), like XSPH a correction of where it goes and not of its momentum.
/// (As a target velocity of the stop — session 45 — the walk-back parted the pair at up to
/// δ/(32Δt_max), ≈ 0.1 m/s, and threw the light capsule particles outward: 154 mm/s in the liver's
/// relaxation at 7 mm, 15 mm/s with no seal.) Liquid in the band is never pushed inward: a
/// `PerfusedBlock`'s outer liquid layer, generated 0.06Δx_s beneath the capsule, stays where it is.
///
/// The liquid's acceleration is −Σ σ_ij `stop` / (Σ w · s Δt_max), σ_ij its share of the pair's stop,
/// s = [`CAPSULE_SEAL_STOP_STEPS`], Δt_max = `Params::dt_upper`, and its ṽ gains Σ `back` / Σ w (at
/// p ≤ 0), the sums over the intact membrane particles within reach; j receives the stop's reaction.
/// `xij` = x_i − x_j, `v_rel` = v_i − v_j, `n` j's outward normal (`capsule_normal`). Twin of
/// `capsule_seal_pair` in common.wgsl.
#[inline]
pub fn capsule_seal_pair(p: &Params, n: Vec3, xij: Vec3, r: f32, v_rel: Vec3) -> SealPair {
    let none = SealPair { w: 0.0, stop: Vec3::ZERO, back: Vec3::ZERO };
    if r >= p.capsule_dx_solid || n == Vec3::ZERO {
        return none;
    }
    let w = p.k_liquid.w_poly6(r);
    let depth = 0.25 * p.capsule_dx_liquid;
    let sd = xij.dot(n) - capsule_seal_offset(p);
    if sd <= -depth || sd >= depth {
        return SealPair { w, ..none };
    }
    let back = n * (-w * sd.max(0.0) / (CAPSULE_SEAL_STEPS * p.dt_upper()));
    SealPair { w, stop: n * (w * v_rel.dot(n).max(0.0)), back }
}

/// One intact membrane particle's part in the seal on one liquid particle ([`capsule_seal_pair`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SealPair {
    /// Its weight W_P(r; h_l), 0 beyond Δx_s.
    pub w: f32,
    /// w (v_n)⁺ n̂: the outward relative normal velocity it stops, weighted.
    pub stop: Vec3,
    /// −w (sd)⁺ n̂ / (s Δt_max): the walk back to its plane, weighted (an advection velocity).
    pub back: Vec3,
}

/// The liquid's share of the seal's stop, m_j/(m_i + m_j) for liquid i and membrane particle j: the
/// pair's relative outward velocity is removed as in an inelastic collision, the liquid taking the
/// share m_j/(m_i + m_j) of the change and the membrane m_i/(m_i + m_j), so that momentum is conserved
/// and the pair stops without overshoot. Without it (the liquid stopped in full, the membrane given
/// the reaction) a capsule child of a quarter site's mass under liquid 3.3× heavier (the §4.2
/// specimens) was thrown outward 0.8× the excess per step by each liquid neighbour: past the liquid,
/// back by its bonds, thrown out again: in the 8³ projectile specimen's relaxation the fastest capsule
/// particle fell from 330 to 187 mm/s with the share, and to 18 mm/s once the walk-back also left the
/// stop (README: deviations from SPEC). Twin of `capsule_seal_share` in common.wgsl.
#[inline]
pub fn capsule_seal_share(m_liquid: f32, m_membrane: f32) -> f32 {
    m_membrane / (m_liquid + m_membrane)
}

/// Monaghan's (2000) artificial pressure of a liquid pair under tension (`numerics.liquid_artificial_
/// pressure`; README: deviations from SPEC): (R_i + R_j) f_ij^n with R = ε max(0, −p/ρ²), the liquid's
/// form of the solid's artificial stress (2.59)–(2.60), and f_ij = W_C(r; h_l)/W_C(Δx_l; h_l). Added to
/// the pair's p_i/ρ_i² + p_j/ρ_j², it repels particles closer than Δx_l where the suction would pull them
/// into pairs and stacks (SPH's tensile instability). `pi`, `pj` are p/ρ². Twin of
/// `liquid_artificial_pressure` in forces.wgsl.
#[inline]
pub fn liquid_artificial_pressure(p: &Params, pi: f32, pj: f32, r: f32) -> f32 {
    let big_r = p.ap_eps * ((-pi).max(0.0) + (-pj).max(0.0));
    if big_r <= 0.0 {
        return 0.0;
    }
    big_r * (p.k_liquid.w_cubic(r) / p.wc_dx_l).powi(p.ap_exp)
}

/// Pair factor of the liquid–void attraction (3.4), SPEC §3.12: w_j (γ/h_×²) cos(πr/(4h_×)) with the
/// switch w_j = max(0, 1 − nˢ_j − nˡ_j) of the solid particle j; the force per unit volume on the liquid
/// particle points toward j (D-22). Zero beyond R_× = 2h_× and for coincident particles.
#[inline]
pub fn wicking_pair(gamma: f32, h_x: f32, ns_j: f32, nl_j: f32, r: f32) -> f32 {
    let w = (1.0 - ns_j - nl_j).max(0.0);
    if r <= 0.0 || r >= 2.0 * h_x {
        return 0.0;
    }
    w * (gamma / (h_x * h_x)) * (std::f32::consts::PI * r / (4.0 * h_x)).cos()
}

/// Pair force \[N\] of the Tartakovsky–Meakin surface tension (3.3), SPEC §3.12: s cos(πr/(2R)), toward
/// the neighbour (D-22). Zero beyond R and for coincident particles.
#[inline]
pub fn cohesion_pair(s: f32, radius: f32, r: f32) -> f32 {
    if r <= 0.0 || r >= radius {
        return 0.0;
    }
    s * (std::f32::consts::PI * r / (2.0 * radius)).cos()
}

/// Accelerations of the liquid (twin of `forces_liquid` and, with `xsph`, `forces_liquid_xsph`), and
/// with `xsph` the XSPH advection velocities (2.69) ṽ_i = v_i + ε̃ Σ (m_j/ρ̄_ij)(v_j − v_i)W6, summed in
/// the same walk over the liquid (R_l).
pub fn forces_liquid(
    c: &ForceCtx,
    l: &LiquidSet,
    s: &SolidSet,
    b: &BoundarySet,
    nb: &Nbrs,
    xsph: bool,
) -> LiquidForces {
    let p = c.p;
    let kl = &p.k_liquid;
    let kx = &p.k_cross;
    let g = if c.gravity_liquid { c.gravity } else { Vec3::ZERO };
    let seal = p.capsule_seal > 0.0;
    let (a, (vx, seal_scale)): (Vec<Vec3>, (Vec<Vec3>, Vec<f32>)) = (0..l.x.len())
        .into_par_iter()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|i| {
            let (xi, vi, rho, pr, n_l, n_s) = (l.x[i], l.v[i], l.rho[i], l.p[i], l.n_l[i], l.n_s[i]);
            if let Some(o) = OutletRegion::find(c.outlets, xi) {
                // an outlet's buffer feels no force; evaluation 0 gives it the velocity of the liquid
                // around it as its ṽ (the predictor makes it its v: `integrate_predict`)
                let u = if xsph { outlet_velocity(p, o, c.outlets, l, nb, i) } else { vi };
                return (Vec3::ZERO, (u, 0.0));
            }
            let pi = pr / (rho * rho);
            let inv_m = 1.0 / l.m[i];
            let mut a = Vec3::ZERO;
            let mut d_xsph = Vec3::ZERO;
            nb.liquid.for_each(xi, kl.r, |j, xij, r| {
                if j == i {
                    return;
                }
                if p.cohesion_ll > 0.0 && r > 0.0 {
                    // Surface tension (3.3): pair force toward j.
                    a -= xij * (cohesion_pair(p.cohesion_ll, kl.r, r) * inv_m / r);
                }
                let grad = xij * kl.grad_spiky_factor(r);
                let pj = l.p[j] / (l.rho[j] * l.rho[j]);
                let mut p_pair = pi + pj;
                if p.ap_eps > 0.0 {
                    p_pair += liquid_artificial_pressure(p, pi, pj, r);
                }
                // −n∇p with the pair's mean fraction: an antisymmetric pair force, so the phase's
                // pressure forces sum to zero (D-16's n_i alone propels a body with an asymmetric surface)
                a += grad * (-0.5 * (n_l + l.n_l[j]) * l.m[j] * p_pair * p.kappa_s);
                a += (l.v[j] - vi) * (p.kappa_v * p.eta / rho * (l.m[j] / l.rho[j]) * kl.lap_viscosity(r));
                if p.av_liquid {
                    let pij = artificial_viscosity(
                        vi - l.v[j],
                        xij,
                        r,
                        kl.h,
                        p.c_l,
                        0.5 * (rho + l.rho[j]),
                        p.av_alpha,
                        p.av_beta,
                        p.av_gamma,
                    );
                    a -= grad * (l.m[j] * pij);
                }
                if xsph && p.xsph_l != 0.0 {
                    d_xsph += (l.v[j] - vi) * (l.m[j] / (0.5 * (rho + l.rho[j])) * kl.w_poly6(r));
                }
            });
            nb.boundary.for_each(xi, kl.r, |j, xij, r| {
                let obj = b.object[j] as usize;
                let slip = no_slip_factor(&c.geoms[obj], xi, b.x[j]);
                a += liquid_from_boundary(p, rho, pr, n_l, vi, b.m_l[j], b.v[j], xij, r, c.contacts[obj], slip, g, 0.0);
                if p.cohesion_lb > 0.0 && r > 0.0 {
                    // Adhesion (3.3) to walls and plates.
                    a -= xij * (cohesion_pair(p.cohesion_lb, kl.r, r) * inv_m / r);
                }
            });
            // the capsule's blood ghosts as boundary particles with their wall pressure (`ghosts`)
            if let Some(gn) = &nb.ghosts {
                gn.for_each(xi, kl.r, |k, xig, r| {
                    let (m_g, st) = (gn.gh.m_l[k], &gn.state[k]);
                    if m_g > 0.0 && st.rho > 0.0 {
                        let v_o = s.v[gn.gh.owner[k] as usize];
                        a += super::ghosts::ghost_on_liquid(p, rho, pr, n_l, vi, m_g, v_o, xig, r, st, 0.0);
                    }
                });
            }
            let sees_ghost = c.sees_ghost(i);
            // One pass over the solid (R_× ≥ R_l): membrane particles as boundary, and friction (2.17).
            let mut f = Vec3::ZERO;
            let (mut seal_w, mut seal_sum, mut seal_back) = (0.0f32, Vec3::ZERO, Vec3::ZERO);
            nb.solid.for_each(xi, kx.r, |j, xij, r| {
                if r < kl.r && s.flags[j] & SolidFlags::MEMBRANE != 0 {
                    let (m_b, vb) = (s.m_bl[j], s.v[j]);
                    let mirror = ObjectContact::MIRROR;
                    let n = capsule_normal(s.def_grad[j], s.normal0[j]);
                    if seal && capsule_seals(s.bond_count[j], s.bond_count0[j]) {
                        let sp = capsule_seal_pair(p, n, xij, r, vi - vb);
                        seal_w += sp.w;
                        seal_sum += sp.stop * capsule_seal_share(l.m[i], s.m[j]);
                        seal_back += sp.back;
                    }
                    // beneath the capsule its ghosts are the wall (`capsule_inner`)
                    if !capsule_inner(p, n, xij) && !sees_ghost {
                        a += liquid_from_boundary(p, rho, pr, n_l, vi, m_b, vb, xij, r, mirror, 1.0, g, 0.0);
                    }
                }
                if p.kbar > 0.0 {
                    let k = friction_coefficient(p.kbar, n_s, s.n_s[j]);
                    f += (vi - s.v[j]) * (s.m[j] / s.rho[j] * k * kx.w_poly6(r));
                }
                if p.wicking > 0.0 && r > 0.0 {
                    // Liquid–void attraction (3.4) toward unsaturated solid, per unit volume ÷ ρ_i.
                    a -= xij * (wicking_pair(p.wicking, kx.h, s.n_s[j], s.n_l[j], r) / (rho * r));
                }
            });
            if p.kbar > 0.0 {
                a -= f / rho;
            }
            // the capsule's seal (`capsule_seal_pair`): 1/(Σw s Δt_max), kept for the membrane's reaction
            let scale = if seal_w > 0.0 { 1.0 / (seal_w * (CAPSULE_SEAL_STOP_STEPS * p.dt_upper())) } else { 0.0 };
            a -= seal_sum * scale;
            // and its walk back to the capsule's plane, in ṽ alone, where the mirror pressure does not
            // hold the blood (`capsule_seal_walks`)
            let back = if seal_w > 0.0 && capsule_seal_walks(pr) { seal_back / seal_w } else { Vec3::ZERO };
            (a + g, (xsph_velocity(vi, d_xsph, p.xsph_l) + back, scale))
        })
        .unzip();
    LiquidForces { a, xsph: xsph.then_some(vx), seal_scale }
}

/// What `forces_liquid` returns: accelerations, XSPH velocities (evaluation 0), and per particle the
/// capsule seal's 1/(Σw s Δt_max) (`capsule_seal_pair`; 0 where no intact capsule is within reach), which the membrane's
/// reaction in `forces_solid` needs (on the GPU: `liquid_acc.w`).
pub struct LiquidForces {
    pub a: Vec<Vec3>,
    pub xsph: Option<Vec<Vec3>>,
    pub seal_scale: Vec<f32>,
}

/// Velocity of a liquid particle i in outlet `o`'s buffer: along the outlet's normal, the normal part
/// of the Shepard mean Σ (ρ_j/ρ_o) v_j W6 / Σ W6 over the open liquid within R_l (outside every buffer;
/// after Tafuni et al. 2018's first-order extrapolation, of the mass flux ρ_j v_j over the buffer's own
/// density ρ_o rather than of v_j: continuity across the buffer's face. The buffer is pure liquid at the
/// outlet's pressure, so blood drawn out of tissue at nˡ = 0.4 enters it at 0.4/(ρ_o/ρ₀) of its speed;
/// at v_j the buffer ran 2.5 times too fast and emptied: 0.25–0.36 full in `tests/outlet.rs`'s porous
/// channel, 0.62 in the reduced syringe; now 0.71–0.97 and 0.82), or, for the buffer's far
/// rows beyond R_l of the open liquid, over all the other liquid within R_l (so that they follow the
/// rows below them rather than keep their velocity), or of v_i when none is near. Along the normal
/// only, so that the buffer, which feels no force, keeps the lattice it was filled with instead of
/// drifting into a disorder whose kernel sums would misstate the prescribed pressure. Twin of
/// `outlet_velocity` in forces.wgsl.
fn outlet_velocity(p: &Params, o: &OutletRegion, outlets: &[OutletRegion], l: &LiquidSet, nb: &Nbrs, i: usize) -> Vec3 {
    let kl = &p.k_liquid;
    let (mut sum_w, mut sum_v) = (0.0f32, Vec3::ZERO);
    let (mut all_w, mut all_v) = (0.0f32, Vec3::ZERO);
    nb.liquid.for_each(l.x[i], kl.r, |j, _, r| {
        if j != i {
            let w = kl.w_poly6(r);
            all_w += w;
            all_v += l.v[j] * w;
            if OutletRegion::find(outlets, l.x[j]).is_none() {
                // continuity: the mass flux ρ_j v_j in front carried off at the buffer's density
                sum_w += w;
                sum_v += l.v[j] * (w * l.rho[j] / o.density);
            }
        }
    });
    let v = if sum_w > 0.0 {
        sum_v / sum_w
    } else if all_w > 0.0 {
        all_v / all_w
    } else {
        l.v[i]
    };
    o.normal * v.dot(o.normal)
}

/// ṽ = v + ε̃ d of XSPH (2.69) (v itself when ε̃ = 0).
fn xsph_velocity(v: Vec3, d: Vec3, eps: f32) -> Vec3 {
    if eps == 0.0 { v } else { v + d * eps }
}

/// Accelerations of the solid (twin of `forces_solid` and, with `xsph`, `forces_solid_xsph`), and with
/// `xsph` the XSPH advection velocities (2.69) with poly6 of R_s, summed in the same walk over the solid;
/// kinematic particles keep v.
pub fn forces_solid(
    c: &ForceCtx,
    s: &SolidSet,
    l: &LiquidSet,
    b: &BoundarySet,
    nb: &Nbrs,
    xsph: bool,
    seal_scale: &[f32],
) -> SolidForces {
    let p = c.p;
    let ks = &p.k_solid;
    let kl = &p.k_liquid;
    let kx = &p.k_cross;
    let support = 2.0 * ks.h;
    let cap = s.bond_capacity;
    let period = p.periodic_len();
    let g_l = if c.gravity_liquid { c.gravity } else { Vec3::ZERO };
    let dt_upper = p.dt_upper();
    let dims = p.dim.n();
    let hg = if s.hg_fit.len() == s.x.len() { p.hourglass } else { 0.0 };
    let out: Vec<(Vec3, Vec3, f32)> = (0..s.x.len())
        .into_par_iter()
        .with_min_len(super::MIN_PAR_LEN)
        .map(|i| {
            if s.flags[i] & SolidFlags::KINEMATIC != 0 {
                return (Vec3::ZERO, s.v[i], 0.0);
            }
            let (xi, vi, rho, pr, n_s) = (s.x[i], s.v[i], s.rho[i], s.p[i], s.n_s[i]);
            let inv2 = 1.0 / (rho * rho);
            let tau_i = s.tau[i] * inv2;
            let mut a = Vec3::ZERO;
            // Deviatoric stress over intact bonds (2.48), (2.43).
            let bonds = &s.bonds[i * cap..i * cap + s.bond_count[i] as usize];
            for &j in bonds {
                let j = j as usize;
                let xij = super::grid::min_image(xi - s.x[j], period);
                let grad = xij * ks.grad_cubic_factor(xij.length());
                let tj = s.tau[j] / (s.rho[j] * s.rho[j]);
                a += (tau_i + tj) * grad * s.m[j];
            }
            // The hourglass control over the same bonds (its own loop, as in forces.wgsl).
            if hg > 0.0 {
                for &j in bonds {
                    let j = j as usize;
                    let xij = super::grid::min_image(xi - s.x[j], period);
                    let stiff = hourglass_stiffness(p, s.flags[i], s.flags[j]);
                    a += hourglass_pair(p, s.hg_fit[i], s.hg_fit[j], s.x_ref[j] - s.x_ref[i], xij, s.m[j], stiff);
                }
            }
            // Isotropic pressure, artificial stress and artificial viscosity over current neighbours, and
            // the continuity dρ/dt (2.47) over the same pairs.
            let pi = pr * inv2;
            let mut d_xsph = Vec3::ZERO;
            let mut drho = 0.0f32;
            nb.solid.for_each(xi, support, |j, xij, r| {
                if j == i {
                    return;
                }
                let grad = xij * ks.grad_cubic_factor(r);
                drho += s.m[j] * (vi - s.v[j]).dot(grad);
                let pj = s.p[j] / (s.rho[j] * s.rho[j]);
                // −n∇p with the pair's mean fraction (antisymmetric: see forces_liquid)
                let mut acc = grad * (-0.5 * (n_s + s.n_s[j]) * (pi + pj));
                if p.as_eps > 0.0 {
                    let f = ks.w_cubic(r) / p.wc_dx;
                    acc += (s.art[i] + s.art[j]) * grad * f.powi(p.as_exp);
                }
                let pij = artificial_viscosity(
                    vi - s.v[j],
                    xij,
                    r,
                    ks.h,
                    p.c_s,
                    0.5 * (rho + s.rho[j]),
                    p.av_alpha,
                    p.av_beta,
                    p.av_gamma,
                );
                acc -= grad * pij;
                a += acc * s.m[j];
                if xsph && p.xsph_s != 0.0 {
                    d_xsph += (s.v[j] - vi) * (s.m[j] / (0.5 * (rho + s.rho[j])) * ks.w_poly6(r));
                }
            });
            // Boundary contact (mirror pressure, SPEC §4.1) and artificial viscosity against walls; an
            // object with Coulomb contact damps only the normal relative velocity and adds Coulomb
            // friction (README: deviations from SPEC).
            let mut contact = WallContact::default();
            nb.boundary.for_each(xi, support, |j, xib, r| {
                let grad = xib * ks.grad_cubic_factor(r);
                // B_s in the continuity (2.47), with its solid-equivalent mass
                if r < support {
                    drho += b.m_s[j] * (vi - b.v[j]).dot(grad);
                }
                let obj = b.object[j] as usize;
                let mode = c.contacts[obj];
                let bracket = if mode.density < 0.0 {
                    2.0 * pr.max(0.0) * inv2
                } else {
                    pi + mode.pressure / (mode.density * mode.density)
                };
                let mut vib = vi - b.v[j];
                if mode.friction >= 0.0
                    && let Some(n) = surface_normal(&c.geoms[obj], xi, dims)
                {
                    vib = n * n.dot(vib);
                }
                let pib = artificial_viscosity(vib, xib, r, ks.h, p.c_s, rho, p.av_alpha, p.av_beta, p.av_gamma);
                a += grad * (b.m_s[j] * (-n_s * bracket - pib));
                if mode.friction > 0.0 {
                    // the pressure part alone; grad ∥ −x_ib, so it pushes i off the wall when nˢ·bracket > 0
                    contact.add(mode.friction, grad * (b.m_s[j] * (-n_s * bracket)), n_s * bracket > 0.0, b.v[j]);
                }
            });
            a += contact.friction(vi, dt_upper);
            // Friction reaction (2.17, D-18) and reaction of the liquid–void attraction (3.4) —
            // −(m_j/ρ_j) × the pair term on liquid j (§3.12) — and on a membrane particle the reaction of
            // the liquid–membrane boundary forces (§4.1, within R_l), in one walk over the liquid within
            // R_× ≥ R_l (each sum takes its terms in the order separate walks would).
            let pair_terms = p.kbar > 0.0 || p.wicking > 0.0;
            let membrane = s.flags[i] & SolidFlags::MEMBRANE != 0;
            let normal_i = if membrane { capsule_normal(s.def_grad[i], s.normal0[i]) } else { Vec3::ZERO };
            let seals = membrane && p.capsule_seal > 0.0 && capsule_seals(s.bond_count[i], s.bond_count0[i]);
            if pair_terms || membrane {
                let r2l = kl.r * kl.r;
                let (mut f, mut fw, mut fm) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
                nb.liquid.for_each(xi, kx.r, |j, xij, r| {
                    if p.kbar > 0.0 {
                        let k = friction_coefficient(p.kbar, n_s, l.n_s[j]);
                        f += (vi - l.v[j]) * (l.m[j] / l.rho[j] * k * kx.w_poly6(r));
                    }
                    if p.wicking > 0.0 && r > 0.0 {
                        fw -= xij * (l.m[j] / l.rho[j] * wicking_pair(p.wicking, kx.h, n_s, s.n_l[i], r) / r);
                    }
                    if membrane && xij.length_squared() < r2l {
                        let (rho_j, p_j, nl_j, v_j, m_b) = (l.rho[j], l.p[j], l.n_l[j], l.v[j], s.m_bl[i]);
                        let (mirror, p_a) = (ObjectContact::MIRROR, p.ambient_pressure);
                        let xjb = -xij;
                        // on liquid j beneath the capsule its ghosts' reaction acts instead (below)
                        if !capsule_inner(p, normal_i, xjb) && !c.sees_ghost(j) {
                            let on_j =
                                liquid_from_boundary(p, rho_j, p_j, nl_j, v_j, m_b, vi, xjb, r, mirror, 1.0, g_l, p_a);
                            fm -= on_j * l.m[j];
                        }
                        if seals && seal_scale[j] > 0.0 {
                            // the reaction of the capsule's seal on liquid j (`capsule_seal_pair`)
                            let stop = capsule_seal_pair(p, normal_i, xjb, r, v_j - vi).stop;
                            fm += stop * (l.m[j] * seal_scale[j] * capsule_seal_share(l.m[j], s.m[i]));
                        }
                    }
                });
                if pair_terms {
                    a -= f / rho;
                    a += fw / s.m[i];
                }
                if membrane {
                    // the reaction of its ghosts' boundary forces on the liquid (`ghosts::ghost_pressure`)
                    if let Some(gn) = &nb.ghosts {
                        for k in gn.gh.start[i] as usize..gn.gh.start[i + 1] as usize {
                            fm += gn.state[k].reaction;
                        }
                    }
                    a += fm / s.m[i];
                }
            }
            // Ligament spring and dashpot to the anchor X (`Scenario::ligaments`): −ω²(x − X) − 2ζω v.
            if s.flags[i] & SolidFlags::TETHERED != 0 {
                let d = super::grid::min_image(xi - s.x_ref[i], period);
                a -= d * p.tether_omega2 + vi * p.tether_damping;
            }
            (a + c.gravity, xsph_velocity(vi, d_xsph, p.xsph_s), drho)
        })
        .collect();
    let mut a = Vec::with_capacity(out.len());
    let mut vx = Vec::with_capacity(out.len());
    let mut drho = Vec::with_capacity(out.len());
    for (x, y, z) in out {
        a.push(x);
        vx.push(y);
        drho.push(z);
    }
    SolidForces { a, xsph: xsph.then_some(vx), drho }
}

/// What `forces_solid` returns per solid particle: the acceleration, the XSPH velocity (evaluation 0)
/// and the continuity dρ/dt (2.47), summed in the force walks over the solid and the walls (0 for a
/// kinematic particle, whose ρ is not integrated).
pub struct SolidForces {
    pub a: Vec<Vec3>,
    pub xsph: Option<Vec<Vec3>>,
    pub drho: Vec<f32>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Scenario, generate};

    /// Parameters of a perfused block with a capsule (Δx = 2 mm on both lattices).
    fn capsule_params() -> Params {
        let text = "Scenario(name: \"t\", dimensions: 3, domain: Domain(min: (-0.02, -0.02, -0.02), max: (0.02, 0.02, 0.02)), \
             liquid: Some(Liquid(density: 1000.0, viscosity: 0.0035, sound_speed: Some(10.0))), \
             solid: Some(Solid(density: 1000.0, c10: 1e3, c01: 0.0, k_s: 1e4, n_sat: 0.7, k_sat: 1e4, friction: 1e6)), \
             numerics: Numerics(dx_liquid: Some(0.002), dx_solid: Some(0.002)), \
             particles: [PerfusedBlock(min: (-0.006, -0.006, -0.006), max: (0.006, 0.006, 0.006), solid_fraction: 0.7, liquid_fraction: 0.3)], \
             membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483)), duration: 1.0)";
        let sc = Scenario::from_str_named(text, "test").expect("valid test scenario");
        Params::new(&sc, &generate(&sc))
    }

    /// The seal's plane: the organ's surface, Δx_s/2 beyond the capsule's particles, with the capsule's
    /// ghost sites (the default), which fill that half spacing with blood; the particles' own plane
    /// with the thesis's capsule.
    #[test]
    fn the_seal_acts_at_the_organs_surface_with_ghost_sites() {
        let mut p = capsule_params();
        assert!(p.capsule_ghosts, "membrane.ghosts is on by default");
        assert_eq!(capsule_seal_offset(&p), 0.5 * p.capsule_dx_solid);
        p.capsule_ghosts = false;
        assert_eq!(capsule_seal_offset(&p), 0.0);
    }

    /// The seal's rule for one membrane particle (normal +z) and liquid at depth `sd` along its plane
    /// (the thesis's capsule, whose plane is the particle's: `capsule_seal_offset` 0) moving at `vz`:
    /// in the band it stops the outward velocity, never an inward one; beyond the plane it also walks
    /// the particle back in `CAPSULE_SEAL_STEPS` steps, by its advection velocity; outside its band and
    /// reach it acts on nothing, but the particle still counts in the weights.
    #[test]
    fn the_seal_removes_outward_motion_through_the_capsule_only() {
        let mut p = capsule_params();
        p.capsule_ghosts = false;
        assert_eq!(p.capsule_seal, 1.0, "membrane.seal is on by default");
        let (dx_l, dt) = (p.capsule_dx_liquid, p.dt_upper());
        let n = Vec3::Z;
        let pair = |sd: f32, lateral: f32, vz: f32| {
            let xij = Vec3::new(lateral, 0.0, sd);
            capsule_seal_pair(&p, n, xij, xij.length(), Vec3::new(0.3, 0.0, vz))
        };
        let lateral = 0.3 * dx_l;
        let w = |sd: f32| p.k_liquid.w_poly6(Vec3::new(lateral, 0.0, sd).length());
        // beneath the plane, in the band, moving out at 2 cm/s: all of it, and no walk
        let sp = pair(-0.1 * dx_l, lateral, 0.02);
        assert_eq!(sp.w, w(-0.1 * dx_l));
        assert!((sp.stop - n * (sp.w * 0.02)).length() <= 1e-6 * sp.w * 0.02, "{sp:?}");
        assert_eq!(sp.back, Vec3::ZERO);
        // moving in, or at rest beneath the plane: nothing (a PerfusedBlock's outer layer stays put)
        assert_eq!(pair(-0.1 * dx_l, lateral, -0.02).stop, Vec3::ZERO);
        assert_eq!(pair(-0.1 * dx_l, lateral, 0.0).stop, Vec3::ZERO);
        // beyond the plane at rest: no stop (no push that parts the pair), the walk back sd / (steps Δt_max)
        let sd = 0.2 * dx_l;
        let sp = pair(sd, lateral, 0.0);
        let back = sd / (CAPSULE_SEAL_STEPS * dt);
        assert_eq!(sp.stop, Vec3::ZERO);
        assert!((sp.back.z + sp.w * back).abs() <= 1e-5 * sp.w * back, "{} against {}", sp.back.z, -sp.w * back);
        // beyond the plane moving out: stopped as beneath it
        assert!((pair(sd, lateral, 0.02).stop - n * (sp.w * 0.02)).length() <= 1e-6 * sp.w * 0.02);
        // outside the band (half a spacing beneath, as the liquid rests; or bled out) and beyond the reach
        let rest = pair(-0.5 * dx_l, lateral, 0.02);
        assert_eq!((rest.stop, rest.back), (Vec3::ZERO, Vec3::ZERO));
        assert!(rest.w > 0.0, "a resting neighbour still weighs");
        let out = pair(0.3 * dx_l, lateral, 0.02);
        assert_eq!((out.stop, out.back), (Vec3::ZERO, Vec3::ZERO));
        assert_eq!(pair(0.0, 1.01 * p.capsule_dx_solid, 0.02).w, 0.0);
        // a capsule particle with more than a quarter of its bonds broken no longer seals
        assert!(capsule_seals(30, 40) && !capsule_seals(29, 40) && capsule_seals(0, 0));
        // the pair's stop is an inelastic collision: the liquid's change σ·e and the membrane's reaction
        // (m_l/m_s)σ·e remove the relative excess e once, whatever the masses (a capsule child of a
        // quarter site's mass under 3.3× heavier liquid is not thrown past the liquid)
        for (m_l, m_s) in [(1.0f32, 1.0f32), (3.3, 1.0), (1.0, 4.0), (1.7, 1.0)] {
            let sigma = capsule_seal_share(m_l, m_s);
            assert!((sigma + m_l / m_s * sigma - 1.0).abs() <= 1e-6, "masses {m_l}, {m_s}: share {sigma}");
        }
    }
}
